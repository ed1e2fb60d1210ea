"""Robot descriptions: the data read from a robot file, validated.

A :class:`Robot` is the *description* of an arm (DH table, limits, stiffness,
masses, tool).  Working data computed from it (symbolic functions, caches) live
in :mod:`models.symbolic`, in the spirit of pinocchio's ``model``/``data`` split.

Conventions (see ``docs/conventions.md``):

* lengths in m, angles in rad, stiffness in N*m/rad, masses in kg;
* ``standard_dh``: ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``;
* ``modified_dh``: ``A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``,
  where row *i* of the file holds ``a_{i-1}``, ``alpha_{i-1}``, ``d_i``;
* ``theta_i = q_i + theta_offset_i``;
* the tool transform ``tcp2flange`` maps TCP-frame coordinates to flange-frame
  coordinates; its rotation is ``Rz(yaw) Ry(pitch) Rx(roll)``.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any
from collections.abc import Mapping, Sequence

import numpy as np

from .constants import (
    PLAUSIBLE_JOINT_SPEED_MAX_RAD_S,
    PLAUSIBLE_LINK_MASS_MAX_KG,
    PLAUSIBLE_MASS_PER_REACH3_MAX_KG_M3,
    PLAUSIBLE_POSITION_MAX_M,
    STANDARD_GRAVITY,
    gravity_problem,
)
from .errors import InputError
from .transforms import rpy_to_matrix, transform

CONVENTIONS = ("standard_dh", "modified_dh")
BUILTIN_ROBOTS = ("ar5", "ur5", "ur10", "ur5e", "kr6_r900")

# Keys that may be given in radians (plain name) or degrees (``_deg`` suffix).
_ANGLE_KEYS = ("alpha", "theta_offset", "q_min", "q_max")
_JOINT_REQUIRED = ("a", "alpha", "d", "theta_offset", "q_min", "q_max", "v_max", "a_max", "j_max", "stiffness")
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
#: Keys of the ``[controller]`` table: the controller's joint angle is ``sign * q + offset``.
_CONTROLLER_KEYS = ("joint_sign", "joint_offset", "joint_offset_deg")
#: Keys of a transform table (``[tool]``, ``[frame0_in_base]``, ``[flange_in_frame6]``).
_FRAME_KEYS = ("xyz", "rpy", "rpy_deg")
#: Keys of the optional ``[collision]`` table (the arm's own collision geometry, ``docs/cell.md``).
COLLISION_KEYS = ("radii_m", "allowed_pairs", "segments", "replace_dh", "source")
#: Keys of one ``[[collision.segments]]`` entry.
COLLISION_SEGMENT_KEYS = ("body", "frame_a", "xyz_a", "frame_b", "xyz_b", "radius_m", "line", "name")
#: Collision bodies: 0 the base, i = 1..6 the link moved by joint i.
COLLISION_N_BODIES = 7
#: A segment end may be fixed in the base frame (-1) or a DH frame 0..6.
COLLISION_FRAMES = tuple(range(-1, 7))
#: A segment end whose position in its body's frame changes by more than this (m, per m of the
#: arm's reach) between configurations is not fixed to that body.
COLLISION_FIXED_TOL_M_PER_M = 1e-9


class RobotFileError(InputError):
    """A robot file (or robot dictionary) is malformed; the message names where."""


# --------------------------------------------------------------------------------------
# Reading a user's text file (robot, problem, measurement, simulation files)
# --------------------------------------------------------------------------------------


def _not_utf8(where: str, raw: bytes, exc: UnicodeDecodeError) -> str:
    """One line for text that is not UTF-8: line and column of the first bad byte, a hint."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        return (
            f"{where}: the file is UTF-16 encoded; save the file as UTF-8 (a plain text file, "
            "e.g. 'Save as... UTF-8' in the editor or spreadsheet)"
        )
    start = exc.start
    line = raw.count(b"\n", 0, start) + 1
    if b"\x00" in raw[:4096]:
        return f"{where}: not a text file (binary content, byte 0x{raw[start]:02x} at line {line}); expected UTF-8 text"
    col = start - (raw.rfind(b"\n", 0, start) + 1) + 1
    return (
        f"{where}: line {line}, column {col}: byte 0x{raw[start]:02x} is not UTF-8 text (the file is "
        "probably Latin-1 / Windows-1252); save the file as UTF-8"
    )


def read_text_file(path: str | Path, what: str = "file", error: type[InputError] = InputError) -> str:
    """The text of a user's input file, decoded as UTF-8 (a UTF-8 byte-order mark is dropped).

    Parameters
    ----------
    path : path
        The file.
    what : str
        What the file is, for messages (``"robot file"``, ``"measurement file"``, ...).
    error : type
        The :class:`~models.errors.InputError` subclass raised.

    Raises
    ------
    InputError
        One line naming the path: no such file, a folder where a file is expected, not
        readable, binary, or not UTF-8 (line and column of the first bad byte and the hint to
        save the file as UTF-8).
    """
    p = Path(path)
    if p.is_dir():
        raise error(f"{p}: is a folder; expected a {what}")
    if not p.exists():
        raise error(f"{p}: no such {what}")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise error(f"{p}: cannot read the {what}: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(_not_utf8(str(p), raw, exc)) from None
    if "\x00" in text:
        raise error(f"{p}: not a text file (binary content); expected a {what} (UTF-8 text)")
    return text.removeprefix("\ufeff")


@dataclass(frozen=True)
class Joint:
    """One revolute joint with the link that follows it (SI units).

    Attributes
    ----------
    a, d : float
        DH link length and offset, m.
    alpha, theta_offset : float
        DH twist and joint-angle offset, rad.
    q_min, q_max : float
        Position limits of the joint variable ``q``, rad.
    v_max, a_max, j_max : float
        Velocity, acceleration and jerk limits, rad/s, rad/s^2, rad/s^3.
    stiffness : float
        Joint (gear) stiffness, N*m/rad.
    mass : float or None
        Mass of the link carried by this joint, kg.
    com : ndarray, shape (3,), or None
        Centre of mass of that link in the joint's DH link frame *i*, m.
    inertia : ndarray, shape (3, 3), or None
        Inertia tensor of that link about its centre of mass, axes of DH link frame *i*, kg*m^2.
    """

    a: float
    alpha: float
    d: float
    theta_offset: float
    q_min: float
    q_max: float
    v_max: float
    a_max: float
    j_max: float
    stiffness: float
    mass: float | None = None
    com: np.ndarray | None = None
    inertia: np.ndarray | None = None
    #: Angle keys the robot file gave in degrees (``{"q_min", "q_max"}`` for ``q_min_deg``,
    #: ``q_max_deg``): messages quote a limit in the key and unit the file used.
    deg_keys: frozenset[str] = field(default=frozenset(), compare=False, repr=False)

    def limit_text(self, key: str, value_rad: float | None = None) -> str:
        """``key`` (``q_min``/``q_max``) as the robot file wrote it, with ``value_rad`` (default:
        the limit itself) in that key's unit: ``"q_max_deg = 360"`` or ``"q_max = 6.283 rad"``."""
        v = getattr(self, key) if value_rad is None else float(value_rad)
        if key in self.deg_keys:
            return f"{key}_deg = {math.degrees(v):.6g}"
        return f"{key} = {v:.6g} rad"


@dataclass(frozen=True)
class CollisionSegment:
    """One capsule segment a robot file (or its URDF) declares, fixed to one body.

    Attributes
    ----------
    body : int
        0 the base, i = 1..6 the link moved by joint i.
    frame_a, frame_b : int
        Frame each end point is given in: -1 the base frame, 0..6 DH frame i.
    xyz_a, xyz_b : ndarray, shape (3,)
        End points in those frames, m.
    radius : float or None
        Capsule radius, m; None: the body's radius (``radii_m``, else the built-in or generic one),
        for a line the thin line radius (``models.collision.capsules.LINE_RADIUS_M``).
    line : bool
        A line of the arm's kinematic skeleton (between two joint origins), not material: a thin
        capsule, kept only where it leaves the body's other capsules (``docs/cell.md``).
    name : str
        Where the segment comes from (messages, ``docs/cell.md``), e.g. ``urdf link 'forearm' box``.
    """

    body: int
    frame_a: int
    xyz_a: np.ndarray
    frame_b: int
    xyz_b: np.ndarray
    radius: float | None = None
    line: bool = False
    name: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The segment as a ``[[collision.segments]]`` entry (m)."""
        out: dict[str, Any] = {
            "body": int(self.body),
            "frame_a": int(self.frame_a),
            "xyz_a": [float(v) for v in self.xyz_a],
            "frame_b": int(self.frame_b),
            "xyz_b": [float(v) for v in self.xyz_b],
        }
        if self.radius is not None:
            out["radius_m"] = float(self.radius)
        if self.line:
            out["line"] = True
        if self.name:
            out["name"] = self.name
        return out


@dataclass(frozen=True)
class RobotCollision:
    """The arm's own collision geometry: the ``[collision]`` table of a robot file, with the
    capsules of a URDF's ``<collision>`` elements (``docs/cell.md``, "The arm as capsules").

    Attributes
    ----------
    radii : ndarray, shape (7,), or None
        Capsule radius per body 0..6, m; None: the built-in or generic radii.
    allowed_pairs : tuple of (int, int), or None
        Body pairs (i < j) left out of self-collision; None: the built-in ones (none for another arm).
    segments : tuple of CollisionSegment
        Capsule segments added to the DH capsules.
    replace_dh : tuple of int
        Bodies whose DH capsules are left out: ``segments`` describe them (URDF ``<collision>``).
    source : str
        Where the radii and segments come from.
    """

    radii: np.ndarray | None = None
    allowed_pairs: tuple[tuple[int, int], ...] | None = None
    segments: tuple[CollisionSegment, ...] = ()
    replace_dh: tuple[int, ...] = ()
    source: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The ``[collision]`` table (m)."""
        out: dict[str, Any] = {}
        if self.radii is not None:
            out["radii_m"] = [float(r) for r in self.radii]
        if self.source:
            out["source"] = self.source
        if self.allowed_pairs is not None:
            out["allowed_pairs"] = [[int(i), int(j)] for i, j in self.allowed_pairs]
        if self.replace_dh:
            out["replace_dh"] = [int(b) for b in self.replace_dh]
        if self.segments:
            out["segments"] = [s.to_dict() for s in self.segments]
        return out


@dataclass(frozen=True)
class Robot:
    """A validated 6R arm description.

    Attributes
    ----------
    name : str
    convention : {"standard_dh", "modified_dh"}
    joints : tuple of Joint, length 6
    tcp2flange : ndarray, shape (4, 4)
        Homogeneous transform TCP frame -> flange frame (x_flange = A @ x_tcp).
    gravity : ndarray, shape (3,)
        Gravity acceleration in the base frame, m/s^2.
    description, source : str
        Free text (what the values are and where they come from).
    frame02base : ndarray, shape (4, 4)
        DH frame 0 -> base frame (identity for a plain DH table); a chain read from a URDF
        gets the frame its DH table starts from.
    flange2frame6 : ndarray, shape (4, 4)
        Flange frame -> DH frame 6 (identity for a plain DH table: the flange *is* DH frame 6).
    joint_names : tuple of str, length 6, or None
        The controller's / URDF's joint names, base to tip.
    urdf : dict or None
        Where a URDF-based robot came from: ``{"path", "base_link", "tip_link"}``.
    notes : tuple of str
        What was assumed while reading the file (defaults taken, parts ignored).
    """

    name: str
    convention: str
    joints: tuple[Joint, ...]
    tcp2flange: np.ndarray = field(default_factory=lambda: np.eye(4))
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -STANDARD_GRAVITY]))
    description: str = ""
    source: str = ""
    #: Optional ``[identified]`` table written by ``compplan identify`` (registration,
    #: effects and their parameters); opaque to the kinematics, used by ``problems.identify``.
    identified: dict[str, Any] | None = None
    frame02base: np.ndarray = field(default_factory=lambda: np.eye(4))
    flange2frame6: np.ndarray = field(default_factory=lambda: np.eye(4))
    joint_names: tuple[str, ...] | None = None
    urdf: dict[str, str] | None = field(default=None, compare=False)
    notes: tuple[str, ...] = field(default=(), compare=False)
    #: The controller's joint angle is ``controller_sign * q + controller_offset`` (rad): the sign
    #: and zero of each joint on the robot's controller (exports, ``docs/export.md``).
    controller_sign: np.ndarray = field(default_factory=lambda: np.ones(6), compare=False)
    controller_offset: np.ndarray = field(default_factory=lambda: np.zeros(6), compare=False)
    #: The robot file has a ``[controller]`` table: the signs and zeros above are the controller's,
    #: not a default (vendor exports warn without it, ``docs/export.md``).
    controller_declared: bool = field(default=False, compare=False)
    #: The arm's own collision geometry (``[collision]`` table, URDF ``<collision>`` elements), or
    #: None: the built-in or generic capsules (``models/collision/capsules.py``, ``docs/cell.md``).
    collision: RobotCollision | None = field(default=None, compare=False)

    @property
    def has_chain_transforms(self) -> bool:
        """Whether DH frame 0 or the flange differ from the base frame / DH frame 6."""
        return not (np.array_equal(self.frame02base, np.eye(4)) and np.array_equal(self.flange2frame6, np.eye(4)))

    # --- array views (shape (6,)) -------------------------------------------------
    def _col(self, key: str) -> np.ndarray:
        return np.array([getattr(j, key) for j in self.joints], dtype=float)

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def a(self) -> np.ndarray:
        """DH a, m, shape (6,)."""
        return self._col("a")

    @property
    def alpha(self) -> np.ndarray:
        """DH alpha, rad, shape (6,)."""
        return self._col("alpha")

    @property
    def d(self) -> np.ndarray:
        """DH d, m, shape (6,)."""
        return self._col("d")

    @property
    def theta_offset(self) -> np.ndarray:
        """Joint-angle offsets, rad, shape (6,)."""
        return self._col("theta_offset")

    @property
    def stiffness(self) -> np.ndarray:
        """Joint stiffnesses, N*m/rad, shape (6,)."""
        return self._col("stiffness")

    @property
    def q_min(self) -> np.ndarray:
        return self._col("q_min")

    @property
    def q_max(self) -> np.ndarray:
        return self._col("q_max")

    @property
    def v_max(self) -> np.ndarray:
        return self._col("v_max")

    @property
    def a_max(self) -> np.ndarray:
        return self._col("a_max")

    @property
    def j_max(self) -> np.ndarray:
        return self._col("j_max")

    @property
    def has_masses(self) -> bool:
        return all(j.mass is not None and j.com is not None for j in self.joints)

    @property
    def masses(self) -> np.ndarray:
        """Link masses, kg, shape (6,); raises if the file gives none."""
        if not self.has_masses:
            raise RobotFileError(f"robot '{self.name}': link masses/com are not given")
        return self._col("mass")

    @property
    def has_inertias(self) -> bool:
        return self.has_masses and all(j.inertia is not None for j in self.joints)

    @property
    def inertias(self) -> np.ndarray:
        """Link inertia tensors about their centres of mass, DH link frames, kg*m^2, shape (6, 3, 3)."""
        if not self.has_inertias:
            raise RobotFileError(f"robot '{self.name}': link inertias are not given")
        return np.array([j.inertia for j in self.joints], dtype=float)

    @property
    def coms(self) -> np.ndarray:
        """Centres of mass in DH link frames, m, shape (6, 3)."""
        if not self.has_masses:
            raise RobotFileError(f"robot '{self.name}': link masses/com are not given")
        return np.array([j.com for j in self.joints], dtype=float)

    def with_tool(self, tcp2flange: np.ndarray) -> Robot:
        """Return a copy with another tool transform (4x4, TCP -> flange)."""
        t = np.asarray(tcp2flange, dtype=float)
        if t.shape != (4, 4) or not np.all(np.isfinite(t)):
            raise RobotFileError("tool transform must be a finite 4x4 matrix")
        return replace(self, tcp2flange=t)

    def with_stiffness(self, stiffness: np.ndarray) -> Robot:
        """Return a copy with other joint stiffnesses (N*m/rad, shape (6,))."""
        k = np.asarray(stiffness, dtype=float).reshape(-1)
        if k.shape != (self.n_joints,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise RobotFileError(f"stiffness must be 6 finite positive values, got {k}")
        joints = tuple(replace(j, stiffness=float(ki)) for j, ki in zip(self.joints, k))
        return replace(self, joints=joints)

    def to_dict(self) -> dict[str, Any]:
        """The robot as a dictionary in the robot-file schema (SI, radians)."""
        joints = []
        for j in self.joints:
            row: dict[str, Any] = {k: float(getattr(j, k)) for k in _JOINT_REQUIRED}
            if j.mass is not None:
                row["mass"] = float(j.mass)
            if j.com is not None:
                row["com"] = [float(c) for c in j.com]
            if j.inertia is not None:
                I = np.asarray(j.inertia, dtype=float)
                row["inertia"] = [
                    float(I[0, 0]),
                    float(I[1, 1]),
                    float(I[2, 2]),
                    float(I[0, 1]),
                    float(I[0, 2]),
                    float(I[1, 2]),
                ]
            joints.append(row)
        out: dict[str, Any] = {
            "name": self.name,
            "convention": self.convention,
            "description": self.description,
            "source": self.source,
            "gravity": [float(g) for g in self.gravity],
            "tool": _frame_dict(self.tcp2flange),
        }
        if self.joint_names is not None:
            out["joint_names"] = list(self.joint_names)
        if not np.array_equal(self.frame02base, np.eye(4)):
            out["frame0_in_base"] = _frame_dict(self.frame02base)
        if not np.array_equal(self.flange2frame6, np.eye(4)):
            out["flange_in_frame6"] = _frame_dict(self.flange2frame6)
        if self.controller_declared or np.any(self.controller_sign != 1.0) or np.any(self.controller_offset != 0.0):
            out["controller"] = {
                "joint_sign": [int(v) for v in self.controller_sign],
                "joint_offset": [float(v) for v in self.controller_offset],
            }
        out["joints"] = joints
        if self.identified is not None:
            out["identified"] = self.identified
        if self.collision is not None:
            out["collision"] = self.collision.to_dict()
        return out


def _frame_dict(T: np.ndarray) -> dict[str, list[float]]:
    """A transform as a robot-file table ``{xyz (m), rpy (rad)}``."""
    from .transforms import matrix_to_rpy

    return {"xyz": [float(v) for v in T[:3, 3]], "rpy": [float(v) for v in matrix_to_rpy(T[:3, :3])]}


# --------------------------------------------------------------------------------------
# Loading and validation
# --------------------------------------------------------------------------------------


def _finite(where: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RobotFileError(f"{where}: key '{key}' must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise RobotFileError(f"{where}: key '{key}' must be finite, got {value!r}")
    return v


def _vector(where: str, key: str, value: Any, n: int) -> np.ndarray:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise RobotFileError(f"{where}: key '{key}' must be a list of {n} numbers, got {value!r}")
    return np.array([_finite(where, f"{key}[{i}]", v) for i, v in enumerate(value)])


#: A DH twist, joint offset or tool angle in radians beyond this magnitude is implausible:
#: degrees given under the radian key (one turn).
PLAUSIBLE_ANGLE_MAX_RAD = 2.0 * math.pi * (1.0 + 1e-9)
#: A joint limit in radians beyond this magnitude is implausible (two turns).
PLAUSIBLE_LIMIT_MAX_RAD = 4.0 * math.pi * (1.0 + 1e-9)


def _check_radians(
    where: str, key: str, value: float, limit: float = PLAUSIBLE_ANGLE_MAX_RAD, deg_key: str | None = None
) -> float:
    """Refuse a radian value that is almost certainly degrees (|value| > ``limit``); the
    message suggests ``deg_key`` (default ``key + "_deg"``)."""
    if abs(value) > limit:
        raise RobotFileError(
            f"{where}: key '{key}' = {value:g} rad is implausible (|value| > {limit:.4g} rad); "
            f"a key without '_deg' is in radians: degrees given? use '{deg_key or key + '_deg'}'"
        )
    return value


def _angle(where: str, row: Mapping[str, Any], key: str) -> float:
    has_rad, has_deg = key in row, f"{key}_deg" in row
    if has_rad and has_deg:
        raise RobotFileError(f"{where}: give either '{key}' (rad) or '{key}_deg', not both")
    if has_deg:
        return math.radians(_finite(where, f"{key}_deg", row[f"{key}_deg"]))
    if has_rad:
        limit = PLAUSIBLE_LIMIT_MAX_RAD if key in ("q_min", "q_max") else PLAUSIBLE_ANGLE_MAX_RAD
        return _check_radians(where, key, _finite(where, key, row[key]), limit)
    raise RobotFileError(f"{where}: missing key '{key}' (rad) or '{key}_deg'")


def _as_written(row: Mapping[str, Any], key: str) -> tuple[str, str]:
    """The key of an angle as the file wrote it (``q_min`` or ``q_min_deg``) and its value text
    with the unit (``"-360 deg"``, ``"1 rad"``)."""
    if f"{key}_deg" in row:
        return f"{key}_deg", f"{float(row[f'{key}_deg']):g} deg"
    return key, f"{float(row[key]):g} rad"


def _parse_joint(where: str, row: Any) -> Joint:
    if not isinstance(row, Mapping):
        raise RobotFileError(f"{where}: expected a table of joint keys, got {row!r}")
    allowed = set(_JOINT_REQUIRED) | set(_JOINT_OPTIONAL) | {f"{k}_deg" for k in _ANGLE_KEYS}
    unknown = sorted(set(row) - allowed)
    if unknown:
        raise RobotFileError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    vals: dict[str, Any] = {}
    for key in _JOINT_REQUIRED:
        if key in _ANGLE_KEYS:
            vals[key] = _angle(where, row, key)
        elif key not in row:
            raise RobotFileError(f"{where}: missing key '{key}'")
        else:
            vals[key] = _finite(where, key, row[key])
    for key in ("a", "d"):
        if abs(vals[key]) > PLAUSIBLE_POSITION_MAX_M:
            raise RobotFileError(
                f"{where}: key '{key}' = {vals[key]:g} m is implausible for a link "
                f"(> {PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres "
                "(millimetres given?)"
            )
    if vals["q_min"] >= vals["q_max"]:
        (kmin, vmin), (kmax, vmax) = _as_written(row, "q_min"), _as_written(row, "q_max")
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
        vals["mass"] = _finite(where, "mass", row["mass"])
        if vals["mass"] < 0:
            raise RobotFileError(f"{where}: key 'mass' must be >= 0, got {vals['mass']}")
        if vals["mass"] > PLAUSIBLE_LINK_MASS_MAX_KG:
            raise RobotFileError(
                f"{where}: key 'mass' = {vals['mass']:g} kg is implausible for a link "
                f"(> {PLAUSIBLE_LINK_MASS_MAX_KG:g} kg); masses are in kg (grams given?)"
            )
        vals["com"] = _vector(where, "com", row["com"], 3)
    if "inertia" in row:
        if "mass" not in row:
            raise RobotFileError(f"{where}: key 'inertia' needs 'mass' and 'com'")
        vals["inertia"] = inertia_matrix(where, _vector(where, "inertia", row["inertia"], 6))
    deg = frozenset(k for k in _ANGLE_KEYS if f"{k}_deg" in row)
    return Joint(**vals, deg_keys=deg)


#: Relative tolerance of the triangle inequality of principal moments (rounding in published tables).
INERTIA_TRIANGLE_RTOL = 1e-6


def inertia_matrix(where: str, v: np.ndarray) -> np.ndarray:
    """Symmetric 3x3 inertia from ``[ixx, iyy, izz, ixy, ixz, iyz]`` (kg*m^2), checked physical:
    positive semi-definite and principal moments obeying the triangle inequality."""
    ixx, iyy, izz, ixy, ixz, iyz = (float(x) for x in v)
    I = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    ev = np.linalg.eigvalsh(I)
    scale = max(float(np.max(np.abs(ev))), 1e-300)
    if ev[0] < -INERTIA_TRIANGLE_RTOL * scale or ev[2] > ev[0] + ev[1] + INERTIA_TRIANGLE_RTOL * scale:
        raise RobotFileError(
            f"{where}: key 'inertia' = {[float(x) for x in v]} kg*m^2 is not a physical inertia "
            f"(principal moments {[float(e) for e in ev]}: each must be >= 0 and at most "
            "the sum of the other two); order is [ixx, iyy, izz, ixy, ixz, iyz]"
        )
    return I


def robot_from_dict(data: Mapping[str, Any], where: str = "robot", base_dir: Path | None = None) -> Robot:
    """Build and validate a :class:`Robot` from a robot-file dictionary.

    Parameters
    ----------
    data : mapping
        The parsed TOML document (see ``docs/robot-file.md``): a DH table, or a URDF-based
        file (key ``urdf``, read by :mod:`models.urdf`).
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
        from .urdf import robot_from_urdf_dict

        return robot_from_urdf_dict(data, where, base_dir)
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        hint = (
            "; this looks like a problem file (compplan plan PROBLEM), not a robot file"
            if {"path", "wrench", "orientation"} & set(unknown)
            else ""
        )
        raise RobotFileError(f"{where}: unknown top-level key(s) {unknown}; allowed: {list(_TOP_KEYS)}{hint}")
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise RobotFileError(f"{where}: key 'name' must be a non-empty string, got {name!r}")
    conv = data.get("convention")
    if conv not in CONVENTIONS:
        raise RobotFileError(f"{where}: key 'convention' must be one of {CONVENTIONS}, got {conv!r}")
    joints_raw = data.get("joints")
    if not isinstance(joints_raw, list) or len(joints_raw) != 6:
        n = len(joints_raw) if isinstance(joints_raw, list) else joints_raw
        raise RobotFileError(f"{where}: key 'joints' must be an array of 6 [[joints]] tables, got {n!r}")
    joints = tuple(_parse_joint(f"{where}: joints[{i + 1}]", row) for i, row in enumerate(joints_raw))

    tcp2flange = parse_frame_table(where, "tool", data.get("tool", {}))
    gravity = _vector(where, "gravity", data.get("gravity", [0.0, 0.0, -STANDARD_GRAVITY]), 3)
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
    from .degenerate import check_chain, robot_axes  # a chain that spans < 6 DOF everywhere

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


def parse_frame_table(where: str, key: str, table: Any) -> np.ndarray:
    """A transform table ``{xyz (m), rpy (rad) | rpy_deg}`` of a robot file as a 4x4 matrix.

    ``R = Rz(yaw) Ry(pitch) Rx(roll)`` with ``rpy = [roll, pitch, yaw]``; missing keys are zero.
    Raises :class:`RobotFileError` naming ``key`` and the offending entry.
    """
    if not isinstance(table, Mapping):
        raise RobotFileError(f"{where}: key '{key}' must be a table")
    w = f"{where}: {key}"
    unknown = sorted(set(table) - set(_FRAME_KEYS))
    if unknown:
        raise RobotFileError(f"{w}: unknown key(s) {unknown}; allowed: {list(_FRAME_KEYS)}")
    xyz = _vector(w, "xyz", table.get("xyz", [0.0, 0.0, 0.0]), 3)
    if np.max(np.abs(xyz)) > PLAUSIBLE_POSITION_MAX_M:
        raise RobotFileError(
            f"{w}: key 'xyz' = {[float(v) for v in xyz]} is implausible (> "
            f"{PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres (millimetres given?)"
        )
    if "rpy" in table and "rpy_deg" in table:
        raise RobotFileError(f"{w}: give either 'rpy' (rad) or 'rpy_deg', not both")
    if "rpy_deg" in table:
        rpy = np.radians(_vector(w, "rpy_deg", table["rpy_deg"], 3))
    else:
        rpy = _vector(w, "rpy", table.get("rpy", [0.0, 0.0, 0.0]), 3)
        for i, v in enumerate(rpy):
            _check_radians(w, f"rpy[{i}]", float(v), deg_key="rpy_deg")
    return transform(rpy_to_matrix(rpy), xyz)


def parse_controller(where: str, table: Any) -> dict[str, np.ndarray]:
    """The optional ``[controller]`` table: ``joint_sign`` (6 of +1/-1) and ``joint_offset``
    (rad) or ``joint_offset_deg``: the controller's angle is ``sign * q + offset``."""
    if table is None:
        return {}
    w = f"{where}: controller"
    if not isinstance(table, Mapping):
        raise RobotFileError(f"{where}: key 'controller' must be a table")
    unknown = sorted(set(table) - set(_CONTROLLER_KEYS))
    if unknown:
        raise RobotFileError(f"{w}: unknown key(s) {unknown}; allowed: {list(_CONTROLLER_KEYS)}")
    out: dict[str, np.ndarray] = {}
    if "joint_sign" in table:
        sign = _vector(w, "joint_sign", table["joint_sign"], 6)
        bad = [i for i, v in enumerate(sign) if v not in (1.0, -1.0)]
        if bad:
            raise RobotFileError(
                f"{w}: key 'joint_sign'[{bad[0]}] (joint {bad[0] + 1}) = {sign[bad[0]]:g}; expected +1 or -1"
            )
        out["controller_sign"] = sign
    if "joint_offset" in table and "joint_offset_deg" in table:
        raise RobotFileError(f"{w}: give either 'joint_offset' (rad) or 'joint_offset_deg', not both")
    if "joint_offset_deg" in table:
        out["controller_offset"] = np.radians(_vector(w, "joint_offset_deg", table["joint_offset_deg"], 6))
    elif "joint_offset" in table:
        off = _vector(w, "joint_offset", table["joint_offset"], 6)
        for i, v in enumerate(off):
            _check_radians(w, f"joint_offset[{i}]", float(v), deg_key="joint_offset_deg")
        out["controller_offset"] = off
    return out


def parse_joint_names(where: str, names: Any) -> tuple[str, ...] | None:
    """The optional ``joint_names`` (6 distinct non-empty strings, base to tip)."""
    if names is None:
        return None
    if (
        not isinstance(names, list)
        or len(names) != 6
        or not all(isinstance(n, str) and n for n in names)
        or len(set(names)) != 6
    ):
        raise RobotFileError(
            f"{where}: key 'joint_names' must be a list of 6 distinct non-empty strings, got {names!r}"
        )
    return tuple(names)


def _int_in(where: str, key: str, value: Any, allowed: Sequence[int], what: str) -> int:
    """An integer key that must be one of ``allowed`` (a body or frame number)."""
    if isinstance(value, bool) or not isinstance(value, int) or value not in allowed:
        raise RobotFileError(
            f"{where}: key '{key}' = {value!r}; expected {what} (an integer {allowed[0]}..{allowed[-1]})"
        )
    return int(value)


def _radius(where: str, key: str, value: Any) -> float:
    """A capsule radius: finite, > 0, plausible in metres."""
    r = _finite(where, key, value)
    if r <= 0:
        raise RobotFileError(f"{where}: key '{key}' = {r:g}; expected a radius > 0 (m)")
    if r > PLAUSIBLE_POSITION_MAX_M:
        raise RobotFileError(
            f"{where}: key '{key}' = {r:g} m is implausible for a capsule radius (> "
            f"{PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres (millimetres given?)"
        )
    return r


def _collision_point(where: str, key: str, value: Any) -> np.ndarray:
    p = _vector(where, key, value, 3)
    if np.max(np.abs(p)) > PLAUSIBLE_POSITION_MAX_M:
        raise RobotFileError(
            f"{where}: key '{key}' = {[float(v) for v in p]} is implausible (> {PLAUSIBLE_POSITION_MAX_M:g} m); "
            "lengths are in metres (millimetres given?)"
        )
    return p


def _collision_segment(where: str, seg: Any) -> CollisionSegment:
    if not isinstance(seg, Mapping):
        raise RobotFileError(f"{where}: expected a table (body, frame_a, xyz_a, frame_b, xyz_b), got {seg!r}")
    unknown = sorted(set(seg) - set(COLLISION_SEGMENT_KEYS))
    if unknown:
        raise RobotFileError(f"{where}: unknown key(s) {unknown}; allowed: {list(COLLISION_SEGMENT_KEYS)}")
    for key in ("body", "frame_a", "xyz_a", "frame_b", "xyz_b"):
        if key not in seg:
            raise RobotFileError(f"{where}: missing key '{key}'")
    frames = COLLISION_FRAMES
    name = seg.get("name", "")
    if not isinstance(name, str):
        raise RobotFileError(f"{where}: key 'name' must be a string, got {name!r}")
    line = seg.get("line", False)
    if not isinstance(line, bool):
        raise RobotFileError(f"{where}: key 'line' must be true or false, got {line!r}")
    return CollisionSegment(
        body=_int_in(where, "body", seg["body"], range(COLLISION_N_BODIES), "a body: 0 base, i link moved by joint i"),
        frame_a=_int_in(where, "frame_a", seg["frame_a"], frames, "a frame: -1 base, 0..6 DH frame"),
        xyz_a=_collision_point(where, "xyz_a", seg["xyz_a"]),
        frame_b=_int_in(where, "frame_b", seg["frame_b"], frames, "a frame: -1 base, 0..6 DH frame"),
        xyz_b=_collision_point(where, "xyz_b", seg["xyz_b"]),
        radius=_radius(where, "radius_m", seg["radius_m"]) if "radius_m" in seg else None,
        line=line,
        name=name,
    )


def parse_collision_table(where: str, table: Any) -> RobotCollision:
    """The optional ``[collision]`` table of a robot file (``docs/robot-file.md``, ``docs/cell.md``).

    Keys: ``radii_m`` (7 radii, m, body 0 base .. 6), ``allowed_pairs`` (pairs of two different
    bodies 0..6), ``replace_dh`` (bodies), ``source`` (text), ``[[collision.segments]]`` (``body``,
    ``frame_a``, ``xyz_a``, ``frame_b``, ``xyz_b``, optional ``radius_m``, ``line`` and ``name``).

    Raises
    ------
    RobotFileError
        Naming the file, the key (``collision.segments[2]: key 'body'``), the value and what was expected.
    """
    w = f"{where}: collision"
    if not isinstance(table, Mapping):
        raise RobotFileError(f"{where}: key 'collision' must be a table, got {table!r}")
    unknown = sorted(set(table) - set(COLLISION_KEYS))
    if unknown:
        raise RobotFileError(f"{w}: unknown key(s) {unknown}; allowed: {list(COLLISION_KEYS)}")
    radii = None
    if "radii_m" in table:
        raw = table["radii_m"]
        if not isinstance(raw, (list, tuple)) or len(raw) != COLLISION_N_BODIES:
            raise RobotFileError(
                f"{w}: key 'radii_m' must be a list of {COLLISION_N_BODIES} radii (m, body 0 base .. 6), got {raw!r}"
            )
        radii = np.array([_radius(w, f"radii_m[{i}]", v) for i, v in enumerate(raw)])
    pairs = None
    if "allowed_pairs" in table:
        raw = table["allowed_pairs"]
        if not isinstance(raw, (list, tuple)):
            raise RobotFileError(f"{w}: key 'allowed_pairs' must be a list of [i, j] body pairs, got {raw!r}")
        out = []
        for k, pair in enumerate(raw):
            key = f"allowed_pairs[{k}]"
            bodies = range(COLLISION_N_BODIES)
            if (
                not isinstance(pair, (list, tuple))
                or len(pair) != 2
                or any(isinstance(b, bool) or not isinstance(b, int) or b not in bodies for b in pair)
                or pair[0] == pair[1]
            ):
                raise RobotFileError(
                    f"{w}: key '{key}' = {pair!r}; expected two different bodies [i, j] (integers 0..6)"
                )
            out.append((min(pair), max(pair)))
        pairs = tuple(sorted(set(out)))
    replace_dh: tuple[int, ...] = ()
    if "replace_dh" in table:
        raw = table["replace_dh"]
        if not isinstance(raw, (list, tuple)):
            raise RobotFileError(f"{w}: key 'replace_dh' must be a list of bodies (integers 0..6), got {raw!r}")
        replace_dh = tuple(
            sorted({_int_in(w, f"replace_dh[{k}]", b, range(COLLISION_N_BODIES), "a body") for k, b in enumerate(raw)})
        )
    segs_raw = table.get("segments", [])
    if not isinstance(segs_raw, (list, tuple)):
        raise RobotFileError(f"{w}: key 'segments' must be an array of tables ([[collision.segments]])")
    segments = tuple(_collision_segment(f"{w}.segments[{k}]", seg) for k, seg in enumerate(segs_raw))
    missing = sorted(set(replace_dh) - {s.body for s in segments})
    if missing:
        raise RobotFileError(
            f"{w}: key 'replace_dh' = {list(replace_dh)}: body {missing[0]} has no segment to replace its DH capsules"
        )
    source = table.get("source", "")
    if not isinstance(source, str):
        raise RobotFileError(f"{w}: key 'source' must be a string, got {source!r}")
    source = " ".join(source.split())  # one line (messages, summary.json)
    return RobotCollision(radii=radii, allowed_pairs=pairs, segments=segments, replace_dh=replace_dh, source=source)


def check_collision_fixed(where: str, robot: Robot, n: int = 4) -> None:
    """Refuse a declared collision segment whose ends move relative to its body.

    Body 0 moves with the base, body i with DH frame i; an end given in another frame is fixed
    to the body only when it lies on the joint axes between (e.g. a point on joint i's axis given
    in DH frame i-1 or i). Checked at ``n`` fixed pseudo-random configurations within the limits.
    """
    col = robot.collision
    if col is None or not col.segments:
        return
    from .transforms import dh_chain_frames

    rng = np.random.default_rng(0)
    qs = rng.uniform(robot.q_min, robot.q_max, (n, 6))
    F = [
        dh_chain_frames(robot.convention, robot.a, robot.alpha, robot.d, robot.theta_offset, q, robot.frame02base)
        for q in qs
    ]
    reach = float(np.sum(np.abs(robot.a)) + np.sum(np.abs(robot.d)))
    tol = COLLISION_FIXED_TOL_M_PER_M * max(1.0, reach)
    for k, seg in enumerate(col.segments):
        for end, frame, xyz in (("a", seg.frame_a, seg.xyz_a), ("b", seg.frame_b, seg.xyz_b)):
            local = []
            for Fq in F:
                T = np.eye(4) if frame < 0 else Fq[frame]
                p = T[:3, :3] @ xyz + T[:3, 3]
                B = np.eye(4) if seg.body == 0 else Fq[seg.body]
                local.append(B[:3, :3].T @ (p - B[:3, 3]))
            spread = float(np.max(np.ptp(np.array(local), axis=0)))
            if spread > tol:
                raise RobotFileError(
                    f"{where}: collision.segments[{k}]: end {end} (frame_{end} = {frame}, xyz_{end} = "
                    f"{[float(v) for v in xyz]}) is not fixed to body {seg.body}: it moves by {spread:.3g} m "
                    f"relative to it; a point of body {seg.body} is given in DH frame {seg.body}"
                    + (" (or the base frame -1 / DH frame 0)" if seg.body == 0 else "")
                    + ", or in a neighbouring frame only when it lies on the joint axis between"
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
