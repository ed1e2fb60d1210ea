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

LOAD = Load(wrench_base=np.array([5.0, -10.0, -20.0, 0.5, 0.0, 0.2]), payload_mass_kg=4.0,
            payload_com_m=np.array([0.01, 0.0, 0.06]))


def _states(rng, n=20):
    return rng.uniform(-2.5, 2.5, (n, 6)), rng.uniform(-2.0, 2.0, (n, 6)), rng.uniform(-5.0, 5.0, (n, 6))


def test_at_rest_the_command_is_the_static_exact_compensation(rng):
    arm = load_arm("ur5")
    q = rng.uniform(-2.5, 2.5, (10, 6))
    cmd = motor_command(arm, q, np.zeros_like(q), np.zeros_like(q), LOAD)
    assert cmd.status is DynamicStatus.OK
    np.testing.assert_allclose(cmd.theta, exact(arm, q, LOAD).q_command, atol=ANGLE_TOL)
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
