"""The per-pose kernel of a placement study: one chunk of base placements in, their scores out.

For every placement of a chunk and every waypoint of the problem's path, at every scanned
orientation (:func:`problems.posture.warm_start.candidates`: the same candidates as the posture
NLP's warm starts), the kernel solves every IK branch, drops the solutions inside a
singularity guard, evaluates the arm model's ``load_error`` (the posture NLP's objective, with
every effect of the model), and keeps, per branch, the cheapest candidate sequence along the
path (a Viterbi programme over the waypoints: node cost the squared load-induced error,
transition cost the smoothness weight times the squared joint step, steps above
``max_joint_step`` excluded: no flip).  A branch is feasible at a placement if such a sequence
exists and a common ``2 pi k`` per joint puts it inside the joint limits.

A *pose* is one TCP target (a waypoint at one scanned orientation at one placement); each
pose solves all B branches.  The cost of a chunk is proportional to its poses.

Frames: the problem's path, rotations and base-frame wrench are in the *cell frame*; a
placement's ``cell2base`` (:mod:`problems.placement.grid`) maps them into the base frame, where
the IK and the model are evaluated.  A base-frame wrench and the payload's gravity are fixed in
the cell (they turn with ``cell2base``); a tool-frame wrench turns with the tool.

The arm's own gravity (its self-weight, when the model has the ``gravity`` effect) is fixed in
the cell too: the kernel evaluates the model's ``load_error_g`` (``load_error`` with the gravity
constant as an input, :attr:`models.symbolic.KinematicModel.load_error_gravity`) with the
robot's gravity turned into each placement's base frame, so one compiled function serves every
yaw, tilt and placement.

The kernel is picklable: it ships the compiled libraries of the model's ``load_error_g`` and of
the IK's closed form (or, where the CPU differs or nothing was compiled, CasADi's serialised
functions for its virtual machine) with itself (:func:`models.portable.portable_state`), so a
Dask worker needs no compiler.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from models.arm import ArmModel
from models.codegen import BatchFunction, VMBatchFunction, batch_function
from models.portable import evaluator_from_state, portable_state
from models.errors import InputError
from models.ik import IKStatus, ik_solver
from models.robot import Robot
from problems.placement.collide import KernelCell
from problems.placement.grid import base2cell, cell2base
from problems.placement.scores import ChunkScores, PlacementStatus
from problems.posture.task import COST_SCALE, DP_MAX_STATES, DP_NEIGHBOUR_ANGLE_RAD
from problems.posture.verification import guard_bounds
from problems.posture.warm_start import candidates

#: Threads of the kernel's compiled evaluation (parallelism comes from chunks, not threads).
KERNEL_THREADS = 1
#: With at most this many candidate orientations every candidate may follow every other one
#: (the warm starts' dense programme, ``DP_MAX_STATES``); with more, only candidates within
#: ``DP_NEIGHBOUR_ANGLE_RAD`` of each other (the warm starts' restricted programme), and the
#: rows that restricted programme finds blocked run the dense one, as the warm starts do.
DENSE_CANDIDATES = DP_MAX_STATES
#: Round-off allowance of the joint-limit shift (as the warm starts), in units of 2 pi.
_SHIFT_EPS = 1e-12
#: Lazy collision rounds: a branch's chosen sequence is checked, its violating nodes excluded and
#: the programme re-run, this many times before each round also checks every live node at the
#: row's first violating waypoint.  0: a violating waypoint is resolved at once (measured on
#: placement_milling with a cell: fewer configurations checked than with 1 or 3, same scores).
LAZY_COLLISION_ROUNDS = 0


def _rotate_load(L: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Load rows (N, 19) of the cell frame into the base frames of rotations ``R`` (P, 3, 3)
    (``cell2base``): base-frame force, moment and gravity turn; tool-frame parts do not.
    Returns (P, N, 19)."""
    out = np.broadcast_to(L, (len(R),) + L.shape).copy()
    for a in (0, 3, 16):
        out[:, :, a : a + 3] = np.einsum("pij,nj->pni", R, L[:, a : a + 3])
    return out


class PlacementKernel:
    """Scores of base placements for one problem (see the module docstring).

    Parameters
    ----------
    problem : Problem
        Path, orientation rule, load, limits and arm model, in the cell frame.
    threads : int
        Threads of the compiled evaluation (default :data:`KERNEL_THREADS`).

    Raises
    ------
    InputError
        The robot's IK family does not keep its branch labels across calls (the sweep
        compares branches across placements).
    """

    def __init__(self, problem: Any, threads: int = KERNEL_THREADS) -> None:
        task = problem.task()
        self.robot: Robot = problem.robot
        self.positions = np.asarray(task.positions, dtype=float)  # (N, 3) cell
        self.rotations = np.stack([R for _, R in candidates(task)])  # (S, N, 3, 3) cell
        self.load_cell = np.asarray(task.load, dtype=float)  # (N, 19) cell
        self.smoothness = float(task.smoothness)
        self.max_joint_step = float(task.max_joint_step)
        self.threads = int(threads)
        arm: ArmModel = problem.model
        #: The arm's gravity (m/s^2) in the cell frame: the robot file's, read in the base frame
        #: of the problem as written (the placement at the origin).
        self.gravity_cell = np.asarray(arm.nominal.gravity, dtype=float).reshape(3)
        f = arm.kinematics.load_error_gravity
        model = batch_function(f, self.threads)
        self._model_state = portable_state(f, model)
        ik = ik_solver(self.robot)
        self._ik_state = None if ik.function is None else portable_state(ik.function, ik.evaluator)
        #: The cell's checks (``problems/placement/collide.py``), or None without ``[cell]``.
        self.cell: KernelCell | None = None if problem.cell is None else KernelCell(self.robot, problem.cell)
        self._setup(ik, model)

    # -------------------------------------------------------------- pickling (shipping)
    def __getstate__(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        for k in ("ik", "_model", "_bounds", "_nbr"):
            d.pop(k, None)
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        self.__dict__.update(d)
        ik = ik_solver(self.robot)
        if self._ik_state is not None:
            ik.use_evaluator(evaluator_from_state(self._ik_state, self.threads))
        self._setup(ik, evaluator_from_state(self._model_state, self.threads))

    def _setup(self, ik: Any, model: BatchFunction | VMBatchFunction) -> None:
        if not ik.labels_stable:
            raise InputError(
                f"robot '{self.robot.name}': its IK family ({type(ik).__name__}) does not keep "
                "branch labels from one call to the next; a placement sweep needs a family that "
                "does (UR-type or OPW arms)"
            )
        self.ik = ik
        self._bounds = guard_bounds(ik)
        self._model = model
        self._nbr = _neighbour_table(self.rotations)

    # ------------------------------------------------------------------ properties
    @property
    def n_waypoints(self) -> int:
        return int(len(self.positions))

    @property
    def n_candidates(self) -> int:
        return int(len(self.rotations))

    @property
    def n_branches(self) -> int:
        return int(self.ik.n_branches)

    @property
    def poses_per_placement(self) -> int:
        """TCP targets per placement (waypoints x scanned orientations); each solves every branch."""
        return self.n_waypoints * self.n_candidates

    @property
    def compiled(self) -> bool:
        """Whether the model's ``load_error_g`` and the IK's closed form run compiled C here (else
        CasADi's virtual machine)."""
        return isinstance(self._model, BatchFunction) and (
            self.ik.function is None or isinstance(self.ik.evaluator, BatchFunction)
        )

    # ------------------------------------------------------------------ the kernel
    def evaluate(self, placements: np.ndarray) -> ChunkScores:
        """Scores of a chunk of placements.

        Parameters
        ----------
        placements : ndarray, shape (P, 5)
            ``[x, y, z, yaw, tilt]`` (m, rad), see :mod:`problems.placement.grid`.

        Returns
        -------
        ChunkScores
            One row per placement.
        """
        pl = np.atleast_2d(np.asarray(placements, dtype=float))
        if self.cell is None:
            return self._evaluate(pl)
        foot = self.cell.footprint_blocked(pl)  # before the IK: these are not solved
        if not foot.any():
            return self._evaluate(pl)
        out = ChunkScores.empty(len(pl), self.n_branches)
        out.status[foot] = PlacementStatus.COLLISION.code
        free = np.flatnonzero(~foot)
        if free.size:
            out.set_rows(free, self._evaluate(pl[free]))
        return out

    def _evaluate(self, pl: np.ndarray) -> ChunkScores:
        """Scores of placements (P, 5) whose base footprint is free."""
        P, S, N, B = len(pl), self.n_candidates, self.n_waypoints, self.n_branches
        C2B = cell2base(pl)
        R, t = C2B[:, :3, :3], C2B[:, :3, 3]
        T = np.zeros((P, S, N, 4, 4))
        T[..., :3, :3] = np.einsum("pij,snjk->psnik", R, self.rotations)
        T[..., :3, 3] = (np.einsum("pij,nj->pni", R, self.positions) + t[:, None, :])[:, None]
        T[..., 3, 3] = 1.0
        sol = self.ik.solve(T.reshape(-1, 4, 4))
        Q = sol.q.reshape(P, S, N, B, 6)
        # flat boolean masks over (P, S, N, B) (cheaper than index tuples); NaN rows are never read
        ok = (sol.status == IKStatus.OK.code).ravel()
        Qf = Q.reshape(-1, 6)
        ratio = np.zeros(P * S * N * B)
        ratio[ok] = (np.abs(self.ik.guard_factors(Qf[ok])) / self._bounds).min(axis=-1)
        ratio = ratio.reshape(P, S, N, B)
        valid = ratio >= 1.0  # (P, S, N, B)
        reach_any = valid.any(axis=(1, 3))  # (P, N)
        # a solution that only the joint limits exclude (no 2 pi k puts it inside them)
        outside = (sol.status == IKStatus.JOINT_LIMIT.code).reshape(P, S, N, B).any(axis=(1, 3))  # (P, N)
        # only branches reaching every waypoint can be feasible: the model is evaluated there only
        valid &= valid.any(axis=1).all(axis=1)[:, None, None, :]
        vf = valid.ravel()
        err = np.full(P * S * N * B, np.inf)
        if vf.any():
            L = _rotate_load(self.load_cell, R).reshape(P * N, -1)  # (P N, 19)
            G = R @ self.gravity_cell  # (P, 3) base
            p_of = np.broadcast_to(np.arange(P)[:, None, None, None], (P, S, N, B)).ravel()[vf]
            n_of = np.broadcast_to(np.arange(N)[None, None, :, None], (P, S, N, B)).ravel()[vf]
            D = self._model(Qf[vf], L[p_of * N + n_of], G[p_of])[0][:, :3]
            err[vf] = np.sqrt(np.einsum("ij,ij->i", D, D))
        err = err.reshape(P, S, N, B)
        return self._score(Q, err, ratio, reach_any, outside, pl)

    def _score(
        self,
        Q: np.ndarray,
        err: np.ndarray,
        ratio: np.ndarray,
        any_reach: np.ndarray,
        outside: np.ndarray,
        pl: np.ndarray | None = None,
    ) -> ChunkScores:
        """Per placement and branch: the cheapest flip-free sequence, its limits, its errors.

        ``err`` (P, S, N, B) m, inf where a node is invalid or its branch misses a waypoint;
        ``any_reach`` (P, N): the waypoint has a valid node on some branch; ``outside`` (P, N):
        it has an IK solution outside the joint limits; ``pl`` (P, 5) the placements (for the
        cell's checks)."""
        P, S, N, B = err.shape
        reach_all = np.isfinite(err).any(axis=1).all(axis=1)  # (P, B)
        out = ChunkScores.empty(P, B)
        first_gap = np.where(~any_reach.all(axis=1), np.argmin(any_reach, axis=1), -1)
        out.blocked_waypoint[:] = first_gap
        gap_limit = (first_gap >= 0) & outside[np.arange(P), np.maximum(first_gap, 0)]
        pb = np.argwhere(reach_all)  # (M, 2)
        flip = np.zeros((P, B), dtype=bool)
        limit = np.zeros((P, B), dtype=bool)
        coll = np.zeros((P, B), dtype=bool)
        if len(pb):
            node = err[pb[:, 0], :, :, pb[:, 1]]  # (M, S, N) m
            qm = Q[pb[:, 0], :, :, pb[:, 1]]  # (M, S, N, 6)
            # float32 halves the programme's memory traffic; it only picks the sequence, whose
            # errors and joint angles are then read in float64.  Joint-major (6, N, M, S).
            qj = np.nan_to_num(qm.transpose(3, 2, 0, 1).astype(np.float32), copy=False, nan=0.0)
            cost = (COST_SCALE * node**2).astype(np.float32)
            seq, blocked = self._programme(cost, qj)
            if self.cell is not None and pl is not None:
                hit = self._avoid_collisions(cost, qj, qm, seq, blocked, pb, base2cell(pl))
                coll[pb[hit, 0], pb[hit, 1]] = True
                blocked &= ~hit
                seq[hit] = 0
            flip[pb[blocked, 0], pb[blocked, 1]] = True
            good = ~blocked & ~coll[pb[:, 0], pb[:, 1]]
            pbg, seqg = pb[good], seq[good]
            if len(pbg):
                qpath = _unwrap(qm, np.flatnonzero(good), seqg)  # (M', N, 6)
                # the float32 programme's step test, again in float64 (a step at the bound)
                smooth = (np.abs(np.diff(qpath, axis=1)) <= self.max_joint_step).all(axis=(1, 2))
                flip[pbg[~smooth, 0], pbg[~smooth, 1]] = True
                shifted, inside = _into_limits(qpath, self.ik.q_min, self.ik.q_max)
                limit[pbg[smooth & ~inside, 0], pbg[smooth & ~inside, 1]] = True
                inside &= smooth
                n_idx = np.arange(N)
                e = err[pbg[:, 0][:, None], seqg, n_idx[None, :], pbg[:, 1][:, None]]  # (M', N)
                r = ratio[pbg[:, 0][:, None], seqg, n_idx[None, :], pbg[:, 1][:, None]]
                margin = np.minimum(shifted - self.ik.q_min, self.ik.q_max - shifted).min(axis=(1, 2))
                rms = np.sqrt(np.mean(e**2, axis=1))
                f = inside
                out.branch_rms_m[pbg[f, 0], pbg[f, 1]] = rms[f]
                out.branch_max_m[pbg[f, 0], pbg[f, 1]] = e.max(axis=1)[f]
                out.branch_joint_margin_rad[pbg[f, 0], pbg[f, 1]] = margin[f]
                out.branch_singular_margin[pbg[f, 0], pbg[f, 1]] = r.min(axis=1)[f]
        out.finish(flip, limit, gap_limit, coll)
        return out

    def _programme(self, cost: np.ndarray, qj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The Viterbi programme on rows (``cost`` (M, S, N), ``qj`` (6, N, M, S)); where the
        restricted graph is blocked, the dense one (every candidate may follow every other)."""
        S = cost.shape[1]
        seq, blocked = _viterbi(cost, qj, self.smoothness, self.max_joint_step, self._nbr)
        if blocked.any() and self._nbr.shape[1] < S:
            rb = np.flatnonzero(blocked)
            seq[rb], blocked[rb] = _viterbi(
                cost[rb], qj[:, :, rb], self.smoothness, self.max_joint_step, np.tile(np.arange(S), (S, 1))
            )
        return seq, blocked

    def _avoid_collisions(
        self,
        cost: np.ndarray,
        qj: np.ndarray,
        qm: np.ndarray,
        seq: np.ndarray,
        blocked: np.ndarray,
        pb: np.ndarray,
        b2c: np.ndarray,
    ) -> np.ndarray:
        """The cheapest collision-free sequence of each row (placement x branch), in place.

        A row's chosen sequence is checked; where it violates the clearance, its violating nodes
        get an infinite cost (after :data:`LAZY_COLLISION_ROUNDS` rounds, also every live node at the
        row's first violating waypoint is checked and the violating ones excluded) and the
        programme is re-run on those rows.  Each node's result is kept: a node is checked at most
        once.  Each round from then on resolves at least one waypoint of every violating row whole,
        so at most ``LAZY_COLLISION_ROUNDS + N`` rounds end with every row's sequence clear; a row
        still unverified then (never, by that argument) is counted as colliding.  Only rows whose
        sequence is flip-free in float64 and fits the joint limits are checked (the others are
        not feasible anyway).  ``cost`` (M, S, N) is modified; ``seq`` (M, N) and ``blocked``
        (M,) are updated.

        Returns
        -------
        ndarray of bool, shape (M,)
            Rows that had a sequence without a flip but have none without a collision.
        """
        cell = self.cell
        assert cell is not None
        M, S, N = cost.shape
        hit = np.zeros(M, dtype=bool)
        known = np.zeros((M, S, N), dtype=np.int8)  # 0 not checked, 1 clear, 2 violating
        n_idx = np.arange(N)
        rows = self._checkable(qm, seq, np.flatnonzero(~blocked))
        for rnd in range(LAZY_COLLISION_ROUNDS + N + 1):
            if rows.size == 0:
                break
            s_of = seq[rows]  # (R, N)
            st = known[rows[:, None], s_of, n_idx[None, :]]  # (R, N)
            r_u, n_u = np.nonzero(st == 0)
            if r_u.size:
                rr = rows[r_u]
                d = cell.min_distance(qm[rr, s_of[r_u, n_u], n_u], b2c[pb[rr, 0]])
                st[r_u, n_u] = np.where(d < cell.clearance, 2, 1)
                known[rr, s_of[r_u, n_u], n_u] = st[r_u, n_u]
            bad = st == 2
            rb = np.flatnonzero(bad.any(axis=1))
            if rb.size == 0:
                break
            rows_b = rows[rb]
            r_i, n_i = np.nonzero(bad[rb])
            cost[rows_b[r_i], seq[rows_b[r_i], n_i], n_i] = np.inf
            if rnd >= LAZY_COLLISION_ROUNDS:  # every live node at each row's first violating waypoint
                n_f = np.argmax(bad[rb], axis=1)  # (Rb,)
                live = np.isfinite(cost[rows_b, :, n_f]) & (known[rows_b, :, n_f] == 0)  # (Rb, S)
                v_i, s_i = np.nonzero(live)
                if v_i.size:
                    rr, nn = rows_b[v_i], n_f[v_i]
                    dn = cell.min_distance(qm[rr, s_i, nn], b2c[pb[rr, 0]])
                    v = dn < cell.clearance
                    known[rr, s_i, nn] = np.where(v, 2, 1)
                    cost[rr[v], s_i[v], nn[v]] = np.inf
            seq[rows_b], now_blocked = self._programme(cost[rows_b], qj[:, :, rows_b])
            hit[rows_b[now_blocked]] = True
            rows = self._checkable(qm, seq, rows_b[~now_blocked])
        else:
            hit[rows] = True  # unreachable (docstring); conservative
        return hit

    def _checkable(self, qm: np.ndarray, seq: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Those of ``rows`` whose sequence is flip-free in float64 and fits the joint limits."""
        if rows.size == 0:
            return rows
        qpath = _unwrap(qm, rows, seq[rows])
        smooth = (np.abs(np.diff(qpath, axis=1)) <= self.max_joint_step).all(axis=(1, 2))
        _, inside = _into_limits(qpath, self.ik.q_min, self.ik.q_max)
        return rows[smooth & inside]


def _neighbour_table(rot: np.ndarray) -> np.ndarray:
    """(S, K) candidate indices allowed to precede each candidate (-1 padded): every candidate
    up to :data:`DENSE_CANDIDATES`, else those within ``DP_NEIGHBOUR_ANGLE_RAD`` at the first
    waypoint (as the warm starts' restricted programme)."""
    S = len(rot)
    if S <= DENSE_CANDIDATES:
        return np.tile(np.arange(S), (S, 1))
    R = rot[:, 0]
    tr = np.einsum("aji,bji->ab", R, R)
    close = np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0)) <= DP_NEIGHBOUR_ANGLE_RAD
    K = int(close.sum(axis=1).max())
    out = -np.ones((S, K), dtype=int)
    for i, row in enumerate(close):
        j = np.flatnonzero(row)
        out[i, : len(j)] = j
    return out


def _viterbi(
    node: np.ndarray, q: np.ndarray, lam: float, max_step: float, nbr: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Cheapest candidate sequences of M independent rows (placement x branch) at once.

    Parameters
    ----------
    node : ndarray (M, S, N)
        Node costs, mm^2 (inf where invalid).
    q : ndarray (6, N, M, S)
        Candidate joint angles, rad, joint-major (any value where the node cost is inf).
    lam : float
        Smoothness weight, mm^2/rad^2.
    max_step : float
        Largest joint step between waypoints, rad.
    nbr : ndarray (S, K)
        Allowed predecessors of each candidate (-1 padded).

    Returns
    -------
    seq : ndarray of int (M, N)
    blocked : ndarray of bool (M,)
        No sequence without a step above ``max_step`` (a flip).

    Notes
    -----
    The transition of candidate ``s'`` at waypoint k to ``s`` at k + 1 costs ``lam * sum_j d_j^2``
    with ``d_j`` the wrapped step of joint j, and is excluded if some ``|d_j| > max_step``.  It is
    computed one joint at a time on (M, S, K) buffers reused across joints and waypoints (the
    working set stays in cache; about five times faster than one (M, S, K, 6) array per step).
    """
    M, S, N = node.shape
    K = nbr.shape[1]
    dtype = q.dtype
    dense = K == S and bool((nbr == np.arange(S)[None, :]).all())
    pidx = np.where(nbr >= 0, nbr, 0)
    pad = nbr < 0  # (S, K) padding slots
    qj = np.ascontiguousarray(q)
    V = node[:, :, 0].copy()
    backs = np.zeros((max(N - 1, 0), M, S), dtype=np.int32)
    two_pi, inv = dtype.type(2.0 * np.pi), dtype.type(0.5 / np.pi)
    lam_, step = dtype.type(lam), dtype.type(max_step)
    cost, worst, d, tmp = (np.empty((M, S, K), dtype) for _ in range(4))
    for k in range(N - 1):
        for j in range(6):
            prev = qj[j, k][:, None, :] if dense else qj[j, k][:, pidx]  # (M, 1|S, K)
            np.subtract(qj[j, k + 1][:, :, None], prev, out=d)
            np.multiply(d, inv, out=tmp)
            np.rint(tmp, out=tmp)
            tmp *= two_pi
            d -= tmp  # wrapped into [-pi, pi]
            if j == 0:
                np.multiply(d, d, out=cost)
                np.abs(d, out=worst)
            else:
                np.multiply(d, d, out=tmp)
                cost += tmp
                np.abs(d, out=d)
                np.maximum(worst, d, out=worst)
        cost *= lam_
        cost += V[:, None, :] if dense else V[:, pidx]
        cost[worst > step] = np.inf
        if not dense:
            cost[:, pad] = np.inf
        jj = np.argmin(cost, axis=2)  # (M, S)
        V = np.take_along_axis(cost, jj[:, :, None], axis=2)[:, :, 0] + node[:, :, k + 1]
        backs[k] = jj if dense else pidx[np.arange(S)[None, :], jj]
    blocked = ~np.isfinite(V).any(axis=1)
    seq = np.zeros((M, N), dtype=np.int64)
    seq[:, -1] = np.argmin(V, axis=1)
    rows = np.arange(M)
    for k in range(N - 1, 0, -1):
        seq[:, k - 1] = backs[k - 1][rows, seq[:, k]]
    return seq, blocked


def _unwrap(q: np.ndarray, rows: np.ndarray, seq: np.ndarray) -> np.ndarray:
    """Continuous joint paths (M', N, 6) of rows ``rows`` (M',) of the candidate angles ``q``
    (M, S, N, 6) along their chosen candidates ``seq`` (M', N) (wrapped differences)."""
    N = seq.shape[1]
    qs = q[rows[:, None], seq, np.arange(N)[None, :]]  # (M', N, 6)
    d = np.diff(qs, axis=1)
    d = (d + np.pi) % (2.0 * np.pi) - np.pi
    return np.concatenate([qs[:, :1], qs[:, :1] + np.cumsum(d, axis=1)], axis=1)


def _into_limits(q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shift each joint of each path (M, N, 6) by the 2 pi k nearest zero that fits its limits.

    Returns the shifted paths and whether every joint of each path fits (M,)."""
    lo, hi = q.min(axis=1), q.max(axis=1)  # (M, 6)
    k_lo = np.ceil((q_min - lo) / (2.0 * np.pi) - _SHIFT_EPS)
    k_hi = np.floor((q_max - hi) / (2.0 * np.pi) + _SHIFT_EPS)
    fits = (k_lo <= k_hi).all(axis=1)
    k = np.minimum(np.maximum(0.0, k_lo), k_hi)
    return q + 2.0 * np.pi * k[:, None, :], fits


__all__ = [
    "PlacementKernel",
    "PlacementStatus",
]
