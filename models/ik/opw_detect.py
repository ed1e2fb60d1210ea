"""Detection of an ortho-parallel arm with a spherical wrist (:mod:`models.ik.opw`): its canonical
OPW parameters from the chain's joint axes.

:func:`opw_from_axes` reads the chain given as product-of-exponentials axes (``w``, ``p``, ``M0``),
checks the OPW structure (parallel and orthogonal axes, a spherical wrist, a shoulder offset) and
returns the :class:`~models.ik.opw_closed_form.OPWGeometry` of the closed form, checked against the
chain's numeric FK (:func:`poe_fk`) at random configurations; :class:`NotOPW` says why a chain is
not one.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import InputError
from .. import transforms

from .opw_closed_form import OPW_DIST_TOL_REL, TWO_PI, NotOPW, OPWGeometry, opw_canonical_fk

#: Structure checks: largest deviation of an axis angle from 0 or pi/2 (rad).
OPW_ANGLE_TOL = 1e-9
#: Self-check of the extracted model: canonical FK vs PoE FK, largest entry error
#: (rotation entries; positions divided by max(arm size, 1 m)).
OPW_SELFCHECK_TOL = 1e-10
#: Axis directions whose norm differs from 1 by more than this are refused (dimensionless).
OPW_UNIT_TOL = 1e-6
#: Number of random configurations of the self-check.
OPW_SELFCHECK_SAMPLES = 20


# --------------------------------------------------------------------------- numeric FK


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
    return transforms.poe_fk(w, p, M0, np.atleast_2d(np.asarray(q, dtype=float)))


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
    return float(lo + TWO_PI - np.mod(lo + TWO_PI - a, TWO_PI))


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
