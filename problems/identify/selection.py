"""Effect selection: scores, tests and the forward/backward steps (``docs/identification.md`` §4).

* **Scores and tests** (:mod:`.selection_scores`): cross-validated RMS, BIC, F-test and the share
  of the excess variance explained of a candidate;
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

from models.effects import N_PARAMS, PARAM_NAMES, ModelLayout, get_const
from models.robot import Robot

from .diagnostics import diagnose, structure_left
from .error_map import MapProposal
from .evaluation import FitProblem, gravity_problem, update_knots
from .identifiability import priority_order, select_identifiable
from .lsq import ModelFit, evaluate, fit_model, jacobian, rms, weighted_jacobian, weighted_residual
from .map_candidate import MAP_SEARCH_COMPONENTS, map_detail, map_problem
from .results import CandidateScore, SelectionStep
from .selection_scores import (
    Score,
    candidate_score,
    linear_scores,
    score_p,
    significance,
)

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


def _unscored(e: str, reason: str, held: list[str] | None = None) -> CandidateScore:
    """Score of a candidate not tested, with the reason (and the parameters held, when given)."""
    if held is None:
        return CandidateScore(e, 0, None, None, None, None, None, None, reason=reason)
    return CandidateScore(e, 0, None, None, None, None, None, None, reason=reason, held=held)


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
            scores.append(_unscored(e, f"not testable: {run.applicable[e]}"))
            continue
        prob_e, th_e = run.with_effect(st.prob, fit.theta, e, fit, np.column_stack(others) if others else None)
        if prob_e is None:
            scores.append(
                _unscored(
                    e,
                    "no joint angle shows a significant periodic error in the residual "
                    "(spectrum search with a family-wise test)",
                )
            )
            continue
        layout = prob_e.layout
        new = [int(i) for i in layout.effect_indices(e) if i not in cur_order]
        if not new:
            scores.append(_unscored(e, "subsumed by an effect already added"))
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
            scores.append(_unscored(e, "no parameter identifiable from these data", held=[PARAM_NAMES[i] for i in new]))
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
