"""A chain given by its joint axes at q = 0 as a modified-DH table with fixed end transforms, and
the check that the DH form reproduces the chain (``models.robot_file.urdf_file``; the frame rules
in its module docstring)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.description import RobotFileError
from models.transforms import dh_chain_frames, poe_fk

#: Two axes closer to parallel than this (sine of the angle) are treated as parallel.
DH_PARALLEL_TOL = 1e-9
#: Two axes closer than this (m) are treated as meeting.
DH_INTERSECT_TOL_M = 1e-9
#: Two nearly parallel axes whose common normal lies farther than this many arm sizes from the
#: chain are refused (the DH form is ill-conditioned there).
DH_NEAR_PARALLEL_REACH = 10.0
#: The DH model must reproduce the URDF chain's flange pose to this (m and rotation entries).
DH_CHECK_TOL = 1e-10


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
