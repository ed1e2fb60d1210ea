"""The triangle mesh: a closed surface read from an STL, OBJ or PLY file (``file``, ``scale``).

Its vertices are the file's times ``scale`` (m) in the shape's frame (the file's own origin).  coal
sees it as a BVH of its triangles (:attr:`Mesh.surface_only`: a point or capsule wholly inside is
found by ``trimesh``'s inside test); it has no closed form: the posture NLP measures its oriented
bounding box and the placement kernel its axis-aligned one (both hold it, so both are
conservative); its bounding capsule lies along the principal axis of its vertices.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import InputError
from .base import Shape, register_shape
from .box import Box

__all__ = [
    "Mesh",
]

#: Added to a mesh's capsule radius, m: rounding in the fit must not leave a vertex outside.
FIT_MARGIN_M = 1e-9


def mesh_capsule(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule holding every vertex (V, 3): along their principal axis through their centroid,
    radius the largest distance from that axis, ends as close as the vertices allow (the capsule is
    convex, so it holds the vertices' convex hull and with it the closed mesh)."""
    c = vertices.mean(axis=0)
    X = vertices - c
    _, vecs = np.linalg.eigh(X.T @ X)
    u = vecs[:, -1]  # largest variance
    t = X @ u
    rho = np.linalg.norm(X - t[:, None] * u, axis=1)
    r = float(rho.max())
    h = np.sqrt(np.maximum(r * r - rho * rho, 0.0))  # how far along the axis each vertex lets an end stop short
    hi = float(np.max(t - h))  # the upper end must reach at least this far
    lo = float(np.min(t + h))  # the lower end at least this far back
    if lo > hi:  # a short, fat cloud: any point between them holds all
        lo = hi = 0.5 * (lo + hi)
    return c + lo * u, c + hi * u, r + FIT_MARGIN_M


def mesh_bvh(mesh: Any) -> Any:
    """A coal BVH model (OBBRSS) of a ``trimesh.Trimesh``'s triangles (vertices as they are, m)."""
    import coal

    verts = coal.StdVec_Vec3s()
    verts.extend(np.asarray(v, dtype=float) for v in mesh.vertices)
    tris = coal.StdVec_Triangle()
    tris.extend(coal.Triangle(int(i), int(j), int(k)) for i, j, k in mesh.faces)
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(mesh.faces), len(mesh.vertices))
    bvh.addSubModel(verts, tris)
    bvh.endModel()
    return bvh


@register_shape
class Mesh(Shape):
    """A closed triangle mesh (``trimesh.Trimesh``, vertices in its frame, m).

    Attributes
    ----------
    mesh : trimesh.Trimesh
    mesh_file : str or None
        The file read (resolved path).
    mesh_scale : float
        File unit to m (0.001 for a file in mm).
    """

    kind = "mesh"
    keys = ("file", "scale")
    surface_only = True
    exact_in_kernel = False

    def __init__(self, mesh: Any, mesh_file: str | None = None, mesh_scale: float = 1.0) -> None:
        super().__init__(np.asarray(mesh.extents, dtype=float))
        self.mesh, self.mesh_file, self.mesh_scale = mesh, mesh_file, mesh_scale

    @classmethod
    def build(
        cls, size: Any, what: str, mesh: Any = None, mesh_file: str | None = None, mesh_scale: float = 1.0
    ) -> Shape:
        if mesh is None or len(getattr(mesh, "vertices", ())) == 0:
            raise InputError(f"{what}: a mesh needs its mesh (with vertices)")
        return cls(mesh, mesh_file, mesh_scale)

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.mesh_file, "scale": self.mesh_scale}

    @classmethod
    def check_record(cls, rec: Mapping[str, Any], key: str, vector: Any) -> dict[str, Any]:
        f, s = rec.get("file"), rec.get("scale", 1.0)
        if not isinstance(f, str) or not f:
            raise InputError(f"{key}.file = {f!r}; expected the mesh file's path")
        if isinstance(s, bool) or not isinstance(s, (int, float)) or not np.isfinite(s) or s <= 0:
            raise InputError(f"{key}.scale = {s!r}; expected a number > 0")
        return {"file": f, "scale": float(s)}

    @classmethod
    def from_record(cls, rec: Mapping[str, Any]) -> Shape:
        """Reads the recorded file again (the caller checks it is the file the run read)."""
        import trimesh

        path = Path(rec["file"]).resolve()
        mesh = trimesh.load_mesh(path, force="mesh")
        mesh.apply_scale(rec["scale"])
        return cls(mesh, str(path), rec["scale"])

    def geometry(self) -> Any:
        return mesh_bvh(self.mesh)

    def signed_distance(self, q: np.ndarray) -> np.ndarray:
        """The closest triangle's distance with the sign of ``trimesh``'s inside test."""
        import trimesh

        return -np.asarray(trimesh.proximity.signed_distance(self.mesh, q), dtype=float)  # trimesh: + inside

    def contains(self, q: np.ndarray, tol: float) -> np.ndarray:
        """Tested only at the points inside its bounding box (the rest are outside)."""
        lo, hi = self.mesh.bounds
        near = np.flatnonzero(np.all((q > lo + tol) & (q < hi - tol), axis=1))
        inside = np.zeros(len(q), dtype=bool)
        if near.size:
            inside[near] = self.signed_distance(q[near]) < -tol
        return inside

    def encloses_any(self, q: np.ndarray) -> bool:
        """``trimesh``'s inside test of a closed mesh (an open one: False)."""
        return bool(self.mesh.is_watertight and np.any(self.mesh.contains(q)))

    def nlp_proxy(self) -> tuple[Shape, np.ndarray | None]:
        """Its oriented bounding box (trimesh)."""
        box = self.mesh.bounding_box_oriented
        half = 0.5 * np.asarray(box.primitive.extents, dtype=float)
        return Box(2.0 * half), np.asarray(box.primitive.transform, dtype=float)

    def kernel_proxy(self) -> tuple[Shape, np.ndarray | None]:
        """Its axis-aligned bounding box in its frame (a bound of the mesh: not exact)."""
        lo, hi = (np.asarray(b, dtype=float) for b in self.mesh.bounds)
        C = np.eye(4)
        C[:3, 3] = 0.5 * (lo + hi)
        box = Box(hi - lo)
        box.exact_in_kernel = False  # type: ignore[misc]
        return box, C

    @property
    def half_extents(self) -> np.ndarray:
        lo, hi = (np.asarray(b, dtype=float) for b in self.mesh.bounds)
        return np.maximum(np.abs(lo), np.abs(hi))

    def bounding_sphere(self) -> tuple[np.ndarray | None, float]:
        """About its bounding box's centre, to its farthest vertex."""
        lo, hi = self.mesh.bounds
        c = 0.5 * (lo + hi)
        return c, float(np.max(np.linalg.norm(self.mesh.vertices - c, axis=1)))

    def bounding_capsule(self) -> tuple[np.ndarray, np.ndarray, float]:
        return mesh_capsule(np.asarray(self.mesh.vertices, dtype=float))

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.mesh.vertices, dtype=float), np.asarray(self.mesh.faces, dtype=np.int64)
