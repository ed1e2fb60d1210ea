"""Inverse kinematics: every branch, per arm family, detected from the chain.

One module per family registers an :class:`~models.ik.base.IKSolver` (extend by adding a
file): :mod:`models.ik.ur` (UR-type closed form, 8 branches), :mod:`models.ik.opw`
(ortho-parallel arms with a spherical wrist, closed form, 8 branches), :mod:`models.ik.general`
(any other 6R: EAIK's subproblem decomposition, else a numeric multi-start; the fallback).
:func:`ik_solver` returns the first family, in increasing ``order``, that accepts a robot's chain.

Every module of this package other than the helpers ``base``, ``general_numeric``,
``general_solver``, ``opw_closed_form`` and ``opw_detect`` is imported here (``ur``, ``opw``,
``general`` first, in that order), and so is every module in the folders named by
``$COMPPLAN_IK_PATH`` (``os.pathsep``-separated), as ``models.ik.<name>``
(:func:`models.plugins.import_plugins`): a new family is one module that defines and registers it,
in this package or in such a folder.
"""

from models.plugins import import_plugins

from .base import IK_REASONS, IKSolution, IKSolver, IKStatus, IKStructureError, ik_solver
from .ur import BRANCH_LABELS, AnalyticIK

#: Extra folders searched for IK family modules (``os.pathsep``-separated).
IK_PATH_VARIABLE = "COMPPLAN_IK_PATH"
import_plugins(
    __name__,
    __path__,
    IK_PATH_VARIABLE,
    skip=("base", "general_numeric", "general_solver", "opw_closed_form", "opw_detect"),
    first=("ur", "opw", "general"),
)

__all__ = [
    "BRANCH_LABELS",
    "IK_REASONS",
    "AnalyticIK",
    "IKSolution",
    "IKSolver",
    "IKStatus",
    "IKStructureError",
    "ik_solver",
]
