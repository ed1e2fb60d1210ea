"""A cutting stretch's joint waypoints smoothed within the path tolerance, so that the joint path's
higher derivatives come from the part's shape, not from its facets.

A CAM program's 3-D finishing moves are chords of the surface within a chordal tolerance, printed
to 0.001 mm, a few µm to tens of mm long; the postures are optimised waypoint by waypoint. A spline
through those waypoints turns at every chord end and carries the rounding and the posture's small
waviness: its third derivative, the joints' jerk at the feed, is that of the facets (``d3q/dtau3``
of noise ``e`` on steps ``h``: ``e / h^3``), and a jerk-limited law must crawl there.

Here the waypoints ``q_k`` of one stretch, at programmed times ``tau_k`` (s), are replaced by
``q_k + d_k``, the minimiser of::

    sum_k w_k |J_k d_k|^2  +  lam * sum_i h_i |D3(q + d)_i|^2

where ``D3`` is the third divided difference (times 3!, rad/s^3: the joints' jerk at the feed)
over waypoints ``i .. i+3`` and ``h_i`` their span in ``tau`` (a discrete ``integral |q'''|^2``),
and ``J_k`` the Jacobian of the TCP and of a point up its tool axis (so ``|J_k d_k|`` is how far
the smoothing moves them, to first order; a rotation about the tool axis moves neither);
the stretch's end waypoints (stops) are kept (``d = 0``). The system is banded (bandwidth 3 waypoints, the joints
interleaved), so a solve is linear in the waypoints. ``lam`` is first the largest (bisection in ``log lam``,
:data:`SMOOTH_BISECTIONS` steps) for which every waypoint's TCP and a point up its tool axis, by
the forward kinematics of the commands, move at most ``budget_m`` -- a share of the path tolerance
(``problems.toolpath.feed``). One waypoint near its budget would then hold the whole stretch back,
so ``lam`` is raised further by decades while the waypoints that would leave their budget get
larger weights ``w_k`` (a few reweightings per decade): the smoothing uses
the room the tolerance gives, where it gives it, and no more. A free rotation about the tool axis
(``free_tool_axis``) moves neither point, so the smoothing may use it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["SMOOTH_BISECTIONS", "smooth_stretch", "smooth_stretch_lam"]

#: Bisection steps on ``log10 lam`` over [SMOOTH_LOG_LAM_MIN, SMOOTH_LOG_LAM_MAX].
SMOOTH_BISECTIONS: int = 9
SMOOTH_LOG_LAM_MIN: float = -30.0
#: With a hint (a previous solve of the same stretch): decades searched either side, and steps.
SMOOTH_HINT_DECADES: float = 2.0
SMOOTH_HINT_BISECTIONS: int = 5
SMOOTH_LOG_LAM_MAX: float = 10.0
#: A stretch needs at least this many waypoints (two interior) to be smoothed.
SMOOTH_MIN_WAYPOINTS: int = 5
#: The tool axis's tilt is bounded through a point this far (m) up the axis from the TCP.
SMOOTH_TILT_LEVER_M: float = 0.1
#: The rotation about the tool axis the smoothing may add, rad (free for the path; it turns a
#: tool-frame load, so it is bounded: 0.01 rad turns a 0.1 mm deflection by 1 µm).
SMOOTH_SPIN_MAX_RAD: float = 0.01
#: Step of the central differences of the metric's Jacobian, rad.
SMOOTH_JACOBIAN_STEP_RAD: float = 1e-6
#: Floor of the data term's metric, relative to its mean eigenvalue (keeps it definite).
SMOOTH_METRIC_FLOOR: float = 1e-6
#: Local smoothing beyond the uniform one: steps of SMOOTH_LOCAL_STEP_DECADES in log10 lam, each
#: with at most SMOOTH_REWEIGHTS reweightings of the waypoints above SMOOTH_REWEIGHT_AT of the budget.
SMOOTH_LOCAL_STEPS: int = 4
SMOOTH_LOCAL_STEP_DECADES: float = 1.0
SMOOTH_REWEIGHTS: int = 4
SMOOTH_REWEIGHT_AT: float = 0.7


def _third_difference(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the third divided difference times 3! over ``tau`` (m,): coefficients ``(m - 3, 4)``
    of waypoints ``i .. i+3``, and the weights ``h_i = (tau_{i+3} - tau_i) / 3`` (s)."""
    t0, t1, t2, t3 = tau[:-3], tau[1:-2], tau[2:-1], tau[3:]
    c = np.stack(
        [
            -1.0 / ((t1 - t0) * (t2 - t0) * (t3 - t0)),
            1.0 / ((t1 - t0) * (t2 - t1) * (t3 - t1)),
            -1.0 / ((t2 - t0) * (t2 - t1) * (t3 - t2)),
            1.0 / ((t3 - t0) * (t3 - t1) * (t3 - t2)),
        ],
        axis=1,
    )
    return 6.0 * c, (t3 - t0) / 3.0


def _normal_bands(c: np.ndarray, h: np.ndarray, m: int) -> np.ndarray:
    """Upper bands ``(4, m)`` of ``D^T H D`` in the layout of ``scipy.linalg.solveh_banded``."""
    ab = np.zeros((4, m))
    for a in range(4):
        for b in range(a, 4):
            vals = h * c[:, a] * c[:, b]  # row i: entry (i + a, i + b)
            np.add.at(ab[3 - (b - a)], np.arange(len(h)) + b, vals)
    return ab


def _moved(tcp: Callable[[np.ndarray], np.ndarray], q: np.ndarray, ref: np.ndarray, spin_m: float) -> np.ndarray:
    """Per waypoint, how far (m) the three points of :func:`_points` move from ``ref`` (the same
    points of the unsmoothed waypoints, (m, 3, 3))."""
    return np.max(np.linalg.norm(_points(tcp, q, spin_m) - ref, axis=2), axis=1)


def _points(tcp: Callable[[np.ndarray], np.ndarray], q: np.ndarray, spin_m: float = 0.0) -> np.ndarray:
    """The TCP, the point :data:`SMOOTH_TILT_LEVER_M` up its z (tool) axis and, with ``spin_m``, the
    point ``spin_m`` along its x axis (which bounds a rotation about the tool axis), (m, 3, 3) m;
    without ``spin_m`` the first two, (m, 2, 3)."""
    T = tcp(q)
    pts = [T[:, :3, 3], T[:, :3, 3] + SMOOTH_TILT_LEVER_M * T[:, :3, 2]]
    if spin_m > 0.0:
        pts.append(T[:, :3, 3] + spin_m * T[:, :3, 0])
    return np.stack(pts, axis=1)


def _metric(tcp: Callable[[np.ndarray], np.ndarray], q: np.ndarray) -> np.ndarray:
    """Per waypoint, ``J^T J + eps I`` (n, n) of the two points of :func:`_points` (their stacked
    Jacobian ``J``, m/rad, by central differences), in m^2/rad^2: the data term's metric, blind to
    a rotation about the tool axis (moving neither point), which the smoothing is then free to
    use; ``eps`` (:data:`SMOOTH_METRIC_FLOOR` times the mean eigenvalue) keeps the system definite."""
    m, n = q.shape
    J = np.empty((m, 6, n))
    for j in range(n):
        dq = np.zeros(n)
        dq[j] = SMOOTH_JACOBIAN_STEP_RAD
        J[:, :, j] = (_points(tcp, q + dq) - _points(tcp, q - dq)).reshape(m, 6) / (2.0 * SMOOTH_JACOBIAN_STEP_RAD)
    M = np.einsum("kai,kaj->kij", J, J)
    floor = SMOOTH_METRIC_FLOOR * np.trace(M, axis1=1, axis2=2) / n
    return M + floor[:, None, None] * np.eye(n)[None]


def smooth_stretch(
    tau: np.ndarray,
    q: np.ndarray,
    tcp_frame: Callable[[np.ndarray], np.ndarray],
    budget_m: float,
    weight: np.ndarray | None = None,
) -> np.ndarray:
    """The stretch's waypoints smoothed within ``budget_m`` (see the module docstring); the first
    element of :func:`smooth_stretch_lam`.

    Parameters
    ----------
    tau : np.ndarray
        Shape ``(m,)``, s: programmed time at each waypoint, strictly increasing.
    q : np.ndarray
        Shape ``(m, n)``, rad: the joint waypoints (commands).
    tcp_frame : callable
        ``tcp_frame(q (M, n)) -> (M, 4, 4)``: the TCP frame in the base frame (homogeneous, m) by
        forward kinematics.
    budget_m : float
        Largest displacement (m, > 0) of a waypoint's TCP and of the point
        :data:`SMOOTH_TILT_LEVER_M` up its tool axis (which bounds the tool axis's tilt); a rotation
        about the tool axis is held within :data:`SMOOTH_SPIN_MAX_RAD`.
    weight : np.ndarray, optional
        Shape ``(m,)``, > 0: the starting weights ``w_k`` (default 1); a large weight pins a waypoint.

    Returns
    -------
    np.ndarray
        Shape ``(m, n)``, rad; ``q`` itself when the stretch is too short or ``tau`` not increasing.
    """
    return smooth_stretch_lam(tau, q, tcp_frame, budget_m, weight)[0]


def smooth_stretch_lam(
    tau: np.ndarray,
    q: np.ndarray,
    tcp_frame: Callable[[np.ndarray], np.ndarray],
    budget_m: float,
    weight: np.ndarray | None = None,
    log_lam_hint: float | None = None,
) -> tuple[np.ndarray, float]:
    """:func:`smooth_stretch`, and the ``log10 lam`` of its uniform stage (NaN when not smoothed).
    ``log_lam_hint`` (a previous call's on the same stretch) narrows the bisection to
    :data:`SMOOTH_HINT_DECADES` either side of it, in :data:`SMOOTH_HINT_BISECTIONS` steps."""
    tau = np.asarray(tau, dtype=float)
    if len(tau) < SMOOTH_MIN_WAYPOINTS or not np.all(np.diff(tau) > 0.0) or not budget_m > 0.0:
        return q, float("nan")
    system = _System(tau, q, tcp_frame, budget_m)
    ones = np.ones(len(tau) - 2) if weight is None else np.asarray(weight, dtype=float)[1:-1].copy()
    # 1. the largest uniform smoothing within the budget (bisection)
    lo, hi, steps = SMOOTH_LOG_LAM_MIN, SMOOTH_LOG_LAM_MAX, SMOOTH_BISECTIONS
    if log_lam_hint is not None and np.isfinite(log_lam_hint):
        lo, hi, steps = log_lam_hint - SMOOTH_HINT_DECADES, log_lam_hint + SMOOTH_HINT_DECADES, SMOOTH_HINT_BISECTIONS
    best = q
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        out, moved = system.solve(mid, ones)
        if moved.max() <= budget_m:
            lo, best = mid, out
        else:
            hi = mid
    if best is q:
        return q, float("nan")
    uniform = lo
    # 2. more smoothing where there is room: raise lam, holding the waypoints that would leave the
    #    budget by raising their weights (a few reweightings per step)
    weight = ones.copy()
    log_lam = lo
    for _ in range(SMOOTH_LOCAL_STEPS):
        trial_w = weight.copy()
        log_lam_try = log_lam + SMOOTH_LOCAL_STEP_DECADES
        for _ in range(SMOOTH_REWEIGHTS):
            out, moved = system.solve(log_lam_try, trial_w)
            over = moved[1:-1] / budget_m
            if over.max() <= 1.0:
                break
            trial_w = np.where(over > SMOOTH_REWEIGHT_AT, trial_w * np.maximum(over, 1.0) ** 2 * 4.0, trial_w)
        else:
            break
        best, weight, log_lam = out, trial_w, log_lam_try
    return best, uniform


class _System:
    """The banded normal equations of one stretch's smoothing (the module docstring), built once;
    :meth:`solve` for a ``lam`` and weights."""

    def __init__(self, tau: np.ndarray, q: np.ndarray, tcp_frame: Callable[[np.ndarray], np.ndarray], budget_m: float):
        m, n = q.shape
        self.q, self.tcp_frame = q, tcp_frame
        # seconds are small: work in units of the stretch's mean step so the system is well scaled
        unit = float(tau[-1] - tau[0]) / (m - 1)
        c, h = _third_difference((tau - tau[0]) / unit)
        smooth = _normal_bands(c, h, m)  # (4, m): D^T H D, per joint
        rows = np.arange(len(h))
        Dq = sum(c[:, a, None] * q[rows + a] for a in range(4))  # (m - 3, n)
        rhs = np.zeros_like(q)
        for a in range(4):
            np.add.at(rhs, rows + a, -(h * c[:, a])[:, None] * Dq)
        self.rhs = rhs[1:-1].ravel()  # the interior unknowns (the ends are kept), joint fastest
        self.spin_m = budget_m / SMOOTH_SPIN_MAX_RAD
        self.ref = _points(tcp_frame, q, self.spin_m)
        self.metric = _metric(tcp_frame, q[1:-1])  # (m - 2, n, n): |J d|^2 of the two points
        self.u = 3 * n  # upper bandwidth of the interleaved system
        N = (m - 2) * n
        self.base = np.zeros((self.u + 1, N))
        for o in range(4):  # D^T H D (x) I_n: offsets 3n, 2n, n, 0
            self.base[self.u - o * n] = np.repeat(smooth[3 - o, 1:-1], n)
        col = np.arange(N)
        blk_j, k_of = col % n, col // n
        # the data term's blocks w_k M_k, entry (k n + j - off, k n + j): per offset, the columns, their
        # waypoint and the metric's values (the weights change between solves, these do not)
        self.blocks = []
        for off in range(n):
            ok = blk_j >= off
            self.blocks.append((off, col[ok], k_of[ok], self.metric[k_of[ok], blk_j[ok] - off, blk_j[ok]]))

    def solve(self, log_lam: float, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The smoothed waypoints for ``lam = 10**log_lam`` and interior weights ``weight``, and how
        far each moves (:func:`_moved`, m); ``q`` and inf where the system is singular."""
        from scipy.linalg import solveh_banded

        m, n = self.q.shape
        band = 10.0**log_lam * self.base
        for off, cols, k, vals in self.blocks:
            band[self.u - off, cols] += weight[k] * vals
        out = self.q.copy()
        try:
            out[1:-1] += solveh_banded(band, 10.0**log_lam * self.rhs, check_finite=False).reshape(m - 2, n)
        except np.linalg.LinAlgError:  # lam so large that the system is singular in floating point
            return self.q, np.full(m, np.inf)
        return out, _moved(self.tcp_frame, out, self.ref, self.spin_m)
