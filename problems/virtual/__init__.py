"""The virtual robot: a measurement-campaign simulator with optional effects.

It is the project's own test bench for ``compplan identify``.  It is written
independently of the identification model (:mod:`models.effects`): NumPy
kinematics, physical forms of the effects (a two-slope hardening curve, a hard
dead band, Euler-Bernoulli beams, COM Jacobians for gravity), so that a test
passes only if the identification's parametrisation covers the physics rather
than reproduces its own formulas.

The configuration is a TOML table (schema in ``docs/identification.md``, examples
in ``problems/files/sim/``).  :meth:`VirtualRobot.truth` returns every realised
parameter, so a campaign can be re-measured after compensation.

A campaign measures the position of the measured point and, with ``[campaign]
orientation = true``, the orientation of the measured frame (the TCP's orientation,
carried to the measured point) as a rotation vector in the measurement frame.

Conventions as everywhere: SI units, wrench ``[f; m]`` in the base frame acting
on the TCP, a joint yields in the direction of the torque applied to it.

Modules
-------
:mod:`~problems.virtual.config`
    The configuration's top-level and campaign keys, defaults and limits,
    :class:`SimConfigError`, :func:`load_config` and the checks of values.
:mod:`~problems.virtual.registry`
    Which physics the virtual robot simulates: its realisations (:func:`simulates`), keyed by
    the model effects' declarations (``Effect.simulation`` names each effect's table), the
    valid tables, the effects it does not simulate (:func:`not_simulated`) and the check of
    the ``[effects.NAME]`` tables.
:mod:`~problems.virtual.geometry`
    NumPy kinematics of the true arm: link transforms, frames, joint axes, torques of
    a force at a point, :func:`rotvecs`.
:mod:`~problems.virtual.effects`
    Realising each simulated table (the declared model's ``[stiffness]`` and
    ``[registration]``, each ``[effects.NAME]``): the true parameters of the arm.
:mod:`~problems.virtual.physics`
    Joint errors, torques (loads and gravity), joint deflection (hardening, lost
    motion), the deflected equilibrium, the link beams.
:mod:`~problems.virtual.measure`
    True positions and orientations of the deflected arm and their noise-free
    measurement (registration, drift); the TCP error.
:mod:`~problems.virtual.campaign`
    A campaign: pose sampling, loads, times and temperatures, noise, outliers, the
    :class:`~problems.measurements.Measurements`.
:mod:`~problems.virtual.robot`
    :class:`VirtualRobot` (its ``__init__`` checks the configuration; its methods come
    from the parts in ``effects``, ``physics``, ``measure`` and ``campaign``),
    :meth:`VirtualRobot.truth`, :func:`simulator`.
:mod:`~problems.virtual.truth`
    Truth records: :func:`from_truth`, :func:`load_truth`.

Dependencies run one way: ``config`` and ``geometry`` import nothing of the package;
``registry`` uses ``config`` and reads the effects' declarations (never their formulas);
``effects`` uses ``config`` and ``registry``; ``physics`` and ``measure`` use ``geometry``; ``campaign``
uses ``config`` and ``geometry``; ``robot`` uses ``config``, ``registry`` and the four parts; ``truth``
uses ``config`` and ``robot``.
"""

from __future__ import annotations

from .config import SimConfigError, load_config
from .geometry import rotvecs
from .registry import effect_tables, not_simulated, realisation, realisations
from .robot import VirtualRobot, simulator
from .truth import from_truth, load_truth

#: The valid ``[effects.NAME]`` tables, in the order they are realised (from the effects'
#: declarations and the realisations registered when the package is imported).
SIM_EFFECTS: tuple[str, ...] = tuple(effect_tables())

__all__ = [
    "SIM_EFFECTS",
    "SimConfigError",
    "VirtualRobot",
    "effect_tables",
    "from_truth",
    "load_config",
    "load_truth",
    "not_simulated",
    "realisation",
    "realisations",
    "rotvecs",
    "simulator",
]
