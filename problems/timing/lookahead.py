"""``method="lookahead"``: jerk-limited, with bounds that are local along the path; linear in its length.

The method a CNC look-ahead planner would be if it knew the arm's joints. On a uniform grid of the
path parameter ``s`` (cells of ``1/G``, ``G`` about :data:`CELLS_PER_KNOT` per waypoint), every
cell gets its own bounds from the joint path's derivatives there (``P'``, ``P''``, ``P'''``: the
largest magnitude over the cell, exact for ``P'''`` and ``P''`` of the cubic spline) and each
joint's limits split into shares (:data:`SHARE_CENTRIPETAL`, :data:`SHARE_JERK_CRUISE`,
:data:`SHARE_JERK_CROSS`). With ``x = ds/dt``, ``u = d2s/dt2``,
``w = d3s/dt3``, joint j's acceleration is ``P'_j u + P''_j x^2`` and its jerk
``P'_j w + 3 P''_j x u + P'''_j x^3``, so on a cell:

* path speed ``x <= X = min_j (v_j / |P'_j|, sqrt(rho a_j / |P''_j|), cbrt(s1 J_j / |P'''_j|))``;
* path acceleration ``|u| <= A = min_j ((a_j - |P''_j| X^2) / |P'_j|, c (J_j - |P'''_j| X^3) / (3 |P''_j| X))``;
* path jerk ``|w| <= W = min_j ((J_j - |P'''_j| X^3 - 3 |P''_j| X A) / |P'_j|)``

(``rho``, ``s1``, ``c``: the shares), so that the joints' limits hold wherever ``x <= X``.

A bound is therefore only as tight as the path is demanding *there*: a cutting stretch runs at the
feed (the programmed-time pseudo-joint's speed limit, ``problems.toolpath.feed``) wherever the
joints allow it and slows only where they do not.

The time law is made in two steps, both vectorised (no loop over cells):

1. the time-optimal law under ``x <= X(s)``, ``|u| <= min(A, W T / 2)`` (velocity and acceleration
   only): the classic forward and backward passes over the grid (``x^2`` grows by at most ``2 A ds``
   a cell), each a cumulative minimum; the bounds are first *eroded* (a running minimum over the
   distance ``T max X`` the filter below mixes), so that the filtered law meets the bounds of the
   point where it is;
2. a moving average over ``T`` seconds of that law's ``s(t)`` (a finite-impulse-response filter, as
   CNC interpolators smooth a trapezoidal feed profile into an S-curve): the filtered law's speed and
   acceleration are averages of the first law's (within the eroded bounds) and its jerk is
   ``(u(t) - u(t - T)) / T``, at most ``2 A / T <= W``. It is exact in closed form (``s(t)`` is
   piecewise quadratic, its integral piecewise cubic), starts and ends at rest, and lasts ``T``
   longer. ``T`` is chosen per path among :data:`FILTER_CANDIDATES` values, the shortest total
   time kept: a short ``T`` costs accelerations (``A <= W T / 2``), a long one costs ``T``. Near
   the best ``T``, ``A <= W T`` is tried too (the jerk is ``A / T`` where the first law's
   acceleration does not flip sign within ``T``) and kept where the sampled path jerk shows it
   within ``W``.

The sampled trajectory is checked like every method's (``problems.timing.verification``); where the
cell maxima miss a peak (``P'`` between knots) and a ratio exceeds 1, the law is slowed uniformly in
time by ``k = max(r_v, sqrt(r_a), cbrt(r_j))`` (at most :data:`SCALE_ROUNDS` times).

On a short path (a move from rest to rest) the filter's length is a large share of the motion;
there (where the filter is at least :data:`LOOKAHEAD_ALSO_SHARE` of it) Ruckig's time-optimal
rest-to-rest profile of the path parameter under the grid's smallest bounds is computed too and
kept when it is shorter (the reason says so).

Cost: O(G) per candidate ``T``; ``G`` is :data:`CELLS_PER_KNOT` per waypoint, at least
:data:`MIN_CELLS`, at most :data:`MAX_CELLS`. Options: ``cells_per_knot`` (int >= 1). Importing
this module registers the method.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from problems.timing.path import SplinePath
from problems.timing.registry import TimingMethod, check_integer_options, register_method
from problems.timing.trajectory import LIMIT_KEYS, JointLimits, Trajectory
from problems.timing.verification import (
    check_times,
    finish_trajectory,
    format_ratios,
    sampled_ratios,
    time_scale_factor,
)

__all__ = ["LocalBounds", "local_bounds", "BOUND_KINDS"]

#: Share of each joint's acceleration limit the path's curvature (``P'' x^2``) may take at the
#: cruising bound; what cruising at the bound leaves goes to speeding up and slowing down (``P' u``).
SHARE_CENTRIPETAL: float = 0.8
#: Share of each joint's jerk limit the path's third derivative at speed (``P''' x^3``) may take;
#: of what cruising at the bound leaves, SHARE_JERK_CROSS goes to the cross term (``3 P'' x u``)
#: and the rest to the path jerk itself (``P' w``).
SHARE_JERK_CRUISE: float = 0.6
SHARE_JERK_CROSS: float = 0.5
#: Grid cells per waypoint, and the least and most cells of a path.
CELLS_PER_KNOT: int = 4
MIN_CELLS: int = 400
MAX_CELLS: int = 400_000
#: Filter lengths tried (s): geometric from FILTER_T_MIN_S to FILTER_T_MAX_S, floored at dt.
FILTER_CANDIDATES: int = 9
FILTER_T_MIN_S: float = 0.004
FILTER_T_MAX_S: float = 2.0
#: Uniform slow-down when the sampled check exceeds a limit: margin and most rounds.
SCALE_MARGIN: float = 1e-4
SCALE_ROUNDS: int = 3
#: Ruckig's rest-to-rest profile under the grid's smallest bounds is tried where the filter is at
#: least this share of the motion (see the module docstring).
LOOKAHEAD_ALSO_SHARE: float = 0.05
#: The kinds of bound, in the order of :attr:`LocalBounds.kind`.
BOUND_KINDS: tuple[str, ...] = ("velocity", "acceleration", "jerk")


@dataclass(frozen=True)
class LocalBounds:
    """The path-speed bound at points of a path and what sets it.

    Attributes
    ----------
    speed : np.ndarray
        Shape ``(M,)``, 1/s: the largest ``ds/dt`` the joints allow at each point while cruising.
    joint : np.ndarray
        Shape ``(M,)``, int: the joint (0-based column of the path) whose limit sets it.
    kind : np.ndarray
        Shape ``(M,)``, int: index into :data:`BOUND_KINDS` (velocity, acceleration, jerk).
    """

    speed: np.ndarray
    joint: np.ndarray
    kind: np.ndarray


def _ratio(limit: np.ndarray, value: np.ndarray) -> np.ndarray:
    """``limit / value`` with ``inf`` where ``value`` is 0 (shapes broadcast)."""
    with np.errstate(divide="ignore"):
        return np.where(value > 0.0, limit / np.where(value > 0.0, value, 1.0), np.inf)


def _speed_terms(p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, limits: JointLimits) -> np.ndarray:
    """Shape ``(3, M, n)``: the speed each joint's velocity, acceleration and jerk allow (1/s)."""
    return np.stack(
        [
            _ratio(limits.velocity, p1),
            np.sqrt(_ratio(SHARE_CENTRIPETAL * limits.acceleration, p2)),
            np.cbrt(_ratio(SHARE_JERK_CRUISE * limits.jerk, p3)),
        ]
    )


def local_bounds(path: SplinePath, limits: JointLimits, s: np.ndarray, joints: int | None = None) -> LocalBounds:
    """The cruising path-speed bound at parameters ``s`` (shape ``(M,)``, in [0, 1]), with the joint
    and the kind of limit that sets it (the speed bound of the module docstring, at points), over
    the first ``joints`` columns of the path (default all)."""
    s = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    cols = slice(None) if joints is None else slice(0, joints)
    sp = path.spline
    lim = JointLimits(limits.velocity[cols], limits.acceleration[cols], limits.jerk[cols])
    terms = _speed_terms(
        np.abs(sp.derivative(1)(s)[:, cols]),
        np.abs(sp.derivative(2)(s)[:, cols]),
        np.abs(sp.derivative(3)(s)[:, cols]),
        lim,
    )
    m, n = terms.shape[1], terms.shape[2]
    flat = terms.transpose(1, 0, 2).reshape(m, 3 * n)
    arg = np.argmin(flat, axis=1)
    return LocalBounds(speed=flat[np.arange(m), arg], joint=arg % n, kind=arg // n)


def _cell_max(knot_vals: np.ndarray, edge_vals: np.ndarray, kidx: np.ndarray) -> np.ndarray:
    """Per cell, the largest of the values at its two edges and at the knots inside it.

    ``knot_vals (N, n)``, ``edge_vals (G + 1, n)``, ``kidx (G + 1,)``: the first knot at or after
    each edge. Returns shape ``(G, n)``."""
    out = np.maximum(edge_vals[:-1], edge_vals[1:])
    inside = kidx[1:] > kidx[:-1]
    if np.any(inside):
        start = np.minimum(kidx[:-1], len(knot_vals) - 1)
        red = np.maximum.reduceat(knot_vals, start, axis=0)
        out[inside] = np.maximum(out[inside], red[inside])
    return out


@dataclass(frozen=True)
class _Grid:
    """The cells' bounds: speed ``X``, acceleration ``A`` and jerk ``W`` of the path parameter."""

    ds: float
    X: np.ndarray  # (G,), 1/s
    A: np.ndarray  # (G,), 1/s^2
    W: np.ndarray  # (G,), 1/s^3


def _grid(path: SplinePath, limits: JointLimits, cells_per_knot: int) -> _Grid:
    """Cell bounds on a uniform grid of ``s`` (see the module docstring)."""
    knots = path.knots
    G = int(min(MAX_CELLS, max(MIN_CELLS, cells_per_knot * (len(knots) - 1))))
    edges = np.linspace(0.0, 1.0, G + 1)
    sp = path.spline
    d1, d2 = sp.derivative(1), sp.derivative(2)
    kidx = np.searchsorted(knots, edges, side="left")
    p1 = _cell_max(np.abs(d1(knots)), np.abs(d1(edges)), kidx)
    p2 = _cell_max(np.abs(d2(knots)), np.abs(d2(edges)), kidx)
    # P''' is constant on each knot interval: the largest over the intervals a cell overlaps
    third = np.abs(6.0 * sp.c[0])  # (N - 1, n)
    lo = np.clip(np.searchsorted(knots, edges[:-1], side="right") - 1, 0, len(third) - 1)
    hi = np.clip(np.searchsorted(knots, edges[1:], side="left") - 1, 0, len(third) - 1)
    p3 = np.maximum(np.maximum.reduceat(third, lo, axis=0), third[hi])
    X = _speed_terms(p1, p2, p3, limits).min(axis=(0, 2))
    # what cruising at X leaves of each joint's limits goes to speeding up and slowing down
    Xc = X[:, None]
    left_acc = np.maximum(limits.acceleration - p2 * Xc**2, 0.0)
    left_jerk = np.maximum(limits.jerk - p3 * Xc**3, 0.0)
    A = np.minimum(
        _ratio(left_acc, p1).min(axis=1),
        _ratio(SHARE_JERK_CROSS * left_jerk, 3.0 * p2 * Xc).min(axis=1),
    )
    # the path jerk gets what the cross term leaves at that acceleration (all of it on a straight path)
    W = _ratio(np.maximum(left_jerk - 3.0 * p2 * Xc * A[:, None], 0.0), p1).min(axis=1)
    return _Grid(ds=1.0 / G, X=X, A=A, W=W)


def _running_min(a: np.ndarray, half: int) -> np.ndarray:
    """Minimum over ``[i - half, i + half]`` (clipped at the ends), O(len)."""
    if half <= 0:
        return a
    from scipy.ndimage import minimum_filter1d

    return minimum_filter1d(a, size=2 * half + 1, mode="nearest")


def _passes(X: np.ndarray, A: np.ndarray, ds: float) -> np.ndarray:
    """Node speeds (G + 1,) of the time-optimal law under cell bounds ``X``, ``A``, at rest at both
    ends: forward and backward passes, each a cumulative minimum."""
    cap = np.r_[0.0, np.minimum(X[:-1], X[1:]), 0.0] ** 2
    step = 2.0 * A * ds
    c = np.r_[0.0, np.cumsum(step)]
    fwd = c + np.minimum.accumulate(cap - c)
    cb = np.r_[0.0, np.cumsum(step[::-1])]
    bwd = (cb + np.minimum.accumulate(cap[::-1] - cb))[::-1]
    return np.sqrt(np.maximum(np.minimum(fwd, bwd), 0.0))


@dataclass(frozen=True)
class FilteredLaw:
    """The moving average over ``T`` of a piecewise constant-acceleration law on a uniform grid.

    Attributes
    ----------
    t_nodes : np.ndarray
        Shape ``(G + 1,)``, s: the first law's time at each grid node.
    s_nodes, v_nodes, a_cells, i_nodes : np.ndarray
        The first law's path parameter, speed (1/s) at the nodes, acceleration (1/s^2) per cell and
        the integral of ``s`` (s) at the nodes.
    T : float
        Filter length, s.
    scale : float
        Time scale >= 1 of a uniform slow-down (``s(t / scale)``).
    """

    t_nodes: np.ndarray
    s_nodes: np.ndarray
    v_nodes: np.ndarray
    a_cells: np.ndarray
    i_nodes: np.ndarray
    T: float
    scale: float = 1.0

    @property
    def duration(self) -> float:
        """End of the motion, s."""
        return (float(self.t_nodes[-1]) + self.T) * self.scale

    def _raw(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The first law's integral, ``s``, speed and acceleration at times ``t`` (any, clamped)."""
        t_end = float(self.t_nodes[-1])
        k = np.clip(np.searchsorted(self.t_nodes, t, side="right") - 1, 0, len(self.a_cells) - 1)
        tau = np.clip(t, 0.0, t_end) - self.t_nodes[k]
        s0, v0, a = self.s_nodes[k], self.v_nodes[k], self.a_cells[k]
        s = s0 + v0 * tau + 0.5 * a * tau**2
        v = v0 + a * tau
        integral = self.i_nodes[k] + s0 * tau + 0.5 * v0 * tau**2 + a * tau**3 / 6.0
        before, after = t <= 0.0, t >= t_end
        integral = np.where(before, 0.0, np.where(after, self.i_nodes[-1] + (t - t_end) * 1.0, integral))
        s = np.where(before, 0.0, np.where(after, 1.0, s))
        v = np.where(before | after, 0.0, v)
        a = np.where(before | after, 0.0, a)
        return integral, s, v, a

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(s, sd, sdd, sddd)`` at times ``t`` (s): -, 1/s, 1/s^2, 1/s^3."""
        k, T = self.scale, self.T
        tt = np.asarray(t, dtype=float) / k
        i1, s1, v1, a1 = self._raw(tt)
        i0, s0, v0, a0 = self._raw(tt - T)
        return (
            np.clip((i1 - i0) / T, 0.0, 1.0),
            (s1 - s0) / T / k,
            (v1 - v0) / T / k**2,
            (a1 - a0) / T / k**3,
        )


def _law(grid: _Grid, T: float, v_max: float, jerk_factor: float) -> FilteredLaw:
    """The filtered law for filter length ``T`` (s), the path acceleration held to ``W T / jerk_factor``."""
    G = len(grid.X)
    A = np.minimum(grid.A, grid.W * T / jerk_factor)
    half = int(math.ceil(T * v_max / grid.ds)) + 1
    X, A = _running_min(grid.X, half), _running_min(A, half)
    v = _passes(X, A, grid.ds)
    dt = 2.0 * grid.ds / np.maximum(v[:-1] + v[1:], 1e-300)
    t_nodes = np.r_[0.0, np.cumsum(dt)]
    a = (v[1:] ** 2 - v[:-1] ** 2) / (2.0 * grid.ds)
    s_nodes = np.linspace(0.0, 1.0, G + 1)
    # integral of s over each cell: s0 dt + v0 dt^2 / 2 + a dt^3 / 6
    cell_int = s_nodes[:-1] * dt + 0.5 * v[:-1] * dt**2 + a * dt**3 / 6.0
    return FilteredLaw(t_nodes, s_nodes, v, a, np.r_[0.0, np.cumsum(cell_int)], T)


def _path_jerk_ok(grid: _Grid, law: FilteredLaw, dt: float) -> bool:
    """Whether the filtered law's path jerk stays within the cells' ``W`` where it is (sampled at
    ``dt / VERIFY_OVERSAMPLE``)."""
    t = check_times(law.duration, dt)
    s, _, _, sddd = law(t)
    cell = np.clip((s / grid.ds).astype(int), 0, len(grid.W) - 1)
    return bool(np.all(np.abs(sddd) <= grid.W[cell] * (1.0 + 1e-9)))


def _best_law(grid: _Grid, dt: float) -> FilteredLaw:
    """The shortest filtered law over the candidate filter lengths and jerk factors.

    The filtered jerk is ``(u(t) - u(t - T)) / T``: at most ``A / T`` where the first law's
    acceleration changes from 0 or to 0 within ``T``, ``2 A / T`` where it flips sign within ``T``.
    Factor 2 is always within ``W``; factor 1 (shorter accelerations) is kept where the sampled
    path jerk shows it is."""
    v_max = float(np.max(grid.X[np.isfinite(grid.X)])) if np.any(np.isfinite(grid.X)) else 1.0
    lo = max(FILTER_T_MIN_S, dt)
    Ts = np.unique(np.geomspace(lo, max(lo, FILTER_T_MAX_S), FILTER_CANDIDATES))
    safe = min((_law(grid, float(T), v_max, 2.0) for T in Ts), key=lambda law: law.duration)
    # the bold factor gains most near the safe optimum's filter length: tried there and one step around
    near = Ts[max(0, int(np.searchsorted(Ts, safe.T)) - 1) : int(np.searchsorted(Ts, safe.T)) + 2]
    bold = sorted((_law(grid, float(T), v_max, 1.0) for T in near), key=lambda law: law.duration)
    for law in bold:
        if law.duration >= safe.duration:
            break
        if _path_jerk_ok(grid, law, dt):
            return law
    return safe


def _options(out: dict[str, Any]) -> dict[str, Any]:
    """Check the values of the options (``cells_per_knot``: int >= 1)."""
    check_integer_options(out, (("cells_per_knot", 1),))
    return out


def run_lookahead(path: SplinePath, limits: JointLimits, dt: float, opts: Mapping[str, Any]) -> Trajectory:
    """Time ``path`` rest to rest (the registered runner of ``"lookahead"``; see the module docstring)."""
    grid = _grid(path, limits, int(opts.get("cells_per_knot", CELLS_PER_KNOT)))
    if not np.all(np.isfinite(grid.X)):
        grid = _Grid(grid.ds, np.where(np.isfinite(grid.X), grid.X, 1.0 / dt), grid.A, grid.W)
    law = _best_law(grid, dt)
    first: dict[str, np.ndarray] | None = None
    rounds = 0
    while True:
        rounds += 1
        ratio, sd = sampled_ratios(path, law, law.duration, limits, dt)
        first = ratio if first is None else first
        worst = time_scale_factor(ratio)
        if worst <= 1.0 or rounds > SCALE_ROUNDS:
            break
        law = replace(law, scale=law.scale * worst * (1 + SCALE_MARGIN))
    summary = (
        f"look-ahead on {len(grid.X)} cells, filter {law.T * 1e3:.3g} ms"
        + (f", slowed x{law.scale:.4g} after the sampled check" if law.scale > 1.0 else "")
        + f"; {format_ratios(ratio)}"
    )
    own = finish_trajectory(
        "lookahead",
        path,
        limits,
        dt,
        law,
        law.duration,
        ratio,
        summary,
        check_sd=sd,
        sd_scale=float(np.max(np.abs(sd))) if sd.size else 1.0,
        iterations=rounds,
        first=first,
    )
    if law.T < LOOKAHEAD_ALSO_SHARE * law.duration:
        return own  # the filter is a small share of the motion: Ruckig's one bound set cannot win
    return _shorter_of(own, path, grid, limits, dt)


def _shorter_of(own: Trajectory, path: SplinePath, grid: _Grid, limits: JointLimits, dt: float) -> Trajectory:
    """``own`` or, where it is shorter and within every limit, Ruckig's time-optimal rest-to-rest
    profile of the path parameter under the grid's smallest bounds (``min X``, ``min A``, ``min W``:
    within the joints' limits everywhere by the same shares): on a short path, a move from rest to
    rest, it beats a filtered law, whose filter adds up to ~20 % there."""
    from problems.timing.ruckig_method import RuckigLaw
    from problems.timing.trajectory import TimingStatus

    bounds = [float(np.min(b[np.isfinite(b)])) if np.any(np.isfinite(b)) else 0.0 for b in (grid.X, grid.A, grid.W)]
    if not all(b > 0.0 for b in bounds):
        return own
    law = RuckigLaw()
    attempt = law.solve(*bounds)
    if not attempt.ok or not attempt.duration < own.duration_s:
        return own
    ratio, sd = sampled_ratios(path, law.profile_eval, attempt.duration, limits, dt)
    other = finish_trajectory(
        "lookahead",
        path,
        limits,
        dt,
        law.profile_eval,
        attempt.duration,
        ratio,
        f"Ruckig ({attempt.solver_code}) under the look-ahead's smallest bounds sd<={bounds[0]:.6g} 1/s, "
        f"|sdd|<={bounds[1]:.6g} 1/s^2, |sddd|<={bounds[2]:.6g} 1/s^3, shorter than the filtered law's "
        f"{own.duration_s:.4g} s on this path; {format_ratios(ratio)}",
        check_sd=sd,
        sd_scale=float(np.max(np.abs(sd))) if sd.size else 1.0,
        iterations=1,
    )
    return other if other.status is TimingStatus.OK and other.duration_s < own.duration_s else own


LOOKAHEAD_METHOD: TimingMethod = register_method(
    TimingMethod(
        name="lookahead",
        run=run_lookahead,
        options=("cells_per_knot",),
        validate_options=_options,
        checked_limits=LIMIT_KEYS,
        description="jerk-limited, bounds local along the path (look-ahead passes and a moving-average filter)",
        display_name="look-ahead",
        controller_rank=15,
        program_default=True,
        duration_note="look-ahead, jerk-limited: the trajectory the controller runs",
        underuse_cause=(
            "each joint's acceleration and jerk limits are split into shares (curvature, speeding up, "
            "jerk of the path), so no single share reaches the whole limit"
        ),
    )
)
