"""Outliers: rows inconsistent with the others (robust fit, ``docs/identification.md`` §5).

Rows of a pose measured at least :data:`OUTLIER_MIN_POSE_ROWS` times are tested
against the other rows of their pose; other rows against all rows.  Scales are
robust; the bound is a Bonferroni chi-square quantile (3 dof) and at least
:data:`OUTLIER_MIN_SIGMAS` robust standard deviations; a visibly heavy bulk leaves
only gross errors; none are excluded when more than :data:`OUTLIER_MAX_FRACTION`
would be.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .evaluation import FitProblem

#: Outlier rejection: family-wise false-alarm probability of the chi-square bound.
OUTLIER_FALSE_ALARM = 0.01
#: At most this fraction of rows may be excluded as outliers; more rows beyond the
#: bound means the model is incomplete, not that the data are bad (then none is).
OUTLIER_MAX_FRACTION = 0.10
#: Tail check of the robust fit: rows with a standardised chi-square (3 dof) above
#: the ``1 - OUTLIER_TAIL_QUANTILE`` quantile but below the outlier bound may number
#: at most ``OUTLIER_TAIL_FACTOR`` times the expected count plus ``OUTLIER_TAIL_SLACK``.
#: A heavy shoulder is tolerated when the rows beyond the bound outnumber it by
#: ``1/OUTLIER_SEPARATION`` (gross errors stand apart from the bulk).
OUTLIER_TAIL_QUANTILE = 1e-3
OUTLIER_TAIL_FACTOR = 3.0
OUTLIER_TAIL_SLACK = 3
OUTLIER_SEPARATION = 0.5
#: Quantile of the squared residual norms that sets the robust scale (with the MAD).
OUTLIER_SCALE_QUANTILE = 0.8
#: An outlier is at least this many robust standard deviations from the bulk, whatever
#: the Bonferroni bound (gross errors, not the shoulder of a slightly heavy bulk).
OUTLIER_MIN_SIGMAS = 8.0
#: Gross errors: this many robust standard deviations from the bulk (scale from a
#: quantile, so a heavy bulk only raises it) are excluded even when the bulk is not
#: Gaussian.
OUTLIER_GROSS_SIGMAS = 20.0
#: Poses with at least this many rows are tested row against row.
OUTLIER_MIN_POSE_ROWS = 3
#: Robust-exclusion refits per model.
OUTLIER_MAX_ROUNDS = 5


def _robust_d2(r: np.ndarray) -> np.ndarray:
    """Squared robust standardised norms of 3-D residual rows (chi-square, 3 dof, under H0).

    ``r`` (N, 3), any unit; returns (N,), dimensionless.  The scale is the larger of
    the median-absolute-deviation scale and the one implied by the
    :data:`OUTLIER_SCALE_QUANTILE` quantile of the squared norms, so that a bulk
    slightly heavier than Gaussian (model error) does not put its shoulder beyond the
    bound; both ignore up to 20 % contamination.
    """
    med = np.median(r, axis=0)
    s_mad = 1.4826 * np.median(np.abs(r - med))
    raw = np.sum(np.square(r - med), axis=1)
    s2_q = float(np.quantile(raw, OUTLIER_SCALE_QUANTILE)) / stats.chi2.ppf(OUTLIER_SCALE_QUANTILE, df=3)
    s2 = max(s_mad**2, s2_q)
    if not np.isfinite(s2) or s2 <= 0:
        return np.zeros(len(r))
    return raw / s2


def _exceeds(d2: np.ndarray, n: int, gross_only: bool) -> np.ndarray:
    """Rows of ``d2`` (standardised chi-square, 3 dof) beyond the outlier bound of ``n`` rows.

    Bonferroni bound (and :data:`OUTLIER_MIN_SIGMAS`), or only gross errors
    (:data:`OUTLIER_GROSS_SIGMAS`) when asked or when the bulk is heavier than
    Gaussian and not clearly separated from the rows beyond the bound.
    """
    bonf = stats.chi2.isf(OUTLIER_FALSE_ALARM / max(n, 1), df=3)
    bound = max(bonf, OUTLIER_MIN_SIGMAS**2)
    lo = stats.chi2.isf(OUTLIER_TAIL_QUANTILE, df=3)
    gross = d2 > OUTLIER_GROSS_SIGMAS**2
    mid = int(np.sum((d2 > lo) & (d2 <= bonf)))
    above = int(np.sum(d2 > bound))
    heavy = mid > OUTLIER_TAIL_FACTOR * len(d2) * OUTLIER_TAIL_QUANTILE + OUTLIER_TAIL_SLACK
    separated = mid <= OUTLIER_SEPARATION * above
    if gross_only or (heavy and not separated):
        return gross
    return d2 > bound


def outlier_mask(prob: FitProblem, pred: np.ndarray, gross_only: bool = False) -> np.ndarray:
    """Inlier mask (N,) of the robust fit of the prediction ``pred`` (N, 3), m.

    Rows of a pose measured at least :data:`OUTLIER_MIN_POSE_ROWS` times are tested
    against the other rows of their pose (the residual minus the median of the
    others), so that pose-level model error -- shared by every row of a pose -- is
    never mistaken for bad measurements and gross errors show even while the model
    is still incomplete; other rows are tested against all rows.  Scales are robust
    (median absolute deviation); the bound is the Bonferroni chi-square quantile
    (3 dof, family-wise false alarm :data:`OUTLIER_FALSE_ALARM`), and at least
    :data:`OUTLIER_MIN_SIGMAS` robust standard deviations.

    Contamination presumes a Gaussian bulk: when the band between the
    ``1 - OUTLIER_TAIL_QUANTILE`` quantile and the Bonferroni bound holds many more
    rows than chance allows (and not clearly fewer than lie beyond the bound), the
    residual is model error with heavy tails and only gross errors
    (:data:`OUTLIER_GROSS_SIGMAS`) are called outliers; none are when more than
    :data:`OUTLIER_MAX_FRACTION` of the rows would be.  ``gross_only``: only gross
    errors (used when the residual is known to hold structure the model lacks).
    """
    r = (pred - prob.m.p) * prob.weights
    n = len(r)
    out = np.zeros(n, dtype=bool)
    groups = prob.m.pose_groups()
    _ug, inv, counts = np.unique(groups, return_inverse=True, return_counts=True)
    multi = counts[inv] >= OUTLIER_MIN_POSE_ROWS
    if multi.any():
        dev = np.zeros_like(r)
        for g in np.flatnonzero(counts >= OUTLIER_MIN_POSE_ROWS):
            idx = np.flatnonzero(inv == g)
            for i in idx:
                dev[i] = r[i] - np.median(r[idx[idx != i]], axis=0)
        out[multi] = _exceeds(_robust_d2(dev[multi]), n, gross_only)
    if (~multi).any():
        out[~multi] = _exceeds(_robust_d2(r[~multi]), n, gross_only)
    if out.sum() > int(OUTLIER_MAX_FRACTION * n):
        return np.ones(n, dtype=bool)
    return ~out
