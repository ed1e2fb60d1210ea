"""Which constraint binds, and why a trajectory stays under half of every limit (problems/timing/limit_use)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from problems.timing import JointLimits, get_method, time_parametrize
from problems.timing.limit_use import ACTIVE_RATIO, describe_binding, limit_use

LIMITS = JointLimits(np.full(6, 2.0), np.full(6, 4.0), np.full(6, 40.0))


def _path() -> np.ndarray:
    u = np.linspace(0.0, 1.0, 12)[:, None]
    return np.array([0.3, -1.0, 1.2, -0.5, 1.4, 0.1]) + np.outer(
        np.sin(0.5 * np.pi * u[:, 0]), [0.6, 0.2, -0.4, 0.3, 0.1, 0.5]
    )


def test_time_optimal_trajectory_names_its_binding_acceleration():
    tr = time_parametrize(_path(), LIMITS, "toppra", 0.004)
    use = limit_use(tr, LIMITS, get_method("toppra").checked_limits)
    assert use["peak_ratio"] >= ACTIVE_RATIO and not use["under_half"] and use["why"] is None
    top = use["binding"][0]
    r = (
        np.abs(tr.qdd[:, top["joint"] - 1]) / LIMITS.acceleration[top["joint"] - 1]
        if top["limit"] == "acceleration"
        else np.abs(tr.qd[:, top["joint"] - 1]) / LIMITS.velocity[top["joint"] - 1]
    )
    assert top["fraction_of_time"] == np.mean(r >= ACTIVE_RATIO) > 0
    assert describe_binding(use).startswith("binds: ")


def test_under_half_of_every_limit_says_why():
    tr = time_parametrize(_path(), LIMITS, "ruckig", 0.004)
    slow = replace(tr, qd=0.3 * tr.qd, qdd=0.3 * tr.qdd, qddd=0.3 * tr.qddd)
    use = limit_use(slow, LIMITS, get_method("ruckig").checked_limits)
    assert use["under_half"] and use["binding"] == []
    assert "under half of every limit" in use["why"] and get_method("ruckig").underuse_cause in use["why"]
    assert describe_binding(use) == use["why"]
    # a limit that is not enforced does not count
    jerk_only = replace(tr, qd=0.1 * tr.qd, qdd=0.1 * tr.qdd)
    assert (
        not limit_use(jerk_only, LIMITS, ("velocity", "acceleration", "jerk"))["under_half"]
        or np.max(np.abs(tr.qddd) / LIMITS.jerk) < 0.5
    )
    assert limit_use(jerk_only, LIMITS, ("velocity", "acceleration"))["under_half"]


def test_a_method_not_registered_here_still_gets_its_limit_use():
    """A trajectory of a plug-in that is not loaded (a run read back elsewhere): no cause, no error."""
    tr = time_parametrize(_path(), LIMITS, "ruckig", 0.004)
    slow = replace(tr, method="not_loaded", qd=0.3 * tr.qd, qdd=0.3 * tr.qdd, qddd=0.3 * tr.qddd)
    use = limit_use(slow, LIMITS, ("velocity", "acceleration", "jerk"))
    assert use["under_half"] and use["why"].endswith("no limit binds; see the method's reason")
