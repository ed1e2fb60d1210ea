"""Where the posture NLP poses the cell's clearance constraints: a broad phase in NumPy.

A pair of the cell (:class:`~problems.posture.clearance.ClearanceSpec`) is posed only at the
waypoints where it can come near, not at every waypoint of every branch:

* :func:`pair_distances`: every pair's surface distance at N configurations, vectorised in NumPy
  (capsule-object by the object's closed form,
  :func:`models.collision.vectorised.capsule_object_distance`
  on the shape the NLP measures; capsule-capsule closed form): exact for boxes, spheres and the
  self pairs, a lower bound for the other kinds (the larger of their closed form's and the NLP's
  own bound);
* :func:`depth_margin`: how deep a warm start lies, as the NLP measures it (a branch more than
  :data:`~problems.posture.clearance.NLP_MAX_PENETRATION_M` deep is not given to the NLP);
* :func:`posed_at`: pair p is posed at waypoint k when it comes within :data:`POSED_DISTANCE_M`
  at k or at a neighbouring waypoint of some branch's warm start;
* :func:`unposed_violations`: after a solve, the entries not posed that come closer than the
  clearance; the branch is then solved again with them posed (and with the pair's other
  waypoints within :data:`POSED_DISTANCE_M`), at most :data:`MAX_RESOLVES` times.

So what the NLP returns keeps the clearance at every pair and waypoint (posed: by the NLP's
constraint; not posed: by this check), as before, at a fraction of the constraints.

Units: m.  Frames: the base frame.
"""

from __future__ import annotations

import numpy as np

from models.collision import capsule_distance, capsule_segments, chain_frames, segment_distance
from models.collision.vectorised import capsule_object_distance
from problems.posture.clearance import (
    CLEARANCE_SCALE,
    NLP_MAX_PENETRATION_M,
    ClearanceSpec,
    pair_functions,
    sample_count,
)

__all__ = [
    "MAX_RESOLVES",
    "POSED_DISTANCE_M",
    "clearance_margin",
    "closest_pair_words",
    "depth_margin",
    "pair_depth_margins",
    "pair_distances",
    "posed_at",
    "unposed_violations",
]

#: A pair is posed at a waypoint where it comes within this distance (m, surface to surface) at
#: a branch's warm start (or at a neighbouring waypoint's).
POSED_DISTANCE_M = 0.10
#: Waypoints on either side of a near one where the pair is posed too.
POSED_NEIGHBOURS = 1
#: How many times a branch is solved again with the entries it violated posed.
MAX_RESOLVES = 3
#: A pair this much (m) short of :data:`~problems.posture.clearance.NLP_MAX_PENETRATION_M` deep
#: (by :func:`pair_distances`) is measured by the NLP's own distance too (:func:`depth_margin`).
DEPTH_CANDIDATE_M = 0.02


def pair_distances(spec: ClearanceSpec, q: np.ndarray) -> np.ndarray:
    """Every pair's surface distance at configurations ``q`` (N, 6) rad, shape (N, P), m.

    Exact where the object's closed form is (box, sphere, a mesh's bounding box as the NLP
    measures it) and for capsule pairs; else a lower bound (module docstring).
    """
    q = np.atleast_2d(q)
    out = np.empty((q.shape[0], len(spec.pairs)))
    if not spec.pairs:
        return out
    seg = capsule_segments(spec.model, chain_frames(spec.robot, q))  # (N, M, 2, 3)
    r = spec.model.radius
    self_idx = [i for i, p in enumerate(spec.pairs) if isinstance(p.other, int)]
    if self_idx:
        ci = np.array([spec.pairs[i].capsule for i in self_idx])
        cj = np.array([spec.pairs[i].other for i in self_idx])
        out[:, self_idx] = capsule_distance(seg[:, ci], r[ci], seg[:, cj], r[cj])
    groups: dict[int, list[int]] = {}
    for i, p in enumerate(spec.pairs):
        if not isinstance(p.other, int):
            groups.setdefault(id(p.other), []).append(i)
    bounds: list[int] = []
    for idx in groups.values():
        obj = spec.pairs[idx[0]].other
        caps = np.array([spec.pairs[i].capsule for i in idx])
        try:
            out[:, idx] = capsule_object_distance(seg[:, caps], r[caps], obj)
        except NotImplementedError:  # a shape kind without a closed form: the NLP's bound alone
            out[:, idx] = -np.inf
        if not obj.shape.exact_in_kernel or np.isneginf(out[0, idx[0]]):
            bounds += idx
    if bounds:  # the larger of two lower bounds is one
        fns = pair_functions(spec, bounds)
        nlp = np.vstack([np.asarray(f["g"].map(q.shape[0])(q.T)) for f in fns]).T / CLEARANCE_SCALE
        out[:, bounds] = np.maximum(out[:, bounds], nlp + spec.clearance)
    return out


def clearance_margin(spec: ClearanceSpec | None, q: np.ndarray) -> np.ndarray:
    """Each waypoint's smallest margin over every pair (m, :func:`pair_distances` less the
    clearance) at ``q`` (N, 6) rad; ``+inf`` without a cell; ``-inf`` where ``q`` is not finite."""
    q = np.atleast_2d(q)
    if spec is None or not spec.pairs:
        return np.full(q.shape[0], np.inf)
    ok = np.all(np.isfinite(q), axis=1)
    out = np.full(q.shape[0], -np.inf)
    if ok.any():
        out[ok] = pair_distances(spec, q[ok]).min(axis=1) - spec.clearance
    return out


def closest_pair_words(spec: ClearanceSpec | None, q: np.ndarray) -> str:
    """The pair that comes closest at configuration ``q`` (6,) rad, in words for a reason:
    ``"link 3 – table 2.1 mm apart, clearance 5 mm"`` (``... 4 mm deep ...`` when the surfaces
    overlap); empty without a cell or at a configuration that is not finite."""
    q = np.asarray(q, float).reshape(1, -1)
    if spec is None or not spec.pairs or not np.all(np.isfinite(q)):
        return ""
    d = pair_distances(spec, q)[0]
    i = int(np.argmin(d))
    if not np.isfinite(d[i]):
        return f"{spec.pairs[i].name} (no closed-form distance), clearance {spec.clearance * 1e3:.3g} mm"
    gap = f"{d[i] * 1e3:.3g} mm apart" if d[i] >= 0 else f"{-d[i] * 1e3:.3g} mm deep"
    return f"{spec.pairs[i].name} {gap}, clearance {spec.clearance * 1e3:.3g} mm"


def depth_margin(spec: ClearanceSpec | None, q: np.ndarray) -> np.ndarray:
    """Each waypoint's smallest margin (m) over the pairs of :func:`pair_depth_margins`."""
    return pair_depth_margins(spec, q).min(axis=1)


def pair_depth_margins(spec: ClearanceSpec | None, q: np.ndarray) -> np.ndarray:
    """Each waypoint's margin per pair (N, P), m, at ``q`` (N, 6) rad as the NLP measures depth: where a
    pair comes within :data:`DEPTH_CANDIDATE_M` of being
    :data:`~problems.posture.clearance.NLP_MAX_PENETRATION_M` deep, the smallest signed distance
    of its capsule's sample points (the NLP's, :func:`~problems.posture.clearance.sample_count`)
    less its radius: the depth a posture change has to undo; elsewhere :func:`pair_distances`;
    less the clearance.  Decides which branches the NLP is given."""
    q = np.atleast_2d(q)
    if spec is None or not spec.pairs:
        return np.full((q.shape[0], 1), np.inf)
    m = pair_distances(spec, q) - spec.clearance
    deep = np.flatnonzero((m < -NLP_MAX_PENETRATION_M + DEPTH_CANDIDATE_M).any(axis=0))
    if deep.size:
        seg = capsule_segments(spec.model, chain_frames(spec.robot, q))
        for i in deep:
            d = _sampled_distance(spec, int(i), seg)
            if d is not None:
                m[:, i] = d - spec.clearance
    return m


def _sampled_distance(spec: ClearanceSpec, i: int, seg: np.ndarray) -> np.ndarray | None:
    """Pair ``i``'s smallest signed distance (m) over its capsule's sample points less its radius,
    at segments ``seg`` (N, M, 2, 3); None for a shape without a NumPy signed distance."""
    p, r = spec.pairs[i], spec.model.radius
    a, b = seg[:, p.capsule, 0], seg[:, p.capsule, 1]
    t = np.linspace(0.0, 1.0, sample_count(a[0], b[0]))
    pts = a[:, None] + t[None, :, None] * (b - a)[:, None]  # (N, S, 3)
    if isinstance(p.other, int):
        o = seg[:, p.other]
        d = segment_distance(pts, pts, o[:, None, 0], o[:, None, 1])[0] - r[p.other]
    else:
        try:
            d = p.other.shape.signed_distance(p.other.to_local(pts.reshape(-1, 3))).reshape(pts.shape[:2])
        except NotImplementedError:
            return None
    return d.min(axis=1) - r[p.capsule]


def _dilate(mask: np.ndarray, k: int = POSED_NEIGHBOURS) -> np.ndarray:
    """``mask`` (P, N) widened by ``k`` waypoints on either side."""
    out = mask.copy()
    for s in range(1, k + 1):
        out[:, s:] |= mask[:, :-s]
        out[:, :-s] |= mask[:, s:]
    return out


def posed_at(spec: ClearanceSpec, q_sets: list[np.ndarray], near_m: float = POSED_DISTANCE_M) -> np.ndarray:
    """Where each pair is posed: within ``near_m`` (m) at waypoint k, or a neighbour, of any of
    ``q_sets`` (each (N, 6) rad, the branches' warm starts).

    Returns
    -------
    ndarray of bool, shape (P, N)
    """
    n = q_sets[0].shape[0] if q_sets else 0
    near = np.zeros((len(spec.pairs), n), dtype=bool)
    for q in q_sets:
        near |= (pair_distances(spec, q) < near_m).T
    return _dilate(near)


def unposed_violations(
    spec: ClearanceSpec, posed: np.ndarray, q: np.ndarray, near_m: float = POSED_DISTANCE_M
) -> np.ndarray | None:
    """The entries to pose in addition after a solve ending at ``q`` (N, 6) rad: for every pair
    that comes closer than the clearance at a waypoint where it is not posed, the waypoints where
    it comes within ``near_m`` (dilated as :func:`posed_at`); None when there is no such pair.

    Returns
    -------
    ndarray of bool, shape (P, N), or None
    """
    if not spec.pairs or not np.all(np.isfinite(q)):
        return None
    d = pair_distances(spec, q).T  # (P, N)
    bad = (d < spec.clearance) & ~posed
    if not bad.any():
        return None
    rows = bad.any(axis=1)
    more = np.zeros_like(posed)
    more[rows] = _dilate(d[rows] < near_m) | bad[rows]
    return more & ~posed
