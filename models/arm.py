"""The arm model, where its callers import it from: :func:`load_arm` (a model from a built-in name,
a robot or model file, a :class:`~models.robot.Robot` or a model) and the names of
:mod:`models.arm_model` (:class:`ArmModel`, :class:`CampaignFrame`, :class:`EquilibriumResult`),
which describes the model.
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
