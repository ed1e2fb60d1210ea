"""A time law slowed to a near stop is a FAILED trajectory that names the hard waypoints, not an
error blaming the limits' units (the lower bound of the duration already ruled those out)."""

from __future__ import annotations

import numpy as np
import pytest

from problems.timing import (
    JointLimits,
    TimingMethod,
    TimingStatus,
    register_method,
    time_parametrize,
    unregister_method,
)
from problems.timing.registry import MAX_TRAJECTORY_SAMPLES, TimeLawTooLong, check_sample_count
from problems.timing.verification import check_times

LIMITS = JointLimits(np.full(6, 3.0), np.full(6, 5.0), np.full(6, 50.0))


def _stalling(path, limits, dt, options):
    """A method whose time law takes ~1e146 s (as a jerk-limited NLP did at a sharp corner)."""
    check_times(4.9e146, dt)
    raise AssertionError("check_times must refuse the duration")


@pytest.fixture
def stalling_method():
    register_method(TimingMethod("stalling_test", _stalling, (), lambda o: o, ("velocity",)))
    yield "stalling_test"
    unregister_method("stalling_test")


def test_a_near_stop_is_failed_with_the_sharpest_step_named(stalling_method):
    q = np.zeros((50, 6))
    q[:, 0] = np.linspace(0.0, 0.049, 50)
    q[30:, 5] = 0.25  # one sharp step of joint 6 between waypoints 29 and 30
    tr = time_parametrize(q, LIMITS, stalling_method, 0.008)
    assert tr.status is TimingStatus.FAILED and tr.t.size == 0 and np.isnan(tr.duration_s)
    assert "near stop (4.9e+146 s" in tr.reason
    assert "largest joint step is 0.25 rad between waypoints 29 and 30" in tr.reason
    assert "wrong unit" not in tr.reason and not tr.reason.startswith("failed")


def test_check_times_refuses_non_finite_and_over_cap_durations():
    with pytest.raises(TimeLawTooLong):
        check_times(float("inf"), 0.008)
    with pytest.raises(TimeLawTooLong) as exc:
        check_times(0.008 * MAX_TRAJECTORY_SAMPLES, 0.008)
    assert exc.value.duration_s == 0.008 * MAX_TRAJECTORY_SAMPLES
    assert check_times(1.0, 0.008).size > 0


def test_limits_in_the_wrong_unit_are_still_named_before_any_method_runs():
    from models.errors import InputError

    with pytest.raises(InputError, match="wrong unit"):
        check_sample_count(1e9, 0.008, "toppra", lower_bound=True)
