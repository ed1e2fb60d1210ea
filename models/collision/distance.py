"""Distances between capsules and cell objects.

* segments and capsules in closed form: :mod:`models.collision.segments`.
* Objects (:class:`models.collision.scene.SceneObject`: a shape of a registered kind, placed) carry
  their `coal <https://github.com/coal-library/coal>`_ geometries (the maintained hpp-fcl);
  :func:`capsule_shape_distance` asks coal for the signed distance between a capsule and an object
  and its closest points.  Meshes are read with ``trimesh`` into coal BVH models
  (:func:`models.collision.shapes.mesh.mesh_bvh`).

Signed distances: negative is penetration depth.  coal gives it for primitives and convex meshes
(GJK/EPA); for a non-convex mesh coal's depth is per triangle, so a capsule crossing the surface
reports at most the depth past the nearest triangle, and a capsule wholly inside a closed mesh is
found by an inside test of its end points (reported as a penetration of its radius).

Units: m; every point in the base frame unless named otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import coal
import numpy as np

from ..errors import InputError

if TYPE_CHECKING:
    from .scene import SceneObject

__all__ = [
    "CellShape",
    "PairDistance",
    "box_shape",
    "capsule_shape_distance",
    "cylinder_shape",
    "mesh_shape",
    "shape_pair_distance",
    "sphere_shape",
]

#: GJK convergence tolerance handed to coal (m): far below the 1e-6 m the distances are checked to.
COAL_GJK_TOLERANCE_M = 1e-10
#: EPA (penetration) tolerance handed to coal (m).
COAL_EPA_TOLERANCE_M = 1e-10


@dataclass(frozen=True)
class CellShape:
    """A raw coal geometry with its pose (a capsule as coal measures it); the cell's objects are
    :class:`models.collision.scene.SceneObject` s.

    Attributes
    ----------
    name : str
        Used in messages (``table``, ``fixture``).
    geometry : coal.CollisionGeometry
        In the shape's own frame.
    shape2base : ndarray, shape (4, 4)
        The shape's frame in the base frame.
    kind : str
        What it is (``capsule``).
    """

    name: str
    geometry: Any
    shape2base: np.ndarray
    kind: str


@dataclass(frozen=True)
class PairDistance:
    """The signed distance of one pair and its closest points.

    Attributes
    ----------
    distance : float
        Signed distance, m (negative: penetration depth).
    point_a, point_b : ndarray, shape (3,)
        Closest points on the first and second member, base frame, m.
    pair : str
        The pair named for messages, ``"link 3 – table"``.
    """

    distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    pair: str


def _transform(T: np.ndarray) -> Any:
    tf = coal.Transform3s()
    tf.setRotation(np.ascontiguousarray(T[:3, :3], dtype=float))
    tf.setTranslation(np.ascontiguousarray(T[:3, 3], dtype=float))
    return tf


def box_shape(name: str, size: np.ndarray, shape2base: np.ndarray) -> SceneObject:
    """A box of extents ``size`` (3,) m along its x, y, z, centred on its frame's origin."""
    return _posed("box", name, size, shape2base)


def sphere_shape(name: str, radius: float, shape2base: np.ndarray) -> SceneObject:
    """A sphere of ``radius`` m centred on its frame's origin."""
    return _posed("sphere", name, [radius], shape2base)


def cylinder_shape(name: str, radius: float, length: float, shape2base: np.ndarray) -> SceneObject:
    """A cylinder of ``radius`` and ``length`` m along its z axis, centred on its frame's origin."""
    return _posed("cylinder", name, [radius, length], shape2base)


def _posed(kind: str, name: str, size: Any, shape2base: np.ndarray) -> SceneObject:
    from .scene import SceneObject
    from .shapes import shape_class

    return SceneObject(name, shape_class(kind).build(size, f"object '{name}'"), shape2base)


def mesh_shape(name: str, source: Any, shape2base: np.ndarray, scale: float = 1.0) -> SceneObject:
    """A triangle mesh (a ``trimesh.Trimesh`` or an STL/OBJ/PLY file) as a coal BVH model.

    Parameters
    ----------
    name : str
    source : trimesh.Trimesh or path
        The mesh, vertices in its own frame (in the file's unit, times ``scale``).
    shape2base : ndarray, shape (4, 4)
    scale : float
        Vertex unit to m (0.001 for a file in mm).

    Raises
    ------
    InputError
        The file does not exist or holds no triangles.
    """
    import trimesh

    from .scene import SceneObject
    from .shapes.mesh import Mesh

    if isinstance(source, trimesh.Trimesh):
        mesh = source.copy()
    else:
        path = Path(source)
        if not path.is_file():
            raise InputError(f"{path}: no such mesh file (object '{name}')")
        try:
            mesh = trimesh.load_mesh(path, force="mesh")
        except Exception as exc:  # trimesh raises many types on bad files
            raise InputError(f"{path}: cannot read the mesh of object '{name}': {exc}") from None
    if len(mesh.faces) == 0:
        raise InputError(f"{source}: the mesh of object '{name}' has no triangles")
    mesh.apply_scale(float(scale))
    return SceneObject(name, Mesh(mesh), shape2base)


def _request() -> Any:
    req = coal.DistanceRequest()
    req.enable_signed_distance = True
    req.gjk_tolerance = COAL_GJK_TOLERANCE_M
    req.epa_tolerance = COAL_EPA_TOLERANCE_M
    return req


_REQUEST = _request()


def shape_pair_distance(a: CellShape | SceneObject, b: CellShape | SceneObject) -> PairDistance:
    """Signed distance between two shapes through coal, with the closest points (base frame)."""
    res = coal.DistanceResult()
    dist = coal.distance(a.geometry, _transform(a.shape2base), b.geometry, _transform(b.shape2base), _REQUEST, res)
    return PairDistance(
        float(dist), np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2()), f"{a.name} – {b.name}"
    )


def _capsule_frame(p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, float]:
    """A frame centred on the segment with z along it (coal's capsule axis), and its length."""
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = 0.5 * (p0 + p1)
    return T, length


def capsule_shape_distance(
    p0: np.ndarray, p1: np.ndarray, radius: float, obj: SceneObject, name: str = "capsule"
) -> PairDistance:
    """Signed distance between the capsule ``p0-p1`` of ``radius`` (m, base frame) and an object.

    A capsule whose end point lies inside a closed mesh object is reported as penetrating it (the
    distance is then minus the depth past the nearest triangle, at least minus the radius).
    """
    T, length = _capsule_frame(np.asarray(p0, dtype=float), np.asarray(p1, dtype=float))
    cap = CellShape(name, coal.Capsule(float(radius), length), T, "capsule")
    out = shape_pair_distance(cap, obj)
    if obj.shape.surface_only and out.distance > 0:
        local = (np.linalg.inv(obj.shape2base) @ np.array([[*p0, 1.0], [*p1, 1.0]]).T).T[:, :3]
        if obj.shape.encloses_any(local):
            out = PairDistance(-out.distance - float(radius), out.point_a, out.point_b, out.pair)
    return out
