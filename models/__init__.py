"""Robot descriptions and the symbolic CasADi model built from them (FK, Jacobian,
compliance, analytic IK).  Depends on nothing else in the project."""

from typing import TYPE_CHECKING

from models.lazy import lazy_exports

if TYPE_CHECKING:
    from .errors import CompplanError, InfeasibleError, InputError, UnreachableError
    from .ik import BRANCH_LABELS, AnalyticIK, IKSolution, IKSolver, IKStatus, IKStructureError, ik_solver
    from .robot import BUILTIN_ROBOTS, Joint, Robot, RobotFileError, load_robot, robot_from_dict
    from .symbolic import KinematicModel, cartesian_stiffness, directional_stiffness

#: The submodule defining each name re-exported here.  Imported on first use (PEP 562), so that
#: importing one light submodule (``models.errors``) does not import CasADi, SciPy and the IK
#: families: ``compplan --version`` and every command's start-up stay fast.
_LAZY = {
    **dict.fromkeys(
        ("CompplanError", "InfeasibleError", "InputError", "SingularityError", "UnreachableError"), "errors"
    ),
    **dict.fromkeys(
        ("BRANCH_LABELS", "AnalyticIK", "IKSolution", "IKSolver", "IKStatus", "IKStructureError", "ik_solver"), "ik"
    ),
    **dict.fromkeys(("BUILTIN_ROBOTS", "Joint", "Robot", "RobotFileError", "load_robot", "robot_from_dict"), "robot"),
    **dict.fromkeys(("KinematicModel", "cartesian_stiffness", "directional_stiffness"), "symbolic"),
}


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)


__all__ = [
    "AnalyticIK",
    "BRANCH_LABELS",
    "BUILTIN_ROBOTS",
    "CompplanError",
    "IKSolution",
    "IKSolver",
    "IKStatus",
    "ik_solver",
    "IKStructureError",
    "InfeasibleError",
    "InputError",
    "Joint",
    "KinematicModel",
    "Robot",
    "RobotFileError",
    "UnreachableError",
    "cartesian_stiffness",
    "directional_stiffness",
    "load_robot",
    "robot_from_dict",
]
