"""The sections of a problem file other than ``[path]``, ``[timing]``, programs and ``[cell]``.

The header (``name``, ``description``, ``source``), ``[robot]`` (with its tool), ``[orientation]``,
``[wrench]``, ``[payload]``, ``[limits]``, ``[cost]``, ``[solver]``, ``[branch]`` and
``[placement]``: each ``parse_*`` function validates one section of the parsed document and returns
its values in SI units (m, rad, N, N*m, kg, s), with the settings and section types they return
(:class:`Limits`, :class:`Header`, :class:`RobotSection`, :class:`OrientationSection`,
:class:`WrenchSection`, :class:`PayloadSection`). The package :mod:`problems.problem_file`
re-exports them with the other sections' names.

Every error is a :class:`ProblemFileError` naming the file, the key (dotted,
e.g. ``path.points``) and, for tables of rows, the row; the value found; and
what was expected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple
from collections.abc import Mapping

import numpy as np

from models.arm import ArmModel, load_arm
from models.constants import PLAUSIBLE_POSITION_MAX_M, gravity_problem
from models.robot import BUILTIN_ROBOTS, Robot, RobotFileError
from models.tables.keys import Key, KeyTable
from models.transforms import matrix_to_rpy, rpy_to_matrix, transform
from problems import paper
from problems.path import MAX_JOINT_STEP
from problems.posture import (
    DEFAULT_MAX_ITER,
    DEFAULT_SCAN,
    DEFAULT_SMOOTHNESS,
    DEFAULT_TOL,
    OrientationRule,
    SolverSettings,
)
from problems.problem_file.values import (
    PLAUSIBLE_JOINT_MAX_RAD,
    PLAUSIBLE_JOINT_STEP_MAX_RAD,
    ProblemFileError,
    angle_pair,
    check_radians,
    err,
    flag,
    integer,
    number,
    positive,
    rows,
    rpy_angles,
    table,
    vector,
    vector_or_scalar,
)

#: Default nominal TCP orientation: tool z axis pointing down (roll = 180 deg).
DEFAULT_RPY = np.array([math.pi, 0.0, 0.0])

_TOP = (
    *("name", "description", "source", "robot", "path", "orientation", "wrench", "payload", "limits", "cost"),
    *("solver", "branch", "timing", "placement", "workpiece", "cell", "material", "stock", "cut"),
)
#: Frames a wrench may be given in.
WRENCH_FRAMES = ("base", "tool")


# --------------------------------------------------------------------------------------
# Settings and parsed sections
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Limits:
    """Kinematic limits used by the plan (SI).

    Attributes
    ----------
    velocity, acceleration, jerk : ndarray, shape (6,)
        rad/s, rad/s^2, rad/s^3.
    max_joint_step : float
        Largest joint step between neighbouring waypoints, rad.
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    max_joint_step: float = MAX_JOINT_STEP


class Header(NamedTuple):
    """The top-level keys of a problem file.

    Attributes
    ----------
    name : str
        Non-empty, stripped.
    description : str
        Stripped; ``""`` if absent.
    source_text : str
        The file's ``source`` key (where the task comes from), stripped; ``""`` if absent.
    """

    name: str
    description: str
    source_text: str


class RobotSection(NamedTuple):
    """The ``[robot]`` section.

    Attributes
    ----------
    spec : str
        The robot as named in the file (built-in name, or robot / model file path
        resolved against the problem file's directory).
    arm : ArmModel
        The arm model with the file's tool (``robot.tool``: TCP in the flange frame, m, rad)
        applied.
    """

    spec: str
    arm: ArmModel


class OrientationSection(NamedTuple):
    """The ``[orientation]`` section.

    Attributes
    ----------
    rule : OrientationRule
    nominal_rpy : ndarray, shape (3,)
        Nominal base->TCP roll-pitch-yaw, rad.
    rotation : ndarray, shape (3, 3)
        The same nominal base->TCP rotation as a matrix (base frame).
    cone_half_angle : float
        rad (rule ``cone``), else 0.
    scan : int
        Scanned rotations about the tool axis for the warm starts.
    """

    rule: OrientationRule
    nominal_rpy: np.ndarray
    rotation: np.ndarray
    cone_half_angle: float
    scan: int


class WrenchSection(NamedTuple):
    """The ``[wrench]`` section.

    Attributes
    ----------
    frame : {"base", "tool"}
        Frame of the wrench (``tool``: the TCP frame, turning with the tool).
    wrench : ndarray, shape (N, 6)
        ``[f; m]`` on the TCP per waypoint, N and N*m, in ``frame``.
    per_waypoint : bool
        Whether the file gave one row per waypoint.
    """

    frame: str
    wrench: np.ndarray
    per_waypoint: bool


class PayloadSection(NamedTuple):
    """The ``[payload]`` section (all defaults when the table is absent or empty).

    Attributes
    ----------
    mass_kg : float
        Payload mass, kg (0 if absent).
    com_m : ndarray, shape (3,)
        Payload centre of mass, TCP frame, m.
    gravity : ndarray, shape (3,) or None
        Gravity acting on the payload, base frame, m/s^2; None: the robot's.
    """

    mass_kg: float
    com_m: np.ndarray
    gravity: np.ndarray | None


# --------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------


def _rotation_with_axis(axis: np.ndarray) -> np.ndarray:
    """A rotation whose z column is ``axis`` (x chosen deterministically)."""
    z = axis / np.linalg.norm(axis)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - z * (ref @ z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


# --------------------------------------------------------------------------------------
# Section parsers, in file order (each: where = the source for messages, data = the document)
# --------------------------------------------------------------------------------------


def parse_header(where: str, data: Any) -> Header:
    """Check the document is a table with known top-level keys; read name, description, source.

    Raises
    ------
    ProblemFileError
        Not a table, an unknown top-level key, an empty ``name``, or a non-string
        ``description`` / ``source``.
    """
    if not isinstance(data, Mapping):
        raise ProblemFileError(f"{where}: expected a table at top level")
    unknown = sorted(set(data) - set(_TOP))
    if unknown:
        hint = (
            '; this looks like a robot file (give it as [robot] model = "FILE" or --robot), not a problem file'
            if {"joints", "convention"} & set(unknown)
            else ""
        )
        raise ProblemFileError(f"{where}: unknown top-level key(s) {unknown}; allowed: {list(_TOP)}{hint}")
    name = data.get("name")
    if not isinstance(name, str) or not name.strip():
        raise err(where, "name", f"must be a non-empty string, got {name!r}")
    desc = data.get("description", "")
    src = data.get("source", "")
    for key, val in (("description", desc), ("source", src)):
        if not isinstance(val, str):
            raise err(where, key, f"must be a string, got {val!r}")
    return Header(name.strip(), desc.strip(), src.strip())


def parse_robot(where: str, data: Mapping[str, Any], base_dir: Path | None) -> RobotSection:
    """The ``[robot]`` section: load the arm model and apply the tool.

    Parameters
    ----------
    base_dir : Path, optional
        Directory against which a relative ``robot.model`` path is resolved.
    """
    rt = table(where, data, "robot")
    spec = rt.get("model")
    if not isinstance(spec, str) or not spec:
        raise err(
            where,
            "robot.model",
            f"must be a built-in robot name {list(BUILTIN_ROBOTS)} or a robot file path, got {spec!r}",
        )
    if spec not in BUILTIN_ROBOTS and base_dir is not None and not Path(spec).is_absolute():
        spec = str((base_dir / spec).resolve())
    try:
        arm = load_arm(spec)
    except RobotFileError as exc:
        raise ProblemFileError(f"{where}: key 'robot.model': {exc}") from None
    if "tool" in rt:
        tt = table(where, data, "robot.tool")
        xyz = vector(where, "robot.tool.xyz", tt.get("xyz", [0.0, 0.0, 0.0]), 3)
        if np.max(np.abs(xyz)) > PLAUSIBLE_POSITION_MAX_M:
            raise err(
                where,
                "robot.tool.xyz",
                f"= {xyz.tolist()} m is implausible for a tool (> "
                f"{PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres "
                "(millimetres given?)",
            )
        rpy = rpy_angles(where, tt, "robot.tool.")
        arm = arm.with_tool(transform(rpy_to_matrix(np.zeros(3) if rpy is None else rpy), xyz))
    return RobotSection(spec, arm)


def parse_orientation(where: str, data: Mapping[str, Any], program: bool = False) -> OrientationSection:
    """The ``[orientation]`` section: rule, nominal rotation (rpy or tool axis), cone, scan.

    ``program``: the path is a CAM program, which gives the tool axis: the rule defaults to
    ``free_tool_axis``, ``fixed`` and a nominal rotation are refused.
    """
    ot = table(where, data, "orientation")
    if program:
        for key in ("rpy", "rpy_deg", "axis"):
            if key in ot:
                raise err(
                    where, f"orientation.{key}", "does not apply to a program path (the program gives the tool axis)"
                )
        if ot.get("rule") == OrientationRule.FIXED.value:
            raise err(
                where,
                "orientation.rule",
                "= 'fixed' does not apply to a program path: a program gives the tool axis, not the "
                "rotation about it; use 'free_tool_axis' (the default), 'cone' or 'position_only'",
            )
    rule_raw = ot.get("rule", OrientationRule.FREE_TOOL_AXIS.value if program else None)
    try:
        rule = OrientationRule(rule_raw)
    except ValueError:
        raise err(
            where, "orientation.rule", f"must be one of {[r.value for r in OrientationRule]}, got {rule_raw!r}"
        ) from None
    rpy = rpy_angles(where, ot, "orientation.")
    if "axis" in ot:
        if rpy is not None:
            raise ProblemFileError(f"{where}: give either 'orientation.axis' or 'orientation.rpy'/'rpy_deg', not both")
        if rule is OrientationRule.FIXED:
            raise err(
                where,
                "orientation.axis",
                "cannot define a fixed orientation (an axis leaves the "
                "rotation about it open); give orientation.rpy_deg",
            )
        ax = vector(where, "orientation.axis", ot["axis"], 3)
        if np.linalg.norm(ax) < 1e-12:
            raise err(where, "orientation.axis", f"must be a non-zero vector, got {ax.tolist()}")
        R_nom = _rotation_with_axis(ax)
        nominal_rpy = matrix_to_rpy(R_nom)
    else:
        nominal_rpy = DEFAULT_RPY.copy() if rpy is None else rpy
        R_nom = rpy_to_matrix(nominal_rpy)
    half = _cone_half_angle(where, ot, rule)
    scan = integer(where, "orientation.scan", ot.get("scan", DEFAULT_SCAN), 1, 720)
    return OrientationSection(rule, np.asarray(nominal_rpy, float), R_nom, half, scan)


def _cone_half_angle(where: str, ot: Mapping[str, Any], rule: OrientationRule) -> float:
    """``orientation.half_angle`` (rad) / ``half_angle_deg``: required for, and only for, rule cone."""
    half = 0.0
    got = angle_pair(where, ot, "half_angle", "orientation.")
    if rule is OrientationRule.CONE:
        if got is None:
            raise err(where, "orientation.half_angle_deg", "is required for rule 'cone' (or half_angle, rad)")
        raw, deg = got
        key = f"orientation.half_angle{'_deg' if deg else ''}"
        given = number(where, key, raw)
        half = math.radians(given) if deg else given
        if not 0.0 < half < math.pi / 2:
            rng = "(0, 90) deg" if deg else "(0, pi/2) rad, i.e. (0, 1.5708)"
            hint = "" if deg or given <= 0 else "; degrees given? use 'orientation.half_angle_deg'"
            raise err(where, key, f"must be in {rng}, got {given:g}{' deg' if deg else ' rad'}{hint}")
    elif got is not None:
        raise err(where, "orientation.half_angle", f"only applies to rule 'cone' (rule is '{rule.value}')")
    return half


def parse_wrench(
    where: str, data: Mapping[str, Any], n: int, tool_rows: np.ndarray | None = None, optional: bool = False
) -> WrenchSection:
    """The ``[wrench]`` section: frame, and a constant force/moment or one row per waypoint.

    Parameters
    ----------
    n : int
        Number of waypoints N of the path.
    tool_rows : ndarray, shape (N, 6), optional
        A per-waypoint wrench in the TCP frame from the path itself (CL data with wrench columns):
        then ``[wrench]`` must be absent.
    optional : bool
        The section may be absent (zero): the load comes from elsewhere (a predicted cut).
    """
    if tool_rows is not None:
        if "wrench" in data:
            raise err(where, "wrench", "must be absent: the path's CL file gives the wrench per point (fx_N ... mz_Nm)")
        _check_wrench(where, "wrench.per_waypoint", tool_rows)
        return WrenchSection("tool", np.asarray(tool_rows, dtype=float), True)
    if optional and "wrench" not in data:
        return WrenchSection("base", np.zeros((n, 6)), False)
    wt = table(where, data, "wrench")
    frame = wt.get("frame", "base")
    if frame not in WRENCH_FRAMES:
        raise err(
            where,
            "wrench.frame",
            f"must be one of {list(WRENCH_FRAMES)} (base frame, or the TCP frame turning with the tool), got {frame!r}",
        )
    if "per_waypoint" in wt:
        if "force" in wt or "moment" in wt:
            raise ProblemFileError(f"{where}: give either 'wrench.per_waypoint' or 'wrench.force'/'moment', not both")
        W = rows(where, "wrench.per_waypoint", wt["per_waypoint"], 6)
        if len(W) != n:
            raise err(where, "wrench.per_waypoint", f"has {len(W)} rows but the path has {n} waypoints")
        _check_wrench(where, "wrench.per_waypoint", W)
        return WrenchSection(frame, W, True)
    if "force" not in wt:
        raise err(where, "wrench.force", "is required (or wrench.per_waypoint), in N")
    f = vector(where, "wrench.force", wt["force"], 3)
    m = vector(where, "wrench.moment", wt.get("moment", [0.0, 0.0, 0.0]), 3)
    _check_wrench(where, "wrench", np.r_[f, m][None, :])
    W = np.broadcast_to(np.r_[f, m], (n, 6)).copy()
    return WrenchSection(frame, W, False)


def _check_wrench(where: str, key: str, W: np.ndarray) -> None:
    """Refuse implausible force (N) or moment (N*m) components (kN or N*mm given by mistake),
    with the limits of the measurement files."""
    from problems.measurements import PLAUSIBLE_FORCE_MAX_N, PLAUSIBLE_MOMENT_MAX_NM

    for cols, limit, name, unit in (
        (slice(0, 3), PLAUSIBLE_FORCE_MAX_N, "force", "N"),
        (slice(3, 6), PLAUSIBLE_MOMENT_MAX_NM, "moment", "N*m"),
    ):
        part = np.abs(W[:, cols])
        if np.any(part > limit):
            i, j = np.unravel_index(int(np.argmax(part)), part.shape)
            k = f"{key}[{i}][{j + cols.start}]" if key.endswith("per_waypoint") else f"{key}.{name}[{j}]"
            raise err(
                where,
                k,
                f"= {float(W[i, j + cols.start]):g} {unit} is implausible (|value| above "
                f"{limit:g} {unit}); the {name} is in {unit}",
            )


def _payload_mass(where: str, key: str, v: Any) -> float:
    """``[payload] mass_kg``: a number >= 0, kg."""
    m = number(where, key, v)
    if m < 0:
        raise err(where, key, f"must be >= 0 kg, got {m!r}")
    return m


def _payload_com(where: str, key: str, v: Any) -> np.ndarray:
    """``[payload] com_m``: the centre of mass in the TCP frame, m, shape (3,), plausible in metres."""
    com = vector(where, key, v, 3)
    if np.max(np.abs(com)) > PLAUSIBLE_POSITION_MAX_M:
        raise err(
            where, key, f"= {com.tolist()} m is implausible (> {PLAUSIBLE_POSITION_MAX_M:g} m; millimetres given?)"
        )
    return com


def _payload_gravity(where: str, key: str, v: Any) -> np.ndarray:
    """``[payload] gravity_m_s2``: the gravity vector in the base frame, m/s^2, shape (3,)."""
    g = vector(where, key, v, 3)
    why = gravity_problem(g)
    if why:
        raise err(where, key, f"= {g.tolist()} {why}")
    return g


#: ``[payload]``, key by key (a present table needs ``mass_kg``).
PAYLOAD_KEYS = KeyTable(
    "payload",
    (
        Key(
            "mass_kg",
            _payload_mass,
            required=lambda where, key: err(where, key, "is required in a [payload] table (kg)"),
            unit="kg",
        ),
        Key("com_m", _payload_com, default=[0.0, 0.0, 0.0], unit="m"),
        Key("gravity_m_s2", _payload_gravity, unit="m/s^2"),
    ),
)


def parse_payload(where: str, data: Mapping[str, Any]) -> PayloadSection:
    """The ``[payload]`` section (:data:`PAYLOAD_KEYS`): mass (kg), centre of mass (TCP frame, m),
    optional gravity (base frame, m/s^2); no table: no payload."""
    pt = table(where, data, "payload", PAYLOAD_KEYS.names)
    if not pt:
        return PayloadSection(0.0, np.zeros(3), None)
    v = PAYLOAD_KEYS.read(where, pt)
    return PayloadSection(v["mass_kg"], v["com_m"], v["gravity_m_s2"])


def parse_limits(where: str, data: Mapping[str, Any], robot: Robot) -> Limits:
    """The ``[limits]`` section: joint limits (absolute or scaling the robot's) and joint step.

    Parameters
    ----------
    robot : Robot
        Supplies the default velocity, acceleration and jerk limits (rad/s, rad/s^2, rad/s^3).
    """
    lt = table(where, data, "limits")
    lims = {}
    for key, base in (("velocity", robot.v_max), ("acceleration", robot.a_max), ("jerk", robot.j_max)):
        if key in lt and f"{key}_scale" in lt:
            raise ProblemFileError(f"{where}: give either 'limits.{key}' or 'limits.{key}_scale', not both")
        if key in lt:
            v = vector_or_scalar(where, f"limits.{key}", lt[key], 6)
            bad = np.where(v <= 0)[0]
            if bad.size:
                raise ProblemFileError(
                    f"{where}: key 'limits.{key}' joint {int(bad[0]) + 1}: must be > 0, got {float(v[bad[0]]):g}"
                )
        elif f"{key}_scale" in lt:
            s = positive(where, f"limits.{key}_scale", lt[f"{key}_scale"])
            v = base * s
        else:
            v = base.copy()
        lims[key] = v
    got = angle_pair(where, lt, "max_joint_step", "limits.")
    if got is None:
        step = MAX_JOINT_STEP
    else:
        raw, deg = got
        step = positive(where, f"limits.max_joint_step{'_deg' if deg else ''}", raw)
        if not deg:
            check_radians(
                where,
                "limits.max_joint_step",
                np.array([step]),
                PLAUSIBLE_JOINT_STEP_MAX_RAD,
                "limits.max_joint_step_deg",
            )
        step = math.radians(step) if deg else step
    return Limits(lims["velocity"], lims["acceleration"], lims["jerk"], step)


def _smoothness(where: str, key: str, v: Any) -> float:
    """``[cost] smoothness``: a number >= 0, mm^2/rad^2."""
    smooth = number(where, key, v)
    if smooth < 0:
        raise err(where, key, f"must be >= 0 (mm^2/rad^2), got {smooth!r}")
    return smooth


def _solver_name(where: str, key: str, v: Any) -> str:
    """``[solver] name``: only ``ipopt``."""
    if v != "ipopt":
        raise err(where, key, f"must be 'ipopt' (the only NLP solver available), got {v!r}")
    return v


#: ``[cost]``, key by key.
COST_KEYS = KeyTable("cost", (Key("smoothness", _smoothness, default=DEFAULT_SMOOTHNESS, unit="mm^2/rad^2"),))

#: ``[solver]``, key by key (the fields of :class:`~problems.posture.SolverSettings`).
SOLVER_KEYS = KeyTable(
    "solver",
    (
        Key("name", _solver_name, default="ipopt"),
        Key("max_iter", lambda where, key, v: integer(where, key, v, 0), default=DEFAULT_MAX_ITER),
        Key("tol", positive, default=DEFAULT_TOL),
        Key("codegen", flag, default=True),
    ),
)


def parse_cost(where: str, data: Mapping[str, Any]) -> float:
    """The ``[cost]`` section (:data:`COST_KEYS`): the smoothness weight, mm^2/rad^2 (>= 0)."""
    return COST_KEYS.read(where, table(where, data, "cost", COST_KEYS.names))["smoothness"]


def parse_solver(where: str, data: Mapping[str, Any]) -> SolverSettings:
    """The ``[solver]`` section (:data:`SOLVER_KEYS`): NLP solver name (only ``ipopt``), iterations,
    tolerance, codegen."""
    return SolverSettings(**SOLVER_KEYS.read(where, table(where, data, "solver", SOLVER_KEYS.names)))


def parse_branch(where: str, data: Mapping[str, Any]) -> np.ndarray:
    """The ``[branch]`` section: the home configuration choosing the IK branch.

    Returns
    -------
    ndarray, shape (6,)
        Joint angles, rad (the paper's home pose if absent).
    """
    bt = table(where, data, "branch")
    got = angle_pair(where, bt, "home", "branch.")
    if got is None:
        return paper.HOME_Q.copy()
    raw, deg = got
    home = vector(where, f"branch.home{'_deg' if deg else ''}", raw, 6)
    if not deg:
        check_radians(where, "branch.home", home, PLAUSIBLE_JOINT_MAX_RAD, "branch.home_deg")
    return np.radians(home) if deg else home


def parse_placement(where: str, data: Mapping[str, Any]) -> Any:
    """The optional ``[placement]`` table: the grid of ``compplan place`` (keys ``x_m``, ``y_m``,
    ``z_m``, ``yaw_deg``, ``tilt_deg``: a number or ``[start, stop, count]``; ``top``), or None.

    Returns
    -------
    problems.placement.grid.PlacementGrid or None
    """
    from problems.placement.grid import PlacementGridError, grid_from_table

    if "placement" not in data:
        return None
    tab = data["placement"]
    if not isinstance(tab, Mapping):
        raise err(where, "placement", f"must be a table, got {tab!r}")
    try:
        return grid_from_table(tab, f"{where}: [placement]")
    except PlacementGridError as exc:
        raise ProblemFileError(str(exc)) from None
