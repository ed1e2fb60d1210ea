"""The ``joint_tilt`` effect: its term against a NumPy computation written here, its moments
against the joint torques, its derivatives against finite differences, and closed loops on the
virtual robot (found where simulated, also from unloaded data through the self-weight; not
added where not simulated).

The reference computation below forms each joint's moment link by link (the weight of each
distal link at its centre of mass, the wrench's moment and its force at the TCP), not through
the barycentric sums of the model.
"""

from __future__ import annotations

import copy

import casadi as ca
import numpy as np
import pytest

import models.effects as fx
from models import load_robot
from models.arm import ArmModel
from models.effects.graph import Graph, chain
from models.effects.joint_tilt import distal_lengths, joint_moments, tilt_joints
from problems.identify import identify, validate_on
from problems.virtual import VirtualRobot

#: Model term against the NumPy computation of this file, m (double-precision round-off of
#: sub-millimetre displacements).
TILT_MATCH_TOL_M = 1e-12
#: The moment about each joint axis against the graph's joint torques, N*m.
MOMENT_MATCH_TOL_NM = 1e-9
#: Relative tolerance of analytic derivatives against central differences.
FD_REL_TOL = 1e-6
#: Per-axis measurement noise of the closed-loop campaigns, m.
SIGMA_M = 2e-5
#: Held-out RMS of an identified model at most this many noise sigmas.
HELDOUT_MAX_RATIO = 1.5


def _axes_frames(robot, frames: np.ndarray) -> np.ndarray:
    """Rotation of the DH frame whose z is each joint's axis, (6, 3, 3), written out per
    convention: standard DH, joint i turns about z of frame i-1; modified DH, about z of frame i."""
    if robot.convention == "standard_dh":
        f0 = np.asarray(robot.frame02base, dtype=float)[:3, :3]
        return np.array([f0] + [frames[k][:3, :3] for k in range(5)])
    return np.array([frames[k][:3, :3] for k in range(6)])


def _tilt_reference(robot, q, F, masses, coms, cx, cy, point):
    """Displacement (3,) m of ``point`` (base frame) by the joint tilts, in NumPy: moments link by
    link about each joint's point, their x/y components in the joint's frame times the compliances,
    and ``phi x (point - p_i)``."""
    frames = np.array([np.asarray(T) for T in ArmModel.from_robot(robot).kinematics.fk_frames(q)])
    axes = _axes_frames(robot, frames)
    if robot.convention == "standard_dh":
        pivots = [np.asarray(robot.frame02base, dtype=float)[:3, 3]] + [frames[k][:3, 3] for k in range(5)]
    else:
        pivots = [frames[k][:3, 3] for k in range(6)]
    g = np.asarray(robot.gravity, dtype=float)
    tcp = frames[5] @ np.asarray(robot.flange2frame6) @ np.asarray(robot.tcp2flange)
    dp = np.zeros(3)
    for i in range(6):
        m = F[3:] + np.cross(tcp[:3, 3] - pivots[i], F[:3])
        for j in range(i, 6):
            c = frames[j][:3, 3] + frames[j][:3, :3] @ coms[j]
            m = m + np.cross(c - pivots[i], masses[j] * g)
        x, y = axes[i][:, 0], axes[i][:, 1]
        phi = cx[i] * (m @ x) * x + cy[i] * (m @ y) * y
        dp += np.cross(phi, point - pivots[i])
    return dp


def _theta(robot, rng, cx, cy):
    """Nominal parameters with the tilt compliances and masses off the robot file's (so the term
    must take ``gravity``'s parameters, not the file's)."""
    lay = fx.make_layout(robot)
    th = lay.nominal.copy()
    th[fx.GROUP_SLICES["gravity.m"]] *= rng.uniform(0.7, 1.3, 6)
    th[fx.GROUP_SLICES["gravity.h"]] += rng.normal(0.0, 0.05, 18)
    th[fx.GROUP_SLICES["joint_tilt.cx"]] = cx
    th[fx.GROUP_SLICES["joint_tilt.cy"]] = cy
    return lay, th


@pytest.mark.parametrize("robot_name", ["ur5", "kr6_r900"])
def test_tilt_term_equals_the_numpy_computation(robot_name, rng):
    robot = load_robot(robot_name)
    el = tilt_joints(robot)
    cx = np.where(el, rng.uniform(1e-6, 2e-5, 6), 0.0)
    cy = np.where(el, rng.uniform(1e-6, 2e-5, 6), 0.0)
    lay, th = _theta(robot, rng, cx, cy)
    th0 = th.copy()
    th0[fx.GROUP_SLICES["joint_tilt.cx"]] = 0.0
    th0[fx.GROUP_SLICES["joint_tilt.cy"]] = 0.0
    const = fx.make_const(robot)
    general = not (np.allclose(robot.frame02base, np.eye(4)) and np.allclose(robot.flange2frame6, np.eye(4)))
    f = fx.identification_functions(robot.convention, tuple(bool(x) for x in lay.eligible), False, general)["measure"]
    masses = th[fx.GROUP_SLICES["gravity.m"]]
    assert np.all(masses > 0)  # each link's weight acts at its centre of mass h / m
    coms = th[fx.GROUP_SLICES["gravity.h"]].reshape(6, 3) / masses[:, None]
    point_tool = th[fx.GROUP_SLICES["tool.p"]]
    largest = 0.0
    for _ in range(6):
        q = rng.uniform(-2.5, 2.5, 6)
        F = np.r_[rng.normal(0, 50.0, 3), rng.normal(0, 3.0, 3)]
        row = np.r_[q, F, 0.0, 0.0, 0, 0, 0, 0]
        p_t, q_eq = f(row, th, const)
        p_0, _q = f(row, th0, const)
        dp_model = np.asarray(p_t - p_0).reshape(3)
        q_eq = np.asarray(q_eq).reshape(6)
        fl = ArmModel.from_robot(robot).kinematics.fk_frames(q_eq)[5] @ np.asarray(robot.flange2frame6)
        point = np.asarray(fl)[:3, :3] @ point_tool + np.asarray(fl)[:3, 3]
        dp_ref = _tilt_reference(robot, q_eq, F, masses, coms, cx, cy, point)
        assert np.linalg.norm(dp_model - dp_ref) < TILT_MATCH_TOL_M, (dp_model, dp_ref)
        largest = max(largest, float(np.linalg.norm(dp_ref)))
    assert largest > 1e-5  # the term is not trivially absent


def test_only_joints_with_a_long_distal_chain_tilt():
    """UR5 (standard DH): the distance between consecutive joint points is sqrt(a^2 + d^2) of the
    row, so the distal chain of joint i sums rows i..6; joints 1-3 carry >= 30 % of the arm."""
    robot = load_robot("ur5")
    by_hand = np.cumsum(np.hypot(robot.a, robot.d)[::-1])[::-1]
    assert np.allclose(distal_lengths(robot), by_hand, atol=1e-12)
    assert tilt_joints(robot).tolist() == [True, True, True, False, False, False]
    lay = fx.make_layout(robot)
    s = fx.GROUP_SLICES["joint_tilt.cx"]
    assert lay.eligible[s].tolist() == [True, True, True, False, False, False]
    assert lay.lower[s].tolist() == [0.0] * 6  # a compliance is not negative


def test_moment_about_each_axis_is_the_joint_torque(rng):
    """The z_i component of the moment the tilt uses is what the graph applies to joint i: the
    wrench's torque plus ``gravity``'s self-weight torque (the same masses and first moments)."""
    robot = load_robot("ur10")
    lay, th = _theta(robot, rng, np.zeros(6), np.zeros(6))
    const = fx.make_const(robot, gravity_on=True)
    graph = Graph(robot.convention, fx.registry(), lay.eligible)
    for _ in range(4):
        q = rng.uniform(-2.5, 2.5, 6)
        F = np.r_[rng.normal(0, 50.0, 3), rng.normal(0, 3.0, 3)]
        ctx = graph.context(ca.DM(th), ca.DM(const), 0.0, 0.0, ca.DM(q))
        dh = graph.geometry(ctx)
        wrench = ca.DM(F)
        ctx.at(chain(ca.DM(q), dh, robot.convention), lambda _c, w=wrench: w)
        moments = joint_moments(ctx)
        about_axes = np.array([float(ca.dot(ctx.zs[i], moments[i])) for i in range(6)])
        te, tg = graph.torques(ctx)
        tau = np.asarray(ca.DM(te + tg)).reshape(6)
        assert np.abs(about_axes - tau).max() < MOMENT_MATCH_TOL_NM, (about_axes, tau)


def test_planning_error_matches_finite_differences(rng):
    """The planning model with ``joint_tilt`` alone: ``load_error`` (tilt included through the
    point displacement) against central differences in q."""
    robot = load_robot("ur5")
    lay, th = _theta(robot, rng, np.where(tilt_joints(robot), 1e-5, 0.0), np.where(tilt_joints(robot), 2e-5, 0.0))
    arm = ArmModel(nominal=robot, theta=th, effects=["joint_tilt"])
    f = arm.kinematics.fn["load_error"]
    q_s, L_s = ca.SX.sym("q", 6), ca.SX.sym("L", fx.LOAD_SIZE)
    jf = ca.Function("j", [q_s, L_s], [ca.jacobian(f(q_s, L_s), q_s)])
    L = np.zeros(fx.LOAD_SIZE)
    L[0:6] = [30.0, -20.0, -60.0, 1.0, 2.0, 0.0]
    L[16:19] = robot.gravity
    h = 1e-6
    for _ in range(3):
        q = rng.uniform(-2.5, 2.5, 6)
        J = np.asarray(jf(q, L))
        fd = np.column_stack(
            [(np.asarray(f(q + h * e, L)) - np.asarray(f(q - h * e, L))).reshape(-1) / (2 * h) for e in np.eye(6)]
        )
        assert np.abs(J - fd).max() < FD_REL_TOL * max(np.abs(J).max(), 1e-12) * 10
    # the tilt is in the planning model: without it the error differs
    e_tilt = np.asarray(f(q, L)).reshape(-1)
    e_none = np.asarray(ArmModel(nominal=robot, theta=th, effects=[]).kinematics.fn["load_error"](q, L)).reshape(-1)
    assert np.linalg.norm(e_tilt[:3] - e_none[:3]) > 1e-6


# ----------------------------------------------------------------------------------
# Closed loops on the virtual robot (unloaded campaigns: the self-weight alone excites the tilt)
# ----------------------------------------------------------------------------------


def _identify(robot_name: str, effects: dict, seed: int, poses: int = 80):
    cfg = {
        "campaign": {"poses": poses, "loaded_rows": 0},
        "noise": {"sigma_m": SIGMA_M},
        "registration": {"registered": False},
        "effects": copy.deepcopy(effects),
    }
    vr = VirtualRobot(load_robot(robot_name), cfg, seed=seed)
    res = identify(load_robot(robot_name), vr.campaign())
    heldout = VirtualRobot(load_robot(robot_name), cfg, seed=seed).campaign(seed=seed + 1000)
    return res, validate_on(res.model, heldout)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 3])
def test_tilt_is_found_from_self_weight_alone(seed):
    """UR5 with self-weight and tilting joints 2 and 3, no load in the data: both effects are
    added, nothing else, and the held-out residual reaches the noise."""
    res, val = _identify("ur5", {"gravity": {}, "joint_tilt": {}}, seed)
    assert set(res.effects_added) == {"gravity", "joint_tilt"}, [h.reason for h in res.history]
    assert not res.unexplained["present"]
    assert val["rms_mm"] <= HELDOUT_MAX_RATIO * SIGMA_M * 1e3, val


@pytest.mark.slow
def test_a_base_tilt_is_told_from_self_weight_torques():
    """UR5 with DH errors and a tilting base (joint 1), no self-weight torques simulated: the
    tilt is added, ``gravity`` is not (both are driven by the self-weight)."""
    tilt = {"joints": [1], "compliance_x_rad_per_Nm": 3.4e-5, "compliance_y_rad_per_Nm": 3.4e-5}
    res, val = _identify("ur5", {"geometric": {}, "joint_tilt": tilt}, 11, poses=120)
    assert set(res.effects_added) == {"geometric", "joint_tilt"}, [h.reason for h in res.history]
    assert val["rms_mm"] <= HELDOUT_MAX_RATIO * SIGMA_M * 1e3, val


@pytest.mark.slow
@pytest.mark.parametrize(
    "robot_name, effects, poses",
    [("ur10", {"gravity": {}}, 80), ("ur5", {"geometric": {}, "gravity": {}}, 120)],
)
def test_self_weight_torques_are_not_taken_for_a_tilt(robot_name, effects, poses):
    """Self-weight without tilt (and DH errors: the real UR5 grid's situation), no load in the
    data: the simulated effects are added, ``joint_tilt`` is not."""
    res, val = _identify(robot_name, effects, 11, poses=poses)
    assert set(res.effects_added) == set(effects), [h.reason for h in res.history]
    assert val["rms_mm"] <= HELDOUT_MAX_RATIO * SIGMA_M * 1e3, val
