"""Re-fit a selected model to other measured points of the same rows, without selecting again.

:func:`refit_selection` keeps everything an identification (:func:`~.engine.select_model`) selected --
the effects, the joint error maps' frequencies and constants, the gravity switch and knots, the
registration's start rotation, the held parameters and the inlier rows -- and re-fits only the free
parameters by Levenberg-Marquardt (:func:`~.lsq.levenberg_marquardt`) from a given start.  The
"before" fit (registration and measured point on the nominal model) is recomputed on the new points.
Its use: several campaigns (:mod:`.campaigns`), whose merged table changes only in its measured
points when a campaign's transform is re-estimated.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..measurements import Measurements
from .engine import Selection
from .fit_setup import setup_fit
from .identifiability import priority_order
from .lsq import levenberg_marquardt
from .selection import SelectionState
from .selection_scores import linear_scores


def _same_rows(a: Measurements, b: Measurements) -> bool:
    """Whether ``a`` and ``b`` have the same rows (joint angles, loads, times), whatever their points."""
    if a.n != b.n or not (np.array_equal(a.q, b.q) and np.array_equal(a.wrench, b.wrench)):
        return False
    return (a.t is None) == (b.t is None) and (a.t is None or np.array_equal(a.t, b.t))


def refit_selection(sel: Selection, data: Measurements, theta: np.ndarray) -> Selection:
    """The model of ``sel`` re-fitted to ``data`` from ``theta``, its structure kept.

    Parameters
    ----------
    sel : Selection
        A selected model (:func:`~.engine.select_model`, or an earlier re-fit).
    data : Measurements
        The rows of ``sel``'s table (same joint angles, loads and times, same order) with other
        measured points ``p`` (m, the same measurement frame up to a small motion).
    theta : ndarray, shape (N_PARAMS,)
        Start, SI: the held parameters must be at ``sel``'s values (nominal); the free ones are
        clipped to the parameter bounds (the joint Gauss-Newton of several campaigns has none).

    Returns
    -------
    Selection
        The same effects, problem constants, held parameters, inlier rows, history and notes; the free
        parameters fitted (Levenberg-Marquardt on the inlier rows); the "before" fit and score on
        ``data``.  Its :meth:`~.engine.Selection.result` is the identification's result.

    Raises
    ------
    ValueError
        ``data`` does not have ``sel``'s rows.
    """
    run, st = sel.run, sel.st
    s = setup_fit(run.robot, data, run.registered, sel.folds, len(run.cand), run.tick)  # the "before" fit
    if not _same_rows(st.prob.m, s.prob.m) or (s.prob.m.rotation is None) != (st.prob.m.rotation is None):
        raise ValueError("refit_selection: the data must have the rows of the selected model's table")
    prob = replace(st.prob, m=s.prob.m)  # the selection's constants, weights and folds; the new points
    order = priority_order(prob.layout, st.active, run.registered)
    free = np.asarray([i for i in order if i not in st.fit.held], dtype=int)
    start = np.asarray(theta, dtype=float).copy()
    start[free] = np.clip(start[free], prob.lower[free], prob.upper[free])  # a start from an unbounded fit
    fit = levenberg_marquardt(prob, start, free, st.fit.inliers)
    fit.held = dict(st.fit.held)
    state = SelectionState(
        prob=prob,
        fit=fit,
        active=list(st.active),
        effects_added=list(st.effects_added),
        history=list(st.history),
        step_idx=st.step_idx,
        stop_reason=st.stop_reason,
    )
    score_b = linear_scores(s.prob, s.fit_b.J, s.fit_b.pred, sel.score_mask, np.asarray(s.order_b, dtype=int))
    # the model's constants (registration start, torque scales, references) stay the selection's
    setup = replace(sel.s, fit_b=s.fit_b, order_b=s.order_b)
    return replace(sel, st=state, s=setup, score_b=score_b, notes=list(sel.notes))
