"""The box: ``size = [x, y, z]`` extents (m) along its axes, centred on its origin."""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import Shape, box_signed_distance, excess_distance_sx, register_shape
from .segment_box import segment_box_distance

__all__ = ["Box"]

#: The corners of the unit cube about the origin, (8, 3).
_CORNERS = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)


@register_shape
class Box(Shape):
    """A box of extents ``size`` (3,) m, centred on its frame's origin."""

    kind = "box"
    size_length = 3
    size_meaning = "[x, y, z] extents (m)"
    urdf_element = "box"

    @classmethod
    def from_urdf(cls, element: Any) -> Shape:
        return cls(np.abs(np.asarray(element.size, dtype=float)))

    def geometry(self) -> Any:
        import coal

        sx, sy, sz = (float(v) for v in self.size)
        return coal.Box(sx, sy, sz)

    def signed_distance(self, q: np.ndarray) -> np.ndarray:
        return box_signed_distance(q, 0.5 * self.size)

    def signed_distance_sx(self, local: Any) -> Any:
        import casadi as ca

        return excess_distance_sx(ca.fabs(local) - ca.DM(self.half_extents))

    def capsule_distance(self, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray | float) -> np.ndarray:
        return segment_box_distance(p0, p1, self.half_extents) - radii

    @property
    def half_extents(self) -> np.ndarray:
        return 0.5 * self.size

    def bounding_capsule(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The segment along its longest side (the full side), radius the cross-section's half-diagonal."""
        s = self.size
        k = int(np.argmax(s))
        cross = np.delete(s, k)
        a, b = np.zeros(3), np.zeros(3)
        a[k], b[k] = -0.5 * s[k], 0.5 * s[k]
        return a, b, 0.5 * float(np.hypot(cross[0], cross[1]))

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        import trimesh

        mesh = trimesh.creation.box(extents=self.size)
        return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)

    def outline_points(self) -> np.ndarray:
        return 0.5 * self.size * _CORNERS
