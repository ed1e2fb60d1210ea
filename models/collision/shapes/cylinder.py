"""The cylinder: ``size = [radius, length]`` (m), its axis its frame's z axis, centred on its origin."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..segments import segment_distance
from .base import NORM_EPS_M, Shape, box_signed_distance, excess_distance_sx, outline_ring, register_shape
from .segment_box import segment_box_distance

__all__ = [
    "Cylinder",
]

#: Sides of a cylinder's triangles when it is drawn.
CYLINDER_SECTIONS = 48


@register_shape
class Cylinder(Shape):
    """A cylinder of radius ``size[0]`` and length ``size[1]`` m along its z axis, centred.

    In the placement kernel a conservative bound (:meth:`capsule_distance`): the larger of the
    distances to its enclosing box (half extents radius, radius, half length) and to its enclosing
    capsule (its axis, its radius); both hold it, so neither reports more clearance than the
    cylinder has; exact where the nearest point is on a flat end face or on the side along the
    box's faces, at most ``(sqrt(2) - 1) * radius`` short near the side's diagonals.
    """

    kind = "cylinder"
    size_length = 2
    size_meaning = "[radius, length] (m), the axis along the object's z"
    exact_in_kernel = False
    urdf_element = "cylinder"

    @classmethod
    def from_urdf(cls, element: Any) -> Shape:
        return cls(np.array([float(element.radius), float(element.length)]))

    def geometry(self) -> Any:
        import coal

        return coal.Cylinder(float(self.size[0]), float(self.size[1]))

    def signed_distance(self, q: np.ndarray) -> np.ndarray:
        s = self.size
        rz = np.stack([np.linalg.norm(q[..., :2], axis=-1), q[..., 2]], axis=-1)
        return box_signed_distance(rz, np.array([s[0], 0.5 * s[1]]))

    def signed_distance_sx(self, local: Any) -> Any:
        import casadi as ca

        rho = ca.sqrt(local[0] ** 2 + local[1] ** 2 + NORM_EPS_M**2)
        h = self.half_extents
        return excess_distance_sx(ca.vertcat(rho - float(h[0]), ca.fabs(local[2]) - float(h[2])))

    def capsule_distance(self, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray | float) -> np.ndarray:
        h = self.half_extents
        box = segment_box_distance(p0, p1, h)
        cap, _, _ = segment_distance(p0, p1, np.array([0.0, 0.0, -h[2]]), np.array([0.0, 0.0, h[2]]))
        return np.maximum(box, cap - h[0]) - radii

    @property
    def half_extents(self) -> np.ndarray:
        s = self.size
        return np.array([s[0], s[0], 0.5 * s[1]])

    @property
    def bounding_radius(self) -> float:
        h = self.half_extents
        return float(np.hypot(h[0], h[2]))

    def bounding_capsule(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Its axis (the full length), its radius."""
        s = self.size
        return np.array([0.0, 0.0, -0.5 * s[1]]), np.array([0.0, 0.0, 0.5 * s[1]]), float(s[0])

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        import trimesh

        mesh = trimesh.creation.cylinder(radius=self.size[0], height=self.size[1], sections=CYLINDER_SECTIONS)
        return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)

    def outline_points(self) -> np.ndarray:
        s, ring = self.size, outline_ring()
        return np.vstack([np.column_stack([s[0] * ring, np.full(len(ring), z)]) for z in (-0.5 * s[1], 0.5 * s[1])])
