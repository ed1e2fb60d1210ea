"""``method="jerk_optimal"``: time-optimal under joint velocity, acceleration *and jerk* limits.

The path-velocity profile is optimised directly: on a grid ``s_0 = 0 < s_1 < ... < s_K = 1``
of the path parameter (every waypoint knot plus points spread in proportion to the knot
intervals, :func:`profile_grid`), the variables are the path velocity ``x_k = ds/dt`` (1/s) and
the path acceleration ``u_k = d2s/dt2`` (1/s^2) at every gridpoint.  Inside, ``u`` is linear in
``s`` on each interval (``c_k = du/ds``, so the path jerk is ``d3s/dt3 = x c_k``); the two end
intervals are constant-jerk cubics in time from and to rest.  IPOPT (through CasADi, exact
derivatives) minimises the motion time ``T = sum_k 2 ds_k / (x_k + x_{k+1})`` (``3 ds / x`` on the
end intervals) plus a tiny penalty on the change of ``c_k`` (:data:`JERK_SMOOTHING`), subject to

* consistency: ``x_{k+1}^2 - x_k^2 = (u_k + u_{k+1}) ds_k`` (``d(x^2)/ds = 2u``), and
  ``x^2 = 1.5 |u| ds`` at the inner gridpoint of each end interval;
* rest at both ends: ``x_0 = x_K = u_0 = u_K = 0``;
* velocity: ``x_k <= min_j v_j / |P'_j(s_k)|`` (variable bounds);
* per interval, for the :data:`JERK_SLOTS` joints most loaded there ("slots"): the acceleration
  ``P''_j x^2 + P'_j u`` at the left gridpoint (and, for the first :data:`JERK_MID_ACC_SLOTS`
  slots, at the midpoint, ``x^2`` and ``u`` from the model) within ``+-a_j``, and the jerk
  ``x (P'''_j x^2 + 3 P''_j u + P'_j c_k)`` at both ends within ``+-jerk_j``.  ``P'''`` is the
  midpoint value, or on a dense path (knots inside the interval) the largest-magnitude value of
  the knot segments the interval overlaps (:func:`_third_derivative`), so that the jerk between
  gridpoints is represented.

The slots are chosen from the warm start's model ratios; after a solve any other joint above its
limit replaces the slot of smallest ratio on that interval and the NLP is solved again (at most
:data:`JERK_SLOT_ROUNDS` solves), warm-started from the previous primal-dual optimum
(:data:`JERK_WARM_IPOPT`).  The NLP is parametric (the path derivatives, grid steps and limits of
the slot joints are parameters), so it is built once per grid size and process and reused
(:data:`JERK_GRIDPOINTS`; the re-solves' solver shares its derivatives, :func:`_solver`).  The
first solve is warm-started from TOPP-RA's time-optimal velocity/acceleration profile on the same
grid, scaled by :data:`JERK_WARM_FRACTION`.

The optimum is turned into the exact time law of that model, :class:`JerkLaw` (C2 in ``s(t)``,
jerk bounded, gridpoint times by quadrature).  The constraints hold on the model at the
gridpoints (and midpoints) only, so the sampled trajectory is checked on the fine grid like every
method's, and when a ratio exceeds 1 (discretisation) the law is slowed uniformly in time by
``k = max(r_v, sqrt(r_a), cbrt(r_j))`` (times ``1 + JERK_SCALE_MARGIN``), which divides every
velocity by k, acceleration by k^2 and jerk by k^3 on the same path: the result is always within
every limit, at the price of that factor in duration (reported).

Why this method (``docs/cli.md``, "Timing"; ``benchmarks/bench_timing.py`` compares them):
Ruckig (community version) has no intermediate waypoints, so ``method="ruckig"`` times the
path parameter under global bounds and is 1.6-2.2x slower than time-optimal; TOPP-RA's law
smoothed to the jerk limit by a moving average is 1.1-1.7x slower (the window is paid at
every acceleration switch); this NLP lands within a few per cent of the jerk-free optimum.

Options: ``gridpoints`` (int >= 20, default :func:`default_gridpoints`), ``max_iterations``
(int >= 1, IPOPT's iteration limit, default ``JERK_MAX_ITER``).  Importing this module
registers the method.
"""

from __future__ import annotations

import math
import threading
from typing import Any
from collections.abc import Mapping

import casadi as ca
import numpy as np

from models import interrupts
from problems.timing.jerk_law import JerkLaw
from problems.timing.path import SplinePath
from problems.timing.registry import (
    LIMIT_RATIO_TOL,
    TimingMethod,
    check_integer_options,
    register_method,
)
from problems.timing.toppra_import import import_toppra
from problems.timing.toppra_method import toppra_once
from problems.timing.trajectory import JointLimits, TimingStatus, Trajectory, empty_trajectory
from problems.timing.verification import (
    check_times,
    finish_trajectory,
    format_ratios,
    limit_ratios,
)

__all__ = [
    "JERK_GRIDPOINTS",
    "JERK_MAX_ITER",
    "JerkLaw",
]

#: Grid sizes the NLP is built for by default (the smallest with >= JERK_GRIDPOINTS_PER_WAYPOINT
#: gridpoints per waypoint, capped at the largest: on denser paths the interval data cover the
#: knots in between, :func:`_third_derivative`; 960 points cost ~3x the time for ~1 %).
JERK_GRIDPOINTS: tuple[int, ...] = (160, 240, 480)
#: Gridpoints per waypoint wanted before capping at the largest size (halving it lengthens the
#: motion by ~1 % on the shipped problems).
JERK_GRIDPOINTS_PER_WAYPOINT: int = 6
#: IPOPT iteration limit and tolerance.
JERK_MAX_ITER: int = 300
JERK_TOL: float = 1e-7
#: Weight of the jerk-smoothness penalty (s per (1/s^2)^2 of du/ds change, integrated over s).
JERK_SMOOTHING: float = 1e-6
#: IPOPT's constraint tolerance: the velocity-acceleration consistency holds to this (1/s^2 * 1),
#: so the law's path acceleration is continuous at the gridpoints to about this over the step.
JERK_CONSTR_TOL: float = 1e-10
#: Extra factor on the uniform slow-down when the fine check exceeds a limit, and the most
#: slow-down rounds (each slower law is checked again, at its own times).
JERK_SCALE_MARGIN: float = 1e-5
JERK_SCALE_ROUNDS: int = 4
#: Fraction of the TOPP-RA profile used as the warm start (jerk-feasible-ish, strictly inside).
JERK_WARM_FRACTION: float = 0.8
#: Joints constrained per interval in the NLP (the most loaded ones; the others are checked after
#: the solve), the most solves while swapping joints in, and the model ratio that calls a swap.
JERK_SLOTS: int = 3
JERK_SLOT_ROUNDS: int = 4
JERK_SLOT_TOL: float = 1e-6
#: Slots (the most loaded first) that also constrain the acceleration at every interval's midpoint
#: (1: the most loaded joint only -- the others bind at the gridpoints; fewer rows, same durations).
JERK_MID_ACC_SLOTS: int = 1
#: IPOPT's barrier parameter target: the optimum stays this far inside the constraints (and the
#: last few barrier iterations are skipped).
JERK_MU_TARGET: float = 1e-7
#: IPOPT options of the re-solves after a slot swap: started from the previous primal-dual optimum
#: (the swapped rows' multipliers zeroed) with a small barrier parameter and small pushes away
#: from the bounds, they take 5-10 iterations instead of 20-30.
JERK_WARM_IPOPT: dict[str, Any] = {
    "warm_start_init_point": "yes",
    "mu_init": 1e-4,
    "warm_start_bound_push": 1e-6,
    "warm_start_bound_frac": 1e-6,
    "warm_start_mult_bound_push": 1e-6,
    "warm_start_slack_bound_push": 1e-6,
    "warm_start_slack_bound_frac": 1e-6,
}
#: Option names accepted by ``method="jerk_optimal"``.
JERK_OPTIONS: tuple[str, ...] = ("gridpoints", "max_iterations")

_CHECKED: tuple[str, ...] = ("velocity", "acceleration", "jerk")
#: IPOPT solvers by (grid size, slots, iteration limit, warm variant, midpoint slots).
_NLP_CACHE: dict[tuple[int, int, int, bool, int], ca.Function] = {}
#: The NLP (its symbolic dict) and its derivative functions by (grid size, slots, midpoint slots):
#: built with the first solver of an NLP and given to the others (the warm variant, another
#: iteration limit), which then skip CasADi's symbolic differentiation (most of the build).
_NLP_PARTS: dict[tuple[int, int, int], tuple[dict[str, ca.SX], dict[str, ca.Function]]] = {}
_NLP_LOCK = threading.Lock()
#: The solver's derivative functions and the options that hand them to another solver of the NLP.
_DERIVATIVE_OPTIONS: tuple[tuple[str, str], ...] = (
    ("nlp_grad_f", "grad_f"),
    ("nlp_jac_g", "jac_g"),
    ("nlp_hess_l", "hess_lag"),
)


def _no_nlp_grad() -> dict[str, bool]:
    """``no_nlp_grad`` where this CasADi has it: the Lagrangian's gradient function (for ``lam_p``,
    not computed) is then not built at all."""
    try:
        ca.nlpsol_option_type("ipopt", "no_nlp_grad")
    except RuntimeError:  # an older CasADi: the function is built, not used
        return {}
    return {"no_nlp_grad": True}


_NO_NLP_GRAD: dict[str, bool] = _no_nlp_grad()


def profile_grid(knots: np.ndarray, n_grid: int) -> np.ndarray:
    """Exactly ``n_grid`` gridpoints in s: every waypoint knot and the rest spread over the
    intervals in proportion to their length; a uniform grid when there are more knots than
    gridpoints (the interval data then cover the knots in between, :func:`_third_derivative`)."""
    N = knots.size
    if N >= n_grid:
        return np.linspace(0.0, 1.0, n_grid)
    h = np.diff(knots)
    extra = (n_grid - N) * h / h.sum()
    k = np.floor(extra).astype(int)
    k[np.argsort(extra - k)[::-1][: (n_grid - N) - int(k.sum())]] += 1
    pts = [knots[:1]]
    for i in range(N - 1):
        pts.append(np.linspace(knots[i], knots[i + 1], k[i] + 2)[1:])
    return np.concatenate(pts)


def default_gridpoints(n_waypoints: int) -> int:
    """The grid size for a path of ``n_waypoints`` waypoints (from :data:`JERK_GRIDPOINTS`)."""
    want = JERK_GRIDPOINTS_PER_WAYPOINT * n_waypoints
    return next((g for g in JERK_GRIDPOINTS if g >= want), JERK_GRIDPOINTS[-1])


# --------------------------------------------------------------------------- #
# The parametric NLP
# --------------------------------------------------------------------------- #


def _solver(n_grid: int, n_slots: int, max_iter: int, warm: bool = False) -> ca.Function:
    """IPOPT solver of the profile NLP (:func:`_nlp`) for ``n_grid`` gridpoints and ``n_slots``
    joint slots (cached); ``warm``: the variant for re-solves from a primal-dual point
    (:data:`JERK_WARM_IPOPT`).

    The solvers of one NLP share its derivative functions (gradient, constraint Jacobian,
    Hessian of the Lagrangian: built once, by the first).  The multipliers of the parameters
    (``lam_p``) are not computed: nothing reads them, and their function (the Lagrangian's
    gradient over the thousands of parameters) costs as much to build as the Hessian.
    """
    key = (n_grid, n_slots, max_iter, warm, JERK_MID_ACC_SLOTS)
    with _NLP_LOCK:
        if key in _NLP_CACHE:
            return _NLP_CACHE[key]
        nlp_key = (n_grid, n_slots, JERK_MID_ACC_SLOTS)
        nlp, derivatives = _NLP_PARTS.get(nlp_key) or (_nlp(n_grid, n_slots), {})
        opts = {
            "print_time": False,
            "calc_lam_p": False,
            **_NO_NLP_GRAD,
            **derivatives,
            "ipopt": {
                "print_level": 0,
                "sb": "yes",
                "max_iter": int(max_iter),
                "tol": JERK_TOL,
                "constr_viol_tol": JERK_CONSTR_TOL,
                "mu_strategy": "adaptive",
                "mu_target": JERK_MU_TARGET,
                **(JERK_WARM_IPOPT if warm else {}),
            },
        }
        solver = ca.nlpsol("jerk_optimal", "ipopt", nlp, opts)
        if nlp_key not in _NLP_PARTS:
            _NLP_PARTS[nlp_key] = nlp, {opt: solver.get_function(name) for name, opt in _DERIVATIVE_OPTIONS}
        _NLP_CACHE[key] = solver
        return solver


def _nlp(n_grid: int, n_slots: int) -> dict[str, ca.SX]:
    """The profile NLP for ``n_grid`` gridpoints and ``n_slots`` joint slots, as ``nlpsol``'s dict.

    Each interval constrains the ``n_slots`` joints most likely to bind there (chosen per call,
    :func:`_slots`; the others are checked after the solve and swapped in if they exceed).
    Variables ``[x (K+1); u (K+1)]``; parameters ``[ds (K); then per slot a (K, 9) block:
    first and second path derivatives at the interval's left and right gridpoints, the first two
    at its midpoint, the third representing it (:func:`_third_derivative`), and the slot joint's
    acceleration and jerk limits]``; the rows per slot are listed in :func:`_rows`.
    """
    K1, K = n_grid, n_grid - 1
    x, u = ca.SX.sym("x", K1), ca.SX.sym("u", K1)
    ds = ca.SX.sym("ds", K)
    slots = [ca.SX.sym(f"slot{r}", K, 9) for r in range(n_slots)]
    du = (u[1:] - u[:-1]) / ds
    # the end intervals start (end) at rest with constant jerk: s = J t^3 / 6, so at their
    # inner gridpoint J = x1 u1 / (3 ds) (the linear-in-s model would say x1 u1 / ds)
    w_end = ca.DM.ones(K)
    w_end[0] = w_end[K - 1] = 1.0 / 3.0
    dul, dur = du * w_end, du * w_end
    dul[0] = 0.0  # at rest: no jerk term from x = 0
    dur[K - 1] = 0.0
    xm2 = x[:-1] ** 2 + u[:-1] * ds + 0.25 * (u[1:] - u[:-1]) * ds  # x^2 at the midpoint (model)
    um = 0.5 * (u[:-1] + u[1:])
    # consistency: u linear in s inside (d(x^2)/ds = 2u); the end intervals are constant-jerk
    # cubics in time from / to rest (x^2 = 1.5 |u| ds at their inner gridpoint)
    cons = x[1:] ** 2 - x[:-1] ** 2 - (u[:-1] + u[1:]) * ds
    cons[0] = x[1] ** 2 - 1.5 * u[1] * ds[0]
    cons[K - 1] = x[K - 1] ** 2 + 1.5 * u[K - 1] * ds[K - 1]
    g = [cons]
    xl, xr, ul, ur = x[:-1], x[1:], u[:-1], u[1:]
    for r, S in enumerate(slots):  # (velocity: bounds on x, see _bounds)
        L1, L2, R1, R2, M1, M2, M3, alim, jlim = (S[:, c] for c in range(9))
        g.append((L2 * xl**2 + L1 * ul) / alim)
        if _rows(r) == 4:  # the acceleration at the midpoint
            g.append((M2 * xm2 + M1 * um) / alim)
        # jerk at both ends of every interval (x changes fastest near rest)
        g.append(xl * (M3 * xl**2 + 3.0 * L2 * ul + L1 * dul) / jlim)
        g.append(xr * (M3 * xr**2 + 3.0 * R2 * ur + R1 * dur) / jlim)
    T = ca.sum1(_interval_times(ds, x, ca))
    # a small penalty on the change of du/ds between neighbouring intervals keeps the jerk from
    # chattering at the grid's period (IPOPT otherwise alternates between equivalent optima)
    dc = du[1:] - du[:-1]
    T = T + JERK_SMOOTHING * ca.sum1(dc**2 * 0.5 * (ds[1:] + ds[:-1]))
    p = ca.vertcat(ds, *[ca.vec(S) for S in slots])
    return {"x": ca.vertcat(x, u), "p": p, "f": T, "g": ca.vertcat(*g)}


class _Terms:
    """Path derivatives (gridpoints and midpoints) and limits of every joint, for the slots."""

    def __init__(self, path: SplinePath, grid: np.ndarray, limits: JointLimits) -> None:
        m = 0.5 * (grid[:-1] + grid[1:])
        self.P1, self.P2 = path._d1(grid), path._d2(grid)  # (K+1, n)
        self.M1, self.M2 = path._d1(m), path._d2(m)  # (K, n)
        self.M3 = _third_derivative(path, grid)  # (K, n)
        self.a, self.j = np.asarray(limits.acceleration), np.asarray(limits.jerk)
        self.ds = np.diff(grid)

    def ratios(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Model ratios (K, n): the worst of acceleration (left gridpoint, midpoint) and jerk
        (both ends) of every joint on every interval, for the profile ``x``, ``u``."""
        ds, du = self.ds, np.diff(u) / self.ds
        w = np.ones_like(ds)
        w[0] = w[-1] = 1.0 / 3.0
        dul, dur = du * w, du * w
        dul[0], dur[-1] = 0.0, 0.0
        xl, xr, ul, ur = x[:-1, None], x[1:, None], u[:-1, None], u[1:, None]
        xm2 = (x[:-1] ** 2 + u[:-1] * ds + 0.25 * np.diff(u) * ds)[:, None]
        um = 0.5 * (ul + ur)
        acc = (
            np.maximum(np.abs(self.P2[:-1] * xl**2 + self.P1[:-1] * ul), np.abs(self.M2 * xm2 + self.M1 * um)) / self.a
        )
        jl = np.abs(xl * (self.M3 * xl**2 + 3.0 * self.P2[:-1] * ul + self.P1[:-1] * dul[:, None]))
        jr = np.abs(xr * (self.M3 * xr**2 + 3.0 * self.P2[1:] * ur + self.P1[1:] * dur[:, None]))
        return np.maximum(acc, np.maximum(jl, jr) / self.j)

    def parameters(self, slots: np.ndarray) -> np.ndarray:
        """The NLP's parameter vector for slot joints ``slots`` (K, R)."""
        k = np.arange(self.ds.size)[:, None]
        blocks = [self.ds]
        for r in range(slots.shape[1]):
            j = slots[:, r : r + 1]
            cols = [
                self.P1[:-1][k, j],
                self.P2[:-1][k, j],
                self.P1[1:][k, j],
                self.P2[1:][k, j],
                self.M1[k, j],
                self.M2[k, j],
                self.M3[k, j],
                self.a[j],
                self.j[j],
            ]
            blocks.append(np.hstack(cols).reshape(-1, order="F"))
        return np.concatenate(blocks)


def _rows(slot: int) -> int:
    """Constraint rows per interval of slot ``slot``: acceleration at the left gridpoint, jerk at
    both ends, and for the first :data:`JERK_MID_ACC_SLOTS` slots the midpoint acceleration."""
    return 4 if slot < JERK_MID_ACC_SLOTS else 3


def _row_offset(slot: int, K: int) -> int:
    """Index of slot ``slot``'s first row in the constraint vector (after the K consistency rows)."""
    return K + K * sum(_rows(i) for i in range(slot))


def _third_derivative(path: SplinePath, grid: np.ndarray) -> np.ndarray:
    """The third path derivative representing each grid interval, (K, n): its midpoint value, or
    where knots lie inside the interval (a dense path; the derivative is constant on every knot
    segment) the value of largest magnitude among the segments the interval overlaps, signed."""
    p3 = path._d3(0.5 * (grid[:-1] + grid[1:]))
    knots = path.knots
    first = np.searchsorted(knots, grid[:-1], side="right") - 1
    inside = np.searchsorted(knots, grid[1:], side="left") - 1 - first  # knots strictly inside
    if not np.any(inside > 0):
        return p3
    seg = 6.0 * np.asarray(path.spline.c[0])  # (N-1, n) per knot segment
    first = np.clip(first, 0, seg.shape[0] - 1)
    cols = np.arange(seg.shape[1])
    for k in np.flatnonzero(inside > 0):
        block = seg[first[k] : first[k] + inside[k] + 1]
        p3[k] = block[np.argmax(np.abs(block), axis=0), cols]
    return p3


def _slots(ratio: np.ndarray, n_slots: int) -> np.ndarray:
    """The ``n_slots`` joints of largest model ratio on every interval, (K, n_slots) int."""
    return np.argsort(-ratio, axis=1, kind="stable")[:, :n_slots]


def _interval_times(ds: Any, x: Any, lib: Any = np) -> Any:
    """Duration of each interval (s): the trapezoid rule ``2 ds / (x_k + x_{k+1})`` inside, and
    ``3 ds / x`` for the two end intervals, which start or end at rest with constant jerk
    (``s = J t^3 / 6``: ``t = 3 s / x``).  NumPy or CasADi (``lib``) vectors."""
    h = 2.0 * ds / (x[:-1] + x[1:] + 1e-12)
    if lib is np:
        h = np.array(h, dtype=float)
        h[0], h[-1] = 3.0 * ds[0] / x[1], 3.0 * ds[-1] / x[-2]
        return h
    n = ds.shape[0]
    first = 3.0 * ds[0] / (x[1] + 1e-12)
    last = 3.0 * ds[n - 1] / (x[n - 1] + 1e-12)
    return ca.vertcat(first, h[1 : n - 1], last)


def _bounds(n_grid: int, n_slots: int, x_max: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Variable and constraint bounds: ``0 <= x <= x_max`` (the velocity limits, 1/s), rest at
    both ends; consistency = 0; acceleration and jerk ratios in [-1, 1]."""
    K1 = n_grid
    lbx = np.r_[np.zeros(K1), np.full(K1, -np.inf)]
    ubx = np.r_[x_max, np.full(K1, np.inf)]
    for i in (0, K1 - 1, K1, 2 * K1 - 1):
        lbx[i] = ubx[i] = 0.0
    ub = np.r_[np.zeros(K1 - 1), np.ones(sum(_rows(r) for r in range(n_slots)) * (K1 - 1))]
    return lbx, ubx, -ub, ub


# --------------------------------------------------------------------------- #
# The method
# --------------------------------------------------------------------------- #


def _warm_start(path: SplinePath, grid: np.ndarray, limits: JointLimits) -> np.ndarray | None:
    """TOPP-RA's velocity/acceleration-optimal profile on the grid, scaled inside (x, u)."""
    tp = import_toppra().SplineInterpolator(path.knots, path.q_path, bc_type="natural")
    sd, _msg, _inf = toppra_once(tp, grid, limits.velocity, limits.acceleration)
    if sd is None:
        return None
    x = JERK_WARM_FRACTION * sd
    x[0] = x[-1] = 0.0
    b = x**2
    u = np.zeros_like(x)
    u[1:-1] = (b[2:] - b[:-2]) / (2.0 * (grid[2:] - grid[:-2]))
    return np.r_[x, u]


def _fine_check(path: SplinePath, limits: JointLimits, dt: float, law: JerkLaw) -> dict[str, np.ndarray]:
    tc = check_times(law.duration, dt, law.breaks)
    cs, csd, csdd, csddd = law(tc[tc < law.duration])
    _, qd, qdd, qddd = path.evaluate(cs, csd, csdd, csddd)
    return limit_ratios(qd, qdd, qddd, limits)


def _optimise(terms: _Terms, z0: np.ndarray, x_max: np.ndarray, max_iter: int) -> tuple[np.ndarray, dict, int]:
    """Solve the slot NLP, swapping in any joint the solution shows above its limits (at most
    JERK_SLOT_ROUNDS solves; each re-solve starts from the last primal-dual optimum, the swapped
    rows' multipliers zeroed).  Returns the solution, IPOPT's stats of the last solve and the
    number of solves."""
    K1, K = terms.ds.size + 1, terms.ds.size
    n_slots = min(JERK_SLOTS, terms.a.size)
    slots = _slots(terms.ratios(z0[:K1], z0[K1:]), n_slots)
    bounds = dict(zip(("lbx", "ubx", "lbg", "ubg"), _bounds(K1, n_slots, x_max)))
    z, st, rounds, warm = z0, {}, 0, {}
    for rounds in range(1, JERK_SLOT_ROUNDS + 1):  # noqa: B007 - the count is reported after the loop
        solver = _solver(K1, n_slots, max_iter, warm=bool(warm))
        with interrupts.native_call():  # IPOPT swallows Ctrl-C: raised again after the call
            res = solver(x0=z, p=terms.parameters(slots), **bounds, **warm)
        st, z = solver.stats(), np.asarray(res["x"]).ravel()
        if not st.get("success", False):
            break
        ratio = terms.ratios(np.maximum(z[:K1], 0.0), z[K1:])
        k_bad, j_bad = np.nonzero(ratio > 1.0 + JERK_SLOT_TOL)
        outside = [(k, j) for k, j in zip(k_bad, j_bad) if j not in slots[k]]
        if not outside:
            break
        warm = {"lam_x0": np.asarray(res["lam_x"]).ravel(), "lam_g0": np.asarray(res["lam_g"]).ravel()}
        for k, j in outside:  # the joint replaces the slot of smallest ratio there
            r = int(np.argmin(ratio[k, slots[k]]))
            slots[k, r] = j
            warm["lam_g0"][_row_offset(r, K) + np.arange(_rows(r)) * K + k] = 0.0
    return z, st, rounds


def run_jerk_optimal(path: SplinePath, limits: JointLimits, dt: float, opts: Mapping[str, Any]) -> Trajectory:
    """Time ``path`` time-optimally under velocity, acceleration and jerk limits (see module doc).

    Returns
    -------
    Trajectory
        ``method = "jerk_optimal"``; status OK only with every ratio within its limit; never
        raises for solver failures (IPOPT's own status is quoted in the reason).
    """
    n = limits.n_joints
    n_grid = int(opts.get("gridpoints", default_gridpoints(path.knots.shape[0])))
    max_iter = int(opts.get("max_iterations", JERK_MAX_ITER))
    grid = profile_grid(path.knots, n_grid)
    z0 = _warm_start(path, grid, limits)
    if z0 is None:
        return empty_trajectory("jerk_optimal", TimingStatus.FAILED, "TOPP-RA warm start failed on the grid", n, dt, 0)
    terms = _Terms(path, grid, limits)
    with np.errstate(divide="ignore"):
        x_max = np.min(limits.velocity[None, :] / np.abs(terms.P1), axis=1)  # (K+1,) 1/s
    z0[:n_grid] = np.minimum(z0[:n_grid], x_max)
    z, st, rounds = _optimise(terms, z0, x_max, max_iter)
    ip = str(st.get("return_status", "unknown"))
    x, u = np.maximum(z[:n_grid], 0.0), z[n_grid:].copy()
    x[0] = x[-1] = u[0] = u[-1] = 0.0
    if not st.get("success", False) or np.any(x[1:-1] <= 0.0):
        return empty_trajectory(
            "jerk_optimal",
            TimingStatus.FAILED,
            f"IPOPT ({ip}) after {st.get('iter_count', 0)} iterations on {n_grid} gridpoints",
            n,
            dt,
            rounds,
        )
    law, scale = JerkLaw(grid, x, u), 1.0
    ratio = _fine_check(path, limits, dt, law)
    for _ in range(JERK_SCALE_ROUNDS):  # a slower law is checked at other times: repeat
        r = max(
            float(ratio["velocity"].max()),
            math.sqrt(float(ratio["acceleration"].max())),
            float(ratio["jerk"].max()) ** (1.0 / 3.0),
        )
        if r <= 1.0 + LIMIT_RATIO_TOL:
            break
        scale *= r * (1.0 + JERK_SCALE_MARGIN)
        law = JerkLaw(grid, x, u, scale)
        ratio = _fine_check(path, limits, dt, law)
    t_nlp = float(np.sum(_interval_times(np.diff(grid), x)))
    summary = (
        f"IPOPT ({ip}, {st.get('iter_count', 0)} iterations in the last of {rounds} solve(s)) on {n_grid} "
        f"gridpoints with the {min(JERK_SLOTS, n)} most loaded joints of every interval, warm start "
        f"TOPP-RA; optimal profile {t_nlp:.4f} s, slowed x{scale:.4f} after the fine check; "
        f"motion {law.duration:.4f} s; {format_ratios(ratio)}"
    )
    check_sd = law(check_times(law.duration, dt, law.breaks))[1]
    return finish_trajectory(
        "jerk_optimal",
        path,
        limits,
        dt,
        law,
        law.duration,
        ratio,
        summary,
        check_sd=check_sd,
        sd_scale=float(x.max()),
        iterations=1,
    )


def _validate(out: dict[str, Any]) -> dict[str, Any]:
    check_integer_options(out, (("gridpoints", 20), ("max_iterations", 1)))
    return out


#: The registry record of ``method="jerk_optimal"``.
JERK_OPTIMAL_METHOD: TimingMethod = register_method(
    TimingMethod(
        name="jerk_optimal",
        run=run_jerk_optimal,
        options=JERK_OPTIONS,
        validate_options=_validate,
        checked_limits=_CHECKED,
        description="time-optimal under joint velocity, acceleration and jerk limits (NLP over the "
        "path-velocity profile, IPOPT, warm-started from TOPP-RA)",
        display_name="jerk-optimal",
        controller_rank=10,
        default=True,
        duration_note="time-optimal under velocity, acceleration and jerk limits: the trajectory the controller runs",
    )
)
