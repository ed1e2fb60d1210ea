"""Inverse kinematics of a general 6R arm (not UR-type, not OPW): every branch.

The chain is given as a product of exponentials at ``q = 0``: ``w`` (6, 3) unit joint
axes and ``p`` (6, 3) one point on each axis, both in the base frame (joint i turns
positively about ``w_i``), and ``M0`` (4, 4) ``flange2base`` at ``q = 0``::

    T(q) = exp([S1] q1) ... exp([S6] q6) M0,   S_i = (w_i, -w_i x p_i).

Two methods, chosen once per arm by :class:`GeneralIK`:

``"eaik"`` -- closed form by subproblem decomposition (EAIK 1.2.2) when
``hasKnownDecomposition()`` is true.  What EAIK expects and returns (read from its
source and measured):

* H-P convention: ``H`` (6, 3) the joint axes at ``q = 0`` (base frame) and ``P`` (7, 3)
  the offsets ``P[0] = p_1``, ``P[i] = p_{i+1} - p_i``, ``P[6] = o_flange - p_6``; its
  FK ``p = P0 + sum_i R_{0i} P_i`` with ``R_{0i} = prod_j rot(h_j, q_j)`` is exactly the POE
  above.  ``HPRobot`` fixes the flange orientation at ``q = 0`` to the identity, so the
  targets are passed as ``T diag(R0^T, 1)`` (``R0 = M0[:3, :3]``).  Parallelism and
  intersection are decided with absolute thresholds (~1e-8, in m where a length).
* Per pose it returns a *variable* number of candidates (family dependent; measured
  3 to 32): every two-solution subproblem (SP3, SP4) collapses to one least-squares
  candidate when it has no real solution, and SP5 yields 4 candidates per real root of
  its quartic, most of them spurious.  ``is_LS`` marks least-squares candidates but is
  not reliable: in the ``SPHERICAL_NO_PARALLEL_NO_INTERSECTING`` family (SP5) every
  candidate is flagged, the exact ones included.  Here a candidate is a solution iff
  its FK residual (max of position error in m and rotation angle in rad) is at most
  ``IK_ROUNDTRIP_TOL`` after at most ``POLISH_MAX_ITER`` Levenberg-Marquardt steps
  (from every candidate within ``EAIK_CANDIDATE_TOL``: at an exactly singular wrist
  EAIK returns the singular branch as a least-squares candidate with q4 + q6 split
  wrongly, 0.2 rad off in a test, and the steps recover it); duplicates are merged.
  At most ``EAIK_MAX_BRANCHES`` = 8 distinct solutions exist for every family EAIK
  knows (spherical wrist: <= 4 position solutions x 2; three consecutive parallel
  axes: <= 8), measured: 2, 4, 6 or 8.
* Order: the index is the formula branch (the fixed +/- order of SP3/SP4) only while
  every subproblem has two real solutions; a collapse shifts every later index, and the
  roots of SP5/SP6 come in no fixed order.  Along smooth paths (400 poses, <= 0.01 rad
  per step) the index jumped by > 0.1 rad between consecutive poses 32-48 times on
  three of six paths of the SP6 arm, even with a constant count, and after a count
  change on the SP3/SP2 arm.  So the order is NOT stable: the solutions are *tracked*.
* Throughput (2 shared cores, 20 000 poses): ``IK_batched`` 0.27 M poses/s (SP3/SP2
  arm) and 0.1 M/s (SP6 arm), 1 to 8 threads within noise, a Python loop over ``IK``
  0.22 and 0.09 M/s.  The FK check, polish, dedupe, guard and tracking here dominate:
  ``solve`` runs 5-7 k poses/s (7-9 k with ``track=False``).

``"numeric"`` -- otherwise: damped least squares (Levenberg-Marquardt on the 6-D pose
error, position scaled by the arm length, with the POE Jacobian) from
``NUMERIC_N_STARTS`` fixed Sobol starts; solutions reproducing the target to
``IK_ROUNDTRIP_TOL`` are merged when their wrapped joint distance is below
``SAME_SOLUTION_TOL`` and ordered lexicographically.  ``complete`` is False: a general
6R arm has up to 16 solutions and fewer found cannot be proven complete (an odd count
at a regular pose proves a miss: the note says so).  The number of starts that
converged to each solution is returned (``n_starts``).  Measured on 100 random poses
of a general arm: 128 starts found the same sets as 512 (64 missed 3 solutions); on
the EAIK arms it finds exactly EAIK's sets; 30-50 poses/s.

Labels ``b1 .. bK`` (``K = n_branches``: 8 for EAIK, 16 numeric).  With ``track=True``
(default) the poses are a sequence: at the first pose the slots take the solutions in
the method's order; at every later pose each solution takes the slot whose last known
solution is nearest (wrapped joint distance, one-to-one assignment), a slot never used
costing ``NEW_SLOT_COST``.  Branch ``k`` thus moves continuously along a smooth path
away from singularities, where two branches meet and may swap.  With ``track=False``
every pose is labelled on its own (method order).

Status (:class:`GeneralIKStatus`; :mod:`models.ik.general` maps it): 0 OK; 3
singular, ``|det J| / L^3 < SINGULAR_DET_TOL`` (q given); 4 no solution in that slot
(EAIK least-squares only, LM not converged, or fewer branches; q NaN).  Every non-NaN q
reproduces the target to ``IK_ROUNDTRIP_TOL``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..constants import IK_ROUNDTRIP_TOL
from ..errors import InputError
from ..status import CodedStatus
from ..transforms import poe_fk, wrap_angle
from .general_numeric import (
    SAME_SOLUTION_TOL,
    Chain,
    arm_length_scale,
    general_guard_factors,
    levenberg_marquardt,
    merge_solutions,
    pad_solutions,
    pose_error,
    pose_residual,
    track_solutions,
    wrapped_distance,
)

#: Distinct solutions of every 6R family EAIK decomposes (dimensionless count).
EAIK_MAX_BRANCHES = 8
#: Upper bound on the real IK solutions of a general 6R arm.
NUMERIC_MAX_BRANCHES = 16
#: Deterministic starts of the numeric multi-start (a power of 2: Sobol balance).
NUMERIC_N_STARTS = 128
#: Worker threads of EAIK's batched IK (measured best of 1, 2, 4, 8 on 2 cores).
EAIK_THREADS = 4
#: Poses per EAIK call (bounds the memory of the duplicate check).
EAIK_BLOCK = 4096
#: Poses per multi-start batch (bounds the memory: NUMERIC_BLOCK * NUMERIC_N_STARTS configurations).
NUMERIC_BLOCK = 32
#: EAIK candidates (least-squares ones included) with an FK residual below this (max of m
#: and rad) get POLISH_MAX_ITER LM steps; this recovers the branch EAIK returns as
#: least-squares at an exactly singular wrist (q4 + q6 split wrongly).  Others are dropped.
EAIK_CANDIDATE_TOL = 1.0
#: LM iterations polishing an EAIK candidate.
POLISH_MAX_ITER = 5
#: LM iteration cap of the multi-start.
LM_MAX_ITER = 100
#: |det J| / L^3 below this: the solution is reported singular (dimensionless).
SINGULAR_DET_TOL = 1e-7
#: Tolerance on |w_i| = 1 and on the rotation part of M0 (dimensionless).
UNIT_TOL = 1e-9
#: Axes closer to parallel than this (sine of the angle) are turned to point the same way for EAIK.
PARALLEL_SIGN_TOL = 1e-8
#: EAIK must find the configuration of FK(q) for this many fixed pseudo-random q ...
SELF_CHECK_POSES = 16
#: ... to this (rad, modulo 2 pi), else the numeric multi-start is used.
SELF_CHECK_TOL = 1e-6


class GeneralIKStatus(CodedStatus):
    """Per-slot status of :class:`GeneralIKResult` (``code`` is the integer of its array)."""

    OK = "ok", 0
    SINGULAR = "singular", 3  # solution at |det J| / L^3 < SINGULAR_DET_TOL
    UNREACHABLE = "unreachable", 4  # no solution in this slot (q is NaN)


@dataclass(frozen=True)
class GeneralIKResult:
    """All branches for N target poses.

    Attributes
    ----------
    q : ndarray, shape (N, K, 6)
        Joint variables (rad) wrapped to (-pi, pi]; NaN where the slot has no solution.
    status : ndarray of int, shape (N, K)
        :attr:`GeneralIKStatus.code` per slot.
    guard : ndarray, shape (N, K)
        :func:`general_guard_factors` at each solution (dimensionless); NaN where absent.
    method : str
        ``"eaik"`` or ``"numeric"``.
    complete : bool
        True when the method enumerates every branch by construction (EAIK).
    note : str
        What the method guarantees and what it may have missed.
    labels : tuple of str
        ``("b1", ..., "bK")``.
    n_starts : ndarray of int, shape (N, K), or None
        Numeric method: starts that converged to each solution (0 where absent).
    """

    q: np.ndarray
    status: np.ndarray
    guard: np.ndarray
    method: str
    complete: bool
    note: str
    labels: tuple[str, ...]
    n_starts: np.ndarray | None = None

    @property
    def valid(self) -> np.ndarray:
        """(N, K) bool: the slot holds a regular solution."""
        return self.status == GeneralIKStatus.OK.code


# ----------------------------------------------------------------------------- the solver


def _hp_parameters(w: np.ndarray, p: np.ndarray, M0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """EAIK's H (6, 3) and P (7, 3) of the POE chain (see the module docstring)."""
    P = np.vstack([p[:1], np.diff(p, axis=0), M0[None, :3, 3] - p[5:6]])
    return w.copy(), P


def _parallel_signs(w: np.ndarray) -> np.ndarray:
    """+1 / -1 per axis so that every axis parallel to an earlier one points the same way."""
    sign = np.ones(6)
    for i in range(6):
        for j in range(i):
            if np.linalg.norm(np.cross(w[i], w[j])) < PARALLEL_SIGN_TOL:
                sign[i] = sign[j] * (1.0 if float(w[i] @ w[j]) > 0 else -1.0)
                break
    return sign


def _validated_chain(w: np.ndarray, p: np.ndarray, M0: np.ndarray) -> Chain:
    w, p, M0 = (np.asarray(a, dtype=float) for a in (w, p, M0))
    if w.shape != (6, 3) or p.shape != (6, 3) or M0.shape != (4, 4):
        raise InputError(f"GeneralIK: expected w (6, 3), p (6, 3), M0 (4, 4); got {w.shape}, {p.shape}, {M0.shape}")
    if not (np.isfinite(w).all() and np.isfinite(p).all() and np.isfinite(M0).all()):
        raise InputError("GeneralIK: w, p and M0 must be finite")
    if np.abs(np.linalg.norm(w, axis=1) - 1.0).max() > UNIT_TOL:
        raise InputError(f"GeneralIK: joint axes w must be unit vectors (tolerance {UNIT_TOL})")
    R0 = M0[:3, :3]
    if np.abs(R0.T @ R0 - np.eye(3)).max() > UNIT_TOL or np.linalg.det(R0) < 0:
        raise InputError("GeneralIK: M0[:3, :3] must be a rotation matrix")
    return w, p, M0


class GeneralIK:
    """All IK branches of a 6R arm given as a POE chain (see the module docstring).

    Parameters
    ----------
    w : ndarray, shape (6, 3)
        Unit joint axes, base frame, at q = 0.
    p : ndarray, shape (6, 3)
        A point on each axis, base frame (m).
    M0 : ndarray, shape (4, 4)
        ``flange2base`` at q = 0.
    method : {"auto", "numeric"}
        ``"auto"``: EAIK when it knows a decomposition; ``"numeric"`` forces the
        multi-start (e.g. to cross-check EAIK).

    Attributes
    ----------
    kind, method : str
        ``"eaik"`` or ``"numeric"`` (the same; ``kind`` names the solver family).
    family : str
        EAIK's kinematic family of the chain (``"6R-Unknown Kinematic Class"``: none).
    n_branches : int
        Slots K per pose.
    labels : tuple of str
        ``("b1", ..., "bK")``.
    length_scale : float
        :func:`arm_length_scale` (m).
    """

    def __init__(self, w: np.ndarray, p: np.ndarray, M0: np.ndarray, method: str = "auto") -> None:
        from eaik.IK_HP import HPRobot

        if method not in ("auto", "numeric"):
            raise InputError(f"GeneralIK: method must be 'auto' or 'numeric', got {method!r}")
        self.w, self.p, self.M0 = _validated_chain(w, p, M0)
        self._chain = (self.w, self.p, self.M0)
        self.length_scale = arm_length_scale(self.w, self.p, self.M0)
        if self.length_scale <= 0.0:
            raise InputError("GeneralIK: the axis points and the flange all coincide")
        # EAIK's decompositions assume parallel axes point the same way: hand it the chain with
        # such axes turned to agree (q_i -> -q_i), and turn its solutions back
        self._sign = _parallel_signs(self.w)
        try:
            self._eaik = HPRobot(*_hp_parameters(self.w * self._sign[:, None], self.p, self.M0))
            self.family: str = self._eaik.getKinematicFamily()
            known = self._eaik.hasKnownDecomposition()
        except RuntimeError as exc:  # EAIK refuses some degenerate chains
            self.family, known = f"6R-Unknown Kinematic Class (EAIK: {exc})", False
        self.method = self.kind = "eaik" if known and method == "auto" else "numeric"
        self.n_branches = EAIK_MAX_BRANCHES
        if self.method == "eaik" and not self._eaik_finds_its_own_poses():
            self.family += " (EAIK missed known solutions in the self-check: numeric multi-start used)"
            self.method = self.kind = "numeric"
        self.n_branches = EAIK_MAX_BRANCHES if self.method == "eaik" else NUMERIC_MAX_BRANCHES
        self.labels = tuple(f"b{k + 1}" for k in range(self.n_branches))
        from scipy.stats import qmc  # imported on demand: scipy.stats costs ~0.6 s at import

        u = qmc.Sobol(6, scramble=False).random(NUMERIC_N_STARTS) + 0.5 / NUMERIC_N_STARTS
        self.starts = wrap_angle(2.0 * np.pi * (u % 1.0) - np.pi)

    def _eaik_finds_its_own_poses(self) -> bool:
        """Whether EAIK finds the configuration of FK(q) for every one of SELF_CHECK_POSES
        fixed pseudo-random q (a guard against a decomposition that does not fit the chain)."""
        q = np.random.default_rng(0).uniform(-np.pi, np.pi, (SELF_CHECK_POSES, 6))
        sols, _, _ = self._solve_eaik(poe_fk(*self._chain, q))
        for qi, s in zip(q, sols):
            if len(s) == 0 or wrapped_distance(s, qi[None, :]).min() > SELF_CHECK_TOL:
                return False
        return True

    def solve(self, flange2base: np.ndarray, track: bool = True) -> GeneralIKResult:
        """Every branch for each target.

        Parameters
        ----------
        flange2base : ndarray, shape (N, 4, 4) or (4, 4)
            Target flange poses, base frame (m).
        track : bool
            Label by continuity along the sequence of poses (True) or per pose.

        Returns
        -------
        GeneralIKResult
        """
        T = np.asarray(flange2base, dtype=float)
        T = T[None] if T.shape == (4, 4) else T
        if T.ndim != 3 or T.shape[1:] != (4, 4) or not np.isfinite(T).all():
            raise InputError(f"GeneralIK.solve: expected finite (N, 4, 4) poses, got {T.shape}")
        block, one = (EAIK_BLOCK, self._solve_eaik) if self.method == "eaik" else (NUMERIC_BLOCK, self._solve_numeric)
        sols, counts, found = [], [], []  # per pose: solutions, start counts, number found
        for b in range(0, len(T), block):
            s, c, f = one(T[b : b + block])
            sols, counts, found = sols + s, counts + c, found + f
        return self._assemble(sols, counts, np.array(found, dtype=int), track)

    def _solve_eaik(self, T: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray], list[int]]:
        """Distinct exact solutions (m_i, 6) per pose in EAIK's order, no start counts, and
        how many were found before the cut to ``n_branches``."""
        Tq = T.copy()
        Tq[:, :3, :3] = T[:, :3, :3] @ self.M0[:3, :3].T  # HPRobot's flange is I at q = 0
        raw = self._eaik.IK_batched(Tq, EAIK_THREADS) if len(T) else []
        cand, mask = pad_solutions([np.asarray(s.Q, dtype=float).reshape(-1, 6) * self._sign for s in raw], len(T))
        owner = np.nonzero(mask)[0]
        flat = cand[mask]
        near = pose_residual(pose_error(poe_fk(*self._chain, flat), T[owner])) <= EAIK_CANDIDATE_TOL
        flat[near], res = levenberg_marquardt(
            self._chain, self.length_scale, flat[near], T[owner[near]], POLISH_MAX_ITER
        )
        good = np.zeros(len(flat), dtype=bool)
        good[np.flatnonzero(near)[res <= IK_ROUNDTRIP_TOL]] = True
        cand[mask], ok = flat, np.zeros_like(mask)
        ok[mask] = good
        sol, smask = pad_solutions([cand[i, ok[i]] for i in range(len(T))], len(T))
        # a solution equal (mod 2 pi) to an earlier one of the same pose is a duplicate
        d = wrapped_distance(sol[:, :, None, :], sol[:, None, :, :])
        earlier = np.tril(np.ones((sol.shape[1],) * 2, dtype=bool), -1)
        keep = smask & ~np.any((d < SAME_SOLUTION_TOL) & earlier & smask[:, None, :], axis=2)
        sols = [sol[i, keep[i]][: self.n_branches] for i in range(len(T))]
        return sols, [np.zeros(len(s), dtype=int) for s in sols], keep.sum(axis=1).tolist()

    def _solve_numeric(self, T: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray], list[int]]:
        """Distinct converged LM solutions per pose (lexicographic), their start counts and
        how many were found before the cut to ``n_branches``."""
        n, n0 = len(T), len(self.starts)
        q, res = levenberg_marquardt(
            self._chain, self.length_scale, np.tile(self.starts, (n, 1)), np.repeat(T, n0, axis=0), LM_MAX_ITER
        )
        q, res = q.reshape(n, n0, 6), res.reshape(n, n0)
        sols, counts, found = [], [], []
        for i in range(n):
            ok = res[i] <= IK_ROUNDTRIP_TOL
            reps, cnt = merge_solutions(q[i, ok], res[i, ok])
            keep = np.argsort(-cnt, kind="stable")[: self.n_branches]  # most starts if too many
            order = keep[np.lexsort(reps[keep].T[::-1])]
            sols.append(reps[order])
            counts.append(cnt[order])
            found.append(len(reps))
        return sols, counts, found

    def _note(self, status: np.ndarray, found: np.ndarray) -> str:
        """What the result guarantees; ``found`` (N,) distinct solutions before any cut."""
        cut = int(np.sum(found > self.n_branches))
        if self.method == "eaik":
            note = (
                f"closed form (EAIK, {self.family}): every branch by subproblem decomposition; "
                f"solutions verified by FK residual <= {IK_ROUNDTRIP_TOL:g}"
            )
        else:
            note = (
                f"numeric multi-start ({NUMERIC_N_STARTS} Sobol starts, Levenberg-Marquardt): "
                f"may have missed a branch; a 6R arm has up to {NUMERIC_MAX_BRANCHES} solutions "
                "and fewer found cannot be proven complete"
            )
            regular = np.sum(status == GeneralIKStatus.OK.code, axis=1)
            singular = np.any(status == GeneralIKStatus.SINGULAR.code, axis=1)
            odd = int(np.sum((regular % 2 == 1) & ~singular))
            if odd:
                note += (
                    f"; {odd} pose(s) have an odd number of regular solutions, so a branch was certainly missed there"
                )
        if cut:
            note += f"; {cut} pose(s) had more than {self.n_branches} distinct solutions (singular?)"
        return note

    def _assemble(
        self, sols: list[np.ndarray], counts: list[np.ndarray], found: np.ndarray, track: bool
    ) -> GeneralIKResult:
        """Place the solutions in slots, add the guard, the status and the note."""
        N, K = len(sols), self.n_branches
        numeric = self.method == "numeric"
        slots = track_solutions(sols, K) if track else [np.arange(len(s)) for s in sols]
        q = np.full((N, K, 6), np.nan)
        n_starts = np.zeros((N, K), dtype=int)
        for i, (s, k) in enumerate(zip(sols, slots)):
            q[i, k] = s
            n_starts[i, k] = counts[i]
        q = wrap_angle(q)
        present = ~np.isnan(q[..., 0])
        guard = np.full((N, K), np.nan)
        guard[present] = general_guard_factors(*self._chain, q[present])[:, 0]
        status = np.full((N, K), GeneralIKStatus.UNREACHABLE.code)
        status[present] = np.where(
            np.abs(guard[present]) < SINGULAR_DET_TOL, GeneralIKStatus.SINGULAR.code, GeneralIKStatus.OK.code
        )
        return GeneralIKResult(
            q=q,
            status=status,
            guard=guard,
            method=self.method,
            complete=not numeric,
            note=self._note(status, found),
            labels=self.labels,
            n_starts=n_starts if numeric else None,
        )
