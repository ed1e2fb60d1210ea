"""Any 6R arm: IK families detected from the chain, every branch, and plans that land on the path.

* FK(IK(T)) = T over 10,000 random poses per shipped arm, the generating configuration among
  the branches;
* the OPW branch set of the shipped KUKA equals an independent OPW solver's
  (py-opw-kinematics, with KUKA's published parameters, not ours);
* a plan on an industrial arm the product does not ship (an ABB IRB 2400 written here as a
  URDF, with its own stiffness, a tool-frame process force): the exactly compensated path,
  run through an independent simulation (pinocchio's kinematics from the same URDF and the
  joint springs), lands on the path within 1 micrometre.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from models import KinematicModel, load_robot
from models.compiler import NO_COMPILER_ENV
from models.ik import IKStatus, ik_solver

#: FK(IK(T)) against T: positions (m) and rotation entries.
FK_IK_TOL = 1e-10
#: The generating configuration among the branches (rad, modulo 2 pi).
GENERATOR_TOL_RAD = 1e-8
#: Random poses per shipped arm.
N_POSES = 10_000
#: Branch sets against the independent OPW solver (rad, modulo 2 pi).
OPW_SET_TOL_RAD = 1e-8
#: Exactly compensated TCP against the path in the independent simulation (m).
LANDING_TOL_M = 1e-6

SHIPPED = {"ar5": "ur", "ur5": "ur", "ur10": "ur", "ur5e": "ur", "kr6_r900": "opw"}


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


@pytest.mark.parametrize("name,family", SHIPPED.items())
def test_fk_of_ik_over_random_poses_of_every_shipped_arm(name, family):
    robot = load_robot(name)
    ik = ik_solver(robot)
    assert ik.family == family
    km = KinematicModel(robot)
    rng = np.random.default_rng(11)
    q = rng.uniform(np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi), (N_POSES, 6))
    T = km.tcp(q)
    sol = ik.solve(T)
    ok = sol.valid
    assert ok.any(axis=1).mean() > 0.999  # (a pose exactly at a singularity may fail)
    Tq = km.tcp(np.nan_to_num(sol.q.reshape(-1, 6))).reshape(N_POSES, ik.n_branches, 4, 4)
    err = np.abs(Tq - T[:, None])[ok]
    assert err.max() < FK_IK_TOL
    d = np.abs(_wrap(sol.q - q[:, None])).max(axis=2)
    found = np.nanmin(np.where(ok, d, np.nan), axis=1) < GENERATOR_TOL_RAD
    # the generating q is missing only where it sits at a singularity (its branch is ill-defined)
    assert found.mean() > 0.999, f"{(~found).sum()} of {N_POSES} generators not found"


def test_shipped_kuka_branch_set_equals_an_independent_opw_solver():
    pko = pytest.importorskip("py_opw_kinematics")
    from scipy.spatial.transform import RigidTransform

    robot = load_robot("kr6_r900")
    ik = ik_solver(robot)
    # KUKA KR 6 R900 sixx as published for OPW solvers (not extracted by compplan)
    model = pko.KinematicModel(
        a1=0.025,
        a2=-0.035,
        b=0.0,
        c1=0.400,
        c2=0.455,
        c3=0.420,
        c4=0.080,
        offsets=(0.0, -math.pi / 2, 0.0, 0.0, 0.0, 0.0),
        flip_axes=(True, False, False, True, False, True),
    )
    ref = pko.Robot(model, degrees=False)
    km = KinematicModel(robot)
    rng = np.random.default_rng(3)
    q = rng.uniform(np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi), (500, 6))
    T = km.tcp(q)  # tool0 in base_link: the OPW solver's flange frame
    theirs = np.asarray(ref.reach(RigidTransform.from_matrix(T)).joints)  # (N, 8, 6), NaN: none
    ours = ik.solve(T)
    for k in range(len(T)):
        # every branch either solver finds (ours: all solutions, before joint limits)
        a = [_wrap(x) for x in theirs[k] if np.all(np.isfinite(x))]
        b = [
            _wrap(x)
            for x, s in zip(ours.q[k], ours.status[k])
            if s in (IKStatus.OK.code, IKStatus.JOINT_LIMIT.code) and np.all(np.isfinite(x))
        ]
        b += [_wrap(x) for x, s in zip(_raw_solutions(ik, T[k]), ours.status[k]) if s == IKStatus.JOINT_LIMIT.code]
        b = [x for x in b if np.all(np.isfinite(x))]
        for x in a:
            assert min(np.abs(_wrap(x - y)).max() for y in b) < OPW_SET_TOL_RAD, (k, x)
        for y in b:
            assert min(np.abs(_wrap(x - y)).max() for x in a) < OPW_SET_TOL_RAD, (k, y)


def _raw_solutions(ik, T: np.ndarray) -> np.ndarray:
    """The closed form's branches before the joint limits (q wrapped to (-pi, pi])."""
    T = T @ np.linalg.inv(ik.robot.tcp2flange)
    q, _ = ik.evaluator(T.T.reshape(1, 16))
    return np.asarray(q)[0].T


# --------------------------------------------------------------------------------------
# An industrial arm we do not ship: ABB IRB 2400, its own URDF, stiffness and a process force
# --------------------------------------------------------------------------------------

IRB2400_URDF = """<?xml version="1.0"?>
<robot name="abb_irb2400">
  <link name="base_link"/>
  <link name="link_1"><inertial><origin xyz="0 0 0.3"/><mass value="90"/>
    <inertia ixx="3" iyy="3" izz="2" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="link_2"><inertial><origin xyz="0 0 0.35"/><mass value="30"/>
    <inertia ixx="1.5" iyy="1.5" izz="0.2" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="link_3"><inertial><origin xyz="0.1 0 0.1"/><mass value="25"/>
    <inertia ixx="0.5" iyy="0.8" izz="0.8" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="link_4"><inertial><origin xyz="0.25 0 0"/><mass value="8"/>
    <inertia ixx="0.05" iyy="0.2" izz="0.2" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="link_5"><inertial><origin xyz="0 0 0"/><mass value="2"/>
    <inertia ixx="0.005" iyy="0.005" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="link_6"><inertial><origin xyz="0.01 0 0"/><mass value="0.5"/>
    <inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tool0"/>
  <joint name="joint_1" type="revolute"><parent link="base_link"/><child link="link_1"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3.1416" upper="3.1416" velocity="2.618" effort="0"/></joint>
  <joint name="joint_2" type="revolute"><parent link="link_1"/><child link="link_2"/>
    <origin xyz="0.1 0 0.615" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1.7453" upper="1.9199" velocity="2.618" effort="0"/></joint>
  <joint name="joint_3" type="revolute"><parent link="link_2"/><child link="link_3"/>
    <origin xyz="0 0 0.705" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1.0472" upper="1.1345" velocity="2.618" effort="0"/></joint>
  <joint name="joint_4" type="revolute"><parent link="link_3"/><child link="link_4"/>
    <origin xyz="0.258 0 0.135" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-3.49" upper="3.49" velocity="6.2832" effort="0"/></joint>
  <joint name="joint_5" type="revolute"><parent link="link_4"/><child link="link_5"/>
    <origin xyz="0.497 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.0944" upper="2.0944" velocity="6.2832" effort="0"/></joint>
  <joint name="joint_6" type="revolute"><parent link="link_5"/><child link="link_6"/>
    <origin xyz="0.085 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-6.9813" upper="6.9813" velocity="7.854" effort="0"/></joint>
  <joint name="joint_6-tool0" type="fixed"><parent link="link_6"/><child link="tool0"/>
    <origin xyz="0 0 0" rpy="0 1.5707963267948966 0"/></joint>
</robot>
"""

IRB2400_ROBOT = """name = "irb2400"
urdf = "irb2400.urdf"
base_link = "base_link"
tip_link = "tool0"
stiffness = [450000.0, 420000.0, 300000.0, 40000.0, 35000.0, 20000.0]
"""

IRB2400_PROBLEM = """name = "irb2400_drilling"
[robot]
model = "irb2400.toml"
tool = { xyz = [0.0, 0.02, 0.2], rpy_deg = [0.0, 0.0, 0.0] }
[path]
kind = "line"
start = [0.9, -0.3, 0.4]
end = [0.9, 0.3, 0.4]
points = 12
[orientation]
rule = "cone"
rpy_deg = [180.0, 0.0, 0.0]
half_angle_deg = 8.0
scan = 12
[wrench]
frame = "tool"
force = [20.0, -10.0, -250.0]
moment = [0.0, 0.0, 6.0]
[limits]
max_joint_step = 0.3
"""


def _pinocchio_landing(
    urdf: Path,
    names: tuple[str, ...],
    stiffness: np.ndarray,
    tool: np.ndarray,
    q_cmd: np.ndarray,
    f_tool: np.ndarray,
    m_tool: np.ndarray,
) -> np.ndarray:
    """TCP positions (N, 3) of the elastic arm commanded to ``q_cmd``: the equilibrium
    ``K (q - q_cmd) = J(q)^T W(q)`` with the tool-frame wrench turned by the TCP's rotation,
    by fixed-point iteration on pinocchio's kinematics (independent of compplan's model)."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    fid = model.getFrameId("tool0")
    idx = [model.joints[model.getJointId(n)].idx_q for n in names]
    out = []
    for qc in q_cmd:
        q = qc.copy()
        for _ in range(60):
            qp = pin.neutral(model)
            qp[idx] = q
            pin.computeJointJacobians(model, data, qp)
            pin.updateFramePlacements(model, data)
            M = data.oMf[fid].homogeneous @ tool
            Jf = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:, idx]
            r = M[:3, 3] - data.oMf[fid].translation  # flange -> TCP, base frame
            Jv = Jf[:3] + np.cross(Jf[3:].T, r).T  # TCP linear velocity: v + w x r
            f, m = M[:3, :3] @ f_tool, M[:3, :3] @ m_tool
            tau = Jv.T @ f + Jf[3:].T @ m
            q_new = qc + tau / stiffness
            if np.abs(q_new - q).max() < 1e-15:
                q = q_new
                break
            q = q_new
        qp = pin.neutral(model)
        qp[idx] = q
        pin.framesForwardKinematics(model, data, qp)
        out.append((data.oMf[fid].homogeneous @ tool)[:3, 3])
    return np.array(out)


def _tilted_irb2400(deg: float) -> str:
    """The IRB 2400 with joint 2's axis tilted by ``deg`` about x: no longer ortho-parallel."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    old = '<origin xyz="0.1 0 0.615" rpy="0 0 0"/><axis xyz="0 1 0"/>'
    assert old in IRB2400_URDF
    return IRB2400_URDF.replace(old, f'<origin xyz="0.1 0 0.615" rpy="0 0 0"/><axis xyz="0 {c!r} {s!r}"/>')


@pytest.mark.parametrize("tilt_deg,family", [(0.0, "opw"), (20.0, "general")])
def test_a_plan_on_an_unshipped_industrial_arm_lands_on_the_path(tmp_path, monkeypatch, tilt_deg, family):
    if family == "general":
        # CasADi's virtual machine evaluates the same functions (tests/test_no_compiler.py: equal to
        # rounding); compiling this one-off arm's posture NLP took 25 s of CPU with a cold cache.
        # The OPW case plans with compiled code.
        monkeypatch.setenv(NO_COMPILER_ENV, "1")
    (tmp_path / "irb2400.urdf").write_text(_tilted_irb2400(tilt_deg), encoding="utf-8")
    (tmp_path / "irb2400.toml").write_text(IRB2400_ROBOT, encoding="utf-8")
    (tmp_path / "problem.toml").write_text(IRB2400_PROBLEM, encoding="utf-8")
    from planner.plan import plan
    from problems.problem import load_problem

    pr = load_problem(str(tmp_path / "problem.toml"))
    res = plan(pr).raise_for_status()
    assert res.posture.ik_family == family
    assert len(res.posture.branches) >= 2  # the branch choice is a real one
    q_cmd = res.exact.q_command
    robot = pr.robot
    tcp = _pinocchio_landing(
        tmp_path / "irb2400.urdf",
        robot.joint_names,
        robot.stiffness,
        robot.tcp2flange,
        q_cmd,
        np.array([20.0, -10.0, -250.0]),
        np.array([0.0, 0.0, 6.0]),
    )
    err = np.linalg.norm(tcp - pr.positions, axis=1)
    assert err.max() < LANDING_TOL_M, err.max()
    # and without compensation it would not have landed (the check can fail)
    tcp0 = _pinocchio_landing(
        tmp_path / "irb2400.urdf",
        robot.joint_names,
        robot.stiffness,
        robot.tcp2flange,
        res.posture.best.q,
        np.array([20.0, -10.0, -250.0]),
        np.array([0.0, 0.0, 6.0]),
    )
    assert np.linalg.norm(tcp0 - pr.positions, axis=1).max() > 100 * LANDING_TOL_M


def test_a_ur_arm_with_reversed_axes_is_solved_completely_by_the_general_family(tmp_path):
    """A UR5 whose URDF turns joints 2 and 5 the other way is not UR-type (anti-parallel axes);
    EAIK solves it once its parallel axes are made to agree, every branch found."""
    from tests.test_urdf import _robot_file, _with_masses, urdf_from_dh

    urdf_from_dh(_with_masses(load_robot("ur5")), tmp_path / "arm.urdf", (1, 4))
    robot = load_robot(_robot_file(tmp_path, load_robot("ur5")))
    ik = ik_solver(robot)
    assert ik.family == "general" and ik.complete
    km = KinematicModel(robot)
    q = np.random.default_rng(4).uniform(-np.pi, np.pi, (300, 6))
    T = km.tcp(q)
    sol = ik.solve(T)
    assert sol.valid.sum(axis=1).mean() > 6.5  # a UR pose has 8 solutions, few fewer
    Tq = km.tcp(np.nan_to_num(sol.q.reshape(-1, 6))).reshape(len(q), ik.n_branches, 4, 4)
    assert np.abs(Tq - T[:, None])[sol.valid].max() < FK_IK_TOL
    d = np.abs(_wrap(sol.q - q[:, None])).max(axis=2)
    assert (np.nanmin(np.where(sol.valid, d, np.nan), axis=1) < GENERATOR_TOL_RAD).mean() > 0.99


def test_general_branch_labels_follow_a_reference():
    """The general family's labels hold within one call; solve_like puts another call's branches
    in the reference's slots (the posture warm starts rely on it)."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "irb2400.urdf").write_text(_tilted_irb2400(20.0), encoding="utf-8")
        (Path(d) / "irb2400.toml").write_text(IRB2400_ROBOT, encoding="utf-8")
        robot = load_robot(Path(d) / "irb2400.toml")
    ik = ik_solver(robot)
    assert not ik.labels_stable
    km = KinematicModel(robot)
    q = np.random.default_rng(6).uniform(-1.0, 1.0, (12, 6))
    T = km.tcp(q)
    ref = ik.solve(T)
    mixed = ik.solve(np.concatenate([km.tcp(np.random.default_rng(7).uniform(-1, 1, (5, 6))), T]))
    from models.ik.base import IKSolution, match_branches

    tail = IKSolution(q=mixed.q[5:], status=mixed.status[5:], labels=mixed.labels)
    matched = match_branches(tail, ref.q)
    assert np.array_equal(np.isnan(matched.q), np.isnan(ref.q))
    assert np.allclose(np.nan_to_num(matched.q), np.nan_to_num(ref.q), atol=1e-9)
    assert np.array_equal(matched.status, ref.status)
