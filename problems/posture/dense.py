"""Postures along long paths (CAM programs of 10^4-10^6 waypoints) at a cost linear in the waypoints.

The posture NLP (:mod:`problems.posture.solve`) is solved on at most :data:`POSTURE_MAX_NODES`
**nodes** spread evenly over the waypoints (the first and last included), and the postures are
carried to every waypoint between them:

1. the node task keeps the waypoints' positions, rotations, rule and load; its smoothness weight is
   ``smoothness / g^2`` for a mean gap of ``g`` waypoints between nodes (the sum of squared joint
   steps over ``g`` steps of ``dq / g`` each is ``||dq||^2 / g``, and the load term summed over the
   ``g`` waypoints a node stands for is ``g`` times the node's, so the node objective is the dense
   one divided by ``g``), and its joint-step bound is ``min(g * max_joint_step, pi)``;
2. every branch is optimised on the nodes as usual (warm starts by dynamic programming over the
   scanned tool-axis rotations, IPOPT, polish, verification);
3. for each usable branch, the TCP rotation at every waypoint is interpolated between its nodes'
   optimised rotations (element-wise, by a natural cubic spline over the waypoint index so that the joint path stays
   smooth for the timing, then the nearest rotation
   by SVD); for ``free_tool_axis`` its x axis is then made normal to the waypoint's tool axis,
   for ``fixed`` the waypoint's own rotation is used. The branch's closed-form IK at those poses
   (moved onto the model's geometry when it is not nominal) gives the posture at every waypoint,
   checked for the joint limits and the joint-step bound like any path (:func:`problems.path.branch_paths`);
4. the branch of least load-induced error over **all** waypoints is chosen.

The cost is the NLP on the nodes (fixed size) plus a few vectorised passes over the waypoints. The
postures between nodes are not optimal, only interpolated: ``benchmarks/bench_toolpath.py``
measures the load-induced error of this against the NLP over every waypoint.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from models.arm import ArmModel
from models.ik import IKSolver
from models.symbolic import KinematicModel
from problems.path import branch_paths, poses
from problems.posture.task import (
    BranchResult,
    OrientationRule,
    PostureResult,
    PostureStatus,
    PostureTask,
)
from problems.posture.warm_start import linear_error

__all__ = ["POSTURE_MAX_NODES", "densify", "node_indices", "node_task"]

#: Largest number of waypoints the posture NLP is solved on; longer paths are solved on this many
#: nodes and densified (module docstring).
POSTURE_MAX_NODES = 1000


def node_indices(n: int, max_nodes: int | None = None) -> np.ndarray:
    """``min(n, max_nodes)`` waypoint indices spread evenly over ``0 .. n-1``, both ends included
    (``max_nodes``: default :data:`POSTURE_MAX_NODES`)."""
    max_nodes = POSTURE_MAX_NODES if max_nodes is None else max_nodes
    if n <= max_nodes:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max_nodes)).astype(int))


def node_task(task: PostureTask, nodes: np.ndarray) -> PostureTask:
    """The posture task on the nodes (positions, rotations, load; smoothness and step bound scaled)."""
    g = (task.n - 1) / max(1, len(nodes) - 1)
    return PostureTask(
        task.positions[nodes],
        task.rotations[nodes],
        task.rule,
        task.wrench[nodes],
        cone_half_angle=task.cone_half_angle,
        max_joint_step=min(math.pi, task.max_joint_step * math.ceil(g)),
        smoothness=task.smoothness / g**2,
        scan=task.scan,
    )


def _nearest_rotations(M: np.ndarray) -> np.ndarray:
    """The proper rotations nearest (Frobenius) to the matrices ``M`` (N, 3, 3)."""
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    U[:, :, 2] *= d[:, None]
    return U @ Vt


def _dense_rotations(task: PostureTask, nodes: np.ndarray, R_nodes: np.ndarray) -> np.ndarray:
    """Rotations at every waypoint from the nodes' (see the module docstring, step 3)."""
    if task.rule is OrientationRule.FIXED:
        return task.rotations
    from scipy.interpolate import CubicSpline

    if len(nodes) < 3:
        M = np.stack([np.interp(np.arange(task.n), nodes, R_nodes[:, i // 3, i % 3]) for i in range(9)], axis=1)
    else:
        M = CubicSpline(nodes, R_nodes.reshape(-1, 9), axis=0, bc_type="natural")(np.arange(task.n))
    R = _nearest_rotations(M.reshape(-1, 3, 3))
    if task.rule is OrientationRule.FREE_TOOL_AXIS:
        z = task.axes
        x = R[:, :, 0] - z * np.einsum("ij,ij->i", R[:, :, 0], z)[:, None]
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        R = np.stack([x, np.cross(z, x), z], axis=2)
    return R


def densify(
    arm: ArmModel,
    model: KinematicModel,
    ik: IKSolver,
    task: PostureTask,
    nodes: np.ndarray,
    on_nodes: PostureResult,
) -> PostureResult:
    """Carry the node postures ``on_nodes`` to every waypoint of ``task`` (steps 3 and 4).

    Branches whose densified posture fails (a waypoint out of reach, a joint limit, a step above
    ``task.max_joint_step``) move to ``rejected`` with the reason.
    """
    from problems.compensation import rigid_pose_solve

    moved = not arm.geometry_is_nominal
    analytic, _ = branch_paths(ik, poses(task.positions, task.rotations), task.max_joint_step)
    results: dict[int, BranchResult] = {}
    rejected = dict(on_nodes.rejected)
    note = f"; on {len(nodes)} nodes of the {task.n} waypoints, interpolated between them"
    for b, r in on_nodes.branches.items():
        if not r.status.usable:
            rejected[b] = f"{r.status.value} on the nodes: {r.reason}"
            continue
        R_nodes = model.tcp(r.q).reshape(-1, 4, 4)[:, :3, :3]  # the node poses (model geometry)
        T = poses(task.positions, _dense_rotations(task, nodes, R_nodes))
        one = _branch_ik(ik, T, b, r.q[0], task.max_joint_step)
        if isinstance(one, str):
            rejected[b] = f"densified from {len(nodes)} nodes: {one}"
            continue
        q = rigid_pose_solve(arm, one, T) if moved else one
        qa = analytic[b].q if b in analytic else None
        if qa is not None and moved:
            qa = rigid_pose_solve(arm, qa, poses(task.positions, task.rotations))
        err = linear_error(model, q, task.load)
        err_a = linear_error(model, qa, task.load) if qa is not None else np.full(task.n, np.nan)
        cost = float(np.sum(err**2))
        results[b] = replace(  # the node result's solver record, with the dense posture and errors
            r,
            reason=r.reason + note,
            q=q,
            q_analytic=qa,
            q_warm=q,
            cost=cost,
            cost_analytic=float(np.sum(err_a**2)) if qa is not None else math.nan,
            cost_warm=cost,
            error_m=err,
            error_analytic_m=err_a,
            active_guards=dict(r.active_guards),
        )
    labels = on_nodes.labels
    if not results:
        why = "; ".join(f"{labels[b] if b < len(labels) else b}: {w}" for b, w in sorted(rejected.items()))
        status, reason, chosen = PostureStatus.NO_BRANCH, f"no IK branch is feasible along the whole path ({why})", None
    else:
        chosen = min(results, key=lambda b: results[b].cost)
        status, reason = (
            PostureStatus.OK,
            f"branch {labels[chosen]} chosen among {len(results)} usable branch(es) on {task.n} waypoints "
            f"(the NLP on {len(nodes)} nodes)",
        )
    return replace(  # the nodes' freedom, build time, labels and IK family
        on_nodes,
        status=status,
        reason=reason,
        task=task,
        branches=results,
        rejected=rejected,
        chosen=chosen,
        default=on_nodes.default if not results or on_nodes.default in results else None,
        unreachable=[],
    )


def _branch_ik(ik: IKSolver, T: np.ndarray, b: int, q_start: np.ndarray, max_step: float) -> np.ndarray | str:
    """Branch ``b``'s IK along the poses ``T`` (N, 4, 4), unwrapped from ``q_start``; or why not."""
    from models.ik import IKStatus

    sol = ik.solve(T)
    bad = np.flatnonzero(sol.status[:, b] != IKStatus.OK.code)
    if bad.size:
        k = int(bad[0])
        return f"waypoint {k}: {sol.reason(k, b)}"
    q = np.unwrap(sol.q[:, b, :], axis=0)
    q += 2 * np.pi * np.round((q_start - q[0]) / (2 * np.pi))
    out = (q < ik.q_min - 1e-12) | (q > ik.q_max + 1e-12)
    if out.any():
        k, j = (int(v) for v in np.argwhere(out)[0])
        return f"joint {j + 1} leaves its limits at waypoint {k} ({q[k, j]:.6g} rad)"
    if len(q) > 1:
        steps = np.abs(np.diff(q, axis=0)).max(axis=1)
        k = int(np.argmax(steps))
        if steps[k] > max_step:
            return f"flip between waypoints {k} and {k + 1}: joint step {steps[k]:.3g} rad > {max_step:g} rad"
    return q
