"""The arm's own collision geometry (issue 25): the capsules contain the real arm's skeleton.

Checked against independent kinematics: pinocchio's forward kinematics of the shipped URDFs (and of a
small URDF written here), the UR arms' joint-origin chain built from ur_description's published
offsets, and the DH chain from ``models.transforms.dh_chain_frames``.  Also the ``[collision]`` table of
robot files (parsing, errors at the boundary, round trip) and URDF ``<collision>`` elements.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import tomli_w
import trimesh

from models.collision import capsule_model, capsule_segments, chain_frames, self_collision_pairs
from models.collision.capsules import LINE_RADIUS_M
from models.robot import BUILTIN_ROBOTS, RobotFileError, load_robot, robot_from_dict
from models.transforms import dh_chain_frames

#: A point counts as inside a capsule within this distance beyond its radius (m): rounding only.
CONTAIN_TOL_M = 1e-9
#: A segment lies on a joint axis when both ends are this close to the axis line (m).
ON_AXIS_TOL_M = 1e-9
#: Random configurations (within the joint limits) per arm.
N_CONFIGS = 200
#: Points sampled along each skeleton segment (ends included).
N_ALONG = 21
#: The flange of our model and of the independent kinematics agree to this (m).
FK_AGREE_M = 1e-9
#: An STL stores float32 vertices: sizes of a mesh read back agree to this (m).
STL_FLOAT32_TOL_M = 1e-7

#: The UR arms' published link offsets along the joint axes (ROS-Industrial ur_description
#: ur5.urdf.xacro, ur10.urdf.xacro; ur_e_description ur5e.urdf.xacro): shoulder_offset s (upper arm
#: along joint 2's axis) and elbow_offset e (the forearm back by e). The seed paper's ar5 has UR5
#: proportions: the UR5's offsets.
UR_OFFSETS_M = {"ur5": (0.13585, 0.1197), "ur10": (0.220941, 0.1719), "ur5e": (0.138, 0.131), "ar5": (0.13585, 0.1197)}
#: UR's published standard DH of the UR5e (d1, a2, a3, d4, d5, d6; alpha): the shipped ur5e.urdf is
#: built from it, in the controller's Base frame (our robot's base).
UR5E_DH = {
    "a": [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0],
    "d": [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996],
    "alpha": [math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0],
}


def _configs(robot, n=N_CONFIGS, seed=0):
    return np.random.default_rng(seed).uniform(robot.q_min, robot.q_max, (n, 6))


def _excess(P: np.ndarray, S: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Per point P (K, 3), the smallest distance beyond a capsule's radius over capsules S (M, 2, 3)."""
    a, b = S[:, 0][None], S[:, 1][None]
    ab = b - a
    L2 = np.maximum(np.sum(ab * ab, axis=-1), 1e-300)
    t = np.clip(np.sum((P[:, None] - a) * ab, axis=-1) / L2, 0.0, 1.0)
    d = np.linalg.norm(P[:, None] - (a + t[..., None] * ab), axis=-1) - radius[None]
    return d.min(axis=1)


def _on_line(x: np.ndarray, p: np.ndarray, w: np.ndarray) -> bool:
    return bool(np.linalg.norm(np.cross(x - p, w)) <= ON_AXIS_TOL_M * max(1.0, float(np.linalg.norm(x))))


def _bodies_of(k: int, pa, pb, axes) -> set[int]:
    """Bodies a segment of link k (0 base) is fixed to: link k, and the link on the other side of a
    joint whose axis holds the whole segment (``axes[i]`` = (point, direction) of joint i+1)."""
    out = {k}
    if k < 6 and all(_on_line(x, *axes[k]) for x in (pa, pb)):
        out.add(k + 1)
    if k > 0 and all(_on_line(x, *axes[k - 1]) for x in (pa, pb)):
        out.add(k - 1)
    return out


def _assert_inside(model, S, chain, axes, what):
    """Every point along every chain segment (link k: chain[k] -> chain[k+1]) lies inside a capsule
    of a body the segment is fixed to."""
    worst = -np.inf
    for k in range(len(chain) - 1):
        pa, pb = chain[k], chain[k + 1]
        bodies = _bodies_of(min(k, 6), pa, pb, axes)
        sel = np.isin(model.body, sorted(bodies))
        P = pa + np.linspace(0.0, 1.0, N_ALONG)[:, None] * (pb - pa)
        e = _excess(P, S[sel], model.radius[sel])
        worst = max(worst, float(e.max()))
        assert e.max() <= CONTAIN_TOL_M, (
            f"{what}: segment {k} (link {k}, bodies {sorted(bodies)}) leaves the capsules by {e.max() * 1e3:.2f} mm"
        )
    return worst


# --------------------------------------------------------------------------------------
# The shipped URDFs: pinocchio's joint origins
# --------------------------------------------------------------------------------------


def _urdf_axes(path: str) -> dict[str, np.ndarray]:
    """Joint axis (in the joint frame) per joint name, from the URDF's XML."""
    out = {}
    for j in ET.parse(path).getroot().iter("joint"):
        ax = j.find("axis")
        out[j.get("name")] = (
            np.array([1.0, 0.0, 0.0]) if ax is None else np.array([float(v) for v in ax.get("xyz").split()])
        )
    return out


def _pin_chain(robot, q: np.ndarray):
    """Base origin, the six joint origins and the tip (robot base frame), the joint axes, the tip pose,
    by pinocchio from the URDF itself."""
    path = robot.urdf["path"]
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    axes_local = _urdf_axes(path)
    base_id, tip_id = model.getFrameId(robot.urdf["base_link"]), model.getFrameId(robot.urdf["tip_link"])
    jids = [model.getJointId(n) for n in robot.joint_names]
    for qi in np.atleast_2d(q):
        x = pin.neutral(model)
        for jid, v in zip(jids, qi):
            x[model.joints[jid].idx_q] = v
        pin.forwardKinematics(model, data, x)
        pin.updateFramePlacements(model, data)
        w2b = np.linalg.inv(data.oMf[base_id].homogeneous)
        Js = [w2b @ data.oMi[j].homogeneous for j in jids]
        tip = w2b @ data.oMf[tip_id].homogeneous
        chain = [np.zeros(3)] + [J[:3, 3] for J in Js] + [tip[:3, 3]]
        axes = [
            (J[:3, 3], J[:3, :3] @ axes_local[n] / np.linalg.norm(axes_local[n])) for J, n in zip(Js, robot.joint_names)
        ]
        yield chain, axes, tip


@pytest.mark.parametrize("name", ["ur5e", "kr6_r900"])
def test_urdf_joint_origin_chain_inside_capsules(name):
    """The lines between consecutive joint origins of the shipped URDF (pinocchio) lie inside the
    capsules of their link at N_CONFIGS random configurations."""
    robot = load_robot(name)
    model = capsule_model(robot)
    q = _configs(robot)
    F = chain_frames(robot, q)
    S = capsule_segments(model, F)
    for i, (chain, axes, tip) in enumerate(_pin_chain(robot, q)):
        flange = F[i, 6] @ robot.flange2frame6
        np.testing.assert_allclose(flange[:3, 3], tip[:3, 3], atol=FK_AGREE_M)  # the same arm
        _assert_inside(model, S[i], chain, axes, f"{name} q={q[i].round(3)}")


# --------------------------------------------------------------------------------------
# The DH chain and the UR arms' real joint-origin chain
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_dh_chain_inside_capsules(name):
    """The lines between consecutive DH frame origins (base, O0 .. O6, flange), by the NumPy twin of
    the model's chain, lie inside the capsules of the link they are fixed to."""
    robot = load_robot(name)
    model = capsule_model(robot)
    q = _configs(robot, seed=1)
    S = capsule_segments(model, chain_frames(robot, q))
    std = robot.convention == "standard_dh"
    for i in range(len(q)):
        F = dh_chain_frames(
            robot.convention, robot.a, robot.alpha, robot.d, robot.theta_offset, q[i], robot.frame02base
        )
        O = [F[k][:3, 3] for k in range(7)]
        flange = (F[6] @ robot.flange2frame6)[:3, 3]
        # joint i+1's axis: standard z_i through O_i; modified z_{i+1} through O_{i+1}
        axes = [(O[k], F[k][:3, 2]) if std else (O[k + 1], F[k + 1][:3, 2]) for k in range(6)]
        # link of each line: base -> O0 base; O_{k-1} -> O_k: standard link k, modified link k-1; O6 -> flange link 6
        chain = [np.zeros(3), *O, flange]
        links = [0] + [k if std else k - 1 for k in range(1, 7)] + [6]
        for j, link in enumerate(links):
            pa, pb = chain[j], chain[j + 1]
            bodies = _bodies_of(link, pa, pb, axes)
            sel = np.isin(model.body, sorted(bodies))
            P = pa + np.linspace(0.0, 1.0, N_ALONG)[:, None] * (pb - pa)
            e = _excess(P, S[i][sel], model.radius[sel])
            assert e.max() <= CONTAIN_TOL_M, f"{name}: DH line {j} (link {link}) leaves the capsules by {e.max():.4f} m"


def _standard_frames(a, d, alpha, q):
    """Standard-DH frames 0..6 (base frame 0 = identity), the test's own product."""
    T, out = np.eye(4), [np.eye(4)]
    for ai, di, al, qi in zip(a, d, alpha, q):
        ct, st, ca, sa = math.cos(qi), math.sin(qi), math.cos(al), math.sin(al)
        T = T @ np.array(
            [[ct, -st * ca, st * sa, ai * ct], [st, ct * ca, -ct * sa, ai * st], [0, sa, ca, di], [0, 0, 0, 1]]
        )
        out.append(T)
    return out


@pytest.mark.parametrize("name", ["ur5", "ur10", "ur5e", "ar5"])
def test_ur_real_joint_origin_chain_inside_capsules(name):
    """The UR arms' links lie off the DH line (ur_description: upper arm at shoulder_offset s along
    joint 2's axis, forearm back by elbow_offset e): the chain base -> shoulder (d1) -> joint 2 (+s)
    -> elbow (s - e) -> wrist 1 (s - e) -> wrist 2 (d4) -> wrist 3 -> flange lies inside the capsules."""
    robot = load_robot(name)
    model = capsule_model(robot)
    s, e = UR_OFFSETS_M[name]
    if name == "ur5e":  # URDF-based: UR's published DH, checked to be the same arm below
        a, d, alpha = (np.array(UR5E_DH[k]) for k in ("a", "d", "alpha"))
    else:
        assert robot.convention == "standard_dh" and not np.any(robot.theta_offset)
        a, d, alpha = robot.a, robot.d, robot.alpha
    q = _configs(robot, seed=2)
    Fm = chain_frames(robot, q)
    S = capsule_segments(model, Fm)
    for i in range(len(q)):
        T = _standard_frames(a, d, alpha, q[i])
        np.testing.assert_allclose((Fm[i, 6] @ robot.flange2frame6)[:3, 3], T[6][:3, 3], atol=FK_AGREE_M)
        O, z = [t[:3, 3] for t in T], [t[:3, 2] for t in T]
        off2, off3 = s - e - d[1], s - e - d[1] - d[2]  # the forearm's offset from O2 and O3 along the axes
        chain = [
            np.zeros(3),
            O[0] + d[0] * z[0],
            O[1] + s * z[1],
            O[2] + off2 * z[2],
            O[3] + off3 * z[3],
            O[4],
            O[5],
            O[6],
        ]
        axes = [(O[k], z[k]) for k in range(6)]
        _assert_inside(model, S[i], chain, axes, f"{name} q={q[i].round(3)}")


def test_ur_offsets_are_physical_segments():
    """The UR5e's upper arm tube (at s along joint 2's axis, from joint 2 to joint 3) is material (the
    body's radius, in self-collision), not a line: points on it lie inside a material capsule of link 2."""
    robot = load_robot("ur5e")
    model = capsule_model(robot)
    s, _ = UR_OFFSETS_M["ur5e"]
    q = _configs(robot, 50, seed=3)
    S = capsule_segments(model, chain_frames(robot, q))
    mat = (model.body == 2) & ~model.is_line
    assert np.all(model.radius[mat] == load_robot("ur5e").collision.radii[2])
    for i in range(len(q)):
        T = _standard_frames(*(np.array(UR5E_DH[k]) for k in ("a", "d")), UR5E_DH["alpha"], q[i])
        p0, p1 = T[1][:3, 3] + s * T[1][:3, 2], T[2][:3, 3] + s * T[2][:3, 2]
        P = p0 + np.linspace(0, 1, N_ALONG)[:, None] * (p1 - p0)
        assert _excess(P, S[i][mat], model.radius[mat]).max() <= CONTAIN_TOL_M
    lines = np.flatnonzero(model.is_line)
    assert lines.size and np.all(model.radius[lines] == LINE_RADIUS_M)
    pairs = self_collision_pairs(model)
    assert not np.isin(pairs, lines).any(), "a line is in self-collision"


# --------------------------------------------------------------------------------------
# The [collision] table of a robot file
# --------------------------------------------------------------------------------------


def _write(tmp_path: Path, data: dict, name: str = "arm.toml") -> Path:
    p = tmp_path / name
    p.write_text(tomli_w.dumps(data), encoding="utf-8")
    return p


def _ur5_dict(**collision) -> dict:
    d = load_robot("ur5").to_dict()
    d["name"] = "my_arm"
    if collision:
        d["collision"] = collision
    else:
        d.pop("collision", None)
    return d


def test_declared_geometry_is_used(tmp_path):
    radii = [0.09, 0.08, 0.07, 0.06, 0.05, 0.04, 0.03]
    seg = {"body": 2, "frame_a": 1, "xyz_a": [0.0, 0.0, 0.1], "frame_b": 2, "xyz_b": [0.0, 0.0, 0.1], "radius_m": 0.02}
    path = _write(tmp_path, _ur5_dict(radii_m=radii, allowed_pairs=[[5, 3]], segments=[seg], source="my drawing"))
    robot = load_robot(path)
    model = capsule_model(robot)
    assert model.radii_source == "my drawing" and model.allowed_pairs == ((3, 5),)
    mat = ~model.is_line
    declared = np.flatnonzero((model.frame_a == 1) & (model.frame_b == 2) & np.isclose(model.local_a[:, 2], 0.1))
    assert declared.size == 1 and model.radius[declared[0]] == 0.02 and model.body[declared[0]] == 2
    others = np.setdiff1d(np.flatnonzero(mat), declared)
    np.testing.assert_allclose(model.radius[others], np.array(radii)[model.body[others]])
    # without a table: generic radii (not a built-in name); named ur5: the built-in ones
    plain = load_robot(_write(tmp_path, _ur5_dict(), "plain.toml"))
    assert plain.collision is None and capsule_model(plain).radii_source.startswith("generic")
    builtin = capsule_model(replace(plain, name="ur5"))
    assert builtin.radii_source == capsule_model(load_robot("ur5")).radii_source
    assert builtin.allowed_pairs == ((3, 5), (4, 6))
    # source defaults to "robot file"
    nosrc = load_robot(_write(tmp_path, _ur5_dict(radii_m=radii), "nosrc.toml"))
    assert capsule_model(nosrc).radii_source == "robot file"


def test_replace_dh_leaves_out_the_bodys_dh_capsules(tmp_path):
    seg = {"body": 3, "frame_a": 2, "xyz_a": [0.0, 0.0, 0.05], "frame_b": 3, "xyz_b": [0.0, 0.0, 0.05]}
    robot = load_robot(_write(tmp_path, _ur5_dict(segments=[seg], replace_dh=[3])))
    model = capsule_model(robot)
    sel = (model.body == 3) & ~model.is_line
    assert sel.sum() == 1
    np.testing.assert_allclose(model.local_a[sel][0], [0.0, 0.0, 0.05])


@pytest.mark.parametrize(
    ("table", "expect"),
    [
        ({"radii_m": [0.1] * 6}, "collision: key 'radii_m' must be a list of 7"),
        ({"radii_m": [0.1, 0.1, -0.05, 0.1, 0.1, 0.1, 0.1]}, r"radii_m\[2\]' = -0.05; expected a radius > 0"),
        ({"radii_m": [0.1, 0.1, 50.0, 0.1, 0.1, 0.1, 0.1]}, "millimetres given"),
        ({"allowed_pairs": [[3, 3]]}, r"allowed_pairs\[0\]' = \[3, 3\]; expected two different bodies"),
        ({"allowed_pairs": [[1, 9]]}, r"allowed_pairs\[0\]' = \[1, 9\]"),
        ({"allowed_pairs": [[1]]}, r"allowed_pairs\[0\]'"),
        (
            {"segments": [{"body": 7, "frame_a": 1, "xyz_a": [0, 0, 0], "frame_b": 1, "xyz_b": [0, 0, 0]}]},
            r"segments\[0\]: key 'body' = 7; expected a body",
        ),
        (
            {"segments": [{"body": 2, "frame_a": -2, "xyz_a": [0, 0, 0], "frame_b": 1, "xyz_b": [0, 0, 0]}]},
            r"segments\[0\]: key 'frame_a' = -2; expected a frame",
        ),
        (
            {"segments": [{"body": 2, "frame_a": 1, "xyz_a": [0, 0], "frame_b": 1, "xyz_b": [0, 0, 0]}]},
            r"segments\[0\]: key 'xyz_a' must be a list of 3",
        ),
        ({"segments": [{"body": 2, "frame_a": 1, "xyz_a": [0, 0, 0], "frame_b": 1}]}, r"missing key 'xyz_b'"),
        (
            {"segments": [{"body": 2, "frame_a": 4, "xyz_a": [0.1, 0, 0], "frame_b": 2, "xyz_b": [0, 0, 0]}]},
            r"segments\[0\]: end a .* is not fixed to body 2",
        ),
        ({"colour": "red"}, r"collision: unknown key\(s\) \['colour'\]"),
        ({"replace_dh": [4]}, "body 4 has no segment"),
    ],
)
def test_collision_table_errors_name_file_and_key(tmp_path, table, expect):
    path = _write(tmp_path, _ur5_dict(**table))
    with pytest.raises(RobotFileError, match=expect) as exc:
        load_robot(path)
    assert str(path) in str(exc.value)


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_robot_dict_round_trip_keeps_the_capsules(name):
    """A robot written as a dictionary (summary.json, identified files) and read back has the same
    capsules (a URDF robot's geometry is written as segments in DH frames)."""
    robot = load_robot(name)
    back = robot_from_dict(robot.to_dict(), "round trip")
    m0, m1 = capsule_model(robot), capsule_model(back)
    for f in ("frame_a", "frame_b", "local_a", "local_b", "radius", "body", "line"):
        np.testing.assert_allclose(getattr(m0, f), getattr(m1, f), atol=1e-12, err_msg=f)
    assert m0.allowed_pairs == m1.allowed_pairs and m0.radii_source == m1.radii_source


# --------------------------------------------------------------------------------------
# URDF <collision> elements
# --------------------------------------------------------------------------------------

BOX_SIZE = (0.5, 0.1, 0.12)
CYL_R, CYL_L = 0.05, 0.3
SPHERE_R = 0.08
MESH_SIZE = (0.06, 0.08, 0.35)


def _test_urdf(tmp_path: Path, mesh_name: str = "part.stl") -> Path:
    """A 6R arm (axes z, y, y, x, y, x like an industrial arm) with collision elements on the base
    (box), link 1 (sphere), link 2 (box, turned), link 3 (cylinder), link 4 (mesh via package://); links
    5 and 6 have none."""
    (tmp_path / "meshes").mkdir(exist_ok=True)
    trimesh.creation.box(extents=MESH_SIZE).export(tmp_path / "meshes" / "part.stl")
    (tmp_path / "urdf").mkdir(exist_ok=True)
    bx, cy = " ".join(map(str, BOX_SIZE)), f'radius="{CYL_R}" length="{CYL_L}"'

    def link(name, geom=""):
        return f'<link name="{name}">{geom}</link>'

    def joint(name, parent, child, xyz, axis):
        return (
            f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
            '<limit lower="-3" upper="3" velocity="2" effort="10"/></joint>'
        )

    col = '<collision><origin xyz="{}" rpy="{}"/><geometry>{}</geometry></collision>'
    text = "".join(
        [
            '<?xml version="1.0"?><robot name="t">',
            link("base_link", col.format("0 0 0.1", "0 0 0", '<box size="0.3 0.3 0.2"/>')),
            link("link_1", col.format("0 0 0.05", "0 0 0", f'<sphere radius="{SPHERE_R}"/>')),
            link("link_2", col.format("0.25 0.02 0", "0.1 0.2 0.3", f'<box size="{bx}"/>')),
            link("link_3", col.format("0.15 0 0.02", "0 1.5707963 0.2", f"<cylinder {cy}/>")),
            link(
                "link_4",
                col.format("0.2 0 0", "0 1.5707963 0", f'<mesh filename="package://tpkg/meshes/{mesh_name}"/>'),
            ),
            link("link_5"),
            link("link_6"),
            joint("j1", "base_link", "link_1", "0 0 0.4", "0 0 1"),
            joint("j2", "link_1", "link_2", "0.05 0 0", "0 1 0"),
            joint("j3", "link_2", "link_3", "0.45 0 0", "0 1 0"),
            joint("j4", "link_3", "link_4", "0 0 0.04", "1 0 0"),
            joint("j5", "link_4", "link_5", "0.4 0 0", "0 1 0"),
            joint("j6", "link_5", "link_6", "0.08 0 0", "1 0 0"),
            "</robot>",
        ]
    )
    path = tmp_path / "urdf" / "t.urdf"
    path.write_text(text, encoding="utf-8")
    return path


def _urdf_robot(tmp_path: Path, **kw):
    urdf = _test_urdf(tmp_path, **kw)
    data = {"name": "t", "urdf": str(urdf), "base_link": "base_link", "tip_link": "link_6", "stiffness": [1e4] * 6}
    return load_robot(_write(tmp_path, data, "t.toml"))


def _element_points(mesh_file: Path) -> dict[str, tuple[int, np.ndarray, np.ndarray]]:
    """Per link: its body, the element's points (its own frame; the mesh as stored, float32 STL) and
    its origin (element -> link)."""
    from models.transforms import rpy_to_matrix, transform

    corners = np.array(np.meshgrid(*[[-0.5, 0.5]] * 3)).reshape(3, -1).T
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    rim = np.array([[CYL_R * np.cos(t), CYL_R * np.sin(t), h] for t in ang for h in (-CYL_L / 2, CYL_L / 2)])
    u = np.random.default_rng(5).normal(size=(60, 3))
    sphere = SPHERE_R * u / np.linalg.norm(u, axis=1)[:, None]
    mesh = np.asarray(trimesh.load(mesh_file, force="mesh").vertices, dtype=float)
    return {
        "base_link": (0, corners * [0.3, 0.3, 0.2], transform(np.eye(3), [0, 0, 0.1])),
        "link_1": (1, sphere, transform(np.eye(3), [0, 0, 0.05])),
        "link_2": (2, corners * BOX_SIZE, transform(rpy_to_matrix([0.1, 0.2, 0.3]), [0.25, 0.02, 0])),
        "link_3": (3, rim, transform(rpy_to_matrix([0, 1.5707963, 0.2]), [0.15, 0, 0.02])),
        "link_4": (4, mesh, transform(rpy_to_matrix([0, 1.5707963, 0]), [0.2, 0, 0])),
    }


def test_urdf_collision_elements_are_contained(tmp_path):
    """Each <collision> element (box, sphere, cylinder, mesh) lies inside its body's capsules at random
    configurations, by pinocchio's link frames of the same URDF; links without elements keep the DH capsules."""
    robot = _urdf_robot(tmp_path)
    model = capsule_model(robot)
    assert set(robot.collision.replace_dh) == {0, 1, 2, 3, 4}
    plain = capsule_model(replace(robot, collision=None))
    for b in (5, 6):  # no element: the DH capsules are kept
        mine = model.local_a[(model.body == b) & ~model.is_line]
        np.testing.assert_allclose(mine, plain.local_a[plain.body == b])
    urdf = robot.urdf["path"]
    pm = pin.buildModelFromUrdf(urdf)
    pd = pm.createData()
    q = _configs(robot, N_CONFIGS, seed=4)
    S = capsule_segments(model, chain_frames(robot, q))
    pts = _element_points(tmp_path / "meshes" / "part.stl")
    for i in range(len(q)):
        x = pin.neutral(pm)
        for n, v in zip(robot.joint_names, q[i]):
            x[pm.joints[pm.getJointId(n)].idx_q] = v
        pin.forwardKinematics(pm, pd, x)
        pin.updateFramePlacements(pm, pd)
        for link, (body, P, el2link) in pts.items():
            T = pd.oMf[pm.getFrameId(link)].homogeneous @ el2link
            W = P @ T[:3, :3].T + T[:3, 3]
            sel = model.body == body
            e = _excess(W, S[i][sel], model.radius[sel])
            assert e.max() <= CONTAIN_TOL_M, f"{link}: element leaves its capsule by {e.max() * 1e3:.3f} mm"


def test_urdf_element_capsules_are_tight(tmp_path):
    """The bounding capsules are the stated ones: box along its longest side with the half-diagonal of
    the other two; cylinder its own radius and length; sphere a point; mesh within a few mm of the box it is."""
    model = capsule_model(_urdf_robot(tmp_path))
    length = np.linalg.norm(model.local_b - model.local_a, axis=1)

    def one(body):
        (k,) = np.flatnonzero(model.body == body)
        return model.radius[k], length[k]

    np.testing.assert_allclose(one(2), (0.5 * math.hypot(*BOX_SIZE[1:]), BOX_SIZE[0]), atol=1e-12)
    np.testing.assert_allclose(one(3), (CYL_R, CYL_L), atol=1e-12)
    np.testing.assert_allclose(one(1), (SPHERE_R, 0.0), atol=1e-12)
    r, L = one(4)
    assert abs(r - 0.5 * math.hypot(*MESH_SIZE[:2])) <= STL_FLOAT32_TOL_M  # the box's cross-section
    assert L <= MESH_SIZE[2] + STL_FLOAT32_TOL_M


def test_urdf_mesh_not_found_names_file_and_link(tmp_path):
    with pytest.raises(
        RobotFileError, match=r"link 'link_4': <collision> mesh 'package://tpkg/meshes/gone.stl' not found"
    ):
        _urdf_robot(tmp_path, mesh_name="gone.stl")


def test_shipped_urdfs_without_elements_keep_the_dh_capsules():
    """ur5e.urdf and kr6_r900.urdf have no <collision> elements: every DH capsule is kept."""
    for name in ("ur5e", "kr6_r900"):
        robot = load_robot(name)
        assert not robot.collision.replace_dh
        model, plain = capsule_model(robot), capsule_model(replace(robot, collision=None))
        mat = ~plain.is_line  # the DH offsets (the lines are cut by whatever else the body has)
        for a, b in zip(plain.local_a[mat], plain.local_b[mat]):
            assert np.any(np.all(np.isclose(model.local_a, a), axis=1) & np.all(np.isclose(model.local_b, b), axis=1))
