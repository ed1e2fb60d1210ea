"""Joint tilt: the moments perpendicular to each joint axis tilt the joint (bearing and link).

The moment carried through joint i, about its point ``p_i`` (base frame, N*m), is the
self-weight of the links distal to it plus the external wrench on the TCP::

    m_i = (S_i - M_i p_i) x g + m + (p_load - p_i) x f

with ``S_i = sum_{j>=i} (m_j p_j + R_j h_j)`` and ``M_i = sum_{j>=i} m_j`` exactly as the
``gravity`` effect forms them (its parameters: link masses and first moments; their robot-file
values when ``gravity`` is not added) and ``p_load`` where the force acts (the TCP plus the
``load_offset`` arms).  Its components about the two axes perpendicular to the joint axis,
``x_i`` and ``y_i`` of the joint's DH frame (the frame whose z is the joint axis: DH frame
i-1 in standard DH, which does not turn with joint i; DH frame i in modified DH), times a tilt
compliance per joint and axis give a small rotation of everything distal to the joint::

    phi_i = cx_i (m_i . x_i) x_i + cy_i (m_i . y_i) y_i        (rad)
    dp    = sum_i phi_i x (p - p_i)                            (m)

The moment about the axis itself is the joint torque (``joint_springs``); this adds what it
leaves out.  Only joints whose distal links make up a good part of the arm tilt
(:func:`tilt_joints`: joints 1-3 of a 6R arm with a compact wrist).  Linear in the compliances
``cx, cy`` (rad/(N*m), at least 0; default 0, where the effect vanishes).  Without a varying
wrench only their products with the self-weight are observable; the identifiability step holds
the rest.  The self-weight term is present whether or not ``gravity`` is added (the joint
torques of the self-weight are ``gravity``'s); a robot file without masses leaves only the
wrench to excite it.

Near-aliases (``docs/identification.md`` section 2): on a UR arm the second joint's tilt about
its x axis sees an almost constant moment (the lateral offsets times the weight), which the DH
errors (``dalpha[1]``) take; its y axis is vertical and sees no self-weight moment.  An
isotropic tilt of the first (vertical) joint turns the arm about the same horizontal axis as a
softer second joint under the self-weight, pivoting at the base instead of the shoulder.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from models.robot import Robot

from .base import Effect, ParamGroup, joint_labels, mean_compliance, register

#: Typical tilt compliance as a fraction of the mean joint compliance (dimensionless): a
#: bearing's tilt stiffness is well above the joint's torsional stiffness.
TILT_SCALE_FRACTION = 0.1
#: A joint tilts (has parameters) when the links distal to it are at least this fraction as long
#: as the whole arm (:func:`distal_lengths`, dimensionless): a wrist's
#: tilt moves the TCP by its short lever only, far below the data's noise under self-weight, and
#: left free it trades with the masses (measured: a UR5's joint-4 tilt and masses drifted
#: together, and the fit did not converge, on unloaded data).
TILT_MIN_LEVER_FRACTION = 0.3


def _scale(robot: Robot) -> float:
    return TILT_SCALE_FRACTION * mean_compliance(robot)


def distal_lengths(robot: Robot) -> np.ndarray:
    """Length of the chain distal to each joint, m, shape (6,): the distances from the joint's
    point to the next joint's, and on to the flange, summed (each is the same in every pose)."""
    dh = robot.nominal_dh()
    rows = (np.zeros(6) if dh.get(k) is None else dh[k] for k in ("a", "alpha", "d", "theta_offset", "beta"))
    key = tuple(tuple(float(x) for x in row) for row in rows)
    return np.array(_distal_lengths(robot.convention, key))


@lru_cache(maxsize=32)
def _distal_lengths(convention: str, dh_rows: tuple[tuple[float, ...], ...]) -> tuple[float, ...]:
    """:func:`distal_lengths` of a DH table (``a, alpha, d, theta_offset, beta`` rows), cached: the
    layout asks for it per parameter group."""
    from .graph import chain, joint_axes

    dh = {k: ca.DM(v) for k, v in zip(("a", "alpha", "d", "theta_offset", "beta"), dh_rows)}
    frames = chain(ca.DM.zeros(6), dh, convention)
    _z, ps = joint_axes(frames, convention)
    pts = [np.asarray(ca.DM(p)).reshape(3) for p in ps] + [np.asarray(ca.DM(frames[5][:3, 3])).reshape(3)]
    steps = np.linalg.norm(np.diff(np.array(pts), axis=0), axis=1)
    return tuple(float(x) for x in np.cumsum(steps[::-1])[::-1])


def tilt_joints(robot: Robot) -> np.ndarray:
    """Which joints tilt (bool, (6,)): those whose distal chain is at least
    :data:`TILT_MIN_LEVER_FRACTION` of the arm's (:func:`distal_lengths`; UR5, UR10: joints 1-3)."""
    distal = distal_lengths(robot)
    return distal >= TILT_MIN_LEVER_FRACTION * distal[0]


def joint_rotations(ctx: Any) -> list[Any]:
    """Rotation (base <- frame, 3x3) of the DH frame whose z is each joint's axis, one per joint:
    standard DH: frame i-1 (DH frame 0 for joint 1); modified DH: frame i."""
    if ctx.convention == "standard_dh":
        f0 = ctx.frame02base()
        first = ca.DM.eye(3) if f0 is None else f0[:3, :3]
        return [first] + [T[:3, :3] for T in ctx.frames[:5]]
    return [T[:3, :3] for T in ctx.frames]


def joint_moments(ctx: Any) -> list[Any]:
    """Moment carried through each joint about its point ``p_i``, base frame, N*m, six 3-vectors:
    the distal links' self-weight (``gravity``'s masses and first moments) plus the wrench."""
    mass, h, g = ctx.p("gravity.m"), ctx.p("gravity.h"), ctx.c("gravity")
    f, m = ctx.wrench[0:3], ctx.wrench[3:6]
    p_load = ctx.load_point()
    S, M = ca.DM.zeros(3), 0
    out: list[Any] = [None] * 6
    for j in range(5, -1, -1):
        Rj, pj = ctx.frames[j][:3, :3], ctx.frames[j][:3, 3]
        S = S + mass[j] * pj + ca.mtimes(Rj, h[3 * j : 3 * j + 3])
        M = M + mass[j]
        out[j] = ca.cross(S - M * ctx.ps[j], g) + m + ca.cross(p_load - ctx.ps[j], f)
    return out


@register
class JointTilt(Effect):
    name = "joint_tilt"
    order = 10
    groups = (
        ParamGroup(
            "joint_tilt.cx",
            joint_labels("joint_tilt.cx"),
            "rad/(N*m)",
            scale=_scale,
            bounds=(0.0, np.inf),
            eligible=tilt_joints,
        ),
        ParamGroup(
            "joint_tilt.cy",
            joint_labels("joint_tilt.cy"),
            "rad/(N*m)",
            scale=_scale,
            bounds=(0.0, np.inf),
            eligible=tilt_joints,
        ),
    )
    formula = (
        "tilt of each joint about the axes x_i, y_i perpendicular to it: phi_i = cx_i (m_i.x_i) x_i + "
        "cy_i (m_i.y_i) y_i, m_i the moment through joint i of the distal self-weight and the wrench; "
        "the TCP moves by sum phi_i x (p - p_i)"
    )
    simulation = "joint_tilt"

    def point_displacement(self, ctx: Any, point: Any) -> Any:
        cx, cy = ctx.p("joint_tilt.cx"), ctx.p("joint_tilt.cy")
        rots = joint_rotations(ctx)
        moments = joint_moments(ctx)
        tilts = ctx.eligible_of("joint_tilt.cx") | ctx.eligible_of("joint_tilt.cy")
        dp = ca.DM.zeros(3)
        for i in range(6):
            if not tilts[i]:
                continue
            x, y = rots[i][:, 0], rots[i][:, 1]
            phi = cx[i] * ca.dot(moments[i], x) * x + cy[i] * ca.dot(moments[i], y) * y
            dp = dp + ca.cross(phi, point - ctx.ps[i])
        return dp
