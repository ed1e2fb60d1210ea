"""The geometric path shared by every timing method.

The input is a geometric path given as joint waypoints ``q_path`` (shape
``(N, n)``, rad, joint space). All methods time the *same* path:

A cubic spline ``P(s)`` through the waypoints over the path parameter ``s``
in ``[0, 1]`` (dimensionless), with ``s`` proportional to the cumulative
joint-space chord length (Euclidean norm of the waypoint differences, rad)
and *natural* end conditions (``P''(0) = P''(1) = 0``). The spline is C2, it
passes through every waypoint in order (waypoint ``k`` sits at the knot
``s_k``), and waypoints that lie on a straight line give an exactly straight
path. Natural (rather than clamped zero-derivative) end conditions are used
because ``P'(s) = 0`` would make the path singular for the timing (no
velocity bound from the joint limits) at the ends; rest at the ends comes
from the time law (``ds/dt = 0``), not from the path.

Consecutive waypoints that are *exactly* identical are dropped (they add no
geometry); if that leaves a single waypoint the path has zero length and
:func:`problems.timing.time_parametrize` returns status ``INFEASIBLE``.
Distinct but nearly identical neighbours are kept unless their chord is too
small to give strictly increasing knots, which raises
:class:`~models.errors.InputError` (a ``ValueError``).

Every trajectory is ``q(t) = P(s(t))`` with a monotone scalar time law
``s(t)`` from ``s = 0`` at rest to ``s = 1`` at rest, so it follows the path
exactly. The joint derivatives are obtained analytically by the chain rule::

    qd   = P'(s) sd
    qdd  = P''(s) sd^2 + P'(s) sdd
    qddd = P'''(s) sd^3 + 3 P''(s) sd sdd + P'(s) sddd
"""

from __future__ import annotations

from typing import Any

import numpy as np

from models.errors import InputError

__all__ = ["SplinePath", "validate_path"]


def validate_path(q_path: Any, n: int) -> tuple[np.ndarray, int]:
    """Check ``q_path``; return it without consecutive exact duplicates.

    Parameters
    ----------
    q_path : array_like
        Shape ``(N, n)``, rad (joint space), ``N >= 2``, all finite.
    n : int
        Expected number of joints.

    Returns
    -------
    q : np.ndarray
        Shape ``(N', n)``, rad, a copy with consecutive duplicates removed.
    n_input : int
        Number of waypoints given (``N``).

    Raises
    ------
    InputError
        Not numeric, wrong shape or joint count, fewer than 2 waypoints, or a
        non-finite value (the message names the waypoint row and joint).
    """
    try:
        q = np.array(q_path, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"q_path must be a numeric (N, n) array (rad): {exc}") from exc
    if q.ndim != 2:
        raise InputError(f"q_path must have shape (N, n) with N >= 2, got shape {q.shape}")
    if q.shape[0] < 2:
        raise InputError(f"q_path needs at least 2 waypoints, got {q.shape[0]}")
    if q.shape[1] != n:
        raise InputError(f"q_path has {q.shape[1]} joints (shape {q.shape}) but the limits have {n}")
    bad = np.argwhere(~np.isfinite(q))
    if bad.size:
        row, col = (int(x) for x in bad[0])
        raise InputError(
            f"q_path[{row}, {col}] (waypoint row {row}, joint {col + 1}) is "
            f"{float(q[row, col])!r}; all waypoint values must be finite"
        )
    keep = np.concatenate(([True], np.any(np.diff(q, axis=0) != 0.0, axis=1)))
    return q[keep], int(q.shape[0])


class SplinePath:
    """Natural cubic spline ``P(s)``, ``s`` in [0, 1] by chord length.

    Parameters
    ----------
    q_path : np.ndarray
        Shape ``(N, n)``, rad (joint space), ``N >= 2``, no consecutive
        exact duplicates.

    Attributes
    ----------
    q_path : np.ndarray
        Shape ``(N, n)``, rad, the waypoints.
    knots : np.ndarray
        Shape ``(N,)``, path parameter of each waypoint, from 0 to 1.
    length : float
        Joint-space chord length of the polygon through the waypoints (rad).
    spline : scipy.interpolate.CubicSpline
        ``P(s)``, values of shape ``(n,)`` in rad.
    abs_max : tuple of np.ndarray
        ``(A1, A2, A3)``, each shape ``(n,)``: the exact maxima over ``s`` of
        ``|P'|, |P''|, |P'''|`` per joint (rad per unit of ``s``, ``s^2``,
        ``s^3``).

    Raises
    ------
    InputError
        If two distinct neighbours are too close to give strictly increasing
        knots.
    """

    def __init__(self, q_path: np.ndarray) -> None:
        chord = np.linalg.norm(np.diff(q_path, axis=0), axis=1)
        total = float(chord.sum())
        s = np.concatenate(([0.0], np.cumsum(chord))) / total
        s[-1] = 1.0
        steps = np.diff(s)
        if np.any(steps <= 0.0):
            k = int(np.flatnonzero(steps <= 0.0)[0])
            raise InputError(
                f"waypoints {k} and {k + 1} are distinct but too close "
                f"(joint-space distance {chord[k]:.3g} rad on a path of length "
                f"{total:.3g} rad) to give increasing path parameters; remove one"
            )
        self.q_path = q_path
        self.knots = s  # (N,)
        self.length = total  # rad (joint-space chord length)
        from scipy.interpolate import CubicSpline  # SciPy on first use: reading a problem file does not need it

        self.spline = CubicSpline(s, q_path, bc_type="natural")
        self._d1 = self.spline.derivative(1)
        self._d2 = self.spline.derivative(2)
        self._d3 = self.spline.derivative(3)
        self.abs_max = self._exact_abs_maxima()  # (A1, A2, A3), each (n,)

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return int(self.q_path.shape[1])

    def _exact_abs_maxima(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact ``max_s |P'|, |P''|, |P'''|`` per joint, each shape ``(n,)``.

        ``P'''`` is piecewise constant, ``P''`` piecewise linear and ``P'``
        piecewise quadratic, so the maxima are at the knots or, for ``P'``,
        at the vertex of a parabola inside an interval.
        """
        c = self.spline.c  # (4, N-1, n): c0 h^3 + c1 h^2 + c2 h + c3
        h = np.diff(self.knots)[:, None]  # (N-1, 1)
        c0, c1, c2 = c[0], c[1], c[2]
        a3 = np.abs(6.0 * c0).max(axis=0)
        a2 = np.maximum(np.abs(2.0 * c1), np.abs(6.0 * c0 * h + 2.0 * c1)).max(axis=0)
        d1_end = 3.0 * c0 * h**2 + 2.0 * c1 * h + c2
        a1 = np.maximum(np.abs(c2), np.abs(d1_end))
        with np.errstate(divide="ignore", invalid="ignore"):
            h_star = np.where(c0 != 0.0, -c1 / (3.0 * c0), -1.0)
            inner = (h_star > 0.0) & (h_star < h)
            v_star = np.where(inner, c2 - c1**2 / (3.0 * np.where(c0 != 0, c0, 1.0)), 0.0)
        a1 = np.maximum(a1, np.abs(v_star)).max(axis=0)
        return a1, a2, a3

    def evaluate(
        self, s: np.ndarray, sd: np.ndarray, sdd: np.ndarray, sddd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Joint trajectory from a time law by the chain rule.

        Parameters
        ----------
        s, sd, sdd, sddd : np.ndarray
            Shape ``(M,)``: path parameter (-) and its first three time
            derivatives (1/s, 1/s^2, 1/s^3). ``s`` is clipped to [0, 1].

        Returns
        -------
        q, qd, qdd, qddd : np.ndarray
            Shape ``(M, n)``: rad, rad/s, rad/s^2, rad/s^3 (joint space).
        """
        s = np.clip(s, 0.0, 1.0)
        p0 = self.spline(s)
        p1 = self._d1(s)
        p2 = self._d2(s)
        p3 = self._d3(s)
        sd_ = sd[:, None]
        sdd_ = sdd[:, None]
        qd = p1 * sd_
        qdd = p2 * sd_**2 + p1 * sdd_
        qddd = p3 * sd_**3 + 3.0 * p2 * (sd_ * sdd_) + p1 * sddd[:, None]
        return p0, qd, qdd, qddd
