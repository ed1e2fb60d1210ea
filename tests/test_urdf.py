"""URDF-based robot files: the chain read from a URDF is the product's one model.

Cross-checks: pinocchio's model built from the same URDF (FK and Jacobian of the flange);
a URDF written from a DH table against the DH robot file; clear errors for bad URDFs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from models import KinematicModel, load_robot
from models.errors import InputError
from models.robot import RobotFileError
from models.transforms import matrix_to_rpy

pin = pytest.importorskip("pinocchio")

#: FK (m and rotation entries) and Jacobian (m, 1) against pinocchio from the same URDF.
PINOCCHIO_TOL = 1e-12
#: A URDF written from a DH table against the DH robot file (FK, J, C relative, torques relative).
DH_URDF_TOL = 1e-12
#: Random configurations per comparison.
N_CONFIGS = 200

ROBOTS_DIR = Path(__file__).resolve().parents[1] / "models" / "robots"
SHIPPED_URDF_ROBOTS = ("ur5e", "kr6_r900")


# --------------------------------------------------------------------------------------
# Writing URDFs from DH tables (the test's own, independent of models.robot_file)
# --------------------------------------------------------------------------------------


def _sdh(th: float, d: float, a: float, al: float) -> np.ndarray:
    ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1.0]])


def _mdh(th: float, d: float, a: float, al: float) -> np.ndarray:
    ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
    return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1.0]])


def _xyz_rpy(T: np.ndarray) -> str:
    f = lambda v: " ".join(repr(float(x)) for x in v)  # noqa: E731 - a one-line helper local to this test
    return f'xyz="{f(T[:3, 3])}" rpy="{f(matrix_to_rpy(T[:3, :3]))}"'


def _inertial(mass: float, com: np.ndarray, I: np.ndarray) -> str:
    v = [repr(float(x)) for x in (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])]
    return (
        f'<inertial><origin xyz="{" ".join(repr(float(c)) for c in com)}" rpy="0 0 0"/>'
        f'<mass value="{float(mass)!r}"/><inertia ixx="{v[0]}" iyy="{v[1]}" izz="{v[2]}" '
        f'ixy="{v[3]}" ixz="{v[4]}" iyz="{v[5]}"/></inertial>'
    )


def urdf_from_dh(robot, path: Path, flip_axes: tuple[int, ...] = ()) -> None:
    """A URDF of a DH robot: link i's frame is DH frame i-1 turned by q_i (standard) or DH frame i
    (modified).  ``flip_axes``: joints whose link frame is turned by pi about x, so that their
    axis +z points the other way: the same chain with those joint angles negated."""
    lines = [f'<robot name="{robot.name}_urdf">', '<link name="base_link"/>']
    prev, parent2prev = "base_link", np.eye(4)
    rx_pi = np.diag([1.0, -1.0, -1.0, 1.0])
    for i, j in enumerate(robot.joints):
        if robot.convention == "standard_dh":
            origin = (
                np.eye(4)
                if i == 0
                else _sdh(
                    robot.joints[i - 1].theta_offset,
                    robot.joints[i - 1].d,
                    robot.joints[i - 1].a,
                    robot.joints[i - 1].alpha,
                )
            )
            link2dh = _sdh(j.theta_offset, j.d, j.a, j.alpha)  # DH frame i in link i's frame
        else:
            origin = _mdh(j.theta_offset, j.d, j.a, j.alpha)
            link2dh = np.eye(4)
        origin = np.linalg.inv(parent2prev) @ origin
        flip = i in flip_axes
        if flip:
            origin = origin @ rx_pi
            link2dh = rx_pi @ link2dh
        com = (link2dh @ np.r_[j.com, 1.0])[:3]
        I = link2dh[:3, :3] @ (j.inertia if j.inertia is not None else np.diag([0.01, 0.02, 0.015])) @ link2dh[:3, :3].T
        lines.append(f'<link name="link{i + 1}">{_inertial(j.mass, com, I)}</link>')
        lines.append(
            f'<joint name="joint{i + 1}" type="revolute"><parent link="{prev}"/><child link="link{i + 1}"/>'
            f'<origin {_xyz_rpy(origin)}/><axis xyz="0 0 1"/><limit lower="{float(j.q_min)!r}" '
            f'upper="{float(j.q_max)!r}" velocity="{float(j.v_max)!r}" effort="100"/></joint>'
        )
        prev, parent2prev = f"link{i + 1}", (rx_pi if flip else np.eye(4))  # next origin: in this frame
    last = robot.joints[5]
    tip = _sdh(last.theta_offset, last.d, last.a, last.alpha) if robot.convention == "standard_dh" else np.eye(4)
    tip = np.linalg.inv(parent2prev) @ tip
    lines.append('<link name="flange"/>')
    lines.append(
        f'<joint name="flange_fixed" type="fixed"><parent link="link6"/><child link="flange"/>'
        f"<origin {_xyz_rpy(tip)}/></joint>"
    )
    lines.append("</robot>")
    path.write_text("\n".join(lines), encoding="utf-8")


def _robot_file(folder: Path, robot, urdf: str = "arm.urdf", extra: str = "") -> Path:
    k = ", ".join(repr(float(v)) for v in robot.stiffness)
    am = ", ".join(repr(float(v)) for v in robot.a_max)
    jm = ", ".join(repr(float(v)) for v in robot.j_max)
    p = folder / "arm.toml"
    p.write_text(
        f'name = "{robot.name}_urdf"\nurdf = "{urdf}"\nbase_link = "base_link"\ntip_link = "flange"\n'
        f"stiffness = [{k}]\na_max = [{am}]\nj_max = [{jm}]\n{extra}",
        encoding="utf-8",
    )
    return p


def _weight_torques(robot, q: np.ndarray, L: np.ndarray) -> np.ndarray:
    """Joint torques of the arm's own weight (the gravity effect on), N*m, (N, 6)."""
    from dataclasses import replace

    from models.arm import ArmModel

    km = KinematicModel(replace(ArmModel.from_robot(robot), gravity_on=True))
    return km.batch(km.fn["joint_torques"], q, L)[0]


def _with_masses(robot):
    """The robot with a mass, centre of mass and inertia on every link (for the torque checks)."""
    from dataclasses import replace

    rng = np.random.default_rng(5)
    joints = []
    for j in robot.joints:
        A = rng.normal(size=(3, 3))
        joints.append(
            replace(
                j,
                mass=j.mass if j.mass is not None else 2.0,
                com=j.com if j.com is not None else rng.uniform(-0.05, 0.05, 3),
                inertia=0.01 * np.eye(3) + 1e-3 * (A @ A.T) / 3.0,
            )
        )
    return replace(robot, joints=tuple(joints))


# --------------------------------------------------------------------------------------
# pinocchio from the same URDF
# --------------------------------------------------------------------------------------


def _pinocchio_fk_jac(urdf: Path, tip: str, names: tuple[str, ...], q: np.ndarray, base: str = "base_link"):
    """pinocchio's pose of ``tip`` in the frame of ``base`` and its Jacobian (LOCAL_WORLD_ALIGNED,
    turned into ``base``'s axes) at each q (joints by name)."""
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    fid, bid = model.getFrameId(tip), model.getFrameId(base)
    idx = [model.joints[model.getJointId(n)].idx_q for n in names]
    T, J = [], []
    for qi in q:
        qp = pin.neutral(model)
        qp[idx] = qi
        pin.computeJointJacobians(model, data, qp)
        pin.updateFramePlacements(model, data)
        B = np.linalg.inv(data.oMf[bid].homogeneous)  # root -> base frame
        T.append(B @ data.oMf[fid].homogeneous)
        Jw = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        Jw = Jw[:, [model.joints[model.getJointId(n)].idx_v for n in names]]
        J.append(np.vstack([B[:3, :3] @ Jw[:3], B[:3, :3] @ Jw[3:]]))
    return np.array(T), np.array(J)


@pytest.mark.parametrize("name", SHIPPED_URDF_ROBOTS)
def test_shipped_urdf_fk_and_jacobian_equal_pinocchio(name, rng):
    robot = load_robot(name)
    assert robot.urdf is not None and robot.joint_names is not None
    km = KinematicModel(robot.with_tool(np.eye(4)))
    q = rng.uniform(robot.q_min, robot.q_max, (N_CONFIGS, 6))
    T_pin, J_pin = _pinocchio_fk_jac(
        Path(robot.urdf["path"]), robot.urdf["tip_link"], robot.joint_names, q, robot.urdf["base_link"]
    )
    assert np.abs(km.tcp(q) - T_pin).max() < PINOCCHIO_TOL
    assert np.abs(km.J(q) - J_pin).max() < PINOCCHIO_TOL


@pytest.mark.parametrize("name,flips", [("ur5", ()), ("ur10", (1, 4)), ("ar5", ()), ("ar5", (0, 2, 5))])
def test_urdf_from_dh_equals_pinocchio_and_the_dh_model(name, flips, tmp_path, rng):
    dh = _with_masses(load_robot(name))
    urdf_from_dh(dh, tmp_path / "arm.urdf", flips)
    ur = load_robot(_robot_file(tmp_path, dh))
    q = rng.uniform(-np.pi, np.pi, (N_CONFIGS, 6))
    q[:, list(flips)] *= -1.0  # a flipped axis turns the other way
    qd = q.copy()
    qd[:, list(flips)] *= -1.0
    km_u, km_d = KinematicModel(ur), KinematicModel(dh)
    T_pin, J_pin = _pinocchio_fk_jac(tmp_path / "arm.urdf", "flange", ur.joint_names, q)
    assert np.abs(km_u.tcp(q) - T_pin).max() < PINOCCHIO_TOL
    assert np.abs(km_u.J(q) - J_pin).max() < PINOCCHIO_TOL
    # the same model as the DH robot file
    assert np.abs(km_u.tcp(q) - km_d.tcp(qd)).max() < DH_URDF_TOL
    sign = np.ones(6)
    sign[list(flips)] = -1.0
    Jd = km_d.J(qd) * sign
    assert np.abs(km_u.J(q) - Jd).max() < DH_URDF_TOL
    C_u, C_d = km_u.C(q), km_d.C(qd)
    assert np.abs(C_u - C_d).max() < DH_URDF_TOL * np.abs(C_d).max()
    # masses, centres of mass: the self-weight torques (gravity effect on) agree
    L = np.zeros((1, 19))
    L[0, 16:19] = dh.gravity
    tu = _weight_torques(ur, q, L)
    td = _weight_torques(dh, qd, L) * sign
    assert np.abs(tu).max() > 1.0  # the check can fail: real torques
    assert np.abs(tu - td).max() < DH_URDF_TOL * max(1.0, np.abs(td).max())
    # ... and equal pinocchio's generalised gravity from the same URDF (the load's torque on the
    # joints is minus the torque that holds the arm)
    model = pin.buildModelFromUrdf(str(tmp_path / "arm.urdf"))
    model.gravity.linear = np.asarray(dh.gravity, dtype=float)  # pinocchio's default is 9.81
    data = model.createData()
    idx = [model.joints[model.getJointId(n)].idx_v for n in ur.joint_names]
    g_pin = np.array([pin.computeGeneralizedGravity(model, data, qi)[idx] for qi in q])
    assert np.abs(tu + g_pin).max() < DH_URDF_TOL * max(1.0, np.abs(g_pin).max())
    assert np.allclose(ur.masses, dh.masses, rtol=0, atol=1e-12)


def test_urdf_robot_round_trips_through_its_dh_form(tmp_path):
    from models.robot import robot_from_dict

    dh = _with_masses(load_robot("ur5"))
    urdf_from_dh(dh, tmp_path / "arm.urdf", (2,))
    ur = load_robot(_robot_file(tmp_path, dh))
    again = robot_from_dict(ur.to_dict(), "round trip")
    q = np.random.default_rng(1).uniform(-3, 3, (20, 6))
    assert np.abs(KinematicModel(again).tcp(q) - KinematicModel(ur).tcp(q)).max() < 1e-12
    assert again.joint_names == ur.joint_names
    assert np.allclose(again.inertias, ur.inertias, atol=1e-12)


# --------------------------------------------------------------------------------------
# Robot-file keys, defaults and overrides
# --------------------------------------------------------------------------------------


def test_defaults_and_overrides(tmp_path):
    dh = _with_masses(load_robot("ur5"))
    urdf_from_dh(dh, tmp_path / "arm.urdf")
    p = tmp_path / "arm.toml"
    p.write_text(
        'name = "x"\nurdf = "arm.urdf"\nbase_link = "base_link"\ntip_link = "flange"\n'
        "stiffness = [1e4, 1e4, 1e4, 1e3, 1e3, 1e3]\n"
        "[joints.joint2]\nq_min_deg = -90\nq_max_deg = 90\nv_max = 1.0\na_max = 3.0\n",
        encoding="utf-8",
    )
    r = load_robot(p)
    assert r.q_min[1] == pytest.approx(-math.pi / 2) and r.v_max[1] == 1.0 and r.a_max[1] == 3.0
    # no a_max / j_max: the documented defaults, and notes saying so
    from models.robot_file.urdf_file import DEFAULT_TIME_TO_ACCEL_S, DEFAULT_TIME_TO_SPEED_S

    assert r.a_max[0] == pytest.approx(dh.v_max[0] / DEFAULT_TIME_TO_SPEED_S)
    assert r.j_max[0] == pytest.approx(r.a_max[0] / DEFAULT_TIME_TO_ACCEL_S)
    assert any("a_max not given" in n for n in r.notes)


# --------------------------------------------------------------------------------------
# Bad URDFs: clear errors naming the file, the joint or link and what was expected
# --------------------------------------------------------------------------------------


def _write(tmp_path: Path, urdf: str, toml_extra: str = "", tip: str = "flange", base: str = "base_link") -> Path:
    (tmp_path / "arm.urdf").write_text(urdf, encoding="utf-8")
    p = tmp_path / "arm.toml"
    p.write_text(
        f'name = "x"\nurdf = "arm.urdf"\nbase_link = "{base}"\ntip_link = "{tip}"\n'
        f"stiffness = [1, 1, 1, 1, 1, 1]\n{toml_extra}",
        encoding="utf-8",
    )
    return p


def _chain(joints: list[str], tail: str = "") -> str:
    """A serial URDF: ``joints`` are the <joint> bodies (type, axis, limit...) in order."""
    out = ['<robot name="t">', '<link name="base_link"/>']
    prev = "base_link"
    for i, body in enumerate(joints):
        out.append(f'<link name="l{i + 1}"/>')
        out.append(
            f'<joint name="j{i + 1}" {body.split("|")[0]}><parent link="{prev}"/><child link="l{i + 1}"/>'
            f"{body.split('|')[1] if '|' in body else ''}</joint>"
        )
        prev = f"l{i + 1}"
    out.append('<link name="flange"/>')
    out.append(f'<joint name="jf" type="fixed"><parent link="{prev}"/><child link="flange"/></joint>')
    out.append(tail + "</robot>")
    return "\n".join(out)


_REV = 'type="revolute"|<origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" velocity="2" effort="1"/>'
_REV_Z = (
    'type="revolute"|<origin xyz="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="2" effort="1"/>'
)
_SIX = [_REV_Z, _REV, _REV, _REV_Z, _REV, _REV_Z]


@pytest.mark.parametrize(
    "joints,tip,base,needle",
    [
        (_SIX, "nowhere", "base_link", "key 'tip_link' = 'nowhere': no such link"),
        (_SIX, "l1", "l3", "tip_link 'l1' is not below base_link 'l3'"),
        (_SIX[:5], "flange", "base_link", "5 moving joint(s)"),
        (_SIX + [_REV], "flange", "base_link", "7 moving joint(s)"),
        (
            _SIX[:2]
            + ['type="revolute"|<axis xyz="0 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/>']
            + _SIX[3:],
            "flange",
            "base_link",
            "joint 'j3': <axis xyz> = [0.0, 0.0, 0.0] is zero",
        ),
        (
            _SIX[:1]
            + [
                'type="revolute"|<origin xyz="0 nan 0.1"/><axis xyz="0 1 0"/>'
                '<limit lower="-1" upper="1" velocity="1" effort="1"/>'
            ]
            + _SIX[2:],
            "flange",
            "base_link",
            "joint 'j2': <origin> is not finite",
        ),
        (
            _SIX[:3]
            + ['type="prismatic"|<axis xyz="1 0 0"/><limit lower="0" upper="1" velocity="1" effort="1"/>']
            + _SIX[4:],
            "flange",
            "base_link",
            "joint 'j4' is prismatic",
        ),
        (
            _SIX[:5] + ['type="continuous"|<axis xyz="0 0 1"/>'],
            "flange",
            "base_link",
            "joint 'j6' is continuous (no position limits in the URDF)",
        ),
        (
            _SIX[:5]
            + [
                'type="revolute"|<axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/>'
                '<mimic joint="j5"/>'
            ],
            "flange",
            "base_link",
            "joint 'j6' mimics joint 'j5'",
        ),
        (
            _SIX[:5] + ['type="revolute"|<axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="0" effort="1"/>'],
            "flange",
            "base_link",
            "joint 'j6': the URDF gives no positive <limit velocity>",
        ),
        (
            _SIX[:5] + ['type="revolute"|<axis xyz="0 0 1"/><limit lower="-360" upper="360" velocity="1" effort="1"/>'],
            "flange",
            "base_link",
            "URDF joint 'j6': <limit lower=\"-360\"> rad is implausible",
        ),
        (
            _SIX[:2]
            + [
                'type="revolute"|<origin xyz="0 0 0.1"/><axis xyz="0 1 0.001"/>'
                '<limit lower="-3" upper="3" velocity="2" effort="1"/>'
            ]
            + _SIX[3:],
            "flange",
            "base_link",
            "joints 2 and 3 are nearly but not exactly parallel",
        ),
    ],
)
def test_bad_urdfs_give_clear_errors(tmp_path, joints, tip, base, needle):
    p = _write(tmp_path, _chain(joints), tip=tip, base=base)
    with pytest.raises(RobotFileError) as ei:
        load_robot(p)
    assert needle in str(ei.value)
    assert str(p) in str(ei.value) or str(tmp_path / "arm.urdf") in str(ei.value)


@pytest.mark.parametrize(
    "inertial,needle",
    [
        (
            '<inertial><mass value="-2"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>',
            "link 'l2': <mass value=\"-2\"> must be >= 0",
        ),
        (
            '<inertial><mass value="2"/><inertia ixx="-5" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>',
            "link 'l2': <inertia>: <inertia ixx iyy izz ixy ixz iyz>",
        ),
    ],
)
def test_bad_inertials_are_refused_naming_the_link(tmp_path, inertial, needle):
    urdf = _chain(_SIX).replace('<link name="l2"/>', f'<link name="l2">{inertial}</link>')
    with pytest.raises(RobotFileError) as ei:
        load_robot(_write(tmp_path, urdf))
    assert needle in str(ei.value)


def test_override_limits_must_be_positive(tmp_path):
    for key in ("a_max", "j_max", "v_max"):
        p = _write(tmp_path, _chain(_SIX), toml_extra=f"[joints.j1]\n{key} = -1.0\n")
        with pytest.raises(RobotFileError, match=f"joints.j1: key '{key}' must be > 0, got -1"):
            load_robot(p)


def test_a_tip_on_another_branch_of_the_tree_is_refused(tmp_path):
    tail = '<link name="camera"/><joint name="jc" type="fixed"><parent link="base_link"/><child link="camera"/></joint>'
    p = _write(tmp_path, _chain(_SIX, tail), tip="camera", base="l2")
    with pytest.raises(
        RobotFileError, match="tip_link 'camera' is not below base_link 'l2'.*goes up through the moving joint"
    ):
        load_robot(p)


def test_bad_urdf_files_and_keys(tmp_path):
    p = _write(tmp_path, "this is not xml")
    with pytest.raises(RobotFileError, match="not a URDF"):
        load_robot(p)
    p = _write(tmp_path, "<robot name='t'><link name='a'><broken></robot>")
    with pytest.raises(RobotFileError, match="not well-formed XML at line 1"):
        load_robot(p)
    (tmp_path / "arm.urdf").unlink()
    with pytest.raises(RobotFileError, match="no such URDF file"):
        load_robot(p)
    p = _write(tmp_path, _chain(_SIX), toml_extra="convention = 'standard_dh'\n")
    with pytest.raises(RobotFileError, match="'convention' and \\[\\[joints\\]\\] DH rows belong to DH robot files"):
        load_robot(p)
    p = _write(tmp_path, _chain(_SIX), toml_extra="[joints.j9]\nv_max = 1\n")
    with pytest.raises(RobotFileError, match="joints.j9: no such moving joint"):
        load_robot(p)
    p = _write(tmp_path, _chain(_SIX), toml_extra="[joints.j1]\nstiffness = 1\n")
    with pytest.raises(RobotFileError, match="joints.j1: unknown key"):
        load_robot(p)
    (tmp_path / "arm.toml").write_text('name = "x"\nurdf = "arm.urdf"\nbase_link = "base_link"\ntip_link = "flange"\n')
    with pytest.raises(RobotFileError, match="missing key 'stiffness'"):
        load_robot(tmp_path / "arm.toml")
    assert issubclass(RobotFileError, InputError)


def test_the_cli_reports_a_bad_urdf_without_a_traceback(tmp_path, capsys):
    """In this process (an exception escaping ``main`` fails the test as a traceback would)."""
    from planner.cli import main

    p = _write(tmp_path, _chain(_SIX[:5]))
    assert main(["robot", "check", str(p)]) != 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "5 moving joint(s)" in err
    assert main(["plan", "paper_4_4", "--robot", str(p), "--out", str(tmp_path / "out")]) != 0
    err = capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    assert "Traceback" not in err and "5 moving joint(s)" in err


def test_a_copied_urdf_builtin_is_the_same_robot(tmp_path, capsys):
    """compplan robot show NAME > file and show NAME --urdf > its URDF: the copy loads as the built-in."""
    from planner.cli import main

    assert main(["robot", "show", "kr6_r900"]) == 0
    out = capsys.readouterr()
    (tmp_path / "my_kr6.toml").write_text(out.out, encoding="utf-8")
    assert "--urdf" in out.err
    assert main(["robot", "show", "kr6_r900", "--urdf"]) == 0
    (tmp_path / "kr6_r900.urdf").write_text(capsys.readouterr().out, encoding="utf-8")
    mine, ref = load_robot(tmp_path / "my_kr6.toml"), load_robot("kr6_r900")
    q = np.random.default_rng(2).uniform(-2, 2, (10, 6))
    assert np.abs(KinematicModel(mine).tcp(q) - KinematicModel(ref).tcp(q)).max() == 0.0
    assert main(["robot", "check", str(tmp_path / "my_kr6.toml")]) == 0
    text = capsys.readouterr().out
    assert "IK family: opw" in text and "a1 = 0.025" in text and "c4 = 0.08" in text
    assert main(["robot", "show", "ur5", "--urdf"]) == 2
