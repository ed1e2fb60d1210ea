"""The ``[cell]`` section of a problem file: the objects around the robot, read and checked.

``[cell]`` holds ``clearance`` (m, default :data:`problems.cell.DEFAULT_CLEARANCE_M`) and a list
``[[cell.objects]]``, each with ``name``, ``shape`` (box | cylinder | sphere | mesh), ``size`` (m;
primitives), ``file`` and ``scale`` (meshes: STL, OBJ or PLY, a relative path relative to the
problem file), ``xyz`` (m) and ``rpy`` / ``rpy_deg``, ``role`` (obstacle | workpiece) and ``frame``
(``base``, or ``workpiece``: the pose is in a program's ``[workpiece]`` frame). The format is
``docs/problem-file.md``, "[cell]"; :class:`problems.cell.Cell` is what it becomes.

Every error is a :class:`~problems.problem_file.ProblemFileError` naming the problem file, the key
(``cell.objects[2].size``), the value and what was expected; besides the values, the cell is
checked against the problem: no object may overlap the robot's base footprint at the problem's own
placement, and no path point (TCP target) may lie inside an object other than the workpiece.

The tool's collision geometry is read here too (:func:`parse_tool_geometry`): ``[robot.tool]``'s
``[[robot.tool.body]]`` elements (``name``, ``shape``, ``size`` or ``file`` / ``scale``, ``xyz``,
``rpy`` / ``rpy_deg`` in the **flange** frame) and ``[robot.tool.cutter]`` (``radius``, ``length``,
m); it becomes :attr:`problems.cell.Cell.tool` (:mod:`models.collision.tool`). It is checked
whenever the file declares it, and used only with a ``[cell]``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.transforms import rpy_to_matrix, transform
from models.collision.shapes import SHAPE_KEYS, Shape, shape_class, shape_kinds
from problems.cell import (
    DEFAULT_CLEARANCE_M,
    OBJECT_ROLES,
    POINT_INSIDE_TOL_M,
    Cell,
    CellObject,
    base_footprint,
    footprint_overlaps,
)

# The function bodies call the value kinds by their former local names (kept: moved verbatim).
from problems.problem_file.values import (
    VALUES,
    ProblemFileError,
    err,
    number,
    positive,
    rpy_angles,
    vector,
)

__all__ = [
    "parse_cell",
    "parse_tool_geometry",
]

#: The keys of ``[cell]``.
CELL_KEYS = ("clearance", "objects")
#: The keys of one ``[[cell.objects]]`` table.
OBJECT_KEYS = ("name", "shape", "size", "file", "scale", "xyz", "rpy", "rpy_deg", "role", "frame")
#: The keys of one ``[[robot.tool.body]]`` table (a tool body element, pose in the flange frame).
TOOL_BODY_KEYS = ("name", "shape", "size", "file", "scale", "xyz", "rpy", "rpy_deg")
#: A clearance at or above this (m) is implausible: millimetres given under the metre key.
MAX_CLEARANCE_M = 0.1
#: The mesh file types read (by suffix, lower case).
MESH_SUFFIXES = (".stl", ".obj", ".ply")
#: The frames an object's pose may be given in: the robot's base frame, or a program's
#: ``[workpiece]`` frame (``program2base``).
OBJECT_FRAMES = ("base", "workpiece")


def parse_cell(
    where: str,
    data: Mapping[str, Any],
    base_dir: Path | None,
    robot: Any,
    positions: np.ndarray,
    program: Any = None,
) -> Cell | None:
    """The optional ``[cell]`` table, read and checked against the problem.

    Parameters
    ----------
    where : str
        The problem file, for messages.
    data : mapping
        The parsed problem file.
    base_dir : Path or None
        The problem file's folder: a relative mesh ``file`` is resolved against it.
    robot : models.robot.Robot
        The robot with its tool: its base footprint (:func:`problems.cell.base_footprint`).
    positions : ndarray, shape (N, 3)
        The path's TCP targets, base frame, m.
    program : problems.program_section.ProgramSection, optional
        A program path: its ``workpiece.program2base`` is the frame of ``frame = "workpiece"`` and
        its program lines name the waypoints in messages.

    Returns
    -------
    Cell or None
        None when the file has no ``[cell]`` (a declared tool geometry is checked all the same,
        :func:`parse_tool_geometry`); else with the tool geometry as ``tool``.

    Raises
    ------
    ProblemFileError
        Naming the file, the key, the value and what was expected.
    """
    tool = parse_tool_geometry(where, data, base_dir, robot.tcp2flange)
    if "cell" not in data:
        return None
    ct = data["cell"]
    if not isinstance(ct, Mapping):
        raise err(where, "cell", f"must be a table, got {ct!r}")
    VALUES.unknown_keys(f"{where}: [cell]", ct, CELL_KEYS)
    clearance = number(where, "cell.clearance", ct.get("clearance", DEFAULT_CLEARANCE_M))
    if not 0.0 <= clearance < MAX_CLEARANCE_M:
        hint = " (millimetres given? the clearance is in m)" if clearance >= MAX_CLEARANCE_M else ""
        raise err(where, "cell.clearance", f"must be in [0, {MAX_CLEARANCE_M:g}) m, got {clearance!r}{hint}")
    raw = ct.get("objects", [])
    if not isinstance(raw, list) or not all(isinstance(t, Mapping) for t in raw):
        raise err(where, "cell.objects", f"must be a list of tables ([[cell.objects]]), got {raw!r}")
    program2base = program.workpiece.program2base if program is not None else None
    objects: list[CellObject] = []
    for i, tab in enumerate(raw):
        obj = _parse_object(where, f"cell.objects[{i}]", tab, base_dir, program2base)
        for j, other in enumerate(objects):
            if other.name == obj.name:
                raise err(
                    where,
                    f"cell.objects[{i}].name",
                    f"= {obj.name!r} repeats cell.objects[{j}]'s; names must be unique",
                )
        objects.append(obj)
    wps = [i for i, o in enumerate(objects) if o.role == "workpiece"]
    if len(wps) > 1:
        raise err(
            where,
            f"cell.objects[{wps[1]}].role",
            f"= 'workpiece' for '{objects[wps[1]].name}', but '{objects[wps[0]].name}' (cell.objects[{wps[0]}]) "
            "is the workpiece already; at most one object may be the workpiece",
        )
    cell = Cell(tuple(objects), clearance, tool)
    _check_footprint(where, cell, robot)
    _check_path_points(where, cell, np.asarray(positions, dtype=float), program)
    return cell


def parse_tool_geometry(
    where: str, data: Mapping[str, Any], base_dir: Path | None, tcp2flange: np.ndarray | None = None
) -> Any:
    """The tool's collision geometry: ``[[robot.tool.body]]`` and ``[robot.tool.cutter]``, or None.

    Parameters
    ----------
    where : str
        The problem file, for messages.
    data : mapping
        The parsed problem file (``[robot.tool]`` was checked for its keys by the ``[robot]`` parser).
    base_dir : Path or None
        The problem file's folder: a relative mesh ``file`` is resolved against it.

    Returns
    -------
    models.collision.tool.ToolGeometry or None
        None when neither ``body`` nor ``cutter`` is given.

    Raises
    ------
    ProblemFileError
        Naming the file, the key (``robot.tool.body[1].shape``, ``robot.tool.cutter.radius``), the
        value and what was expected: not a list of tables / a table, an unknown key, a missing or
        repeated or reserved name, an unknown shape, a size of the wrong count or not positive or
        implausible (millimetres?), a mesh not found / not readable / not closed / implausibly large
        (millimetres read as metres), a cutter radius or length not positive or implausible. A
        cutter longer than the flange -> TCP distance is accepted.
    """
    robot = data.get("robot")
    tt = robot.get("tool") if isinstance(robot, Mapping) else None
    if not isinstance(tt, Mapping) or ("body" not in tt and "cutter" not in tt):
        return None
    from models.collision.tool import ToolGeometry  # loads coal: only for a declared tool

    raw = tt.get("body", [])
    if not isinstance(raw, list) or not all(isinstance(t, Mapping) for t in raw):
        raise err(where, "robot.tool.body", f"must be a list of tables ([[robot.tool.body]]), got {raw!r}")
    elements: list[Any] = []
    for i, tab in enumerate(raw):
        key = f"robot.tool.body[{i}]"
        e = _parse_tool_element(where, key, tab, base_dir)
        for j, other in enumerate(elements):
            if other.name == e.name:
                raise err(where, f"{key}.name", f"= {e.name!r} repeats robot.tool.body[{j}]'s; names must be unique")
        elements.append(e)
    from problems.problem_file.cutter_section import parse_tool_cutter  # one home for the cutter

    cutter = parse_tool_cutter(where, data, tcp2flange)
    return ToolGeometry(tuple(elements), cutter)


def _parse_tool_element(where: str, key: str, tab: Mapping[str, Any], base_dir: Path | None) -> Any:
    """One ``[[robot.tool.body]]`` table (``key`` = ``robot.tool.body[i]``) as a
    :class:`models.collision.tool.ToolElement`."""
    from models.collision.tool import ToolElement, reserved_name

    VALUES.unknown_keys(f"{where}: [{key}]", tab, TOOL_BODY_KEYS)
    name = tab.get("name")
    if not isinstance(name, str) or not name.strip():
        raise err(where, f"{key}.name", f"must be a non-empty string, got {name!r}")
    name = name.strip()
    if reserved_name(name):
        raise err(
            where,
            f"{key}.name",
            f"= {name!r} is the name of a capsule already (base, link i, tool, cutter); choose another",
        )
    shape = tab.get("shape")
    if shape not in shape_kinds():
        raise err(where, f"{key}.shape", f"must be one of {list(shape_kinds())} (tool element '{name}'), got {shape!r}")
    element2flange = _pose(where, key, tab)
    v = _shape_values(where, key, name, shape_class(shape), tab, base_dir, "tool element")
    return ToolElement(name, shape, v["size"], element2flange, v["mesh"], v["file"], v["scale"])


def _pose(where: str, key: str, tab: Mapping[str, Any]) -> np.ndarray:
    """The table's pose from ``xyz`` (m, checked plausible) and ``rpy`` / ``rpy_deg``: 4x4, mapping
    the shape's coordinates to its frame's."""
    xyz = vector(where, f"{key}.xyz", tab.get("xyz", [0.0, 0.0, 0.0]), 3)
    if np.max(np.abs(xyz)) > PLAUSIBLE_POSITION_MAX_M:
        raise err(
            where,
            f"{key}.xyz",
            f"= {xyz.tolist()} m is implausible (> {PLAUSIBLE_POSITION_MAX_M:g} m); in metres (millimetres given?)",
        )
    rpy = rpy_angles(where, tab, f"{key}.")
    return transform(rpy_to_matrix(np.zeros(3) if rpy is None else rpy), xyz)


def _parse_object(
    where: str, key: str, tab: Mapping[str, Any], base_dir: Path | None, program2base: np.ndarray | None
) -> CellObject:
    """One ``[[cell.objects]]`` table (``key`` = ``cell.objects[i]``)."""
    VALUES.unknown_keys(f"{where}: [{key}]", tab, OBJECT_KEYS)
    name = tab.get("name")
    if not isinstance(name, str) or not name.strip():
        raise err(where, f"{key}.name", f"must be a non-empty string, got {name!r}")
    name = name.strip()
    shape = tab.get("shape")
    if shape not in shape_kinds():
        raise err(where, f"{key}.shape", f"must be one of {list(shape_kinds())} (object '{name}'), got {shape!r}")
    role = tab.get("role", "obstacle")
    if role not in OBJECT_ROLES:
        raise err(where, f"{key}.role", f"must be one of {list(OBJECT_ROLES)} (object '{name}'), got {role!r}")
    object2frame = _pose(where, key, tab)
    object2base = _in_base(where, key, tab.get("frame", "base"), object2frame, program2base)
    v = _shape_values(where, key, name, shape_class(shape), tab, base_dir, "object")
    return CellObject(name, shape, v["size"], object2base, role, v["file"], v["scale"], v["mesh"])


def _shape_values(
    where: str, key: str, name: str, kind: type[Shape], tab: Mapping[str, Any], base_dir: Path | None, what: str
) -> dict[str, Any]:
    """The values of a shape table's keys the kind declares (:attr:`~models.collision.shapes.Shape.keys`):
    ``size`` (:func:`_size`), ``file`` and ``scale`` (:func:`_read_mesh`); a shape key it does not
    take is an error.  ``what``: the kind of thing in messages (``object``, ``tool element``).

    Returns
    -------
    dict
        ``size`` (ndarray, m; zeros without the key), ``mesh``, ``file`` (resolved path) and ``scale``.
    """
    for k in SHAPE_KEYS:
        if k in tab and k not in kind.keys:
            if k == "size":
                note = f"does not apply to a {kind.kind} ({what} '{name}': the file gives its size)"
            else:
                owners = " or ".join(repr(c) for c in shape_kinds() if k in shape_class(c).keys)
                note = f"only applies to shape {owners} ({what} '{name}' is a {kind.kind})"
            raise err(where, f"{key}.{k}", note)
    out: dict[str, Any] = {"size": np.zeros(3), "mesh": None, "file": None, "scale": 1.0}
    if "size" in kind.keys:
        out["size"] = _size(where, key, name, kind, tab, what)
    if "file" in kind.keys:
        mesh, path, scale = _read_mesh(where, key, name, tab, base_dir, what)
        out.update(mesh=mesh, file=str(path), scale=scale)
    return out


def _in_base(where: str, key: str, frame: Any, object2frame: np.ndarray, program2base: np.ndarray | None) -> np.ndarray:
    """``object2base`` from the pose in ``frame`` (``base``, or a program's ``workpiece`` frame)."""
    if frame not in OBJECT_FRAMES:
        raise err(where, f"{key}.frame", f"must be one of {list(OBJECT_FRAMES)}, got {frame!r}")
    if frame == "base":
        return object2frame
    if program2base is None:
        raise err(
            where,
            f"{key}.frame",
            "= 'workpiece' needs a program path ([path] kind 'gcode' or 'toolpath_csv') and its [workpiece]",
        )
    return program2base @ object2frame


def _size(where: str, key: str, name: str, kind: type[Shape], tab: Mapping[str, Any], what: str) -> np.ndarray:
    """A shape's ``size``: the kind's count of positive, plausible lengths (m); ``what``: the kind
    of thing in messages (``object``, ``tool element``)."""
    n = kind.size_length
    raw = tab.get("size")
    if not isinstance(raw, list) or len(raw) != n:
        raise err(
            where,
            f"{key}.size",
            f"must be {n} number(s) for a {kind.kind}: {kind.size_meaning} ({what} '{name}'), got {raw!r}",
        )
    size = np.array([positive(where, f"{key}.size[{j}]", v) for j, v in enumerate(raw)])
    if np.max(size) > PLAUSIBLE_POSITION_MAX_M:
        raise err(
            where,
            f"{key}.size",
            f"= {size.tolist()} m is implausible for {what} '{name}' (> {PLAUSIBLE_POSITION_MAX_M:g} m); "
            "sizes are in metres (millimetres given?)",
        )
    return size


def _read_mesh(
    where: str, key: str, name: str, tab: Mapping[str, Any], base_dir: Path | None, what: str = "object"
) -> tuple[Any, Path, float]:
    """A mesh's file read with trimesh, scaled to m, checked closed and plausibly sized; ``what``:
    the kind of thing in messages (``object``, ``tool element``)."""
    import trimesh
    from trimesh import grouping

    raw = tab.get("file")
    if not isinstance(raw, str) or not raw:
        raise err(
            where,
            f"{key}.file",
            f"is required for shape 'mesh' ({what} '{name}'): an STL, OBJ or PLY file, got {raw!r}",
        )
    scale = positive(where, f"{key}.scale", tab.get("scale", 1.0))
    path = Path(raw)
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise err(
            where, f"{key}.file", f"= {raw!r} ({what} '{name}'): must be an STL, OBJ or PLY file {list(MESH_SUFFIXES)}"
        )
    if not path.is_file():
        raise err(where, f"{key}.file", f"= {raw!r} ({what} '{name}'): no such file ({path})")
    try:
        mesh = trimesh.load_mesh(path, force="mesh")
    except Exception as exc:  # trimesh raises many types on a bad file
        raise err(where, f"{key}.file", f"= {raw!r} ({what} '{name}'): cannot be read as a mesh: {exc}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise err(where, f"{key}.file", f"= {raw!r} ({what} '{name}'): holds no triangles (not a mesh file, or empty)")
    if not mesh.is_watertight:
        n_open = len(grouping.group_rows(mesh.edges_sorted, require_count=1))
        raise err(
            where,
            f"{key}.file",
            f"= {raw!r} ({what} '{name}'): the mesh is not closed ({n_open} open edge(s)); it must be a closed "
            "surface (repair it, e.g. fill its holes, before use)",
        )
    mesh.apply_scale(scale)
    ext = float(np.max(mesh.extents))
    if ext > PLAUSIBLE_POSITION_MAX_M:
        raise err(
            where,
            f"{key}.file",
            f"= {raw!r} ({what} '{name}'): the mesh is {ext:.4g} m across after scale = {scale:g} "
            f"(> {PLAUSIBLE_POSITION_MAX_M:g} m): read as metres; add scale = 0.001 if the file is in millimetres",
        )
    return mesh, path, scale


def _check_footprint(where: str, cell: Cell, robot: Any) -> None:
    """No object may overlap the robot's base footprint at the problem's own placement."""
    radius, height = base_footprint(robot)
    for i, obj in enumerate(cell.objects):
        if footprint_overlaps(obj, radius, height):
            raise err(
                where,
                f"cell.objects[{i}]",
                f"object '{obj.name}' overlaps the robot's base (footprint: a cylinder of radius {radius:g} m from "
                f"z = 0 to {height:g} m about the base z axis, {getattr(robot, 'name', 'robot')}) at the problem's own "
                "placement; move the object or the robot",
            )


def _check_path_points(where: str, cell: Cell, positions: np.ndarray, program: Any) -> None:
    """No TCP target may lie inside an object other than the workpiece."""
    for i, obj in enumerate(cell.objects):
        if obj.role == "workpiece":
            continue
        inside = np.flatnonzero(obj.contains(positions, POINT_INSIDE_TOL_M))
        if not inside.size:
            continue
        k = int(inside[0])
        depth = -float(obj.distance_to_point(positions[k])[0])
        line = f" (program {program.file}:{int(program.waypoints.line[k])})" if program is not None else ""
        raise ProblemFileError(
            f"{where}: waypoint {k}{line} at {np.round(positions[k], 6).tolist()} m lies {depth:.4g} m inside cell "
            f"object '{obj.name}' (cell.objects[{i}], role {obj.role}); {len(inside)} waypoint(s) are inside it. "
            "Only the workpiece may hold the path: move the object, or give it role = 'workpiece'"
        )
