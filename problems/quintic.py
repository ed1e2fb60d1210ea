"""Quintic pieces through timed samples and their peaks: NumPy only.

Between two samples ``h`` apart with positions, velocities and accelerations, the quintic that takes
both samples' three values is what a controller interpolating ``(q, qd, qdd)`` runs (ROS 2's
joint_trajectory_controller, :mod:`planner.export.quintic`) and what the dynamic compensation's
command is checked on (:mod:`problems.dynamic`).  One formula for both, in a module that imports
neither CasADi nor SciPy (the command line's start-up reaches it through the ROS 2 export's check).
"""

from __future__ import annotations

import numpy as np

__all__ = ["curve_peaks", "polynomial_value", "quadratic_roots", "quintic_pieces"]


def quintic_pieces(
    t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray
) -> tuple[list[np.ndarray], np.ndarray]:
    """Coefficients ``c0 .. c5`` ((M-1, 6) each, low degree first, in the time since the piece's first
    sample) of the quintic through each two consecutive samples' positions ``q``, velocities ``qd`` and
    accelerations ``qdd`` (M, 6), and the pieces' durations ``h`` (M-1, 1) s; ``t`` (M,) s."""
    h = np.diff(t)[:, None]
    p0, v0, a0, p1, v1, a1 = q[:-1], qd[:-1], qdd[:-1], q[1:], qd[1:], qdd[1:]
    dp = p1 - p0
    c3 = (20.0 * dp - (8.0 * v1 + 12.0 * v0) * h - (3.0 * a0 - a1) * h**2) / (2.0 * h**3)
    c4 = (-30.0 * dp + (14.0 * v1 + 16.0 * v0) * h + (3.0 * a0 - 2.0 * a1) * h**2) / (2.0 * h**4)
    c5 = (12.0 * dp - 6.0 * (v1 + v0) * h - (a0 - a1) * h**2) / (2.0 * h**5)
    return [p0, v0, 0.5 * a0, c3, c4, c5], h


def polynomial_value(c: list[np.ndarray], tau: np.ndarray) -> np.ndarray:
    """``sum c[k] tau^k`` (Horner), broadcast."""
    out = np.zeros(np.broadcast_shapes(c[0].shape, tau.shape))
    for ck in reversed(c):
        out = out * tau + ck
    return out


def quadratic_roots(c0: np.ndarray, c1: np.ndarray, c2: np.ndarray, h: np.ndarray) -> list[np.ndarray]:
    """The real roots of ``c0 + c1 tau + c2 tau^2`` clipped to ``[0, h]`` (0 where there is none), by
    the stable formula (a vanishing ``c2`` leaves the linear root)."""
    disc = c1 * c1 - 4.0 * c2 * c0
    real = disc >= 0.0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        w = -0.5 * (c1 + np.where(c1 >= 0.0, 1.0, -1.0) * np.sqrt(np.where(real, disc, 0.0)))
        r1 = np.where(real & (c2 != 0.0), w / c2, 0.0)
        r2 = np.where(real & (w != 0.0), c0 / w, 0.0)
    return [np.clip(np.nan_to_num(r, nan=0.0, posinf=0.0, neginf=0.0), 0.0, h) for r in (r1, r2)]


def curve_peaks(t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> dict[str, np.ndarray]:
    """Peak magnitude (6,) per joint of the velocity (rad/s), acceleration (rad/s^2) and jerk (rad/s^3)
    of the quintics through consecutive samples (:func:`quintic_pieces`: what a controller that
    interpolates ``(q, qd, qdd)`` runs, and for :func:`problems.dynamic.command_derivatives`' columns
    the spline itself), between the samples included.

    Jerk (a quadratic per piece) and acceleration (a cubic: its extremes at the jerk's roots) exactly;
    the velocity as an upper bound, the samples' largest plus ``max|jerk| h^2 / 8`` of the piece (an
    interior extreme has zero acceleration and lies within ``h / 2`` of a sample).
    """
    c, h = quintic_pieces(np.asarray(t, float), np.asarray(q, float), np.asarray(qd, float), np.asarray(qdd, float))
    jerk = [6.0 * c[3], 24.0 * c[4], 60.0 * c[5]]
    acc = [2.0 * c[2], 6.0 * c[3], 12.0 * c[4], 20.0 * c[5]]
    hh = np.broadcast_to(h, c[0].shape)
    zero = np.zeros_like(hh)
    with np.errstate(divide="ignore", invalid="ignore"):
        vertex = np.clip(np.nan_to_num(-c[4] / (5.0 * c[5]), nan=0.0, posinf=0.0, neginf=0.0), 0.0, hh)
    j_piece = np.max([np.abs(polynomial_value(jerk, tau)) for tau in (zero, hh, vertex)], axis=0)
    a_piece = np.max([np.abs(polynomial_value(acc, tau)) for tau in (zero, hh, *quadratic_roots(*jerk, hh))], axis=0)
    v_piece = np.maximum(np.abs(qd[:-1]), np.abs(qd[1:])) + j_piece * hh**2 / 8.0
    return {"velocity": v_piece.max(axis=0), "acceleration": a_piece.max(axis=0), "jerk": j_piece.max(axis=0)}
