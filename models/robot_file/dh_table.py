"""DH-table robot files: the joints' rows read and checked, the whole file into a :class:`Robot`
(a URDF-based file handed to :mod:`models.robot_file.urdf_file`), built-in robots by name, and
back to TOML."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any
from collections.abc import Mapping, Sequence

import numpy as np

from models.constants import (
    PLAUSIBLE_JOINT_SPEED_MAX_RAD_S,
    PLAUSIBLE_LINK_MASS_MAX_KG,
    PLAUSIBLE_MASS_PER_REACH3_MAX_KG_M3,
    PLAUSIBLE_POSITION_MAX_M,
    STANDARD_GRAVITY,
    gravity_problem,
)
from models.degenerate import check_chain, robot_axes
from models.description import BUILTIN_ROBOTS, CONVENTIONS, JOINT_REQUIRED, Joint, Robot, RobotFileError
from models.tables.text_file import read_text_file

from .collision_table import check_collision_fixed, parse_collision_table
from .sections import parse_controller, parse_frame_table, parse_joint_names
from .values import VALUES, angle, as_written, finite, inertia_matrix, vector

# Keys that may be given in radians (plain name) or degrees (``_deg`` suffix).
_ANGLE_KEYS = ("alpha", "theta_offset", "q_min", "q_max")
_JOINT_OPTIONAL = ("mass", "com", "inertia")
_TOP_KEYS = (
    "name",
    "convention",
    "description",
    "joints",
    "tool",
    "gravity",
    "source",
    "identified",
    "joint_names",
    "frame0_in_base",
    "flange_in_frame6",
    "controller",
    "collision",
)


def _parse_joint(where: str, row: Any) -> Joint:
    if not isinstance(row, Mapping):
        raise RobotFileError(f"{where}: expected a table of joint keys, got {row!r}")
    allowed = set(JOINT_REQUIRED) | set(_JOINT_OPTIONAL) | {f"{k}_deg" for k in _ANGLE_KEYS}
    VALUES.unknown_keys(where, row, sorted(allowed))
    vals: dict[str, Any] = {}
    for key in JOINT_REQUIRED:
        if key in _ANGLE_KEYS:
            vals[key] = angle(where, row, key)
        elif key not in row:
            raise RobotFileError(f"{where}: missing key '{key}'")
        else:
            vals[key] = finite(where, key, row[key])
    for key in ("a", "d"):
        if abs(vals[key]) > PLAUSIBLE_POSITION_MAX_M:
            raise RobotFileError(
                f"{where}: key '{key}' = {vals[key]:g} m is implausible for a link "
                f"(> {PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres "
                "(millimetres given?)"
            )
    if vals["q_min"] >= vals["q_max"]:
        (kmin, vmin), (kmax, vmax) = as_written(row, "q_min"), as_written(row, "q_max")
        raise RobotFileError(f"{where}: key '{kmin}' ({vmin}) must be below '{kmax}' ({vmax}); limits inverted?")
    for key in ("v_max", "a_max", "j_max", "stiffness"):
        if vals[key] <= 0:
            raise RobotFileError(f"{where}: key '{key}' must be > 0, got {vals[key]}")
    if vals["v_max"] > PLAUSIBLE_JOINT_SPEED_MAX_RAD_S:
        raise RobotFileError(
            f"{where}: key 'v_max' = {vals['v_max']:g} rad/s is implausible for a joint "
            f"(> {PLAUSIBLE_JOINT_SPEED_MAX_RAD_S:g} rad/s); speeds are in rad/s (degrees per second given?)"
        )
    if ("mass" in row) != ("com" in row):
        raise RobotFileError(f"{where}: give 'mass' and 'com' together")
    if "mass" in row:
        vals["mass"] = finite(where, "mass", row["mass"])
        if vals["mass"] < 0:
            raise RobotFileError(f"{where}: key 'mass' must be >= 0, got {vals['mass']}")
        if vals["mass"] > PLAUSIBLE_LINK_MASS_MAX_KG:
            raise RobotFileError(
                f"{where}: key 'mass' = {vals['mass']:g} kg is implausible for a link "
                f"(> {PLAUSIBLE_LINK_MASS_MAX_KG:g} kg); masses are in kg (grams given?)"
            )
        vals["com"] = vector(where, "com", row["com"], 3)
    if "inertia" in row:
        if "mass" not in row:
            raise RobotFileError(f"{where}: key 'inertia' needs 'mass' and 'com'")
        vals["inertia"] = inertia_matrix(where, vector(where, "inertia", row["inertia"], 6))
    deg = frozenset(k for k in _ANGLE_KEYS if f"{k}_deg" in row)
    return Joint(**vals, deg_keys=deg)


def robot_from_dict(data: Mapping[str, Any], where: str = "robot", base_dir: Path | None = None) -> Robot:
    """Build and validate a :class:`Robot` from a robot-file dictionary.

    Parameters
    ----------
    data : mapping
        The parsed TOML document (see ``docs/robot-file.md``): a DH table, or a URDF-based
        file (key ``urdf``, read by :mod:`models.robot_file.urdf_file`).
    where : str
        Name of the source, used in error messages (usually the file path).
    base_dir : Path, optional
        Folder a ``urdf`` path is relative to (the robot file's folder).

    Raises
    ------
    RobotFileError
        Naming the file, the key and the offending value.
    """
    if not isinstance(data, Mapping):
        raise RobotFileError(f"{where}: expected a table at top level")
    if "urdf" in data:
        from .urdf_file import robot_from_urdf_dict  # imports yourdfpy: only for a URDF-based file

        return robot_from_urdf_dict(data, where, base_dir)
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        hint = (
            "; this looks like a problem file (compplan plan PROBLEM), not a robot file"
            if {"path", "wrench", "orientation"} & set(unknown)
            else ""
        )
        raise RobotFileError(f"{where}: unknown top-level key(s) {unknown}; allowed: {list(_TOP_KEYS)}{hint}")
    name = VALUES.text(where, "name", data.get("name"), empty=False)
    conv = data.get("convention")
    if conv not in CONVENTIONS:
        raise RobotFileError(f"{where}: key 'convention' must be one of {CONVENTIONS}, got {conv!r}")
    joints_raw = data.get("joints")
    if not isinstance(joints_raw, list) or len(joints_raw) != 6:
        n = len(joints_raw) if isinstance(joints_raw, list) else joints_raw
        raise RobotFileError(f"{where}: key 'joints' must be an array of 6 [[joints]] tables, got {n!r}")
    joints = tuple(_parse_joint(f"{where}: joints[{i + 1}]", row) for i, row in enumerate(joints_raw))

    tcp2flange = parse_frame_table(where, "tool", data.get("tool", {}))
    gravity = vector(where, "gravity", data.get("gravity", [0.0, 0.0, -STANDARD_GRAVITY]), 3)
    why = gravity_problem(gravity)
    if why:
        raise RobotFileError(f"{where}: key 'gravity' = {gravity.tolist()} {why}")
    desc = data.get("description", "")
    src = data.get("source", "")
    for key, val in (("description", desc), ("source", src)):
        if not isinstance(val, str):
            raise RobotFileError(f"{where}: key '{key}' must be a string")
    identified = data.get("identified")
    if identified is not None and not isinstance(identified, Mapping):
        raise RobotFileError(f"{where}: key 'identified' must be a table")
    frames = {
        key: parse_frame_table(where, key, data[key]) for key in ("frame0_in_base", "flange_in_frame6") if key in data
    }
    robot = Robot(
        name=name,
        convention=conv,
        joints=joints,
        tcp2flange=tcp2flange,
        gravity=gravity,
        description=desc,
        source=src,
        identified=dict(identified) if identified is not None else None,
        collision=parse_collision_table(where, data["collision"]) if "collision" in data else None,
        frame02base=frames.get("frame0_in_base", np.eye(4)),
        flange2frame6=frames.get("flange_in_frame6", np.eye(4)),
        joint_names=parse_joint_names(where, data.get("joint_names")),
        **parse_controller(where, data.get("controller")),
        controller_declared="controller" in data,
    )
    check_chain(where, robot_axes(robot), robot.q_min, robot.q_max, robot.joint_names)
    _check_mass_scale(where, joints)
    check_collision_fixed(where, robot)
    return robot


def _check_mass_scale(where: str, joints: Sequence[Joint]) -> None:
    """Refuse link masses that are implausible for the arm's size (grams given as kg): the total
    mass over the cube of the reach above :data:`PLAUSIBLE_MASS_PER_REACH3_MAX_KG_M3`."""
    total = sum(j.mass for j in joints if j.mass is not None)
    reach = sum(abs(j.a) + abs(j.d) for j in joints)
    if total <= 0 or reach <= 0:
        return
    ratio = total / reach**3
    if ratio > PLAUSIBLE_MASS_PER_REACH3_MAX_KG_M3:
        raise RobotFileError(
            f"{where}: the link masses add up to {total:g} kg for an arm of reach {reach:.3g} m "
            f"({ratio:.3g} kg/m^3 of reach cubed; real arms lie near 5 to 150, the limit is "
            f"{PLAUSIBLE_MASS_PER_REACH3_MAX_KG_M3:g}): key 'mass' is in kg (grams given?)"
        )


def load_robot(spec: str | Path) -> Robot:
    """Load a robot by built-in name (:data:`BUILTIN_ROBOTS`) or TOML file path.

    Raises
    ------
    RobotFileError
        The file is missing, not TOML, or fails validation (message names the key).
    """
    s = str(spec)
    if s in BUILTIN_ROBOTS:
        folder = resources.files("models").joinpath("robots")
        text = folder.joinpath(f"{s}.toml").read_text(encoding="utf-8")
        where = f"built-in robot '{s}'"
        base_dir = Path(str(folder))
    else:
        path = Path(s)
        if not path.exists():
            raise RobotFileError(
                f"robot '{s}': no such file, and not a built-in robot (built-ins: {', '.join(BUILTIN_ROBOTS)})"
            )
        text = read_text_file(path, "robot file (TOML)", RobotFileError)
        where = str(path)
        base_dir = path.parent
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{where}: not valid TOML: {exc}") from None
    return robot_from_dict(data, where, base_dir)


def robot_to_toml(robot: Robot) -> str:
    """Serialise a robot to robot-file TOML text (SI units, radians)."""
    import tomli_w

    return tomli_w.dumps(robot.to_dict())
