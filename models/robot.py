"""Robots: the description (:mod:`models.description`: :class:`Robot`, :class:`Joint`, the
collision declarations, :class:`RobotFileError`) and the robot-file readers
(:mod:`models.robot_file`: :func:`load_robot`, :func:`robot_from_dict`, :func:`robot_to_toml`, the
tables' parsers), re-exported here under the names callers use."""

from models.description import (
    BUILTIN_ROBOTS,
    CONVENTIONS,
    CollisionSegment,
    Joint,
    Robot,
    RobotCollision,
    RobotFileError,
)
from models.robot_file import (
    COLLISION_FIXED_TOL_M_PER_M,
    COLLISION_FRAMES,
    COLLISION_KEYS,
    COLLISION_N_BODIES,
    COLLISION_SEGMENT_KEYS,
    INERTIA_TRIANGLE_RTOL,
    PLAUSIBLE_ANGLE_MAX_RAD,
    PLAUSIBLE_LIMIT_MAX_RAD,
    check_collision_fixed,
    inertia_matrix,
    load_robot,
    parse_collision_table,
    parse_controller,
    parse_frame_table,
    parse_joint_names,
    robot_from_dict,
    robot_to_toml,
)
from models.tables.text_file import read_text_file

__all__ = [
    "BUILTIN_ROBOTS",
    "COLLISION_FIXED_TOL_M_PER_M",
    "COLLISION_FRAMES",
    "COLLISION_KEYS",
    "COLLISION_N_BODIES",
    "COLLISION_SEGMENT_KEYS",
    "CONVENTIONS",
    "INERTIA_TRIANGLE_RTOL",
    "PLAUSIBLE_ANGLE_MAX_RAD",
    "PLAUSIBLE_LIMIT_MAX_RAD",
    "CollisionSegment",
    "Joint",
    "Robot",
    "RobotCollision",
    "RobotFileError",
    "check_collision_fixed",
    "inertia_matrix",
    "load_robot",
    "parse_collision_table",
    "parse_controller",
    "parse_frame_table",
    "parse_joint_names",
    "read_text_file",
    "robot_from_dict",
    "robot_to_toml",
]
