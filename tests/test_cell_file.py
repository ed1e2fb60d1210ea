"""The ``[cell]`` table of problem files (issue 25): objects read into coal geometry, checked at the
boundary (``problems/cell.py``, ``problems/problem_file/cell_section.py``, ``docs/problem-file.md``, "[cell]").

* every primitive becomes the right coal shape: coal's distances from points outside it, and the
  object's own signed distances from points inside and outside, agree with the closed form written
  here to 1e-9 m, at a pose with a rotation;
* a closed STL box (written with trimesh) gives the same distances, inside tests and coal distances
  as the equivalent box, in metres and in millimetres with ``scale = 0.001``;
* every class of bad input is one ProblemFileError naming the file and the key;
* the cell survives the problem's copies and its round trip through ``to_dict``; its mesh files
  are inputs of the provenance; the shipped problems have no cell.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

coal = pytest.importorskip("coal")
trimesh = pytest.importorskip("trimesh")

from models.transforms import rpy_to_matrix  # noqa: E402
from problems.cell import BASE_FOOTPRINT_HEIGHT_M, base_footprint  # noqa: E402
from problems.problem import load_problem, problem_from_dict, shipped_problems  # noqa: E402
from problems.problem_file import ProblemFileError  # noqa: E402

#: Distances agree with the closed form to this, m.
DIST_TOL_M = 1e-9

HEAD = """
name = "cell_test"
[robot]
model = "ur5"
[path]
kind = "line"
start = [0.40, -0.20, 0.30]
end = [0.40, 0.20, 0.30]
points = 5
[orientation]
rule = "free_tool_axis"
[wrench]
force = [0.0, 0.0, 10.0]
"""

#: An object's pose for the geometry tests: away from the base and the path, turned about all axes.
CENTRE = np.array([0.60, -0.50, 0.40])
RPY_DEG = np.array([20.0, -35.0, 50.0])


def _write(tmp_path: Path, cell: str, head: str = HEAD) -> Path:
    f = tmp_path / "cell.toml"
    f.write_text(head + cell, encoding="utf-8")
    return f


def _obj(**keys: object) -> str:
    """One [[cell.objects]] table from keyword arguments (TOML values via repr of lists / strings)."""
    lines = ["[[cell.objects]]"]
    for k, v in keys.items():
        val = f'"{v}"' if isinstance(v, str) else ("true" if v is True else repr(v))
        lines.append(f"{k} = {val}")
    return "\n".join(lines) + "\n"


def _coal_point_distance(obj, p: np.ndarray) -> float:
    """coal's distance between the object's geometry and the point p (a zero-radius sphere)."""
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    req.gjk_tolerance = 1e-12
    tf = coal.Transform3s()
    tf.setTranslation(np.asarray(p, dtype=float))
    return float(coal.distance(obj.geometry, obj.coal_transform, coal.Sphere(0.0), tf, req, res))


# (shape, size, coal type, points in the object frame with their signed distance by hand)
CASES = [
    (
        "box",
        [0.30, 0.20, 0.40],
        "Box",
        [
            ([0.50, 0.0, 0.0], 0.35),  # in front of the +x face
            ([0.30, 0.30, 0.30], math.sqrt(0.15**2 + 0.2**2 + 0.1**2)),  # off a corner
            ([0.0, -0.25, 0.21], math.hypot(0.15, 0.01)),  # off an edge
            ([0.01, 0.02, 0.03], -0.08),  # inside: nearest the y faces
            ([0.0, 0.0, 0.19], -0.01),  # inside: near the +z face
        ],
    ),
    (
        "cylinder",
        [0.10, 0.50],
        "Cylinder",
        [
            ([0.30, 0.0, 0.10], 0.20),  # beside the mantle
            ([0.30, 0.30, 0.30], math.hypot(math.hypot(0.3, 0.3) - 0.1, 0.05)),  # off the rim
            ([0.0, 0.0, -0.40], 0.15),  # below the -z cap
            ([0.01, 0.02, 0.03], -(0.1 - math.hypot(0.01, 0.02))),  # inside: nearest the mantle
            ([0.0, 0.0, 0.19], -0.06),  # inside on the axis: nearest the cap
        ],
    ),
    (
        "sphere",
        [0.20],
        "Sphere",
        [
            ([0.50, 0.0, 0.0], 0.30),
            ([0.30, 0.30, 0.30], math.sqrt(0.27) - 0.2),
            ([0.01, 0.02, 0.03], math.sqrt(0.0014) - 0.2),
        ],
    ),
]


@pytest.mark.parametrize(("shape", "size", "coal_type", "points"), CASES, ids=[c[0] for c in CASES])
def test_primitive_geometry_and_distances(tmp_path, shape, size, coal_type, points):
    f = _write(
        tmp_path,
        "[cell]\n" + _obj(name="thing", shape=shape, size=size, xyz=CENTRE.tolist(), rpy_deg=RPY_DEG.tolist()),
    )
    cell = load_problem(f).cell
    (obj,) = cell.objects
    assert type(obj.geometry).__name__ == coal_type
    assert cell.clearance == pytest.approx(0.005, abs=0.0)  # the default
    R = rpy_to_matrix(np.radians(RPY_DEG))
    np.testing.assert_allclose(obj.object2base[:3, :3], R, atol=1e-15)
    np.testing.assert_allclose(obj.object2base[:3, 3], CENTRE, atol=0.0)
    local = np.array([p for p, _ in points])
    expected = np.array([d for _, d in points])
    P = local @ R.T + CENTRE
    np.testing.assert_allclose(obj.distance_to_point(P), expected, atol=DIST_TOL_M, rtol=0.0)
    np.testing.assert_array_equal(obj.contains(P), expected < 0)
    for p, d in zip(P, expected):
        if d > 0:  # coal's geometry as built, from outside (coal's signed depth inside is EPA's)
            assert _coal_point_distance(obj, p) == pytest.approx(d, abs=DIST_TOL_M, rel=0.0)


def _box_stl(path: Path, extents: np.ndarray) -> None:
    """A closed box mesh centred on its origin (extents in the file's unit)."""
    trimesh.creation.box(extents=extents).export(path)


# Dyadic sizes and points: exact in the float32 of an STL file.
MESH_EXTENTS_M = np.array([0.25, 0.5, 0.375])
MESH_POINTS_LOCAL = np.array(
    [[0.5, 0.0, 0.0], [0.25, 0.375, 0.25], [0.0, -0.375, 0.25], [0.0625, 0.125, 0.03125], [0.0, 0.0, 0.15625]]
)


@pytest.mark.parametrize(("unit", "scale"), [("m", None), ("mm", 0.001)])
def test_mesh_agrees_with_the_equivalent_box(tmp_path, unit, scale):
    factor = 1.0 if scale is None else 1.0 / scale
    _box_stl(tmp_path / "part.stl", MESH_EXTENTS_M * factor)
    mesh_keys = {"file": "part.stl"} | ({} if scale is None else {"scale": scale})
    cell_text = (
        "[cell]\n"
        + _obj(name="mesh_box", shape="mesh", **mesh_keys, xyz=CENTRE.tolist(), rpy_deg=RPY_DEG.tolist())
        + _obj(name="box", shape="box", size=MESH_EXTENTS_M.tolist(), xyz=CENTRE.tolist(), rpy_deg=RPY_DEG.tolist())
    )
    cell = load_problem(_write(tmp_path, cell_text)).cell
    mesh, box = cell.objects
    assert isinstance(mesh.geometry, coal.BVHModelOBBRSS)
    np.testing.assert_allclose(mesh.size, MESH_EXTENTS_M, atol=1e-12)
    R = rpy_to_matrix(np.radians(RPY_DEG))
    P = MESH_POINTS_LOCAL @ R.T + CENTRE
    d_box = box.distance_to_point(P)
    assert np.any(d_box < 0) and np.any(d_box > 0)  # both sides are tested
    np.testing.assert_allclose(mesh.distance_to_point(P), d_box, atol=DIST_TOL_M, rtol=0.0)
    np.testing.assert_array_equal(mesh.contains(P), box.contains(P))
    np.testing.assert_array_equal(cell.contains(P), np.column_stack([d_box < 0, d_box < 0]))
    for p, d in zip(P, d_box):
        if d > 0:
            assert _coal_point_distance(mesh, p) == pytest.approx(d, abs=DIST_TOL_M, rel=0.0)
            assert _coal_point_distance(box, p) == pytest.approx(d, abs=DIST_TOL_M, rel=0.0)


# --------------------------------------------------------------------------------------------
# Bad input: one line naming the file and the key
# --------------------------------------------------------------------------------------------

FIXTURE = {"name": "fixture", "shape": "box", "size": [0.3, 0.2, 0.4], "xyz": [0.6, 0.1, 0.2]}


def _with(**changes: object) -> dict:
    d = dict(FIXTURE)
    for k, v in changes.items():
        if v is None:
            d.pop(k, None)
        else:
            d[k] = v
    return d


def _open_stl(path: Path) -> None:
    m = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    trimesh.Trimesh(m.vertices, m.faces[:-1], process=False).export(path)


BAD = [
    ("cell_unknown_key", "[cell]\nclearence = 0.005\n", None, ["[cell]", "clearence"]),
    ("object_unknown_key", "[cell]\n" + _obj(**_with(colour="red")), None, ["cell.objects[0]", "colour"]),
    ("clearance_negative", "[cell]\nclearance = -0.001\n", None, ["cell.clearance", "-0.001"]),
    ("clearance_mm", "[cell]\nclearance = 5.0\n", None, ["cell.clearance", "5.0", "millimetres"]),
    ("objects_not_tables", "[cell]\nobjects = [1, 2]\n", None, ["cell.objects", "list of tables"]),
    ("name_missing", "[cell]\n" + _obj(**_with(name=None)), None, ["cell.objects[0].name"]),
    ("shape_unknown", "[cell]\n" + _obj(**_with(shape="cone")), None, ["cell.objects[0].shape", "cone"]),
    ("role_unknown", "[cell]\n" + _obj(**_with(role="table")), None, ["cell.objects[0].role", "table"]),
    ("box_size_2", "[cell]\n" + _obj(**_with(size=[0.3, 0.2])), None, ["cell.objects[0].size", "3 number(s)"]),
    (
        "cylinder_size_3",
        "[cell]\n" + _obj(**_with(shape="cylinder", size=[0.1, 0.2, 0.3])),
        None,
        ["cell.objects[0].size", "2 number(s)", "radius, length"],
    ),
    (
        "sphere_size_2",
        "[cell]\n" + _obj(**_with(shape="sphere", size=[0.1, 0.2])),
        None,
        ["cell.objects[0].size", "1 number(s)"],
    ),
    ("size_zero", "[cell]\n" + _obj(**_with(size=[0.3, 0.0, 0.4])), None, ["cell.objects[0].size[1]", "> 0"]),
    ("size_negative", "[cell]\n" + _obj(**_with(size=[-0.3, 0.2, 0.4])), None, ["cell.objects[0].size[0]", "> 0"]),
    ("size_mm", "[cell]\n" + _obj(**_with(size=[300.0, 200.0, 400.0])), None, ["cell.objects[0].size", "millimetres"]),
    ("xyz_mm", "[cell]\n" + _obj(**_with(xyz=[600.0, 100.0, 200.0])), None, ["cell.objects[0].xyz", "millimetres"]),
    ("rpy_in_degrees", "[cell]\n" + _obj(**_with(rpy=[0.0, 0.0, 90.0])), None, ["cell.objects[0].rpy", "rpy_deg"]),
    (
        "duplicate_name",
        "[cell]\n" + _obj(**FIXTURE) + _obj(**_with(xyz=[0.6, -0.5, 0.2])),
        None,
        ["cell.objects[1].name", "'fixture'", "unique"],
    ),
    (
        "two_workpieces",
        "[cell]\n"
        + _obj(**_with(role="workpiece"))
        + _obj(**_with(name="other", xyz=[0.6, -0.5, 0.2], role="workpiece")),
        None,
        ["cell.objects[1].role", "other", "at most one"],
    ),
    (
        "size_on_mesh",
        "[cell]\n" + _obj(**_with(shape="mesh", file="part.stl")),
        "closed",
        ["cell.objects[0].size", "mesh"],
    ),
    ("file_on_box", "[cell]\n" + _obj(**_with(file="part.stl")), None, ["cell.objects[0].file", "only applies"]),
    (
        "mesh_missing",
        "[cell]\n" + _obj(**_with(shape="mesh", size=None, file="nowhere.stl")),
        None,
        ["cell.objects[0].file", "nowhere.stl", "no such file"],
    ),
    (
        "mesh_suffix",
        "[cell]\n" + _obj(**_with(shape="mesh", size=None, file="part.step")),
        None,
        ["cell.objects[0].file", "part.step", "STL, OBJ or PLY"],
    ),
    (
        "mesh_unreadable",
        "[cell]\n" + _obj(**_with(shape="mesh", size=None, file="part.stl")),
        "garbage",
        ["cell.objects[0].file", "part.stl", "no triangles"],
    ),
    (
        "mesh_not_closed",
        "[cell]\n" + _obj(**_with(shape="mesh", size=None, file="part.stl")),
        "open",
        ["cell.objects[0].file", "not closed", "open edge"],
    ),
    (
        "mesh_in_mm",
        "[cell]\n" + _obj(**_with(shape="mesh", size=None, file="part.stl")),
        "mm",
        ["cell.objects[0].file", "read as metres", "scale = 0.001"],
    ),
    (
        "mesh_scale_zero",
        "[cell]\n" + _obj(**_with(shape="mesh", size=None, file="part.stl", scale=0.0)),
        "closed",
        ["cell.objects[0].scale", "> 0"],
    ),
    (
        "frame_workpiece_without_program",
        "[cell]\n" + _obj(**_with(frame="workpiece")),
        None,
        ["cell.objects[0].frame", "program path"],
    ),
    ("frame_unknown", "[cell]\n" + _obj(**_with(frame="tool")), None, ["cell.objects[0].frame", "tool"]),
    (
        "overlaps_base",
        "[cell]\n" + _obj(**FIXTURE) + _obj(name="pillar", shape="cylinder", size=[0.05, 0.5], xyz=[0.1, 0.0, 0.25]),
        None,
        ["cell.objects[1]", "'pillar'", "overlaps the robot's base"],
    ),
    (
        "overlaps_base_mesh",
        "[cell]\n" + _obj(name="housing", shape="mesh", file="part.stl", xyz=[0.0, 0.0, 0.05]),
        "big",
        ["cell.objects[0]", "'housing'", "overlaps the robot's base"],
    ),
    (
        "path_inside_obstacle",
        "[cell]\n" + _obj(name="block", shape="box", size=[0.1, 0.1, 0.1], xyz=[0.40, 0.10, 0.30]),
        None,
        ["waypoint 3", "'block'", "cell.objects[0]", "inside"],
    ),
    (
        "path_inside_mesh",
        "[cell]\n" + _obj(name="part", shape="mesh", file="part.stl", xyz=[0.40, -0.20, 0.30]),
        "closed",
        ["waypoint 0", "'part'", "cell.objects[0]", "inside"],
    ),
]


@pytest.mark.parametrize(("cell_text", "mesh", "needles"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_cell_is_one_clear_error(tmp_path, cell_text, mesh, needles):
    stl = tmp_path / "part.stl"
    if mesh == "closed":
        _box_stl(stl, np.array([0.1, 0.1, 0.1]))
    elif mesh == "big":
        _box_stl(stl, np.array([0.5, 0.5, 0.1]))
    elif mesh == "mm":
        _box_stl(stl, np.array([300.0, 200.0, 400.0]))  # a part drawn in mm
    elif mesh == "open":
        _open_stl(stl)
    elif mesh == "garbage":
        stl.write_text("this is not a mesh\n", encoding="utf-8")
    f = _write(tmp_path, cell_text)
    with pytest.raises(ProblemFileError) as exc:
        load_problem(f)
    msg = str(exc.value)
    assert "\n" not in msg
    assert msg.startswith(f"{f}:"), msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_path_inside_the_workpiece_and_touching_objects_are_allowed(tmp_path):
    r, h = base_footprint(load_problem(_write(tmp_path, "")).robot)
    cell_text = (
        "[cell]\nclearance = 0.0\n"
        + _obj(name="block", shape="box", size=[0.1, 0.1, 0.1], xyz=[0.40, 0.10, 0.30], role="workpiece")
        + _obj(name="table", shape="box", size=[2.0, 2.0, 0.05], xyz=[0.0, 0.0, -0.025])  # top: the mounting plane
        + _obj(name="ring", shape="cylinder", size=[0.05, h], xyz=[r + 0.05, 0.0, h / 2])  # touches the footprint
    )
    p = load_problem(_write(tmp_path, cell_text))
    assert p.cell.workpiece.name == "block"
    assert [o.name for o in p.cell.obstacles] == ["table", "ring"]
    assert p.cell.clearance == 0.0
    assert BASE_FOOTPRINT_HEIGHT_M == h
    inside = p.cell.contains(p.positions)
    assert inside[:, 0].any() and not inside[:, 1:].any()


def test_program_frame_and_program_line_in_messages(tmp_path):
    ngc = Path(__file__).resolve().parents[1] / "problems" / "files" / "milling_pocket.ngc"
    src = (Path(__file__).resolve().parents[1] / "problems" / "files" / "milling_pocket.toml").read_text()
    head = src.replace('file = "milling_pocket.ngc"', f'file = "{ngc}"')
    wp = _obj(
        name="stock",
        shape="box",
        size=[0.12, 0.08, 0.031],
        xyz=[0.0, 0.0, -0.0155],
        role="workpiece",
        frame="workpiece",
    )
    p = load_problem(_write(tmp_path, "\n[cell]\n" + wp, head=head))
    obj = p.cell.workpiece
    np.testing.assert_allclose(obj.object2base[:3, 3], [0.65, 0.0, 0.10 - 0.0155], atol=1e-15)
    k = 100
    bad = _obj(name="clamp", shape="sphere", size=[0.002], xyz=p.positions[k].tolist())
    with pytest.raises(ProblemFileError) as exc:
        load_problem(_write(tmp_path, "\n[cell]\n" + wp + bad, head=head))
    line = int(p.program.waypoints.line[k])
    assert f"milling_pocket.ngc:{line}" in str(exc.value)
    assert "'clamp'" in str(exc.value)


def test_cell_survives_copies_round_trip_and_is_an_input(tmp_path):
    from planner.provenance import problem_provenance

    _box_stl(tmp_path / "part.stl", MESH_EXTENTS_M)
    cell_text = (
        "[cell]\nclearance = 0.01\n"
        + _obj(**FIXTURE)
        + _obj(name="part", shape="mesh", file="part.stl", xyz=[-0.6, 0.0, 0.3], rpy_deg=[0.0, 0.0, 30.0])
    )
    p = load_problem(_write(tmp_path, cell_text))
    for q in (p.with_timing(dt=0.004), p.with_robot("ur10"), p.with_points(7)):
        assert q.cell is p.cell
    again = problem_from_dict(p.to_dict(), "round trip").cell
    assert again.names == p.cell.names and again.clearance == p.cell.clearance
    for a, b in zip(again.objects, p.cell.objects):
        np.testing.assert_allclose(a.object2base, b.object2base, atol=1e-12)
        np.testing.assert_allclose(a.size, b.size, atol=1e-12)
    shift = np.eye(4)
    shift[:3, 3] = 1.0
    moved = p.cell.moved(shift)
    np.testing.assert_allclose(moved.objects[0].object2base[:3, 3], np.array(FIXTURE["xyz"]) + 1.0)
    inputs = problem_provenance(p)["inputs"]
    mesh_in = [e for e in inputs if e["role"] == "cell mesh"]
    assert len(mesh_in) == 1 and mesh_in[0]["name"] == "part.stl" and len(mesh_in[0]["sha256"]) == 64


def test_shipped_problems_have_a_cell_only_where_they_declare_one():
    for name in shipped_problems():
        declares = "[cell]" in (Path(__file__).resolve().parents[1] / "problems" / "files" / f"{name}.toml").read_text()
        assert (load_problem(name).cell is not None) == declares, name
    assert load_problem("cell_table").cell.workpiece.name == "fixture"


def test_placed_problem_sees_the_cell_from_its_base(tmp_path):
    from problems.placement.placed import problem_at

    p = load_problem(_write(tmp_path, "[cell]\n" + _obj(**FIXTURE)))
    placed = problem_at(p, np.array([0.1, -0.2, 0.05, math.radians(30.0), 0.0]))
    # the path and the objects move together: each waypoint keeps its distance from the fixture
    np.testing.assert_allclose(
        placed.cell.distance_to_point(placed.positions), p.cell.distance_to_point(p.positions), atol=1e-12
    )
    assert not np.allclose(placed.cell.objects[0].object2base, p.cell.objects[0].object2base)
