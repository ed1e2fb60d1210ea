"""Elastic-joint simulation of a timed trajectory (problems.virtual.elastic).

* its NumPy rigid-body dynamics against pinocchio (RNEA with payload and wrench, CRBA) and against
  the CasADi model (models.dynamics), on UR5 and the URDF-based arms;
* rest: a constant command stays at the static equilibrium, which is the virtual robot's and the
  model's deflected pose; released from the undeflected pose the arm settles there;
* a fast move (UR5, 5 kg, accelerations and jerks at 92-96 % of the limits) under the static
  compensation alone: a dynamic TCP error during the motion that decays after the stop; commanded
  with the link-side plan itself, the arm comes to rest at the static deflection;
* physics: without gravity and damping the energy is conserved, with damping it only falls;
* the PID motor, the trajectory-file reader, bad inputs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from models.dynamics import payload_vector, rnea_function
from models.errors import InputError
from models.robot import load_robot
from models.transforms import rot_x, rot_z, transform
from problems.virtual import VirtualRobot
from problems.virtual.elastic import (
    SIM_ATOL_ANGLE_RAD,
    SIM_RTOL,
    ElasticArm,
    ElasticStatus,
    read_trajectory_csv,
    simulate_elastic,
    static_command,
    tracking_error,
)

pin = pytest.importorskip("pinocchio")
from tests.test_dynamics import _fext, pinocchio_from_dh, pinocchio_from_urdf  # noqa: E402 - after the importorskip above

#: NumPy dynamics against pinocchio / CasADi, relative to max(1, largest |value|).
DYNAMICS_TOL = 1e-10
#: Rest pose: the simulation starts at the equilibrium, whose residual is rounding; the TCP stays
#: within this (m) whatever the solver's tolerances.
REST_TCP_TOL = 1e-9
#: Released from the undeflected pose (strong damping, 1.5 s): decayed to the solver's accuracy,
#: ~ SIM_ATOL_ANGLE_RAD x 1 m lever x 100 (m).
SETTLED_TCP_TOL = 100 * SIM_ATOL_ANGLE_RAD
#: Relative energy drift allowed without damping over ENERGY_T: 20 x the solver's rtol (measured
#: 3.7e-9 with rtol 1e-8).
ENERGY_REL_TOL = 20 * SIM_RTOL
#: Duration of the free oscillation, s (~15 periods of the slowest mode, hundreds of the wrist's).
ENERGY_T = 0.05

TOOL = transform(rot_z(0.3) @ rot_x(-0.4), np.array([0.05, -0.02, 0.12]))
PAYLOAD = payload_vector(
    3.5, [0.02, -0.03, 0.09], np.array([[0.021, 0.002, -0.003], [0.002, 0.018, 0.001], [-0.003, 0.001, 0.012]])
)
WRENCH = np.array([30.0, -20.0, -45.0, 2.0, -1.5, 0.8])
#: UR5 move: quintic rest to rest in MOVE_T s; 0.8 rad gives 4.6 rad/s^2 (a_max 5) and 48 rad/s^3 (j_max 50).
MOVE_T = 1.0
MOVE_DQ = np.array([0.8, 0.6, -0.8, 0.8, 0.8, 0.8])
MOVE_Q0 = np.array([0.0, -1.5, 1.2, -1.3, -1.57, 0.0])
MOVE_PAYLOAD = payload_vector(5.0, [0.0, 0.0, 0.05], np.diag([0.02, 0.02, 0.02]))
DT = 0.008


def _move(T: float = MOVE_T, dq: np.ndarray = MOVE_DQ):
    t = np.arange(0.0, T + 1e-12, DT)
    s = t / T
    h, hd = 10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    return t, MOVE_Q0 + h[:, None] * dq, hd[:, None] * dq


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(1.0, np.abs(b).max()))


# --------------------------------------------------------------------------------------
# Rigid-body dynamics
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["ur5", "kr6_r900"])
def test_numpy_dynamics_equal_pinocchio(name, rng):
    robot = load_robot(name).with_tool(TOOL)
    arm = ElasticArm(robot, PAYLOAD, WRENCH)
    if name == "ur5":
        model, jid, tcp = pinocchio_from_dh(robot, PAYLOAD)
        idx, b2w = list(range(6)), np.eye(4)
    else:
        model, jid, tcp, idx, b2w = pinocchio_from_urdf(robot, PAYLOAD)
    data = model.createData()
    Q, V, A = rng.uniform(-np.pi, np.pi, (10, 6)), rng.normal(0, 1.5, (10, 6)), rng.normal(0, 4, (10, 6))
    tau, M = arm.inverse_dynamics(Q, V, A), arm.mass_matrix(Q)
    for k in range(len(Q)):
        qp, vp, ap = (np.zeros(model.nq) for _ in range(3))
        qp[idx], vp[idx], ap[idx] = Q[k], V[k], A[k]
        pin.forwardKinematics(model, data, qp)
        ref = pin.rnea(model, data, qp, vp, ap, _fext(model, data, jid, tcp, WRENCH, b2w))[idx]
        assert _rel(tau[k], ref) < DYNAMICS_TOL
        Mp = pin.crba(model, data, qp)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        assert _rel(M[k], Mp[np.ix_(idx, idx)]) < DYNAMICS_TOL
    assert np.abs(tau).max() > 10.0


@pytest.mark.parametrize("name", ["ur5", "ur10", "ur5e", "kr6_r900"])
def test_numpy_dynamics_equal_the_casadi_model(name, rng):
    robot = load_robot(name).with_tool(TOOL)
    arm, f = ElasticArm(robot, PAYLOAD, WRENCH), rnea_function(robot)
    Q, V, A = rng.uniform(-np.pi, np.pi, (10, 6)), rng.normal(0, 1.5, (10, 6)), rng.normal(0, 4, (10, 6))
    tau = arm.inverse_dynamics(Q, V, A)
    for k in range(len(Q)):
        assert _rel(tau[k], np.asarray(f(Q[k], V[k], A[k], PAYLOAD, WRENCH)).ravel()) < DYNAMICS_TOL
    # the mass matrix is the columns of the inverse dynamics
    zero = np.zeros_like(Q)
    cols = np.stack(
        [arm.inverse_dynamics(Q, zero, np.eye(6)[j][None].repeat(len(Q), 0), gravity=False) for j in range(6)], axis=2
    )
    assert _rel(arm.mass_matrix(Q), cols) < DYNAMICS_TOL


# --------------------------------------------------------------------------------------
# Rest
# --------------------------------------------------------------------------------------


def _virtual(robot, payload):
    """The virtual robot with the robot file's link masses, the payload as a point mass (its COM
    in the flange frame) and the base-frame wrench at the TCP."""
    com_flange = robot.tcp2flange[:3, :3] @ payload[1:4] + robot.tcp2flange[:3, 3]
    cfg = {
        "registration": {"registered": True},
        "effects": {"gravity": {"payload_kg": float(payload[0]), "payload_com_m": com_flange.tolist()}},
    }
    return VirtualRobot(robot, cfg)


@pytest.mark.parametrize("name", ["ur5", "kr6_r900"])
def test_constant_command_rests_at_the_static_deflected_pose(name):
    robot = load_robot(name).with_tool(TOOL)
    q_star = np.array([0.3, -1.1, 1.4, -0.9, 1.2, 0.4])
    hold = np.asarray(rnea_function(robot)(q_star, np.zeros(6), np.zeros(6), PAYLOAD, WRENCH)).ravel()
    theta = q_star + hold / robot.stiffness  # the model's exact static compensation
    assert np.allclose(theta, static_command(robot, q_star, payload=PAYLOAD, wrench=WRENCH)[0], atol=1e-14)
    t = np.array([0.0, 0.1, 0.2])
    res = simulate_elastic(robot, t, np.tile(theta, (3, 1)), payload=PAYLOAD, wrench=WRENCH, settle_s=0.2)
    assert res.status is ElasticStatus.OK, res.reason
    p_star = ElasticArm(robot).tcp_position(q_star)[0]
    assert np.linalg.norm(res.p_tcp - p_star, axis=1).max() < REST_TCP_TOL
    q_virtual = _virtual(robot, PAYLOAD).equilibrium(theta[None], WRENCH)[0]
    assert np.linalg.norm(ElasticArm(robot).tcp_position(q_virtual)[0] - p_star) < REST_TCP_TOL
    assert np.linalg.norm(p_star - ElasticArm(robot).tcp_position(theta)[0]) > 1e-4  # a real deflection
    # released from the undeflected pose, the arm settles at the same equilibrium
    free = simulate_elastic(
        robot, t, np.tile(theta, (3, 1)), payload=PAYLOAD, wrench=WRENCH, q0=theta, damping_ratio=0.7, settle_s=1.5
    )
    assert free.ok and np.linalg.norm(free.p_tcp[-1] - p_star) < SETTLED_TCP_TOL
    assert np.linalg.norm(free.p_tcp - p_star, axis=1).max() > 1e-4


# --------------------------------------------------------------------------------------
# Motion
# --------------------------------------------------------------------------------------


@pytest.mark.slow
def test_fast_move_leaves_the_path_and_settles():
    robot = load_robot("ur5")
    t, q, qd = _move()
    assert np.abs(np.gradient(qd, t, axis=0)).max() > 0.9 * robot.a_max.max()
    theta = static_command(robot, q, payload=MOVE_PAYLOAD)  # static compensation, no dynamics
    res = simulate_elastic(robot, t, theta, qd, payload=MOVE_PAYLOAD, settle_s=0.5)
    assert res.ok, res.reason
    err = tracking_error(res, robot, t, q, qd)
    assert err.error[0] < REST_TCP_TOL  # starts at rest on the path
    assert err.max_motion > 5e-5 and err.rms_motion > 1e-5  # the dynamic deflection
    late = err.error[res.t > res.t[-1] - 0.1]
    assert late.max() < 0.1 * err.max_motion  # damped after the stop
    assert np.all(np.isfinite(err.error)) and err.max_rest < err.max_motion
    # the link-side plan itself: the arm comes to rest at the static deflection of the final pose
    raw = simulate_elastic(robot, t, q, qd, payload=MOVE_PAYLOAD, settle_s=0.5, damping_ratio=0.7)
    sag = _virtual(robot, MOVE_PAYLOAD).equilibrium(q[-1:], np.zeros(6))
    p_sag, p_plan = ElasticArm(robot).tcp_position(sag)[0], ElasticArm(robot).tcp_position(q[-1])[0]
    assert np.linalg.norm(raw.p_tcp[-1] - p_sag) < 1e-3 * np.linalg.norm(p_sag - p_plan)


def _energy(arm: ElasticArm, res, K: np.ndarray) -> np.ndarray:
    M = arm.mass_matrix(res.q)
    d = res.theta - res.q
    return 0.5 * np.einsum("ni,nij,nj->n", res.qd, M, res.qd) + 0.5 * np.einsum("ni,i,ni->n", d, K, d)


@pytest.mark.slow
def test_energy_without_gravity_and_damping():
    robot = replace(load_robot("ur5"), gravity=np.zeros(3))
    arm, K = ElasticArm(robot, MOVE_PAYLOAD), robot.stiffness
    t = np.linspace(0.0, ENERGY_T, 101)
    theta = np.tile(MOVE_Q0, (len(t), 1))
    q0 = MOVE_Q0 + np.array([2e-3, -1e-3, 1.5e-3, 2e-3, -2e-3, 1e-3])
    res = simulate_elastic(robot, t, theta, payload=MOVE_PAYLOAD, q0=q0, damping=np.zeros(6), settle_s=0.0)
    assert res.ok, res.reason
    E = _energy(arm, res, K)
    assert np.abs(E - E[0]).max() < ENERGY_REL_TOL * E[0]
    assert np.ptp(0.5 * np.einsum("ni,ni->n", res.qd, res.qd)) > 1e-6  # it does move
    damped = simulate_elastic(robot, t, theta, payload=MOVE_PAYLOAD, q0=q0, settle_s=0.0)
    Ed = _energy(arm, damped, K)
    assert np.all(np.diff(Ed) <= ENERGY_REL_TOL * E[0]) and Ed[-1] < 0.5 * E[0]


@pytest.mark.slow
def test_pid_motor_settles_on_the_command_and_tracks_like_the_exact_motor():
    robot = load_robot("ur5")
    t, q, qd = _move(T=0.6, dq=0.3 * MOVE_DQ)
    theta = static_command(robot, q, payload=MOVE_PAYLOAD)
    exact = simulate_elastic(robot, t, theta, qd, payload=MOVE_PAYLOAD, settle_s=0.4, damping_ratio=0.3)
    pid = simulate_elastic(robot, t, theta, qd, payload=MOVE_PAYLOAD, settle_s=0.4, damping_ratio=0.3, motor="pid")
    assert exact.ok and pid.ok
    e_x, e_p = tracking_error(exact, robot, t, q), tracking_error(pid, robot, t, q)
    assert e_p.max_motion >= 0.5 * e_x.max_motion and e_p.max_motion < 3 * e_x.max_motion
    assert e_p.final < 0.1 * e_p.max_motion and np.abs(pid.theta[-1] - theta[-1]).max() < 1e-5


# --------------------------------------------------------------------------------------
# Input
# --------------------------------------------------------------------------------------


def test_trajectory_csv_and_bad_inputs(tmp_path):
    t, q, qd = _move(T=0.2)
    head = ["t"] + [f"q{i}" for i in range(1, 7)] + [f"qd{i}" for i in range(1, 7)] + ["qdd1"]
    rows = np.column_stack([t, q, qd, np.zeros(len(t))])
    path = tmp_path / "trajectory.csv"
    path.write_text(",".join(head) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    t2, q2, qd2 = read_trajectory_csv(path)
    assert np.array_equal(t2, t) and np.array_equal(q2, q) and np.array_equal(qd2, qd)
    (tmp_path / "bad.csv").write_text("t,q1,q2\n0,1,2\n1,1,2\n")
    with pytest.raises(InputError, match="missing column"):
        read_trajectory_csv(tmp_path / "bad.csv")
    robot = load_robot("ur5")
    with pytest.raises(InputError, match="theta_cmd"):
        simulate_elastic(robot, t, q[:, :5])
    with pytest.raises(InputError, match="increase"):
        simulate_elastic(robot, t[::-1], q)
    with pytest.raises(InputError, match="motor"):
        simulate_elastic(robot, t, q, motor="ideal")
    soft = simulate_elastic(robot, t, q, stiffness=np.full(6, 1.0))  # cannot hold its weight
    assert soft.status is ElasticStatus.NO_EQUILIBRIUM and "equilibrium" in soft.reason and soft.t.size == 0
