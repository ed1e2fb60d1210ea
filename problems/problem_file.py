"""The problem-file format: one validating parser per section of a problem file.

A problem file (TOML, documented in ``docs/problem-file.md``) has the sections
header (``name``, ``description``, ``source``), ``[robot]`` (with its tool),
``[orientation]``, ``[path]``, ``[wrench]``, ``[payload]``, ``[limits]``,
``[cost]``, ``[solver]``, ``[branch]`` and ``[timing]``.  Each ``parse_*``
function below validates one section of the parsed document and returns its
values in SI units (m, rad, N, N*m, kg, s); :func:`problems.problem.problem_from_dict`
calls them in file order and assembles the :class:`~problems.problem.Problem`.

Every error is a :class:`ProblemFileError` naming the file, the key (dotted,
e.g. ``path.points``) and, for tables of rows, the row; the value found; and
what was expected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple
from collections.abc import Mapping

import numpy as np

from models.arm import ArmModel, load_arm
from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError
from models.robot import BUILTIN_ROBOTS, Robot, RobotFileError
from models.transforms import matrix_to_rpy, rpy_to_matrix, transform
from problems import paper
from problems.path import MAX_JOINT_STEP, line_positions
from problems.posture import (
    DEFAULT_MAX_ITER,
    DEFAULT_SCAN,
    DEFAULT_SMOOTHNESS,
    DEFAULT_TOL,
    OrientationRule,
    SolverSettings,
)
from problems.timing import (
    DT_DEFAULT_S,
    available_methods,
    controller_methods,
    default_methods,
    get_method,
    program_default_methods,
)
from problems.timing.registry import validate_options

# The timing methods a problem may name, those run when it names none, the default and largest
# controller period and each method's options are the registry's (problems.timing.registry).

#: ``[timing]`` keys that set a method's option (kept from before the ``[timing.<method>]``
#: tables): key -> (method, option).
TIMING_OPTION_KEYS: dict[str, tuple[str, str]] = {
    "toppra_gridpoints": ("toppra", "gridpoints"),
    "toppra_max_iterations": ("toppra", "max_iterations"),
    "ruckig_max_iterations": ("ruckig", "max_iterations"),
}
#: Default nominal TCP orientation: tool z axis pointing down (roll = 180 deg).
DEFAULT_RPY = np.array([math.pi, 0.0, 0.0])

_TOP = (
    "name",
    "description",
    "source",
    "robot",
    "path",
    "orientation",
    "wrench",
    "payload",
    "limits",
    "cost",
    "solver",
    "branch",
    "timing",
    "placement",
    "workpiece",
)
#: Frames a wrench may be given in.
WRENCH_FRAMES = ("base", "tool")
_TABLE_KEYS: dict[str, tuple[str, ...]] = {
    "robot": ("model", "tool"),
    "robot.tool": ("xyz", "rpy", "rpy_deg"),
    "path": ("kind", "start", "end", "points", "positions", "rpy", "rpy_deg", "file", "tolerance_mm"),
    "workpiece": ("xyz", "rpy", "rpy_deg"),
    "orientation": ("rule", "rpy", "rpy_deg", "axis", "half_angle", "half_angle_deg", "scan"),
    "wrench": ("frame", "force", "moment", "per_waypoint"),
    "payload": ("mass_kg", "com_m", "gravity_m_s2"),
    "limits": (
        "velocity",
        "acceleration",
        "jerk",
        "velocity_scale",
        "acceleration_scale",
        "jerk_scale",
        "max_joint_step",
        "max_joint_step_deg",
    ),
    "cost": ("smoothness",),
    "solver": ("name", "max_iter", "tol", "codegen"),
    "branch": ("home", "home_deg"),
    "timing": ("methods", "dt", "toppra_gridpoints", "toppra_max_iterations", "ruckig_max_iterations", "dynamic"),
}


class ProblemFileError(InputError):
    """A problem file is malformed; the message names the file, key, value and expectation."""


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


@dataclass(frozen=True)
class TimingSettings:
    """Time parametrisation: methods by name (registered in :mod:`problems.timing`), controller
    period (s) and method options.

    ``method_options`` holds the ``[timing.<method>]`` tables (option name -> value, as the
    method's ``options`` name them); ``toppra_gridpoints``, ``toppra_max_iterations`` and
    ``ruckig_max_iterations`` are the older flat keys of two of them (0: the method's default).
    """

    methods: tuple[str, ...] = field(default_factory=default_methods)
    dt: float = DT_DEFAULT_S
    toppra_gridpoints: int = 0  # 0: the timing module's default
    toppra_max_iterations: int = 0  # 0: default
    ruckig_max_iterations: int = 0  # 0: default
    dynamic: bool = False  # motor-side commands for the inertial torques (problems/dynamic.py)
    method_options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def options(self, method: str) -> dict[str, Any]:
        """Keyword options of ``method`` for ``problems.timing.time_parametrize``."""
        out: dict[str, Any] = {
            opt: getattr(self, key)
            for key, (m, opt) in TIMING_OPTION_KEYS.items()
            if m == method and getattr(self, key)
        }
        out.update(self.method_options.get(method, {}))
        return out


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


class PathSection(NamedTuple):
    """The ``[path]`` section.

    Attributes
    ----------
    kind : {"line", "waypoints", "gcode", "toolpath_csv"}
    line : tuple (start (3,), end (3,)) or None
        For ``line`` paths, m, base frame.
    positions : ndarray, shape (N, 3)
        TCP waypoints, m, base frame.
    rotations : ndarray, shape (N, 3, 3)
        Nominal base->TCP rotations (the path's own or the orientation's nominal one).
    program : problems.program_section.ProgramSection or None
        For a program path (``gcode``, ``toolpath_csv``): the program read and placed.
    """

    kind: str
    line: tuple[np.ndarray, np.ndarray] | None
    positions: np.ndarray
    rotations: np.ndarray
    program: Any = None


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
# Value helpers (every message: "<file>: key '<key>' ...")
# --------------------------------------------------------------------------------------


def _err(where: str, key: str, msg: str) -> ProblemFileError:
    return ProblemFileError(f"{where}: key '{key}' {msg}")


def _number(where: str, key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _err(where, key, f"must be a number, got {v!r}")
    f = float(v)
    if not math.isfinite(f):
        raise _err(where, key, f"must be finite, got {v!r}")
    return f


def _positive(where: str, key: str, v: Any) -> float:
    f = _number(where, key, v)
    if f <= 0.0:
        raise _err(where, key, f"must be > 0, got {v!r}")
    return f


def _integer(where: str, key: str, v: Any, lo: int, hi: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise _err(where, key, f"must be an integer {rng}, got {v!r}")
    return int(v)


def _vector(where: str, key: str, v: Any, n: int) -> np.ndarray:
    if not isinstance(v, list) or len(v) != n:
        raise _err(where, key, f"must be a list of {n} numbers, got {v!r}")
    return np.array([_number(where, f"{key}[{i}]", x) for i, x in enumerate(v)])


def _vector_or_scalar(where: str, key: str, v: Any, n: int) -> np.ndarray:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return np.full(n, _number(where, key, v))
    return _vector(where, key, v, n)


def _rows(where: str, key: str, v: Any, width: int) -> np.ndarray:
    if not isinstance(v, list) or not v:
        raise _err(where, key, f"must be a non-empty list of rows of {width} numbers, got {v!r}")
    out = np.empty((len(v), width))
    for i, row in enumerate(v):
        if not isinstance(row, list) or len(row) != width:
            raise ProblemFileError(f"{where}: key '{key}' row {i}: must be a list of {width} numbers, got {row!r}")
        for j, x in enumerate(row):
            out[i, j] = _number(where, f"{key}[{i}][{j}]", x)
    return out


def _table(where: str, data: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    parts = key.split(".")
    cur: Any = data
    for p in parts:
        cur = cur.get(p, {}) if isinstance(cur, Mapping) else None
        if not isinstance(cur, Mapping):
            raise _err(where, key, f"must be a table, got {cur!r}")
    allowed = _TABLE_KEYS[key] + (available_methods() if key == "timing" else ())  # [timing.<method>]
    unknown = sorted(set(cur) - set(allowed))
    if unknown:
        raise ProblemFileError(f"{where}: [{key}]: unknown key(s) {unknown}; allowed: {list(allowed)}")
    return cur


def _angle_pair(where: str, tab: Mapping[str, Any], key: str, prefix: str) -> tuple[Any, bool] | None:
    """The raw value of ``key`` (rad) or ``key_deg``, and whether it is in degrees."""
    has_rad, has_deg = key in tab, f"{key}_deg" in tab
    if has_rad and has_deg:
        raise ProblemFileError(f"{where}: give either '{prefix}{key}' (rad) or '{prefix}{key}_deg', not both")
    if has_deg:
        return tab[f"{key}_deg"], True
    if has_rad:
        return tab[key], False
    return None


def _rpy(where: str, tab: Mapping[str, Any], prefix: str) -> np.ndarray | None:
    got = _angle_pair(where, tab, "rpy", prefix)
    if got is None:
        return None
    raw, deg = got
    v = _vector(where, f"{prefix}rpy{'_deg' if deg else ''}", raw, 3)
    if not deg:
        _check_radians(where, f"{prefix}rpy", v, PLAUSIBLE_RPY_MAX_RAD, f"{prefix}rpy_deg")
    return np.radians(v) if deg else v


def _rotation_with_axis(axis: np.ndarray) -> np.ndarray:
    """A rotation whose z column is ``axis`` (x chosen deterministically)."""
    z = axis / np.linalg.norm(axis)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - z * (ref @ z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def _check_positions(where: str, key: str, P: np.ndarray) -> None:
    r = np.linalg.norm(P, axis=1)
    if np.any(r > PLAUSIBLE_POSITION_MAX_M):
        k = int(np.argmax(r))
        raise ProblemFileError(
            f"{where}: key '{key}' row {k}: position {P[k].tolist()} is {r[k]:.4g} m from the base "
            f"(> {PLAUSIBLE_POSITION_MAX_M:g} m); positions are in metres (millimetres given?)"
        )


#: An orientation angle (rpy) in radians beyond this magnitude is implausible: degrees given
#: under the radian key (one turn).
PLAUSIBLE_RPY_MAX_RAD = 2.0 * math.pi * (1.0 + 1e-9)
#: A joint angle (``branch.home``) or joint step in radians beyond this magnitude is
#: implausible (two turns for a joint angle, one turn for a step).
PLAUSIBLE_JOINT_MAX_RAD = 4.0 * math.pi * (1.0 + 1e-9)
PLAUSIBLE_JOINT_STEP_MAX_RAD = 2.0 * math.pi * (1.0 + 1e-9)


def _check_radians(where: str, key: str, values: np.ndarray, limit: float, deg_key: str) -> None:
    """Refuse radian values that are almost certainly degrees (|value| > ``limit``), naming the
    key, the value and the ``_deg`` key to use instead."""
    v = np.atleast_1d(np.asarray(values, dtype=float))
    bad = np.flatnonzero(np.abs(v) > limit)
    if bad.size:
        i = int(bad[0])
        raise _err(
            where,
            key,
            f"= {v.tolist() if v.size > 1 else float(v[0])} rad is implausible "
            f"(|{float(v[i]):g}| > {limit:.4g} rad): a key without '_deg' is in radians; "
            f"degrees given? use '{deg_key}'",
        )


def check_timing(where: str, t: TimingSettings) -> None:
    """Validate timing settings against the registry of timing methods: methods registered and
    non-empty, one the controller can run among them, ``dt`` in (0, the smallest ``dt_max_s`` of
    the methods] s, each method's options known to it and valid.

    Parameters
    ----------
    where : str
        The source, used in error messages.
    t : TimingSettings

    Raises
    ------
    ProblemFileError
        Naming ``timing.methods``, ``timing.dt`` or the option's key; an unknown method's message
        lists the registered ones.
    """
    valid = list(available_methods())
    if not t.methods:
        raise _err(where, "timing.methods", f"must name at least one of {valid}")
    for m in t.methods:
        if m not in valid:
            raise _err(where, "timing.methods", f"has unknown method {m!r}; valid: {valid}")
    if not controller_methods(t.methods):
        raise _err(
            where,
            "timing.methods",
            f"= {list(t.methods)} has no method whose trajectory the controller "
            f"can run; add one of {list(controller_methods())}",
        )
    dt_max = min(get_method(m).dt_max_s for m in t.methods)
    if not (0.0 < t.dt <= dt_max) or not math.isfinite(t.dt):
        raise _err(where, "timing.dt", f"must be in (0, {dt_max}] s, got {t.dt!r}")
    for m in dict.fromkeys([*t.methods, *t.method_options]):
        if m not in valid:
            raise ProblemFileError(f"{where}: [timing.{m}]: unknown method {m!r}; valid: {valid}")
        try:
            validate_options(get_method(m), t.options(m))
        except InputError as exc:  # name the flat [timing] key when the bad option came from one
            flat = [k for k, (mm, opt) in TIMING_OPTION_KEYS.items() if mm == m and getattr(t, k) and opt in str(exc)]
            key = f"timing.{flat[0]}" if flat else f"[timing.{m}]"
            raise ProblemFileError(f"{where}: {key}: {exc}") from None


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
        raise _err(where, "name", f"must be a non-empty string, got {name!r}")
    desc = data.get("description", "")
    src = data.get("source", "")
    for key, val in (("description", desc), ("source", src)):
        if not isinstance(val, str):
            raise _err(where, key, f"must be a string, got {val!r}")
    return Header(name.strip(), desc.strip(), src.strip())


def parse_robot(where: str, data: Mapping[str, Any], base_dir: Path | None) -> RobotSection:
    """The ``[robot]`` section: load the arm model and apply the tool.

    Parameters
    ----------
    base_dir : Path, optional
        Directory against which a relative ``robot.model`` path is resolved.
    """
    rt = _table(where, data, "robot")
    spec = rt.get("model")
    if not isinstance(spec, str) or not spec:
        raise _err(
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
        tt = _table(where, data, "robot.tool")
        xyz = _vector(where, "robot.tool.xyz", tt.get("xyz", [0.0, 0.0, 0.0]), 3)
        if np.max(np.abs(xyz)) > PLAUSIBLE_POSITION_MAX_M:
            raise _err(
                where,
                "robot.tool.xyz",
                f"= {xyz.tolist()} m is implausible for a tool (> "
                f"{PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres "
                "(millimetres given?)",
            )
        rpy = _rpy(where, tt, "robot.tool.")
        arm = arm.with_tool(transform(rpy_to_matrix(np.zeros(3) if rpy is None else rpy), xyz))
    return RobotSection(spec, arm)


def parse_orientation(where: str, data: Mapping[str, Any], program: bool = False) -> OrientationSection:
    """The ``[orientation]`` section: rule, nominal rotation (rpy or tool axis), cone, scan.

    ``program``: the path is a CAM program, which gives the tool axis: the rule defaults to
    ``free_tool_axis``, ``fixed`` and a nominal rotation are refused.
    """
    ot = _table(where, data, "orientation")
    if program:
        for key in ("rpy", "rpy_deg", "axis"):
            if key in ot:
                raise _err(
                    where, f"orientation.{key}", "does not apply to a program path (the program gives the tool axis)"
                )
        if ot.get("rule") == OrientationRule.FIXED.value:
            raise _err(
                where,
                "orientation.rule",
                "= 'fixed' does not apply to a program path: a program gives the tool axis, not the "
                "rotation about it; use 'free_tool_axis' (the default), 'cone' or 'position_only'",
            )
    rule_raw = ot.get("rule", OrientationRule.FREE_TOOL_AXIS.value if program else None)
    try:
        rule = OrientationRule(rule_raw)
    except ValueError:
        raise _err(
            where, "orientation.rule", f"must be one of {[r.value for r in OrientationRule]}, got {rule_raw!r}"
        ) from None
    rpy = _rpy(where, ot, "orientation.")
    if "axis" in ot:
        if rpy is not None:
            raise ProblemFileError(f"{where}: give either 'orientation.axis' or 'orientation.rpy'/'rpy_deg', not both")
        if rule is OrientationRule.FIXED:
            raise _err(
                where,
                "orientation.axis",
                "cannot define a fixed orientation (an axis leaves the "
                "rotation about it open); give orientation.rpy_deg",
            )
        ax = _vector(where, "orientation.axis", ot["axis"], 3)
        if np.linalg.norm(ax) < 1e-12:
            raise _err(where, "orientation.axis", f"must be a non-zero vector, got {ax.tolist()}")
        R_nom = _rotation_with_axis(ax)
        nominal_rpy = matrix_to_rpy(R_nom)
    else:
        nominal_rpy = DEFAULT_RPY.copy() if rpy is None else rpy
        R_nom = rpy_to_matrix(nominal_rpy)
    half = _cone_half_angle(where, ot, rule)
    scan = _integer(where, "orientation.scan", ot.get("scan", DEFAULT_SCAN), 1, 720)
    return OrientationSection(rule, np.asarray(nominal_rpy, float), R_nom, half, scan)


def _cone_half_angle(where: str, ot: Mapping[str, Any], rule: OrientationRule) -> float:
    """``orientation.half_angle`` (rad) / ``half_angle_deg``: required for, and only for, rule cone."""
    half = 0.0
    got = _angle_pair(where, ot, "half_angle", "orientation.")
    if rule is OrientationRule.CONE:
        if got is None:
            raise _err(where, "orientation.half_angle_deg", "is required for rule 'cone' (or half_angle, rad)")
        raw, deg = got
        key = f"orientation.half_angle{'_deg' if deg else ''}"
        given = _number(where, key, raw)
        half = math.radians(given) if deg else given
        if not 0.0 < half < math.pi / 2:
            rng = "(0, 90) deg" if deg else "(0, pi/2) rad, i.e. (0, 1.5708)"
            hint = "" if deg or given <= 0 else "; degrees given? use 'orientation.half_angle_deg'"
            raise _err(where, key, f"must be in {rng}, got {given:g}{' deg' if deg else ' rad'}{hint}")
    elif got is not None:
        raise _err(where, "orientation.half_angle", f"only applies to rule 'cone' (rule is '{rule.value}')")
    return half


def is_program_path(data: Mapping[str, Any]) -> bool:
    """Whether the document's path is a program file (``[path] kind`` in ``PROGRAM_KINDS``)."""
    from problems.program_section import PROGRAM_KINDS

    pt = data.get("path") if isinstance(data, Mapping) else None
    return isinstance(pt, Mapping) and pt.get("kind") in PROGRAM_KINDS


def parse_path(
    where: str, data: Mapping[str, Any], R_nom: np.ndarray, base_dir: Path | None = None, robot: Robot | None = None
) -> PathSection:
    """The ``[path]`` section: a line, explicit waypoints, or a program file (with ``[workpiece]``).

    Parameters
    ----------
    R_nom : ndarray, shape (3, 3)
        The orientation's nominal base->TCP rotation, used where the path gives none.
    base_dir : Path, optional
        Directory against which a relative ``path.file`` is resolved.
    robot : Robot, optional
        The robot with its tool: a program point beyond its reach is refused with ``file:line``.
    """
    from problems.program_section import PROGRAM_KINDS, check_reach, parse_program

    pt = _table(where, data, "path")
    kind = pt.get("kind")
    if kind != "gcode" and kind != "toolpath_csv" and "workpiece" in data:
        raise _err(where, "workpiece", f"only applies to a program path (kind {list(PROGRAM_KINDS)}); kind is {kind!r}")
    for key in ("file", "tolerance_mm"):
        if key in pt and kind not in PROGRAM_KINDS:
            raise _err(where, f"path.{key}", f"only applies to kinds {list(PROGRAM_KINDS)}")
    if kind == "line":
        return _line_path(where, pt, R_nom)
    if kind == "waypoints":
        return _waypoints_path(where, pt, R_nom)
    if kind in PROGRAM_KINDS:
        wt = _table(where, data, "workpiece") if "workpiece" in data else None
        sec = parse_program(where, pt, wt, base_dir, _err, lambda t, prefix: _rpy(where, t, prefix))
        if robot is not None:
            check_reach(sec, robot)
        return PathSection(kind, None, sec.positions, sec.rotations, sec)
    raise _err(where, "path.kind", f"must be one of {['line', 'waypoints', *PROGRAM_KINDS]}, got {kind!r}")


def _line_path(where: str, pt: Mapping[str, Any], R_nom: np.ndarray) -> PathSection:
    """A ``kind = "line"`` path: ``points`` waypoints from ``start`` to ``end`` (m, base frame)."""
    for key in ("positions", "rpy", "rpy_deg"):
        if key in pt:
            raise _err(where, f"path.{key}", "only applies to kind 'waypoints'")
    for key in ("start", "end", "points"):
        if key not in pt:
            raise _err(where, f"path.{key}", "is required for kind 'line'")
    start = _vector(where, "path.start", pt["start"], 3)
    end = _vector(where, "path.end", pt["end"], 3)
    n = _integer(where, "path.points", pt["points"], 2)
    _check_positions(where, "path.start/end", np.vstack([start, end]))
    if np.linalg.norm(end - start) < 1e-9:
        raise _err(where, "path.end", f"equals path.start {start.tolist()}; a line needs two distinct points")
    P = line_positions(start, end, n)
    R = np.broadcast_to(R_nom, (n, 3, 3)).copy()
    return PathSection("line", (start, end), P, R)


def _waypoints_path(where: str, pt: Mapping[str, Any], R_nom: np.ndarray) -> PathSection:
    """A ``kind = "waypoints"`` path: explicit positions (m) and optional per-row rpy."""
    for key in ("start", "end", "points"):
        if key in pt:
            raise _err(where, f"path.{key}", "only applies to kind 'line'")
    if "positions" not in pt:
        raise _err(where, "path.positions", "is required for kind 'waypoints'")
    P = _rows(where, "path.positions", pt["positions"], 3)
    n = len(P)
    _check_positions(where, "path.positions", P)
    got = _angle_pair(where, pt, "rpy", "path.")
    if got is not None:
        raw, deg = got
        key = f"path.rpy{'_deg' if deg else ''}"
        A = _rows(where, key, raw, 3)
        if len(A) != n:
            raise _err(where, key, f"has {len(A)} rows but path.positions has {n}")
        if not deg:
            for i, row in enumerate(A):
                _check_radians(where, f"path.rpy[{i}]", row, PLAUSIBLE_RPY_MAX_RAD, "path.rpy_deg")
        R = np.stack([rpy_to_matrix(np.radians(a) if deg else a) for a in A])
    else:
        R = np.broadcast_to(R_nom, (n, 3, 3)).copy()
    return PathSection("waypoints", None, P, R)


def parse_wrench(where: str, data: Mapping[str, Any], n: int, tool_rows: np.ndarray | None = None) -> WrenchSection:
    """The ``[wrench]`` section: frame, and a constant force/moment or one row per waypoint.

    Parameters
    ----------
    n : int
        Number of waypoints N of the path.
    tool_rows : ndarray, shape (N, 6), optional
        A per-waypoint wrench in the TCP frame from the path itself (CL data with wrench columns):
        then ``[wrench]`` must be absent.
    """
    if tool_rows is not None:
        if "wrench" in data:
            raise _err(
                where, "wrench", "must be absent: the path's CL file gives the wrench per point (fx_N ... mz_Nm)"
            )
        _check_wrench(where, "wrench.per_waypoint", tool_rows)
        return WrenchSection("tool", np.asarray(tool_rows, dtype=float), True)
    wt = _table(where, data, "wrench")
    frame = wt.get("frame", "base")
    if frame not in WRENCH_FRAMES:
        raise _err(
            where,
            "wrench.frame",
            f"must be one of {list(WRENCH_FRAMES)} (base frame, or the TCP frame turning with the tool), got {frame!r}",
        )
    if "per_waypoint" in wt:
        if "force" in wt or "moment" in wt:
            raise ProblemFileError(f"{where}: give either 'wrench.per_waypoint' or 'wrench.force'/'moment', not both")
        W = _rows(where, "wrench.per_waypoint", wt["per_waypoint"], 6)
        if len(W) != n:
            raise _err(where, "wrench.per_waypoint", f"has {len(W)} rows but the path has {n} waypoints")
        _check_wrench(where, "wrench.per_waypoint", W)
        return WrenchSection(frame, W, True)
    if "force" not in wt:
        raise _err(where, "wrench.force", "is required (or wrench.per_waypoint), in N")
    f = _vector(where, "wrench.force", wt["force"], 3)
    m = _vector(where, "wrench.moment", wt.get("moment", [0.0, 0.0, 0.0]), 3)
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
            raise _err(
                where,
                k,
                f"= {float(W[i, j + cols.start]):g} {unit} is implausible (|value| above "
                f"{limit:g} {unit}); the {name} is in {unit}",
            )


def parse_payload(where: str, data: Mapping[str, Any]) -> PayloadSection:
    """The ``[payload]`` section: mass (kg), centre of mass (TCP frame, m), optional gravity."""
    pt = _table(where, data, "payload")
    p_mass, p_com, p_grav = 0.0, np.zeros(3), None
    if pt:
        if "mass_kg" not in pt:
            raise _err(where, "payload.mass_kg", "is required in a [payload] table (kg)")
        p_mass = _number(where, "payload.mass_kg", pt["mass_kg"])
        if p_mass < 0:
            raise _err(where, "payload.mass_kg", f"must be >= 0 kg, got {p_mass!r}")
        p_com = _vector(where, "payload.com_m", pt.get("com_m", [0.0, 0.0, 0.0]), 3)
        if np.max(np.abs(p_com)) > PLAUSIBLE_POSITION_MAX_M:
            raise _err(
                where,
                "payload.com_m",
                f"= {p_com.tolist()} m is implausible (> {PLAUSIBLE_POSITION_MAX_M:g} m; millimetres given?)",
            )
        if "gravity_m_s2" in pt:
            p_grav = _vector(where, "payload.gravity_m_s2", pt["gravity_m_s2"], 3)
    return PayloadSection(p_mass, p_com, p_grav)


def parse_limits(where: str, data: Mapping[str, Any], robot: Robot) -> Limits:
    """The ``[limits]`` section: joint limits (absolute or scaling the robot's) and joint step.

    Parameters
    ----------
    robot : Robot
        Supplies the default velocity, acceleration and jerk limits (rad/s, rad/s^2, rad/s^3).
    """
    lt = _table(where, data, "limits")
    lims = {}
    for key, base in (("velocity", robot.v_max), ("acceleration", robot.a_max), ("jerk", robot.j_max)):
        if key in lt and f"{key}_scale" in lt:
            raise ProblemFileError(f"{where}: give either 'limits.{key}' or 'limits.{key}_scale', not both")
        if key in lt:
            v = _vector_or_scalar(where, f"limits.{key}", lt[key], 6)
            bad = np.where(v <= 0)[0]
            if bad.size:
                raise ProblemFileError(
                    f"{where}: key 'limits.{key}' joint {int(bad[0]) + 1}: must be > 0, got {float(v[bad[0]]):g}"
                )
        elif f"{key}_scale" in lt:
            s = _positive(where, f"limits.{key}_scale", lt[f"{key}_scale"])
            v = base * s
        else:
            v = base.copy()
        lims[key] = v
    got = _angle_pair(where, lt, "max_joint_step", "limits.")
    if got is None:
        step = MAX_JOINT_STEP
    else:
        raw, deg = got
        step = _positive(where, f"limits.max_joint_step{'_deg' if deg else ''}", raw)
        if not deg:
            _check_radians(
                where,
                "limits.max_joint_step",
                np.array([step]),
                PLAUSIBLE_JOINT_STEP_MAX_RAD,
                "limits.max_joint_step_deg",
            )
        step = math.radians(step) if deg else step
    return Limits(lims["velocity"], lims["acceleration"], lims["jerk"], step)


def parse_cost(where: str, data: Mapping[str, Any]) -> float:
    """The ``[cost]`` section: the smoothness weight, mm^2/rad^2 (>= 0)."""
    ct = _table(where, data, "cost")
    smooth = _number(where, "cost.smoothness", ct.get("smoothness", DEFAULT_SMOOTHNESS))
    if smooth < 0:
        raise _err(where, "cost.smoothness", f"must be >= 0 (mm^2/rad^2), got {smooth!r}")
    return smooth


def parse_solver(where: str, data: Mapping[str, Any]) -> SolverSettings:
    """The ``[solver]`` section: NLP solver name (only ``ipopt``), iterations, tolerance, codegen."""
    st = _table(where, data, "solver")
    sname = st.get("name", "ipopt")
    if sname != "ipopt":
        raise _err(where, "solver.name", f"must be 'ipopt' (the only NLP solver available), got {sname!r}")
    codegen = st.get("codegen", True)
    if not isinstance(codegen, bool):
        raise _err(where, "solver.codegen", f"must be true or false, got {codegen!r}")
    return SolverSettings(
        name=sname,
        max_iter=_integer(where, "solver.max_iter", st.get("max_iter", DEFAULT_MAX_ITER), 0),
        tol=_positive(where, "solver.tol", st.get("tol", DEFAULT_TOL)),
        codegen=codegen,
    )


def parse_branch(where: str, data: Mapping[str, Any]) -> np.ndarray:
    """The ``[branch]`` section: the home configuration choosing the IK branch.

    Returns
    -------
    ndarray, shape (6,)
        Joint angles, rad (the paper's home pose if absent).
    """
    bt = _table(where, data, "branch")
    got = _angle_pair(where, bt, "home", "branch.")
    if got is None:
        return paper.HOME_Q.copy()
    raw, deg = got
    home = _vector(where, f"branch.home{'_deg' if deg else ''}", raw, 6)
    if not deg:
        _check_radians(where, "branch.home", home, PLAUSIBLE_JOINT_MAX_RAD, "branch.home_deg")
    return np.radians(home) if deg else home


def _method_tables(where: str, tt: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The ``[timing.<method>]`` tables of ``[timing]``: method -> option -> value, each name
    known to the method (values are checked by :func:`check_timing`)."""
    out: dict[str, dict[str, Any]] = {}
    for m in available_methods():
        if m not in tt:
            continue
        tab, spec = tt[m], get_method(m)
        if not isinstance(tab, Mapping):
            raise _err(where, f"timing.{m}", f"must be a table of {m}'s options {list(spec.options)}, got {tab!r}")
        unknown = sorted(set(tab) - set(spec.options))
        if unknown:
            raise ProblemFileError(f"{where}: [timing.{m}]: unknown key(s) {unknown}; allowed: {list(spec.options)}")
        for key, (method, opt) in TIMING_OPTION_KEYS.items():
            if method == m and opt in tab and tt.get(key):
                raise ProblemFileError(f"{where}: give either 'timing.{key}' or 'timing.{m}.{opt}', not both")
        out[m] = dict(tab)
    return out


def parse_timing(where: str, data: Mapping[str, Any], program: bool = False) -> TimingSettings:
    """The ``[timing]`` section: methods (registered in :mod:`problems.timing`), controller period
    (s), method options (``[timing.<method>]`` tables and the older flat keys). ``program``: the path
    is a CAM program (the default methods are then :func:`~problems.timing.program_default_methods`)."""
    tt = _table(where, data, "timing")
    methods = tt.get("methods", list(program_default_methods() if program else default_methods()))
    if not isinstance(methods, list) or not all(isinstance(m, str) for m in methods):
        raise _err(
            where, "timing.methods", f"must be a list of method names {list(available_methods())}, got {methods!r}"
        )
    timing = TimingSettings(
        methods=tuple(methods),
        dt=_positive(where, "timing.dt", tt.get("dt", DT_DEFAULT_S)),
        toppra_gridpoints=_integer(where, "timing.toppra_gridpoints", tt.get("toppra_gridpoints", 0), 0),
        toppra_max_iterations=_integer(where, "timing.toppra_max_iterations", tt.get("toppra_max_iterations", 0), 0),
        ruckig_max_iterations=_integer(where, "timing.ruckig_max_iterations", tt.get("ruckig_max_iterations", 0), 0),
        dynamic=tt.get("dynamic", False),
        method_options=_method_tables(where, tt),
    )
    if not isinstance(timing.dynamic, bool):
        raise _err(where, "timing.dynamic", f"must be true or false, got {timing.dynamic!r}")
    check_timing(where, timing)
    return timing


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
        raise _err(where, "placement", f"must be a table, got {tab!r}")
    try:
        return grid_from_table(tab, f"{where}: [placement]")
    except PlacementGridError as exc:
        raise ProblemFileError(str(exc)) from None
