"""Clearance constraints of the posture NLP: the arm's capsules kept away from the cell's objects
and from each other, closed form in CasADi with exact gradients (and Hessians, which the NLP leaves
out by default: :data:`CLEARANCE_EXACT_HESSIAN`).

Per waypoint, one constraint per checked pair (capsule - object, capsule - capsule)::

    g_pair(q) = softmin_i  m_i(q)  -  r  -  c   >= 0        (in mm)

* ``f_s = d_pair(p_s(q))``, ``s = 0..S-1``: the exact signed distance of points spread evenly
  along the capsule's segment (both ends included, at most :data:`SAMPLE_SPACING_M` apart,
  spacing ``h``) from the other body: the shape's own signed distance function
  (:meth:`models.collision.shapes.Shape.signed_distance_sx`), or the distance from the other
  capsule's segment minus its radius; ``r`` the capsule's radius, ``c`` the cell's clearance.
  A shape without one enters as its NLP proxy, which holds it (a mesh: its oriented bounding
  box, trimesh), so its constraint is conservative; the plan's check afterwards measures the
  shape itself (coal).
* ``m_i``: a lower bound of the distance's minimum between samples i and i+1
  (:func:`_interval_bounds`).  Every body here is convex, so the signed distance along a
  segment is a convex, 1-Lipschitz function of the arc length: it lies above the secant lines
  of the neighbouring samples, and above ``(f_i + f_i+1 - h) / 2``.
* ``softmin_i x_i = m - log(sum_i exp(-beta (x_i - m))) / beta`` (``m = min_i x_i``) is never
  above the minimum (by at most ``log(S) / beta``, :data:`SOFTMIN_SHARPNESS_PER_M`).
* So a feasible posture keeps *at least* the clearance, pair by pair, at its waypoints.  What
  the bound gives away is measured against coal in ``tests/test_posture_clearance.py``: a
  fraction of a millimetre along faces, a few millimetres where a segment passes a box's edge or
  corner.
* The NLP is local: from a warm start inside an object IPOPT may report the branch infeasible
  although another posture of it is free; the branch then gets status ``collision``.  A branch
  deeper than :data:`NLP_MAX_PENETRATION_M` at its warm start is not given to the NLP.

Each pair's functions are built on their own (:func:`pair_functions`, one symbolic chain per
spec) and the NLP maps them over only the waypoints where the pair can come near
(:mod:`problems.posture.clearance_active`, :mod:`problems.posture.clearance_rows`); the plan's
exact check after the NLP (``planner/cell_check.py``) still checks every pair.

Units: m inside, constraints scaled to mm for IPOPT (:data:`CLEARANCE_SCALE`).  Frames: the
base frame; ``shape2base`` maps a shape's own coordinates to the base frame.
"""

from __future__ import annotations

import hashlib
import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from models.collision.capsules import CapsuleModel
from models.collision.chain import capsule_points_sx, chain_frames_sx
from models.collision.scene import Scene, SceneObject
from models.collision.shapes import NORM_EPS_M
from models.robot import Robot

__all__ = [
    "CLEARANCE_MAX_NODES",
    "CLEARANCE_SCALE",
    "CLEARANCE_TOL_M",
    "NLP_MAX_PENETRATION_M",
    "ClearanceSpec",
    "clearance_functions",
    "clearance_spec",
    "distance_function",
    "pair_functions",
    "sample_count",
]

#: Largest spacing of the sample points along a capsule's segment (m); half of it is the most
#: the constraint gives away to the sampling.
SAMPLE_SPACING_M = 0.04
#: Sharpness ``beta`` of the smooth minimum over a capsule's samples (1/m): it is below the true
#: minimum by at most ``log(S) / beta`` (1.5 mm for 20 samples).
SOFTMIN_SHARPNESS_PER_M = 5000.0
#: Constraints are posed in mm (m -> mm), as the position constraints.
CLEARANCE_SCALE = 1e3
#: With clearance constraints, a long path's NLP is solved on at most this many nodes (each
#: waypoint's constraints cost about as much as its stage functions ten times over); the densified
#: postures between the nodes are checked exactly by the plan afterwards.
CLEARANCE_MAX_NODES = 250
#: Whether the constraints' second derivatives enter the Lagrangian Hessian.  Left out: on the
#: shipped cell cases IPOPT then takes about twice the iterations at a third of their cost, to the
#: same postures (measured: cell_table 9.3 s vs 11.6 s, a ceiling case 13.9 s vs 20.0 s).
CLEARANCE_EXACT_HESSIAN = False
#: A branch whose warm start lies deeper than this (m) inside some pair's clearance is not given to
#: the NLP (changing the posture along a path does not pull a link a table's depth out of it; IPOPT
#: would spend its iterations proving the branch infeasible); the plan's check then sets it aside.
NLP_MAX_PENETRATION_M = 0.05
#: A posture keeps the posed clearance to this (m): IPOPT's constraint tolerance and the
#: Gauss-Newton polish after it move the joints by about 1e-8 rad.
CLEARANCE_TOL_M = 1e-6
#: Secant slopes closer than this (m/m) count as one line (the function is linear there).
SECANT_SLOPE_EPS = 1e-9
#: A capsule shorter than this (m) is a sphere: its centre alone is measured.
MIN_SAMPLED_LENGTH_M = 1e-9


@dataclass(frozen=True)
class PairSpec:
    """One pair of the clearance constraints.

    Attributes
    ----------
    capsule : int
        The sampled capsule (index into the capsule model).
    other : models.collision.scene.SceneObject or int
        What it keeps away from: an object as the NLP measures it (its shape's NLP proxy,
        :meth:`~models.collision.scene.SceneObject.proxy`, base frame), or another capsule's index.
    name : str
        ``link 3 – table`` (messages).
    """

    capsule: int
    other: SceneObject | int
    name: str

    @property
    def kind(self) -> str:
        """``capsule``, or the object's (proxy's) shape kind."""
        return "capsule" if isinstance(self.other, int) else self.other.kind

    @property
    def size(self) -> np.ndarray:
        """The other capsule's index (a capsule pair), else the object's size, m."""
        return np.array([float(self.other)]) if isinstance(self.other, int) else self.other.shape.size


@dataclass(frozen=True)
class ClearanceSpec:
    """The clearance constraints of one robot in one cell.

    Attributes
    ----------
    robot : Robot
        Its nominal DH chain places the capsules.
    model : models.collision.CapsuleModel
        The capsule model (tool included).
    pairs : tuple of PairSpec
        Every pair the plan's check checks (objects, then self pairs).
    clearance : float
        m.
    """

    robot: Robot
    model: CapsuleModel
    pairs: tuple[PairSpec, ...]
    clearance: float

    @property
    def key(self) -> str:
        """A hash of everything the constraint functions depend on (solver cache key)."""
        h = hashlib.sha256()
        r = self.robot
        for arr in (r.a, r.alpha, r.d, r.theta_offset, r.frame02base, r.flange2frame6):
            h.update(np.ascontiguousarray(arr, dtype=float).tobytes())
        h.update(r.convention.encode())
        m = self.model
        for arr in (m.frame_a, m.frame_b, m.local_a, m.local_b, m.radius):
            h.update(np.ascontiguousarray(arr).tobytes())
        for p in self.pairs:
            h.update(f"{p.capsule}|{p.kind}|".encode())
            if not isinstance(p.other, int):
                h.update(np.ascontiguousarray(p.other.pose, dtype=float).tobytes())
            h.update(np.ascontiguousarray(p.size, dtype=float).tobytes())
        h.update(np.float64(self.clearance).tobytes())
        return h.hexdigest()

    def subset(self, keep: np.ndarray) -> ClearanceSpec:
        """The spec with only the pairs ``keep`` (indices or a boolean mask)."""
        idx = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep, dtype=int)
        return ClearanceSpec(self.robot, self.model, tuple(self.pairs[int(i)] for i in idx), self.clearance)


def clearance_spec(scene: Scene) -> ClearanceSpec:
    """Every pair a collision scene checks, as NLP constraints.

    Parameters
    ----------
    scene : models.collision.scene.Scene
        The capsules (tool included), the objects (base frame), the pairs checked and the
        clearance (m); an object enters as its shape's NLP proxy (a mesh as its oriented bounding
        box).
    """
    pairs = []
    proxies = [o.proxy(nlp=True) for o in scene.objects]
    for c in range(scene.model.n_capsules):
        for j, o in enumerate(proxies):
            if scene.checked[c, j]:
                pairs.append(PairSpec(c, o, f"{scene.names[c]} – {o.name}"))
    for i, j in np.asarray(scene.self_pairs, dtype=int).reshape(-1, 2):
        # sample the longer capsule, measure from the other's segment
        pairs.append(PairSpec(int(i), int(j), f"{scene.names[i]} – {scene.names[j]}"))
    return ClearanceSpec(scene.robot, scene.model, tuple(pairs), float(scene.clearance))


# --------------------------------------------------------------------------------------
# Symbolic geometry
# --------------------------------------------------------------------------------------


def _norm(v: ca.SX) -> ca.SX:
    return ca.sqrt(ca.sumsqr(v) + NORM_EPS_M**2)


def _sdf(p: ca.SX, pair: PairSpec, segs: list[tuple[ca.SX, ca.SX]], radius: np.ndarray) -> ca.SX:
    """Signed distance (m) of point ``p`` (3,) from the pair's other body."""
    if isinstance(pair.other, int):
        j = pair.other
        a, b = segs[j]
        ab = b - a
        t = ca.fmin(ca.fmax(ca.dot(p - a, ab) / (ca.sumsqr(ab) + NORM_EPS_M**2), 0.0), 1.0)
        return _norm(p - a - t * ab) - float(radius[j])
    T = pair.other.pose
    local = ca.mtimes(ca.DM(T[:3, :3].T), p - ca.DM(T[:3, 3]))
    return pair.other.shape.signed_distance_sx(local)


def _softmin(x: list[ca.SX]) -> ca.SX:
    """Smooth minimum, never above the minimum (module docstring)."""
    if len(x) == 1:
        return x[0]
    v = ca.vertcat(*x)
    m = ca.mmin(v)
    beta = SOFTMIN_SHARPNESS_PER_M
    return m - ca.log(ca.sum1(ca.exp(-beta * (v - m)))) / beta


def sample_count(a: np.ndarray, b: np.ndarray) -> int:
    """Number of samples along a segment of these end points at q = 0 (its length is constant)."""
    return max(2, int(math.ceil(float(np.linalg.norm(b - a)) / SAMPLE_SPACING_M)) + 1)


def _interval_bounds(f: list[ca.SX], h: float) -> list[ca.SX]:
    """Lower bounds of a convex, 1-Lipschitz function's minimum on each interval between samples.

    ``f``: its values at samples ``h`` (m) apart.  On interval ``[t_i, t_i+1]`` it lies above the
    secant lines through its neighbours (slope ``s_L`` of samples i-1, i through sample i, slope
    ``s_R`` of samples i+1, i+2 through sample i+1; -1 and +1 at the ends, the Lipschitz bound);
    the bound is the least value of the larger of the two lines on the interval, at their
    crossing clamped to the interval; or, where larger, the Lipschitz bound
    ``(f_i + f_i+1 - h) / 2`` (deep inside an object, where the secants cross kinks).
    """
    n = len(f)
    out = []
    for i in range(n - 1):
        s_l = (f[i] - f[i - 1]) / h if i > 0 else -1.0
        s_r = (f[i + 2] - f[i + 1]) / h if i + 2 < n else 1.0
        den = s_r - s_l  # >= 0 for a convex function
        safe = ca.if_else(den > SECANT_SLOPE_EPS, den, 1.0)
        tau = ca.fmin(ca.fmax((f[i] - f[i + 1] + s_r * h) / safe, 0.0), h)
        both = ca.fmax(f[i] + s_l * tau, f[i + 1] + s_r * (tau - h))
        convex = ca.if_else(den > SECANT_SLOPE_EPS, both, ca.fmin(f[i], f[i + 1]))
        out.append(ca.fmax(convex, 0.5 * (f[i] + f[i + 1] - h)))  # and the Lipschitz bound
    return out


def _ends_sx(spec: ClearanceSpec, q: ca.SX) -> tuple[ca.SX, np.ndarray, np.ndarray]:
    """Every capsule's end points at ``q`` as one vector ``E`` (6 M,: a then b per capsule, base
    frame, m), and the end points (M, 2, 3) and segment lengths (M,) at q = 0 (constant)."""
    E = ca.vertcat(*[ca.vertcat(a, b) for a, b in capsule_points_sx(spec.model, chain_frames_sx(spec.robot, q))])
    ends = np.asarray(ca.Function("ends0", [q], [E])(np.zeros(6))).reshape(-1, 2, 3)
    return E, ends, np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)


def _chain_segments(spec: ClearanceSpec, q: ca.SX) -> tuple[list[tuple[ca.SX, ca.SX]], np.ndarray, np.ndarray]:
    """Every capsule's segment ends at ``q`` (3 x 1 SX each, one chain), and the end points
    (M, 2, 3) and segment lengths (M,) at q = 0 (constant)."""
    E, ends, lengths = _ends_sx(spec, q)
    return [(E[6 * c : 6 * c + 3], E[6 * c + 3 : 6 * c + 6]) for c in range(spec.model.n_capsules)], ends, lengths


def _pair_sx(
    spec: ClearanceSpec, i: int, segs: list[tuple[ca.SX, ca.SX]], ends: np.ndarray, lengths: np.ndarray
) -> ca.SX:
    """Pair ``i``'s lower-bound surface distance (m), an SX scalar (module docstring)."""
    m, p = spec.model, spec.pairs[i]
    a, b = segs[p.capsule]
    length = float(lengths[p.capsule])
    if length < MIN_SAMPLED_LENGTH_M:  # a sphere
        return _sdf(a, p, segs, m.radius) - float(m.radius[p.capsule])
    n = sample_count(ends[p.capsule, 0], ends[p.capsule, 1])
    f = [_sdf(a + (s / (n - 1)) * (b - a), p, segs, m.radius) for s in range(n)]
    return _softmin(_interval_bounds(f, length / (n - 1))) - float(m.radius[p.capsule])


def _pair_distances_sx(spec: ClearanceSpec, q: ca.SX) -> list[ca.SX]:
    """Each pair's lower-bound surface distance (m) at ``q``, one SX scalar per pair, all on one
    chain (its frames built once)."""
    segs, ends, lengths = _chain_segments(spec, q)
    return [_pair_sx(spec, i, segs, ends, lengths) for i in range(len(spec.pairs))]


def _distance_sx(spec: ClearanceSpec, q: ca.SX) -> ca.SX:
    """The pairs' lower-bound surface distances (P,), m, at ``q`` (module docstring)."""
    g = _pair_distances_sx(spec, q)
    return ca.vertcat(*g) if g else ca.SX(0, 1)


def distance_function(spec: ClearanceSpec) -> ca.Function:
    """``q (6,) -> distance (P,)``: each pair's lower-bound surface distance, m (what the
    constraint keeps at least the clearance)."""
    q = ca.SX.sym("q", 6)
    return ca.Function("clearance_distance", [q], [_distance_sx(spec, q)], ["q"], ["distance"])


def _functions(q: ca.SX, gc: ca.SX, exact_hessian: bool, name: str) -> dict[str, ca.Function]:
    """The ``g``, ``jac`` and ``hess`` functions of constraints ``gc`` (mm) of ``q`` (6,)."""
    lam = ca.SX.sym("lam", gc.shape[0])
    if exact_hessian and gc.shape[0]:
        H = ca.hessian(ca.dot(lam, gc), q)[0]
        H = 0.5 * (H + H.T)
    else:
        H = ca.SX(6, 6)
    return {
        "g": ca.Function(f"{name}_g", [q], [gc], ["q"], ["g"]),
        "jac": ca.Function(f"{name}_jac", [q], [gc, ca.densify(ca.jacobian(gc, q))], ["q"], ["g", "jac"]),
        "hess": ca.Function(f"{name}_hess", [q, lam], [ca.densify(H)], ["q", "lam"], ["hess"]),
    }


def clearance_functions(spec: ClearanceSpec, exact_hessian: bool = CLEARANCE_EXACT_HESSIAN) -> dict[str, ca.Function]:
    """The per-waypoint clearance functions of every pair of ``spec`` (SX, CasADi's virtual machine).

    Parameters
    ----------
    spec : ClearanceSpec
    exact_hessian : bool
        False: the constraints' second derivatives are left out of the Lagrangian Hessian (the
        objective's are kept); cheaper per iteration, more iterations.

    Returns
    -------
    dict str -> casadi.Function
        ``"g"``: q (6,) -> g (P,), mm, ``>= 0`` where every pair keeps the clearance;
        ``"jac"``: q -> (g, dg/dq (P, 6) dense); ``"hess"``: (q, lam (P,)) -> Hessian (6, 6) of
        ``lam . g``, dense, symmetric.
    """
    q = ca.SX.sym("q", 6)
    return _functions(q, CLEARANCE_SCALE * (_distance_sx(spec, q) - spec.clearance), exact_hessian, "clearance")


#: Per-pair functions built so far, by (spec key, exact Hessian); cleared beyond this many specs.
_PAIR_FUNCTIONS_MAX = 16
_PAIR_FUNCTIONS: dict[tuple[str, bool], dict[str, Any]] = {}
_PAIR_LOCK = threading.Lock()


def pair_functions(
    spec: ClearanceSpec, pairs: Sequence[int], exact_hessian: bool = CLEARANCE_EXACT_HESSIAN
) -> list[dict[str, ca.Function]]:
    """Pair ``i``'s clearance functions for each ``i`` of ``pairs``, as :func:`clearance_functions`
    gives them for all pairs (``g``: q (6,) -> (1,) mm; ``jac``: q -> (g, (1, 6)); ``hess``).

    Built on one symbolic chain per spec, each pair once, on first use, and cached: the NLP maps
    each over the waypoints where its pair is posed (:mod:`problems.posture.clearance_rows`), and
    a pair posed later (:mod:`problems.posture.clearance_active`) costs only its own build.
    """
    key = (spec.key, bool(exact_hessian))
    with _PAIR_LOCK:
        entry = _PAIR_FUNCTIONS.get(key)
        if entry is None:
            if len(_PAIR_FUNCTIONS) >= _PAIR_FUNCTIONS_MAX:
                _PAIR_FUNCTIONS.clear()
            q = ca.SX.sym("q", 6)
            entry = {"q": q, "chain": _chain_segments(spec, q), "built": {}}
            _PAIR_FUNCTIONS[key] = entry
        out = []
        for i in pairs:
            fn = entry["built"].get(int(i))
            if fn is None:
                d = _pair_sx(spec, int(i), *entry["chain"])
                fn = _functions(entry["q"], CLEARANCE_SCALE * (d - spec.clearance), exact_hessian, f"clearance_{i}")
                entry["built"][int(i)] = fn
            out.append(fn)
    return out
