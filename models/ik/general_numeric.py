"""The numeric pieces of the general 6R solver (:mod:`models.ik.general_solver`).

Product-of-exponentials kinematics (:func:`poe_jacobian_sx`, :func:`poe_jacobians`, the arm's
length scale and the branch guard factors :func:`general_guard_factors`), the 6-D pose error and
its damped least squares (:func:`levenberg_marquardt`), and the bookkeeping of solutions: merging
duplicates (:func:`merge_solutions`), padding to the branch slots (:func:`pad_solutions`) and
tracking the slots along a path (:func:`track_solutions`).
"""

from __future__ import annotations


import casadi as ca
import numpy as np

from ..transforms import poe_fk, wrap_angle

#: A chain ``(w (6, 3), p (6, 3) m, M0 (4, 4))`` (see the module docstring).
Chain = tuple[np.ndarray, np.ndarray, np.ndarray]
#: Initial LM damping and its bounds (dimensionless; position rows scaled by 1/L).
LM_LAMBDA0, LM_LAMBDA_MIN, LM_LAMBDA_MAX = 1e-3, 1e-12, 1e8
#: Two solutions are one when every wrapped joint difference is below this (rad).
SAME_SOLUTION_TOL = 1e-6
#: Tracking cost of a slot that never held a solution (rad; above any wrapped distance).
NEW_SLOT_COST = 100.0
#: Jacobians per zero-copy CasADi evaluation.
JACOBIAN_CHUNK = 64
#: LM stops (converged) when the pose error is below this (m and rad).
LM_TOL = 1e-13


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


def pose_error(T: np.ndarray, Tt: np.ndarray) -> np.ndarray:
    """(n, 6) ``[p_t - p (m); rotvec(R_t R^T) (rad)]``, base frame."""
    from scipy.spatial.transform import Rotation  # imported on demand (scipy.spatial costs ~0.4 s)

    dR = Tt[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2)
    return np.hstack([Tt[:, :3, 3] - T[:, :3, 3], Rotation.from_matrix(dR).as_rotvec()])


def pose_residual(e: np.ndarray) -> np.ndarray:
    """(n,) max of position error (m) and rotation angle (rad)."""
    return np.maximum(np.linalg.norm(e[:, :3], axis=1), np.linalg.norm(e[:, 3:], axis=1))


def levenberg_marquardt(
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
    e = pose_error(_fk_np(*chain, q), Tt)
    cost = np.sum((e * scale) ** 2, axis=1)
    lam = np.full(len(q), LM_LAMBDA0)
    J, stale = np.empty((len(q), 6, 6)), np.ones(len(q), dtype=bool)
    active = pose_residual(e) > LM_TOL
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
        e_new = pose_error(_fk_np(*chain, q_new), Tt[idx])
        cost_new = np.sum((e_new * scale) ** 2, axis=1)
        ok = cost_new < cost[idx]
        acc = idx[ok]
        q[acc], e[acc], cost[acc], stale[acc] = q_new[ok], e_new[ok], cost_new[ok], True
        lam[acc] = np.maximum(lam[acc] / 3.0, LM_LAMBDA_MIN)
        lam[idx[~ok]] *= 4.0
        active[idx] = (pose_residual(e[idx]) > LM_TOL) & (lam[idx] < LM_LAMBDA_MAX)
    return q, pose_residual(e)


def wrapped_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Max-abs wrapped joint difference (rad), broadcasting over leading axes."""
    return np.max(np.abs(wrap_angle(a - b)), axis=-1)


def merge_solutions(q: np.ndarray, res: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct solutions among ``q`` (m, 6), lowest residual first within a cluster.

    Returns the representatives (k, 6) and how many entries each absorbed (k,).
    """
    order = np.argsort(res, kind="stable")
    reps, counts = [], []
    for i in order:
        if reps:
            d = wrapped_distance(np.asarray(reps), q[i])
            j = int(np.argmin(d))
            if d[j] < SAME_SOLUTION_TOL:
                counts[j] += 1
                continue
        reps.append(q[i])
        counts.append(1)
    return np.asarray(reps).reshape(-1, 6), np.asarray(counts, dtype=int)


def pad_solutions(rows: list[np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray]:
    """Stack ``n`` arrays (m_i, 6) into (n, max m_i, 6) (NaN padded) and the (n, max m_i) mask."""
    m = np.array([len(r) for r in rows] + [0] * (n - len(rows)), dtype=int)
    mask = np.arange(max(int(m.max(initial=0)), 1))[None, :] < m[:, None]
    out = np.full(mask.shape + (6,), np.nan)
    if m.sum():
        out[mask] = np.vstack([r for r in rows if len(r)])
    return out, mask


def track_solutions(solutions: list[np.ndarray], K: int) -> list[np.ndarray]:
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
