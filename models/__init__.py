"""Robot descriptions and the symbolic CasADi model built from them (FK, Jacobian,
compliance, analytic IK).  Depends on nothing else in the project."""

from .errors import CompplanError, InfeasibleError, InputError, SingularityError, UnreachableError
from .ik import BRANCH_LABELS, AnalyticIK, IKSolution, IKSolver, IKStatus, IKStructureError, ik_solver
from .robot import BUILTIN_ROBOTS, Joint, Robot, RobotFileError, load_robot, robot_from_dict
from .symbolic import KinematicModel, cartesian_stiffness, directional_stiffness

__all__ = [
    "AnalyticIK", "BRANCH_LABELS", "BUILTIN_ROBOTS", "CompplanError", "IKSolution", "IKSolver", "IKStatus",
    "ik_solver",
    "IKStructureError", "InfeasibleError", "InputError", "Joint", "KinematicModel", "Robot",
    "RobotFileError", "SingularityError", "UnreachableError", "cartesian_stiffness",
    "directional_stiffness", "load_robot", "robot_from_dict",
]
