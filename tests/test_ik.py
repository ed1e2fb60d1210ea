"""Analytic IK: FK(IK(T)) = T over >= 10,000 random poses per robot, every branch; the
generating configuration is among the branches; branch set equal to ur-analytic-ik's."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
import ur_analytic_ik

from models import AnalyticIK, IKStatus, IKStructureError, KinematicModel, load_robot
from models.constants import IK_ROUNDTRIP_TOL, IK_WRIST_SINGULAR_TOL
from models.errors import InputError
from models.ik import BRANCH_LABELS
from models.robot import robot_from_dict
from models.transforms import rotation_angle

from .conftest import ROBOTS, as_modified_dh, get_model

N_RANDOM = 10_000
#: Two configurations are "the same" when every wrapped joint difference is below this (rad).
SAME_CONFIG_TOL = 1e-7
#: ur-analytic-ik works in float64 with its own formulas; agreement per joint (rad).
URIK_TOL = 1e-8


def _wrapdiff(a, b):
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("name", ROBOTS)
def test_fk_ik_roundtrip_every_branch(name):
    robot, km, ik = get_model(name)
    rng = np.random.default_rng(zlib.crc32(name.encode()))  # stable across processes (hash() is salted)
    q = rng.uniform(robot.q_min / 2, robot.q_max / 2, (N_RANDOM, 6))
    T = km.tcp(q)
    sol = ik.solve(T)
    assert sol.q.shape == (N_RANDOM, 8, 6)
    # every returned branch reproduces T
    Q = np.where(sol.valid[..., None], sol.q, 0.0).reshape(-1, 6)
    T2 = km.tcp(Q).reshape(N_RANDOM, 8, 4, 4)
    perr = np.linalg.norm(T2[..., :3, 3] - T[:, None, :3, 3], axis=-1)
    rerr = rotation_angle(T2[..., :3, :3], np.broadcast_to(T[:, None, :3, :3], T2[..., :3, :3].shape))
    assert np.all(perr[sol.valid] < IK_ROUNDTRIP_TOL)
    assert np.all(rerr[sol.valid] < IK_ROUNDTRIP_TOL)
    # no NaN leaks: invalid branches are NaN *and* flagged; valid ones are finite
    assert np.all(np.isfinite(sol.q[sol.valid]))
    assert np.all(np.isnan(sol.q[~sol.valid]))
    # the generating configuration is among the returned branches
    d = _wrapdiff(sol.q, q[:, None, :]).max(axis=-1)
    found = (np.where(sol.valid, d, np.inf) < SAME_CONFIG_TOL).any(axis=1)
    # ... unless the generating configuration is within IK_WRIST_SINGULAR_TOL of the wrist
    # singularity, where theta6 is undetermined and the pose must be flagged, not solved
    wrist = np.abs(np.sin(q[:, 4] + robot.theta_offset[4])) < IK_WRIST_SINGULAR_TOL
    assert found[~wrist].all(), f"{(~found[~wrist]).sum()} poses lost their generating configuration"
    assert (sol.status[wrist] == IKStatus.WRIST_SINGULAR.code).any(axis=1).all()
    # most random poses have all 8 branches (sanity: the solver is not trivially rejecting)
    assert sol.valid.sum(axis=1).mean() > 6.0


def test_branch_set_equals_ur_analytic_ik():
    robot, km, ik = get_model("ur5")
    rng = np.random.default_rng(5)
    q = rng.uniform(-np.pi, np.pi, (2000, 6))
    T = km.tcp(q)
    sol = ik.solve(T)
    for i in range(len(q)):
        # ur-analytic-ik's UR5 uses the same published DH table
        Tu = ur_analytic_ik.ur5.forward_kinematics(*q[i])
        assert np.allclose(Tu, T[i], atol=1e-12)
        theirs = np.array(ur_analytic_ik.ur5.inverse_kinematics(np.ascontiguousarray(T[i])))
        ours = sol.q[i][sol.valid[i]]
        assert len(theirs) == len(ours), f"pose {i}: {len(theirs)} vs {len(ours)} branches"
        for qt in theirs:
            assert _wrapdiff(ours, qt).max(axis=1).min() < URIK_TOL
        for qo in ours:
            assert _wrapdiff(theirs, qo).max(axis=1).min() < URIK_TOL


def test_branch_labels_are_stable_along_a_path():
    """Labels follow the formula: a continuous path keeps each branch continuous."""
    robot, km, ik = get_model("ar5")
    q0 = np.array([0.4, -1.2, 1.4, -1.5, -1.3, 0.2])
    qs = q0 + np.linspace(0, 0.3, 200)[:, None] * np.array([1, 0.5, -0.5, 0.3, 0.2, 1.0])
    sol = ik.solve(km.tcp(qs))
    assert sol.valid.all()
    steps = _wrapdiff(sol.q[1:], sol.q[:-1]).max(axis=-1)
    assert steps.max() < 0.05
    assert len(set(BRANCH_LABELS)) == 8


def test_unreachable_and_singular_poses_give_reasons():
    robot, km, ik = get_model("ur5")
    far = np.eye(4)
    far[:3, 3] = [2.0, 0.0, 0.3]
    sol = ik.solve(far)
    assert not sol.valid.any()
    assert "unreachable" in sol.summary(0)
    # wrist singular: q5 = 0 -> theta6 undetermined, those branches flagged, no NaN passed on
    q = np.array([0.3, -1.0, 1.2, 0.4, 0.0, 0.2])
    sol = ik.solve(km.tcp(q))
    assert (sol.status[0] == IKStatus.WRIST_SINGULAR.code).any()
    assert "singular" in sol.reason(0, int(np.argmax(sol.status[0] == IKStatus.WRIST_SINGULAR.code)))
    # non-finite input
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(InputError, match="not finite"):
        ik.solve(bad)


def test_nearest_branch_helper_and_joint_limits():
    robot, km, ik = get_model("ur10")
    q = np.array([-0.5, -1.1, 1.3, -1.7, -1.5, 0.4])
    T = km.tcp(q)
    seed = q + 0.05
    qn, chosen, _ = ik.nearest(T, seed)
    assert chosen[0] >= 0
    assert np.allclose(qn[0], q, atol=1e-9)
    # a seed near +2*pi picks the 2*pi-shifted copy of joint 1 (limits are +-2*pi)
    seed2 = q.copy()
    seed2[0] += 2 * np.pi
    qn2, _, _ = ik.nearest(T, seed2)
    assert np.isclose(qn2[0, 0], q[0] + 2 * np.pi)
    # tight limits exclude branches with a JOINT_LIMIT status
    d = robot.to_dict()
    for row in d["joints"]:
        row["q_min"], row["q_max"] = -1.6, 1.6
    tight = AnalyticIK(robot_from_dict(d))
    sol = tight.solve(T)
    assert (sol.status[0] == IKStatus.JOINT_LIMIT.code).any()
    assert np.all(np.abs(sol.q[0][sol.valid[0]]) <= 1.6 + 1e-12)


def test_modified_dh_ik_and_non_ur_structure():
    d = load_robot("ur5").to_dict()
    rm = robot_from_dict(as_modified_dh(d))
    km, ik = KinematicModel(rm), AnalyticIK(rm)
    q = np.random.default_rng(2).uniform(-np.pi, np.pi, (500, 6))
    T = km.tcp(q)
    sol = ik.solve(T)
    Q = np.where(sol.valid[..., None], sol.q, 0).reshape(-1, 6)
    T2 = km.tcp(Q).reshape(500, 8, 4, 4)
    err = np.linalg.norm(T2[..., :3, 3] - T[:, None, :3, 3], axis=-1)
    assert sol.valid.any(axis=1).all()
    assert np.all(err[sol.valid] < IK_ROUNDTRIP_TOL)
    # a non-UR arm: the error names the parameter (alpha4 = 0 would make axes 4 and 5 one line: refused at load)
    d["joints"][3]["alpha"] = 0.5
    with pytest.raises(IKStructureError, match="alpha4"):
        AnalyticIK(robot_from_dict(d))


def test_theta_offsets_are_respected():
    r = load_robot("ar5")
    d = r.to_dict()
    d["joints"][1]["theta_offset"] = -np.pi / 2
    d["joints"][3]["theta_offset"] = np.pi / 2
    ro = robot_from_dict(d)
    km, ik = KinematicModel(ro), AnalyticIK(ro)
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (500, 6))
    sol = ik.solve(km.tcp(q))
    dd = _wrapdiff(sol.q, q[:, None, :]).max(axis=-1)
    assert (np.where(sol.valid, dd, np.inf) < SAME_CONFIG_TOL).any(axis=1).all()
