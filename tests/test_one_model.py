"""One arm model from measurement to motion.

Acceptance-like: a truth robot (the virtual robot, which implements the physics
independently of the model's parametrisation) with several undeclared effects is
measured (2 um noise) -> identified -> the identified model plans -> the exactly
compensated commands, run through the truth robot under the problem's load, land on
the path; the nominal model's commands miss by far more.  Done for a base-frame
wrench, a payload whose orientation changes along the path, and a tool-frame wrench.

Loads: the joint torques of a payload and of tool- and base-frame wrenches are checked
against pinocchio (frame Jacobians at the TCP and at the payload's centre of mass).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from models import load_robot
from models.arm import ArmModel
from models.arm_file import load_model, model_toml
from models.load import Load
from planner.cli import main as cli_main
from planner.plan import plan
from problems.compensation import CompensationStatus, exact, uncompensated
from problems.identify import compensate, identify
from problems.problem import load_problem
from problems.virtual import VirtualRobot

from .test_kinematics import pinocchio_from_dh

#: Measurement noise of the campaign (per axis), m.
NOISE_SIGMA_M = 2e-6
#: The identified model's compensated commands land within this on the truth robot, m.
LANDING_TOL_M = 10e-6
#: The nominal model's commands must miss by more than this (so the test can fail), m.
NOMINAL_MISS_MIN_M = 100e-6
#: Torques of the loads against pinocchio, N*m (relative to the torque scale).
TORQUE_RTOL = 1e-10
#: Independent equilibrium check of the payload plan: TCP on the waypoint, m.
PAYLOAD_PHYSICS_TOL_M = 1e-9

TRUTH_EFFECTS = {
    "geometric": {"sigma_length_m": 5e-4, "sigma_angle_rad": 1e-3},
    "gravity": {},
    "stiffness_hardening": {"model": "two_slope", "knee_torque_Nm": 25.0, "stiffness_ratio": 1.6},
    "link_compliance": {"EI_Nm2": 2.0e5, "GJ_Nm2": 1.5e5},
}


def _truth(robot_name: str, tool: np.ndarray, seed: int) -> tuple[VirtualRobot, object]:
    robot = load_robot(robot_name).with_tool(tool)
    cfg = {
        "campaign": {"poses": 120, "loaded_rows": 3, "force_magnitudes_N": [40.0, 90.0, 140.0]},
        "noise": {"sigma_m": NOISE_SIGMA_M},
        "registration": {"registered": True},
        "effects": {k: dict(v) for k, v in TRUTH_EFFECTS.items()},
    }
    vr = VirtualRobot(robot, cfg, seed=seed)
    return vr, robot


def _truth_landing(vr: VirtualRobot, q_command: np.ndarray, load: Load, target_p: np.ndarray) -> np.ndarray:
    """True TCP position error (m, base frame) of commands under a load that may turn with the
    tool: the base-frame wrench is re-evaluated at the truth robot's deflected TCP rotation
    until it stops changing."""
    n = len(q_command)
    F = load.wrench_at(np.broadcast_to(np.eye(3), (n, 3, 3)))
    for _ in range(6):
        _p, tcp = vr.positions(q_command, F)
        F_new = load.wrench_at(tcp[:, :3, :3])
        if np.max(np.abs(F_new - F)) < 1e-12:
            break
        F = F_new
    _p, tcp = vr.positions(q_command, F)
    return np.linalg.norm(tcp[:, :3, 3] - target_p, axis=1)


@pytest.fixture(scope="module")
def identified_ur10(tmp_path_factory):
    problem = load_problem("ur10_payload_tilt")
    vr, robot = _truth("ur10", problem.robot.tcp2flange, seed=21)
    res = identify(robot, vr.campaign(), registered=True)
    path = tmp_path_factory.mktemp("model") / "ur10_identified.toml"
    path.write_text(model_toml(res.model))
    return vr, res, path


@pytest.mark.parametrize("case", ["payload", "base_wrench"])
def test_identified_model_plans_commands_that_land_on_the_truth_robot(identified_ur10, case):
    vr, res, model_path = identified_ur10
    problem = load_problem("ur10_payload_tilt")
    if case == "base_wrench":
        from dataclasses import replace

        problem = replace(
            problem,
            payload_mass_kg=0.0,
            wrench=np.broadcast_to([20.0, -30.0, -60.0, 0.0, 1.0, 0.0], (problem.n, 6)).copy(),
        )
    assert {"geometric", "gravity"} <= set(res.model.effects), res.model.effects
    identified = plan(problem.with_robot(str(model_path)))
    nominal = plan(problem)
    assert identified.ok and nominal.ok, (identified.reason, nominal.reason)
    assert identified.exact.status is CompensationStatus.OK
    load = problem.load
    err_id = _truth_landing(vr, identified.exact.q_command, load, problem.positions)
    err_nom = _truth_landing(vr, nominal.exact.q_command, load, problem.positions)
    assert err_id.max() < LANDING_TOL_M, err_id.max()
    assert err_nom.max() > NOMINAL_MISS_MIN_M, err_nom.max()
    # the summary records which model planned and which effects were active
    md = identified.summary()["model"]
    assert md["sha256"] and set(res.model.effects) <= set(md["effects"])


def test_tool_frame_wrench_plan_lands_on_the_truth_robot():
    problem = load_problem("ur5_tool_thrust")
    vr, robot = _truth("ur5", problem.robot.tcp2flange, seed=22)
    res = identify(robot, vr.campaign(), registered=True)
    identified = plan(problem.with_robot(res.model))
    nominal = plan(problem)
    assert identified.ok and nominal.ok
    # the tool axis leans differently along the path, so the thrust turns with it
    R = identified.problem.model.kinematics.tcp(identified.branch.q)[:, :3, :3]
    assert np.ptp(R[:, :, 2], axis=0).max() > 1e-3
    err_id = _truth_landing(vr, identified.exact.q_command, problem.load, problem.positions)
    err_nom = _truth_landing(vr, nominal.exact.q_command, problem.load, problem.positions)
    assert err_id.max() < LANDING_TOL_M, err_id.max()
    assert err_nom.max() > NOMINAL_MISS_MIN_M, err_nom.max()


def test_plan_with_identified_model_equals_compensate_on_the_same_commands(identified_ur10):
    _vr, res, model_path = identified_ur10
    problem = load_problem("ur10_payload_tilt")
    from dataclasses import replace

    problem = replace(
        problem, payload_mass_kg=0.0, wrench=np.broadcast_to([0.0, 0.0, -50.0, 0.0, 0.0, 0.0], (problem.n, 6)).copy()
    )
    out = plan(problem.with_robot(str(model_path)))
    model = load_model(model_path).with_tool(problem.robot.tcp2flange)
    targets = model.kinematics.tcp(out.branch.q)
    comp = compensate(model, out.branch.q, problem.wrench, target2base=targets)
    assert comp.status is CompensationStatus.OK
    assert np.abs(comp.q_command - out.exact.q_command).max() < 1e-12


def test_cli_plan_with_robot_model_records_it(identified_ur10, tmp_path, capsys):
    _vr, _res, model_path = identified_ur10
    rc = cli_main(
        ["plan", "ur10_payload_tilt", "--robot", str(model_path), "--out", str(tmp_path / "run"), "--no-report"]
    )
    assert rc == 0
    import json

    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["model"]["file"] == str(model_path.resolve())
    assert s["payload"]["mass_kg"] == 5.0
    assert "arm model:" in capsys.readouterr().out


# ----------------------------------------------------------------------------------
# Loads against an independent implementation
# ----------------------------------------------------------------------------------


def test_payload_and_wrench_torques_match_pinocchio(rng):
    robot = load_robot("ur10").with_tool(
        np.array([[0, -1, 0, 0.03], [1, 0, 0, -0.02], [0, 0, 1, 0.15], [0, 0, 0, 1.0]])
    )
    arm = ArmModel.from_robot(robot)
    pm, fid = pinocchio_from_dh(robot)
    com = np.array([0.02, 0.05, 0.08])
    parent = pm.frames[fid].parentJoint
    cid = pm.addFrame(
        pin.Frame("payload_com", parent, 0, pm.frames[fid].placement * pin.SE3(np.eye(3), com), pin.FrameType.OP_FRAME)
    )
    pd = pm.createData()
    g = robot.gravity
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, 6)
        load = Load(
            wrench_base=rng.normal(0, 30, 6),
            wrench_tool=rng.normal(0, 30, 6),
            payload_mass_kg=4.0,
            payload_com_m=com,
            gravity=g,
        )
        tau = np.asarray(arm.kinematics.fn["joint_torques"](q, load.rows(1)[0])).reshape(6)
        pin.forwardKinematics(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        Jt = pin.computeFrameJacobian(pm, pd, q, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        Jc = pin.computeFrameJacobian(pm, pd, q, cid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        R = pd.oMf[fid].rotation
        wt = np.r_[R @ load.wrench_tool[:3], R @ load.wrench_tool[3:]]
        ref = Jt.T @ (load.wrench_base + wt) + Jc[:3].T @ (4.0 * g)
        assert np.allclose(tau, ref, rtol=0, atol=TORQUE_RTOL * max(1.0, np.abs(ref).max())), (tau, ref)


def test_payload_plan_lands_under_independent_physics():
    """The payload plan's commands through an independent fixed point (pinocchio FK and
    Jacobians, the payload's weight at its centre of mass) land on the waypoints."""
    problem = load_problem("ur10_payload_tilt")
    res = plan(problem)
    assert res.ok
    robot = problem.robot
    pm, fid = pinocchio_from_dh(robot)
    parent = pm.frames[fid].parentJoint
    cid = pm.addFrame(
        pin.Frame(
            "c", parent, 0, pm.frames[fid].placement * pin.SE3(np.eye(3), problem.payload_com_m), pin.FrameType.OP_FRAME
        )
    )
    pd = pm.createData()
    w = problem.payload_mass_kg * robot.gravity
    worst = 0.0
    for k, qc in enumerate(res.exact.q_command):
        q = qc.copy()
        for _ in range(100):
            pin.computeJointJacobians(pm, pd, q)
            pin.updateFramePlacements(pm, pd)
            Jc = pin.getFrameJacobian(pm, pd, cid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            q_new = qc + (Jc[:3].T @ w) / robot.stiffness
            if np.abs(q_new - q).max() < 1e-15:
                q = q_new
                break
            q = q_new
        pin.forwardKinematics(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        worst = max(worst, float(np.linalg.norm(pd.oMf[fid].translation - problem.positions[k])))
    assert worst < PAYLOAD_PHYSICS_TOL_M, worst
    # and the payload does bend the uncompensated arm
    before = uncompensated(problem.model, res.branch.q, problem.load)
    assert before.error_norm_m.max() > 1e-4


def test_exact_compensation_with_link_compliance_solves_the_pose():
    """With an effect that moves the TCP outside the joints, the exact engine solves the pose."""
    robot = load_robot("ur10")
    arm = ArmModel.from_robot(robot)
    from models import effects as fx

    th = arm.theta.copy()
    s = fx.GROUP_SLICES["link_compliance.link"]
    lay = fx.make_layout(robot)
    th[s] = lay.scale[s] * lay.eligible[s] * 3.0
    arm2 = ArmModel(nominal=robot, theta=th, effects=["link_compliance"])
    q = np.array([[0.2, -1.2, 1.4, -1.6, -1.5, 0.3], [0.5, -1.0, 1.2, -1.3, -1.4, 0.1]])
    F = np.array([30.0, -20.0, -80.0, 1.0, 0.0, 2.0])
    out = exact(arm2, q, F)
    assert out.status is CompensationStatus.OK and out.error_norm_m.max() < 1e-9
    # the displacement is real: the springs-only command misses
    miss = exact(arm, q, F)
    p, _R = arm2.loaded_tcp(arm2.equilibrium(miss.q_command, F).q, F)
    assert np.linalg.norm(p - arm2.kinematics.tcp(q)[:, :3, 3], axis=1).max() > 1e-5


def test_plan_warns_where_the_identified_torque_curve_is_extrapolated(identified_ur10):
    _vr, res, model_path = identified_ur10
    assert "stiffness_hardening" in res.model.effects and res.model.torque_range_Nm is not None
    from dataclasses import replace

    problem = load_problem("ur10_payload_tilt").with_robot(str(model_path))
    inside = plan(problem)
    assert not [w for w in inside.warnings if "extrapolated" in w]
    heavy = plan(replace(problem, payload_mass_kg=60.0))
    lines = [w for w in heavy.warnings if "extrapolated" in w]
    assert lines and "stiffness_hardening" in lines[0] and "N*m" in lines[0]


def test_plan_with_a_model_from_unregistered_data_says_the_base_frame_is_not_exact():
    problem = load_problem("ur5_tool_thrust")
    robot = load_robot("ur5").with_tool(problem.robot.tcp2flange)
    cfg = {
        "campaign": {"poses": 60},
        "noise": {"sigma_m": NOISE_SIGMA_M},
        "registration": {"registered": False},
        "effects": {"geometric": {}},
    }
    res = identify(robot, VirtualRobot(robot, cfg, seed=23).campaign(), candidates=["geometric"])
    out = plan(problem.with_robot(res.model), optimise=False)
    lines = [w for w in out.warnings if "unregistered" in w]
    assert out.ok and lines and "dtheta[1]" in lines[0] and "measurement frame" in lines[0]
    registered = plan(problem, optimise=False)
    assert not [w for w in registered.warnings if "unregistered" in w]


def test_plan_says_where_a_joint_stays_inside_its_dead_band():
    """A thrust along a vertical tool axis puts (almost) no torque on the wrist joint 5: with lost
    motion identified there the joint's side of its dead band is not determined, which the plan
    must say (with the size)."""
    from models import effects as fx

    problem = load_problem("ur5_tool_thrust")
    lay = fx.make_layout(problem.robot)
    theta = lay.nominal.copy()
    theta[fx.GROUP_SLICES["lost_motion.b"]] = 2e-4
    arm = ArmModel(nominal=problem.robot, theta=theta, tau_scale=np.full(6, 20.0), effects=["lost_motion"])
    out = plan(problem.with_robot(arm), optimise=False)
    lines = [w for w in out.warnings if "dead band" in w]
    assert out.ok and any(w.startswith("joint 5:") for w in lines), out.warnings
    mm = float(lines[0].split("up to ")[1].split(" mm")[0])
    assert 0.01 < mm < 0.5  # 2e-4 rad times a lever of 0.05 .. 2.5 m
    assert not [w for w in plan(problem, optimise=False).warnings if "dead band" in w]


def test_plan_with_a_model_of_implausible_geometry_says_so():
    """A model whose DH corrections are centimetres (identified with the wrong robot file) plans
    with a warning naming them, not silently."""
    from models import effects as fx

    problem = load_problem("ur5_tool_thrust")
    lay = fx.make_layout(problem.robot)
    theta = lay.nominal.copy()
    theta[fx.GROUP_SLICES["geometric.da"]][1] = -0.05  # 50 mm on a2
    arm = ArmModel(nominal=problem.robot, theta=theta, effects=["geometric"])
    out = plan(problem.with_robot(arm), optimise=False)
    lines = [w for w in out.warnings if "implausible geometry" in w]
    assert lines and "da[2] = -50.0 mm" in lines[0]
    assert not [w for w in plan(problem, optimise=False).warnings if "implausible" in w]
