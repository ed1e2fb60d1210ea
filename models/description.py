"""Robot descriptions: the data read from a robot file, validated.

A :class:`Robot` is the *description* of an arm (DH table, limits, stiffness,
masses, tool).  Working data computed from it (symbolic functions, caches) live
in :mod:`models.symbolic`, in the spirit of pinocchio's ``model``/``data`` split.
The readers of robot files (a DH table, a URDF-based file) are :mod:`models.robot_file`;
:mod:`models.robot` re-exports both, the names callers use.

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
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .constants import STANDARD_GRAVITY
from .errors import InputError

CONVENTIONS = ("standard_dh", "modified_dh")
BUILTIN_ROBOTS = ("ar5", "ur5", "ur10", "ur5e", "kr6_r900")
#: The keys every ``[[joints]]`` row of a DH robot file holds (``to_dict`` writes them).
JOINT_REQUIRED = ("a", "alpha", "d", "theta_offset", "q_min", "q_max", "v_max", "a_max", "j_max", "stiffness")


class RobotFileError(InputError):
    """A robot file (or robot dictionary) is malformed; the message names where."""


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

    def nominal_dh(self, frame02base: Any = None) -> dict[str, Any]:
        """The nominal DH parameters in the form the model graph's chain reads
        (:func:`models.effects.graph.chain`): ``a``, ``alpha``, ``d`` (m, rad), ``theta_offset`` (rad),
        ``beta`` (rad, zero: no Hayati tilt) and ``frame02base`` as given (``None``: frame 0 is the
        base frame; else a 4 x 4 transform, NumPy or CasADi)."""
        return {
            "a": self.a,
            "alpha": self.alpha,
            "d": self.d,
            "theta_offset": self.theta_offset,
            "beta": np.zeros(6),
            "frame02base": frame02base,
        }

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
            row: dict[str, Any] = {k: float(getattr(j, k)) for k in JOINT_REQUIRED}
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
