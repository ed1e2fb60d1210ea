"""The arm model: one object from measurement to motion (defined in :mod:`models.arm_model`).

An :class:`ArmModel` is the kinematic chain of a robot description plus its
deflection model, a set of effect plug-ins (:mod:`models.effects`) with their
parameter values.  A plain robot file gives the nominal model (DH table and
linear joint springs); a robot file with an ``[identified]`` table (written by
``compplan identify``, see :mod:`models.arm_file`) gives the identified one.
Planning, compensation, maps, prediction and reports all evaluate this object:

* :attr:`ArmModel.kinematics` -- named CasADi functions with the parameters fixed
  (:class:`models.symbolic.KinematicModel`), compiled for batches;
* :meth:`ArmModel.equilibrium` -- the deflected equilibrium ``q = q_c + dq(q, L)``,
  the one place the product decides where a loaded arm settles (the deflection is
  evaluated at the deflected pose).

Frames: the base frame of the robot (``tcp2base`` maps TCP-frame coordinates to
base-frame coordinates); the measurement frame and the measured point matter only
for identification and prediction (:meth:`base2meas`, :attr:`measured_point`).
"""

from __future__ import annotations

# the arm model's names, imported from here by their callers (models.arm_model defines them)
from .arm_model import ArmModel
from .arm_model import CampaignFrame as CampaignFrame
from .arm_model import EquilibriumResult as EquilibriumResult
from .robot import Robot


def load_arm(spec: str | Robot | ArmModel) -> ArmModel:
    """An :class:`ArmModel` from a built-in name, a robot file (with or without an
    ``[identified]`` table), a :class:`Robot` or an existing model."""
    if isinstance(spec, ArmModel):
        return spec
    if isinstance(spec, Robot):
        from .arm_file import model_from_robot

        return model_from_robot(spec, spec.name)
    from .arm_file import load_model

    return load_model(str(spec))
