"""Robot files that name a URDF: the chain between two links, read with ``yourdfpy``, as a DH model.

A URDF-based robot file (``docs/robot-file.md``) gives ``urdf``, ``base_link``, ``tip_link``
(the flange) and the joint stiffnesses.  This module reads the kinematic chain from
``base_link`` down to ``tip_link`` and turns it, exactly, into the product's one chain form:
a **modified-DH** table (Khalil-Kleinfinger / Craig) with a fixed transform ``frame02base``
(DH frame 0 -> base link) before it and ``flange2frame6`` (tip link -> DH frame 6) after it.
Every model function, effect, IK family and identification parametrisation then works on it
unchanged.

Reading the URDF (``docs/robot-file.md``, "URDF-based robot files"):

* only ``revolute`` joints move; ``fixed`` joints are folded into the neighbouring
  transforms; ``continuous`` joints need limits in the robot file; ``prismatic``,
  ``planar``, ``floating`` joints and ``mimic`` joints in the chain are errors;
* exactly 6 revolute joints between ``base_link`` and ``tip_link``;
* a joint's angle ``q`` is the URDF joint variable (same zero, same sign), so the
  controller's angles are the model's;
* link masses, centres of mass and inertias: every link rigidly attached after joint *i*
  (fixed joints, also off the chain) is one body; its mass, centre of mass and inertia
  about the centre of mass are combined and expressed in DH frame *i*.  Links hanging
  off the chain by a moving joint are left out (a note says which).

The DH frames are chosen so that frame *i*'s z axis is joint *i*'s URDF axis: frame 0 is the
base link's frame when joint 1 turns about its z axis (else a frame on joint 1's axis),
each common normal is taken from joint *i* towards joint *i + 1* (``a >= 0``), frames on
parallel axes keep ``d = 0``, and frame 6 sits where the tip link's origin projects on
joint 6's axis, with ``theta_offset_6 = 0``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from xml.etree import ElementTree
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from .robot import (
    Joint,
    Robot,
    RobotFileError,
    _angle,
    _finite,
    _vector,
    inertia_matrix,
    CollisionSegment,
    RobotCollision,
    check_collision_fixed,
    parse_collision_table,
    parse_controller,
    parse_frame_table,
    read_text_file,
)
from .constants import PLAUSIBLE_JOINT_SPEED_MAX_RAD_S, STANDARD_GRAVITY
from .degenerate import URDF_HINT, check_chain, poe_axes
from .transforms import dh_chain_frames, poe_fk

#: Keys of a URDF-based robot file.
URDF_TOP_KEYS = (
    "name",
    "description",
    "source",
    "urdf",
    "base_link",
    "tip_link",
    "stiffness",
    "a_max",
    "j_max",
    "gravity",
    "tool",
    "joints",
    "identified",
    "controller",
    "collision",
)
#: Per-joint override keys (``[joints.<urdf joint name>]``).
URDF_JOINT_KEYS = ("q_min", "q_max", "q_min_deg", "q_max_deg", "v_max", "a_max", "j_max")
#: A joint axis shorter than this (URDF ``<axis xyz>``) is refused as zero.
AXIS_MIN_NORM = 1e-9
#: Two axes closer to parallel than this (sine of the angle) are treated as parallel.
DH_PARALLEL_TOL = 1e-9
#: Two axes closer than this (m) are treated as meeting.
DH_INTERSECT_TOL_M = 1e-9
#: Two nearly parallel axes whose common normal lies farther than this many arm sizes from the
#: chain are refused (the DH form is ill-conditioned there).
DH_NEAR_PARALLEL_REACH = 10.0
#: The DH model must reproduce the URDF chain's flange pose to this (m and rotation entries).
DH_CHECK_TOL = 1e-10
#: A URDF joint limit beyond two turns (rad) is implausible: degrees written as radians.
PLAUSIBLE_URDF_LIMIT_RAD = 4.0 * math.pi * (1.0 + 1e-9)
#: Without an ``a_max`` the acceleration limit is ``v_max / DEFAULT_TIME_TO_SPEED_S`` (full speed in this time).
DEFAULT_TIME_TO_SPEED_S = 0.5
#: Without a ``j_max`` the jerk limit is ``a_max / DEFAULT_TIME_TO_ACCEL_S``.
DEFAULT_TIME_TO_ACCEL_S = 0.1


# --------------------------------------------------------------------------------------
# The chain read from the URDF
# --------------------------------------------------------------------------------------


@dataclass
class Body:
    """Mass properties of one rigid body, in the frame of the body's first link.

    ``mass`` kg; ``com`` (3,) m; ``inertia`` (3, 3) kg*m^2 about the centre of mass.
    """

    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    links: list[str] = field(default_factory=list)

    def add(self, mass: float, com: np.ndarray, inertia: np.ndarray) -> None:
        """Add a part (mass, com, inertia about its own com, all in this body's frame)."""
        if mass <= 0.0:
            return
        total = self.mass + mass
        c = (self.mass * self.com + mass * com) / total
        I = _shift(self.inertia, self.mass, self.com - c) + _shift(inertia, mass, com - c)
        self.mass, self.com, self.inertia = total, c, I


def _shift(I: np.ndarray, m: float, r: np.ndarray) -> np.ndarray:
    """Inertia about a point at ``-r`` from the centre of mass (parallel-axis theorem)."""
    return I + m * (float(r @ r) * np.eye(3) - np.outer(r, r))


@dataclass
class UrdfChain:
    """The moving part of a URDF between two links, at q = 0.

    Attributes
    ----------
    joint_names : list of str, length 6
    frames : ndarray, shape (6, 4, 4)
        Joint frame *i* (the child link frame of joint *i*) in the base link frame at q = 0.
    axes : ndarray, shape (6, 3)
        Unit axis of joint *i* in its joint frame.
    tip : ndarray, shape (4, 4)
        Tip link frame in the base link frame at q = 0.
    limits : list of (lower, upper, velocity) with None where the URDF gives none
    continuous : list of bool
    bodies : list of Body, length 6
        Mass properties after joint *i*, in joint frame *i*.
    notes : list of str
    """

    joint_names: list[str]
    frames: np.ndarray
    axes: np.ndarray
    tip: np.ndarray
    limits: list[tuple[float | None, float | None, float | None]]
    continuous: list[bool]
    bodies: list[Body]
    notes: list[str]
    #: The parsed URDF (yourdfpy), for its collision elements and link frames (``urdf_collision``).
    model: Any = field(default=None, repr=False)

    def zero_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit axes ``w`` (6, 3) and points ``p`` (6, 3), base link frame, at q = 0."""
        w = np.einsum("nij,nj->ni", self.frames[:, :3, :3], self.axes)
        return w, self.frames[:, :3, 3].copy()


def _origin(where: str, j: Any) -> np.ndarray:
    T = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
    if not np.all(np.isfinite(T)):
        raise RobotFileError(f"{where}: joint '{j.name}': <origin> is not finite (NaN or inf)")
    return T


def _load_urdf(where: str, path: Path) -> Any:
    try:
        import yourdfpy
    except ImportError:  # pragma: no cover - a declared dependency
        raise RobotFileError(f"{where}: reading a URDF needs the package 'yourdfpy' (pip install yourdfpy)") from None
    text = read_text_file(path, "URDF file", RobotFileError)
    if "<robot" not in text:
        raise RobotFileError(f"{path}: not a URDF (no <robot> element)")
    try:  # well-formedness first: the URDF parser would otherwise guess at broken XML
        ElementTree.fromstring(text.encode("utf-8"))
    except ElementTree.ParseError as exc:
        line, col = exc.position
        raise RobotFileError(f"{path}: not well-formed XML at line {line}, column {col + 1}: {exc}") from None
    try:
        return yourdfpy.URDF.load(
            str(path), build_scene_graph=False, load_meshes=False, load_collision_meshes=False
        ).robot
    except Exception as exc:
        raise RobotFileError(f"{path}: not a readable URDF: {exc}") from None


def _chain_joints(where: str, model: Any, base_link: str, tip_link: str) -> tuple[np.ndarray, list[Any]]:
    """The path from base_link to tip_link: the fixed transform from base_link up to the
    links' common ancestor (fixed joints only), and the joints from there down to tip_link."""
    links = {lk.name for lk in model.links}
    for key, name in (("base_link", base_link), ("tip_link", tip_link)):
        if name not in links:
            raise RobotFileError(f"{where}: key '{key}' = {name!r}: no such link in the URDF; links: {sorted(links)}")
    parent_joint = {j.child: j for j in model.joints}

    def up(link: str) -> list[Any]:
        out = []
        while link in parent_joint:
            out.append(parent_joint[link])
            link = parent_joint[link].parent
        return out

    tip_up, base_up = up(tip_link), up(base_link)
    tip_links = [tip_link] + [j.parent for j in tip_up]
    base_links = [base_link] + [j.parent for j in base_up]
    common = next((lk for lk in base_links if lk in tip_links), None)
    if common is None:
        raise RobotFileError(f"{where}: base_link {base_link!r} and tip_link {tip_link!r} are in different trees")
    rise = base_up[: base_links.index(common)]
    moving = [j.name for j in rise if j.type != "fixed"]
    if moving:
        raise RobotFileError(
            f"{where}: tip_link {tip_link!r} is not below base_link {base_link!r} in the URDF tree: "
            f"the path from the base goes up through the moving joint(s) {moving} to {common!r}; "
            "the chain must run from base_link down to tip_link"
        )
    base2common = np.eye(4)
    for j in rise:  # base_link -> ... -> common, all fixed
        base2common = _origin(where, j) @ base2common
    return np.linalg.inv(base2common), tip_up[: tip_links.index(common)][::-1]


def _check_joint(where: str, j: Any) -> None:
    if j.mimic is not None:
        raise RobotFileError(
            f"{where}: joint '{j.name}' mimics joint '{j.mimic.joint}': mimic joints are not "
            "supported in the chain (every chain joint must be driven)"
        )
    if j.type in ("prismatic", "planar", "floating"):
        raise RobotFileError(
            f"{where}: joint '{j.name}' is {j.type}: only revolute (and fixed) joints may be in "
            "the chain between base_link and tip_link"
        )
    if j.type not in ("revolute", "continuous", "fixed"):
        raise RobotFileError(f"{where}: joint '{j.name}' has unknown type {j.type!r}")


def read_chain(where: str, urdf_path: Path, base_link: str, tip_link: str) -> UrdfChain:
    """Read the chain between two links of a URDF (see the module docstring for the rules).

    Raises
    ------
    RobotFileError
        Naming the file, the joint or link, the value and what was expected.
    """
    model = _load_urdf(where, urdf_path)
    common2base, joints = _chain_joints(where, model, base_link, tip_link)
    for j in joints:
        _check_joint(where, j)
    moving = [j for j in joints if j.type != "fixed"]
    if len(moving) != 6:
        raise RobotFileError(
            f"{where}: {len(moving)} moving joint(s) between {base_link!r} and {tip_link!r} "
            f"({[j.name for j in moving]}); expected 6 revolute joints"
        )
    T = common2base.copy()
    frames, axes, limits = [], [], []
    for j in joints:
        T = T @ _origin(where, j)
        if j.type == "fixed":
            continue
        ax = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, dtype=float)
        if not np.all(np.isfinite(ax)):
            raise RobotFileError(f"{where}: joint '{j.name}': <axis xyz> = {[float(x) for x in ax]} is not finite")
        n = float(np.linalg.norm(ax))
        if n < AXIS_MIN_NORM:
            raise RobotFileError(
                f"{where}: joint '{j.name}': <axis xyz> = {[float(x) for x in ax]} is zero; expected a direction"
            )
        frames.append(T.copy())
        axes.append(ax / n)
        lim = j.limit
        limits.append((None, None, None) if lim is None else (lim.lower, lim.upper, lim.velocity))
    notes: list[str] = []
    bodies = _bodies(where, model, moving, notes)
    return UrdfChain(
        joint_names=[j.name for j in moving],
        frames=np.array(frames),
        axes=np.array(axes),
        tip=T,
        limits=limits,
        continuous=[j.type == "continuous" for j in moving],
        bodies=bodies,
        notes=notes,
        model=model,
    )


def _check_inertial(where: str, link: str, mass: float, origin: np.ndarray, inertia: np.ndarray) -> None:
    """A link's <inertial>: finite, mass >= 0, a physical inertia tensor (clear error naming the link)."""
    if not (math.isfinite(mass) and np.all(np.isfinite(origin)) and np.all(np.isfinite(inertia))):
        raise RobotFileError(f"{where}: link '{link}': <inertial> has a non-finite value")
    if mass < 0:
        raise RobotFileError(f"{where}: link '{link}': <mass value=\"{mass:g}\"> must be >= 0 (kg)")
    v = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    try:
        inertia_matrix(f"{where}: link '{link}': <inertia>", np.array(v))
    except RobotFileError as exc:
        raise RobotFileError(str(exc).replace("key 'inertia'", "<inertia ixx iyy izz ixy ixz iyz>")) from None


def _bodies(where: str, model: Any, moving: list[Any], notes: list[str]) -> list[Body]:
    """Mass properties of the body after each moving joint, in that joint's frame."""
    link_map = {lk.name: lk for lk in model.links}
    children: dict[str, list[Any]] = {}
    for j in model.joints:
        children.setdefault(j.parent, []).append(j)
    chain_names = {j.name for j in moving}
    bodies = []
    for mj in moving:
        body = Body()
        stack = [(mj.child, np.eye(4))]
        while stack:
            name, T = stack.pop()
            body.links.append(name)
            inert = link_map[name].inertial
            if inert is not None and inert.mass is not None:
                O = np.eye(4) if inert.origin is None else np.asarray(inert.origin, dtype=float)
                I = np.zeros((3, 3)) if inert.inertia is None else np.asarray(inert.inertia, dtype=float)
                _check_inertial(where, name, float(inert.mass), O, I)
                R = T[:3, :3] @ O[:3, :3]
                body.add(float(inert.mass), (T @ O)[:3, 3], R @ I @ R.T)
            for cj in children.get(name, []):
                if cj.type == "fixed":
                    stack.append((cj.child, T @ (np.eye(4) if cj.origin is None else np.asarray(cj.origin, float))))
                elif cj.name not in chain_names:
                    notes.append(
                        f"link '{cj.child}' (joint '{cj.name}', {cj.type}) hangs off the chain by a moving "
                        "joint: its mass is left out"
                    )
        bodies.append(body)
    return bodies


# --------------------------------------------------------------------------------------
# The chain as modified DH
# --------------------------------------------------------------------------------------


@dataclass
class DHChain:
    """A modified-DH table with its fixed end transforms (see the module docstring)."""

    a: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    theta_offset: np.ndarray
    frame02base: np.ndarray
    flange2frame6: np.ndarray
    frames0: np.ndarray  # (7, 4, 4): DH frames 0..6 in the base frame at q = 0


def _frame(x: np.ndarray, z: np.ndarray, o: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, o
    return T


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _first_frame(w1: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """DH frame 0: the base frame when joint 1 turns about its z axis, else a frame on axis 1."""
    ez = np.array([0.0, 0.0, 1.0])
    if np.linalg.norm(w1 - ez) < DH_PARALLEL_TOL and np.linalg.norm(p1[:2]) < DH_INTERSECT_TOL_M:
        return np.eye(4)
    o = p1 - float(p1 @ w1) * w1  # foot of the perpendicular from the base origin
    ref = np.array([1.0, 0.0, 0.0]) if abs(w1[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    return _frame(_unit(ref - float(ref @ w1) * w1), w1, o)


def _normal(
    where: str, k: int, entry: np.ndarray, wk: np.ndarray, wn: np.ndarray, pn: np.ndarray, scale: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Origin and x axis of the DH frame on axis ``k`` (1-based, through ``entry``, direction
    ``wk``) towards axis ``k + 1`` (``wn`` through ``pn``), and the length ``a`` of that normal.

    Skew or meeting axes: the foot of the common normal (x from axis k to k + 1, or
    ``wk x wn`` where they meet).  Parallel axes: ``entry`` itself (``d = 0``).
    """
    n = np.cross(wk, wn)
    sin_a = float(np.linalg.norm(n))
    if sin_a > DH_PARALLEL_TOL:
        nh = n / sin_a  # the common normal's direction
        r = pn - entry
        dist = float(r @ nh)  # signed length along nh
        # foot on axis k: entry + s wk with (r - s wk + t wn) perpendicular to both axes
        s = float(np.cross(r, wn) @ n) / sin_a**2
        if abs(s) > DH_NEAR_PARALLEL_REACH * scale:
            raise RobotFileError(
                f"{where}: joints {k} and {k + 1} are nearly but not exactly parallel (angle "
                f"{math.asin(min(sin_a, 1.0)):.3g} rad): their common normal lies {abs(s):.3g} m "
                "away and the DH form is ill-conditioned; give the nominal geometry (exactly "
                "parallel axes) and identify small errors with compplan identify"
            )
        fk = entry + s * wk
        if abs(dist) > DH_INTERSECT_TOL_M:
            return fk, nh * math.copysign(1.0, dist), abs(dist)
        return fk, nh, 0.0
    v = pn - entry
    v = v - float(v @ wk) * wk
    dist = float(np.linalg.norm(v))
    if dist <= DH_INTERSECT_TOL_M:
        raise RobotFileError(
            f"{where}: joints {k} and {k + 1} turn about one and the same axis: the chain has only 5 independent joints"
        )
    return entry, v / dist, dist


def dh_from_axes(where: str, w: np.ndarray, p: np.ndarray, tip: np.ndarray) -> DHChain:
    """The modified-DH table of a chain given by its joint axes at q = 0.

    Parameters
    ----------
    where : str
        For messages (the robot file).
    w, p : ndarray, shape (6, 3)
        Unit joint axes and a point on each, base frame, at q = 0.
    tip : ndarray, shape (4, 4)
        The flange (tip link) in the base frame at q = 0.

    Returns
    -------
    DHChain
        ``A_k = Rx(alpha_k) Tx(a_k) Rz(q_k + theta_offset_k) Tz(d_k)`` (row k holds the previous
        frame's ``a``, ``alpha``), ``flange2base(q) = frame02base A_1 ... A_6 flange2frame6``.
    """
    F = [_first_frame(w[0], p[0])]
    scale = max(1.0, float(np.max(np.abs(p))), float(np.max(np.abs(tip[:3, 3]))))  # arm size, m
    a, alpha, d, off = np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6)
    entry, a_prev = F[0][:3, 3], 0.0  # where the previous frame's x axis meets this axis
    for k in range(6):
        entry = _on_axis(entry, w[k], p[k])
        if k < 5:
            o, x, dist = _normal(where, k + 1, entry, w[k], w[k + 1], p[k + 1], scale)
        else:
            o, x, dist = _on_axis(tip[:3, 3], w[5], p[5]), F[-1][:3, 0], 0.0
        prev = F[-1]
        xp, zp = prev[:3, 0], prev[:3, 2]
        alpha[k] = math.atan2(float(np.cross(zp, w[k]) @ xp), float(zp @ w[k]))
        a[k] = a_prev
        d[k] = float((o - entry) @ w[k])
        off[k] = math.atan2(float(np.cross(xp, x) @ w[k]), float(xp @ x))
        F.append(_frame(x, w[k], o))
        entry, a_prev = o + dist * x, dist
    return DHChain(
        a=a,
        alpha=alpha,
        d=d,
        theta_offset=off,
        frame02base=F[0],
        flange2frame6=np.linalg.inv(F[6]) @ tip,
        frames0=np.array(F),
    )


def _on_axis(point: np.ndarray, w: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Foot of the perpendicular from ``point`` on the line (p, w)."""
    return p + float((point - p) @ w) * w


# --------------------------------------------------------------------------------------
# Checks: the DH model reproduces the URDF chain
# --------------------------------------------------------------------------------------


def check_dh(where: str, w: np.ndarray, p: np.ndarray, tip: np.ndarray, ch: DHChain, n: int = 16) -> None:
    """Raise if the DH form misses the chain's flange pose at ``n`` fixed pseudo-random q."""
    rng = np.random.default_rng(0)
    scale = max(1.0, float(np.max(np.abs(p))), float(np.max(np.abs(tip[:3, 3]))))
    for q in np.vstack([np.zeros(6), rng.uniform(-np.pi, np.pi, (n, 6))]):
        F6 = dh_chain_frames("modified_dh", ch.a, ch.alpha, ch.d, ch.theta_offset, q, ch.frame02base)[6]
        err = np.abs(poe_fk(w, p, tip, q) - F6 @ ch.flange2frame6)
        if err[:3, :3].max() > DH_CHECK_TOL or err[:3, 3].max() > DH_CHECK_TOL * scale:
            raise RobotFileError(
                f"{where}: internal error: the DH form of the URDF chain misses its flange "
                f"pose by {err.max():.3g} at q = {[round(float(x), 4) for x in q]}"
            )


# --------------------------------------------------------------------------------------
# The robot file
# --------------------------------------------------------------------------------------


def _six(where: str, data: Mapping[str, Any], key: str, positive: bool = True) -> np.ndarray | None:
    if key not in data:
        return None
    v = _vector(where, key, data[key], 6)
    if positive and np.any(v <= 0):
        i = int(np.argmax(v <= 0))
        raise RobotFileError(f"{where}: key '{key}'[{i}] (joint {i + 1}) must be > 0, got {v[i]:g}")
    return v


def _joint_limits(where: str, chain: UrdfChain, overrides: Mapping[str, Any], i: int) -> dict[str, float]:
    """q_min, q_max, v_max of chain joint ``i``: the URDF's, replaced by the robot file's overrides."""
    name = chain.joint_names[i]
    ov = overrides.get(name, {})
    w = f"{where}: joints.{name}"
    lo, hi, vel = chain.limits[i]
    out: dict[str, float] = {}
    for key, urdf_val in (("q_min", lo), ("q_max", hi)):
        if key in ov or f"{key}_deg" in ov:
            out[key] = _angle(w, ov, key)
        elif chain.continuous[i]:
            raise RobotFileError(
                f"{where}: joint '{name}' is continuous (no position limits in the URDF); give "
                f"its limits in the robot file: [joints.{name}] q_min_deg = ..., q_max_deg = ..."
            )
        elif urdf_val is None or not math.isfinite(float(urdf_val)):
            raise RobotFileError(
                f"{where}: joint '{name}': the URDF gives no finite "
                f"<limit {key.replace('q_min', 'lower').replace('q_max', 'upper')}>; "
                f"give it in the robot file: [joints.{name}] {key}_deg = ..."
            )
        elif abs(float(urdf_val)) > PLAUSIBLE_URDF_LIMIT_RAD:
            tag = "lower" if key == "q_min" else "upper"
            raise RobotFileError(
                f"{where}: URDF joint '{name}': <limit {tag}=\"{float(urdf_val):g}\"> rad is implausible "
                f"(|value| > {PLAUSIBLE_URDF_LIMIT_RAD:.4g} rad, two turns; URDF limits are in radians); "
                f"override it in the robot file: [joints.{name}] {key}_deg = ..."
            )
        else:
            out[key] = float(urdf_val)
    if out["q_min"] >= out["q_max"]:
        raise RobotFileError(
            f"{where}: joint '{name}': lower limit {out['q_min']:g} rad must be below the upper "
            f"limit {out['q_max']:g} rad"
        )
    if "v_max" in ov:
        out["v_max"] = _positive(where, name, ov, "v_max")
    elif vel is None or not math.isfinite(float(vel)) or float(vel) <= 0:
        raise RobotFileError(
            f"{where}: joint '{name}': the URDF gives no positive <limit velocity> ({vel!r}); "
            f"give it in the robot file: [joints.{name}] v_max = ... (rad/s)"
        )
    else:
        out["v_max"] = float(vel)
    if out["v_max"] <= 0:
        raise RobotFileError(f"{w}: key 'v_max' must be > 0, got {out['v_max']:g}")
    if out["v_max"] > PLAUSIBLE_JOINT_SPEED_MAX_RAD_S:
        raise RobotFileError(
            f"{where}: joint '{name}': velocity limit {out['v_max']:g} rad/s is implausible "
            f"(> {PLAUSIBLE_JOINT_SPEED_MAX_RAD_S:g} rad/s); URDF and robot-file speeds are in rad/s "
            "(degrees per second given?)"
        )
    return out


def _positive(where: str, joint: str, row: Mapping[str, Any], key: str) -> float:
    """An override that must be a positive number (``[joints.<joint>] key``)."""
    v = _finite(f"{where}: joints.{joint}", key, row[key])
    if v <= 0:
        raise RobotFileError(f"{where}: joints.{joint}: key '{key}' must be > 0, got {v:g}")
    return v


def _overrides(where: str, data: Mapping[str, Any], chain: UrdfChain) -> Mapping[str, Any]:
    ov = data.get("joints", {})
    if not isinstance(ov, Mapping):
        raise RobotFileError(
            f"{where}: key 'joints' of a URDF-based robot file is a table of per-joint overrides "
            "([joints.<URDF joint name>]), not an array of DH rows"
        )
    for name, row in ov.items():
        if name not in chain.joint_names:
            raise RobotFileError(
                f"{where}: joints.{name}: no such moving joint in the chain; joints: {chain.joint_names}"
            )
        if not isinstance(row, Mapping):
            raise RobotFileError(f"{where}: joints.{name}: expected a table of overrides")
        bad = sorted(set(row) - set(URDF_JOINT_KEYS))
        if bad:
            raise RobotFileError(f"{where}: joints.{name}: unknown key(s) {bad}; allowed: {list(URDF_JOINT_KEYS)}")
    return ov


def _str_key(where: str, data: Mapping[str, Any], key: str) -> str:
    v = data.get(key)
    if not isinstance(v, str) or not v:
        raise RobotFileError(f"{where}: key '{key}' must be a non-empty string, got {v!r}")
    return v


def robot_from_urdf_dict(data: Mapping[str, Any], where: str, base_dir: Path | None) -> Robot:
    """Build a :class:`Robot` from a URDF-based robot-file dictionary (see ``docs/robot-file.md``).

    Parameters
    ----------
    data : mapping
        The parsed TOML document (has the key ``urdf``).
    where : str
        The robot file, for messages.
    base_dir : Path or None
        Folder the ``urdf`` path is relative to (the robot file's); None: the working folder.
    """
    unknown = sorted(set(data) - set(URDF_TOP_KEYS))
    if unknown:
        hint = "; 'convention' and [[joints]] DH rows belong to DH robot files" if "convention" in unknown else ""
        raise RobotFileError(
            f"{where}: unknown key(s) {unknown} for a URDF-based robot file; allowed: {list(URDF_TOP_KEYS)}{hint}"
        )
    name = _str_key(where, data, "name")
    urdf_rel = _str_key(where, data, "urdf")
    path = Path(urdf_rel) if base_dir is None or Path(urdf_rel).is_absolute() else base_dir / urdf_rel
    base_link, tip_link = _str_key(where, data, "base_link"), _str_key(where, data, "tip_link")
    if "stiffness" not in data:
        raise RobotFileError(f"{where}: missing key 'stiffness' (6 joint stiffnesses, N*m/rad, base to tip)")
    stiffness = _six(where, data, "stiffness")
    chain = read_chain(where, path, base_link, tip_link)
    ov = _overrides(where, data, chain)
    w, p = chain.zero_axes()
    limits = [_joint_limits(where, chain, ov, i) for i in range(6)]
    q_lo, q_hi = (np.array([lim[k] for lim in limits]) for k in ("q_min", "q_max"))
    check_chain(where, poe_axes(w, p), q_lo, q_hi, chain.joint_names, URDF_HINT)  # before its DH form
    ch = dh_from_axes(where, w, p, chain.tip)
    check_dh(where, w, p, chain.tip, ch)
    notes = list(chain.notes)
    a_max, j_max = _six(where, data, "a_max"), _six(where, data, "j_max")
    has_mass = any(b.mass > 0 for b in chain.bodies)
    joints = []
    for i in range(6):
        lim = limits[i]
        row_ov = ov.get(chain.joint_names[i], {})
        am = (
            _positive(where, chain.joint_names[i], row_ov, "a_max")
            if "a_max" in row_ov
            else (float(a_max[i]) if a_max is not None else lim["v_max"] / DEFAULT_TIME_TO_SPEED_S)
        )
        jm = (
            _positive(where, chain.joint_names[i], row_ov, "j_max")
            if "j_max" in row_ov
            else (float(j_max[i]) if j_max is not None else am / DEFAULT_TIME_TO_ACCEL_S)
        )
        mass_kw: dict[str, Any] = {}
        if has_mass:
            b = chain.bodies[i]
            D2J = np.linalg.inv(chain.frames[i]) @ ch.frames0[i + 1]  # DH frame i+1 -> joint frame
            R = D2J[:3, :3]
            com = R.T @ (b.com - D2J[:3, 3])
            mass_kw = {"mass": b.mass, "com": com, "inertia": R.T @ b.inertia @ R}
        joints.append(
            Joint(
                a=float(ch.a[i]),
                alpha=float(ch.alpha[i]),
                d=float(ch.d[i]),
                theta_offset=float(ch.theta_offset[i]),
                q_min=lim["q_min"],
                q_max=lim["q_max"],
                v_max=lim["v_max"],
                a_max=am,
                j_max=jm,
                stiffness=float(stiffness[i]),
                **mass_kw,
            )
        )
    if a_max is None:
        notes.append(
            f"a_max not given: v_max / {DEFAULT_TIME_TO_SPEED_S:g} s assumed (full speed in "
            f"{DEFAULT_TIME_TO_SPEED_S:g} s)"
        )
    if j_max is None:
        notes.append(f"j_max not given: a_max / {DEFAULT_TIME_TO_ACCEL_S:g} s assumed")
    if not has_mass:
        notes.append("the URDF gives no link masses: no self-weight model")
    tcp2flange = parse_frame_table(where, "tool", data.get("tool", {}))
    gravity = _vector(where, "gravity", data.get("gravity", [0.0, 0.0, -STANDARD_GRAVITY]), 3)
    for key in ("description", "source"):
        if not isinstance(data.get(key, ""), str):
            raise RobotFileError(f"{where}: key '{key}' must be a string")
    identified = data.get("identified")
    if identified is not None and not isinstance(identified, Mapping):
        raise RobotFileError(f"{where}: key 'identified' must be a table")
    robot = Robot(
        name=name,
        convention="modified_dh",
        joints=tuple(joints),
        tcp2flange=tcp2flange,
        gravity=gravity,
        description=data.get("description", ""),
        source=data.get("source", ""),
        identified=dict(identified) if identified is not None else None,
        frame02base=ch.frame02base,
        flange2frame6=ch.flange2frame6,
        joint_names=tuple(chain.joint_names),
        urdf={"path": str(path), "base_link": base_link, "tip_link": tip_link},
        notes=tuple(notes),
        **parse_controller(where, data.get("controller")),
        controller_declared="controller" in data,
        collision=urdf_collision(where, path, chain, ch, base_link, tip_link, data.get("collision")),
    )
    check_collision_fixed(where, robot)
    return robot


# --------------------------------------------------------------------------------------
# Collision geometry: the URDF's <collision> elements and link frames as capsules
# --------------------------------------------------------------------------------------

#: Two URDF joint origins closer than this (m) give no link-frame capsule segment.
ORIGIN_SEGMENT_MIN_M = 1e-9
#: A link-frame segment within this distance (m) of joint i+1's axis lies on it (it then belongs to
#: link i+1, as the DH capsules' offsets along joint axes do).
ON_AXIS_TOL_M = 1e-9
#: A mesh's bounding capsule is at least this thick (m): a mesh of collinear vertices.
MESH_MIN_RADIUS_M = 1e-6


def _mesh_path(urdf_path: Path, link: str, filename: str) -> Path:
    """The file of a ``<mesh filename>``: ``package://pkg/sub/file`` relative to the URDF's folder (or
    its parent, the package), ``file://`` absolute, else relative to the URDF's folder."""
    folder = urdf_path.parent
    if filename.startswith("package://"):
        rest = filename[len("package://") :]
        sub = rest.partition("/")[2]
        candidates = [folder / sub, folder.parent / sub, folder / rest, folder.parent / rest]
    elif filename.startswith("file://"):
        candidates = [Path(filename[len("file://") :])]
    else:
        candidates = [Path(filename) if Path(filename).is_absolute() else folder / filename]
    for c in candidates:
        if c.is_file():
            return c
    raise RobotFileError(
        f"{urdf_path}: link '{link}': <collision> mesh '{filename}' not found (looked for "
        f"{', '.join(str(c) for c in dict.fromkeys(candidates))}); put the mesh there or remove the element"
    )


def points_capsule(V: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule containing points (and so their convex hull): along their principal axis.

    Parameters
    ----------
    V : ndarray, shape (N, 3)
        Points, m.

    Returns
    -------
    p0, p1 : ndarray, shape (3,)
        Segment ends, same frame, m.
    radius : float
        The largest distance of a point from the axis (at least :data:`MESH_MIN_RADIUS_M`), m; the
        segment is as short as that radius allows.
    """
    c = V.mean(axis=0)
    X = V - c
    axis = np.linalg.svd(X, full_matrices=False)[2][0] if len(V) > 1 else np.array([0.0, 0.0, 1.0])
    t = X @ axis
    rho = np.linalg.norm(X - np.outer(t, axis), axis=1)
    r = max(float(rho.max()), MESH_MIN_RADIUS_M)
    slack = np.sqrt(np.maximum(r * r - rho * rho, 0.0))
    lo, hi = float(np.min(t + slack)), float(np.max(t - slack))
    if lo > hi:  # a short, thick part: a sphere about the middle
        lo = hi = 0.5 * (lo + hi)
        r = max(r, float(np.max(np.linalg.norm(X - lo * axis, axis=1))))
    return c + lo * axis, c + hi * axis, r


def _element_capsule(where: str, urdf_path: Path, link: str, geom: Any) -> tuple[np.ndarray, np.ndarray, float, str]:
    """The bounding capsule of one ``<collision>`` geometry in its own frame: ends, radius (m), kind."""
    from .collision.shapes import shape_class, shape_kinds

    if geom is None:
        raise RobotFileError(f"{urdf_path}: link '{link}': a <collision> element without <geometry>")
    for kind in shape_kinds():  # the shape kinds that read a URDF element: their bounding capsule
        cls = shape_class(kind)
        element = getattr(geom, cls.urdf_element, None) if cls.urdf_element else None
        if element is not None:
            return (*cls.from_urdf(element).bounding_capsule(), kind)
    if geom.mesh is not None:  # a mesh: the capsule of its vertices, scaled per axis (points_capsule)
        path = _mesh_path(urdf_path, link, geom.mesh.filename)
        try:
            import trimesh

            mesh = trimesh.load(str(path), force="mesh")
            V = np.asarray(mesh.vertices, dtype=float)
        except Exception as exc:
            raise RobotFileError(f"{path}: link '{link}': cannot read the <collision> mesh: {exc}") from None
        if V.ndim != 2 or len(V) == 0 or not np.all(np.isfinite(V)):
            raise RobotFileError(f"{path}: link '{link}': the <collision> mesh has no finite vertices")
        scale = 1.0 if geom.mesh.scale is None else np.asarray(geom.mesh.scale, dtype=float)
        p0, p1, r = points_capsule(V * scale)
        return p0, p1, r, f"mesh {path.name}"
    raise RobotFileError(f"{urdf_path}: link '{link}': a <collision> <geometry> that is no box, cylinder, sphere, mesh")


def _body_links(model: Any, chain: UrdfChain, base_link: str) -> list[list[tuple[str, np.ndarray]]]:
    """Per body 0..6, the links rigidly attached to it and each link's frame in the body's frame:
    body 0 the links joined to ``base_link`` by fixed joints (base_link frame), body i those after
    joint i (its child link's frame)."""
    chain_names = set(chain.joint_names)
    by_parent: dict[str, list[Any]] = {}
    by_child: dict[str, Any] = {}
    for j in model.joints:
        by_parent.setdefault(j.parent, []).append(j)
        by_child[j.child] = j

    def origin(j: Any) -> np.ndarray:
        return np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)

    def component(start: str, up: bool) -> list[tuple[str, np.ndarray]]:
        seen, out, stack = {start}, [], [(start, np.eye(4))]
        while stack:
            name, T = stack.pop()
            out.append((name, T))
            nxt = [(j.child, T @ origin(j)) for j in by_parent.get(name, []) if j.type == "fixed"]
            pj = by_child.get(name)
            if up and pj is not None and pj.type == "fixed":
                nxt.append((pj.parent, T @ np.linalg.inv(origin(pj))))
            for n, Tn in nxt:
                if n not in seen:
                    seen.add(n)
                    stack.append((n, Tn))
        return out

    joints = {j.name: j for j in model.joints if j.name in chain_names}
    return [component(base_link, up=True)] + [component(joints[n].child, up=False) for n in chain.joint_names]


def _element_segments(
    where: str, urdf_path: Path, chain: UrdfChain, ch: DHChain, base_link: str
) -> list[CollisionSegment]:
    """The URDF's ``<collision>`` elements as bounding capsules fixed in the DH frame of their body."""
    links = {lk.name: lk for lk in chain.model.links}
    out = []
    for body, parts in enumerate(_body_links(chain.model, chain, base_link)):
        # body frame (base link / joint frame i) -> the frame the capsule is given in (base / DH frame i)
        to_dh = np.eye(4) if body == 0 else np.linalg.inv(ch.frames0[body]) @ chain.frames[body - 1]
        for name, link2body in parts:
            for k, col in enumerate(links[name].collisions or []):
                p0, p1, r, kind = _element_capsule(where, urdf_path, name, col.geometry)
                if not (math.isfinite(r) and r > 0 and np.all(np.isfinite(p0)) and np.all(np.isfinite(p1))):
                    raise RobotFileError(f"{urdf_path}: link '{name}': <collision> {kind} has no positive finite size")
                el2link = np.eye(4) if col.origin is None else np.asarray(col.origin, dtype=float)
                if not np.all(np.isfinite(el2link)):
                    raise RobotFileError(f"{urdf_path}: link '{name}': <collision> <origin> is not finite (NaN or inf)")
                T = to_dh @ link2body @ el2link
                a, b = (T[:3, :3] @ p + T[:3, 3] for p in (p0, p1))
                label = col.name or f"#{k + 1}"
                out.append(
                    CollisionSegment(
                        body=body,
                        frame_a=body if body else -1,
                        xyz_a=a,
                        frame_b=body if body else -1,
                        xyz_b=b,
                        radius=float(r),
                        name=f"urdf link '{name}' <collision> {label} ({kind})",
                    )
                )
    return out


def _origin_segments(
    where: str, chain: UrdfChain, ch: DHChain, base_link: str, tip_link: str
) -> list[CollisionSegment]:
    """The lines between consecutive URDF joint origins from ``base_link`` to ``tip_link`` (the
    links' frames, where a URDF's author put its links), each fixed in the DH frame of its link; a
    line on the next joint's axis belongs to that joint's link (as the DH offsets along an axis)."""
    common2base, joints = _chain_joints(where, chain.model, base_link, tip_link)
    w, p = chain.zero_axes()
    T, body = common2base.copy(), 0
    pts = [(np.zeros(3), 0, base_link)]
    for j in joints:
        T = T @ _origin(where, j)
        body += int(j.type != "fixed")
        pts.append((T[:3, 3].copy(), body, j.name))
    out = []
    for (pa, b, na), (pb, _, nb) in zip(pts[:-1], pts[1:]):
        if np.linalg.norm(pb - pa) <= ORIGIN_SEGMENT_MIN_M:
            continue
        on_next_axis = b < 6 and all(np.linalg.norm(np.cross(x - p[b], w[b])) <= ON_AXIS_TOL_M for x in (pa, pb))
        # link b's line, given in DH frame b (the base frame for the base); on joint b+1's axis it is
        # link b+1's, still given in DH frame b (fixed there too; DH frame 0 for a line on joint 1's axis)
        frame = b if (b > 0 or on_next_axis) else -1
        body = b + 1 if on_next_axis else b
        inv = np.linalg.inv(ch.frames0[frame]) if frame >= 0 else np.eye(4)
        la, lb = ((inv @ np.append(x, 1.0))[:3] for x in (pa, pb))
        out.append(
            CollisionSegment(
                body=body,
                frame_a=frame,
                xyz_a=la,
                frame_b=frame,
                xyz_b=lb,
                line=True,
                name=f"urdf joint origins {na} -> {nb}",
            )
        )
    return out


def urdf_collision(
    where: str,
    urdf_path: Path,
    chain: UrdfChain,
    ch: DHChain,
    base_link: str,
    tip_link: str,
    table: Any = None,
) -> RobotCollision | None:
    """The collision geometry of a URDF-based robot: the robot file's ``[collision]`` table, the
    URDF's ``<collision>`` elements (each a bounding capsule fixed in its link's DH frame; a body
    with elements is described by them alone: ``replace_dh``), and for the other bodies the lines
    between the URDF's joint origins (``docs/cell.md``, "URDF collision elements").

    Box: along its longest side, radius the half-diagonal of the other two; cylinder: along its
    axis, its radius and length; sphere: a point with its radius; mesh (``package://`` relative to
    the URDF's folder, read with trimesh): along its vertices' principal axis (:func:`points_capsule`).

    Raises
    ------
    RobotFileError
        A malformed ``[collision]`` table, a mesh that cannot be found or read (naming the file and link).
    """
    declared = parse_collision_table(where, table) if table is not None else None
    elements = _element_segments(where, urdf_path, chain, ch, base_link)
    replaced = set(declared.replace_dh if declared is not None else ()) | {s.body for s in elements}
    frames = [s for s in _origin_segments(where, chain, ch, base_link, tip_link) if s.body not in replaced]
    if declared is None and not elements and not frames:
        return None
    source = declared.source if declared is not None else ""
    if elements:
        linked = sorted({lk.name for lk in chain.model.links if lk.collisions})
        what = f"{urdf_path.name}: <collision> elements of link(s) {', '.join(linked)}"
        source = f"{source}; {what}" if source else what
    return RobotCollision(
        radii=declared.radii if declared is not None else None,
        allowed_pairs=declared.allowed_pairs if declared is not None else None,
        segments=(declared.segments if declared is not None else ()) + tuple(elements) + tuple(frames),
        replace_dh=tuple(sorted(replaced)),
        source=source,
    )
