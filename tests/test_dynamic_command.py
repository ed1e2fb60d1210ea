"""Motor-side commands of a timed trajectory (problems/dynamic.py)."""

from __future__ import annotations

import numpy as np
import pytest

from models.arm import load_arm
from models.load import Load
from problems.compensation import exact
from problems.dynamic import DynamicStatus, inertial_torques, motor_command

#: Agreement of two evaluations of the same torques (N*m) and commands (rad).
TORQUE_TOL = 1e-9
ANGLE_TOL = 1e-12

LOAD = Load(
    wrench_base=np.array([5.0, -10.0, -20.0, 0.5, 0.0, 0.2]),
    payload_mass_kg=4.0,
    payload_com_m=np.array([0.01, 0.0, 0.06]),
)


def _states(rng, n=20):
    return rng.uniform(-2.5, 2.5, (n, 6)), rng.uniform(-2.0, 2.0, (n, 6)), rng.uniform(-5.0, 5.0, (n, 6))


def test_at_rest_the_command_is_the_static_exact_compensation(rng):
    arm = load_arm("ur5")
    q = rng.uniform(-2.5, 2.5, (10, 6))
    cmd = motor_command(arm, q, np.zeros_like(q), np.zeros_like(q), LOAD)
    assert cmd.status is DynamicStatus.OK
    from problems.dynamic import link_weight_torques

    static = q - arm.torque_deflection(q, arm.joint_torques(q, LOAD) + link_weight_torques(arm.robot(), q))
    np.testing.assert_allclose(cmd.theta, static, atol=ANGLE_TOL)
    # without the weight of the links it is exactly the static exact compensation of the load
    np.testing.assert_allclose(
        q - arm.torque_deflection(q, arm.joint_torques(q, LOAD)), exact(arm, q, LOAD).q_command, atol=ANGLE_TOL
    )
    assert np.abs(cmd.tau_inertial).max() == 0.0


def test_the_elastic_joints_carry_the_inertial_and_static_torques(rng):
    """K (theta - q) + tau_static = M q'' + c, with the inertial torques from pinocchio."""
    pin = pytest.importorskip("pinocchio")
    arm = load_arm("ur5")
    robot = arm.robot()
    q, qd, qdd = _states(rng)
    cmd = motor_command(arm, q, qd, qdd, LOAD)
    K = np.array([j.stiffness for j in robot.joints])
    spring = K * (cmd.theta - q)
    np.testing.assert_allclose(spring + cmd.tau_static, cmd.tau_inertial, atol=TORQUE_TOL * 1e3)
    # the inertial torques against pinocchio (gravity off, payload as a body at the TCP)
    from models.dynamics import payload_vector
    from tests.test_dynamics import pinocchio_from_dh  # the pinocchio model built from the DH rows

    model, _jid, _tcp = pinocchio_from_dh(robot, payload_vector(LOAD.payload_mass_kg, LOAD.payload_com_m))
    model.gravity.linear = np.zeros(3)
    data = model.createData()
    ref = np.array([pin.rnea(model, data, q[k], qd[k], qdd[k]) for k in range(len(q))])
    np.testing.assert_allclose(cmd.tau_inertial, ref, atol=TORQUE_TOL * max(1.0, np.abs(ref).max()))


def test_inertial_torques_are_linear_in_acceleration(rng):
    robot = load_arm("ur10").robot()
    q, qd, qdd = _states(rng, 5)
    t1 = inertial_torques(robot, q, qd, qdd)
    t2 = inertial_torques(robot, q, qd, 2 * qdd)
    t0 = inertial_torques(robot, q, qd, 0 * qdd)
    np.testing.assert_allclose(t2 - t0, 2 * (t1 - t0), atol=1e-9)
    assert np.abs(t1 - t0).max() > 1.0


def test_without_masses_the_command_fails_with_a_reason():
    arm = load_arm("ar5")
    q = np.zeros((3, 6))
    cmd = motor_command(arm, q, q, q, LOAD)
    assert cmd.status is DynamicStatus.FAILED and "no link masses" in cmd.reason


#: The dynamic command must cut the TCP tracking error during the motion at least this much
#: against the static compensation alone (issue 13), and leave at most this at the end of the rest.
MOTION_GAIN_MIN = 10.0
REST_ERROR_MAX_M = 2e-6


@pytest.mark.slow
def test_motor_command_makes_the_simulated_elastic_arm_follow_the_plan():
    """A fast UR5 move with 5 kg (jerk-limited timing at 4 ms) through the independent elastic-joint
    simulation (problems/virtual/elastic.py: NumPy dynamics, Radau): static compensation only vs the
    motor-side command."""
    from models.dynamics import payload_vector
    from problems.timing import JointLimits, time_parametrize
    from problems.virtual.elastic import simulate_elastic, tracking_error

    arm = load_arm("ur5")
    robot = arm.robot()
    load = Load(payload_mass_kg=5.0, payload_com_m=np.array([0.0, 0.0, 0.05]))
    u = np.linspace(0.0, 1.0, 12)[:, None]
    q0, q1 = np.array([0.0, -1.6, 1.6, -1.5, -1.57, 0.0]), np.array([1.2, -1.0, 1.0, -1.2, -1.2, 0.6])
    tr = time_parametrize(
        q0 + u * (q1 - q0) + 0.1 * np.sin(np.pi * u),
        JointLimits(robot.v_max, robot.a_max, robot.j_max),
        "jerk_optimal",
        0.004,
    )
    dyn = motor_command(arm, tr.q, tr.qd, tr.qdd, load)
    static = motor_command(arm, tr.q, np.zeros_like(tr.q), np.zeros_like(tr.q), load)
    err = {}
    for name, cmd in (("static", static), ("dynamic", dyn)):
        sim = simulate_elastic(robot, tr.t, cmd.theta, payload=payload_vector(5.0, [0.0, 0.0, 0.05]))
        assert sim.status.value == "ok", sim.reason
        err[name] = tracking_error(sim, robot, tr.t, tr.q)
    assert err["static"].max_motion > 1e-4  # the inertial deflection is real (0.4 mm)
    assert err["static"].max_motion >= MOTION_GAIN_MIN * err["dynamic"].max_motion
    assert err["dynamic"].final <= REST_ERROR_MAX_M
