"""The cell: the objects around the robot (tables, fixtures, walls, the workpiece) as geometry.

A :class:`Cell` is the ``[cell]`` table of a problem file read and checked
(:mod:`problems.problem_file.cell_section`, ``docs/problem-file.md``, "[cell]"): the smallest allowed distance
``clearance`` (m) and its :class:`CellObject` s. An object is a box, a cylinder, a sphere or a
triangle mesh (STL, OBJ, PLY read with ``trimesh``), placed by ``object2base`` (pytransform3d's
naming: it maps object-frame coordinates to the base frame, ``p_base = object2base @ p_object``):

* box: ``size = [x, y, z]`` extents (m) along the object's axes, centred on its origin;
* cylinder: ``size = [radius, length]`` (m), its axis the object's z axis, centred on its origin;
* sphere: ``size = [radius]`` (m), centred on its origin;
* mesh: the file's vertices times ``scale`` (m) in the object frame (the file's own origin).

Each object carries its `coal <https://github.com/coal-library/coal>`_ collision geometry
(``coal.Box``, ``coal.Cylinder`` along z, ``coal.Sphere``, a ``coal.BVHModelOBBRSS`` of the mesh's
triangles) in its own frame, for the pair distances of the collision checks (``models/collision``).
Point queries (:meth:`CellObject.distance_to_point`, :meth:`CellObject.contains`) are closed form
for the primitives (vectorised; checked against coal in ``tests/test_cell_file.py``) and
``trimesh``'s closest points and inside test for meshes. One role may be ``workpiece``: the only
object the cutter may touch. The tool's declared geometry (``[robot.tool]`` body elements and
cutter, :mod:`models.collision.tool`) travels with the cell as :attr:`Cell.tool`.

The robot's base **footprint** (:func:`base_footprint`) is a cylinder about the base z axis from the
mounting plane (z = 0) up to :data:`BASE_FOOTPRINT_HEIGHT_M`, of the arm's base radius: at the
problem's own placement no object may overlap it (:func:`footprint_overlaps`).

Units: m. Frames: the base frame (``docs/conventions.md``). coal and trimesh are imported only
when a cell is built, so problems without ``[cell]`` do not load them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
import numpy as np

from models.collision.shapes import Shape, shape_class, shape_kinds
from models.errors import InputError

if TYPE_CHECKING:  # models.collision loads coal: only when a cell is built
    from models.collision.scene import Scene, SceneObject
    from models.collision.tool import ToolGeometry

__all__ = [
    "BASE_FOOTPRINT_HEIGHT_M",
    "COAL_GJK_TOLERANCE_M",
    "DEFAULT_CLEARANCE_M",
    "FOOTPRINT_TOUCH_TOL_M",
    "OBJECT_ROLES",
    "POINT_INSIDE_TOL_M",
    "Cell",
    "CellObject",
    "base_footprint",
    "footprint_overlaps",
]

#: Default smallest allowed distance between the robot (and tool body) and the objects, and
#: between non-adjacent links, m.
DEFAULT_CLEARANCE_M = 0.005
#: The roles an object may have: ``workpiece`` is the only object the cutter may touch.
OBJECT_ROLES = ("obstacle", "workpiece")
#: A point counts as inside an object when its signed distance is below minus this, m: a path
#: point on an object's surface (up to rounding of the pose) is not inside it.
POINT_INSIDE_TOL_M = 1e-6

#: Radius of the base footprint of an arm without an entry in
#: :data:`BUILTIN_BASE_FOOTPRINT_RADIUS_M`, m (a mid-size arm's base foot).
BASE_FOOTPRINT_RADIUS_M = 0.08
#: Base footprint radius of the built-in arms, m: half the base foot's diameter on the makers'
#: dimension drawings, rounded up to 5 mm (UR5 / UR5e foot 149 mm, UR10 190 mm); the seed paper's
#: ``ar5`` has UR5 proportions.
BUILTIN_BASE_FOOTPRINT_RADIUS_M: dict[str, float] = {"ur5": 0.075, "ur5e": 0.075, "ar5": 0.075, "ur10": 0.095}
#: Height of the base footprint above the mounting plane (z = 0 of the base frame), m: the base
#: housing below the shoulder of the built-in arms (UR5 shoulder height 0.089 m, UR10 0.127 m).
BASE_FOOTPRINT_HEIGHT_M = 0.10
#: The footprint is shrunk by this on every side before the overlap test, m, so that an object
#: that only touches it (a table whose top is the mounting plane) is not an overlap (well above
#: coal's resolution of a touch with :data:`COAL_GJK_TOLERANCE_M`).
FOOTPRINT_TOUCH_TOL_M = 1e-5
#: coal's GJK tolerance in the footprint test, m (its default, 1e-6, reports shapes 1e-6 m apart
#: as colliding).
COAL_GJK_TOLERANCE_M = 1e-9


def _coal() -> Any:
    import coal

    return coal


def _coal_transform(T: np.ndarray) -> Any:
    coal = _coal()
    tf = coal.Transform3s()
    tf.setRotation(np.ascontiguousarray(T[:3, :3], dtype=float))
    tf.setTranslation(np.ascontiguousarray(T[:3, 3], dtype=float))
    return tf


@dataclass(frozen=True, eq=False)
class CellObject:
    """One object of the cell.

    Attributes
    ----------
    name : str
        Unique in its cell; used in messages (``link 3 – fixture``).
    shape : str
        A registered shape kind (:func:`models.collision.shapes.shape_kinds`: ``box``, ``cylinder``,
        ``sphere``, ``mesh`` and the plug-ins').
    size : ndarray
        m: box ``(3,)`` x, y, z extents; cylinder ``(2,)`` radius, length (along z); sphere ``(1,)``
        radius; mesh ``(3,)`` the extents of its axis-aligned bounding box in the object frame.
    object2base : ndarray, shape (4, 4)
        Maps object-frame coordinates to the base frame: the centre (primitives) or the file's
        origin (mesh) and the object's axes in the base frame.
    role : {"obstacle", "workpiece"}
    mesh_file : str or None
        The mesh file read (resolved path), meshes only.
    mesh_scale : float
        Mesh file unit to m (0.001 for a file in mm).
    mesh : trimesh.Trimesh or None
        The mesh in the object frame, scaled to m (meshes only).
    form : models.collision.shapes.Shape
        The shape of its kind (:func:`models.collision.shapes.shape_class`) built from the above:
        every per-kind computation (distances, bounds, triangles, its dictionary form).
    geometry : coal.CollisionGeometry
        Its coal geometry (``form.geometry()``), in the object frame.

    Raises
    ------
    InputError
        Unknown shape or role, a size of the wrong length or not positive, a bad transform, a mesh
        object without its mesh.
    """

    name: str
    shape: str
    size: np.ndarray
    object2base: np.ndarray
    role: str = "obstacle"
    mesh_file: str | None = None
    mesh_scale: float = 1.0
    mesh: Any = field(default=None, repr=False)
    form: Shape = field(init=False, repr=False)
    geometry: Any = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.shape not in shape_kinds():
            raise InputError(
                f"cell object '{self.name}': shape must be one of {list(shape_kinds())}, got {self.shape!r}"
            )
        if self.role not in OBJECT_ROLES:
            raise InputError(f"cell object '{self.name}': role must be one of {list(OBJECT_ROLES)}, got {self.role!r}")
        T = np.asarray(self.object2base, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)) or not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3)):
            raise InputError(f"cell object '{self.name}': object2base must be a finite 4x4 rigid transform")
        object.__setattr__(self, "object2base", T)
        form = shape_class(self.shape).build(
            self.size, f"cell object '{self.name}'", self.mesh, self.mesh_file, self.mesh_scale
        )
        object.__setattr__(self, "form", form)
        object.__setattr__(self, "size", form.size)
        object.__setattr__(self, "geometry", form.geometry())

    @property
    def coal_transform(self) -> Any:
        """``object2base`` as a ``coal.Transform3s``."""
        return _coal_transform(self.object2base)

    def to_object(self, points_base: np.ndarray) -> np.ndarray:
        """Points (N, 3) from the base frame to the object frame, m."""
        P = np.atleast_2d(np.asarray(points_base, dtype=float))
        R, t = self.object2base[:3, :3], self.object2base[:3, 3]
        return (P - t) @ R

    def distance_to_point(self, points_base: np.ndarray) -> np.ndarray:
        """Signed distance of points from the object's surface, m (negative inside).

        Parameters
        ----------
        points_base : ndarray, shape (N, 3) or (3,)
            Points in the base frame, m.

        Returns
        -------
        ndarray, shape (N,)
            The shape's :meth:`~models.collision.shapes.Shape.signed_distance`.
        """
        return self.form.signed_distance(self.to_object(points_base))

    def contains(self, points_base: np.ndarray, tol: float = POINT_INSIDE_TOL_M) -> np.ndarray:
        """Whether points lie inside the object by more than ``tol`` (m), shape (N,) bool."""
        return self.form.contains(self.to_object(points_base), tol)

    def scene_object(self) -> SceneObject:
        """The object as the collision scene holds it (:class:`models.collision.scene.SceneObject`,
        its coal geometry shared)."""
        from models.collision.scene import SceneObject

        return SceneObject.with_geometry(self.name, self.form, self.object2base, self.role, self.geometry)

    def moved(self, new2base: np.ndarray) -> CellObject:
        """The same object with ``object2base`` replaced by ``new2base @ object2base`` (e.g. a
        placement's ``base2cell`` inverse: the cell seen from a moved base)."""
        return CellObject(
            self.name,
            self.shape,
            self.size,
            np.asarray(new2base, dtype=float) @ self.object2base,
            self.role,
            self.mesh_file,
            self.mesh_scale,
            self.mesh,
        )

    def to_dict(self) -> dict[str, Any]:
        """The object in the problem-file schema (SI units, radians, base frame)."""
        from models.collision.tool import shape_to_dict

        d = shape_to_dict(self.name, self.form, self.object2base)
        d["role"] = self.role
        return d


@dataclass(frozen=True, eq=False)
class Cell:
    """The cell's objects and the clearance the plan must keep from them.

    Attributes
    ----------
    objects : tuple of CellObject
        Unique names; at most one with role ``workpiece``.
    clearance : float
        m, the smallest allowed distance between the robot (and tool body) and the objects, and
        between non-adjacent links; in ``[0, MAX_CLEARANCE_M)`` (:mod:`problems.problem_file.cell_section`).
    tool : models.collision.tool.ToolGeometry or None
        The tool's declared body elements and cutter (``[robot.tool]`` ``body`` / ``cutter``, flange
        frame), checked against the objects with the arm; None: the tool is one capsule flange -> TCP
        (:func:`models.collision.tool.with_tool_geometry`). Unchanged by :meth:`moved`.

    Raises
    ------
    InputError
        Duplicate names, more than one workpiece, a negative clearance.
    """

    objects: tuple[CellObject, ...] = ()
    clearance: float = DEFAULT_CLEARANCE_M
    tool: ToolGeometry | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "objects", tuple(self.objects))
        names = [o.name for o in self.objects]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise InputError(f"cell: object names must be unique, repeated: {dup}")
        wps = [o.name for o in self.objects if o.role == "workpiece"]
        if len(wps) > 1:
            raise InputError(f"cell: at most one object may have role 'workpiece', got {wps}")
        if not np.isfinite(self.clearance) or self.clearance < 0.0:
            raise InputError(f"cell: clearance must be >= 0 m, got {self.clearance!r}")

    @property
    def workpiece(self) -> CellObject | None:
        """The object with role ``workpiece``, or None."""
        return next((o for o in self.objects if o.role == "workpiece"), None)

    @property
    def obstacles(self) -> tuple[CellObject, ...]:
        """The objects other than the workpiece."""
        return tuple(o for o in self.objects if o.role != "workpiece")

    @property
    def names(self) -> tuple[str, ...]:
        """The objects' names, in file order."""
        return tuple(o.name for o in self.objects)

    def object(self, name: str) -> CellObject:
        """The object called ``name`` (KeyError if none)."""
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(name)

    def distance_to_point(self, points_base: np.ndarray) -> np.ndarray:
        """Signed distances of points (N, 3) (base frame, m) from every object: shape (N, M), m."""
        P = np.atleast_2d(np.asarray(points_base, dtype=float))
        if not self.objects:
            return np.zeros((len(P), 0))
        return np.column_stack([o.distance_to_point(P) for o in self.objects])

    def contains(self, points_base: np.ndarray, tol: float = POINT_INSIDE_TOL_M) -> np.ndarray:
        """Whether each point (N, 3) lies inside each object: shape (N, M) bool."""
        P = np.atleast_2d(np.asarray(points_base, dtype=float))
        if not self.objects:
            return np.zeros((len(P), 0), dtype=bool)
        return np.column_stack([o.contains(P, tol) for o in self.objects])

    def moved(self, new2base: np.ndarray) -> Cell:
        """Every object moved by ``new2base`` (see :meth:`CellObject.moved`)."""
        return Cell(tuple(o.moved(new2base) for o in self.objects), self.clearance, self.tool)

    def scene(self, robot: Any, arm: Any = None) -> Scene:
        """The collision scene of ``robot`` (with its tool) in this cell
        (:meth:`models.collision.scene.Scene.build`: the arm's capsules, or ``arm``, the tool's, the
        objects and the pairs to check)."""
        from models.collision.scene import Scene

        return Scene.build(robot, [o.scene_object() for o in self.objects], self.tool, self.clearance, arm)

    def mesh_files(self) -> tuple[str, ...]:
        """The mesh files the cell was read from (resolved paths, in object order), then the tool's
        (in element order)."""
        tool = self.tool.mesh_files() if self.tool is not None else ()
        return tuple(o.mesh_file for o in self.objects if o.mesh_file is not None) + tool

    def to_dict(self) -> dict[str, Any]:
        """The ``[cell]`` table in the problem-file schema (SI, radians, base frame)."""
        return {"clearance": self.clearance, "objects": [o.to_dict() for o in self.objects]}


def base_footprint(robot: Any) -> tuple[float, float]:
    """The base footprint of an arm: (radius, height), m.

    A cylinder about the base z axis from the mounting plane z = 0 up to ``height``: the radius of
    :data:`BUILTIN_BASE_FOOTPRINT_RADIUS_M` for a built-in arm (by its name), else
    :data:`BASE_FOOTPRINT_RADIUS_M`; the height :data:`BASE_FOOTPRINT_HEIGHT_M`.
    """
    name = str(getattr(robot, "name", "") or "")
    return BUILTIN_BASE_FOOTPRINT_RADIUS_M.get(name, BASE_FOOTPRINT_RADIUS_M), BASE_FOOTPRINT_HEIGHT_M


def footprint_overlaps(obj: CellObject, radius: float, height: float, tol: float = FOOTPRINT_TOUCH_TOL_M) -> bool:
    """Whether an object overlaps the base footprint (a cylinder of ``radius`` from z = 0 to
    ``height`` about the base z axis, m), by more than ``tol`` (m).

    coal's collision test of the footprint shrunk by ``tol``; a mesh that encloses the footprint
    (no triangle near it; a shape coal sees as its surface only) is caught by its inside test at the
    footprint's centre.
    """
    coal = _coal()
    r, h = radius - tol, height - 2.0 * tol
    foot = coal.Cylinder(float(r), float(h))
    T = np.eye(4)
    T[2, 3] = 0.5 * height
    req, res = coal.CollisionRequest(), coal.CollisionResult()
    req.gjk_tolerance = COAL_GJK_TOLERANCE_M
    if coal.collide(foot, _coal_transform(T), obj.geometry, obj.coal_transform, req, res) > 0:
        return True
    return obj.form.surface_only and bool(obj.contains(T[:3, 3][None, :], tol)[0])
