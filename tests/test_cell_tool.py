"""The tool as collision geometry (issue 25): body elements and the cutter under ``[robot.tool]``
(``models/collision/tool.py``, ``problems/problem_file/cell_section.py``, ``docs/cell.md``, "The tool").

* the file's ``[[robot.tool.body]]`` / ``[robot.tool.cutter]`` are read in SI, bad input is one
  ProblemFileError naming the file and the key;
* every element lies inside its capsule: box corners, cylinder rims, mesh vertices carried to the
  base frame by the arm model's own forward kinematics (not :func:`chain_frames`) at random
  configurations, within :data:`CONTAIN_TOL_M`; and the capsule is tight (a point on its surface);
* the rules: the cutter may be inside the workpiece, a body element reaching it is a collision named
  ``spindle – part``, checked independently with coal; the plan's geometry and the placement kernel
  check the same pairs; without declared tool geometry nothing changes;
* a plan whose problem has a tool body names its capsules in ``summary.json`` ``cell.capsules``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

coal = pytest.importorskip("coal")
trimesh = pytest.importorskip("trimesh")

from models.collision import capsule_model, capsule_segments, chain_frames, with_tool  # noqa: E402
from models.collision.segments import segment_distance  # noqa: E402
from models.collision.tool import CUTTER_BODY, TOOL_BODY, with_tool_geometry  # noqa: E402
from models.transforms import rpy_to_matrix, transform  # noqa: E402
from problems.cell import Cell, CellObject  # noqa: E402
from problems.problem import load_problem  # noqa: E402
from problems.problem_file import ProblemFileError  # noqa: E402

#: A point of an element lies inside its capsule to this, m (rounding of the transforms).
CONTAIN_TOL_M = 1e-9
#: Random configurations per containment test.
N_CONFIGURATIONS = 50
#: Points on each cylinder rim in the containment test.
RIM_POINTS = 64
#: The TCP lies this deep inside the workpiece in the rule tests, m.
CUT_DEPTH_M = 0.005
#: The rule tests' clearance, m.
CLEARANCE_M = 0.005

HEAD = """
name = "tool_test"
[robot]
model = "ur5"
[robot.tool]
xyz = [0.0, 0.0, 0.15]
rpy_deg = [0.0, 0.0, 0.0]
{tool}
[path]
kind = "line"
start = [0.40, -0.20, 0.30]
end = [0.40, 0.20, 0.30]
points = 5
[orientation]
rule = "free_tool_axis"
[wrench]
force = [0.0, 0.0, 10.0]
{cell}
"""

#: An obstacle far from the path and the base, so that the file has a [cell].
CELL = """
[cell]
clearance = 0.005
[[cell.objects]]
name = "fixture"
shape = "box"
size = [0.2, 0.2, 0.1]
xyz = [0.6, -0.5, 0.4]
"""


def _body(**keys: object) -> str:
    """One [[robot.tool.body]] table from keyword arguments."""
    lines = ["[[robot.tool.body]]"]
    for k, v in keys.items():
        lines.append(f"{k} = {chr(34) + v + chr(34) if isinstance(v, str) else repr(v)}")
    return "\n".join(lines) + "\n"


def _cutter(radius: object = 0.005, length: object = 0.06) -> str:
    return f"[robot.tool.cutter]\nradius = {radius!r}\nlength = {length!r}\n"


SPINDLE = dict(name="spindle", shape="cylinder", size=[0.04, 0.08], xyz=[0.0, 0.0, 0.05])
CLAMP = dict(name="clamp", shape="box", size=[0.03, 0.12, 0.02], xyz=[0.01, -0.02, 0.02], rpy_deg=[10.0, -20.0, 30.0])


def _load(tmp_path: Path, tool: str, cell: str = CELL):
    f = tmp_path / "tool.toml"
    f.write_text(HEAD.format(tool=tool, cell=cell), encoding="utf-8")
    return load_problem(str(f))


# ------------------------------------------------------------------------------ the file
def test_tool_body_and_cutter_are_read_in_si(tmp_path):
    p = _load(tmp_path, _body(**SPINDLE) + _body(**CLAMP) + _cutter(0.004, 0.07))
    tool = p.cell.tool
    assert tool.names == ("spindle", "clamp")
    spindle, clamp = tool.elements
    np.testing.assert_array_equal(spindle.size, [0.04, 0.08])
    np.testing.assert_allclose(spindle.element2flange, transform(np.eye(3), np.array([0.0, 0.0, 0.05])))
    np.testing.assert_allclose(clamp.element2flange[:3, :3], rpy_to_matrix(np.radians(CLAMP["rpy_deg"])))
    assert (tool.cutter.radius, tool.cutter.length) == (0.004, 0.07)
    # the tool rides with the cell when the cell is moved (it is fixed to the flange)
    assert p.cell.moved(transform(np.eye(3), np.ones(3))).tool is tool


def test_a_cutter_longer_than_the_tool_is_accepted(tmp_path):
    p = _load(tmp_path, _cutter(0.005, 0.4))  # the TCP is 0.15 m from the flange
    assert p.cell.tool.cutter.length == 0.4 and not p.cell.tool.elements


def _open_stl(path: Path) -> None:
    m = trimesh.creation.box(extents=[0.05, 0.05, 0.05])
    trimesh.Trimesh(m.vertices, m.faces[:-1], process=False).export(path)


BAD = [
    ("unknown_shape", _body(name="s", shape="cone", size=[0.1]), None, ["robot.tool.body[0].shape", "cone"]),
    ("size_count", _body(name="s", shape="box", size=[0.1, 0.1]), None, ["robot.tool.body[0].size", "3 number"]),
    ("size_zero", _body(name="s", shape="cylinder", size=[0.04, 0.0]), None, ["robot.tool.body[0].size[1]", "> 0"]),
    ("size_mm", _body(name="s", shape="sphere", size=[40.0]), None, ["robot.tool.body[0].size", "millimetres"]),
    ("xyz_mm", _body(name="s", shape="sphere", size=[0.04], xyz=[0, 0, 50.0]), None, ["body[0].xyz", "metres"]),
    ("unknown_key", _body(name="s", shape="sphere", size=[0.04], colour="red"), None, ["robot.tool.body[0]", "colour"]),
    ("no_name", _body(shape="sphere", size=[0.04]), None, ["robot.tool.body[0].name", "non-empty"]),
    ("reserved_cutter", _body(name="cutter", shape="sphere", size=[0.04]), None, ["body[0].name", "'cutter'"]),
    ("reserved_link", _body(name="link 3", shape="sphere", size=[0.04]), None, ["body[0].name", "'link 3'"]),
    (
        "repeated",
        _body(name="s", shape="sphere", size=[0.04]) + _body(name="s", shape="sphere", size=[0.03]),
        None,
        ["robot.tool.body[1].name", "unique"],
    ),
    ("size_on_mesh", _body(name="s", shape="mesh", file="t.stl", size=[0.1]), "closed", ["body[0].size", "mesh"]),
    ("file_on_box", _body(name="s", shape="box", size=[0.1] * 3, file="t.stl"), None, ["body[0].file", "only"]),
    ("mesh_missing", _body(name="s", shape="mesh", file="nowhere.stl"), None, ["body[0].file", "no such file"]),
    ("mesh_open", _body(name="s", shape="mesh", file="t.stl"), "open", ["body[0].file", "not closed"]),
    ("mesh_in_mm", _body(name="s", shape="mesh", file="t.stl"), "mm", ["body[0].file", "scale = 0.001"]),
    ("cutter_radius", _cutter(0.0, 0.05), None, ["robot.tool.cutter.radius", "> 0"]),
    ("cutter_mm", _cutter(6.0, 50.0), None, ["robot.tool.cutter.radius", "millimetres"]),
    ("cutter_no_length", "[robot.tool.cutter]\nradius = 0.005\n", None, ["robot.tool.cutter.length", "required"]),
    ("cutter_key", "[robot.tool.cutter]\nradius = 0.005\nlength = 0.05\nflutes = 2\n", None, ["flutes"]),
    ("tool_key", "bodies = []\n", None, ["[robot.tool]", "bodies"]),
]


@pytest.mark.parametrize(("tool", "mesh", "needles"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_tool_is_one_clear_error(tmp_path, tool, mesh, needles):
    stl = tmp_path / "t.stl"
    if mesh == "closed":
        trimesh.creation.box(extents=[0.05, 0.05, 0.05]).export(stl)
    elif mesh == "mm":
        trimesh.creation.box(extents=[50.0, 50.0, 300.0 * 20]).export(stl)
    elif mesh == "open":
        _open_stl(stl)
    with pytest.raises(ProblemFileError) as exc:
        _load(tmp_path, tool)
    msg = str(exc.value)
    assert "tool.toml" in msg
    for n in needles:
        assert n in msg, (n, msg)


def test_a_tool_body_is_checked_without_a_cell_too(tmp_path):
    """Used only with a [cell], but a bad declaration is an error either way."""
    assert _load(tmp_path, _body(**SPINDLE), cell="").cell is None
    with pytest.raises(ProblemFileError, match="robot.tool.body"):
        _load(tmp_path, _body(name="s", shape="cone", size=[0.1]), cell="")


# ------------------------------------------------------------------------------ containment
def _flange_frames(problem, q: np.ndarray) -> np.ndarray:
    """flange2base at configurations q (N, 6) from the arm model's own forward kinematics."""
    km = problem.model.kinematics
    F6 = km.batch(km.fk_frames, np.atleast_2d(q))[-1]
    return F6 @ problem.robot.flange2frame6


def _box_corners(size: np.ndarray) -> np.ndarray:
    s = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    return 0.5 * s * size


def _cylinder_rims(radius: float, length: float) -> np.ndarray:
    a = np.linspace(0.0, 2 * np.pi, RIM_POINTS, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros_like(a)])
    return np.vstack([ring + [0, 0, -0.5 * length], ring + [0, 0, 0.5 * length]])


def _element_points(e) -> np.ndarray:
    """Points on the element's surface, element frame: box corners, cylinder rims, sphere poles,
    mesh vertices."""
    if e.shape == "box":
        return _box_corners(e.size)
    if e.shape == "cylinder":
        return _cylinder_rims(*e.size)
    if e.shape == "sphere":
        return np.vstack([np.eye(3), -np.eye(3)]) * e.size[0]
    return np.asarray(e.mesh.vertices, dtype=float)


def test_every_element_lies_in_its_capsule_at_random_configurations(tmp_path):
    # a cylinder mesh in mm, tilted and off the flange axis; a fat mesh (an icosphere: the capsule
    # is nearly a sphere); every primitive, turned
    tilt = transform(rpy_to_matrix(np.radians([35.0, 20.0, 0.0])), np.array([10.0, -5.0, 30.0]))
    trimesh.creation.cylinder(radius=30.0, height=120.0, sections=24).apply_transform(tilt).export(
        tmp_path / "holder.stl"
    )
    trimesh.creation.icosphere(subdivisions=2, radius=0.03).export(tmp_path / "knob.stl")
    tool = (
        _body(**SPINDLE)
        + _body(**CLAMP)
        + _body(name="probe", shape="sphere", size=[0.02], xyz=[0.05, 0.0, 0.1])
        + _body(name="holder", shape="mesh", file="holder.stl", scale=0.001, xyz=[0.0, 0.02, 0.01], rpy_deg=[0, 0, 40])
        + _body(name="knob", shape="mesh", file="knob.stl", xyz=[-0.04, 0.0, 0.03])
        + _cutter(0.005, 0.06)
    )
    p = _load(tmp_path, tool)
    arm = capsule_model(p.robot)
    full, info = with_tool_geometry(arm, p.robot, p.cell.tool)
    rng = np.random.default_rng(11)
    q = rng.uniform(-np.pi, np.pi, (N_CONFIGURATIONS, 6))
    seg = capsule_segments(full, chain_frames(p.robot, q))  # (N, M, 2, 3)
    flange2base = _flange_frames(p, q)
    for e in p.cell.tool.elements:
        c = info.names.index(e.name)
        assert full.body[c] == TOOL_BODY
        local = _element_points(e)
        in_flange = local @ e.element2flange[:3, :3].T + e.element2flange[:3, 3]
        P = np.einsum("nij,kj->nki", flange2base[:, :3, :3], in_flange) + flange2base[:, None, :3, 3]
        d, _, _ = segment_distance(seg[:, c, None, 0], seg[:, c, None, 1], P, P)
        assert d.max() <= full.radius[c] + CONTAIN_TOL_M, e.name
        if e.shape != "sphere" and e.name != "knob":  # the capsule touches its element: not needlessly large
            assert d.max() >= full.radius[c] - 1e-6, e.name
    # the cutter: its rims (TCP frame, ending at the TCP), by the same independent FK
    cutter = p.cell.tool.cutter
    c = info.names.index("cutter")
    assert full.body[c] == CUTTER_BODY and info.tip == c
    rims = _cylinder_rims(cutter.radius, cutter.length) - [0.0, 0.0, 0.5 * cutter.length]
    tcp2base = flange2base @ p.robot.tcp2flange
    P = np.einsum("nij,kj->nki", tcp2base[:, :3, :3], rims) + tcp2base[:, None, :3, 3]
    d, _, _ = segment_distance(seg[:, c, None, 0], seg[:, c, None, 1], P, P)
    np.testing.assert_allclose(d, cutter.radius, atol=CONTAIN_TOL_M)  # every rim point on the capsule
    np.testing.assert_allclose(seg[:, c, 1], tcp2base[:, :3, 3], atol=CONTAIN_TOL_M)  # it ends at the TCP


def test_a_tool_mesh_is_an_input_of_the_run(tmp_path):
    from planner.provenance import problem_provenance

    trimesh.creation.cylinder(radius=0.03, height=0.1).export(tmp_path / "holder.stl")
    p = _load(tmp_path, _body(name="holder", shape="mesh", file="holder.stl"))
    assert p.cell.mesh_files() == (str(tmp_path / "holder.stl"),)
    inputs = [e for e in problem_provenance(p)["inputs"] if e["role"] == "cell mesh"]
    assert [e["name"] for e in inputs] == ["holder.stl"] and len(inputs[0]["sha256"]) == 64


def test_without_tool_geometry_the_model_is_todays():
    p = load_problem("cell_table")
    assert p.cell.tool is None
    arm = capsule_model(p.robot)
    old, has = with_tool(arm, p.robot)
    new, info = with_tool_geometry(arm, p.robot, None)
    assert has and info.has_tool and not info.declared
    for k in ("frame_a", "frame_b", "local_a", "local_b", "radius", "body"):
        np.testing.assert_array_equal(getattr(new, k), getattr(old, k))
    assert info.names == (*arm.names, "tool") and info.tip == arm.n_capsules


# ------------------------------------------------------------------------------ the rules
#: A configuration of the UR5 with the tool pointing about down, the wrist clear of the TCP.
Q_RULE = np.array([0.3, -1.2, 1.6, -1.97, -1.5708, 0.4])


def _workpiece_at_tcp(problem, q: np.ndarray) -> CellObject:
    """A 0.2 x 0.2 x 0.1 m block across the tool axis whose face lies CUT_DEPTH_M behind the TCP
    (toward the flange): the TCP and the cutter's end are inside it."""
    tcp = (_flange_frames(problem, q) @ problem.robot.tcp2flange)[0]
    T = tcp.copy()
    T[:3, 3] = tcp[:3, 3] + tcp[:3, 2] * (0.05 - CUT_DEPTH_M)
    return CellObject("part", "box", np.array([0.2, 0.2, 0.1]), T, role="workpiece")


def _capsule_box_distance(a: np.ndarray, b: np.ndarray, r: float, obj: CellObject) -> float:
    """coal's signed distance between a capsule (ends a, b, radius r) and an object (independent)."""
    length = float(np.linalg.norm(b - a))
    z = (b - a) / length
    x = np.cross([1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    T = transform(np.column_stack([x, np.cross(z, x), z]), 0.5 * (a + b))
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    req.enable_signed_distance = True
    tf = coal.Transform3s()
    tf.setRotation(np.ascontiguousarray(T[:3, :3]))
    tf.setTranslation(np.ascontiguousarray(T[:3, 3]))
    return float(coal.distance(coal.Capsule(r, length), tf, obj.geometry, obj.coal_transform, req, res))


def _rule_case(tmp_path, tool: str):
    from planner.cell_check import cell_geometry, check_poses

    p = _load(tmp_path, tool, cell="")
    part = _workpiece_at_tcp(p, Q_RULE)
    cell = Cell((part,), CLEARANCE_M, _tool_of(tmp_path, tool))
    geom = cell_geometry(p.robot, cell)
    return p, cell, geom, check_poses(geom, Q_RULE[None])


def _tool_of(tmp_path: Path, tool: str):
    """The tool geometry of the test problem with ``tool`` (problems.problem_file.cell_section's reader)."""
    import tomllib

    from problems.problem_file import parse_tool_geometry

    data = tomllib.loads(HEAD.format(tool=tool, cell=""))
    return parse_tool_geometry("tool.toml", data, tmp_path)


def test_the_cutter_may_be_inside_the_workpiece_a_body_element_may_not(tmp_path):
    from problems.placement.collide import KernelCell

    p, cell, geom, ok = _rule_case(tmp_path, _body(**SPINDLE) + _cutter(0.005, 0.06))
    part = cell.objects[0]
    # independently: the cutter really is inside the workpiece (coal, ends from the model's own FK)
    tcp = (_flange_frames(p, Q_RULE) @ p.robot.tcp2flange)[0]
    assert _capsule_box_distance(tcp[:3, 3] - 0.06 * tcp[:3, 2], tcp[:3, 3], 0.005, part) < -CUT_DEPTH_M
    assert ok.status.value == "ok", ok.reason
    assert ok.distance >= CLEARANCE_M
    # the same pose, the spindle long enough to reach past the TCP: a collision, named
    long = dict(SPINDLE, size=[0.04, 0.16], xyz=[0.0, 0.0, 0.08])
    p2, cell2, geom2, bad = _rule_case(tmp_path, _body(**long) + _cutter(0.005, 0.06))
    assert bad.status.value == "collision" and bad.pair == "spindle – part", bad.reason
    flange = _flange_frames(p2, Q_RULE)[0]
    a, b = flange[:3, 3], flange[:3, 3] + 0.16 * flange[:3, 2]
    ref = _capsule_box_distance(a, b, 0.04, part)  # the spindle's own cylinder axis: an independent capsule
    assert ref < 0.0
    assert bad.distance == pytest.approx(ref, abs=1e-6)
    # the placement kernel checks the same pairs, and decides the same (a box: exact there too)
    for g, c in ((geom, cell), (geom2, cell2)):
        k = KernelCell(p.robot, c)
        assert [list(ix) for ix in k.checked] == [list(np.flatnonzero(g.checked[:, j])) for j in range(1)]
        np.testing.assert_array_equal(k.self_pairs, g.self_pairs)
        d = k.min_distance(Q_RULE[None], np.eye(4)[None])[0]
        assert (d < CLEARANCE_M) == (g is geom2)


def test_without_a_cutter_the_capsule_ending_at_the_tcp_may_touch_the_workpiece(tmp_path):
    """A body but no cutter: today's flange -> TCP capsule is kept as the tip; the body is checked."""
    _, _, geom, ok = _rule_case(tmp_path, _body(**SPINDLE))
    assert "tool" in geom.names and "cutter" not in geom.names
    assert not geom.checked[geom.names.index("tool"), 0] and geom.checked[geom.names.index("spindle"), 0]
    assert ok.status.value == "ok", ok.reason
    long = dict(SPINDLE, size=[0.04, 0.16], xyz=[0.0, 0.0, 0.08])
    _, _, _, bad = _rule_case(tmp_path, _body(**long))
    assert bad.status.value == "collision" and bad.pair == "spindle – part"


def test_tool_capsules_are_checked_against_the_links_up_to_link_4(tmp_path):
    _, _, geom, _ = _rule_case(tmp_path, _body(**SPINDLE) + _body(**CLAMP) + _cutter())
    names = geom.names
    tool_pairs = {(names[i], names[j]) for i, j in geom.self_pairs if names[j] in ("spindle", "clamp", "cutter")}
    links = {n for n in names[: geom.names.index("spindle")] if int(n.split()[1].split("#")[0]) <= 4}
    assert tool_pairs == {(n, t) for n in links for t in ("spindle", "clamp", "cutter")}


# ------------------------------------------------------------------------------ the plan
def test_a_plan_names_the_tool_capsules_in_its_summary(tmp_path):
    from planner.plan import plan

    p = _load(tmp_path, _body(**SPINDLE) + _body(**CLAMP) + _cutter(0.005, 0.06))
    res = plan(p, optimise=False)
    assert res.cell is not None and res.cell.waypoints is not None, res.reason
    caps = res.view().summary["cell"]["capsules"]
    assert {"spindle", "clamp", "cutter"} <= set(caps) and "tool" not in caps
    assert caps["spindle"] == pytest.approx(0.04) and caps["cutter"] == pytest.approx(0.005)
    assert caps["clamp"] == pytest.approx(0.5 * np.hypot(0.03, 0.02))
