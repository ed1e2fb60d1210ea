"""The greedy selection of a campaign design with exchange (:mod:`.design`'s algebra).

Rank-3 Sherman-Morrison-Woodbury updates of the posterior covariance, vectorised over the pool
(:func:`greedy_gains`), the greedy choice and its Fedorov exchange passes (:func:`select_greedy`),
and the per-pose predicted sigma of a posterior (:func:`sigma_rms`).  All in the design's scaled
parameters.
"""

from __future__ import annotations

import numpy as np

#: Fedorov exchange passes after the greedy selection (each costs about ``n`` greedy steps).
EXCHANGE_PASSES = 2
#: An exchange is made only when it gains more than this fraction of the criterion's value.
EXCHANGE_REL_GAIN = 1e-9


def _solve3(S: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``S^-1 B`` for a stack of 3x3 systems."""
    return np.linalg.solve(S, B)


def greedy_gains(
    P: np.ndarray, Jc: np.ndarray, s2: float, criterion: str, M: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gain of adding each candidate row to a posterior covariance ``P``.

    Parameters
    ----------
    P : ndarray, shape (p, p)
        Posterior covariance (design's scaled parameters).
    Jc : ndarray, shape (N, 3, p)
        Candidate rows' Jacobians.
    s2 : float
        Noise variance per axis of a new row.
    criterion : {"task", "d"}
    M : ndarray, shape (p, p)
        ``mean_e J_e^T J_e`` (task criterion).

    Returns
    -------
    gain : ndarray, shape (N,)
        ``task``: reduction of ``trace(M P)``, ``trace(S^-1 A M A^T)``; ``d``: increase of
        ``log det`` of the information, ``log det(S / s2)``.
    A : ndarray, shape (N, 3, p)
        ``J_i P``.
    S : ndarray, shape (N, 3, 3)
        ``s2 I + A_i J_i^T``.
    """
    A = Jc @ P
    S = s2 * np.eye(3) + A @ np.swapaxes(Jc, 1, 2)
    if criterion == "task":
        assert M is not None
        T = (A @ M) @ np.swapaxes(A, 1, 2)
        gain = np.trace(_solve3(S, T), axis1=1, axis2=2)
    else:
        _sign, ld = np.linalg.slogdet(S)
        gain = ld - 3.0 * np.log(s2)
    return gain, A, S


def _add(P: np.ndarray, A: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Posterior after adding a row: ``P - A^T S^-1 A`` (symmetrised)."""
    P = P - A.T @ np.linalg.solve(S, A)
    return 0.5 * (P + P.T)


def _remove(P: np.ndarray, J: np.ndarray, s2: float) -> np.ndarray:
    """Posterior after removing a row of Jacobian ``J`` (3, p): ``P + A^T (s2 I - A J^T)^-1 A``."""
    A = J @ P
    S = s2 * np.eye(3) - A @ J.T
    P = P + A.T @ np.linalg.solve(S, A)
    return 0.5 * (P + P.T)


def inv_spd(I: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive definite matrix (Cholesky), symmetrised."""
    L = np.linalg.cholesky(I)
    Li = np.linalg.solve(L, np.eye(len(I)))
    return Li.T @ Li


def select_greedy(
    P0: np.ndarray,
    Jc: np.ndarray,
    n: int,
    s2: float,
    criterion: str,
    M: np.ndarray | None = None,
    exchange_passes: int = EXCHANGE_PASSES,
) -> tuple[np.ndarray, np.ndarray]:
    """Greedy choice of ``n`` candidate rows (then Fedorov exchange passes).

    Returns the chosen indices into ``Jc`` (in the order chosen; exchanged rows take the place of
    those they replace) and the posterior covariance after them.
    """
    N = len(Jc)
    avail = np.ones(N, dtype=bool)
    chosen: list[int] = []
    P = P0.copy()
    for _ in range(n):
        idx = np.flatnonzero(avail)
        gain, A, S = greedy_gains(P, Jc[idx], s2, criterion, M)
        b = int(np.argmax(gain))
        i = int(idx[b])
        P = _add(P, A[b], S[b])
        chosen.append(i)
        avail[i] = False
    for _ in range(exchange_passes):
        changed = False
        for pos in range(len(chosen)):
            j = chosen[pos]
            Pm = _remove(P, Jc[j], s2)
            idx = np.append(np.flatnonzero(avail), j)
            gain, A, S = greedy_gains(Pm, Jc[idx], s2, criterion, M)
            b = int(np.argmax(gain))
            scale = abs(float(gain[-1])) + 1e-300
            if idx[b] != j and gain[b] - gain[-1] > EXCHANGE_REL_GAIN * scale:
                i = int(idx[b])
                avail[i], avail[j] = False, True
                chosen[pos] = i
                P = _add(Pm, A[b], S[b])
                changed = True
        if not changed:
            break
    return np.array(chosen, dtype=int), P


def sigma_rms(Je: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Per pose: ``sqrt(trace(J_e P J_e^T) / 3)``."""
    v = np.einsum("nik,kl,nil->n", Je, P, Je)
    return np.sqrt(np.maximum(v, 0.0) / 3.0)
