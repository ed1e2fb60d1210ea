"""The region of a planning task for :func:`problems.identify.design.design_campaign`: its path's
configurations (evaluation poses, with the task's load) and a pool of configurations around them."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from models.arm import ArmModel
from models.errors import InputError

from ..measurements import Measurements

#: At most this many evaluation poses along the path (evenly subsampled).
TASK_MAX_EVAL_POSES = 200
#: Pool size by default, and the uniform perturbation per joint around a path configuration,
#: rad (15 deg).
TASK_POOL_POSES = 1000
TASK_MARGIN_RAD = float(np.radians(15.0))
#: Share of the pool's configurations that carry the task's load (when the task has one): the
#: design may then choose loaded measurements, which alone determine what acts through the load.
TASK_POOL_LOADED_SHARE = 0.5


@dataclass
class TaskRegion:
    """The region of a planning task: evaluation poses and a pool around its path.

    Unpacks as ``eval_q, pool = task_region(...)``.

    Attributes
    ----------
    eval_q : ndarray, shape (N_e, 6)
        The path's configurations on the chosen branch, subsampled, rad.
    pool : Measurements
        Configurations around the path, guarded by :func:`design_campaign`: unloaded, and (a
        :data:`TASK_POOL_LOADED_SHARE` of them, when the task has a load) under the task's load.
    eval_wrench : ndarray, shape (N_e, 6)
        The task's load at the evaluation poses, base frame, N and N*m.
    branch : str
        The IK branch label of the path.
    source : str
        The problem's source.
    """

    eval_q: np.ndarray
    pool: Measurements
    eval_wrench: np.ndarray
    branch: str
    source: str

    def __iter__(self) -> Iterator[Any]:
        yield self.eval_q
        yield self.pool


def task_region(
    problem: Any,
    model: ArmModel,
    n_pool: int = TASK_POOL_POSES,
    seed: int = 0,
    *,
    margin_rad: float = TASK_MARGIN_RAD,
    max_eval: int = TASK_MAX_EVAL_POSES,
) -> TaskRegion:
    """The evaluation poses and a pool of a planning task, for :func:`design_campaign`.

    The path's configurations are those of the branch the planner chooses without its NLP: the
    analytic IK of every waypoint on each IK branch (:func:`problems.posture.optimise_postures`
    with ``optimise=False``, the problem's tool on the model's chain) and the usable branch of
    least load-induced error at its analytic posture (the plan's branch choice; the optimised
    posture of ``compplan plan`` may differ within the problem's orientation rule).  They are
    subsampled evenly to at most ``max_eval`` evaluation poses, whose wrench is the task's load
    (base frame, at the TCP's rotation).  The pool: ``n_pool`` configurations, each a random path configuration plus a
    uniform perturbation of ``margin_rad`` per joint, clipped to the joint limits (seeded; the
    guards of :func:`design_campaign` set aside those near a singularity); when the task has a load,
    every other one (:data:`TASK_POOL_LOADED_SHARE`) carries the task's load of the waypoint it was
    drawn from (at its own tool orientation), so the design can choose loaded measurements.

    The sigma of a design is that of the model's measured point (its tool) at these
    configurations; the task's TCP sits elsewhere on the flange.

    Parameters
    ----------
    problem : Problem, str or Path
        A problem, or a problem file / shipped name (:func:`problems.problem.load_problem`).
    model : ArmModel
    n_pool : int
        Pool configurations.
    seed : int
        Seed of the pool.
    margin_rad : float
        Uniform perturbation per joint around a path configuration, rad.
    max_eval : int
        At most this many evaluation poses.

    Returns
    -------
    TaskRegion
        Unpacks as ``eval_q, pool``; also ``eval_wrench``, ``branch`` and ``source``.

    Raises
    ------
    InputError
        The task has no branch that reaches its whole path.
    """
    from problems.posture import optimise_postures
    from problems.problem import Problem, load_problem

    prob = problem if isinstance(problem, Problem) else load_problem(str(problem))
    prob = prob.with_robot(model)
    arm = prob.model
    ps = optimise_postures(arm, prob.task(), prob.home_q, prob.solver, model=arm.kinematics, ik=arm.ik, optimise=False)
    if not ps.ok:
        raise InputError(f"{prob.source}: the task has no branch that reaches its whole path ({ps.reason})")
    qpath = np.asarray(ps.best.q, dtype=float)
    N = len(qpath)
    take = np.unique(np.linspace(0, N - 1, min(N, int(max_eval))).round().astype(int))
    eq = qpath[take]
    _p, R, _J, _C = arm.kinematics.kinetostatics.map(len(eq), "thread", 2)(eq.T)
    R = np.asarray(R).reshape(3, len(eq), 3).transpose(1, 0, 2)
    load = prob.load
    ew = replace(load, wrench_base=_sel(load.wrench_base, take), wrench_tool=_sel(load.wrench_tool, take)).wrench_at(R)
    rng = np.random.default_rng(seed)
    drawn = rng.integers(0, N, int(n_pool))
    base = qpath[drawn]
    q = base + rng.uniform(-margin_rad, margin_rad, base.shape)
    q = np.clip(q, model.nominal.q_min, model.nominal.q_max)
    src = f"task region of {Path(str(prob.source)).name}"
    wrench = _pool_wrench(arm, load, q, drawn) if np.any(ew) else np.zeros((len(q), 6))
    pool = Measurements(q=q, wrench=wrench, line=np.arange(1, len(q) + 1), source=src)
    return TaskRegion(eq, pool, ew, ps.labels[ps.chosen] if ps.labels else str(ps.chosen), str(prob.source))


def _pool_wrench(arm: ArmModel, load: Any, q: np.ndarray, drawn: np.ndarray) -> np.ndarray:
    """Base-frame wrenches (N, 6) of the pool: the task's load of waypoint ``drawn[i]`` at row i's tool
    orientation on every ``1/TASK_POOL_LOADED_SHARE``-th row (1-based odd rows), zero elsewhere."""
    n = len(q)
    out = np.zeros((n, 6))
    rows = np.arange(n)[np.arange(n) % max(1, round(1.0 / TASK_POOL_LOADED_SHARE)) == 1]
    if not len(rows):
        return out
    _p, R, _J, _C = arm.kinematics.kinetostatics.map(len(rows), "thread", 2)(q[rows].T)
    R = np.asarray(R).reshape(3, len(rows), 3).transpose(1, 0, 2)
    at = drawn[rows]
    out[rows] = replace(load, wrench_base=_sel(load.wrench_base, at), wrench_tool=_sel(load.wrench_tool, at)).wrench_at(
        R
    )
    return out


def _sel(a: Any, take: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    return a[take] if a.ndim == 2 and len(a) > 1 else a
