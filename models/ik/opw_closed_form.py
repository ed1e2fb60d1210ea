"""Closed-form inverse kinematics of ortho-parallel 6R arms with a spherical wrist (OPW).

The OPW family (Brandstötter, Angerer & Hofbaur 2014: KUKA KR, ABB IRB, Fanuc, ...) is
described here by a *canonical* arm standing upright in its own base frame, all
canonical angles ``phi = 0``:

* axis 1 = +z through the origin; axes 2 and 3 along +y through ``(a1, *, c1)`` and
  ``(a1, *, c1 + c2)``;
* wrist centre ``C = (a1 + a2, b, c1 + c2 + c3)``; axes 4 and 6 along +z, axis 5 along
  +y, all three through ``C``; flange origin at ``C + c4 z`` with the base orientation.

Canonical forward kinematics (checked against ``py_opw_kinematics``, which implements
the same model): ``R = Rz(phi1) Ry(phi2 + phi3) Rz(phi4) Ry(phi5) Rz(phi6)``, the wrist
centre in the arm plane ``x = a1 + c2 sin phi2 + c3 sin phi23 + a2 cos phi23``,
``y = b``, ``z = c1 + c2 cos phi2 + c3 cos phi23 - a2 sin phi23``, rotated by
``Rz(phi1)``; the flange origin is ``C + c4 R e_z``.

A robot given in product-of-exponentials form (axes ``w``, points ``p``, zero pose
``M0``) is mapped onto it by :func:`opw_from_axes`; joint ``i`` relates to its canonical
angle by ``phi_i = s_i q_i + o_i`` and, for every ``q``::

    flange2base(q) = canon2base @ FK_canon(phi(q)) @ flange2canon_flange

(``canon2base`` maps canonical-base coordinates to robot-base coordinates,
``flange2canon_flange`` maps robot-flange coordinates to canonical-flange coordinates).
Note that ``offsets`` follow ``phi = s q + o``; the opw_kinematics / rs-opw-kinematics
convention is ``phi = s q - offset``, see :meth:`OPWGeometry.opw_parameters`.

Branches (index ``4*shoulder + 2*elbow + wrist``, :data:`OPW_BRANCH_LABELS`):

* shoulder "front": the arm plane points at the wrist centre (the wrist centre's
  arm-plane x coordinate is positive), "back": it points away (reaching over axis 1);
* elbow: with ``gamma = atan2(a2, c3)``, ``sin(phi3 + gamma)`` is the sine of the signed
  angle of the triangle shoulder-elbow-wrist, ``cross(W - S, E - S) = c2 K sin(phi3 +
  gamma)`` in the arm plane (x, z), ``K = hypot(a2, c3)``.  For "front" (wrist centre
  ahead of the shoulder) ``sin(phi3 + gamma) > 0`` puts the elbow above the
  shoulder-wrist line: "up"; for "back" the wrist centre lies behind the shoulder, the
  line points the other way and "up" is ``sin(phi3 + gamma) < 0``;
* wrist "noflip": ``sin(phi5) > 0``, "flip": ``sin(phi5) < 0`` (``phi4 + pi, -phi5,
  phi6 + pi``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np

from ..errors import InputError
from ..status import CodedStatus
from ..transforms import poe_fk as _poe_fk, rotations_about

#: Structure checks: largest deviation of an axis angle from 0 or pi/2 (rad).
OPW_ANGLE_TOL = 1e-9
#: Structure checks: largest distance between axes that should meet, relative to the arm
#: size (m per m of arm size, see :attr:`OPWGeometry.scale`).
OPW_DIST_TOL_REL = 1e-9
#: Self-check of the extracted model: canonical FK vs PoE FK, largest entry error
#: (rotation entries; positions divided by max(arm size, 1 m)).
OPW_SELFCHECK_TOL = 1e-10
#: Axis directions whose norm differs from 1 by more than this are refused (dimensionless).
OPW_UNIT_TOL = 1e-6
#: :meth:`OPWGeometry.opw_parameters` reports lengths below this (relative to the arm size)
#: and offsets below this (rad) as exact zeros: rounding residue of the extraction.
OPW_PRINT_ZERO = 1e-12
#: Number of random configurations of the self-check.
OPW_SELFCHECK_SAMPLES = 20
#: acos/sqrt arguments beyond their domain by at most this (relative) are clipped;
#: beyond it the branch is unreachable.
OPW_CLIP_TOL = 1e-12
#: |sin(phi5)| below this: wrist singular, phi4 and phi6 not separable (dimensionless).
OPW_WRIST_SINGULAR_TOL = 1e-10
#: Wrist centre closer to axis 1 than this (relative to the arm size) with b = 0:
#: shoulder singular, phi1 undetermined.
OPW_SHOULDER_SINGULAR_TOL_REL = 1e-9

OPW_BRANCH_LABELS: tuple[str, ...] = tuple(
    f"{sh}-{el}-{wr}" for sh in ("front", "back") for el in ("up", "down") for wr in ("noflip", "flip")
)

_TWO_PI = 2.0 * np.pi


class OPWStatus(CodedStatus):
    """Why a branch has (or has no) solution; values and codes shared with :class:`models.ik.IKStatus`
    (the OPW family stores these codes as IK codes)."""

    OK = "ok", 0
    SHOULDER_UNREACHABLE = "shoulder_unreachable", 1  # wrist centre closer to axis 1 than |b|
    WRIST_SINGULAR = "wrist_singular", 3  # sin(phi5) ~ 0: phi4 and phi6 not separable
    ELBOW_UNREACHABLE = "elbow_unreachable", 4  # wrist centre beyond the reach of links 2-3
    SHOULDER_SINGULAR = "shoulder_singular", 6  # wrist centre on axis 1 with b = 0: phi1 undetermined


class NotOPW(InputError):
    """The chain is not ortho-parallel with a spherical wrist; the message names the joints."""


@dataclass(frozen=True)
class OPWGeometry:
    """Canonical OPW parameters of a chain and the map between both descriptions.

    Attributes
    ----------
    a1, a2, b, c1, c2, c3, c4 : float
        Canonical lengths (m), see the module docstring.
    signs : ndarray, shape (6,)
        ``s_i`` = +1 or -1: ``phi_i = s_i q_i + o_i``.
    offsets : ndarray, shape (6,)
        ``o_i`` (rad).
    canon2base : ndarray, shape (4, 4)
        Canonical base frame -> robot base frame.
    flange2canon_flange : ndarray, shape (4, 4)
        Robot flange coordinates -> canonical flange coordinates, so that
        ``flange2base(q) = canon2base @ FK_canon(phi(q)) @ flange2canon_flange``.
    scale : float
        Arm size used for relative tolerances (m): largest distance of the zero-pose
        flange origin from a joint axis.
    """

    a1: float
    a2: float
    b: float
    c1: float
    c2: float
    c3: float
    c4: float
    signs: np.ndarray
    offsets: np.ndarray
    canon2base: np.ndarray
    flange2canon_flange: np.ndarray
    scale: float

    def phi(self, q: np.ndarray) -> np.ndarray:
        """Canonical angles ``s q + o`` (rad) of joint values ``q`` (rad), shape (..., 6)."""
        return np.asarray(q, dtype=float) * self.signs + self.offsets

    def q_from_phi(self, phi: np.ndarray) -> np.ndarray:
        """Joint values ``s (phi - o)`` (rad) of canonical angles, shape (..., 6), not wrapped."""
        return (np.asarray(phi, dtype=float) - self.offsets) * self.signs

    def fk(self, q: np.ndarray) -> np.ndarray:
        """Flange pose ``flange2base`` (m) through the canonical model, q (N, 6) -> (N, 4, 4)."""
        Tc = opw_canonical_fk(self, self.phi(np.atleast_2d(q)))
        return self.canon2base @ Tc @ self.flange2canon_flange

    def opw_parameters(self) -> dict[str, Any]:
        """Parameters in the opw_kinematics convention ``phi = sign * q - offset``.

        Returns
        -------
        dict
            ``a1 .. c4`` (m), ``offsets`` (6 floats, rad, ``= -o``) and
            ``sign_corrections`` (6 ints).  ``py_opw_kinematics.KinematicModel`` takes
            the same offsets (radians with ``Robot(..., degrees=False)``) and
            ``flip_axes = sign_corrections < 0``; its FK is the canonical flange pose.
            Rounding residue (below OPW_PRINT_ZERO) is reported as exact zeros.
        """
        off = -self.offsets
        off = np.where(np.abs(off) < OPW_PRINT_ZERO, 0.0, off)
        lengths = {k: getattr(self, k) for k in ("a1", "a2", "b", "c1", "c2", "c3", "c4")}
        lengths = {k: (0.0 if abs(v) < OPW_PRINT_ZERO * self.scale else v) for k, v in lengths.items()}
        return {
            **lengths,
            "offsets": tuple(float(v) for v in off),
            "sign_corrections": tuple(int(s) for s in self.signs),
        }


# --------------------------------------------------------------------------- numeric FK

_rodrigues = rotations_about


def _check_chain(w: Any, p: Any, M0: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Arrays of a PoE chain, checked: unit axes (6, 3), points (6, 3) m, pose (4, 4)."""
    w, p, M0 = (np.asarray(x, dtype=float) for x in (w, p, M0))
    for name, arr, shape in (("w", w, (6, 3)), ("p", p, (6, 3)), ("M0", M0, (4, 4))):
        if arr.shape != shape:
            raise InputError(f"{name} must have shape {shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"{name} contains non-finite values")
    norms = np.linalg.norm(w, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > OPW_UNIT_TOL)
    if bad.size:
        raise InputError(f"axis {bad[0] + 1} direction is not a unit vector (norm {norms[bad[0]]:.6g})")
    return w / norms[:, None], p, M0


def poe_fk(w: Any, p: Any, M0: Any, q: Any) -> np.ndarray:
    """Product-of-exponentials forward kinematics ``exp([S1] q1) ... exp([S6] q6) M0``.

    Parameters
    ----------
    w : array_like, shape (6, 3)
        Unit joint-axis directions at q = 0, base frame.
    p : array_like, shape (6, 3)
        A point on each joint axis at q = 0, base frame (m).
    M0 : array_like, shape (4, 4)
        ``flange2base`` at q = 0.
    q : array_like, shape (N, 6) or (6,)
        Joint angles (rad), positive about ``w_i`` (right-hand rule).

    Returns
    -------
    ndarray, shape (N, 4, 4)
        ``flange2base`` for each configuration.
    """
    w, p, M0 = _check_chain(w, p, M0)
    return _poe_fk(w, p, M0, np.atleast_2d(np.asarray(q, dtype=float)))


def opw_canonical_fk(geom: OPWGeometry, phi: Any) -> np.ndarray:
    """Canonical flange pose in the canonical base frame, phi (N, 6) rad -> (N, 4, 4)."""
    phi = np.atleast_2d(np.asarray(phi, dtype=float))
    p1, p2, p4, p5, p6 = phi[:, 0], phi[:, 1], phi[:, 3], phi[:, 4], phi[:, 5]
    p23 = p2 + phi[:, 2]
    ez, ey = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
    R = _rodrigues(ez, p1) @ _rodrigues(ey, p23) @ _rodrigues(ez, p4) @ _rodrigues(ey, p5) @ _rodrigues(ez, p6)
    x = geom.a1 + geom.c2 * np.sin(p2) + geom.c3 * np.sin(p23) + geom.a2 * np.cos(p23)
    z = geom.c1 + geom.c2 * np.cos(p2) + geom.c3 * np.cos(p23) - geom.a2 * np.sin(p23)
    C = np.stack([x * np.cos(p1) - geom.b * np.sin(p1), x * np.sin(p1) + geom.b * np.cos(p1), z], axis=-1)
    T = np.broadcast_to(np.eye(4), (phi.shape[0], 4, 4)).copy()
    T[:, :3, :3] = R
    T[:, :3, 3] = C + geom.c4 * R[:, :, 2]
    return T


# --------------------------------------------------------------------------- detection


def _angle_between(u: np.ndarray, v: np.ndarray) -> float:
    """Angle between two directions (rad, in [0, pi])."""
    return float(np.arctan2(np.linalg.norm(np.cross(u, v)), np.dot(u, v)))


def _line_angle(u: np.ndarray, v: np.ndarray) -> float:
    """Angle between two undirected lines (rad, in [0, pi/2])."""
    return float(np.arctan2(np.linalg.norm(np.cross(u, v)), abs(np.dot(u, v))))


def _closest_points(pa: np.ndarray, ua: np.ndarray, pb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of two non-parallel lines ``pa + t ua`` and ``pb + s ub`` (m)."""
    d = pb - pa
    k = np.dot(ua, ub)
    den = 1.0 - k * k
    t = (np.dot(d, ua) - k * np.dot(d, ub)) / den
    s = (k * np.dot(d, ua) - np.dot(d, ub)) / den
    return pa + t * ua, pb + s * ub


def _off_line(x: np.ndarray, p: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Component of ``x - p`` orthogonal to the unit direction ``u`` (m), shape (3,)."""
    d = x - p
    return d - np.dot(d, u) * u


def _wrap(a: float, lo: float = -np.pi) -> float:
    """Angle (rad) wrapped into (lo, lo + 2 pi]."""
    return float(lo + _TWO_PI - np.mod(lo + _TWO_PI - a, _TWO_PI))


def _in_half_turn(a: float) -> bool:
    """``a`` (rad, in [-pi, pi]) lies in (-pi/2, pi/2], up to OPW_ANGLE_TOL in favour of +pi/2."""
    return -np.pi / 2 + OPW_ANGLE_TOL < a <= np.pi / 2 + OPW_ANGLE_TOL


def _check_structure(w: np.ndarray, p: np.ndarray, dtol: float) -> np.ndarray:
    """Raise :class:`NotOPW` unless the axes have the OPW structure; return the wrist centre (m)."""

    def perp(i: int, j: int) -> None:
        dev = abs(_angle_between(w[i], w[j]) - np.pi / 2)
        if dev > OPW_ANGLE_TOL:
            raise NotOPW(
                f"axes {i + 1} and {j + 1} are not perpendicular "
                f"(angle {_angle_between(w[i], w[j]):.6g} rad, expected pi/2)"
            )

    perp(0, 1)
    ang = _line_angle(w[1], w[2])
    if ang > OPW_ANGLE_TOL:
        raise NotOPW(f"axes 2 and 3 are not parallel (angle {ang:.6g} rad)")
    d23 = float(np.linalg.norm(_off_line(p[2], p[1], w[1])))
    if d23 <= dtol:
        raise NotOPW(f"axes 2 and 3 coincide (distance {d23:.3g} m): no upper arm")
    perp(2, 3)
    perp(3, 4)
    perp(4, 5)
    xa, xb = _closest_points(p[3], w[3], p[4], w[4])
    d45 = float(np.linalg.norm(xa - xb))
    if d45 > dtol:
        raise NotOPW(f"axes 4 and 5 do not intersect (distance {d45:.6g} m): no spherical wrist")
    C = 0.5 * (xa + xb)
    d6 = float(np.linalg.norm(_off_line(C, p[5], w[5])))
    if d6 > dtol:
        raise NotOPW(
            f"axes 4, 5 and 6 do not meet in one point (axis 6 misses the "
            f"intersection of axes 4 and 5 by {d6:.6g} m): no spherical wrist"
        )
    if np.linalg.norm(_off_line(C, p[2], w[2])) <= dtol:
        raise NotOPW("the wrist centre (axes 4, 5, 6) lies on axis 3: no forearm")
    return C


def _shoulder_frame(w: np.ndarray, p: np.ndarray, dtol: float) -> dict[str, Any]:
    """Canonical base frame, ``s1, s2, a1, c1``: z along axis 1 (up), y along axis 2, a1 >= 0."""
    zc = w[0].copy()
    lead = zc[2] if abs(zc[2]) > OPW_ANGLE_TOL else zc[np.flatnonzero(np.abs(zc) > OPW_ANGLE_TOL)[0]]
    s1 = 1.0 if lead > 0 else -1.0
    zc = s1 * zc
    y0 = w[1] - np.dot(w[1], zc) * zc
    y0 /= np.linalg.norm(y0)
    a1 = float(np.dot(p[1] - p[0], np.cross(y0, zc)))
    s2 = -1.0 if a1 < -dtol else 1.0
    yc = s2 * y0
    xc = np.cross(yc, zc)
    a1 = float(np.dot(p[1] - p[0], xc))
    origin = p[0] + np.dot(-p[0], zc) * zc  # foot of the base origin on axis 1
    c1 = float(np.dot(p[1] - origin, zc))
    return {"s1": s1, "s2": s2, "a1": a1, "c1": c1, "x": xc, "y": yc, "z": zc, "origin": origin}


def _arm_params(fr: dict[str, Any], w: np.ndarray, p: np.ndarray, C: np.ndarray, dtol: float) -> dict[str, Any]:
    """``c2, o2, s3, b, a2, c3, s4, o3`` and the joint-4 frame at q = 0 (base coordinates)."""
    xc, yc, zc = fr["x"], fr["y"], fr["z"]
    v = p[2] - p[1]
    o2 = float(np.arctan2(np.dot(v, xc), np.dot(v, zc)))
    c2 = float(np.hypot(np.dot(v, xc), np.dot(v, zc)))
    s3 = 1.0 if np.dot(w[2], yc) > 0 else -1.0
    b = float(np.dot(C - fr["origin"], yc))
    v = C - p[2]
    vx, vz = float(np.dot(v, xc)), float(np.dot(v, zc))
    ux, uz = float(np.dot(w[3], xc)), float(np.dot(w[3], zc))
    c3 = vx * ux + vz * uz
    s4 = -1.0 if c3 < -dtol else 1.0
    ux, uz = s4 * ux, s4 * uz
    o23 = float(np.arctan2(ux, uz))
    c3 = vx * np.sin(o23) + vz * np.cos(o23)
    a2 = vx * np.cos(o23) - vz * np.sin(o23)
    x4 = np.cos(o23) * xc - np.sin(o23) * zc
    z4 = np.sin(o23) * xc + np.cos(o23) * zc
    return {
        "c2": c2,
        "o2": o2,
        "s3": s3,
        "b": b,
        "a2": float(a2),
        "c3": float(c3),
        "s4": s4,
        "o3": _wrap(o23 - o2),
        "x4": x4,
        "z4": z4,
    }


def _wrist_params(
    fr: dict[str, Any], arm: dict[str, Any], w: np.ndarray, C: np.ndarray, flange: np.ndarray, dtol: float
) -> dict[str, Any]:
    """``s5, o4, s6, o5, c4``: offsets of joints 4, 5 in (-pi/2, pi/2] where the signs allow."""
    x4, y4, z4 = arm["x4"], fr["y"], arm["z4"]
    o4 = float(np.arctan2(-np.dot(w[4], x4), np.dot(w[4], y4)))
    s5 = 1.0
    if not _in_half_turn(o4):
        s5, o4 = -1.0, _wrap(o4 + np.pi)
    x5 = np.cos(o4) * x4 + np.sin(o4) * y4
    c4 = float(np.dot(flange - C, w[5]))
    if abs(c4) > dtol:
        s6 = 1.0 if c4 > 0 else -1.0
    else:
        o5 = float(np.arctan2(np.dot(w[5], x5), np.dot(w[5], z4)))
        s6 = 1.0 if _in_half_turn(o5) else -1.0
    o5 = float(np.arctan2(s6 * np.dot(w[5], x5), s6 * np.dot(w[5], z4)))
    return {"s5": s5, "o4": o4, "s6": s6, "o5": o5, "c4": max(s6 * c4, 0.0)}


def opw_from_axes(w: Any, p: Any, M0: Any) -> OPWGeometry:
    """Detect the OPW structure of a PoE chain and extract its canonical parameters.

    Parameters
    ----------
    w : array_like, shape (6, 3)
        Unit joint-axis directions at q = 0, base frame; joint i turns positively about w_i.
    p : array_like, shape (6, 3)
        A point on each joint axis at q = 0, base frame (m).
    M0 : array_like, shape (4, 4)
        ``flange2base`` at q = 0.

    Returns
    -------
    OPWGeometry
        With ``flange2base(q) = canon2base @ FK_canon(s * q + o) @ flange2canon_flange``.
        Free choices, made so the numbers look like published ones: the canonical z has a
        non-negative component along base +z; the canonical origin is the foot of the
        perpendicular from the base origin onto axis 1; ``o1 = 0``; ``a1 >= 0`` (``s2 = +1``
        when ``a1 = 0``); ``c2 > 0``; ``c3 > 0`` fixes ``s4``; ``c4 >= 0`` fixes ``s6``;
        ``s5`` puts ``o4`` into (-pi/2, pi/2]; ``o6 = 0`` (the rest goes into
        ``flange2canon_flange``).

    Raises
    ------
    NotOPW
        If an axis pair breaks the structure (the message names the joints and the
        measured angle or distance), or if the extracted model fails the self-check
        against :func:`poe_fk` (OPW_SELFCHECK_TOL at OPW_SELFCHECK_SAMPLES random q).
    InputError
        On malformed arrays.
    """
    w, p, M0 = _check_chain(w, p, M0)
    flange = M0[:3, 3]
    scale = max(float(np.linalg.norm(_off_line(flange, p[i], w[i]))) for i in range(6))
    scale = scale if scale > 0 else 1.0
    dtol = OPW_DIST_TOL_REL * scale
    C = _check_structure(w, p, dtol)
    fr = _shoulder_frame(w, p, dtol)
    arm = _arm_params(fr, w, p, C, dtol)
    wr = _wrist_params(fr, arm, w, C, flange, dtol)
    signs = np.array([fr["s1"], fr["s2"], arm["s3"], arm["s4"], wr["s5"], wr["s6"]])
    offsets = np.array([0.0, arm["o2"], arm["o3"], wr["o4"], wr["o5"], 0.0]) + 0.0  # no -0.0
    canon2base = np.eye(4)
    canon2base[:3, :3] = np.column_stack([fr["x"], fr["y"], fr["z"]])
    canon2base[:3, 3] = fr["origin"]
    geom = OPWGeometry(
        a1=fr["a1"],
        a2=arm["a2"],
        b=arm["b"],
        c1=fr["c1"],
        c2=arm["c2"],
        c3=arm["c3"],
        c4=wr["c4"],
        signs=signs,
        offsets=offsets,
        canon2base=canon2base,
        flange2canon_flange=np.eye(4),
        scale=scale,
    )
    base2canon = np.linalg.inv(canon2base)
    f2cf = np.linalg.inv(opw_canonical_fk(geom, offsets[None])[0]) @ base2canon @ M0
    geom = replace(geom, flange2canon_flange=f2cf)
    q = np.random.default_rng(0).uniform(-np.pi, np.pi, (OPW_SELFCHECK_SAMPLES, 6))
    err = np.abs(geom.fk(q) - poe_fk(w, p, M0, q))
    err[:, :3, 3] /= max(scale, 1.0)
    if err.max() > OPW_SELFCHECK_TOL:
        raise NotOPW(
            f"the canonical OPW model does not reproduce the chain (largest FK error "
            f"{err.max():.3g}); the structure is not OPW"
        )
    return geom


# --------------------------------------------------------------------------- closed form


def _rz_sx(c: ca.SX, s: ca.SX) -> ca.SX:
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def _ry_sx(c: ca.SX, s: ca.SX) -> ca.SX:
    return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))


def _ik_arm(g: OPWGeometry, Cw: ca.SX) -> tuple[list[tuple[ca.SX, ...]], list[ca.SX], ca.SX, ca.SX]:
    """Shoulder and elbow for the wrist centre ``Cw`` (canonical base, m).

    Returns the four (phi1, phi2, phi3) in the order front-up, front-down, back-up,
    back-down, the unclipped elbow cosines per shoulder, and the shoulder-unreachable /
    shoulder-singular flags.
    """
    r = ca.sqrt(Cw[0] ** 2 + Cw[1] ** 2)
    rho = ca.sqrt(ca.fmax(r**2 - g.b**2, 0.0))
    tol = OPW_SHOULDER_SINGULAR_TOL_REL * g.scale
    b_zero = abs(g.b) <= OPW_DIST_TOL_REL * g.scale
    sh_unreach = ca.SX(0) if b_zero else r < abs(g.b) * (1.0 - OPW_CLIP_TOL)
    sh_sing = r < tol if b_zero else ca.SX(0)
    psi, beta = ca.atan2(Cw[1], Cw[0]), ca.atan2(g.b, rho)
    K = float(np.hypot(g.a2, g.c3))
    gamma = float(np.arctan2(g.a2, g.c3))
    dz = Cw[2] - g.c1
    sols, cosines = [], []
    for front in (True, False):
        phi1 = psi - beta if front else psi + beta - np.pi
        dx = (rho if front else -rho) - g.a1
        c3e = (dx**2 + dz**2 - g.c2**2 - K**2) / (2.0 * g.c2 * K)
        cosines.append(c3e)
        cc = ca.fmin(ca.fmax(c3e, -1.0), 1.0)
        sn = ca.sqrt(1.0 - cc**2)
        # "up" is sin(phi3 + gamma) > 0 in front, < 0 at the back (module docstring).
        for sgn in (1.0, -1.0) if front else (-1.0, 1.0):
            phi2 = ca.atan2(dx, dz) - ca.atan2(K * sgn * sn, g.c2 + K * cc)
            phi3 = ca.atan2(sgn * sn, cc) - gamma
            sols.append((phi1, phi2, phi3))
    return sols, cosines, sh_unreach, sh_sing


def _ik_wrist(g: OPWGeometry, R: ca.SX, phi123: tuple[ca.SX, ...]) -> tuple[list[ca.SX], ca.SX]:
    """Both wrist solutions (phi4, phi5, phi6) for the orientation ``R`` (canonical), and |sin phi5|."""
    phi1, phi2, phi3 = phi123
    R03 = ca.mtimes(_rz_sx(ca.cos(phi1), ca.sin(phi1)), _ry_sx(ca.cos(phi2 + phi3), ca.sin(phi2 + phi3)))
    R36 = ca.mtimes(R03.T, R)
    s5 = ca.sqrt(R36[0, 2] ** 2 + R36[1, 2] ** 2)
    singular = s5 < OPW_WRIST_SINGULAR_TOL
    out = []
    for sgn in (1.0, -1.0):
        # Singular: joint 4 held at q4 = 0 (noflip) or its flip partner; phi6 takes the rest.
        phi4 = ca.if_else(
            singular, g.offsets[3] + (0.0 if sgn > 0 else np.pi), ca.atan2(sgn * R36[1, 2], sgn * R36[0, 2])
        )
        phi5 = ca.atan2(sgn * s5, R36[2, 2])
        Rr = ca.mtimes([_ry_sx(ca.cos(phi5), ca.sin(phi5)).T, _rz_sx(ca.cos(phi4), ca.sin(phi4)).T, R36])
        phi6 = ca.atan2(Rr[1, 0], Rr[0, 0])
        out.append(ca.vertcat(phi4, phi5, phi6))
    return out, s5


def opw_ik_function(geom: OPWGeometry) -> ca.Function:
    """The closed-form IK as a CasADi SX Function "opw_ik" (mappable, code-generable).

    Parameters
    ----------
    geom : OPWGeometry
        From :func:`opw_from_axes`.

    Returns
    -------
    casadi.Function
        ``flange2base`` (4x4, m) -> ``q`` (6 x 8, rad, column = branch in
        :data:`OPW_BRANCH_LABELS` order, joint values wrapped to (-pi, pi]) and
        ``status`` (8,, :attr:`OPWStatus.code` values).  ``q`` is finite for finite input;
        mask it by status.  Precedence: SHOULDER_UNREACHABLE, ELBOW_UNREACHABLE,
        SHOULDER_SINGULAR, WRIST_SINGULAR.  Singular branches still carry a solution that
        reproduces the pose (shoulder: phi1 = polar angle of the wrist centre; wrist:
        joint 4 held at q4 = 0 on "noflip", phi4 + pi on "flip", phi6 takes the rest).
    """
    T = ca.SX.sym("flange2base", 4, 4)
    Tc = ca.mtimes([ca.DM(np.linalg.inv(geom.canon2base)), T, ca.DM(np.linalg.inv(geom.flange2canon_flange))])
    R, P = Tc[:3, :3], Tc[:3, 3]
    Cw = P - geom.c4 * R[:, 2]
    arms, cosines, sh_unreach, sh_sing = _ik_arm(geom, Cw)
    qs, codes = [], []
    for k, phi123 in enumerate(arms):
        wrists, s5 = _ik_wrist(geom, R, phi123)
        for phi456 in wrists:
            phi = ca.vertcat(*phi123, phi456)
            q = (phi - ca.DM(geom.offsets)) * ca.DM(geom.signs)
            qs.append(q - _TWO_PI * ca.ceil((q - np.pi) / _TWO_PI))
            code = ca.if_else(
                s5 < OPW_WRIST_SINGULAR_TOL, float(OPWStatus.WRIST_SINGULAR.code), float(OPWStatus.OK.code)
            )
            code = ca.if_else(sh_sing, float(OPWStatus.SHOULDER_SINGULAR.code), code)
            code = ca.if_else(
                ca.fabs(cosines[k // 2]) > 1.0 + OPW_CLIP_TOL, float(OPWStatus.ELBOW_UNREACHABLE.code), code
            )
            code = ca.if_else(sh_unreach, float(OPWStatus.SHOULDER_UNREACHABLE.code), code)
            codes.append(code)
    return ca.Function("opw_ik", [T], [ca.horzcat(*qs), ca.vertcat(*codes)], ["flange2base"], ["q", "status"])


def opw_ik(fun: ca.Function, flange2base: Any) -> tuple[np.ndarray, np.ndarray]:
    """Evaluate :func:`opw_ik_function` over a batch of poses (CasADi ``map``).

    Parameters
    ----------
    fun : casadi.Function
        From :func:`opw_ik_function`.
    flange2base : array_like, shape (N, 4, 4) or (4, 4)
        Target flange poses, base frame (m).

    Returns
    -------
    q : ndarray, shape (N, 8, 6)
        Joint values (rad) per branch; not masked (see ``status``).
    status : ndarray of int, shape (N, 8)
        :attr:`OPWStatus.code` values.
    """
    T = np.asarray(flange2base, dtype=float).reshape(-1, 4, 4)
    n = T.shape[0]
    q, st = fun.map(n)(np.hstack(list(T)))
    q = np.asarray(q).reshape(6, n, 8).transpose(1, 2, 0)
    status = np.rint(np.asarray(st)).astype(int).T.reshape(n, 8)
    return q, status


# --------------------------------------------------------------------------- branch guards


def opw_guard_factors(geom: OPWGeometry, q: Any) -> Any:
    """Three smooth functions of q whose signs identify the branch.

    Parameters
    ----------
    geom : OPWGeometry
    q : casadi.SX, shape (6,) or ndarray, shape (..., 6)
        Joint values (rad).

    Returns
    -------
    casadi.SX, shape (3,) or ndarray, shape (..., 3)
        ``[shoulder, elbow, wrist]``: the signed horizontal distance (m) of the wrist
        centre from axis 1 along the arm-plane x direction (zero where the wrist centre
        is at distance |b| from axis 1); ``sin(phi3 + atan2(a2, c3))`` (zero with the arm
        stretched or folded); ``sin(phi5)`` (zero at the wrist singularity).  Expected
        signs per branch: :func:`opw_branch_signs`.
    """
    gamma = float(np.arctan2(geom.a2, geom.c3))
    if isinstance(q, (ca.SX, ca.MX)):
        phi = [geom.signs[i] * q[i] + geom.offsets[i] for i in range(6)]
        sin, cos = ca.sin, ca.cos
    else:
        qa = np.asarray(q, dtype=float)
        qa = qa.ravel() if isinstance(q, ca.DM) else qa
        phi = [geom.signs[i] * qa[..., i] + geom.offsets[i] for i in range(6)]
        sin, cos = np.sin, np.cos
    p23 = phi[1] + phi[2]
    shoulder = geom.a1 + geom.c2 * sin(phi[1]) + geom.c3 * sin(p23) + geom.a2 * cos(p23)
    elbow = sin(phi[2] + gamma)
    wrist = sin(phi[4])
    if isinstance(q, (ca.SX, ca.MX)):
        return ca.vertcat(shoulder, elbow, wrist)
    return np.stack([shoulder, elbow, wrist], axis=-1)


def opw_branch_signs() -> np.ndarray:
    """Expected signs of :func:`opw_guard_factors` per branch, shape (8, 3), entries +-1.

    Row ``4*shoulder + 2*elbow + wrist``: shoulder +1 front / -1 back; elbow factor +1
    for front-up and back-down, -1 for front-down and back-up; wrist +1 noflip / -1 flip.
    """
    out = np.empty((8, 3))
    for k in range(8):
        sh, el, wr = k // 4, (k // 2) % 2, k % 2
        out[k] = (1 - 2 * sh, (1 - 2 * el) * (1 - 2 * sh), 1 - 2 * wr)
    return out
