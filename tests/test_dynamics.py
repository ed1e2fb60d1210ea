"""Rigid-body inverse dynamics (models.dynamics) against pinocchio, an independent implementation.

* RNEA of every shipped arm against ``pin.rnea`` of a pinocchio model built here from the DH rows
  (its own joint placements, ``pin.Inertia`` bodies), with a tool, a payload and a process wrench;
* the URDF-based arms against pinocchio built from their URDF files;
* the UR5/UR10 inertia tensors of the robot files against a URDF written from UR's ROS 2 description
  (``config/urX/default_kinematics.yaml`` and ``physical_parameters.yaml``, inertias in UR's link frames):
  the conversion to DH link frames checked through the dynamics;
* the mass matrix (``d tau / d qdd``: finite differences, pinocchio's CRBA, symmetric positive definite);
* the static case equals the static model's self-weight and load torques (``models.effects.gravity``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from models.dynamics import PAYLOAD_SIZE, gravity_torque_function, mass_matrix_function, payload_vector, rnea_function
from models.load import Load
from models.robot import RobotFileError, load_robot
from models.transforms import rot_x, rot_y, rot_z, rpy_to_matrix, transform

pin = pytest.importorskip("pinocchio")

#: RNEA torques against pinocchio, N*m, relative to max(1 N*m, largest torque of the state).
PINOCCHIO_TOL = 1e-10
#: Mass matrix against pinocchio's CRBA, kg*m^2, relative to max(1, largest entry).
CRBA_TOL = 1e-10
#: Central finite differences of tau in qdd (linear: only rounding), relative.
FD_REL_TOL = 1e-7
#: Step of those differences, rad/s^2.
FD_STEP = 1e-3
#: Static RNEA against the static model's torques, N*m, relative to max(1 N*m, largest torque).
STATIC_TOL = 1e-10
#: Random states per comparison.
N_STATES = 25

SHIPPED = ("ur5", "ur10", "ur5e", "kr6_r900")
URDF_ROBOTS = ("ur5e", "kr6_r900")
TOOL = transform(rot_z(0.3) @ rot_x(-0.4), np.array([0.1, -0.02, 0.15]))
PAYLOAD = payload_vector(
    3.5, [0.02, -0.03, 0.09], np.array([[0.021, 0.002, -0.003], [0.002, 0.018, 0.001], [-0.003, 0.001, 0.012]])
)


def _states(rng: np.random.Generator, n: int = N_STATES) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return rng.uniform(-np.pi, np.pi, (n, 6)), rng.normal(0, 1.5, (n, 6)), rng.normal(0, 4.0, (n, 6))


def _with_masses(robot):
    """ar5 carries no masses: random links (mass, com, inertia) to exercise its geometry."""
    rng = np.random.default_rng(5)
    joints = []
    for j in robot.joints:
        A = rng.normal(size=(3, 3))
        joints.append(
            replace(
                j,
                mass=float(rng.uniform(0.5, 8.0)),
                com=rng.uniform(-0.1, 0.1, 3),
                inertia=0.01 * np.eye(3) + 1e-3 * (A @ A.T) / 3.0,
            )
        )
    return replace(robot, joints=tuple(joints))


def _robot(name: str):
    return _with_masses(load_robot("ar5")) if name == "ar5+masses" else load_robot(name)


def _tau(f: ca.Function, *args) -> np.ndarray:
    return np.asarray(f(*args)).reshape(-1)


def _close(ours: np.ndarray, ref: np.ndarray, tol: float) -> float:
    err = float(np.abs(ours - ref).max())
    assert err < tol * max(1.0, float(np.abs(ref).max())), (err, ours, ref)
    return err


# --------------------------------------------------------------------------------------
# pinocchio models: from the DH rows (the test's own construction), from URDF files
# --------------------------------------------------------------------------------------


def _se3(T: np.ndarray) -> pin.SE3:
    return pin.SE3(np.array(T[:3, :3]), np.array(T[:3, 3]))


def _tf(R: np.ndarray | None = None, p=(0.0, 0.0, 0.0)) -> np.ndarray:
    return transform(np.eye(3) if R is None else R, np.asarray(p, dtype=float))


def _inertia3(v: np.ndarray) -> np.ndarray:
    return np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])


def pinocchio_from_dh(robot, payload: np.ndarray | None = None):
    """pinocchio model of a DH robot: joint i turns about z between the constant parts of
    ``A_i = L_i Rz(theta_i) R_i`` (standard: ``L = I, R = Tz(d) Tx(a) Rx(alpha)``; modified:
    ``L = Rx(alpha) Tx(a), R = Tz(d)``); link i's body sits at ``R_i`` (DH frame i).  Returns the
    model, the last joint's id and the TCP in that joint's frame."""
    model = pin.Model()
    model.gravity.linear = np.asarray(robot.gravity, dtype=float)
    parent, right = 0, np.array(robot.frame02base, dtype=float)
    for i, j in enumerate(robot.joints):
        if robot.convention == "standard_dh":
            left, rgt = np.eye(4), _tf(p=(0, 0, j.d)) @ _tf(p=(j.a, 0, 0)) @ _tf(rot_x(j.alpha))
        else:
            left, rgt = _tf(rot_x(j.alpha)) @ _tf(p=(j.a, 0, 0)), _tf(p=(0, 0, j.d))
        parent = model.addJoint(
            parent, pin.JointModelRZ(), _se3(right @ left @ _tf(rot_z(j.theta_offset))), f"joint{i + 1}"
        )
        m = 0.0 if j.mass is None else j.mass
        c = np.zeros(3) if j.com is None else j.com
        I = np.zeros((3, 3)) if j.inertia is None else j.inertia
        model.appendBodyToJoint(
            parent, pin.Inertia(m, np.asarray(c, dtype=float), np.asarray(I, dtype=float)), _se3(rgt)
        )
        right = rgt
    tcp = right @ robot.flange2frame6 @ robot.tcp2flange
    if payload is not None:
        model.appendBodyToJoint(parent, pin.Inertia(payload[0], payload[1:4], _inertia3(payload[4:10])), _se3(tcp))
    return model, parent, tcp


def pinocchio_from_urdf(robot, payload: np.ndarray | None = None):
    """pinocchio model of a URDF-based robot from its URDF file; returns the model, joint 6's
    id, the TCP in its frame, the q/v indices of the robot's joints and ``base2world``."""
    model = pin.buildModelFromUrdf(robot.urdf["path"])
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    base2world = data.oMf[model.getFrameId(robot.urdf["base_link"])].homogeneous.copy()
    tip = model.frames[model.getFrameId(robot.urdf["tip_link"])]
    jid = model.getJointId(robot.joint_names[-1])
    assert tip.parentJoint == jid
    tcp = tip.placement.homogeneous @ robot.tcp2flange
    if payload is not None:
        model.appendBodyToJoint(jid, pin.Inertia(payload[0], payload[1:4], _inertia3(payload[4:10])), _se3(tcp))
    model.gravity.linear = base2world[:3, :3] @ robot.gravity
    idx = [model.joints[model.getJointId(n)].idx_q for n in robot.joint_names]
    return model, jid, tcp, idx, base2world


def _fext(model, data, jid: int, tcp: np.ndarray, wrench: np.ndarray, base2world: np.ndarray) -> list:
    """The wrench on the TCP (base frame, moment about the TCP) as pinocchio's external force on
    joint ``jid`` (its local frame); the kinematics of ``data`` must be current."""
    R = base2world[:3, :3]
    p = (data.oMi[jid].homogeneous @ tcp)[:3, 3]
    f, m = R @ wrench[:3], R @ wrench[3:]
    fw = pin.Force(f, m + np.cross(p, f))  # world frame, about its origin
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    fext[jid] = data.oMi[jid].actInv(fw)
    return fext


# --------------------------------------------------------------------------------------
# RNEA against pinocchio
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SHIPPED + ("ar5+masses",))
@pytest.mark.parametrize("loaded", [False, True])
def test_rnea_equals_pinocchio_of_the_dh_rows(name, loaded, rng):
    robot = _robot(name)
    robot = robot.with_tool(TOOL) if loaded else robot
    payload = PAYLOAD if loaded else np.zeros(PAYLOAD_SIZE)
    f = rnea_function(robot)
    model, jid, tcp = pinocchio_from_dh(robot, payload if loaded else None)
    data = model.createData()
    Q, V, A = _states(rng)
    worst = 0.0
    for q, v, a in zip(Q, V, A):
        w = np.r_[rng.normal(0, 40, 3), rng.normal(0, 4, 3)] if loaded else np.zeros(6)
        pin.forwardKinematics(model, data, q)
        ref = pin.rnea(model, data, q, v, a, _fext(model, data, jid, tcp, w, np.eye(4)))
        worst = max(worst, _close(_tau(f, q, v, a, payload, w), ref, PINOCCHIO_TOL))
    assert np.abs(ref).max() > 1.0  # real torques: the check can fail


@pytest.mark.parametrize("name", URDF_ROBOTS)
@pytest.mark.parametrize("loaded", [False, True])
def test_rnea_of_urdf_arms_equals_pinocchio_of_their_urdf(name, loaded, rng):
    robot = load_robot(name)
    robot = robot.with_tool(TOOL) if loaded else robot
    payload = PAYLOAD if loaded else np.zeros(PAYLOAD_SIZE)
    f = rnea_function(robot)
    model, jid, tcp, idx, b2w = pinocchio_from_urdf(robot, payload if loaded else None)
    assert not np.allclose(b2w, np.eye(4)) or name != "ur5e"  # ur5e: base = Rz(pi) of the URDF root
    data = model.createData()
    Q, V, A = _states(rng)
    for q, v, a in zip(Q, V, A):
        w = np.r_[rng.normal(0, 40, 3), rng.normal(0, 4, 3)] if loaded else np.zeros(6)
        qp, vp, ap = (np.zeros(model.nq) for _ in range(3))
        qp[idx], vp[idx], ap[idx] = q, v, a
        pin.forwardKinematics(model, data, qp)
        ref = pin.rnea(model, data, qp, vp, ap, _fext(model, data, jid, tcp, w, b2w))[idx]
        _close(_tau(f, q, v, a, payload, w), ref, PINOCCHIO_TOL)


def test_gravity_input_map_and_strict():
    robot = load_robot("ur10")
    f, fg = rnea_function(robot), rnea_function(robot, gravity_input=True, name="rnea_g")
    assert f.name() == "rnea" and fg.name() == "rnea_g" and f.name_out() == ["tau"]
    assert f.name_in() == ["q", "qd", "qdd", "payload", "wrench"] and fg.name_in()[-1] == "g"
    rng = np.random.default_rng(2)
    Q, V, A = _states(rng, 40)
    W = rng.normal(0, 10, (40, 6))
    batch = np.asarray(f.map(40)(Q.T, V.T, A.T, PAYLOAD, W.T)).T
    one = np.array([_tau(f, q, v, a, PAYLOAD, w) for q, v, a, w in zip(Q, V, A, W)])
    assert np.abs(batch - one).max() < 1e-12
    assert np.abs(_tau(fg, Q[0], V[0], A[0], PAYLOAD, W[0], robot.gravity) - one[0]).max() < 1e-12
    tilted = rot_y(0.3) @ robot.gravity
    moved = _tau(fg, Q[0], V[0], A[0], PAYLOAD, W[0], tilted)
    assert np.abs(moved - one[0]).max() > 1.0
    # a point-mass arm: links without inertia tensors
    point = replace(robot, joints=tuple(replace(j, inertia=None) for j in robot.joints))
    assert np.abs(_tau(rnea_function(point), Q[0], V[0], A[0], PAYLOAD, W[0]) - one[0]).max() > 1e-3
    with pytest.raises(RobotFileError, match="inertia"):
        rnea_function(point, strict=True)
    with pytest.raises(RobotFileError, match="mass"):
        rnea_function(load_robot("ar5"), strict=True)


# --------------------------------------------------------------------------------------
# The UR5/UR10 inertias of the robot files against UR's ROS 2 description
# --------------------------------------------------------------------------------------

HALF_PI = math.pi / 2
#: UR's ROS 2 description (Universal_Robots_ROS2_Description, config/urX/default_kinematics.yaml):
#: joint origins (xyz m, rpy rad) shoulder_pan .. wrist_3; the ~2e-11 m / 2e-10 rad residues of
#: the yaml written as 0 / pi/2 (as models/robots/ur5e.urdf does).
UR_KINEMATICS = {
    "ur5": [
        ((0, 0, 0.089159), (0, 0, 0)),
        ((0, 0, 0), (HALF_PI, 0, 0)),
        ((-0.425, 0, 0), (0, 0, 0)),
        ((-0.39225, 0, 0.10915), (0, 0, 0)),
        ((0, -0.09465, 0), (HALF_PI, 0, 0)),
        ((0, 0.0823, 0), (HALF_PI, math.pi, math.pi)),
    ],
    "ur10": [
        ((0, 0, 0.1273), (0, 0, 0)),
        ((0, 0, 0), (HALF_PI, 0, 0)),
        ((-0.612, 0, 0), (0, 0, 0)),
        ((-0.5723, 0, 0.163941), (0, 0, 0)),
        ((0, -0.1157, 0), (HALF_PI, 0, 0)),
        ((0, 0.0922, 0), (HALF_PI, math.pi, math.pi)),
    ],
}
#: config/urX/physical_parameters.yaml: per link mass (kg), centre of mass (m, URDF link frame),
#: inertia frame rpy (rad, in the link frame) and tensor [ixx, iyy, izz, ixy, ixz, iyz] (kg*m^2).
#: UR5: cylinder approximation; its forearm mass is 2.33 kg in that yaml, 2.275 kg on UR's DH page
#: (the robot file's value, also the mass of the yaml's forearm cylinder tensor): 2.275 here.
#: UR10: tensors "extracted from URSim".
UR_INERTIALS = {
    "ur5": [
        (3.7, (0, -0.00193, -0.02561), (0, 0, 0), (0.014972358333333331, 0.014972358333333331, 0.01040625, 0, 0, 0)),
        (8.393, (-0.2125, 0, 0.11336), (0, HALF_PI, 0), (0.13388583541666665, 0.13388583541666665, 0.0151074, 0, 0, 0)),
        (
            2.275,
            (-0.24225, 0, 0.0265),
            (0, HALF_PI, 0),
            (0.031216803515624995, 0.031216803515624995, 0.004095, 0, 0, 0),
        ),
        (1.219, (0, -0.01634, -0.0018), (0, 0, 0), (0.002013889583333333, 0.002013889583333333, 0.0021942, 0, 0, 0)),
        (1.219, (0, 0.01634, -0.0018), (0, 0, 0), (0.0018310395833333333, 0.0018310395833333333, 0.0021942, 0, 0, 0)),
        (
            0.1879,
            (0, 0, -0.001159),
            (0, 0, 0),
            (8.062475833333332e-05, 8.062475833333332e-05, 0.0001321171875, 0, 0, 0),
        ),
    ],
    "ur10": [
        (7.1, (0.021, -0.027, 0), (HALF_PI, 0, 0), (0.03408, 0.03529, 0.02156, 0.00002, -0.00425, 0.00008)),
        (12.7, (-0.232, 0, 0.158), (0, 0, 0), (0.02814, 0.77068, 0.76943, 0.00005, -0.01561, 0.00002)),
        (4.27, (-0.3323, 0, 0.068), (0, 0, 0), (0.01014, 0.30928, 0.30646, 0.00008, 0.00916, 0.0)),
        (2.0, (0, -0.018, 0.007), (HALF_PI, 0, 0), (0.00296, 0.00222, 0.00258, -0.00001, 0.0, -0.00024)),
        (2.0, (0, 0.018, -0.007), (-HALF_PI, 0, 0), (0.00296, 0.00222, 0.00258, -0.00001, 0.0, -0.00024)),
        (0.365, (0, 0, -0.026), (0, 0, 0), (0.00040, 0.00041, 0.00034, 0.0, 0.0, 0.0)),
    ],
}
UR_LINKS = ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link")


def ur_description_urdf(name: str) -> str:
    """A URDF of UR's ROS 2 description (chain and inertials as its xacro writes them), rooted
    at UR's base frame (``base_link_inertia`` = DH frame 0)."""
    f = lambda v: " ".join(repr(float(x)) for x in v)  # noqa: E731 - a one-line helper local to this test
    parts = ['<?xml version="1.0"?>', f'<robot name="{name}">', '<link name="base"/>']
    for link, (m, c, rpy, t) in zip(UR_LINKS, UR_INERTIALS[name]):
        parts.append(
            f'<link name="{link}"><inertial><origin xyz="{f(c)}" rpy="{f(rpy)}"/><mass value="{m!r}"/>'
            f'<inertia ixx="{t[0]!r}" iyy="{t[1]!r}" izz="{t[2]!r}" ixy="{t[3]!r}" ixz="{t[4]!r}" '
            f'iyz="{t[5]!r}"/></inertial></link>'
        )
    parents = ("base",) + UR_LINKS[:-1]
    names = load_robot(name).joint_names
    for jn, parent, child, (xyz, rpy) in zip(names, parents, UR_LINKS, UR_KINEMATICS[name]):
        parts.append(
            f'<joint name="{jn}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{f(xyz)}" rpy="{f(rpy)}"/><axis xyz="0 0 1"/>'
            '<limit lower="-6.2832" upper="6.2832" effort="150" velocity="3.14"/></joint>'
        )
    return "\n".join(parts + ["</robot>"])


@pytest.mark.parametrize("name", ["ur5", "ur10"])
def test_ur_inertias_equal_urs_ros2_description(name, tmp_path, rng):
    """The robot file's masses, centres of mass and inertias (DH link frames) give the dynamics of
    UR's description (URDF link frames): RNEA and mass matrix against pinocchio of that URDF."""
    robot = load_robot(name)
    assert robot.has_inertias
    path = tmp_path / f"{name}.urdf"
    path.write_text(ur_description_urdf(name), encoding="utf-8")
    model = pin.buildModelFromUrdf(str(path))
    model.gravity.linear = np.asarray(robot.gravity, dtype=float)
    data = model.createData()
    idx = [model.joints[model.getJointId(n)].idx_q for n in robot.joint_names]
    assert idx == list(range(6))
    f, fM = rnea_function(robot), mass_matrix_function(robot)
    nothing = np.zeros(PAYLOAD_SIZE)
    # the inertias matter: without them (point masses) the torques differ
    point = rnea_function(replace(robot, joints=tuple(replace(j, inertia=None) for j in robot.joints)))
    gap = 0.0
    Q, V, A = _states(rng)
    for q, v, a in zip(Q, V, A):
        ref = pin.rnea(model, data, q, v, a)
        tau = _tau(f, q, v, a, nothing, np.zeros(6))
        _close(tau, ref, PINOCCHIO_TOL)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        _close(np.asarray(fM(q, nothing)), M, CRBA_TOL)
        gap = max(gap, float(np.abs(_tau(point, q, v, a, nothing, np.zeros(6)) - tau).max()))
    assert gap > 0.1, gap


# --------------------------------------------------------------------------------------
# Mass matrix, static case
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["ur10", "kr6_r900"])
def test_mass_matrix_is_d_tau_d_qdd_symmetric_positive_definite(name, rng):
    robot = load_robot(name).with_tool(TOOL)
    f, fM = rnea_function(robot), mass_matrix_function(robot)
    qdd = ca.SX.sym("qdd", 6)
    q0, v0 = ca.DM(rng.uniform(-np.pi, np.pi, 6)), ca.DM(rng.normal(0, 1.5, 6))
    jac = ca.Function("dtau_dqdd", [qdd], [ca.jacobian(f(q0, v0, qdd, PAYLOAD, np.zeros(6)), qdd)])
    model, _jid, _tcp = pinocchio_from_dh(robot, PAYLOAD)
    data = model.createData()
    for q, v, a in zip(*_states(rng, 8)):
        M = np.asarray(fM(q, PAYLOAD))
        fd = np.column_stack(
            [
                (
                    _tau(f, q, v, a + FD_STEP * e, PAYLOAD, np.zeros(6))
                    - _tau(f, q, v, a - FD_STEP * e, PAYLOAD, np.zeros(6))
                )
                / (2 * FD_STEP)
                for e in np.eye(6)
            ]
        )
        assert np.abs(fd - M).max() < FD_REL_TOL * np.abs(M).max(), np.abs(fd - M).max()
        P = pin.crba(model, data, q)
        _close(M, np.triu(P) + np.triu(P, 1).T, CRBA_TOL)
        assert np.array_equal(M, M.T)
        assert np.linalg.eigvalsh(M).min() > 0.0
    # the symbolic Jacobian of tau in qdd (both triangles) is the mass matrix too
    J = np.asarray(jac(rng.normal(0, 4.0, 6)))
    M0 = np.asarray(fM(q0, PAYLOAD))
    assert np.abs(J - M0).max() < 1e-12 * np.abs(M0).max()


@pytest.mark.parametrize("name", SHIPPED)
def test_static_rnea_equals_the_static_models_torques(name, rng):
    """At rest, tau = -(self-weight torques of models.effects.gravity + J^T F + payload weight):
    the drives hold what the static model's loads apply to the joints."""
    from models.arm import ArmModel
    from models.symbolic import KinematicModel

    robot = load_robot(name).with_tool(TOOL)
    km = KinematicModel(replace(ArmModel.from_robot(robot), gravity_on=True))
    f, fg = rnea_function(robot), gravity_torque_function(robot)
    Q = rng.uniform(-np.pi, np.pi, (N_STATES, 6))
    zero = np.zeros(6)
    Lg = Load(gravity=robot.gravity).rows(N_STATES)
    tg = km.batch(km.fn["joint_torques"], Q, Lg)[0]
    W = np.c_[rng.normal(0, 40, (N_STATES, 3)), rng.normal(0, 4, (N_STATES, 3))]
    pl = payload_vector(PAYLOAD[0], PAYLOAD[1:4])
    L = np.array(
        [Load(wrench_base=w, payload_mass_kg=pl[0], payload_com_m=pl[1:4], gravity=robot.gravity).rows(1)[0] for w in W]
    )
    tl = km.batch(km.fn["joint_torques"], Q, L)[0]
    assert np.abs(tg).max() > 1.0
    for k, q in enumerate(Q):
        _close(_tau(f, q, zero, zero, np.zeros(PAYLOAD_SIZE), zero), -tg[k], STATIC_TOL)
        _close(_tau(fg, q, np.zeros(PAYLOAD_SIZE)), -tg[k], STATIC_TOL)
        # a payload's inertia tensor does not matter at rest; its mass and centre of mass do
        _close(_tau(f, q, zero, zero, PAYLOAD, W[k]), -tl[k], STATIC_TOL)
        _close(_tau(fg, q, PAYLOAD), -km.batch(km.fn["joint_torques"], q, np.r_[zero, L[k, 6:]])[0][0], STATIC_TOL)


def test_payload_vector():
    R = rpy_to_matrix([0.1, 0.2, 0.3])
    I = R @ np.diag([0.01, 0.02, 0.025]) @ R.T
    I = np.triu(I) + np.triu(I, 1).T  # exactly symmetric
    v = payload_vector(2.0, [0.0, 0.01, 0.1], I)
    assert v.shape == (PAYLOAD_SIZE,) and v[0] == 2.0
    assert np.array_equal(_inertia3(v[4:]), I)
    assert np.array_equal(payload_vector(1.0, [0, 0, 0.1], v[4:]), np.r_[1.0, 0, 0, 0.1, v[4:]])
    with pytest.raises(ValueError):
        payload_vector(1.0, [0, 0, 0], np.zeros(4))
