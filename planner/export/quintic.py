"""The quintic spline a ROS 2 joint_trajectory_controller lays between points, and its peaks.

With positions, velocities and accelerations in every point, the controller's ``splines``
interpolation (its default) follows, between two points ``h`` apart, the quintic polynomial that
takes both points' position, velocity and acceleration (ros2_controllers,
joint_trajectory_controller, "Trajectory Representation"); it samples it at its own update rate,
so its positions, velocities, accelerations and jerks bound every command the hardware receives.
They are found segment by segment: the jerk (a quadratic) and the acceleration (a cubic, whose
extremes are the jerk's roots) exactly; the velocity and the position where a bound from the ends
(``(|v0| + |v1| + h max|a|) / 2``; ``h max|v|`` from an end) reaches a limit, on sub-samples, and
exactly (roots of their derivative) wherever the sub-samples and the bound of what lies between
them cannot rule out an excess.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from problems.quintic import polynomial_value, quadratic_roots, quintic_pieces

from planner.export.motion import (
    EXACT_MAX,
    EXPORT_FD_TOL,
    EXPORT_POSITION_TOL,
    SCREEN_SAMPLES,
    SEGMENT_CHUNK,
    ControllerMotion,
    Peak,
)

if TYPE_CHECKING:
    from planner.export.data import ExportData

__all__ = ["quintic_coefficients", "quintic_peaks"]


#: The quintic through each two consecutive points' (q, qd, qdd): the same pieces the dynamic
#: compensation's command is checked on (one formula, :func:`problems.quintic.quintic_pieces`).
quintic_coefficients = quintic_pieces


def _derivative(c: list[np.ndarray]) -> list[np.ndarray]:
    return [k * c[k] for k in range(1, len(c))]


def _extreme(c: list[np.ndarray], taus: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The value of largest magnitude of ``c`` among the times ``taus`` and where, (S, 6) each."""
    vals = np.stack([polynomial_value(c, np.broadcast_to(tau, c[0].shape)) for tau in taus])
    k = np.argmax(np.abs(vals), axis=0)
    at = np.stack([np.broadcast_to(tau, c[0].shape) for tau in taus])
    return np.take_along_axis(vals, k[None], 0)[0], np.take_along_axis(at, k[None], 0)[0]


def _screened(
    c: list[np.ndarray], h: np.ndarray, d2max: np.ndarray, hi: np.ndarray, lo: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Largest and smallest value of the polynomials ``c`` (coefficient arrays (N,), low degree
    first) on ``[0, h]`` and where, (N,) each: on :data:`SCREEN_SAMPLES` sub-samples, and exactly
    (the roots of the derivative) where the sub-samples' extreme plus ``(h/n)^2 d2max / 8``
    (``d2max``: the largest magnitude of its second derivative, what lies between sub-samples)
    reaches ``hi`` or ``lo``; beyond :data:`EXACT_MAX` such entries, that bound itself."""
    n = SCREEN_SAMPLES
    taus = h[None] * (np.arange(n + 1) / n)[:, None]
    vals = polynomial_value(c, taus)
    ka, kb = np.argmax(vals, axis=0), np.argmin(vals, axis=0)
    vmax, vmin = vals.max(axis=0), vals.min(axis=0)
    tmax, tmin = h * ka / n, h * kb / n
    bound = (h / n) ** 2 * d2max / 8.0
    unsure = np.flatnonzero((vmax + bound > hi) | (vmin - bound < lo))
    for e in unsure[:EXACT_MAX]:
        coef = [float(ck[e]) for ck in c]
        crit = np.roots([k * coef[k] for k in range(len(coef) - 1, 0, -1)]) if any(coef[1:]) else np.array([])
        real = crit.real[(np.abs(crit.imag) < 1e-12) & (crit.real > 0) & (crit.real < h[e])]
        tau = np.r_[0.0, float(h[e]), real]
        v = np.polyval(coef[::-1], tau)
        vmax[e], tmax[e], vmin[e], tmin[e] = v.max(), tau[np.argmax(v)], v.min(), tau[np.argmin(v)]
    rest = unsure[EXACT_MAX:]
    vmax[rest] += bound[rest]
    vmin[rest] -= bound[rest]
    return vmax, tmax, vmin, tmin


def _range(
    c: list[np.ndarray], h: np.ndarray, d2max: np.ndarray, hi: np.ndarray, lo: np.ndarray, near: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_screened` of the (S, 6) polynomials ``c`` where ``near`` (a bound cannot clear them);
    elsewhere their end values, (S, 6) each."""
    hh = np.broadcast_to(h, near.shape)
    end = polynomial_value(c, hh)
    vmax, vmin = np.maximum(c[0], end), np.minimum(c[0], end)
    tmax, tmin = np.where(c[0] >= end, 0.0, hh), np.where(c[0] <= end, 0.0, hh)
    if np.any(near):
        his, los = np.broadcast_to(hi, near.shape)[near], np.broadcast_to(lo, near.shape)[near]
        got = _screened([ck[near] for ck in c], hh[near], d2max[near], his, los)
        for arr, part in zip((vmax, tmax, vmin, tmin), got):
            arr[near] = part
    return vmax, tmax, vmin, tmin


def _chunk_peaks(
    data: ExportData, t: np.ndarray, c: list[np.ndarray], h: np.ndarray, names: list[str], how: str, eps: float
) -> list[Peak]:
    """The worst peak of each quantity over one chunk of segments starting at times ``t`` (S,)."""
    vel, acc, jerk = _derivative(c), _derivative(_derivative(c)), _derivative(_derivative(_derivative(c)))
    zero = np.zeros_like(h)
    j_val, j_at = _extreme(jerk, [zero, h, np.clip(-c[4] / np.where(c[5] != 0.0, 5.0 * c[5], np.inf), 0.0, h)])
    a_val, a_at = _extreme(acc, [zero, h, *quadratic_roots(*jerk, h)])
    # |v| <= (|v0| + |v1| + h max|a|) / 2 on the segment: the velocity is solved where that reaches its limit
    v_hi = data.robot_limit("velocity") * (1.0 + EXPORT_FD_TOL)
    near = (
        np.abs(c[1]) + np.abs(vel[0] + h * (vel[1] + h * (vel[2] + h * (vel[3] + h * vel[4])))) + h * np.abs(a_val)
    ) / 2
    v_max, v_tmax, v_min, v_tmin = _range(vel, h, np.abs(j_val), v_hi, -v_hi, near > v_hi)
    # the positions move at most h max|v| from an end: solved where that reaches a joint limit
    p_hi, p_lo = data.q_max + (EXPORT_POSITION_TOL + eps), data.q_min - (EXPORT_POSITION_TOL + eps)
    reach = h * np.maximum(v_max, -v_min)
    p_end = polynomial_value(c, np.broadcast_to(h, c[0].shape))
    near = (np.maximum(c[0], p_end) + reach > p_hi) | (np.minimum(c[0], p_end) - reach < p_lo)
    p_max, p_tmax, p_min, p_tmin = _range(c, h, np.abs(a_val), p_hi, p_lo, near)
    t0 = t[:, None]
    out = []
    v_val = np.where(v_max >= -v_min, v_max, v_min)
    v_at = np.where(v_max >= -v_min, v_tmax, v_tmin)
    for name, val, at in (("velocity", v_val, v_at), ("acceleration", a_val, a_at), ("jerk", j_val, j_at)):
        if name in names:
            lim = data.robot_limit(name)
            score = np.abs(val) / (lim * (1.0 + EXPORT_FD_TOL))
            s, j = np.unravel_index(int(np.argmax(score)), score.shape)
            out.append(
                Peak(name, int(j), float(val[s, j]), float(lim[j]), float(score[s, j]), float(t0[s, 0] + at[s, j]), how)
            )
    up, down = p_max - p_hi, p_lo - p_min
    worst = np.maximum(up, down)
    s, j = np.unravel_index(int(np.argmax(worst)), worst.shape)
    high = up[s, j] >= down[s, j]
    out.append(
        Peak(
            "position",
            int(j),
            float(p_max[s, j] if high else p_min[s, j]),
            float(data.q_max[j] if high else data.q_min[j]),
            1.0 + float(worst[s, j]),
            float(t0[s, 0] + (p_tmax if high else p_tmin)[s, j]),
            how,
        )
    )
    return out


def quintic_peaks(data: ExportData, motion: ControllerMotion, names: list[str], how: str) -> list[Peak]:
    """The worst position and the worst of each rate in ``names`` of the quintic spline through
    ``motion``'s points, :data:`SEGMENT_CHUNK` segments at a time."""
    t, q, qd, qdd = motion.t, motion.q, motion.qd, motion.qdd
    worst: dict[str, Peak] = {}
    for a in range(0, len(t) - 1, SEGMENT_CHUNK):
        b = min(a + SEGMENT_CHUNK, len(t) - 1) + 1
        c, h = quintic_coefficients(t[a:b], q[a:b], qd[a:b], qdd[a:b])
        for p in _chunk_peaks(data, t[a : b - 1], c, h, names, how, motion.eps):
            if p.quantity not in worst or p.score > worst[p.quantity].score:
                worst[p.quantity] = p
    return list(worst.values())
