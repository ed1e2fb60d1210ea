"""The order of visiting a campaign's configurations: shortest travel at the joint velocity limits.

Nearest neighbour (from several starts) and the given order, each improved by 2-opt on an open path,
on the time metric ``max_j |dq_j| / v_max_j`` (the slowest joint at its velocity limit; no
acceleration); the shortest wins, so the result is never longer than the given order.
"""

from __future__ import annotations

import numpy as np

#: Travel order: nearest-neighbour starts tried (each chosen row up to this many), and 2-opt passes.
TRAVEL_NN_STARTS = 50
TRAVEL_2OPT_PASSES = 50


def travel_times(q: np.ndarray, v_max: np.ndarray) -> np.ndarray:
    """Pairwise move times ``max_j |q_a,j - q_b,j| / v_max_j``, s, shape (N, N)."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v_max, dtype=float)
    D = np.zeros((len(q), len(q)))
    for j in range(q.shape[1]):  # joint by joint: no (N, N, 6) array
        np.maximum(D, np.abs(q[:, None, j] - q[None, :, j]) / v[j], out=D)
    return D


def path_time(order: np.ndarray, D: np.ndarray) -> float:
    """Time of visiting ``order`` (indices into ``D``) in sequence, s."""
    order = np.asarray(order, dtype=int)
    return float(D[order[:-1], order[1:]].sum()) if len(order) > 1 else 0.0


def _two_opt(order: np.ndarray, D: np.ndarray) -> np.ndarray:
    """2-opt on an open path: reverse a stretch while that shortens it (at most
    :data:`TRAVEL_2OPT_PASSES` passes); never longer than the input."""
    o = np.array(order, dtype=int)
    n = len(o)
    if n < 3:
        return o
    for _ in range(TRAVEL_2OPT_PASSES):
        improved = False
        for i in range(0, n - 1):
            # reverse o[i..j]: edges (o[i-1], o[i]) and (o[j], o[j+1]) become (o[i-1], o[j]), (o[i], o[j+1])
            j = np.arange(i + 1, n)
            before = np.zeros(len(j)) if i == 0 else D[o[i - 1], o[i]] + 0.0 * j
            after = np.where(j < n - 1, D[o[j], o[np.minimum(j + 1, n - 1)]], 0.0)
            new_b = np.zeros(len(j)) if i == 0 else D[o[i - 1], o[j]]
            new_a = np.where(j < n - 1, D[o[i], o[np.minimum(j + 1, n - 1)]], 0.0)
            delta = new_b + new_a - before - after
            b = int(np.argmin(delta))
            if delta[b] < -1e-12:
                jj = int(j[b])
                o[i : jj + 1] = o[i : jj + 1][::-1]
                improved = True
        if not improved:
            break
    return o


def _nearest_neighbour(D: np.ndarray, start: int) -> np.ndarray:
    n = len(D)
    seen = np.zeros(n, dtype=bool)
    out = [start]
    seen[start] = True
    for _ in range(n - 1):
        d = np.where(seen, np.inf, D[out[-1]])
        nxt = int(np.argmin(d))
        out.append(nxt)
        seen[nxt] = True
    return np.array(out, dtype=int)


def travel_order(q: np.ndarray, v_max: np.ndarray) -> tuple[np.ndarray, float]:
    """An order of visiting configurations ``q`` (N, 6), rad, that shortens the travel time at the
    joint velocity limits ``v_max`` (6,), rad/s: nearest neighbour (from up to
    :data:`TRAVEL_NN_STARTS` starts) and the given order, each improved by 2-opt; the shortest.

    Returns the order (a permutation of ``range(N)``, never longer than the given order) and its
    time, s.
    """
    n = len(q)
    if n == 0:
        return np.zeros(0, dtype=int), 0.0
    D = travel_times(q, v_max)
    starts = np.unique(np.linspace(0, n - 1, min(n, TRAVEL_NN_STARTS)).round().astype(int))
    nn = min((_nearest_neighbour(D, int(s)) for s in starts), key=lambda o: path_time(o, D))
    cands = [_two_opt(np.arange(n), D), _two_opt(nn, D)]
    best = min(cands, key=lambda o: path_time(o, D))
    return best, path_time(best, D)
