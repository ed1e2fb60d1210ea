"""Problem files: a planning problem as data (TOML), validated.

A problem names the robot and tool, the path, the orientation rule, the load,
the limits, the cost weights, the NLP solver and the time-parametrisation
settings.  The format is documented in ``docs/problem-file.md``; the shipped
problems live in ``problems/files/*.toml`` and are loaded by name.

Every error names the file, the key (dotted, e.g. ``path.points``) and, for
tables of rows, the row; the value found; and what was expected.  All values
are converted to SI units (m, rad, N, N*m, s) on loading.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from models.arm import ArmModel, load_arm
from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError
from models.load import Load
from models.robot import BUILTIN_ROBOTS, Robot, RobotFileError
from models.transforms import matrix_to_rpy, rpy_to_matrix, transform
from problems import paper
from problems.path import MAX_JOINT_STEP, line_positions
from problems.posture import (DEFAULT_MAX_ITER, DEFAULT_SCAN, DEFAULT_SMOOTHNESS, DEFAULT_TOL,
                              OrientationRule, PostureTask, SolverSettings)

#: Time-parametrisation methods a problem may name (see planner.timing).
TIMING_METHODS = ("toppra", "ruckig")
#: Default controller period, s.
DEFAULT_DT = 0.008
#: Largest accepted controller period, s.
DT_MAX = 0.1
#: Largest accepted number of waypoints (keeps an NLP at a sane size).
MAX_WAYPOINTS = 2000
#: Default nominal TCP orientation: tool z axis pointing down (roll = 180 deg).
DEFAULT_RPY = np.array([math.pi, 0.0, 0.0])

_TOP = ("name", "description", "source", "robot", "path", "orientation", "wrench", "payload", "limits",
        "cost", "solver", "branch", "timing")
#: Frames a wrench may be given in.
WRENCH_FRAMES = ("base", "tool")
_TABLE_KEYS: dict[str, tuple[str, ...]] = {
    "robot": ("model", "tool"),
    "robot.tool": ("xyz", "rpy", "rpy_deg"),
    "path": ("kind", "start", "end", "points", "positions", "rpy", "rpy_deg"),
    "orientation": ("rule", "rpy", "rpy_deg", "axis", "half_angle", "half_angle_deg", "scan"),
    "wrench": ("frame", "force", "moment", "per_waypoint"),
    "payload": ("mass_kg", "com_m", "gravity_m_s2"),
    "limits": ("velocity", "acceleration", "jerk", "velocity_scale", "acceleration_scale",
               "jerk_scale", "max_joint_step", "max_joint_step_deg"),
    "cost": ("smoothness",),
    "solver": ("name", "max_iter", "tol", "codegen"),
    "branch": ("home", "home_deg"),
    "timing": ("methods", "dt", "toppra_gridpoints", "toppra_max_iterations",
               "ruckig_max_iterations"),
}


class ProblemFileError(InputError):
    """A problem file is malformed; the message names the file, key, value and expectation."""


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
    """Time parametrisation: methods by name, controller period and method options."""

    methods: tuple[str, ...] = TIMING_METHODS
    dt: float = DEFAULT_DT
    toppra_gridpoints: int = 0          # 0: the timing module's default
    toppra_max_iterations: int = 0      # 0: default
    ruckig_max_iterations: int = 0      # 0: default

    def options(self, method: str) -> dict[str, int]:
        """Keyword options for ``planner.timing.time_parametrize``."""
        out: dict[str, int] = {}
        if method == "toppra":
            if self.toppra_gridpoints:
                out["gridpoints"] = self.toppra_gridpoints
            if self.toppra_max_iterations:
                out["max_iterations"] = self.toppra_max_iterations
        elif method == "ruckig" and self.ruckig_max_iterations:
            out["max_iterations"] = self.ruckig_max_iterations
        return out


@dataclass(frozen=True)
class Problem:
    """A validated planning problem (SI units, base frame).

    Attributes
    ----------
    name, description, source : str
        ``source`` is where it was read from (file path or shipped name).
    robot_spec : str
        The robot as named in the file (built-in name or resolved path).
    robot : Robot
        With the problem's tool applied.
    path_kind : {"line", "waypoints"}
    line : tuple (start (3,), end (3,)) or None
        For ``line`` paths, m.
    positions : ndarray, shape (N, 3)
        TCP waypoints, m.
    rotations : ndarray, shape (N, 3, 3)
        Nominal base->TCP rotations.
    rule : OrientationRule
    cone_half_angle : float
        rad (rule ``cone``), else 0.
    scan : int
        Scanned rotations about the tool axis for the warm starts.
    wrench : ndarray, shape (N, 6)
        [N, N*m] on the TCP, in the frame ``wrench_frame``.
    wrench_per_waypoint : bool
    wrench_frame : {"base", "tool"}
        ``tool``: the TCP frame (the wrench turns with the tool along the path).
    payload_mass_kg : float
    payload_com_m : ndarray, shape (3,)
        Payload centre of mass, TCP frame, m.
    gravity : ndarray, shape (3,)
        Gravity acting on the payload, base frame, m/s^2.
    arm : ArmModel
        The arm model (chain and deflection model) with the problem's tool; ``robot`` is
        its description.
    limits : Limits
    smoothness : float
        mm^2/rad^2.
    solver : SolverSettings
    home_q : ndarray, shape (6,)
        rad.
    timing : TimingSettings
    """

    name: str
    description: str
    source: str
    robot_spec: str
    robot: Robot
    path_kind: str
    line: tuple[np.ndarray, np.ndarray] | None
    positions: np.ndarray
    rotations: np.ndarray
    rule: OrientationRule
    cone_half_angle: float
    scan: int
    wrench: np.ndarray
    wrench_per_waypoint: bool
    limits: Limits
    smoothness: float
    solver: SolverSettings
    home_q: np.ndarray
    timing: TimingSettings
    nominal_rpy: np.ndarray = field(default_factory=lambda: DEFAULT_RPY.copy())
    wrench_frame: str = "base"
    payload_mass_kg: float = 0.0
    payload_com_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gravity: np.ndarray | None = None
    arm: ArmModel | None = None
    #: The file's own ``source`` text (where the task comes from); ``source`` above is
    #: where the file was read from.
    source_text: str = ""

    @property
    def n(self) -> int:
        """Number of waypoints N."""
        return int(len(self.positions))

    @property
    def model(self) -> ArmModel:
        """The arm model the problem is planned with (the robot file's nominal one unless
        the file, or ``--robot``, names an identified model)."""
        return self.arm if self.arm is not None else ArmModel.from_robot(self.robot)

    @property
    def load(self) -> Load:
        """The load on the TCP: the wrench (in its frame) plus the payload."""
        g = self.robot.gravity if self.gravity is None else self.gravity
        W = self.wrench
        return Load(wrench_base=W if self.wrench_frame == "base" else np.zeros(6),
                    wrench_tool=W if self.wrench_frame == "tool" else np.zeros(6),
                    payload_mass_kg=self.payload_mass_kg, payload_com_m=self.payload_com_m, gravity=g)

    def task(self) -> PostureTask:
        """The posture task of this problem."""
        return PostureTask(self.positions, self.rotations, self.rule, self.load.rows(self.n),
                           cone_half_angle=self.cone_half_angle,
                           max_joint_step=self.limits.max_joint_step,
                           smoothness=self.smoothness, scan=self.scan)

    def with_points(self, n: int) -> "Problem":
        """The same line path re-sampled with ``n`` points (line paths only)."""
        if self.path_kind != "line" or self.line is None:
            raise ProblemFileError(f"{self.source}: key 'path.points' can only be changed for a line path "
                                   f"(this path is '{self.path_kind}')")
        if self.wrench_per_waypoint:
            raise ProblemFileError(f"{self.source}: cannot re-sample a path with a per-waypoint wrench")
        if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= MAX_WAYPOINTS:
            raise ProblemFileError(f"{self.source}: path.points must be an integer in [2, {MAX_WAYPOINTS}], "
                                   f"got {n!r}")
        P = line_positions(self.line[0], self.line[1], n)
        R = np.broadcast_to(self.rotations[0], (n, 3, 3)).copy()
        W = np.broadcast_to(self.wrench[0], (n, 6)).copy()
        return replace(self, positions=P, rotations=R, wrench=W)

    def with_robot(self, robot_spec: "str | ArmModel") -> "Problem":
        """The same problem on another arm model (built-in name, robot file, identified model
        file, or an :class:`ArmModel`), keeping the problem's tool."""
        arm = load_arm(robot_spec).with_tool(self.robot.flange2tcp)
        spec = robot_spec if isinstance(robot_spec, str) else (arm.source or arm.name)
        return replace(self, robot_spec=str(spec), robot=arm.nominal, arm=arm)

    def with_timing(self, **changes: Any) -> "Problem":
        """The same problem with other timing settings (e.g. ``dt=0.002``)."""
        t = replace(self.timing, **changes)
        _check_timing(self.source, t)
        return replace(self, timing=t)

    def to_dict(self) -> dict[str, Any]:
        """The problem as a dictionary in the problem-file schema (SI units, radians)."""
        T = self.robot.flange2tcp
        d: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "source": self.source_text,
            "robot": {"model": self.robot_spec,
                      "tool": {"xyz": [float(v) for v in T[:3, 3]],
                               "rpy": [float(v) for v in matrix_to_rpy(T[:3, :3])]}},
        }
        if self.path_kind == "line" and self.line is not None:
            d["path"] = {"kind": "line", "start": [float(v) for v in self.line[0]],
                         "end": [float(v) for v in self.line[1]], "points": self.n}
        else:
            d["path"] = {"kind": "waypoints", "positions": self.positions.tolist(),
                         "rpy": [matrix_to_rpy(R).tolist() for R in self.rotations]}
        o: dict[str, Any] = {"rule": self.rule.value, "rpy": [float(v) for v in self.nominal_rpy],
                             "scan": self.scan}
        if self.rule is OrientationRule.CONE:
            o["half_angle"] = self.cone_half_angle
        d["orientation"] = o
        if self.wrench_per_waypoint:
            d["wrench"] = {"frame": self.wrench_frame, "per_waypoint": self.wrench.tolist()}
        else:
            d["wrench"] = {"frame": self.wrench_frame, "force": self.wrench[0, :3].tolist(),
                           "moment": self.wrench[0, 3:].tolist()}
        if self.payload_mass_kg:
            d["payload"] = {"mass_kg": float(self.payload_mass_kg),
                            "com_m": [float(v) for v in self.payload_com_m]}
            if self.gravity is not None:
                d["payload"]["gravity_m_s2"] = [float(v) for v in self.gravity]
        d["limits"] = {"velocity": self.limits.velocity.tolist(),
                       "acceleration": self.limits.acceleration.tolist(),
                       "jerk": self.limits.jerk.tolist(), "max_joint_step": self.limits.max_joint_step}
        d["cost"] = {"smoothness": self.smoothness}
        d["solver"] = {"name": self.solver.name, "max_iter": self.solver.max_iter, "tol": self.solver.tol,
                       "codegen": self.solver.codegen}
        d["branch"] = {"home": self.home_q.tolist()}
        d["timing"] = {"methods": list(self.timing.methods), "dt": self.timing.dt,
                       "toppra_gridpoints": self.timing.toppra_gridpoints,
                       "toppra_max_iterations": self.timing.toppra_max_iterations,
                       "ruckig_max_iterations": self.timing.ruckig_max_iterations}
        return d


# --------------------------------------------------------------------------------------
# Parsing helpers (every message: "<file>: key '<key>' ...")
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
            raise ProblemFileError(f"{where}: key '{key}' row {i}: must be a list of {width} numbers, "
                                   f"got {row!r}")
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
    unknown = sorted(set(cur) - set(_TABLE_KEYS[key]))
    if unknown:
        raise ProblemFileError(f"{where}: [{key}]: unknown key(s) {unknown}; allowed: "
                               f"{list(_TABLE_KEYS[key])}")
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
            f"(> {PLAUSIBLE_POSITION_MAX_M:g} m); positions are in metres (millimetres given?)")


def _check_timing(where: str, t: TimingSettings) -> None:
    if not t.methods:
        raise _err(where, "timing.methods", f"must name at least one of {list(TIMING_METHODS)}")
    for m in t.methods:
        if m not in TIMING_METHODS:
            raise _err(where, "timing.methods", f"has unknown method {m!r}; valid: {list(TIMING_METHODS)}")
    if not (0.0 < t.dt <= DT_MAX) or not math.isfinite(t.dt):
        raise _err(where, "timing.dt", f"must be in (0, {DT_MAX}] s, got {t.dt!r}")


# --------------------------------------------------------------------------------------
# The loader
# --------------------------------------------------------------------------------------

def problem_from_dict(data: Mapping[str, Any], where: str = "problem",
                      base_dir: Path | None = None) -> Problem:
    """Build and validate a :class:`Problem` from a parsed problem file.

    Parameters
    ----------
    data : mapping
        The parsed TOML document (see ``docs/problem-file.md``).
    where : str
        The source, used in error messages (usually the file path).
    base_dir : Path, optional
        Directory against which a relative ``robot.model`` path is resolved.

    Raises
    ------
    ProblemFileError
        Naming the file, the key (and row), the value and the expectation.
    """
    if not isinstance(data, Mapping):
        raise ProblemFileError(f"{where}: expected a table at top level")
    unknown = sorted(set(data) - set(_TOP))
    if unknown:
        raise ProblemFileError(f"{where}: unknown top-level key(s) {unknown}; allowed: {list(_TOP)}")
    name = data.get("name")
    if not isinstance(name, str) or not name.strip():
        raise _err(where, "name", f"must be a non-empty string, got {name!r}")
    desc = data.get("description", "")
    src = data.get("source", "")
    for key, val in (("description", desc), ("source", src)):
        if not isinstance(val, str):
            raise _err(where, key, f"must be a string, got {val!r}")

    # --- robot and tool
    rt = _table(where, data, "robot")
    spec = rt.get("model")
    if not isinstance(spec, str) or not spec:
        raise _err(where, "robot.model", f"must be a built-in robot name {list(BUILTIN_ROBOTS)} or a "
                                         f"robot file path, got {spec!r}")
    if spec not in BUILTIN_ROBOTS and base_dir is not None and not Path(spec).is_absolute():
        spec = str((base_dir / spec).resolve())
    try:
        arm = load_arm(spec)
    except RobotFileError as exc:
        raise ProblemFileError(f"{where}: key 'robot.model': {exc}") from None
    if "tool" in rt:
        tt = _table(where, data, "robot.tool")
        xyz = _vector(where, "robot.tool.xyz", tt.get("xyz", [0.0, 0.0, 0.0]), 3)
        rpy = _rpy(where, tt, "robot.tool.")
        arm = arm.with_tool(transform(rpy_to_matrix(np.zeros(3) if rpy is None else rpy), xyz))
    robot = arm.nominal

    # --- orientation (needed for per-waypoint defaults)
    ot = _table(where, data, "orientation")
    rule_raw = ot.get("rule")
    try:
        rule = OrientationRule(rule_raw)
    except ValueError:
        raise _err(where, "orientation.rule", f"must be one of {[r.value for r in OrientationRule]}, "
                                              f"got {rule_raw!r}") from None
    rpy = _rpy(where, ot, "orientation.")
    if "axis" in ot:
        if rpy is not None:
            raise ProblemFileError(f"{where}: give either 'orientation.axis' or 'orientation.rpy'/'rpy_deg', "
                                   "not both")
        if rule is OrientationRule.FIXED:
            raise _err(where, "orientation.axis", "cannot define a fixed orientation (an axis leaves the "
                                                  "rotation about it open); give orientation.rpy_deg")
        ax = _vector(where, "orientation.axis", ot["axis"], 3)
        if np.linalg.norm(ax) < 1e-12:
            raise _err(where, "orientation.axis", f"must be a non-zero vector, got {ax.tolist()}")
        R_nom = _rotation_with_axis(ax)
        nominal_rpy = matrix_to_rpy(R_nom)
    else:
        nominal_rpy = DEFAULT_RPY.copy() if rpy is None else rpy
        R_nom = rpy_to_matrix(nominal_rpy)
    half = 0.0
    got = _angle_pair(where, ot, "half_angle", "orientation.")
    if rule is OrientationRule.CONE:
        if got is None:
            raise _err(where, "orientation.half_angle_deg", "is required for rule 'cone' (or half_angle, rad)")
        raw, deg = got
        half = _number(where, f"orientation.half_angle{'_deg' if deg else ''}", raw)
        half = math.radians(half) if deg else half
        if not 0.0 < half < math.pi / 2:
            raise _err(where, "orientation.half_angle_deg", f"must be in (0, 90) deg, got "
                                                            f"{math.degrees(half):g} deg")
    elif got is not None:
        raise _err(where, "orientation.half_angle", f"only applies to rule 'cone' (rule is '{rule.value}')")
    scan = _integer(where, "orientation.scan", ot.get("scan", DEFAULT_SCAN), 1, 720)

    # --- path
    pt = _table(where, data, "path")
    kind = pt.get("kind")
    line = None
    if kind == "line":
        for key in ("positions", "rpy", "rpy_deg"):
            if key in pt:
                raise _err(where, f"path.{key}", "only applies to kind 'waypoints'")
        for key in ("start", "end", "points"):
            if key not in pt:
                raise _err(where, f"path.{key}", "is required for kind 'line'")
        start = _vector(where, "path.start", pt["start"], 3)
        end = _vector(where, "path.end", pt["end"], 3)
        n = _integer(where, "path.points", pt["points"], 2, MAX_WAYPOINTS)
        _check_positions(where, "path.start/end", np.vstack([start, end]))
        if np.linalg.norm(end - start) < 1e-9:
            raise _err(where, "path.end", f"equals path.start {start.tolist()}; a line needs two distinct points")
        P = line_positions(start, end, n)
        line = (start, end)
        R = np.broadcast_to(R_nom, (n, 3, 3)).copy()
    elif kind == "waypoints":
        for key in ("start", "end", "points"):
            if key in pt:
                raise _err(where, f"path.{key}", "only applies to kind 'line'")
        if "positions" not in pt:
            raise _err(where, "path.positions", "is required for kind 'waypoints'")
        P = _rows(where, "path.positions", pt["positions"], 3)
        n = len(P)
        if n > MAX_WAYPOINTS:
            raise _err(where, "path.positions", f"has {n} rows; at most {MAX_WAYPOINTS}")
        _check_positions(where, "path.positions", P)
        got = _angle_pair(where, pt, "rpy", "path.")
        if got is not None:
            raw, deg = got
            key = f"path.rpy{'_deg' if deg else ''}"
            A = _rows(where, key, raw, 3)
            if len(A) != n:
                raise _err(where, key, f"has {len(A)} rows but path.positions has {n}")
            R = np.stack([rpy_to_matrix(np.radians(a) if deg else a) for a in A])
        else:
            R = np.broadcast_to(R_nom, (n, 3, 3)).copy()
    else:
        raise _err(where, "path.kind", f"must be 'line' or 'waypoints', got {kind!r}")

    # --- wrench
    wt = _table(where, data, "wrench")
    frame = wt.get("frame", "base")
    if frame not in WRENCH_FRAMES:
        raise _err(where, "wrench.frame", f"must be one of {list(WRENCH_FRAMES)} (base frame, or the TCP frame "
                                          f"turning with the tool), got {frame!r}")
    if "per_waypoint" in wt:
        if "force" in wt or "moment" in wt:
            raise ProblemFileError(f"{where}: give either 'wrench.per_waypoint' or 'wrench.force'/'moment', "
                                   "not both")
        W = _rows(where, "wrench.per_waypoint", wt["per_waypoint"], 6)
        if len(W) != n:
            raise _err(where, "wrench.per_waypoint", f"has {len(W)} rows but the path has {n} waypoints")
        per_wp = True
    else:
        if "force" not in wt:
            raise _err(where, "wrench.force", "is required (or wrench.per_waypoint), in N")
        f = _vector(where, "wrench.force", wt["force"], 3)
        m = _vector(where, "wrench.moment", wt.get("moment", [0.0, 0.0, 0.0]), 3)
        W = np.broadcast_to(np.r_[f, m], (n, 6)).copy()
        per_wp = False

    # --- payload
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
            raise _err(where, "payload.com_m", f"= {p_com.tolist()} m is implausible (> "
                                               f"{PLAUSIBLE_POSITION_MAX_M:g} m; millimetres given?)")
        if "gravity_m_s2" in pt:
            p_grav = _vector(where, "payload.gravity_m_s2", pt["gravity_m_s2"], 3)

    # --- limits
    lt = _table(where, data, "limits")
    lims = {}
    for key, base in (("velocity", robot.v_max), ("acceleration", robot.a_max), ("jerk", robot.j_max)):
        if key in lt and f"{key}_scale" in lt:
            raise ProblemFileError(f"{where}: give either 'limits.{key}' or 'limits.{key}_scale', not both")
        if key in lt:
            v = _vector_or_scalar(where, f"limits.{key}", lt[key], 6)
            bad = np.where(v <= 0)[0]
            if bad.size:
                raise ProblemFileError(f"{where}: key 'limits.{key}' joint {bad[0] + 1}: must be > 0, "
                                       f"got {v[bad[0]]!r}")
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
        step = math.radians(step) if deg else step
    limits = Limits(lims["velocity"], lims["acceleration"], lims["jerk"], step)

    # --- cost, solver, branch, timing
    ct = _table(where, data, "cost")
    smooth = _number(where, "cost.smoothness", ct.get("smoothness", DEFAULT_SMOOTHNESS))
    if smooth < 0:
        raise _err(where, "cost.smoothness", f"must be >= 0 (mm^2/rad^2), got {smooth!r}")
    st = _table(where, data, "solver")
    sname = st.get("name", "ipopt")
    if sname != "ipopt":
        raise _err(where, "solver.name", f"must be 'ipopt' (the only NLP solver available), got {sname!r}")
    codegen = st.get("codegen", True)
    if not isinstance(codegen, bool):
        raise _err(where, "solver.codegen", f"must be true or false, got {codegen!r}")
    solver = SolverSettings(name=sname,
                            max_iter=_integer(where, "solver.max_iter", st.get("max_iter", DEFAULT_MAX_ITER), 0),
                            tol=_positive(where, "solver.tol", st.get("tol", DEFAULT_TOL)),
                            codegen=codegen)
    bt = _table(where, data, "branch")
    got = _angle_pair(where, bt, "home", "branch.")
    if got is None:
        home = paper.HOME_Q.copy()
    else:
        raw, deg = got
        home = _vector(where, f"branch.home{'_deg' if deg else ''}", raw, 6)
        home = np.radians(home) if deg else home
    tt = _table(where, data, "timing")
    methods = tt.get("methods", list(TIMING_METHODS))
    if not isinstance(methods, list) or not all(isinstance(m, str) for m in methods):
        raise _err(where, "timing.methods", f"must be a list of method names {list(TIMING_METHODS)}, "
                                            f"got {methods!r}")
    timing = TimingSettings(
        methods=tuple(methods),
        dt=_positive(where, "timing.dt", tt.get("dt", DEFAULT_DT)),
        toppra_gridpoints=_integer(where, "timing.toppra_gridpoints", tt.get("toppra_gridpoints", 0), 0),
        toppra_max_iterations=_integer(where, "timing.toppra_max_iterations",
                                       tt.get("toppra_max_iterations", 0), 0),
        ruckig_max_iterations=_integer(where, "timing.ruckig_max_iterations",
                                       tt.get("ruckig_max_iterations", 0), 0))
    if timing.toppra_gridpoints == 1:
        raise _err(where, "timing.toppra_gridpoints", "must be 0 (default) or >= 2, got 1")
    _check_timing(where, timing)

    return Problem(name=name.strip(), description=desc.strip(), source=where, source_text=src.strip(),
                   robot_spec=spec,
                   robot=robot, path_kind=kind, line=line, positions=P, rotations=R, rule=rule,
                   cone_half_angle=half, scan=scan, wrench=W, wrench_per_waypoint=per_wp, limits=limits,
                   smoothness=smooth, solver=solver, home_q=home, timing=timing,
                   nominal_rpy=np.asarray(nominal_rpy, float), wrench_frame=frame, payload_mass_kg=p_mass,
                   payload_com_m=p_com, gravity=p_grav, arm=arm)


def shipped_problems() -> tuple[str, ...]:
    """Names of the problems shipped in ``problems/files`` (without ``.toml``)."""
    files = resources.files("problems").joinpath("files")
    return tuple(sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml")))


def load_problem(spec: str | Path) -> Problem:
    """Load a problem by shipped name (see :func:`shipped_problems`) or TOML file path.

    Raises
    ------
    ProblemFileError
        The file is missing, not TOML, or fails validation (the message names the key).
    """
    s = str(spec)
    path = Path(s)
    if path.is_file():
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ProblemFileError(f"{path}: cannot read: {exc}") from None
        where, base = str(path), path.parent
    elif s in shipped_problems():
        res = resources.files("problems").joinpath(f"files/{s}.toml")
        text = res.read_text(encoding="utf-8")
        where, base = f"shipped problem '{s}'", None
    else:
        raise ProblemFileError(f"problem '{s}': no such file, and not a shipped problem "
                               f"(shipped: {', '.join(shipped_problems())})")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProblemFileError(f"{where}: not valid TOML: {exc}") from None
    return problem_from_dict(data, where, base)
