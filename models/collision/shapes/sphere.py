"""The sphere: ``size = [radius]`` (m), centred on its origin."""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import NORM_EPS_M, Shape, outline_ring, register_shape

__all__ = [
    "Sphere",
]

#: Subdivisions of a sphere's icosphere when it is drawn.
SPHERE_SUBDIVISIONS = 3
#: Squared segment length (m^2) below which a segment is treated as a point.
DEGENERATE_M2 = 1e-24


@register_shape
class Sphere(Shape):
    """A sphere of radius ``size[0]`` m centred on its frame's origin."""

    kind = "sphere"
    size_length = 1
    size_meaning = "[radius] (m)"
    urdf_element = "sphere"

    @classmethod
    def from_urdf(cls, element: Any) -> Shape:
        return cls(np.array([float(element.radius)]))

    @property
    def radius(self) -> float:
        """m."""
        return float(self.size[0])

    def geometry(self) -> Any:
        import coal

        return coal.Sphere(float(self.size[0]))

    def signed_distance(self, q: np.ndarray) -> np.ndarray:
        return np.linalg.norm(q, axis=-1) - self.size[0]

    def signed_distance_sx(self, local: Any) -> Any:
        import casadi as ca

        return ca.sqrt(ca.sumsqr(local) + NORM_EPS_M**2) - self.radius

    def capsule_distance(self, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray | float) -> np.ndarray:
        """The centre's distance to the segment minus both radii (exact)."""
        d = p1 - p0
        L2 = np.einsum("...i,...i->...", d, d)
        t = np.clip(np.einsum("...i,...i->...", -p0, d) / np.where(L2 > DEGENERATE_M2, L2, 1.0), 0.0, 1.0)
        dist = np.linalg.norm(p0 + t[..., None] * d, axis=-1)
        return dist - self.half_extents[0] - radii

    @property
    def half_extents(self) -> np.ndarray:
        return np.full(3, self.size[0])

    @property
    def bounding_radius(self) -> float:
        return float(self.half_extents[0])

    def bounding_capsule(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Its centre (a point), its radius."""
        return np.zeros(3), np.zeros(3), float(self.size[0])

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        import trimesh

        mesh = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=self.size[0])
        return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)

    def outline_xy(self, shape2x: np.ndarray) -> np.ndarray:
        """Seen from above, its equator's circle about its centre."""
        return shape2x[:2, 3] + self.size[0] * outline_ring()
