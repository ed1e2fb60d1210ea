"""The ``joint_error_map`` candidate of the selection: its problem and its one-line description.

At a selection step the map's frequencies are not known in advance: :func:`map_problem` runs the
spectrum search (:func:`~.error_map.propose_map`) on the residual of the current fit, with the
directions of the current free parameters and of the other candidates projected out, and returns
the problem with those frequencies (model constants) and their coefficients in use.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from models.effects import GROUP_SLICES, make_layout, set_const
from models.effects.joint_error_map import MAP_COMPONENTS
from models.robot import Robot

from .error_map import MapProposal, propose_map
from .evaluation import FitProblem, evaluator_for
from .lsq import ModelFit, weighted_jacobian, weighted_residual

#: The parameter groups whose Jacobian columns are the signatures of the map's components
#: (``models.effects.joint_error_map.MAP_COMPONENTS``: theta, d, a, alpha, beta).
MAP_CHANNEL_GROUPS = ("joint_offset.dtheta", "geometric.dd", "geometric.da", "geometric.dalpha", "geometric.dbeta")
#: Components the map candidate searches: the angular positioning error (gear transmission error,
#: encoder error).  The model carries runout and wobble (d, a, alpha, beta) too, but from position
#: data their signatures are flexible enough to absorb structure of other origins (an error that
#: depends on two joints, a compliance): searched, they would attribute wrongly.
MAP_SEARCH_COMPONENTS = ("theta",)


def map_problem(
    robot: Robot,
    components: Sequence[str],
    p: FitProblem,
    fit: ModelFit,
    th: np.ndarray,
    others: np.ndarray | None = None,
) -> tuple[FitProblem | None, np.ndarray, MapProposal | None]:
    """The problem with the map frequencies of :func:`~.error_map.propose_map` on the residual of
    ``fit`` (its free parameters and the weighted, scaled Jacobian columns ``others`` (3n, k) of
    the other candidates projected out), the start parameters and the proposal; the problem is None
    when no term passes.  ``components``: the map components searched (:data:`MAP_SEARCH_COMPONENTS`)."""
    mask = fit.inliers
    m = p.m.subset(mask)
    w3 = p.weights[mask].reshape(-1)
    channels = {}
    for j in range(6):
        for c, group in enumerate(MAP_CHANNEL_GROUPS):
            if MAP_COMPONENTS[c] not in components:
                continue
            i = GROUP_SLICES[group].start + j
            channels[(j, c)] = (fit.J[np.repeat(mask, 3), i] * w3).reshape(m.n, 3)
    free = [i for i in fit.free if i not in fit.held]
    Jfree = weighted_jacobian(p, fit.J, mask, np.asarray(free, dtype=int))
    if others is not None:
        Jfree = np.column_stack([Jfree, others])
    prop = propose_map(weighted_residual(p, fit.pred, mask), channels, m.q, Jfree, p.folds[mask])
    if prop is None:
        return None, th, None
    const = set_const(p.const, "error_map.freq", prop.freq.reshape(-1))
    const = set_const(const, "error_map.range", prop.range_rad.reshape(-1))
    layout = make_layout(robot, const)
    th = th.copy()
    th[layout.effect_indices("joint_error_map")] = 0.0
    return replace(p, const=const, layout=layout, ev=evaluator_for(robot, const)), th, prop


def map_detail(prop: MapProposal) -> str:
    """One line naming the joints and frequencies of a map proposal."""
    parts = [f"{t.label} ({100 * t.rss_share:.1f} % of the residual SS)" for t in prop.terms]
    return "periodic terms found: " + "; ".join(parts)
