"""Effect selection: scores, tests and the forward/backward steps (``docs/identification.md`` §4).

* **Scores** (:func:`linear_scores`): in-sample and K-fold cross-validated RMS of a
  model linearised at the current fit (folds of whole poses, :func:`assign_folds`),
  BIC ``n ln(RSS/n) + k ln n``;
* **tests** (:func:`candidate_score`, :func:`significance`): CV gain, BIC, F-test
  of the added parameters, share of the excess variance explained;
* **steps**: :func:`forward_selection` adds the best significant candidate until the
  noise floor or no candidate passes; :func:`backward_pass` removes an added effect
  (or replaces ``geometric`` by ``joint_offset``) when the simpler model is as good.

RMS values are per axis, m (unweighted, on the rows used); weighted quantities are in
units of the row weights (``1/sigma``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from models.effects import EFFECTS, N_PARAMS, PARAM_NAMES, ModelLayout, get_const
from models.robot import Robot

from ..measurements import Measurements
from .diagnostics import diagnose, structure_left
from .error_map import MapProposal
from .evaluation import FitProblem, gravity_problem, update_knots
from .identifiability import priority_order, select_identifiable
from .lsq import ModelFit, evaluate, fit_model, jacobian, rms, solve_normal, weighted_jacobian, weighted_residual
from .map_candidate import MAP_SEARCH_COMPONENTS, map_detail, map_problem
from .results import CandidateScore, SelectionStep

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
#: Candidates refined with a full nonlinear fit after the linearised ranking.
REFINE_TOP = 2
#: A runner-up is refined only when its linearised CV RMS is within this relative margin of the best
#: (a full fit can reorder close candidates, not distant ones).
REFINE_MARGIN = 0.10
#: Levenberg-Marquardt iterations of a candidate's refinement (a ranking: the accepted candidate is
#: refitted to convergence).
REFINE_MAX_ITER = 12
#: Among refined candidates, one with fewer parameters whose CV RMS is within this
#: relative margin of the best is preferred (parsimony).
PARSIMONY_REL_TOL = 0.02
#: Stop when the cross-validated RMS is below this multiple of the noise floor.
NOISE_FLOOR_STOP_RATIO = 1.10
#: Temperature range below which ``thermal`` cannot be tested, K.
THERMAL_MIN_RANGE_K = 0.5


# ----------------------------------------------------------------------------------
# Scores
# ----------------------------------------------------------------------------------


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


# ----------------------------------------------------------------------------------
# Selection state
# ----------------------------------------------------------------------------------


@dataclass
class SelectionRun:
    """What the selection steps share and do not change.

    Attributes
    ----------
    robot : Robot
        The nominal description (diagnostics).
    layout : ModelLayout
    registered, robust : bool
        Data declared registered; outliers excluded.
    include : list of str
        Effects added without a test (never removed).
    cand : list of str
        Candidate effects.
    applicable : dict
        Candidates the data cannot test -> why.
    sigma_noise : float or None
        Noise floor, m.
    sigma_w : float or None
        Noise floor in weighted units.
    sat_clean : bool
        The saturated library model leaves no structure (waives the share test).
    mask_sel : ndarray of bool, shape (N,)
        Rows of the refits after an accepted change.
    max_steps : int
    tick : callable
        ``tick(message, done, total)``.
    total_steps : int
    """

    robot: Robot
    layout: ModelLayout
    registered: bool
    robust: bool
    include: list[str]
    cand: list[str]
    applicable: dict[str, str]
    sigma_noise: float | None
    sigma_w: float | None
    sat_clean: bool
    mask_sel: np.ndarray
    max_steps: int
    tick: Callable[[str, int, int], None]
    total_steps: int
    #: The last proposal of the map search (its terms are the candidate's ``detail``).
    map_proposal: MapProposal | None = None
    #: Components of the joint error map the search proposes (:data:`MAP_SEARCH_COMPONENTS`).
    map_components: tuple[str, ...] = MAP_SEARCH_COMPONENTS

    def score(self, p: FitProblem, f: ModelFit, effs: Sequence[str]) -> tuple[Score, list[int]]:
        """Scores and free parameters of the fit ``f`` of the model with ``effs``."""
        return score_p(p, p.layout, f, effs, self.registered)

    def refit(self, p: FitProblem, th: np.ndarray, effs: Sequence[str], mask: np.ndarray) -> ModelFit:
        """Full (robust when asked) fit of the model with ``effs`` from ``th``."""
        return fit_model(p, th, effs, self.registered, mask, robust=self.robust)

    def with_effect(
        self, p: FitProblem, th: np.ndarray, e: str, fit: ModelFit | None = None, others: np.ndarray | None = None
    ) -> tuple[FitProblem | None, np.ndarray]:
        """Problem and start parameters with ``e`` switched on (``gravity``: its switch
        and the robot file's masses; ``joint_error_map``: the frequencies the residual of
        ``fit`` shows beyond the directions ``others``, None when it shows none)."""
        if e == "joint_error_map":
            if fit is None:
                return None, th
            return self.map_problem(p, fit, th, others)
        if e == "gravity" and get_const(p.const, "gravity.on")[0] < 0.5:
            th = th.copy()
            gi = self.layout.effect_indices("gravity")
            th[gi] = self.layout.nominal[gi]
            return gravity_problem(p, True), th
        return p, th

    def map_problem(
        self, p: FitProblem, fit: ModelFit, th: np.ndarray, others: np.ndarray | None = None
    ) -> tuple[FitProblem | None, np.ndarray]:
        """The ``joint_error_map`` candidate's problem (:func:`~.map_candidate.map_problem`), the
        proposal recorded in :attr:`map_proposal`."""
        prob_e, th_e, self.map_proposal = map_problem(self.robot, self.map_components, p, fit, th, others)
        return prob_e, th_e


@dataclass
class SelectionState:
    """The model being selected (changed by the steps)."""

    prob: FitProblem
    fit: ModelFit
    active: list[str]
    effects_added: list[str] = field(default_factory=list)
    history: list[SelectionStep] = field(default_factory=list)
    step_idx: int = 0
    stop_reason: str = "no candidate left"
    #: Candidate problems of the current step (effect -> problem, start), from the screen.
    pending: dict[str, tuple[FitProblem, np.ndarray]] = field(default_factory=dict)


# ----------------------------------------------------------------------------------
# Forward selection
# ----------------------------------------------------------------------------------


def _screen(
    run: SelectionRun, st: SelectionState, score_m: Score, remaining: Sequence[str]
) -> tuple[list[CandidateScore], list[CandidateScore]]:
    """Linearised score of every remaining candidate (one Gauss-Newton step and CV).

    Returns every candidate's record and those with a score (to rank)."""
    fit = st.fit
    sig_now = rms(weighted_residual(st.prob, fit.pred, fit.inliers))
    cur_order = priority_order(st.prob.layout, st.active, run.registered)
    st.pending = {}
    # directions of the other candidates' new parameters: the map, the most flexible candidate,
    # searches only what none of them can explain (it is screened last, in registry order)
    others: list[np.ndarray] = []
    scores: list[CandidateScore] = []
    prelim: list[CandidateScore] = []
    for e in remaining:
        if e in run.applicable:
            scores.append(
                CandidateScore(e, 0, None, None, None, None, None, None, reason=f"not testable: {run.applicable[e]}")
            )
            continue
        prob_e, th_e = run.with_effect(st.prob, fit.theta, e, fit, np.column_stack(others) if others else None)
        if prob_e is None:
            scores.append(
                CandidateScore(
                    e,
                    0,
                    None,
                    None,
                    None,
                    None,
                    None,
                    None,
                    reason="no joint angle shows a significant periodic error in the residual "
                    "(spectrum search with a family-wise test)",
                )
            )
            continue
        layout = prob_e.layout
        new = [int(i) for i in layout.effect_indices(e) if i not in cur_order]
        if not new:
            scores.append(
                CandidateScore(e, 0, None, None, None, None, None, None, reason="subsumed by an effect already added")
            )
            continue
        st.pending[e] = (prob_e, th_e)
        if prob_e is st.prob:
            J_e, pred_e = fit.J, fit.pred
        else:
            pred_e, q_g = evaluate(prob_e, th_e)
            J_e = jacobian(prob_e, th_e, q_g)
        order = priority_order(layout, st.active + [e], run.registered)
        Js = weighted_jacobian(prob_e, J_e, fit.inliers, np.asarray(order, dtype=int))
        kept, held = select_identifiable(Js, order, sig_now)
        kept_new = [i for i in kept if i in new]
        if kept_new and e != "joint_error_map":
            others.append(Js[:, [order.index(i) for i in kept_new]])
        if not kept_new:
            scores.append(
                CandidateScore(
                    e,
                    0,
                    None,
                    None,
                    None,
                    None,
                    None,
                    None,
                    reason="no parameter identifiable from these data",
                    held=[PARAM_NAMES[i] for i in new],
                )
            )
            continue
        sc = linear_scores(prob_e, J_e, pred_e, fit.inliers, np.asarray(kept, dtype=int))
        cs = candidate_score(e, sc, score_m, run.sigma_w, len(kept_new))
        cs.held = [f"{PARAM_NAMES[i]}: {held[i]}" for i in new if i in held]
        if e == "joint_error_map" and run.map_proposal is not None:
            cs.detail = map_detail(run.map_proposal)
        prelim.append(cs)
        scores.append(cs)
    return scores, prelim


def _refine(
    run: SelectionRun, st: SelectionState, prelim: Sequence[CandidateScore], score_m: Score, free_m: Sequence[int]
) -> list[tuple[CandidateScore, ModelFit, FitProblem]]:
    """Full nonlinear fit of the best :data:`REFINE_TOP` candidates (and of ``gravity``
    when its linearisation is visibly off); their records are re-scored in place."""
    ranked = sorted(prelim, key=lambda c: c.cv_rms_m)
    to_refine = [
        c
        for c in ranked[:REFINE_TOP]
        if c.cv_rms_m < score_m.cv_rms_m and c.cv_rms_m <= ranked[0].cv_rms_m * (1 + REFINE_MARGIN)
    ]
    # gravity switches on at the file's masses: when its linearisation is visibly
    # off (worse in-sample than the current model) it is refined anyway
    to_refine += [c for c in ranked if c.effect == "gravity" and c not in to_refine and c.rms_m > score_m.rms_m]
    refined: list[tuple[CandidateScore, ModelFit, FitProblem]] = []
    for cs in to_refine:
        e = cs.effect
        run.tick(f"step {st.step_idx}: fitting {e}", min(3 + st.step_idx, run.total_steps), run.total_steps)
        prob_e, th_e = st.pending[e]
        f_e = fit_model(
            prob_e, th_e, st.active + [e], run.registered, st.fit.inliers, robust=False, max_iter=REFINE_MAX_ITER
        )
        sc_e, free_e = run.score(prob_e, f_e, st.active + [e])
        cs2 = candidate_score(e, sc_e, score_m, run.sigma_w, len([i for i in free_e if i not in free_m]))
        cs.cv_rms_m, cs.rms_m, cs.bic, cs.delta_bic = cs2.cv_rms_m, cs2.rms_m, cs2.bic, cs2.delta_bic
        cs.f_pvalue, cs.explained_share, cs.n_params = cs2.f_pvalue, cs2.explained_share, cs2.n_params
        cs.refined = True
        cs.held = [f"{PARAM_NAMES[i]}: {f_e.held[i]}" for i in prob_e.layout.effect_indices(e) if i in f_e.held]
        refined.append((cs, f_e, prob_e))
    return refined


def _pick(
    refined: list[tuple[CandidateScore, ModelFit, FitProblem]],
) -> tuple[CandidateScore, ModelFit, FitProblem] | None:
    """The refined candidate with the lowest CV RMS, or a smaller one within
    :data:`PARSIMONY_REL_TOL` of it."""
    if not refined:
        return None
    refined.sort(key=lambda x: x[0].cv_rms_m)
    best = refined[0]
    for alt in refined[1:]:
        if alt[0].n_params < best[0].n_params and alt[0].cv_rms_m <= best[0].cv_rms_m * (1 + PARSIMONY_REL_TOL):
            best = alt
    return best


def _accept(run: SelectionRun, best: tuple[CandidateScore, ModelFit, FitProblem], score_m: Score) -> tuple[bool, str]:
    """Acceptance test of the best candidate (section 4, rule 3) and its explanation."""
    basic, share_ok, why = significance(best[0], score_m)
    ok = basic and share_ok
    if basic and not share_ok:
        if run.sat_clean:
            ok = True
            why += (
                "; accepted: the whole library leaves no structure in the residual, so the "
                "share is small only because other effects are present"
            )
        else:
            left = structure_left(diagnose(best[2], best[1], run.robot))
            if left is None:
                ok = True
                why += "; accepted: no diagnostic shows structure left after it"
            else:
                why += (
                    f"; rejected: structure outside the library remains (residual vs "
                    f"{left.variable}) and this effect would explain only a small part"
                )
    return ok, why


def _forward_step(run: SelectionRun, st: SelectionState) -> bool:
    """One forward step: score the current model, test the candidates, add the best one
    that passes; records the step in ``st.history``.  Returns whether one was added."""
    if "stiffness_hardening" not in st.active and get_const(st.prob.const, "gravity.on")[0] > 0.5:
        st.prob = update_knots(st.prob, st.fit)
        st.fit.J = jacobian(st.prob, st.fit.theta, st.fit.q_eq)
    score_m, free_m = run.score(st.prob, st.fit, st.active)
    run.tick(
        f"step {st.step_idx}: CV RMS {score_m.cv_rms_m * 1e3:.4g} mm",
        min(3 + st.step_idx, run.total_steps),
        run.total_steps,
    )
    scores: list[CandidateScore] = []
    accepted = None
    reason = ""
    at_floor = run.sigma_noise is not None and score_m.cv_rms_m <= NOISE_FLOOR_STOP_RATIO * run.sigma_noise
    remaining = [e for e in run.cand if e not in st.active]
    if at_floor:
        st.stop_reason = (
            f"cross-validated RMS {score_m.cv_rms_m * 1e3:.4g} mm is at the noise floor "
            f"({NOISE_FLOOR_STOP_RATIO:g} x {run.sigma_noise * 1e3:.4g} mm)"
        )
    elif not remaining or st.step_idx >= run.max_steps:
        st.stop_reason = "no candidate left" if not remaining else "step limit"
    else:
        scores, prelim = _screen(run, st, score_m, remaining)
        best = _pick(_refine(run, st, prelim, score_m, free_m))
        for cs in scores:
            if cs.cv_rms_m is not None and not cs.reason:
                cs.reason = significance(cs, score_m)[2]
        if best is None or best[0].cv_rms_m >= score_m.cv_rms_m:
            st.stop_reason = "no candidate lowers the cross-validated residual"
        else:
            ok, why = _accept(run, best, score_m)
            best[0].reason = why
            if ok:
                best[0].accepted = True
                accepted = best[0].effect
                st.prob = best[2]
                st.active.append(accepted)
                st.effects_added.append(accepted)
                st.fit = run.refit(st.prob, best[1].theta, st.active, run.mask_sel)
                reason = f"added {accepted}: {why}"
            else:
                st.stop_reason = f"best candidate {best[0].effect} not significant: {why}"
    st.history.append(
        SelectionStep(
            index=st.step_idx,
            effects=list(st.active),
            n_params=score_m.k,
            rms_m=score_m.rms_m,
            cv_rms_m=score_m.cv_rms_m,
            bic=score_m.bic,
            n_excluded=int((~st.fit.inliers).sum()),
            candidates=scores,
            accepted=accepted,
            reason=reason or st.stop_reason,
        )
    )
    st.step_idx += 1
    return accepted is not None


def forward_selection(run: SelectionRun, st: SelectionState) -> None:
    """Forward stepwise selection: add effects while the best candidate passes the test."""
    while _forward_step(run, st):
        pass


# ----------------------------------------------------------------------------------
# Backward pass
# ----------------------------------------------------------------------------------


def _try_simpler(run: SelectionRun, st: SelectionState, e: str, alt: list[str], score_m: Score) -> bool:
    """Replace the current model by ``alt`` (``e`` removed or replaced) when its CV RMS is
    within :data:`PARSIMONY_REL_TOL` and its BIC not worse by more than ``2 ln n``."""
    layout, fit = st.prob.layout, st.fit
    p_alt = st.prob
    th_alt = fit.theta.copy()
    alt_order = priority_order(layout, alt, run.registered)
    gone = [int(i) for i in layout.effect_indices(e) if i not in alt_order]
    # linearised screen first (setting first moments to zero switches gravity off)
    shift = np.zeros(N_PARAMS)
    shift[gone] = (0.0 if e == "gravity" else layout.nominal[gone]) - fit.theta[gone]
    keep = [i for i in alt_order if i not in fit.held]
    sc_lin = linear_scores(st.prob, fit.J, fit.pred, fit.inliers, np.asarray(keep, dtype=int), shift)
    if sc_lin.cv_rms_m > score_m.cv_rms_m * (1 + 2 * PARSIMONY_REL_TOL):
        return False
    if e == "gravity":
        p_alt = gravity_problem(st.prob, False)
    th_alt[gone] = layout.nominal[gone]
    f_alt = fit_model(p_alt, th_alt, alt, run.registered, fit.inliers, robust=False)
    sc_alt, _fa = run.score(p_alt, f_alt, alt)
    if not (
        sc_alt.cv_rms_m <= score_m.cv_rms_m * (1 + PARSIMONY_REL_TOL)
        and sc_alt.bic <= score_m.bic + 2.0 * math.log(sc_alt.n)
    ):
        return False
    replaced = "joint_offset" in alt and "joint_offset" not in st.active
    what = "replaced by joint_offset" if replaced else "removed"
    st.history.append(
        SelectionStep(
            index=st.step_idx,
            effects=list(alt),
            n_params=sc_alt.k,
            rms_m=sc_alt.rms_m,
            cv_rms_m=sc_alt.cv_rms_m,
            bic=sc_alt.bic,
            n_excluded=int((~fit.inliers).sum()),
            candidates=[],
            accepted=None,
            reason=(
                f"backward step: {e} {what} (CV RMS {score_m.cv_rms_m * 1e3:.4g} -> "
                f"{sc_alt.cv_rms_m * 1e3:.4g} mm, within {100 * PARSIMONY_REL_TOL:.0f} %)"
            ),
        )
    )
    st.step_idx += 1
    st.prob, st.fit = p_alt, run.refit(p_alt, f_alt.theta, alt, run.mask_sel)
    st.effects_added = [x for x in st.effects_added if x != e]
    if replaced:
        st.effects_added.append("joint_offset")
    st.active = list(alt)
    return True


def backward_pass(run: SelectionRun, st: SelectionState) -> None:
    """Drop an added effect, or replace it by a nested smaller one (``geometric`` ->
    ``joint_offset``), while the cross-validated RMS does not get worse by more than
    :data:`PARSIMONY_REL_TOL` (forward selection can pick a superset early)."""
    changed = True
    while changed and len(st.effects_added) > 0:
        changed = False
        score_m, _free = run.score(st.prob, st.fit, st.active)
        for e in [x for x in reversed(st.effects_added) if x not in run.include]:
            options: list[list[str]] = [[x for x in st.active if x != e]]
            if e == "geometric":
                options.insert(0, [x if x != "geometric" else "joint_offset" for x in st.active])
            for alt in options:
                if _try_simpler(run, st, e, alt, score_m):
                    changed = True
                    break
            if changed:
                break
