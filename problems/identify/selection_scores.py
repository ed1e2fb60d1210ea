"""The scores and tests of effect selection (``docs/identification.md`` §4).

* **Scores** (:func:`linear_scores`): in-sample and K-fold cross-validated RMS of a
  model linearised at the current fit (folds of whole poses, :func:`assign_folds`),
  BIC ``n ln(RSS/n) + k ln n``; the noise floor of the data (:func:`noise_floor`);
* **tests** (:func:`candidate_score`, :func:`significance`): CV gain, BIC, F-test
  of the added parameters, share of the excess variance explained; whether a candidate
  applies to the data at all (:func:`candidate_applicable`).

RMS values are per axis, m (unweighted, on the rows used); weighted quantities are in
units of the row weights (``1/sigma``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from models.effects import EFFECTS, ModelLayout

from ..measurements import Measurements
from .evaluation import FitProblem
from .identifiability import priority_order
from .lsq import ModelFit, solve_normal, weighted_jacobian, weighted_residual
from .results import CandidateScore

#: Folds of the cross-validation (whole poses are held out together).
CV_FOLDS = 5
#: Seed of the fold assignment (reproducible results).
CV_SEED = 12345
#: Acceptance of an effect: the cross-validated RMS must drop by at least this
#: fraction ...
CV_MIN_REL_GAIN = 0.05
#: ... the F-test of the added parameters must pass at this level ...
F_TEST_ALPHA = 1e-3
#: ... and the effect must explain at least this share of the cross-validated
#: residual variance above the noise floor (of the whole variance when the noise
#: floor is unknown): a small partial fit of structure it does not describe is a
#: wrong attribution.
MIN_EXPLAINED_SHARE = 0.30
#: Temperature range below which ``thermal`` cannot be tested, K.
THERMAL_MIN_RANGE_K = 0.5


@dataclass
class Score:
    """Linearised scores of a model on the rows used.

    Attributes
    ----------
    rss : float
        Weighted in-sample residual sum of squares (linearised).
    cv_rss : float
        Weighted held-out residual sum of squares.
    cv_rms_m, rms_m : float
        Unweighted per-axis RMS of the held-out and in-sample residuals, m.
    n : int
        Residual scalars.
    k : int
        Free parameters.
    """

    rss: float
    cv_rss: float
    cv_rms_m: float
    rms_m: float
    n: int
    k: int

    @property
    def bic(self) -> float:
        """``n ln(RSS/n) + k ln n``."""
        return self.n * math.log(max(self.rss, 1e-300) / self.n) + self.k * math.log(self.n)


def linear_scores(
    prob: FitProblem,
    J: np.ndarray,
    pred: np.ndarray,
    mask: np.ndarray,
    cols: np.ndarray,
    shift: np.ndarray | None = None,
) -> Score:
    """In-sample and K-fold CV scores of the model linearised at the current point.

    The full-data Gauss-Newton step and one per fold (fold rows removed) are taken
    from the same Jacobian; held-out residuals are predicted linearly.  At a
    least-squares optimum this is the standard linearised cross-validation; for a
    candidate whose parameters start at their nominal values it is the one-step
    Gauss-Newton fit.

    Parameters
    ----------
    J : ndarray, shape (3N, N_PARAMS)
        Jacobian at the current point.
    pred : ndarray, shape (N, 3)
        Prediction at the current point, m.
    mask : ndarray of bool, shape (N,)
        Rows used.
    cols : ndarray of int
        Free parameters.
    shift : ndarray, shape (N_PARAMS,), optional
        Parameters moved (linearly) by this, SI, e.g. an effect removed.
    """
    r = weighted_residual(prob, pred, mask)
    if shift is not None:
        nz = np.flatnonzero(shift)
        r = r + weighted_jacobian(prob, J, mask, nz) @ (shift[nz] / prob.layout.scale[nz])
    w3 = prob.weights[mask].reshape(-1)
    pos3 = np.repeat(prob.pos[mask], 3)
    Js = weighted_jacobian(prob, J, mask, cols)
    G = Js.T @ Js
    g = Js.T @ r
    step = -solve_normal(G, g)
    r_in = r + Js @ step
    folds3 = np.repeat(prob.folds[mask], 3)
    cv_rss = 0.0
    cv_un = 0.0
    for k in np.unique(folds3):
        sel = folds3 == k
        Jk, rk = Js[sel], r[sel]
        Gk = G - Jk.T @ Jk
        gk = g - Jk.T @ rk
        dk = -solve_normal(Gk, gk)
        ek = rk + Jk @ dk
        cv_rss += float(ek @ ek)
        cv_un += float(np.sum(np.square(ek / w3[sel])[pos3[sel]]))
    n = r.size
    npos = max(int(pos3.sum()), 1)
    return Score(
        rss=float(r_in @ r_in),
        cv_rss=cv_rss,
        cv_rms_m=math.sqrt(cv_un / npos),
        rms_m=math.sqrt(float(np.sum(np.square(r_in / w3)[pos3])) / npos),
        n=n,
        k=len(cols),
    )


def assign_folds(m: Measurements, k: int, seed: int = CV_SEED) -> np.ndarray:
    """Fold index (N,) per row: whole poses assigned at random (fixed seed) to ``k`` folds."""
    groups = m.pose_groups()
    ug = np.unique(groups)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(ug))
    kk = max(2, min(k, len(ug)))
    fold_of_group = np.empty(len(ug), dtype=int)
    fold_of_group[perm] = np.arange(len(ug)) % kk
    lookup = {g: fold_of_group[i] for i, g in enumerate(ug)}
    return np.array([lookup[g] for g in groups], dtype=int)


def noise_floor(m: Measurements) -> tuple[float | None, str]:
    """Per-axis measurement noise (m) and where it comes from.

    ``sigma`` column (RMS of the declared values), else repeated measurements
    (rows with the same pose and the same wrench: pooled within-group scatter),
    else unknown.
    """
    if m.sigma is not None:
        return float(np.sqrt(np.mean(m.sigma**2))), "sigma column"
    groups = m.pose_groups()
    key = np.column_stack([groups, np.round(m.wrench, 9)])
    _u, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = np.asarray(inv).reshape(-1)
    rep = counts[inv] > 1
    if rep.sum() >= 6 and m.p is not None:
        ss, dof = 0.0, 0
        for g in np.unique(inv[rep]):
            P = m.p[inv == g]
            ss += float(np.sum(np.square(P - P.mean(axis=0))))
            dof += 3 * (len(P) - 1)
        if dof >= 6:
            return math.sqrt(ss / dof), f"repeated measurements ({dof // 3} degrees of freedom per axis)"
    return None, "unknown (no sigma column, no repeated measurements)"


def candidate_applicable(effect: str, m: Measurements) -> tuple[bool, str]:
    """Whether the data can test ``effect`` (varying load, temperature range), and why not."""
    spec = EFFECTS[effect]
    if "load" in spec.needs and not m.load_varies():
        return False, "the applied wrench does not vary in the data"
    if "temperature" in spec.needs:
        if m.temperature is None:
            return False, "no temperature column"
        if np.ptp(m.temperature) < THERMAL_MIN_RANGE_K:
            return False, f"temperature varies by less than {THERMAL_MIN_RANGE_K} K"
    return True, ""


def score_p(
    prob: FitProblem, layout: ModelLayout, f: ModelFit, effs: Sequence[str], registered: bool
) -> tuple[Score, list[int]]:
    """Linearised in-sample and CV scores of a fitted model, and its free parameters."""
    order = priority_order(layout, effs, registered)
    free = [i for i in order if i not in f.held]
    return linear_scores(prob, f.J, f.pred, f.inliers, np.asarray(free, dtype=int)), free


def candidate_score(effect: str, sc: Score, cur: Score, sigma_w: float | None, k_new: int) -> CandidateScore:
    """Scores of a candidate against the current model (same rows, same folds).

    ``sigma_w``: the noise floor in weighted units (None: unknown); ``k_new``: the
    candidate's new free parameters."""
    dbic = sc.bic - cur.bic
    df1 = max(sc.k - cur.k, 1)
    df2 = max(sc.n - sc.k, 1)
    if sc.rss > 0 and cur.rss > sc.rss:
        F = ((cur.rss - sc.rss) / df1) / (sc.rss / df2)
        p = float(stats.f.sf(F, df1, df2))
    else:
        p = 1.0
    cv_cur = cur.cv_rss / cur.n
    cv_new = sc.cv_rss / sc.n
    floor = (sigma_w**2) if sigma_w is not None else 0.0
    excess = cv_cur - floor
    share = max((cv_cur - cv_new) / excess, 0.0) if excess > 0 else 0.0  # a worse CV explains none
    return CandidateScore(
        effect=effect,
        n_params=k_new,
        cv_rms_m=sc.cv_rms_m,
        rms_m=sc.rms_m,
        bic=sc.bic,
        delta_bic=dbic,
        f_pvalue=p,
        explained_share=float(share),
    )


def significance(cs: CandidateScore, cur: Score) -> tuple[bool, bool, str]:
    """(basic tests pass, share test passes, explanation).

    Basic: CV RMS gain >= CV_MIN_REL_GAIN, BIC decreases, F-test p < F_TEST_ALPHA.
    Share: the effect explains >= MIN_EXPLAINED_SHARE of the CV variance above the
    noise floor (of all of it when the floor is unknown).
    """
    gain = 1.0 - cs.cv_rms_m / cur.cv_rms_m
    parts = [
        f"CV RMS {cur.cv_rms_m * 1e3:.4g} -> {cs.cv_rms_m * 1e3:.4g} mm ({-100 * gain:+.1f} %)",  # - is a decrease
        f"dBIC {cs.delta_bic:.1f}",
        f"F-test p = {cs.f_pvalue:.2g}",
        f"explains {100 * cs.explained_share:.0f} % of the excess variance",
    ]
    basic = True
    if gain < CV_MIN_REL_GAIN:
        basic = False
        parts.append(f"gain below {100 * CV_MIN_REL_GAIN:.0f} %")
    if cs.delta_bic >= 0:
        basic = False
        parts.append("BIC does not decrease")
    if cs.f_pvalue >= F_TEST_ALPHA:
        basic = False
        parts.append(f"F-test not significant at {F_TEST_ALPHA:g}")
    share_ok = cs.explained_share >= MIN_EXPLAINED_SHARE
    if not share_ok:
        parts.append(f"explains less than {100 * MIN_EXPLAINED_SHARE:.0f} % of the structure left")
    return basic, share_ok, "; ".join(parts)
