"""Warm starts of the posture NLP: scanned candidate orientations, the dynamic programmes
that pick the cheapest candidate sequence per branch, and moving paths onto the model's
geometry.

The *analytic posture* of a branch is the analytic IK at the nominal rotations ``R_k``.
Where a rotation is free, candidate orientations are scanned at every waypoint
(:func:`candidates`: rotations about the tool axis by ``2 pi j / scan``; plus tilts on the
cone's rim for ``cone`` and tool axes covering the sphere for ``position_only``) and the
cheapest sequence under the NLP's own objective (node cost plus smoothness, joint steps
above ``max_joint_step`` excluded) is found by dynamic programming over the waypoints
(:func:`warm_starts`).  All joint angles are in rad, positions in m, in the base frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.arm import ArmModel
from models.ik import IK_REASONS, IKSolution, IKSolver, IKStatus
from models.load import load_rows
from models.symbolic import KinematicModel
from problems.path import BranchPath, branch_paths, poses
from problems.posture.task import (
    COST_SCALE,
    DP_MAX_STATES,
    DP_NEIGHBOUR_ANGLE_RAD,
    POSITION_ONLY_AXES,
    OrientationRule,
    PostureTask,
)
from problems.posture.verification import guard_bounds


# --------------------------------------------------------------------------------------
# Candidates and helpers
# --------------------------------------------------------------------------------------


def _axis_angle(u: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) of ``angle`` (rad) about the axis ``u`` (3,) (any length > 0)."""
    u = u / np.linalg.norm(u)
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def candidates(task: PostureTask) -> list[tuple[str, np.ndarray]]:
    """Constant orientation offsets scanned for warm starts: (name, rotations (N, 3, 3)).

    The first candidate is always the nominal orientation.
    """
    R = task.rotations
    out = [("nominal", R)]
    if task.rule is OrientationRule.FIXED:
        return out
    tilts: list[tuple[str, float, float]] = [("", 0.0, 0.0)]
    if task.rule is OrientationRule.CONE:
        tilts += [
            (f"tilt={math.degrees(task.cone_half_angle):g}deg@{int(phi)}deg", task.cone_half_angle, math.radians(phi))
            for phi in (0, 90, 180, 270)
        ]
    elif task.rule is OrientationRule.POSITION_ONLY:
        tilts += [
            (f"tilt={t:g}deg@{360.0 * i / nd:g}deg", math.radians(t), 2.0 * math.pi * i / nd)
            for t, nd in POSITION_ONLY_AXES
            for i in range(nd)
        ]
    n_scan = int(task.scan)
    for tname, tilt, phi in tilts:
        if tilt > 0.0:
            # Tilt about a tool-frame direction perpendicular to the tool axis (per waypoint).
            u = math.cos(phi) * R[:, :, 0] + math.sin(phi) * R[:, :, 1]
            Rt = np.stack([_axis_angle(u[k], tilt) @ R[k] for k in range(len(R))])
        else:
            Rt = R
        for j in range(n_scan):
            psi = 2.0 * math.pi * j / n_scan
            if tilt == 0.0 and j == 0:
                continue
            c, s = math.cos(psi), math.sin(psi)
            Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            name = ", ".join(x for x in (tname, f"psi={math.degrees(psi):g}deg") if x)
            out.append((name, Rt @ Rz))
    return out


@dataclass
class WarmStarts:
    """Analytic postures and warm starts of every branch (see :func:`warm_starts`).

    Attributes
    ----------
    analytic : dict branch -> BranchPath
        Analytic IK at the nominal rotations, for the branches reaching the whole path there.
    warm : dict branch -> (BranchPath, str, float)
        Warm start, its label (which candidate(s)) and its cost ``sum ||S C F||^2``, m^2.
    rejected : dict branch -> str
        Why every branch without a warm start was rejected (naming the waypoint).
    unreachable : list of int
        Waypoints with no IK solution on any branch at any candidate.
    """

    analytic: dict[int, BranchPath]
    warm: dict[int, tuple[BranchPath, str, float]]
    rejected: dict[int, str]
    unreachable: list[int]


def linear_error(model: KinematicModel, q: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """First-order load-induced TCP position error per row (the NLP's objective), m.

    For the nominal model and a base-frame wrench this is ``||S C(q_k) F_k||``.

    Parameters
    ----------
    model : KinematicModel
        Its ``fn["load_error"]`` is evaluated.
    q : ndarray, shape (N, 6) or (6,)
        Joint angles, rad.
    wrench : ndarray, shape (N, 6), (6,) or (N, LOAD_SIZE)
        Base-frame wrench on the TCP [N, N*m], or load rows (:mod:`models.load`).

    Returns
    -------
    ndarray, shape (N,)
        Norm of the translational TCP deflection, m.
    """
    q = np.atleast_2d(q)
    D = model.batch(model.fn["load_error"], q, load_rows(wrench, len(q)))[0]
    return np.linalg.norm(D[:, :3], axis=1)


def _wrap(d: np.ndarray) -> np.ndarray:
    """Angles (any shape, rad) wrapped into [-pi, pi)."""
    return (d + np.pi) % (2.0 * np.pi) - np.pi


def _into_limits(q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray) -> np.ndarray | None:
    """Shift each joint of a continuous path (N, 6) by a common 2*pi*k into the limits, or None."""
    out = q.copy()
    for j in range(6):
        lo, hi = q[:, j].min(), q[:, j].max()
        k_lo = math.ceil((q_min[j] - lo) / (2.0 * math.pi) - 1e-12)
        k_hi = math.floor((q_max[j] - hi) / (2.0 * math.pi) + 1e-12)
        if k_lo > k_hi:
            return None
        k = min(max(0, k_lo), k_hi)  # the shift nearest zero that fits
        out[:, j] += 2.0 * math.pi * k
    return out


# --------------------------------------------------------------------------------------
# Warm starts
# --------------------------------------------------------------------------------------


def warm_starts(ik: IKSolver, model: KinematicModel, task: PostureTask) -> WarmStarts:
    """Analytic IK at the nominal rotations, and a warm start per branch.

    The warm start of a branch is the cheapest sequence of scanned candidates
    (:func:`candidates`, one per waypoint) under the NLP's own objective, found by
    dynamic programming over the waypoints: node cost ``s ||S C F||^2`` (mm^2),
    transition cost ``lam ||dq||^2`` (wrapped joint differences), transitions with
    a joint step above ``max_joint_step`` and nodes inside a singularity guard
    excluded.  With a fixed orientation it is the analytic posture itself.

    Parameters
    ----------
    ik : IKSolver
        The all-branch IK of the nominal chain.
    model : KinematicModel
        Evaluates the node costs (:func:`linear_error`).
    task : PostureTask

    Returns
    -------
    WarmStarts
        Joint paths (N, 6) in rad; warm-start costs in m^2.
    """
    feas_nom, rej_nom = branch_paths(ik, poses(task.positions, task.rotations), task.max_joint_step)
    cands = candidates(task)
    sol, Q, ok = _solve_candidates(ik, task, cands)
    unreachable = [int(k) for k in np.where(~ok.any(axis=(0, 2)))[0]]
    if task.rule is OrientationRule.FIXED or len(cands) == 1:
        return _analytic_warm_starts(model, task, feas_nom, rej_nom, unreachable)

    cost = _node_costs(ik, model, task, Q, ok)
    nb = ik.n_branches
    Qb = np.ascontiguousarray(np.nan_to_num(Q).transpose(2, 0, 1, 3))  # (B, S, N, 6)
    sparse = _sparse_sequences(cost, Qb, task, cands) if len(cands) > DP_MAX_STATES else {}
    first_status = sol.status.reshape(len(cands), task.n, nb)[0]  # (N, B)
    warm: dict[int, tuple[BranchPath, str, float]] = {}
    rejected: dict[int, str] = {}
    for b in range(nb):
        out = _branch_warm_start(ik, task, cands, b, cost[:, :, b], Qb[b], sparse.get(b), first_status[:, b])
        if isinstance(out, str):
            rejected[b] = out
        else:
            warm[b] = out
    for b, r in rej_nom.items():
        if b not in warm and b not in rejected:
            rejected[b] = r
    return WarmStarts(feas_nom, warm, rejected, unreachable)


def _solve_candidates(
    ik: IKSolver, task: PostureTask, cands: list[tuple[str, np.ndarray]]
) -> tuple[IKSolution, np.ndarray, np.ndarray]:
    """Analytic IK of every waypoint at every candidate orientation.

    Returns
    -------
    sol : IKSolution
        Of the S * N poses, candidate-major.
    Q : ndarray, shape (S, N, B, 6)
        Joint angles per candidate, waypoint and branch, rad (NaN where unsolved).
    ok : ndarray of bool, shape (S, N, B)
        Where the IK succeeded.
    """
    S, n = len(cands), task.n
    if ik.labels_stable:
        T_all = np.concatenate([poses(task.positions, R) for _, R in cands])  # (S*N, 4, 4)
        sol = ik.solve(T_all)
    else:
        sol = _continued_solutions(ik, task, cands)
    Q = sol.q.reshape(S, n, ik.n_branches, 6)
    ok = sol.status.reshape(S, n, ik.n_branches) == IKStatus.OK.code
    return sol, Q, ok


def _continued_solutions(ik: IKSolver, task: PostureTask, cands: list[tuple[str, np.ndarray]]) -> IKSolution:
    """Every candidate's IK (candidate-major, S * N poses) for a family whose labels hold only
    within one call: the nominal candidate is solved along the path (labels by continuity, as
    :func:`~problems.path.branch_paths` does), then each other candidate, nearest in rotation
    to one already solved, takes that one's branches as the reference of its labels."""
    S = len(cands)
    sols: list[IKSolution | None] = [None] * S
    sols[0] = ik.solve(poses(task.positions, cands[0][1]))
    R0 = np.stack([R[0] for _, R in cands])  # (S, 3, 3) at waypoint 0
    dist = np.arccos(np.clip((np.einsum("aji,bji->ab", R0, R0) - 1.0) / 2.0, -1.0, 1.0))
    done = [0]
    for _ in range(S - 1):
        todo = [s for s in range(S) if sols[s] is None]
        sub = dist[np.ix_(todo, done)]
        i, j = np.unravel_index(np.argmin(sub), sub.shape)
        s, ref = todo[int(i)], sols[done[int(j)]]
        sols[s] = ik.solve_like(poses(task.positions, cands[s][1]), ref.q)
        done.append(s)
    return IKSolution(
        q=np.concatenate([x.q for x in sols]), status=np.concatenate([x.status for x in sols]), labels=ik.labels
    )


def _analytic_warm_starts(
    model: KinematicModel,
    task: PostureTask,
    feas_nom: dict[int, BranchPath],
    rej_nom: dict[int, str],
    unreachable: list[int],
) -> WarmStarts:
    """Warm starts when nothing is scanned (fixed orientation): the analytic postures."""
    warm: dict[int, tuple[BranchPath, str, float]] = {}
    for b, bp in feas_nom.items():
        err = linear_error(model, bp.q, task.load)
        warm[b] = (bp, "nominal", float(np.sum(err**2)))
    return WarmStarts(feas_nom, warm, dict(rej_nom), unreachable)


def _node_costs(ik: IKSolver, model: KinematicModel, task: PostureTask, Q: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Node costs ``COST_SCALE ||S C F||^2`` (mm^2), shape (S, N, B); inf where the IK failed
    or a guard factor lies inside its guard (a node must lie on the branch's side of
    every singularity, with margin)."""
    S, n = Q.shape[:2]
    fac = ik.guard_factors(np.nan_to_num(Q))  # (S, N, B, G)
    valid = ok & (np.abs(fac) >= guard_bounds(ik)).all(axis=-1)
    idx = np.argwhere(valid)  # (M, 3): s, k, b
    cost = np.full((S, n, ik.n_branches), np.inf)
    if len(idx):
        qv = Q[idx[:, 0], idx[:, 1], idx[:, 2]]
        err = linear_error(model, qv, task.load[idx[:, 1]])
        cost[idx[:, 0], idx[:, 1], idx[:, 2]] = COST_SCALE * err**2
    return cost


def _sparse_sequences(
    cost: np.ndarray, Qb: np.ndarray, task: PostureTask, cands: list[tuple[str, np.ndarray]]
) -> dict[int, np.ndarray]:
    """Candidate sequences of every branch reaching all waypoints, by the neighbour-restricted
    programme (:func:`_dp_sparse`); branches whose restricted graph is blocked are left out.

    ``cost`` (S, N, B) node costs, ``Qb`` (B, S, N, 6) candidate joints (rad).
    """
    reach_all = np.isfinite(cost).any(axis=0).all(axis=0)  # (B,)
    bs = np.flatnonzero(reach_all)
    if not bs.size:
        return {}
    # float32 halves the memory traffic of the programme; the sequence it picks is
    # re-evaluated in float64 by the caller
    qk = np.ascontiguousarray(Qb[bs].transpose(0, 2, 1, 3), dtype=np.float32)  # (B, N, S, 6)
    seqs = _dp_sparse(
        cost.transpose(2, 0, 1)[bs].astype(np.float32),
        qk,
        task.smoothness,
        task.max_joint_step,
        _neighbours([R for _, R in cands]),
    )
    return {int(b): sq for b, sq in zip(bs, seqs) if sq is not None}


def _dense_sequence(node: np.ndarray, qb: np.ndarray, task: PostureTask) -> np.ndarray | int:
    """The dense programme (:func:`_dp`), pruned first and with more states kept while the
    pruned graph is disconnected.  Returns the sequence (N,) or the blocked waypoint (int)."""
    limit = DP_MAX_STATES
    seq = _dp(node, qb, task.smoothness, task.max_joint_step, limit)
    while seq is None:  # pruned graph disconnected: keep more states
        limit *= 2
        seq = _dp(node, qb, task.smoothness, task.max_joint_step, limit)
    return seq


def _branch_warm_start(
    ik: IKSolver,
    task: PostureTask,
    cands: list[tuple[str, np.ndarray]],
    b: int,
    node: np.ndarray,
    qb: np.ndarray,
    seq: np.ndarray | None,
    first_status: np.ndarray,
) -> tuple[BranchPath, str, float] | str:
    """One branch's warm start, or why the branch is rejected.

    Parameters
    ----------
    b : int
        The branch.
    node : ndarray, shape (S, N)
        Its node costs, mm^2 (inf where invalid).
    qb : ndarray, shape (S, N, 6)
        Its candidates' joint angles, rad.
    seq : ndarray of int, shape (N,), or None
        The sparse programme's sequence, if it found one (else the dense one runs).
    first_status : ndarray, shape (N,)
        IK status per waypoint at the first (nominal) candidate, for the rejection reason.

    Returns
    -------
    (BranchPath, label, cost in m^2), or str
        The warm start, or the rejection reason (naming the waypoint).
    """
    reachable = np.isfinite(node).any(axis=0)
    if not reachable.all():
        k = int(np.argmin(reachable))
        st = first_status[k]
        why = IK_REASONS[IKStatus.from_code(st)] if st != IKStatus.OK.code else "inside a singularity guard"
        return f"waypoint {k}: {why} (at the nominal orientation and every scanned one)"
    found = _dense_sequence(node, qb, task) if seq is None else seq
    if isinstance(found, int):
        return (
            f"flip between waypoints {found} and {found + 1}: no scanned "
            f"orientation keeps every joint step <= {task.max_joint_step:g} rad"
        )
    n = task.n
    q = np.empty((n, 6))
    q[0] = qb[found[0], 0]
    for k in range(n - 1):
        q[k + 1] = q[k] + _wrap(qb[found[k + 1], k + 1] - qb[found[k], k])
    q = _into_limits(q, ik.q_min, ik.q_max)
    if q is None:
        return "a joint leaves its limits along the path at every scanned orientation"
    steps = np.abs(np.diff(q, axis=0)).max() if n > 1 else 0.0
    names = sorted({cands[s][0] for s in found})
    label = names[0] if len(names) == 1 else f"per-waypoint scan over {len(cands)} orientations"
    return (BranchPath(b, q, float(steps), ik.labels[b]), label, float(np.sum(node[found, np.arange(n)])) / COST_SCALE)


# --------------------------------------------------------------------------------------
# The dynamic programmes
# --------------------------------------------------------------------------------------


def _neighbours(rotations: list[np.ndarray]) -> np.ndarray:
    """(S, M) indices of the candidates within DP_NEIGHBOUR_ANGLE_RAD of each candidate
    (padded with -1), from their rotations at the first waypoint."""
    R = np.stack([r[0] for r in rotations])  # (S, 3, 3)
    tr = np.einsum("aji,bji->ab", R, R)  # trace(Ra^T Rb)
    ang = np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))
    close = ang <= DP_NEIGHBOUR_ANGLE_RAD
    m = int(close.sum(axis=1).max())
    out = -np.ones((len(R), m), dtype=int)
    for i, row in enumerate(close):
        idx = np.flatnonzero(row)
        out[i, : len(idx)] = idx
    return out


def _dp_sparse(
    node: np.ndarray, qb: np.ndarray, lam: float, max_step: float, nbr: np.ndarray
) -> list[np.ndarray | None]:
    """Cheapest candidate sequences of several branches at once, with transitions only
    between neighbouring candidates (:func:`_neighbours`).

    Parameters
    ----------
    node : ndarray (B, S, N)
        Node costs per branch (inf where invalid).
    qb : ndarray (B, N, S, 6)
        The candidates' joint angles per branch (waypoint-major for contiguous slices).
    nbr : ndarray (S, M)
        Neighbour indices, -1 padded.

    Returns
    -------
    list (B,) of sequences (N,), or None where that graph is blocked (the caller then
    runs the dense :func:`_dp`).
    """
    B, S, n = node.shape
    valid = nbr >= 0
    idx = np.where(valid, nbr, 0)
    rows = np.arange(S)
    V = node[:, :, 0].copy()  # (B, S)
    blocked = np.zeros(B, dtype=bool)
    backs = []
    for k in range(n - 1):
        d = qb[:, k + 1][:, :, None, :] - qb[:, k][:, idx]  # (B, S_to, M, 6)
        d -= np.float32(2.0 * np.pi) * np.round(d * np.float32(0.5 / np.pi))
        trans = np.float32(lam) * np.einsum("bsmj,bsmj->bsm", d, d)
        trans[(np.abs(d).max(axis=-1) > max_step) | ~valid] = np.inf
        tot = V[:, idx] + trans
        j = np.argmin(tot, axis=2)  # (B, S)
        V = np.take_along_axis(tot, j[:, :, None], axis=2)[:, :, 0] + node[:, :, k + 1]
        backs.append(idx[rows, j])  # (B, S)
        blocked |= ~np.isfinite(V).any(axis=1)
    out: list[np.ndarray | None] = []
    for i in range(B):
        if blocked[i]:
            out.append(None)
            continue
        seq = np.zeros(n, dtype=int)
        seq[-1] = int(np.argmin(V[i]))
        for k in range(n - 1, 0, -1):
            seq[k - 1] = backs[k - 1][i, seq[k]]
        out.append(seq)
    return out


def _dp(node: np.ndarray, qb: np.ndarray, lam: float, max_step: float, max_states: int) -> np.ndarray | int | None:
    """Cheapest candidate sequence (Viterbi) over the waypoints.

    Parameters
    ----------
    node : ndarray (S, N)
        Node costs (inf where a candidate is not valid).
    qb : ndarray (S, N, 6)
        The candidates' joint angles.
    max_states : int
        Keep at most this many cheapest candidates per waypoint.

    Returns
    -------
    ndarray of int (N,) : the sequence; int k : blocked between waypoints k and k+1
    with every candidate kept; None : blocked with pruned states (retry with more).
    """
    S, n = node.shape
    states = []
    for k in range(n):
        idx = np.flatnonzero(np.isfinite(node[:, k]))
        if len(idx) > max_states:
            idx = idx[np.argsort(node[idx, k])[:max_states]]
        states.append(idx)
    V = node[states[0], 0]
    backs = []
    for k in range(n - 1):
        a, b = states[k], states[k + 1]
        d = qb[b, k + 1][None, :, :] - qb[a, k][:, None, :]  # (A, B, 6)
        d -= 2.0 * np.pi * np.round(d / (2.0 * np.pi))
        trans = lam * np.einsum("abj,abj->ab", d, d)
        trans[np.abs(d).max(axis=-1) > max_step] = np.inf
        tot = V[:, None] + trans
        back = np.argmin(tot, axis=0)
        V = tot[back, np.arange(len(b))] + node[b, k + 1]
        backs.append(back)
        if not np.isfinite(V).any():
            pruned = any(len(states[j]) < np.isfinite(node[:, j]).sum() for j in range(k + 2))
            return None if pruned else k
    pos = int(np.argmin(V))
    seq = np.zeros(n, dtype=int)
    seq[-1] = states[-1][pos]
    for k in range(n - 1, 0, -1):
        pos = int(backs[k - 1][pos])
        seq[k - 1] = states[k - 1][pos]
    return seq


# --------------------------------------------------------------------------------------
# Onto the model's geometry
# --------------------------------------------------------------------------------------


def onto_model_geometry(arm: ArmModel, ik: IKSolver, ws: WarmStarts) -> WarmStarts:
    """Move the analytic postures and warm starts onto the model's geometry.

    The closed-form IK solves the *nominal* chain; an identified model's chain differs
    (DH errors, offsets, thermal).  Each path is moved by damped Newton to the joints whose
    TCP under the model's geometry is the pose the nominal chain had (the IK target).

    Parameters
    ----------
    arm : ArmModel
        The model whose geometry the paths are moved onto.
    ik : IKSolver
        The IK of the nominal chain (``ik.robot``) that produced ``ws``.
    ws : WarmStarts

    Returns
    -------
    WarmStarts
        The same branches, labels, costs and rejections; moved joint paths (N, 6), rad.
    """
    from problems.compensation import rigid_pose_solve

    nominal = KinematicModel(ik.robot)

    def move(bp: BranchPath) -> BranchPath:
        """The path (N, 6) rad moved onto the model's geometry, with its largest joint step."""
        q = rigid_pose_solve(arm, bp.q, nominal.tcp(bp.q).reshape(-1, 4, 4))
        steps = float(np.abs(np.diff(q, axis=0)).max()) if len(q) > 1 else 0.0
        return BranchPath(bp.branch, q, steps, bp.label)

    analytic = {b: move(bp) for b, bp in ws.analytic.items()}
    warm = {
        b: (analytic[b] if b in analytic and bp.q is ws.analytic[b].q else move(bp), name, cost)
        for b, (bp, name, cost) in ws.warm.items()
    }
    return WarmStarts(analytic, warm, ws.rejected, ws.unreachable)
