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

import casadi as ca
import numpy as np

from ..constants import IK_ROUNDTRIP_TOL
from ..errors import InputError
from ..status import CodedStatus
from ..transforms import poe_fk, wrap_angle

#: A chain ``(w (6, 3), p (6, 3) m, M0 (4, 4))`` (see the module docstring).
Chain = tuple[np.ndarray, np.ndarray, np.ndarray]
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
#: LM stops (converged) when the pose error is below this (m and rad).
LM_TOL = 1e-13
#: LM iteration cap of the multi-start.
LM_MAX_ITER = 100
#: Initial LM damping and its bounds (dimensionless; position rows scaled by 1/L).
LM_LAMBDA0, LM_LAMBDA_MIN, LM_LAMBDA_MAX = 1e-3, 1e-12, 1e8
#: Two solutions are one when every wrapped joint difference is below this (rad).
SAME_SOLUTION_TOL = 1e-6
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
#: Tracking cost of a slot that never held a solution (rad; above any wrapped distance).
NEW_SLOT_COST = 100.0
#: Jacobians per zero-copy CasADi evaluation.
JACOBIAN_CHUNK = 64


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


# ----------------------------------------------------------------------------- POE kinematics


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


#: Vectorised POE forward kinematics, q (n, 6) rad -> ``flange2base`` (n, 4, 4).
_fk_np = poe_fk


def arm_length_scale(w: np.ndarray, p: np.ndarray, M0: np.ndarray) -> float:
    """Length scale L (m): ``|p2 - p1| + ... + |p6 - p5| + |o_flange - p6|``.

    Depends on the points chosen on the axes; it only scales tolerances and the guard.
    """
    pts = np.vstack([np.asarray(p, float), np.asarray(M0, float)[:3, 3]])
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def poe_jacobian_sx(w: np.ndarray, p: np.ndarray, M0: np.ndarray, q: ca.SX) -> ca.SX:
    """Geometric Jacobian (6, 6) from the exponentials of the twists, in CasADi.

    At the flange origin, base frame, rows ``[v; omega]`` (the project's convention);
    its determinant does not depend on the reference point or frame.
    """
    T = ca.SX.eye(4)
    cols = []
    for i in range(6):
        K = ca.DM(_skew(w[i]))
        R = ca.DM.eye(3) + ca.sin(q[i]) * K + (1.0 - ca.cos(q[i])) * (K @ K)
        E = ca.vertcat(ca.horzcat(R, (ca.DM.eye(3) - R) @ ca.DM(p[i])), ca.DM([[0, 0, 0, 1]]))
        cols.append((T[:3, :3] @ ca.DM(w[i]), T[:3, :3] @ ca.DM(p[i]) + T[:3, 3]))
        T = T @ E
    o = (T @ ca.DM(M0))[:3, 3]
    return ca.horzcat(*[ca.vertcat(ca.cross(a, o - b), a) for a, b in cols])


_JACOBIAN_CACHE: dict[bytes, ca.Function] = {}


def poe_jacobians(w: np.ndarray, p: np.ndarray, M0: np.ndarray, q: np.ndarray) -> np.ndarray:
    """:func:`poe_jacobian_sx` of the chain ``w, p, M0`` at q (n, 6) rad -> (n, 6, 6).

    A serial map of ``JACOBIAN_CHUNK`` evaluations called through zero-copy buffers
    (measured ~3 us per Jacobian, ~10 us with a plain call and DM conversion).
    """
    key = b"".join(np.ascontiguousarray(a, dtype=float).tobytes() for a in (w, p, M0))
    if key not in _JACOBIAN_CACHE:
        qs = ca.SX.sym("q", 6)
        f = ca.Function("poe_jacobian", [qs], [poe_jacobian_sx(w, p, M0, qs)])
        _JACOBIAN_CACHE[key] = f.map(JACOBIAN_CHUNK, "serial")
    x, y = np.zeros((JACOBIAN_CHUNK, 6)), np.zeros((JACOBIAN_CHUNK, 6, 6))
    buf, trigger = _JACOBIAN_CACHE[key].buffer()
    buf.set_arg(0, memoryview(x))
    buf.set_res(0, memoryview(y))
    out = np.empty((len(q), 6, 6))
    for s in range(0, len(q), JACOBIAN_CHUNK):
        n = min(JACOBIAN_CHUNK, len(q) - s)
        x[:n] = q[s : s + n]
        trigger()
        out[s : s + n] = np.swapaxes(y[:n], 1, 2)  # column-major (6, 6) blocks
    return out


def general_guard_factors(w: np.ndarray, p: np.ndarray, M0: np.ndarray, q: ca.SX | np.ndarray) -> ca.SX | np.ndarray:
    """``det J(q) / L^3``: dimensionless; its sign is a (partial) branch invariant.

    ``J`` is :func:`poe_jacobian_sx` (one CasADi expression for both input types; the
    determinant is ``casadi.det`` symbolically, LU in NumPy numerically).

    Parameters
    ----------
    w, p, M0
        The chain (see :func:`poe_fk`); L is :func:`arm_length_scale`.
    q : casadi.SX, shape (6,), or ndarray, shape (..., 6)
        Joint variables (rad).

    Returns
    -------
    casadi.SX, shape (1,), or ndarray, shape (..., 1)
        Zero exactly at singular configurations; constant in sign along a branch
        that stays away from them.
    """
    w, p, M0 = (np.asarray(a, dtype=float) for a in (w, p, M0))
    L3 = arm_length_scale(w, p, M0) ** 3
    if isinstance(q, ca.SX):
        return ca.det(poe_jacobian_sx(w, p, M0, q)) / L3
    q = np.asarray(q, dtype=float)
    det = np.linalg.det(poe_jacobians(w, p, M0, q.reshape(-1, 6)))
    return (det / L3).reshape(q.shape[:-1] + (1,))


# ----------------------------------------------------------------------------- pose error, LM, labels


def _pose_error(T: np.ndarray, Tt: np.ndarray) -> np.ndarray:
    """(n, 6) ``[p_t - p (m); rotvec(R_t R^T) (rad)]``, base frame."""
    from scipy.spatial.transform import Rotation  # imported on demand (scipy.spatial costs ~0.4 s)

    dR = Tt[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2)
    return np.hstack([Tt[:, :3, 3] - T[:, :3, 3], Rotation.from_matrix(dR).as_rotvec()])


def _residual(e: np.ndarray) -> np.ndarray:
    """(n,) max of position error (m) and rotation angle (rad)."""
    return np.maximum(np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1))


def _levenberg_marquardt(
    chain: Chain, L: float, q0: np.ndarray, Tt: np.ndarray, max_iter: int
) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised LM on the pose error from each start.

    Parameters
    ----------
    chain, L : tuple, float
        ``(w, p, M0)`` and the length scale (m) that divides the position rows.
    q0 : ndarray, shape (n, 6)
        Starts (rad).
    Tt : ndarray, shape (n, 4, 4)
        Target ``flange2base`` of each start.
    max_iter : int
        Iteration cap.

    Returns
    -------
    q : ndarray, shape (n, 6)
        Final joint variables (rad, wrapped).
    residual : ndarray, shape (n,)
        FK residual (max of m and rad) at ``q``.
    """
    q = wrap_angle(q0.astype(float))
    if len(q) == 0:
        return q.reshape(0, 6), np.zeros(0)
    scale = np.array([1 / L] * 3 + [1.0] * 3)
    e = _pose_error(_fk_np(*chain, q), Tt)
    cost = np.sum((e * scale) ** 2, axis=1)
    lam = np.full(len(q), LM_LAMBDA0)
    J, stale = np.empty((len(q), 6, 6)), np.ones(len(q), dtype=bool)
    active = _residual(e) > LM_TOL
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        need = idx[stale[idx]]
        J[need], stale[need] = poe_jacobians(*chain, q[need]), False
        Js = J[idx] * scale[None, :, None]
        A = np.swapaxes(Js, 1, 2) @ Js + lam[idx, None, None] * np.eye(6)
        g = np.einsum("nji,nj->ni", Js, e[idx] * scale)
        q_new = wrap_angle(q[idx] + np.linalg.solve(A, g[..., None])[..., 0])
        e_new = _pose_error(_fk_np(*chain, q_new), Tt[idx])
        cost_new = np.sum((e_new * scale) ** 2, axis=1)
        ok = cost_new < cost[idx]
        acc = idx[ok]
        q[acc], e[acc], cost[acc], stale[acc] = q_new[ok], e_new[ok], cost_new[ok], True
        lam[acc] = np.maximum(lam[acc] / 3.0, LM_LAMBDA_MIN)
        lam[idx[~ok]] *= 4.0
        active[idx] = (_residual(e[idx]) > LM_TOL) & (lam[idx] < LM_LAMBDA_MAX)
    return q, _residual(e)


def _wrapped_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Max-abs wrapped joint difference (rad), broadcasting over leading axes."""
    return np.max(np.abs(wrap_angle(a - b)), axis=-1)


def _merge(q: np.ndarray, res: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct solutions among ``q`` (m, 6), lowest residual first within a cluster.

    Returns the representatives (k, 6) and how many entries each absorbed (k,).
    """
    order = np.argsort(res, kind="stable")
    reps, counts = [], []
    for i in order:
        if reps:
            d = _wrapped_distance(np.asarray(reps), q[i])
            j = int(np.argmin(d))
            if d[j] < SAME_SOLUTION_TOL:
                counts[j] += 1
                continue
        reps.append(q[i])
        counts.append(1)
    return np.asarray(reps).reshape(-1, 6), np.asarray(counts, dtype=int)


def _pad(rows: list[np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray]:
    """Stack ``n`` arrays (m_i, 6) into (n, max m_i, 6) (NaN padded) and the (n, max m_i) mask."""
    m = np.array([len(r) for r in rows] + [0] * (n - len(rows)), dtype=int)
    mask = np.arange(max(int(m.max(initial=0)), 1))[None, :] < m[:, None]
    out = np.full(mask.shape + (6,), np.nan)
    if m.sum():
        out[mask] = np.vstack([r for r in rows if len(r)])
    return out, mask


def _track(solutions: list[np.ndarray], K: int) -> list[np.ndarray]:
    """Slot of every solution at every pose: nearest last-known solution of a slot.

    ``solutions[i]`` is (m_i, 6), m_i <= K; returns a list of (m_i,) int slot indices.
    """
    from scipy.optimize import linear_sum_assignment  # imported on demand (as scipy.stats below)

    last, used, out = np.zeros((K, 6)), np.zeros(K, dtype=bool), []
    for S in solutions:
        if len(S) == 0:
            out.append(np.zeros(0, dtype=int))
            continue
        diff = np.mod(S[:, None, :] - last[None, :, :] + np.pi, 2.0 * np.pi) - np.pi
        cost = np.sqrt(np.sum(diff * diff, axis=2))
        cost[:, ~used] = NEW_SLOT_COST + 1e-3 * np.arange(K)[~used]
        rows, cols = linear_sum_assignment(cost)
        slots = np.empty(len(S), dtype=int)
        slots[rows] = cols
        last[cols] = S[rows]
        used[cols] = True
        out.append(slots)
    return out


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
        sols, _, _ = self._solve_eaik(_fk_np(*self._chain, q))
        for qi, s in zip(q, sols):
            if len(s) == 0 or _wrapped_distance(s, qi[None, :]).min() > SELF_CHECK_TOL:
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
        cand, mask = _pad([np.asarray(s.Q, dtype=float).reshape(-1, 6) * self._sign for s in raw], len(T))
        owner = np.nonzero(mask)[0]
        flat = cand[mask]
        near = _residual(_pose_error(_fk_np(*self._chain, flat), T[owner])) <= EAIK_CANDIDATE_TOL
        flat[near], res = _levenberg_marquardt(
            self._chain, self.length_scale, flat[near], T[owner[near]], POLISH_MAX_ITER
        )
        good = np.zeros(len(flat), dtype=bool)
        good[np.flatnonzero(near)[res <= IK_ROUNDTRIP_TOL]] = True
        cand[mask], ok = flat, np.zeros_like(mask)
        ok[mask] = good
        sol, smask = _pad([cand[i, ok[i]] for i in range(len(T))], len(T))
        # a solution equal (mod 2 pi) to an earlier one of the same pose is a duplicate
        d = _wrapped_distance(sol[:, :, None, :], sol[:, None, :, :])
        earlier = np.tril(np.ones((sol.shape[1],) * 2, dtype=bool), -1)
        keep = smask & ~np.any((d < SAME_SOLUTION_TOL) & earlier & smask[:, None, :], axis=2)
        sols = [sol[i, keep[i]][: self.n_branches] for i in range(len(T))]
        return sols, [np.zeros(len(s), dtype=int) for s in sols], keep.sum(axis=1).tolist()

    def _solve_numeric(self, T: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray], list[int]]:
        """Distinct converged LM solutions per pose (lexicographic), their start counts and
        how many were found before the cut to ``n_branches``."""
        n, n0 = len(T), len(self.starts)
        q, res = _levenberg_marquardt(
            self._chain, self.length_scale, np.tile(self.starts, (n, 1)), np.repeat(T, n0, axis=0), LM_MAX_ITER
        )
        q, res = q.reshape(n, n0, 6), res.reshape(n, n0)
        sols, counts, found = [], [], []
        for i in range(n):
            ok = res[i] <= IK_ROUNDTRIP_TOL
            reps, cnt = _merge(q[i, ok], res[i, ok])
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
        slots = _track(sols, K) if track else [np.arange(len(s)) for s in sols]
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
