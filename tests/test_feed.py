"""The feed law (problems/toolpath/feed.py): the TCP at the programmed feed where the limits allow,
never above it, checked by forward kinematics of the sampled trajectory (not by the law's own
pseudo-joint); rapids time-optimal; slowed moves named."""

from __future__ import annotations

import numpy as np
import pytest

from models.errors import InputError
from problems.timing import JointLimits, TimingStatus
from problems.toolpath.feed import FEED_SLOW_TOL, feed_time_law, programmed_time

#: The TCP may exceed the programmed feed by at most this fraction between samples (issue 23).
FEED_OVERSHOOT_TOL = 0.02
#: The time on cutting moves, stops included, at most this times length / F where limits allow.
FEED_TIME_FACTOR = 1.15
#: Mid-path the TCP runs at least this fraction of the feed: jerk_optimal slows its whole law
#: uniformly when its fine check finds a discretisation excess (x1.0245 measured on this line).
FEED_HOLD_FRACTION = 0.97


def test_programmed_time_counts_cutting_moves_only():
    P = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.2, 0], [0.1, 0.2, 0.3]], float)
    F = np.array([np.nan, 0.05, np.nan, 0.1])  # waypoint 0 ends no move; the second move is a rapid
    np.testing.assert_allclose(programmed_time(P, F), [0.0, 2.0, 2.0, 5.0])
    with pytest.raises(InputError, match="waypoint 1 is 0.0 m/s; expected > 0"):
        programmed_time(P, np.array([np.nan, 0.0, 0.1, 0.1]))
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        programmed_time(P[:, :2], F)


def _line(paper_result):
    """The planned (deflected) posture of the demo's line, its TCP points and the arm."""
    res = paper_result
    return res.exact.q_deflected, res.problem.positions, res.problem.model, res.problem.limits


def _tcp_speed(arm, traj) -> np.ndarray:
    p = arm.kinematics.tcp(traj.q)[:, :3, 3]
    return np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(traj.t)


def test_the_feed_is_held_and_never_exceeded_by_the_tcp(paper_result):
    q, P, arm, L = _line(paper_result)
    lim = JointLimits(L.velocity, L.acceleration, L.jerk)
    feed = np.r_[np.nan, np.full(len(P) - 1, 0.05)]  # 3 m/min
    law = feed_time_law(q, P, feed, lim, 0.008)
    tr = law.trajectory
    assert tr.status is TimingStatus.OK, tr.reason
    assert tr.q.shape[1] == 6 and law.feed_ratio <= 1.0 + 1e-9
    speed = _tcp_speed(arm, tr)
    assert speed.max() <= 0.05 * (1.0 + FEED_OVERSHOOT_TOL), speed.max()
    assert np.median(speed[len(speed) // 4 : -len(speed) // 4]) > 0.05 * FEED_HOLD_FRACTION  # at the feed
    assert tr.duration_s <= FEED_TIME_FACTOR * law.programmed_time_s
    assert law.slowed == {}


def test_a_feed_the_joints_cannot_follow_is_slowed_and_named(paper_result):
    q, P, arm, L = _line(paper_result)
    lim = JointLimits(L.velocity, L.acceleration, L.jerk)
    feed = np.r_[np.nan, np.full(len(P) - 1, 5.0)]  # 300 m/min: beyond the joints
    law = feed_time_law(q, P, feed, lim, 0.008, method="toppra")
    assert law.trajectory.status is TimingStatus.OK, law.trajectory.reason
    assert law.slowed and all(v < 1.0 - FEED_SLOW_TOL for v in law.slowed.values())
    assert law.trajectory.duration_s > 2.0 * law.programmed_time_s
    assert _tcp_speed(arm, law.trajectory).max() < 5.0


def test_rapids_run_at_the_joint_limits(paper_result):
    q, P, arm, L = _line(paper_result)
    lim = JointLimits(L.velocity, L.acceleration, L.jerk)
    half = len(P) // 2
    feed = np.r_[np.nan, np.full(half - 1, 0.02), np.full(len(P) - half, np.nan)]  # cut, then a rapid
    law = feed_time_law(q, P, feed, lim, 0.008)
    assert law.trajectory.status is TimingStatus.OK
    cut_len = np.linalg.norm(np.diff(P[:half], axis=0), axis=1).sum()
    assert law.programmed_time_s == pytest.approx(cut_len / 0.02)
    # the rapid half costs far less than it would at the cutting feed
    assert law.trajectory.duration_s < law.programmed_time_s + 0.5 * (law.programmed_time_s)


def test_wrong_shapes_are_named(paper_result):
    q, P, arm, L = _line(paper_result)
    lim = JointLimits(L.velocity, L.acceleration, L.jerk)
    with pytest.raises(InputError, match="q must be"):
        feed_time_law(q[:-1], P, np.full(len(P), 0.05), lim, 0.008)


#: A 2.5 mm stretch between two corners of the shipped milling_pocket (UR10, waypoints 3881-3883 of its
#: plan): q (rad), then the programmed time (s) and the distance along the path (m) at each waypoint.
_TOPPRA_UNCONTROLLABLE = np.array(
    [
        [2.9750706099815094, 0.545981047818711, -1.6043895118868257, 2.628859712725286, 1.5707491865040297,
         -2.3753879438707513, 152.26522139047552, 5.172183024011046],
        [2.975541781762344, 0.5450267874826004, -1.6016610762114099, 2.6270842760691773, 1.570748307219673,
         -2.377027692331261, 152.30688805714217, 5.173433024011046],
        [2.976013304337836, 0.544070963160185, -1.5989327193612954, 2.6253104824481412, 1.5707474129911947,
         -2.378695556629028, 152.34855472380883, 5.1746830240110455],
    ]
)  # fmt: skip


def test_a_stretch_the_method_fails_on_is_timed_by_the_fallback_and_said():
    from problems.toolpath.feed_stretch import FEED_FALLBACK_METHOD

    a = _TOPPRA_UNCONTROLLABLE
    L = a[:, 7] - a[0, 7]
    P = np.c_[L, np.zeros(3), np.zeros(3)]
    F = np.r_[np.nan, np.diff(L) / np.diff(a[:, 6])]
    lim = JointLimits(np.r_[2.0944, 2.0944, np.full(4, np.pi)], np.full(6, 4.0), np.full(6, 40.0))
    seg = np.c_[a[:, :6], 100.0 * (a[:, 6] - a[0, 6]), 1e-6 * L]
    # the method alone fails on it (toppra: "not controllable")
    from problems.timing import time_parametrize

    aug = JointLimits(np.r_[lim.velocity, 100.0, 1e12], np.r_[lim.acceleration, 1e5, 1e12], np.r_[lim.jerk, 1e8, 1e12])
    assert time_parametrize(seg, aug, "toppra", 0.008).status is not TimingStatus.OK
    law = feed_time_law(a[:, :6], P, F, lim, 0.008, method="toppra")
    assert law.trajectory.status is TimingStatus.OK and law.n_substituted == 1
    assert f"timed by {FEED_FALLBACK_METHOD} where toppra failed" in law.trajectory.reason
    assert law.trajectory.method == "toppra"
