"""Capsule–object signed distances in closed form, vectorised in NumPy over any number of capsules.

For the placement sweep (``problems/placement/kernel.py``), where coal's per-pair Python loop
(about 350 us per pose, ``benchmarks/bench_collision.py``) is far too slow.  One call takes N
capsules (segment end points ``(..., 2, 3)`` and radii, base frame) against one object:

* **box** (exact, both signs).  Outside: the segment–box distance is ``min_t dist(p(t), box)``,
  whose square ``g(t) = sum_i max(|x_i(t)| - h_i, 0)^2`` is a convex piecewise quadratic of the
  segment parameter with at most six breakpoints (where a coordinate crosses a face plane); its
  exact minimum is at a breakpoint, an end, or the stationary point of one piece, so ``g`` is
  evaluated at those 15 candidates.  Penetrating: the segment meets the box, and the penetration
  depth (coal's EPA: the smallest translation that separates them) is the distance from the
  origin to the boundary of the zonotope ``box - segment``, the smallest support value over its
  facet normals: the box's three axes and the cross products of each with the segment (both
  signs).  The capsule's radius is then subtracted.  Agrees with coal to 1e-6 m
  (``tests/test_placement_cell.py``; measured differences about 1e-9 m, coal's GJK/EPA tolerance).
* **sphere** (exact, both signs): the centre's distance to the segment minus both radii.
* **cylinder** (a conservative bound): the larger of the distances to its enclosing box (half
  extents radius, radius, half length) and to its enclosing capsule (its axis, its radius).  Both
  contain the cylinder, so neither reports more clearance than the cylinder has (nor less
  penetration); the bound is exact where the nearest point is on a flat end face or on the side
  along the enclosing box's faces, and at most ``(sqrt(2) - 1) * radius`` short near the side's
  diagonals.
* **mesh** (a conservative bound): its axis-aligned bounding box in the object frame, treated as
  a box.  A capsule that only enters the box's empty corners is reported as touching.

Signed distances: negative is penetration depth.  Units: m; points in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .segments import segment_distance

__all__ = [
    "VecObject",
    "capsule_object_distance",
    "segment_box_distance",
    "vec_object",
]

#: Squared segment length (m^2) or cross-product norm below which a direction is treated as zero.
DEGENERATE_M2 = 1e-24
#: The shapes an object may have here, and which are exact (the others are bounded).
EXACT_KINDS = ("box", "sphere")


@dataclass(frozen=True)
class VecObject:
    """One object as the closed forms take it.

    Attributes
    ----------
    name : str
    kind : {"box", "sphere", "cylinder"}
        What is computed (a mesh is its bounding ``box``).
    object2base : ndarray, shape (4, 4)
        The shape's centre and axes in the base frame.
    half : ndarray, shape (3,)
        m: box half extents; cylinder ``(radius, radius, half length)``; sphere ``(r, r, r)``.
    exact : bool
        False where the distance is a conservative bound (cylinder, mesh).
    source : str
        The object's own shape (``mesh`` for a mesh's bounding box).
    """

    name: str
    kind: str
    object2base: np.ndarray
    half: np.ndarray
    exact: bool
    source: str

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about the centre holding the shape, m."""
        if self.kind == "sphere":
            return float(self.half[0])
        if self.kind == "cylinder":
            return float(np.hypot(self.half[0], self.half[2]))
        return float(np.linalg.norm(self.half))


def vec_object(name: str, shape: str, size: np.ndarray, object2base: np.ndarray, mesh: Any = None) -> VecObject:
    """The :class:`VecObject` of a cell object (``problems.cell.CellObject``'s fields).

    Parameters
    ----------
    name : str
    shape : {"box", "cylinder", "sphere", "mesh"}
    size : ndarray
        box ``(3,)`` extents; cylinder ``(radius, length)``; sphere ``(radius,)``; m (unused for a mesh).
    object2base : ndarray, shape (4, 4)
    mesh : trimesh.Trimesh, optional
        A mesh object's mesh in its own frame, m (its bounds are used).
    """
    T = np.asarray(object2base, dtype=float)
    s = np.asarray(size, dtype=float).reshape(-1)
    if shape == "box":
        return VecObject(name, "box", T, 0.5 * s, True, shape)
    if shape == "sphere":
        return VecObject(name, "sphere", T, np.full(3, s[0]), True, shape)
    if shape == "cylinder":
        return VecObject(name, "cylinder", T, np.array([s[0], s[0], 0.5 * s[1]]), False, shape)
    if shape == "mesh":
        lo, hi = (np.asarray(b, dtype=float) for b in mesh.bounds)
        C = np.eye(4)
        C[:3, 3] = 0.5 * (lo + hi)
        return VecObject(name, "box", T @ C, 0.5 * (hi - lo), False, shape)
    raise ValueError(f"unknown shape {shape!r}")


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def segment_box_distance(p0: np.ndarray, p1: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Signed distance between segments and the axis-aligned box ``|x_i| <= half_i`` (box frame).

    Parameters
    ----------
    p0, p1 : ndarray, shape (..., 3)
        Segment ends in the box frame, m.
    half : ndarray, shape (3,)
        Half extents, m.

    Returns
    -------
    ndarray, shape (...)
        The distance (m) when apart; minus the penetration depth (the smallest translation of the
        segment out of the box) when they meet (module docstring).
    """
    h = np.asarray(half, dtype=float)
    d = p1 - p0
    # --- apart: exact minimum of the convex piecewise quadratic g(t) over [0, 1]
    dd = np.where(np.abs(d) > 0.0, d, 1.0)
    brk = np.concatenate([(h - p0) / dd, (-h - p0) / dd], axis=-1)  # (..., 6)
    brk = np.where(np.concatenate([np.abs(d), np.abs(d)], axis=-1) > 0.0, brk, 0.0)
    ts = np.sort(
        np.concatenate(
            [np.zeros(brk.shape[:-1] + (1,)), np.ones(brk.shape[:-1] + (1,)), np.clip(brk, 0.0, 1.0)], axis=-1
        ),
        axis=-1,
    )  # (..., 8)
    lo, hi = ts[..., :-1], ts[..., 1:]  # (..., 7) pieces
    xm = p0[..., None, :] + (0.5 * (lo + hi))[..., None] * d[..., None, :]  # (..., 7, 3)
    act = np.abs(xm) > h
    sgn = np.sign(xm)
    dk = np.where(act, d[..., None, :], 0.0)
    num = _dot(dk, sgn * h - p0[..., None, :])
    den = _dot(dk, dk)
    tst = np.clip(num / np.where(den > DEGENERATE_M2, den, 1.0), lo, hi)
    cand = np.concatenate([ts, tst], axis=-1)  # (..., 15)
    x = p0[..., None, :] + cand[..., None] * d[..., None, :]
    ex = np.maximum(np.abs(x) - h, 0.0)
    g = np.min(_dot(ex, ex), axis=-1)
    # --- meeting: the smallest support of the zonotope box - segment over its facet normals
    eye = np.broadcast_to(np.eye(3), d.shape[:-1] + (3, 3))
    cr = np.cross(eye, d[..., None, :])  # (..., 3, 3): e_i x d
    cn = np.sqrt(_dot(cr, cr))
    ok = cn**2 > DEGENERATE_M2
    cr = cr / np.where(ok, cn, 1.0)[..., None]
    normals = np.concatenate([eye, -eye, cr, -cr], axis=-2)  # (..., 12, 3)
    valid = np.concatenate([np.ones_like(ok), np.ones_like(ok), ok, ok], axis=-1)
    support = _dot(np.abs(normals), np.broadcast_to(h, normals.shape)) + np.maximum(
        -_dot(normals, p0[..., None, :]), -_dot(normals, p1[..., None, :])
    )
    depth = np.min(np.where(valid, support, np.inf), axis=-1)
    return np.where(g > 0.0, np.sqrt(g), -np.maximum(depth, 0.0))


def _to_object(segments: np.ndarray, obj: VecObject) -> np.ndarray:
    R, t = obj.object2base[:3, :3], obj.object2base[:3, 3]
    return (segments - t) @ R  # (..., 2, 3) in the object frame


def capsule_object_distance(segments: np.ndarray, radii: np.ndarray | float, obj: VecObject) -> np.ndarray:
    """Signed distances between capsules and one object (negative: penetration), m.

    Parameters
    ----------
    segments : ndarray, shape (..., 2, 3)
        Capsule segment ends, base frame, m.
    radii : float or ndarray broadcast to shape (...)
        Capsule radii, m.
    obj : VecObject

    Returns
    -------
    ndarray, shape (...)
        Exact for boxes and spheres; a lower bound (never more clearance than the object has) for
        cylinders and meshes (module docstring).
    """
    s = _to_object(np.asarray(segments, dtype=float), obj)
    p0, p1 = s[..., 0, :], s[..., 1, :]
    if obj.kind == "sphere":
        d = p1 - p0
        L2 = _dot(d, d)
        t = np.clip(_dot(-p0, d) / np.where(L2 > DEGENERATE_M2, L2, 1.0), 0.0, 1.0)
        dist = np.linalg.norm(p0 + t[..., None] * d, axis=-1)
        return dist - obj.half[0] - radii
    box = segment_box_distance(p0, p1, obj.half)
    if obj.kind == "box":
        return box - radii
    # cylinder: also its enclosing capsule (the axis segment, the radius); the larger lower bound
    axis0, axis1 = np.array([0.0, 0.0, -obj.half[2]]), np.array([0.0, 0.0, obj.half[2]])
    cap, _, _ = segment_distance(p0, p1, axis0, axis1)
    return np.maximum(box, cap - obj.half[0]) - radii
