"""The cell in the placement kernel: base footprints and the arm's clearance, vectorised.

What is checked (``docs/placement.md``, "Collisions"), the same pairs as the plan's check
(``planner/cell_check.py``):

* **the base footprint** (:func:`problems.cell.base_footprint`: a cylinder about the base z axis
  from the mounting plane up to 0.10 m) of each placement against every object, before the IK:
  coal's collision test, asked only for the objects whose bounding sphere comes near the
  footprint's (vectorised), the footprint shrunk by ``FOOTPRINT_TOUCH_TOL_M`` as in the problem
  file's check (a table whose top is the mounting plane only touches it);
* **the arm** as the capsules of :func:`models.collision.capsule_model` plus the tool's
  (:func:`models.collision.tool.with_tool_geometry`: the declared body elements and cutter, else a
  capsule from the flange to the TCP of the flange link's radius), at the analytic IK
  configurations: every capsule against every object (closed form, :mod:`models.collision.vectorised`:
  exact for boxes and spheres, a conservative bound for cylinders and meshes), except the cutter
  (else the capsule ending at the TCP) against the workpiece and the capsules fixed to the base (the
  footprint covers the base); self-collision between the arm's self pairs and every tool capsule
  against links 0..4 (closed form); the pairs from :func:`models.collision.tool.check_pairs`, as the
  plan's.
  A pair closer than the cell's ``clearance`` is a violation.  A bounding-sphere lower bound
  first: only the pairs that can come within the clearance are computed exactly.

Frames: the objects are in the cell frame (the problem as written); a configuration's capsules
are computed in its placement's base frame and moved to the cell frame with ``base2cell``.
Units: m.  Picklable (the kernel ships it to Dask workers).
"""

from __future__ import annotations

from typing import Any

import numpy as np

import casadi as ca

from models.codegen import BatchFunction, VMBatchFunction, batch_function
from models.collision import TOOL_MIN_LENGTH_M, TOOL_SELF_MAX_BODY
from models.collision.capsules import CapsuleModel
from models.collision.chain import capsule_points_sx, chain_frames_sx
from models.collision.scene import SceneObject
from models.collision.segments import capsule_distance
from models.collision.vectorised import capsule_object_distance
from models.portable import evaluator_from_state, portable_state
from models.robot import Robot
from problems.cell import FOOTPRINT_TOUCH_TOL_M, COAL_GJK_TOLERANCE_M, base_footprint
from problems.placement.grid import base2cell

__all__ = ["KernelCell", "TOOL_MIN_LENGTH_M", "TOOL_SELF_MAX_BODY"]


def _transform(coal: Any, T: np.ndarray) -> Any:
    tf = coal.Transform3s()
    tf.setRotation(np.ascontiguousarray(T[:3, :3]))
    tf.setTranslation(np.ascontiguousarray(T[:3, 3]))
    return tf


def _capsule_points_function(robot: Robot, model: CapsuleModel) -> ca.Function:
    """CasADi ``capsule_points(q, base2cell) -> ends``: the capsule ends (M x 2 x 3, capsule-major,
    end a then end b, x y z) in the cell frame at joint angles ``q`` (6) of a placement
    ``base2cell`` (4 x 4); the one CasADi chain (:func:`models.collision.chain.chain_frames_sx`)."""
    q = ca.SX.sym("q", 6)
    T = ca.SX.sym("base2cell", 4, 4)
    out = [p for ends in capsule_points_sx(model, chain_frames_sx(robot, q), T) for p in ends]
    return ca.Function("capsule_points", [q, T], [ca.vertcat(*out)])


class KernelCell:
    """The cell's objects and the arm's capsules as the kernel checks them (module docstring).

    Parameters
    ----------
    robot : Robot
        With its tool.
    cell : problems.cell.Cell
        Objects in the cell frame (the problem as written) and the clearance, m.
    """

    def __init__(self, robot: Robot, cell: Any) -> None:
        self.robot = robot
        self.clearance = float(cell.clearance)
        # the capsules, the objects (cell frame) and the pairs checked: the plan's scene (planner/cell_check.py)
        self.scene = scene = cell.scene(robot)
        self.model, self.tool = scene.model, scene.tool
        #: the objects as the closed forms measure them (their shapes' kernel proxies)
        self.objects: tuple[SceneObject, ...] = tuple(o.proxy(nlp=False) for o in scene.objects)
        #: per object, the capsule indices checked against it
        self.checked: tuple[np.ndarray, ...] = tuple(
            np.flatnonzero(scene.checked[:, j]) for j in range(len(scene.objects))
        )
        self.self_pairs = scene.self_pairs.reshape(-1, 2)
        self.footprint = base_footprint(robot)
        f = _capsule_points_function(robot, self.model)
        points = batch_function(f, 1)
        self._points_state = portable_state(f, points)
        self._points: BatchFunction | VMBatchFunction = points

    def __getstate__(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        d.pop("_points", None)
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        self.__dict__.update(d)
        self._points = evaluator_from_state(self._points_state, 1)

    def segments(self, q: np.ndarray, b2c: np.ndarray) -> np.ndarray:
        """Capsule ends in the cell frame, shape (K, M, 2, 3), m, at joint angles ``q`` (K, 6) of
        placements ``base2cell`` ``b2c`` (K, 4, 4)."""
        pts = self._points(np.ascontiguousarray(q), np.ascontiguousarray(b2c.transpose(0, 2, 1)).reshape(-1, 16))[0]
        return pts.reshape(len(q), self.model.n_capsules, 2, 3)

    # ------------------------------------------------------------------ base footprint
    def footprint_blocked(self, placements: np.ndarray) -> np.ndarray:
        """Whether each placement's base footprint overlaps an object (any role), shape (P,) bool."""
        import coal

        pl = np.atleast_2d(np.asarray(placements, dtype=float))
        out = np.zeros(len(pl), dtype=bool)
        if not self.objects:
            return out
        radius, height = self.footprint
        local = np.eye(4)
        local[2, 3] = 0.5 * height
        F = base2cell(pl) @ local  # (P, 4, 4) footprint centre in the cell frame
        foot_r = float(np.hypot(radius, 0.5 * height))
        foot = coal.Cylinder(float(radius - FOOTPRINT_TOUCH_TOL_M), float(height - 2.0 * FOOTPRINT_TOUCH_TOL_M))
        req = coal.CollisionRequest()
        req.gjk_tolerance = COAL_GJK_TOLERANCE_M
        for obj, vo in zip(self.scene.objects, self.objects):
            gap = np.linalg.norm(F[:, :3, 3] - vo.pose[:3, 3], axis=1) - foot_r - vo.shape.bounding_radius
            tf_obj = _transform(coal, obj.pose)
            for i in np.flatnonzero((gap < 0.0) & ~out):
                res = coal.CollisionResult()
                hit = coal.collide(foot, _transform(coal, F[i]), obj.geometry, tf_obj, req, res) > 0
                if not hit and obj.shape.surface_only:
                    hit = bool(obj.contains(F[i][None, :3, 3], FOOTPRINT_TOUCH_TOL_M)[0])
                out[i] = hit
        return out

    # ------------------------------------------------------------------ the arm
    def _object_distance(self, seg: np.ndarray, radius: np.ndarray, obj: SceneObject) -> np.ndarray:
        """The smallest capsule distance to ``obj`` per configuration (K,), m, decided against the
        clearance without computing every pair exactly.  A slab test first: a capsule (segment
        ``seg`` (K, m, 2, 3), cell frame, radii ``radius`` (m,)) within the clearance of the object
        has a segment point inside the object's box (its own box, a cylinder's or mesh's enclosing
        box) grown by the radius plus the clearance on every side; a segment that misses that box
        (a few operations per pair) is farther than the clearance, and its pair is reported as the
        clearance (a lower bound).  The other pairs are computed in closed form
        (:func:`models.collision.vectorised.capsule_object_distance`).  So the decision against
        the clearance is the same as with every pair computed."""
        R, t = obj.pose[:3, :3], obj.pose[:3, 3]
        s = (seg - t) @ R  # (K, m, 2, 3) object frame
        p0 = s[:, :, 0]
        d = s[:, :, 1] - p0
        grown = obj.shape.half_extents + (radius + self.clearance)[:, None]  # (m, 3)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d  # +-inf on a zero component: the slab is all or nothing
            t1 = (-grown - p0) * inv
            t2 = (grown - p0) * inv
        lo, hi = np.fmin(t1, t2), np.fmax(t1, t2)  # NaN (0 * inf, on a slab face) ignored
        # the largest entry / smallest exit over x, y, z, elementwise (a reduction over an axis of 3 is slow)
        t_in = np.maximum(np.fmax(np.fmax(lo[..., 0], lo[..., 1]), lo[..., 2]), 0.0)
        t_out = np.minimum(np.fmin(np.fmin(hi[..., 0], hi[..., 1]), hi[..., 2]), 1.0)
        out = np.full(t_in.shape, self.clearance)
        near = t_in <= t_out  # (K, m)
        if not near.any():
            return out.min(axis=1)
        kk, cc = np.nonzero(near)
        # a point of the segment within the clearance (at the middle of its span in the grown box,
        # or at either end of the span): a violation; its distance, an upper bound, is reported
        tm = np.stack([t_in[kk, cc], 0.5 * (t_in[kk, cc] + t_out[kk, cc]), t_out[kk, cc]], axis=-1)  # (V, 3)
        x = p0[kk, cc][:, None, :] + tm[..., None] * d[kk, cc][:, None, :]  # (V, 3, 3) object frame
        if obj.shape.exact_in_kernel:  # the probes' distances are exact: an upper bound of the pair's
            probe = obj.shape.signed_distance(x).min(axis=-1) - radius[cc]  # (V,)
            hit = probe < self.clearance
            out[kk[hit], cc[hit]] = probe[hit]
        else:
            hit = np.zeros(len(kk), dtype=bool)
        todo = ~hit
        if todo.any():
            out[kk[todo], cc[todo]] = capsule_object_distance(seg[kk[todo], cc[todo]], radius[cc[todo]], obj)
        return out.min(axis=1)

    def min_distance(self, q: np.ndarray, b2c: np.ndarray) -> np.ndarray:
        """A signed distance of each configuration, decided against the clearance, m: at or above
        the clearance, a lower bound of its smallest distance to the objects and between its self
        pairs (pairs the slab test or the bounding spheres keep beyond the clearance are not
        computed); below it, the distance of the first violation found (objects first, then self
        pairs: a configuration stops being checked at its first violation, so the value need not be
        its smallest).  So ``min_distance(...) < clearance`` is the same decision as with every
        pair computed exactly.

        Parameters
        ----------
        q : ndarray, shape (K, 6)
            Joint angles in the placement's base frame, rad.
        b2c : ndarray, shape (K, 4, 4)
            ``base2cell`` of each configuration's placement.

        Returns
        -------
        ndarray, shape (K,), m (``inf`` without any pair).
        """
        K = len(q)
        out = np.full(K, np.inf)
        if K == 0:
            return out
        seg = self.segments(q, b2c)  # (K, M, 2, 3) cell frame
        live = np.arange(K)  # configurations without a violation so far
        for obj, idx in zip(self.objects, self.checked):
            if idx.size == 0 or live.size == 0:
                continue
            d = self._object_distance(seg[live][:, idx], self.model.radius[idx], obj)
            np.minimum.at(out, live, d)
            live = live[out[live] >= self.clearance]
        if len(self.self_pairs) and live.size:
            s = seg[live]
            mid = 0.5 * (s[:, :, 0] + s[:, :, 1])  # (L, M, 3)
            ab = s[:, :, 1] - s[:, :, 0]
            hl = 0.5 * np.sqrt(np.einsum("kmi,kmi->km", ab, ab)) + self.model.radius
            a, b = self.self_pairs[:, 0], self.self_pairs[:, 1]
            dm = mid[:, a] - mid[:, b]
            lb = np.sqrt(np.einsum("kpi,kpi->kp", dm, dm)) - hl[:, a] - hl[:, b]
            near = lb < self.clearance
            d = lb
            if near.any():
                kk, pp = np.nonzero(near)
                d = lb.copy()
                d[kk, pp] = capsule_distance(
                    s[kk, a[pp]], self.model.radius[a[pp]], s[kk, b[pp]], self.model.radius[b[pp]]
                )
            np.minimum.at(out, live, d.min(axis=1))
        return out
