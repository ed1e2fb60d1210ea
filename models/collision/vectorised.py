"""Capsule–object signed distances in closed form, vectorised in NumPy over any number of capsules.

For the placement sweep (``problems/placement/kernel.py``), where coal's per-pair Python loop
(about 350 us per pose, ``benchmarks/bench_collision.py``) is far too slow.  One call takes N
capsules (segment end points ``(..., 2, 3)`` and radii, base frame) against one object, measured by
its shape's own closed form (:meth:`models.collision.shapes.Shape.capsule_distance`) on the
object's kernel proxy (:meth:`models.collision.scene.SceneObject.proxy`):

* **box** (exact, both signs): :func:`models.collision.shapes.segment_box_distance` minus the radius.
* **sphere** (exact, both signs): the centre's distance to the segment minus both radii.
* **cylinder** (a conservative bound): the larger of the distances to its enclosing box and to its
  enclosing capsule (:class:`models.collision.shapes.cylinder.Cylinder`).
* **mesh** (a conservative bound): its axis-aligned bounding box in the object frame, treated as
  a box.  A capsule that only enters the box's empty corners is reported as touching.

Signed distances: negative is penetration depth.  Units: m; points in the base frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .scene import SceneObject
from .shapes import shape_class

__all__ = ["capsule_object_distance", "vec_object"]


def vec_object(name: str, shape: str, size: np.ndarray, object2base: np.ndarray, mesh: Any = None) -> SceneObject:
    """An object of kind ``shape`` (``size`` m, a mesh's ``mesh``) as the closed forms take it:
    its kernel proxy (:meth:`models.collision.scene.SceneObject.proxy`)."""
    form = shape_class(shape).build(size, f"object '{name}'", mesh)
    return SceneObject(name, form, object2base).proxy(nlp=False)


def capsule_object_distance(segments: np.ndarray, radii: np.ndarray | float, obj: SceneObject) -> np.ndarray:
    """Signed distances between capsules and one object (negative: penetration), m.

    Parameters
    ----------
    segments : ndarray, shape (..., 2, 3)
        Capsule segment ends, base frame, m.
    radii : float or ndarray broadcast to shape (...)
        Capsule radii, m.
    obj : SceneObject
        Measured by its shape's :meth:`~models.collision.shapes.Shape.capsule_distance` (give the
        kernel proxy).

    Returns
    -------
    ndarray, shape (...)
        Exact for boxes and spheres; a lower bound (never more clearance than the object has) for
        cylinders and meshes (module docstring).
    """
    R, t = obj.pose[:3, :3], obj.pose[:3, 3]
    s = (np.asarray(segments, dtype=float) - t) @ R  # (..., 2, 3) in the object frame
    return obj.shape.capsule_distance(s[..., 0, :], s[..., 1, :], radii)
