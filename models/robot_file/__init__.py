"""Robot files (``docs/robot-file.md``), read and checked into a :class:`~models.description.Robot`,
split by job: the value kinds and angle checks (``values.py``), the transform, controller and
joint-name tables (``sections.py``), the ``[collision]`` table (``collision_table.py``), DH-table
files, built-in robots and TOML writing (``dh_table.py``), and URDF-based files: the URDF chain
(``urdf_chain.py``), its DH form (``urdf_dh.py``), the file (``urdf_file.py``) and its collision
geometry (``urdf_collision.py``).  :mod:`models.robot` re-exports the names callers use."""

from .collision_table import (
    COLLISION_FIXED_TOL_M_PER_M,
    COLLISION_FRAMES,
    COLLISION_KEYS,
    COLLISION_N_BODIES,
    COLLISION_SEGMENT_KEYS,
    check_collision_fixed,
    parse_collision_table,
)
from .dh_table import load_robot, robot_from_dict, robot_to_toml
from .sections import parse_controller, parse_frame_table, parse_joint_names
from .values import INERTIA_TRIANGLE_RTOL, PLAUSIBLE_ANGLE_MAX_RAD, PLAUSIBLE_LIMIT_MAX_RAD, inertia_matrix

__all__ = [
    "COLLISION_FIXED_TOL_M_PER_M",
    "COLLISION_FRAMES",
    "COLLISION_KEYS",
    "COLLISION_N_BODIES",
    "COLLISION_SEGMENT_KEYS",
    "INERTIA_TRIANGLE_RTOL",
    "PLAUSIBLE_ANGLE_MAX_RAD",
    "PLAUSIBLE_LIMIT_MAX_RAD",
    "check_collision_fixed",
    "inertia_matrix",
    "load_robot",
    "parse_collision_table",
    "parse_controller",
    "parse_frame_table",
    "parse_joint_names",
    "robot_from_dict",
    "robot_to_toml",
]
