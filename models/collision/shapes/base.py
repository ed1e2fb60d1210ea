"""The shape interface and its registry: what every kind of collision shape must do.

A :class:`Shape` is one primitive in its own frame (a box of extents, a cylinder along its z axis, a
sphere, a triangle mesh, ...): its parameters, and everything the product asks of it, in one class
per kind (one module each in this package, or in a folder of ``$COMPPLAN_SHAPE_PATH``,
:mod:`models.collision.shapes`):

* reading: the keys it takes in a problem file's ``[[cell.objects]]`` and ``[[robot.tool.body]]``
  tables (:attr:`Shape.keys`, ``size`` with :attr:`Shape.size_length` numbers, or ``file`` and
  ``scale``), :meth:`Shape.build` (checked), its dictionary form (:meth:`Shape.to_dict`, what
  ``summary.json`` records) and back (:meth:`Shape.check_record`, :meth:`Shape.from_record`);
* the exact distance through `coal <https://github.com/coal-library/coal>`_ (:meth:`Shape.geometry`);
* point signed distances in NumPy (:meth:`Shape.signed_distance`, :meth:`Shape.contains`) and in
  CasADi (:meth:`Shape.signed_distance_sx`, the posture NLP's clearance constraints), and the
  capsule distance of the placement kernel in closed form (:meth:`Shape.capsule_distance`); a shape
  without a closed form stands in there by a **proxy** that holds it (:meth:`Shape.nlp_proxy`,
  :meth:`Shape.kernel_proxy`: a mesh by its oriented or axis-aligned bounding box);
* bounds: its enclosing box (:attr:`Shape.half_extents`), sphere (:meth:`Shape.bounding_sphere`)
  and capsule (:meth:`Shape.bounding_capsule`, a tool element's capsule);
* drawing: its triangles (:meth:`Shape.triangles`) and its outline seen from above
  (:meth:`Shape.outline_xy`).

Units: m.  Frames: the shape's own frame unless a pose ``shape2x`` is given.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from ...errors import InputError

__all__ = [
    "NORM_EPS_M",
    "OUTLINE_CIRCLE_POINTS",
    "SHAPE_KEYS",
    "Shape",
    "box_signed_distance",
    "excess_distance_sx",
    "outline_ring",
    "register_shape",
    "shape_class",
    "shape_kinds",
    "shape_to_dict",
]

#: Points on a circle when a round shape's outline is drawn from above.
OUTLINE_CIRCLE_POINTS = 48
#: The keys a shape kind may take in a problem file's shape table, besides the name, the shape, the
#: pose (``xyz``, ``rpy``, ``rpy_deg``) and an object's ``role`` and ``frame``.
SHAPE_KEYS = ("size", "file", "scale")

#: Regularisation of the Euclidean norms of the CasADi distances (m): keeps their gradients finite at zero.
NORM_EPS_M = 1e-9

_REGISTRY: dict[str, type[Shape]] = {}


def box_signed_distance(q: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Signed distance of points ``q`` (..., k) from the box ``|x_i| <= half_i`` (k-D), m
    (negative inside); the one point-box distance (boxes, cylinders as a 2-D box in (rho, z), the
    placement kernel's probes)."""
    d = np.abs(q) - half
    return np.linalg.norm(np.maximum(d, 0.0), axis=-1) + np.minimum(np.max(d, axis=-1), 0.0)


def excess_distance_sx(d: Any) -> Any:
    """CasADi twin of :func:`box_signed_distance` from the excesses ``d = |q| - half`` (k x 1 SX):
    the outside part's norm regularised by :data:`NORM_EPS_M` (zero at the surface), m."""
    import casadi as ca

    outside = ca.sqrt(ca.sumsqr(ca.fmax(d, 0.0)) + NORM_EPS_M**2) - NORM_EPS_M
    return outside + ca.fmin(ca.mmax(d), 0.0)


def shape_to_dict(name: str, shape: Shape, shape2frame: np.ndarray) -> dict[str, Any]:
    """A posed shape (cell object or tool element) in the problem-file schema: name, shape, its
    keys (:meth:`Shape.to_dict`: size, or a mesh's file and scale), and its pose ``shape2frame`` as
    xyz (m) and rpy (rad)."""
    from ...transforms import matrix_to_rpy

    d: dict[str, Any] = {"name": name, "shape": shape.kind, **shape.to_dict()}
    d["xyz"] = [float(v) for v in shape2frame[:3, 3]]
    d["rpy"] = [float(v) for v in matrix_to_rpy(shape2frame[:3, :3])]
    return d


def outline_ring() -> np.ndarray:
    """:data:`OUTLINE_CIRCLE_POINTS` points on the unit circle, (K, 2)."""
    a = np.linspace(0.0, 2.0 * np.pi, OUTLINE_CIRCLE_POINTS, endpoint=False)
    return np.column_stack([np.cos(a), np.sin(a)])


class Shape:
    """One collision shape in its own frame (module docstring); a subclass per kind.

    Attributes
    ----------
    kind : str
        The kind's name (``box``), the value of ``shape`` in files and summaries.
    keys : tuple of str
        Its keys in a shape table (of :data:`SHAPE_KEYS`).
    size_length : int
        Numbers in its ``size`` (kinds with the key ``size``).
    size_meaning : str
        What ``size`` holds, for messages (``[radius] (m)``).
    exact_in_kernel : bool
        Whether :meth:`capsule_distance` is exact (else a conservative bound).
    surface_only : bool
        Whether coal sees only its surface (a BVH of triangles): a point or capsule wholly inside
        is then found by :meth:`contains`.
    urdf_element : str or None
        The URDF ``<geometry>`` element it reads (``box``; :meth:`from_urdf`), None: none.
    size : ndarray
        Its size, m (a mesh: the extents of its axis-aligned bounding box).
    """

    kind: ClassVar[str] = ""
    keys: ClassVar[tuple[str, ...]] = ("size",)
    size_length: ClassVar[int] = 0
    size_meaning: ClassVar[str] = ""
    exact_in_kernel: ClassVar[bool] = True
    surface_only: ClassVar[bool] = False
    urdf_element: ClassVar[str | None] = None

    size: np.ndarray

    # ------------------------------------------------------------------ building and records
    def __init__(self, size: np.ndarray) -> None:
        self.size = np.asarray(size, dtype=float)

    @classmethod
    def build(
        cls, size: Any, what: str, mesh: Any = None, mesh_file: str | None = None, mesh_scale: float = 1.0
    ) -> Shape:
        """The shape from its values, checked (``what``: the owner in messages, ``cell object 'x'``).

        The default takes ``size``: :attr:`size_length` finite positive numbers, m.

        Raises
        ------
        InputError
        """
        s = np.asarray(size, dtype=float).reshape(-1)
        if s.shape != (cls.size_length,) or not np.all(np.isfinite(s)) or np.any(s <= 0.0):
            raise InputError(
                f"{what}: a {cls.kind} needs {cls.size_length} positive size(s), got {np.asarray(size).tolist()}"
            )
        return cls(s)

    def to_dict(self) -> dict[str, Any]:
        """Its keys as ``summary.json`` and the problem file hold them (SI)."""
        return {"size": [float(v) for v in self.size]}

    @classmethod
    def check_record(cls, rec: Mapping[str, Any], key: str, vector: Any) -> dict[str, Any]:
        """Its keys of a recorded shape (:meth:`to_dict`) read back and checked, without loading
        anything; ``vector(where, value, n)`` reads n finite numbers.

        Raises
        ------
        InputError
            Naming ``key`` (``problem.cell.objects[1]``), the value and what was expected.
        """
        size = vector(f"{key}.size", rec.get("size"), cls.size_length)
        if np.any(size <= 0):
            raise InputError(f"{key}.size = {rec.get('size')!r}; expected {cls.size_length} numbers > 0 (m)")
        return {"size": size}

    @classmethod
    def from_urdf(cls, element: Any) -> Shape:
        """The shape of a URDF ``<geometry>``'s :attr:`urdf_element` (as ``yourdfpy`` reads it),
        unchecked (the URDF reader checks what it makes of it)."""
        raise NotImplementedError

    @classmethod
    def from_record(cls, rec: Mapping[str, Any]) -> Shape:
        """The shape of a checked record (:meth:`check_record`'s keys)."""
        return cls(np.asarray(rec["size"], dtype=float))

    # ------------------------------------------------------------------ coal
    def geometry(self) -> Any:
        """Its coal collision geometry, in its own frame."""
        raise NotImplementedError

    # ------------------------------------------------------------------ signed distances
    def signed_distance(self, q: np.ndarray) -> np.ndarray:
        """Signed distance (m, negative inside) of points ``q`` (..., 3) in its frame."""
        raise NotImplementedError

    def contains(self, q: np.ndarray, tol: float) -> np.ndarray:
        """Whether points ``q`` (N, 3) in its frame lie inside it by more than ``tol`` (m), (N,) bool."""
        return self.signed_distance(q) < -tol

    def encloses_any(self, q: np.ndarray) -> bool:
        """Whether one of the points ``q`` (N, 3), its frame, lies inside it where coal sees only
        its surface (:attr:`surface_only`); False for a shape coal sees solid."""
        return False

    def signed_distance_sx(self, local: Any) -> Any:
        """CasADi signed distance (m) of a point ``local`` (3 x 1 SX, its frame), with gradients
        (norms regularised: :data:`models.collision.shapes.NORM_EPS_M`)."""
        raise NotImplementedError

    def nlp_proxy(self) -> tuple[Shape, np.ndarray | None]:
        """The shape the posture NLP measures (holding this one) and its frame in this shape's
        frame (None: the same frame)."""
        return self, None

    def kernel_proxy(self) -> tuple[Shape, np.ndarray | None]:
        """The shape the placement kernel measures (holding this one) and its frame (None: same)."""
        return self, None

    def capsule_distance(self, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray | float) -> np.ndarray:
        """Signed distances (m) of capsules (segment ends ``p0``, ``p1`` (..., 3) in its frame,
        ``radii``) from it, closed form (exact, or a lower bound: :attr:`exact_in_kernel`)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ bounds
    @property
    def half_extents(self) -> np.ndarray:
        """Half extents of a box about its origin, along its axes, that holds it, (3,) m."""
        raise NotImplementedError

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about its origin that holds it, m."""
        return float(np.linalg.norm(self.half_extents))

    def bounding_sphere(self) -> tuple[np.ndarray | None, float]:
        """Centre (its frame; None: its origin) and radius (m) of a sphere holding it."""
        return None, self.bounding_radius

    def bounding_capsule(self) -> tuple[np.ndarray, np.ndarray, float]:
        """A capsule holding it: segment ends (3,) in its frame and radius, m."""
        raise NotImplementedError

    # ------------------------------------------------------------------ drawing
    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Its surface as triangles in its frame: vertices (V, 3) m, faces (F, 3) int."""
        raise NotImplementedError

    def outline_points(self) -> np.ndarray:
        """Points (K, 3) in its frame whose convex hull seen from above is its outline."""
        return np.asarray(self.triangles()[0], dtype=float)

    def outline_xy(self, shape2x: np.ndarray) -> np.ndarray:
        """Points (K, 2) whose convex hull is its outline seen from above in frame x, m."""
        pts = self.outline_points()
        return (pts @ shape2x[:3, :3].T + shape2x[:3, 3])[:, :2]


def register_shape(cls: type[Shape]) -> type[Shape]:
    """Class decorator: register a shape kind under its :attr:`Shape.kind`.

    Raises
    ------
    InputError
        No kind, a kind registered already, a key outside :data:`SHAPE_KEYS`.
    """
    if not isinstance(cls.kind, str) or not cls.kind:
        raise InputError(f"shape class {cls.__name__}: set its kind (a non-empty string)")
    if cls.kind in _REGISTRY:
        raise InputError(f"shape kind {cls.kind!r} is registered already ({_REGISTRY[cls.kind].__name__})")
    bad = [k for k in cls.keys if k not in SHAPE_KEYS]
    if bad:
        raise InputError(f"shape kind {cls.kind!r}: keys {bad} are not shape keys {list(SHAPE_KEYS)}")
    _REGISTRY[cls.kind] = cls
    return cls


def shape_kinds() -> tuple[str, ...]:
    """The registered kinds, in registration order."""
    return tuple(_REGISTRY)


def shape_class(kind: str) -> type[Shape]:
    """The class of a registered kind (KeyError if none)."""
    return _REGISTRY[kind]
