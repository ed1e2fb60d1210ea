"""Inverse kinematics: every branch, per arm family, detected from the chain.

One module per family registers an :class:`~models.ik.base.IKSolver` (extend by adding a
file): :mod:`models.ik.ur` (UR-type closed form, 8 branches), :mod:`models.ik.opw`
(ortho-parallel arms with a spherical wrist, closed form, 8 branches), :mod:`models.ik.general`
(any other 6R: EAIK's subproblem decomposition, else a numeric multi-start).
:func:`ik_solver` returns the first family that accepts a robot's chain.
"""

from .base import (IK_REASONS, IKSolution, IKSolver, IKStatus, IKStructureError, families, ik_solver,
                   into_limits, register_family)
from .ur import BRANCH_LABELS, AnalyticIK
from . import opw as _opw  # noqa: F401  (registers the family)
from . import general as _general  # noqa: F401  (registers the family)

__all__ = ["AnalyticIK", "BRANCH_LABELS", "IK_REASONS", "IKSolution", "IKSolver", "IKStatus", "IKStructureError",
           "families", "ik_solver", "into_limits", "register_family"]
