"""Per-joint angle error maps from the residual: spectrum search and nonparametric smoothers.

Two jobs, both on the weighted residual of a fitted model (measurement frame):

* :func:`propose_map` -- the candidate ``joint_error_map``
  (:mod:`models.effects.joint_error_map`): a greedy search over joints and frequencies
  (cycles per revolution, :data:`MAP_MIN_CPR` .. :data:`MAP_MAX_CPR` in steps of
  :data:`MAP_FREQ_STEP_CPR`, refined between grid points) of the error signature of joint j,
  ``J_j(q) [cos(f q_j), sin(f q_j)]``, orthogonal to the model's free parameters.  A term is
  kept when its F-test passes at :data:`MAP_ALPHA` divided by the number of (joint,
  frequency) pairs searched (a spectrum with a family-wise significance test) *and* it lowers
  the cross-validated residual (same folds as the selection).  The angle range of each joint
  is the data's; frequencies above what the sampling of the joint angle resolves (three samples
  per cycle across the 90 % quantile of the gaps) are not searched; below one cycle within the
  range only whole harmonics are (:func:`frequency_grid`).  A map is a function of its joint's
  angle everywhere: beyond the covered range its terms continue (:mod:`models.effects.joint_error_map`).
* :func:`smoother_cv` -- a penalised B-spline (P-spline) of a residual component against one
  variable, the smoothing chosen by generalised cross-validation, scored out of fold: the
  nonparametric check behind "no unexplained structure" (:mod:`.diagnostics`).

Units: angles rad, frequencies cycles per revolution, residuals in weighted units (``1/sigma``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.interpolate import BSpline

from models.effects.joint_error_map import FREQ_SHAPE, MAP_COMPONENTS, MAP_SLOTS, N_COMP

#: Frequencies searched, cycles per revolution: from MAP_MIN_CPR to MAP_MAX_CPR in steps of a quarter
#: of the resolution of the joint's covered range (``1 / range`` in revolutions), at least
#: MAP_FREQ_STEP_CPR; the best is refined between its grid neighbours.
MAP_MIN_CPR = 1.0
MAP_MAX_CPR = 48.0
MAP_FREQ_STEP_CPR = 0.1
#: Family-wise significance level of the spectrum search (divided by the pairs searched).
MAP_ALPHA = 1e-3
#: Cycles a term must complete within the joint's covered range.
MAP_MIN_CYCLES_IN_RANGE = 1.0
#: Two terms of one channel are at least this many resolutions (1 / range in revolutions) apart:
#: closer ones cannot be told apart over the range (they would trade large opposite amplitudes).
MAP_MIN_SEPARATION = 1.0
#: A term must remove at least this share of the residual sum of squares left before it.
MAP_MIN_TERM_SHARE = 0.01
#: A joint whose angle spans less than this in the data gets no map, rad (10 deg).
MAP_MIN_RANGE_RAD = np.radians(10.0)
#: Samples per cycle required across the gaps between sorted joint angles (their MAP_GAP_QUANTILE).
MAP_SAMPLES_PER_CYCLE = 3.0
MAP_GAP_QUANTILE = 0.9
#: A whole number of cycles per revolution is preferred unless the refined frequency's gain exceeds
#: its gain by more than this many residual variances (likelihood ratio, chi-square with 1 dof, p = 0.001:
#: a whole number of cycles per revolution is the physical prior of a gear or bearing error).
MAP_WHOLE_CHI2 = 10.83
#: Passes of the frequency refinement with every term in the model.
MAP_BACKFIT_PASSES = 2
#: Golden-section refinement steps of a frequency between grid points.
MAP_REFINE_STEPS = 20


@dataclass
class MapTerm:
    """One term of a proposed map: joint and component (0-based, :data:`MAP_COMPONENTS`), frequency
    (cycles/rev), the share of the residual sum of squares it removes, its F-test p-value and the
    CV residual sum of squares after it."""

    joint: int
    component: int
    freq_cpr: float
    rss_share: float
    p_value: float
    cv_rss: float

    @property
    def label(self) -> str:
        return f"joint {self.joint + 1} {MAP_COMPONENTS[self.component]} at {self.freq_cpr:.4g} cycles/rev"


@dataclass
class MapProposal:
    """Frequencies and ranges of a ``joint_error_map`` candidate.

    Attributes
    ----------
    freq : ndarray, shape FREQ_SHAPE (6, N_COMP, MAP_SLOTS)
        Cycles per revolution per slot (0: unused).
    range_rad : ndarray, shape (6, 2)
        ``[lo, hi]`` commanded angle range of each joint's map, rad.
    terms : list of MapTerm
        In the order found.
    """

    freq: np.ndarray
    range_rad: np.ndarray
    terms: list[MapTerm] = field(default_factory=list)


def joint_max_cpr(q: np.ndarray) -> float:
    """Highest frequency (cycles/rev) the sampling of one joint's angles ``q`` (N,) rad resolves:
    :data:`MAP_SAMPLES_PER_CYCLE` samples per cycle across the gaps between sorted angles (their
    :data:`MAP_GAP_QUANTILE` quantile, so that a few holes in the sampling do not forbid what the
    rest resolves)."""
    s = np.sort(np.unique(q))
    if len(s) < 3:
        return 0.0
    gap = float(np.quantile(np.diff(s), MAP_GAP_QUANTILE))
    return float(2 * np.pi / (MAP_SAMPLES_PER_CYCLE * max(gap, 1e-12)))


def resolution_cpr(q: np.ndarray) -> float:
    """Frequency resolution of one joint's covered range, ``1 / range`` in revolutions (cycles/rev)."""
    return float(2 * np.pi / max(float(np.ptp(q)), 1e-12))


def frequency_grid(q: np.ndarray) -> np.ndarray:
    """Frequencies (cycles/rev) searched for one joint's angles ``q`` (N,) rad (empty: none): from
    one full cycle within the covered range or MAP_MIN_CPR, to what the sampling resolves, in steps
    of a quarter of the range's resolution; and below one cycle within the range the whole harmonics
    of the turn from MAP_MIN_CPR (a bearing's or gear's 1, 2, ... cycles per revolution: what the data
    show of them over part of a turn says something about the rest, the geometric directions are
    projected out so that they claim only what a trend cannot, and the identifiability step holds what
    the data cannot determine)."""
    if np.ptp(q) < MAP_MIN_RANGE_RAD:
        return np.zeros(0)
    res = resolution_cpr(q)
    fmin = max(MAP_MIN_CPR, MAP_MIN_CYCLES_IN_RANGE * res)
    fmax = min(MAP_MAX_CPR, joint_max_cpr(q))
    step = max(MAP_FREQ_STEP_CPR, 0.25 * res)
    if fmax < fmin:
        return np.zeros(0)
    slow = np.arange(MAP_MIN_CPR, fmin - 1e-9, 1.0)  # whole harmonics slower than a cycle over the range
    return np.concatenate([slow, np.arange(fmin, fmax + 1e-9, step)])


def _orth(A: np.ndarray) -> np.ndarray:
    """Orthonormal basis (n, r) of the columns of ``A`` (n, k), rank-revealing."""
    if A.shape[1] == 0:
        return np.zeros((A.shape[0], 0))
    U, s, _vt = np.linalg.svd(A, full_matrices=False)
    keep = s > 1e-10 * max(s[0], 1e-300)
    return U[:, keep]


def _signature(Jc: np.ndarray, q: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Error signatures of one channel, flattened rows ``[x0, y0, z0, x1, ...]``: (3n, 2F).

    ``Jc`` (n, 3) weighted Jacobian column of the DH entry, ``q`` (n,) the joint's angles, ``f`` (F,)."""
    ph = np.outer(q, f)
    c = (Jc[:, :, None] * np.cos(ph)[:, None, :]).reshape(-1, len(f))
    s = (Jc[:, :, None] * np.sin(ph)[:, None, :]).reshape(-1, len(f))
    out = np.empty((c.shape[0], 2 * len(f)))
    out[:, 0::2], out[:, 1::2] = c, s
    return out


def _gain2(a: np.ndarray, b: np.ndarray, aa: np.ndarray, bb: np.ndarray, ab: np.ndarray) -> np.ndarray:
    """Residual SS removed by a pair of columns from their products with the residual (a, b) and
    their Gram entries (aa, bb, ab), all (F,)."""
    det = aa * bb - ab * ab
    ok = det > 1e-12 * np.maximum(aa * bb, 1e-300)
    g = np.zeros(len(aa))
    g[ok] = (bb[ok] * a[ok] ** 2 - 2 * ab[ok] * a[ok] * b[ok] + aa[ok] * b[ok] ** 2) / det[ok]
    return g


def _channel_gain(Jc: np.ndarray, q: np.ndarray, f: np.ndarray, r: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Gain of every frequency ``f`` (F,) of one channel against residual ``r`` (3n,), orthogonal
    to ``Q`` (3n, k), without forming the (3n, 2F) signatures: the pose-wise products
    ``J_c,i . r_i``, ``|J_c,i|^2`` and ``J_c,i . Q_i`` carry everything."""
    n = len(q)
    C, S = np.cos(np.outer(q, f)), np.sin(np.outer(q, f))
    w = np.einsum("ni,ni->n", Jc, r.reshape(n, 3))
    s2 = np.einsum("ni,ni->n", Jc, Jc)
    M = np.einsum("ni,nik->nk", Jc, Q.reshape(n, 3, -1))
    a, b = C.T @ w, S.T @ w
    aa, bb, ab = (C * C).T @ s2, (S * S).T @ s2, (C * S).T @ s2
    if M.shape[1]:
        U, V = M.T @ C, M.T @ S
        Qr = Q.T @ r
        a, b = a - U.T @ Qr, b - V.T @ Qr
        aa, bb, ab = (
            aa - np.einsum("kf,kf->f", U, U),
            bb - np.einsum("kf,kf->f", V, V),
            ab - np.einsum("kf,kf->f", U, V),
        )
    return _gain2(a, b, aa, bb, ab)


def _cv_rss(Z: np.ndarray, r: np.ndarray, folds3: np.ndarray) -> float:
    """K-fold CV residual SS of ``r`` (3n,) regressed on ``Z`` (3n, m)."""
    if Z.shape[1] == 0:
        return float(r @ r)
    G, g = Z.T @ Z, Z.T @ r
    tot = 0.0
    for k in np.unique(folds3):
        sel = folds3 == k
        Zk, rk = Z[sel], r[sel]
        beta = np.linalg.lstsq(G - Zk.T @ Zk, g - Zk.T @ rk, rcond=None)[0]
        e = rk - Zk @ beta
        tot += float(e @ e)
    return tot


def _refine(
    Jc: np.ndarray, q: np.ndarray, r: np.ndarray, Q: np.ndarray, f0: float, lo: float, hi: float, step: float, s2: float
) -> float:
    """Golden-section maximum of the gain within a grid ``step`` of ``f0``, inside ``[lo, hi]``;
    a whole number of cycles per revolution when the data do not tell it from the refined
    frequency (a likelihood-ratio test at :data:`MAP_WHOLE_CHI2` with the residual variance ``s2``)."""
    a, b = max(lo, f0 - step), min(hi, f0 + step)
    gr = (np.sqrt(5) - 1) / 2

    def gain(f: float) -> float:
        return float(_channel_gain(Jc, q, np.array([f]), r, Q)[0])

    c, d = b - gr * (b - a), a + gr * (b - a)
    gc, gd = gain(c), gain(d)
    for _ in range(MAP_REFINE_STEPS):
        if gc > gd:
            b, d, gd = d, c, gc
            c = b - gr * (b - a)
            gc = gain(c)
        else:
            a, c, gc = c, d, gd
            d = a + gr * (b - a)
            gd = gain(d)
    best = c if gc > gd else d
    best = best if gain(best) >= gain(f0) else f0
    whole = float(np.round(best))
    if lo <= whole <= hi and abs(whole - best) <= min(step, 0.5) and gain(best) - gain(whole) <= MAP_WHOLE_CHI2 * s2:
        return whole
    return best


def _bracket(fg: np.ndarray, f: float, others: Sequence[float], sep: float) -> tuple[float, float]:
    """Interval of the grid ``fg`` around ``f`` that keeps ``sep`` (cycles/rev) clear of the
    channel's other frequencies ``others``."""
    lo_f, hi_f = float(fg[0]), float(fg[-1])
    for t in others:
        if t < f:
            lo_f = max(lo_f, t + sep)
        else:
            hi_f = min(hi_f, t - sep)
    return lo_f, hi_f


def _term_signature(t: MapTerm, chans: dict[tuple[int, int], np.ndarray], q: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Signature (3n, 2) of a term with the directions ``Q`` projected out."""
    D = _signature(chans[(t.joint, t.component)], q[:, t.joint], np.array([t.freq_cpr]))
    return D - Q @ (Q.T @ D)


def _set_freq(prop: MapProposal) -> None:
    """``prop.freq`` from its terms (slots of each channel in the order of the terms)."""
    prop.freq[:] = 0.0
    used = np.zeros(prop.freq.shape[:2], dtype=int)
    for t in prop.terms:
        prop.freq[t.joint, t.component, used[t.joint, t.component]] = t.freq_cpr
        used[t.joint, t.component] += 1


def _scan(
    prop: MapProposal,
    chans: dict[tuple[int, int], np.ndarray],
    grids: dict[int, np.ndarray],
    res: dict[int, float],
    q: np.ndarray,
    r: np.ndarray,
    QZ: np.ndarray,
    used: np.ndarray,
) -> tuple[float, tuple[int, int], float] | None:
    """The spectrum: the best (gain, (joint, component), frequency) over every channel with a free
    slot, frequencies within a separation of the channel's terms excluded."""
    best: tuple[float, tuple[int, int], float] | None = None
    for (j, c), Jc in chans.items():
        if used[j, c] >= MAP_SLOTS:
            continue
        fg = grids[j]
        g = _channel_gain(Jc, q[:, j], fg, r, QZ)
        taken = prop.freq[j, c, : used[j, c]]
        if len(taken):
            near = np.min(np.abs(fg[:, None] - taken[None, :]), axis=1) < MAP_MIN_SEPARATION * res[j]
            g = np.where(near, 0.0, g)
        k = int(np.argmax(g))
        if best is None or g[k] > best[0]:
            best = (float(g[k]), (j, c), float(fg[k]))
    return best


def _search_space(
    q: np.ndarray, channels: dict[tuple[int, int], np.ndarray]
) -> tuple[dict[int, np.ndarray], dict[int, float], dict[tuple[int, int], np.ndarray], int]:
    """Per joint the frequency grid and resolution (cycles/rev), the channels searched, and the number of tests."""
    grids = {j: frequency_grid(q[:, j]) for j in range(6)}
    res = {j: resolution_cpr(q[:, j]) for j in range(6)}
    chans = {jc: Jc for jc, Jc in channels.items() if len(grids[jc[0]]) and np.any(Jc != 0)}
    n_tests = int(sum(len(grids[j]) for j, _c in chans))
    return grids, res, chans, n_tests


def propose_map(
    r: np.ndarray, channels: dict[tuple[int, int], np.ndarray], q: np.ndarray, Jfree: np.ndarray, folds: np.ndarray
) -> MapProposal | None:
    """Search the residual for per-joint periodic error motions (see the module docstring).

    Parameters
    ----------
    r : ndarray, shape (3n,)
        Weighted residual, rows ``[x0, y0, z0, x1, ...]`` (measurement frame).
    channels : dict
        (joint, component) (0-based, :data:`MAP_COMPONENTS`) -> weighted Jacobian column (n, 3)
        of that DH entry of that joint.
    q : ndarray, shape (n, 6)
        Commanded joint angles, rad.
    Jfree : ndarray, shape (3n, k)
        Weighted Jacobian of the model's free parameters and of the directions the map must not
        claim (other candidates); projected out.
    folds : ndarray of int, shape (n,)
        Cross-validation fold of each row.

    Returns
    -------
    MapProposal or None
        None when no term passes.
    """
    n = len(q)
    folds3 = np.repeat(folds, 3)
    Q = _orth(Jfree)
    r = r - Q @ (Q.T @ r)
    r0 = r.copy()
    grids, res, chans, n_tests = _search_space(q, channels)
    freq = np.zeros(FREQ_SHAPE)
    prop = MapProposal(freq=freq, range_rad=np.column_stack([q.min(axis=0), q.max(axis=0)]))
    if not n_tests:
        return None
    alpha = MAP_ALPHA / n_tests
    Z = np.zeros((3 * n, 0))
    rss = rss_start = float(r @ r)
    cv_prev = _cv_rss(Z, r0, folds3)
    k_free = Q.shape[1]
    used = np.zeros((6, N_COMP), dtype=int)
    while True:
        QZ = np.column_stack([Q, Z]) if Z.size else Q
        best = _scan(prop, chans, grids, res, q, r, QZ, used)
        if best is None or best[0] <= 0:
            break
        _g, (j, c), f = best
        fg = grids[j]
        Jc = chans[(j, c)]
        step = float(fg[-1] - fg[-2]) if len(fg) > 1 else MAP_FREQ_STEP_CPR
        lo_f, hi_f = _bracket(fg, f, freq[j, c, : used[j, c]], MAP_MIN_SEPARATION * res[j])
        df2 = 3 * n - k_free - Z.shape[1] - 2
        f = _refine(Jc, q[:, j], r, QZ, f, lo_f, hi_f, step, max(rss - best[0], 0.0) / max(df2, 1))
        D = _signature(Jc, q[:, j], np.array([f]))
        D = D - QZ @ (QZ.T @ D)
        coef = np.linalg.lstsq(D, r, rcond=None)[0]
        gain = float(r @ r - np.sum((r - D @ coef) ** 2))
        rss_new = rss - gain
        if df2 <= 0 or rss_new <= 0:
            break
        p = float(stats.f.sf((gain / 2) / (rss_new / df2), 2, df2))
        Dn = _orth(D)
        Zn = np.column_stack([Z, Dn])
        cv_new = _cv_rss(Zn, r0, folds3)
        if p >= alpha or cv_new >= cv_prev or gain < MAP_MIN_TERM_SHARE * rss:
            break
        prop.terms.append(
            MapTerm(joint=j, component=c, freq_cpr=f, rss_share=gain / max(rss_start, 1e-300), p_value=p, cv_rss=cv_new)
        )
        freq[j, c, used[j, c]] = f
        used[j, c] += 1
        Z, rss, cv_prev = Zn, rss_new, cv_new
        r = r - Dn @ (Dn.T @ r)
    if not prop.terms:
        return None
    _backfit(prop, chans, grids, res, q, r0, Q, rss / max(3 * n - k_free - Z.shape[1], 1))
    _prune(prop, chans, q, r0, Q, alpha)
    return prop if prop.terms else None


def _prune(
    prop: MapProposal,
    chans: dict[tuple[int, int], np.ndarray],
    q: np.ndarray,
    r0: np.ndarray,
    Q: np.ndarray,
    alpha: float,
) -> None:
    """Backward elimination: with every term in the model (after backfitting), drop the least
    significant one while its F-test fails at ``alpha`` or it removes under :data:`MAP_MIN_TERM_SHARE`
    of the residual left without it (a term that mattered only while the others were still missing)."""

    def rss_of(cols: list[np.ndarray]) -> float:
        if not cols:
            return float(r0 @ r0)
        Z = _orth(np.column_stack(cols))
        e = r0 - Z @ (Z.T @ r0)
        return float(e @ e)

    while prop.terms:
        sigs = [_term_signature(t, chans, q, Q) for t in prop.terms]
        rss_full = rss_of(sigs)
        df2 = max(len(r0) - Q.shape[1] - 2 * len(sigs), 1)
        worst, worst_p = None, -1.0
        for k in range(len(sigs)):
            rss_k = rss_of(sigs[:k] + sigs[k + 1 :])
            gain = max(rss_k - rss_full, 0.0)
            p = float(stats.f.sf((gain / 2) / max(rss_full / df2, 1e-300), 2, df2))
            if gain < MAP_MIN_TERM_SHARE * rss_k:
                p = max(p, 1.0)
            if p > worst_p:
                worst, worst_p = k, p
        if worst is None or worst_p < alpha:
            break
        del prop.terms[worst]
    _set_freq(prop)


def _backfit(
    prop: MapProposal,
    chans: dict[tuple[int, int], np.ndarray],
    grids: dict[int, np.ndarray],
    res: dict[int, float],
    q: np.ndarray,
    r0: np.ndarray,
    Q: np.ndarray,
    s2: float,
) -> None:
    """Refine each term's frequency with the others in the model (:data:`MAP_BACKFIT_PASSES`
    passes): a term found early was fitted while later ones were still in the residual."""
    for _ in range(MAP_BACKFIT_PASSES):
        for k, t in enumerate(prop.terms):
            others = [_term_signature(u, chans, q, Q) for i, u in enumerate(prop.terms) if i != k]
            O = _orth(np.column_stack([Q] + others)) if others else Q
            r = r0 - O @ (O.T @ r0)
            fg = grids[t.joint]
            step = float(fg[-1] - fg[-2]) if len(fg) > 1 else MAP_FREQ_STEP_CPR
            same = [u.freq_cpr for u in prop.terms if u is not t and (u.joint, u.component) == (t.joint, t.component)]
            lo_f, hi_f = _bracket(fg, t.freq_cpr, same, MAP_MIN_SEPARATION * res[t.joint])
            t.freq_cpr = _refine(chans[(t.joint, t.component)], q[:, t.joint], r, O, t.freq_cpr, lo_f, hi_f, step, s2)
    _set_freq(prop)


# ----------------------------------------------------------------------------------
# Nonparametric smoothers (P-splines) with cross-validation
# ----------------------------------------------------------------------------------

#: Most interior knots of a P-spline; a joint's spline gets four per cycle of the highest
#: map frequency over its range, at most one per five distinct angles.
SMOOTHER_MAX_KNOTS = 120
SMOOTHER_MIN_KNOTS = 8
#: Smoothing parameters tried (relative to trace(B^T B) / trace(P)); GCV picks one.
SMOOTHER_LAMBDAS = tuple(10.0 ** np.arange(-6, 3.5, 0.5))


@dataclass
class SmootherFit:
    """A cross-validated P-spline fit of a residual.

    Attributes
    ----------
    explained : float
        ``1 - CV RSS / RSS0`` (out of fold; RSS0 around the mean).
    p_value : float
        F-test against the mean with the fit's effective degrees of freedom.
    edf : float
        Effective degrees of freedom.
    fitted : ndarray
        In-sample fit, shaped like the response.
    per_column : ndarray
        Explained fraction (out of fold) of each response column (per residual direction).
    """

    explained: float
    p_value: float
    edf: float
    fitted: np.ndarray
    per_column: np.ndarray


def n_knots(x: np.ndarray) -> int:
    """Knots of the P-spline of angles ``x`` (N,) rad (see :data:`SMOOTHER_MAX_KNOTS`)."""
    cycles = MAP_MAX_CPR * float(np.ptp(x)) / (2 * np.pi)
    distinct = len(np.unique(np.round(x, 9)))
    return int(max(SMOOTHER_MIN_KNOTS, min(SMOOTHER_MAX_KNOTS, 4 * cycles, distinct // 5)))


def bspline_basis(x: np.ndarray, knots: int) -> np.ndarray:
    """Cubic B-spline basis (N, knots + 3) on equally spaced knots over the range of ``x``."""
    lo, hi = float(np.min(x)), float(np.max(x))
    if hi <= lo:
        return np.ones((len(x), 1))
    h = (hi - lo) / knots
    t = np.concatenate([lo - h * np.arange(3, 0, -1), np.linspace(lo, hi, knots + 1), hi + h * np.arange(1, 4)])
    return BSpline.design_matrix(np.clip(x, lo, hi), t, 3).toarray()


def _penalty(nb: int) -> np.ndarray:
    Dm = np.diff(np.eye(nb), 2, axis=0)
    return Dm.T @ Dm


def _pspline(
    A: np.ndarray, y: np.ndarray, P: np.ndarray, folds: np.ndarray, intercept: np.ndarray | None
) -> tuple[float, float, float, np.ndarray, float]:
    """GCV-chosen penalised least squares of ``y`` (m,) on ``A`` (m, nb) with penalty ``P``;
    ``intercept`` (m, k) unpenalised columns (or None).  Returns CV RSS, in-sample RSS, edf,
    fitted (m,), RSS0 (around the intercept-only fit)."""
    X = A if intercept is None else np.column_stack([intercept, A])
    k0 = 0 if intercept is None else intercept.shape[1]
    Pf = np.zeros((X.shape[1], X.shape[1]))
    Pf[k0:, k0:] = P
    if intercept is None:
        rss0 = float(y @ y)
    else:
        c0 = np.linalg.lstsq(intercept, y, rcond=None)[0]
        e0 = y - intercept @ c0
        rss0 = float(e0 @ e0)
    XtX, Xty = X.T @ X, X.T @ y
    scale = np.trace(XtX[k0:, k0:]) / max(np.trace(P), 1e-300)
    ridge = 1e-9 * scale * np.eye(X.shape[1])
    m = len(y)
    best = None
    for lam in SMOOTHER_LAMBDAS:
        Amat = XtX + lam * scale * Pf + ridge
        try:
            coef = np.linalg.solve(Amat, Xty)
            edf = float(np.trace(np.linalg.solve(Amat, XtX)))
        except np.linalg.LinAlgError:
            continue
        rss = float(np.sum((y - X @ coef) ** 2))
        gcv = m * rss / max(m - edf, 1.0) ** 2
        if best is None or gcv < best[0]:
            best = (gcv, lam, coef, edf, rss)
    if best is None:
        return rss0, rss0, 0.0, y - y, rss0
    _g, lam, coef, edf, rss1 = best
    cv = 0.0
    for k in np.unique(folds):
        tr, te = folds != k, folds == k
        Amat = X[tr].T @ X[tr] + lam * scale * Pf + ridge
        ck = np.linalg.lstsq(Amat, X[tr].T @ y[tr], rcond=None)[0]
        cv += float(np.sum((y[te] - X[te] @ ck) ** 2))
    return cv, rss1, edf, X @ coef, rss0


def _ftest(rss0: float, rss1: float, edf: float, k0: int, m: int) -> float:
    df1 = max(edf - k0, 1.0)
    df2 = max(m - edf, 1.0)
    if rss1 <= 0:
        return 0.0
    F = max(rss0 - rss1, 0.0) / df1 / (rss1 / df2)
    return float(stats.f.sf(F, df1, df2))


def smoother_cv(y: np.ndarray, x: np.ndarray, folds: np.ndarray) -> SmootherFit:
    """One residual component ``y`` (N,) against one variable ``x`` (N,): a P-spline (cubic
    B-splines, second-difference penalty, GCV smoothing) around the mean, scored out of fold."""
    y = np.asarray(y, dtype=float).reshape(-1)
    B = bspline_basis(x, n_knots(x))
    yc = y - y.mean()
    cv, r1, edf, f, r0 = _pspline(B, yc, _penalty(B.shape[1]), folds, None)
    explained = 1.0 - cv / r0 if r0 > 0 else 0.0
    return SmootherFit(explained, _ftest(r0, r1, edf + 1.0, 1, len(y)), edf, f + y.mean(), np.array([explained]))


def joint_smoother_cv(R: np.ndarray, Jw: np.ndarray, x: np.ndarray, folds: np.ndarray) -> SmootherFit:
    """The error signature of one joint: residual ``R`` (N, 3) against ``J_j(q) s(q_j)`` with ``s`` a
    P-spline of the joint angle ``x`` (N,) rad and ``J_j`` (N, 3) the joint's Jacobian column (same
    weighting as ``R``), a 3-D offset unpenalised.  ``per_column`` is per residual axis."""
    n = len(x)
    B = bspline_basis(x, n_knots(x))
    A = (Jw[:, :, None] * B[:, None, :]).reshape(3 * n, -1)
    icpt = np.tile(np.eye(3), (n, 1))
    y = R.reshape(-1)
    cv, rss1, edf, fitted, rss0 = _pspline(A, y, _penalty(B.shape[1]), np.repeat(folds, 3), icpt)
    explained = 1.0 - cv / rss0 if rss0 > 0 else 0.0
    F3 = fitted.reshape(n, 3)
    Rc = R - R.mean(axis=0)
    per = 1.0 - np.sum((R - F3) ** 2, axis=0) / np.maximum(np.sum(Rc**2, axis=0), 1e-300)
    return SmootherFit(explained, _ftest(rss0, rss1, edf, 3, 3 * n), edf, F3, per)
