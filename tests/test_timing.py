"""Tests for :mod:`problems.timing` (TOPP-RA and Ruckig time parametrisation).

Covers the package split too: the method registry, the re-exported names and
the Ruckig result codes kept on failed results.

All paths are seeded; there are no wall-clock assertions.
"""

from __future__ import annotations

import logging
import os
from dataclasses import replace

import numpy as np
import pytest
import ruckig
import toppra.algorithm
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from models.errors import InputError
from problems import timing
from problems.timing import (
    LIMIT_RATIO_TOL,
    JointLimits,
    TimingStatus,
    Trajectory,
    registry,
    ruckig_method,
    time_parametrize,
    toppra_method,
    verification,
)
from problems.timing import trajectory as trajectory_module

N_JOINTS = 6
N_WAYPOINTS = 40

#: Finite-difference limit check: forward differences of the samples are mean
#: values of the analytic velocity (second differences: weighted means of the
#: acceleration), so they cannot exceed the analytic peak; this only absorbs
#: rounding and the peak falling between the 4x-oversampled check points.
FD_RATIO_TOL = 1e-4
#: Exactness of the end points (rad).
ENDPOINT_TOL = 1e-9
#: "At rest" (rad/s, rad/s^2).
REST_TOL = 1e-12
#: Straight path: max distance of a sample from the line (rad).
LINE_TOL = 1e-9
#: Derivative consistency (relative to the peak of the derivative) at FINE_DT.
DERIV_REL_TOL = 1e-2
#: Re-sampling period for the waypoint-proximity check (s).
FINE_DT = 0.001

LIMIT_SETS = {
    "uniform": JointLimits(
        velocity=np.full(N_JOINTS, 3.15),
        acceleration=np.full(N_JOINTS, 5.0),
        jerk=np.full(N_JOINTS, 50.0),
    ),
    "varied": JointLimits(
        velocity=np.array([2.0, 2.0, 2.5, 3.2, 3.2, 3.2]),
        acceleration=np.array([4.0, 4.0, 6.0, 8.0, 8.0, 10.0]),
        jerk=np.array([40.0, 40.0, 60.0, 80.0, 80.0, 100.0]),
    ),
}
METHODS = ("toppra", "ruckig", "jerk_optimal")


# --------------------------------------------------------------------------- #
# Paths
# --------------------------------------------------------------------------- #


def line_path(seed: int = 0, n_way: int = N_WAYPOINTS) -> np.ndarray:
    """(n_way, 6) rad, equally spaced waypoints on a random straight segment."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-1.5, 1.5, N_JOINTS)
    end = rng.uniform(-1.5, 1.5, N_JOINTS)
    u = np.linspace(0.0, 1.0, n_way)[:, None]
    return start + u * (end - start)


def curved_path(seed: int = 1, n_way: int = N_WAYPOINTS) -> np.ndarray:
    """(n_way, 6) rad, waypoints on a random smooth (trigonometric) curve."""
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 1.0, n_way)[:, None]
    c = rng.uniform(-1.0, 1.0, (4, N_JOINTS))
    return c[0] + c[1] * 1.5 * u + 0.6 * c[2] * np.sin(2.0 * np.pi * u) + 0.4 * c[3] * np.cos(np.pi * u)


PATHS = {"line": line_path, "curved": curved_path}

_CACHE: dict[tuple, Trajectory] = {}


def run(path_name: str, limits_name: str, method: str, dt: float = 0.008) -> Trajectory:
    key = (path_name, limits_name, method, dt)
    if key not in _CACHE:
        _CACHE[key] = time_parametrize(PATHS[path_name](), LIMIT_SETS[limits_name], method=method, dt=dt)
    return _CACHE[key]


def fd_ratios(traj: Trajectory, limits: JointLimits) -> tuple[float, float]:
    """Peak velocity and acceleration ratios from finite differences of q."""
    vel = np.diff(traj.q, axis=0) / traj.dt
    acc = np.diff(traj.q, n=2, axis=0) / traj.dt**2
    return (
        float((np.abs(vel) / limits.velocity).max()),
        float((np.abs(acc) / limits.acceleration).max()),
    )


# --------------------------------------------------------------------------- #
# Valid paths: both methods
# --------------------------------------------------------------------------- #

CASES = [(p, lim, m) for p in PATHS for lim in LIMIT_SETS for m in METHODS]


@pytest.mark.parametrize(("path_name", "limits_name", "method"), CASES)
def test_status_ok_and_ratios_within_limits(path_name, limits_name, method):
    traj = run(path_name, limits_name, method)
    assert traj.status is TimingStatus.OK, traj.reason
    assert traj.ok
    assert traj.method == method
    assert "within limits" in traj.reason and not traj.reason.startswith(traj.status.value)
    assert set(traj.limit_ratio) == {"velocity", "acceleration", "jerk"}
    checked = registry.get_method(method).checked_limits
    for key in checked:
        assert traj.limit_ratio[key].shape == (N_JOINTS,)
        assert np.all(traj.limit_ratio[key] <= 1.0 + LIMIT_RATIO_TOL), (key, traj.limit_ratio[key])
    # the path is actually driven hard: time-optimal TOPP-RA saturates a limit;
    # Ruckig's global bound set is conservative on curved paths (see module doc)
    peak = max(float(traj.limit_ratio[k].max()) for k in checked)
    assert peak > (0.95 if method == "toppra" else 0.5)
    if method == "toppra":
        assert "jerk is not limited" in traj.reason


@pytest.mark.parametrize(("path_name", "limits_name", "method"), CASES)
def test_sampling_grid_endpoints_and_rest(path_name, limits_name, method):
    traj = run(path_name, limits_name, method)
    q_path = PATHS[path_name]()
    m = traj.t.shape[0]
    assert traj.q.shape == traj.qd.shape == traj.qdd.shape == traj.qddd.shape == (m, N_JOINTS)
    assert traj.t[0] == 0.0
    np.testing.assert_allclose(np.diff(traj.t), traj.dt, rtol=0, atol=1e-12)
    assert traj.duration_s == traj.t[-1]
    assert abs(traj.duration_s / traj.dt - round(traj.duration_s / traj.dt)) < 1e-9
    np.testing.assert_allclose(traj.q[0], q_path[0], rtol=0, atol=ENDPOINT_TOL)
    np.testing.assert_allclose(traj.q[-1], q_path[-1], rtol=0, atol=ENDPOINT_TOL)
    for arr in (traj.qd, traj.qdd):
        assert np.abs(arr[0]).max() < REST_TOL
        assert np.abs(arr[-1]).max() < REST_TOL
    assert np.abs(traj.qddd[-1]).max() < REST_TOL
    for arr in (traj.q, traj.qd, traj.qdd, traj.qddd):
        assert np.all(np.isfinite(arr))


@pytest.mark.parametrize(("path_name", "limits_name", "method"), CASES)
def test_limits_hold_by_finite_differences(path_name, limits_name, method):
    limits = LIMIT_SETS[limits_name]
    for dt in (0.008, 0.002):
        traj = run(path_name, limits_name, method, dt=dt)
        v_ratio, a_ratio = fd_ratios(traj, limits)
        assert v_ratio <= 1.0 + FD_RATIO_TOL, (dt, v_ratio)
        assert a_ratio <= 1.0 + FD_RATIO_TOL, (dt, a_ratio)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("path_name", list(PATHS))
def test_analytic_derivatives_match_samples(method, path_name):
    """q, qd, qdd, qddd are mutually consistent.

    Over one sample interval the difference quotient of x is the mean of its
    derivative, so it must lie between the derivative's values at the two
    ends, up to a curvature term that is tiny at 1 ms (this also holds across
    the jerk discontinuities, unlike integrating the samples).
    """
    traj = run(path_name, "uniform", method, dt=FINE_DT)
    pairs = [(traj.q, traj.qd), (traj.qd, traj.qdd), (traj.qdd, traj.qddd)]
    for x, dx in pairs:
        quotient = np.diff(x, axis=0) / traj.dt
        lo = np.minimum(dx[:-1], dx[1:])
        hi = np.maximum(dx[:-1], dx[1:])
        excess = np.maximum(lo - quotient, quotient - hi).max()
        assert excess <= DERIV_REL_TOL * np.abs(dx).max()


@pytest.mark.parametrize("method", METHODS)
def test_straight_path_is_followed_exactly(method):
    q_path = line_path()
    traj = run("line", "varied", method)
    direction = q_path[-1] - q_path[0]
    length = float(np.linalg.norm(direction))
    unit = direction / length
    rel = traj.q - q_path[0]
    along = rel @ unit
    off_line = np.linalg.norm(rel - along[:, None] * unit, axis=1)
    assert off_line.max() < LINE_TOL
    assert np.all(np.diff(along) >= -LINE_TOL)  # monotone, never backwards
    assert along[0] == pytest.approx(0.0, abs=LINE_TOL)
    assert along[-1] == pytest.approx(length, abs=LINE_TOL)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("path_name", list(PATHS))
def test_passes_every_waypoint_in_order(method, path_name):
    q_path = PATHS[path_name]()
    traj = run(path_name, "uniform", method, dt=FINE_DT)
    step = np.linalg.norm(np.diff(traj.q, axis=0), axis=1).max()
    tol = 0.5 * step + 1e-9  # a waypoint lies on the path between two samples
    dist = np.linalg.norm(traj.q[None, :, :] - q_path[:, None, :], axis=2)  # (N, M)
    closest = dist.argmin(axis=1)
    assert dist.min(axis=1).max() <= tol
    assert np.all(np.diff(closest) >= 0)


def reference_path(q_path: np.ndarray, n_dense: int = 20001) -> np.ndarray:
    """Documented geometry: natural cubic spline, chord-length parameter."""
    chord = np.linalg.norm(np.diff(q_path, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(chord))) / chord.sum()
    return CubicSpline(s, q_path, bc_type="natural")(np.linspace(0.0, 1.0, n_dense))


@pytest.mark.parametrize("path_name", list(PATHS))
def test_both_methods_follow_the_documented_spline(path_name):
    q_path = PATHS[path_name]()
    dense = reference_path(q_path)
    spacing = np.linalg.norm(np.diff(dense, axis=0), axis=1).max()
    tree = cKDTree(dense)
    for method in METHODS:
        traj = run(path_name, "uniform", method)
        dist, _ = tree.query(traj.q)
        assert dist.max() <= 0.5 * spacing + 1e-9, method


def test_ruckig_verification_loop_shrinks_too_fast_bounds(monkeypatch):
    """If the bound set were too optimistic, the verification loop fixes it."""
    original = ruckig_method.ruckig_bound_set

    def optimistic(path, limits, law):
        bounds, msg = original(path, limits, law)
        return (bounds[0] * 1.5, bounds[1] * 2.0, bounds[2] * 3.0), msg

    monkeypatch.setattr(ruckig_method, "ruckig_bound_set", optimistic)
    limits = LIMIT_SETS["uniform"]
    traj = time_parametrize(curved_path(), limits, "ruckig")
    assert max(float(r.max()) for r in traj.first_pass_limit_ratio.values()) > 1.2
    assert traj.iterations >= 2
    assert traj.status is TimingStatus.OK, traj.reason
    for key in ("velocity", "acceleration", "jerk"):
        assert np.all(traj.limit_ratio[key] <= 1.0 + LIMIT_RATIO_TOL)
    single = time_parametrize(curved_path(), limits, "ruckig", max_iterations=1)
    assert single.status is TimingStatus.LIMIT_EXCEEDED
    assert not single.reason.startswith(single.status.value)
    assert "ratio above 1 after 1 run(s) (max_iterations=1)" in single.reason


@pytest.mark.parametrize("path_name", list(PATHS))
def test_toppra_not_slower_than_ruckig(path_name):
    # Same path, same velocity/acceleration limits: the time-optimal TOPP-RA
    # solution cannot be slower than a jerk-limited one. TOPP-RA here adds the
    # smoothing window (TOPPRA_SMOOTHING_S) and any limit shrinking, which is
    # well below the a/jerk = 0.1 s that Ruckig needs per ramp with these limits.
    toppra_traj = run(path_name, "uniform", "toppra")
    ruckig_traj = run(path_name, "uniform", "ruckig")
    assert toppra_traj.duration_s <= ruckig_traj.duration_s


def test_ruckig_jerk_limited_toppra_not():
    limits = LIMIT_SETS["uniform"]
    ruckig_traj = run("curved", "uniform", "ruckig")
    toppra_traj = run("curved", "uniform", "toppra")
    assert np.all(ruckig_traj.limit_ratio["jerk"] <= 1.0 + LIMIT_RATIO_TOL)
    assert np.all(np.abs(ruckig_traj.qddd) <= limits.jerk * (1.0 + LIMIT_RATIO_TOL))
    # TOPP-RA does not limit jerk: reported, typically well above 1, still OK
    assert toppra_traj.status is TimingStatus.OK
    assert toppra_traj.limit_ratio["jerk"].max() > 1.0


# --------------------------------------------------------------------------- #
# TOPP-RA overshoot on a coarse grid and the shrinking loop
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize("time_law", ["smoothed", "spline"])
def test_toppra_coarse_grid_overshoot_is_corrected(time_law):
    limits = LIMIT_SETS["uniform"]
    traj = time_parametrize(curved_path(), limits, "toppra", gridpoints=100, time_law=time_law)
    first = traj.first_pass_limit_ratio
    assert first["acceleration"].max() > 1.0 + LIMIT_RATIO_TOL  # raw TOPP-RA output overshoots
    assert traj.iterations >= 2
    assert traj.status is TimingStatus.OK, traj.reason
    assert traj.limit_ratio["acceleration"].max() <= 1.0 + LIMIT_RATIO_TOL
    assert traj.limit_ratio["velocity"].max() <= 1.0 + LIMIT_RATIO_TOL
    v_ratio, a_ratio = fd_ratios(traj, limits)
    assert v_ratio <= 1.0 + FD_RATIO_TOL and a_ratio <= 1.0 + FD_RATIO_TOL


def test_toppra_never_ok_while_exceeding():
    limits = LIMIT_SETS["uniform"]
    traj = time_parametrize(curved_path(), limits, "toppra", gridpoints=100, time_law="spline", max_iterations=1)
    assert traj.iterations == 1
    assert traj.status is TimingStatus.LIMIT_EXCEEDED
    assert traj.reason.startswith("acceleration ratio above 1 after 1 run(s)")
    assert traj.limit_ratio["acceleration"].max() > 1.0 + LIMIT_RATIO_TOL
    # the independent finite-difference check sees the violation too
    assert fd_ratios(traj, limits)[1] > 1.0 + FD_RATIO_TOL
    assert traj.t.size > 0  # the offending trajectory is still returned


def test_toppra_failure_is_reported_not_raised(monkeypatch):
    def fail(self, sd_start, sd_end, return_data=False):
        return None, None, None

    monkeypatch.setattr(toppra.algorithm.TOPPRA, "compute_parameterization", fail)
    traj = time_parametrize(curved_path(), LIMIT_SETS["uniform"], "toppra")
    assert traj.status in (TimingStatus.FAILED, TimingStatus.INFEASIBLE)
    assert "TOPP-RA" in traj.reason and "failed" in traj.reason
    assert traj.t.size == 0 and traj.q.shape == (0, N_JOINTS)
    assert np.isnan(traj.duration_s)


def test_toppra_failure_on_rerun_returns_previous_run(monkeypatch):
    original = toppra.algorithm.TOPPRA.compute_parameterization
    calls = []

    def fail_second(self, sd_start, sd_end, return_data=False):
        calls.append(1)
        if len(calls) == 1:
            return original(self, sd_start, sd_end, return_data=return_data)
        return None, None, None

    monkeypatch.setattr(toppra.algorithm.TOPPRA, "compute_parameterization", fail_second)
    traj = time_parametrize(curved_path(), LIMIT_SETS["uniform"], "toppra", gridpoints=100)
    assert len(calls) == 2
    assert traj.status is TimingStatus.LIMIT_EXCEEDED
    assert "then TOPP-RA run 2" in traj.reason
    assert traj.iterations == 1 and traj.t.size > 0
    assert traj.limit_ratio["acceleration"].max() > 1.0 + LIMIT_RATIO_TOL


def test_library_prints_and_logs_nothing(capsys, caplog):
    caplog.set_level(logging.DEBUG)
    time_parametrize(curved_path(), LIMIT_SETS["varied"], "toppra", gridpoints=100)
    time_parametrize(curved_path(), LIMIT_SETS["varied"], "ruckig")
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""
    noisy = [r for r in caplog.records if r.name.startswith("toppra") and r.levelno >= logging.WARNING]
    assert not noisy
    # toppra's own warnings (e.g. "Fail to parametrize path") are muted inside
    # the call and the logger level is restored afterwards
    toppra_logger = logging.getLogger("toppra")
    before = toppra_logger.level
    with toppra_method.quiet_toppra():
        logging.getLogger("toppra.algorithm").warning("muted")
    assert toppra_logger.level == before
    logging.getLogger("toppra.algorithm").warning("audible")
    messages = [r.getMessage() for r in caplog.records]
    assert "muted" not in messages and "audible" in messages


# --------------------------------------------------------------------------- #
# Degenerate paths
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize("method", METHODS)
def test_zero_length_path_is_infeasible(method):
    q = np.tile(np.array([0.1, -0.2, 0.3, 0.0, 0.5, -1.0]), (5, 1))
    traj = time_parametrize(q, LIMIT_SETS["uniform"], method)
    assert traj.status is TimingStatus.INFEASIBLE
    assert "zero length" in traj.reason
    assert traj.duration_s == 0.0
    np.testing.assert_array_equal(traj.q, q[:1])
    assert np.all(traj.qd == 0.0)


@pytest.mark.parametrize("method", METHODS)
def test_consecutive_duplicates_are_dropped(method):
    q = curved_path(n_way=10)
    q_dup = np.insert(q, [0, 4, 4, 9], q[[0, 4, 4, 9]], axis=0)
    assert q_dup.shape[0] == 14
    a = time_parametrize(q, LIMIT_SETS["uniform"], method)
    b = time_parametrize(q_dup, LIMIT_SETS["uniform"], method)
    assert b.status is TimingStatus.OK
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)


def test_two_waypoints_and_one_moving_joint():
    q = np.zeros((2, N_JOINTS))
    q[1, 2] = 1.0
    for method in METHODS:
        traj = time_parametrize(q, LIMIT_SETS["uniform"], method, dt=0.004)
        assert traj.status is TimingStatus.OK, traj.reason
        assert np.all(traj.q[:, [0, 1, 3, 4, 5]] == 0.0)
        np.testing.assert_allclose(traj.q[-1], q[-1], atol=ENDPOINT_TOL)


# --------------------------------------------------------------------------- #
# Input validation
# --------------------------------------------------------------------------- #


def test_nan_waypoint_names_row_and_joint():
    q = curved_path()
    q[3, 1] = np.nan
    with pytest.raises(InputError, match=r"waypoint row 3, joint 2\).*nan"):
        time_parametrize(q, LIMIT_SETS["uniform"])
    q[3, 1] = np.inf
    with pytest.raises(InputError, match="finite"):
        time_parametrize(q, LIMIT_SETS["uniform"], "ruckig")


@pytest.mark.parametrize(
    "q",
    [
        np.zeros(6),  # 1-D
        np.zeros((1, 6)),  # single waypoint
        np.zeros((5, 5)),  # wrong joint count
        np.zeros((2, 3, 6)),  # 3-D
    ],
)
def test_bad_path_shape(q):
    with pytest.raises(InputError, match="q_path"):
        time_parametrize(q, LIMIT_SETS["uniform"])


@pytest.mark.parametrize(
    ("field", "joint", "value"),
    [("velocity", 2, -1.0), ("acceleration", 4, 0.0), ("jerk", 6, np.nan), ("jerk", 1, np.inf)],
)
def test_bad_limits_name_quantity_joint_value(field, joint, value):
    kwargs = {k: np.ones(N_JOINTS) for k in ("velocity", "acceleration", "jerk")}
    kwargs[field][joint - 1] = value
    with pytest.raises(InputError) as err:
        JointLimits(**kwargs)
    msg = str(err.value)
    assert field in msg and f"joint {joint}" in msg and repr(float(value)) in msg


def test_limits_shape_mismatch_and_read_only():
    with pytest.raises(InputError, match="shape"):
        JointLimits(np.ones(6), np.ones(5), np.ones(6))
    with pytest.raises(InputError, match="1-D"):
        JointLimits(np.ones((2, 3)), np.ones((2, 3)), np.ones((2, 3)))
    lim = JointLimits([1.0] * 6, [2.0] * 6, [3.0] * 6)
    assert lim.velocity.dtype == float and lim.n_joints == 6
    with pytest.raises(ValueError):
        lim.velocity[0] = 5.0


def test_unknown_method_lists_valid_names():
    with pytest.raises(InputError) as err:
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], method="totg")
    msg = str(err.value)
    assert "'totg'" in msg and all(repr(m) in msg for m in registry.available_methods())
    assert isinstance(err.value, ValueError)  # InputError stays a ValueError


@pytest.mark.parametrize("dt", [0.0, -0.008, 0.2, float("nan"), float("inf")])
def test_bad_dt(dt):
    with pytest.raises(InputError, match="dt"):
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], dt=dt)


def test_bad_options_and_limits_type():
    with pytest.raises(InputError, match="gridpoints.*valid options"):
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], "ruckig", gridpoints=100)
    with pytest.raises(InputError, match="gridpoints must be an integer >= 2, got 1"):
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], "toppra", gridpoints=1)
    with pytest.raises(InputError, match="time_law.*'linear'"):
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], "toppra", time_law="linear")
    with pytest.raises(InputError, match="JointLimits"):
        time_parametrize(curved_path(), {"velocity": np.ones(6)})


# --------------------------------------------------------------------------- #
# CSV output
# --------------------------------------------------------------------------- #


def test_to_csv_header_rows_and_values(tmp_path):
    traj = run("curved", "uniform", "ruckig")
    out = tmp_path / "traj.csv"
    traj.to_csv(out)
    lines = out.read_text().splitlines()
    expected = ["t"] + [f"{p}{j}" for p in ("q", "qd", "qdd", "qddd") for j in range(1, 7)]
    assert lines[0].split(",") == expected
    assert len(lines) == traj.t.size + 1
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert data.shape == (traj.t.size, 25)
    np.testing.assert_array_equal(data[:, 0], traj.t)
    np.testing.assert_array_equal(data[:, 1:7], traj.q)
    np.testing.assert_array_equal(data[:, 13:19], traj.qdd)
    np.testing.assert_array_equal(data[:, 19:25], traj.qddd)
    assert sorted(os.listdir(tmp_path)) == ["traj.csv"]


def test_to_csv_failure_mid_write_leaves_nothing(tmp_path):
    traj = run("line", "uniform", "toppra")
    out = tmp_path / "traj.csv"
    out.write_text("previous content\n")
    bad_qdd = traj.qdd.astype(object)
    bad_qdd[-1, 0] = "not a number"  # formatting fails on the last row
    broken = replace(traj, qdd=bad_qdd)
    with pytest.raises(TypeError):
        broken.to_csv(out)
    assert out.read_text() == "previous content\n"
    assert sorted(os.listdir(tmp_path)) == ["traj.csv"]


def test_to_csv_failure_on_replace_leaves_nothing(tmp_path, monkeypatch):
    traj = run("line", "uniform", "toppra")
    out = tmp_path / "new.csv"

    def boom(src, dst):
        raise OSError("simulated rename failure")

    monkeypatch.setattr(trajectory_module.os, "replace", boom)
    with pytest.raises(OSError, match="simulated"):
        traj.to_csv(out)
    assert os.listdir(tmp_path) == []


def test_to_csv_rejects_inconsistent_arrays(tmp_path):
    traj = run("line", "uniform", "toppra")
    broken = replace(traj, qd=traj.qd[:-1])
    with pytest.raises(InputError, match="inconsistent"):
        broken.to_csv(tmp_path / "x.csv")
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- #
# Package layout: registry, re-exports
# --------------------------------------------------------------------------- #


def test_names_imported_elsewhere_are_reexported():
    # planner/plan.py, planner/commands/plan.py, benchmarks/*: keep working
    for name in (
        "JointLimits",
        "Trajectory",
        "TimingStatus",
        "time_parametrize",
        "DT_MAX_S",
        "LIMIT_RATIO_TOL",
        "available_methods",
        "default_methods",
        "controller_methods",
        "display_name",
        "get_method",
    ):
        assert hasattr(timing, name), name
        assert name in timing.__all__, name
    assert timing.DT_MAX_S == registry.DT_MAX_S
    assert set(METHODS) <= set(registry.available_methods())


def test_registry_records_of_builtin_methods():
    tp = registry.get_method("toppra")
    rk = registry.get_method("ruckig")
    jo = registry.get_method("jerk_optimal")
    assert tp.checked_limits == ("velocity", "acceleration") and not tp.enforces_jerk
    assert rk.checked_limits == jo.checked_limits == ("velocity", "acceleration", "jerk")
    assert "time_law" in tp.options and "time_law" not in rk.options
    assert (tp.display_name, jo.display_name, rk.display_name) == ("TOPP-RA", "jerk-optimal", "Ruckig")
    # the controller runs the jerk-limited optimum, else Ruckig, else TOPP-RA
    assert registry.controller_methods(METHODS) == ("jerk_optimal", "ruckig", "toppra")
    assert registry.controller_methods(("toppra", "ruckig")) == ("ruckig", "toppra")
    # a problem that names no method runs the time-optimal reference and the controller's
    assert registry.default_methods() == ("toppra", "jerk_optimal")
    assert all(registry.get_method(m).dt_max_s == registry.DT_MAX_S for m in METHODS)
    assert all(registry.get_method(m).description for m in METHODS)
    assert registry.display_name("not_registered") == "not_registered"
    with pytest.raises(InputError, match="already registered"):
        registry.register_method(tp)
    with pytest.raises(InputError, match="unknown checked limit"):
        registry.register_method(replace(tp, name="bad", checked_limits=("speed",)))
    with pytest.raises(InputError, match="dt_max_s"):
        registry.register_method(replace(tp, name="bad", dt_max_s=1.0))
    assert "bad" not in registry.available_methods()


def test_a_new_method_is_a_registered_module():
    """Adding a method = registering a TimingMethod; dispatch goes through the registry."""
    calls = []
    builtin = registry.available_methods()

    def run_rest(path, limits, dt, opts):
        calls.append((path.q_path.shape, dt, dict(opts)))
        return trajectory_module.Trajectory(
            method="rest",
            status=TimingStatus.FAILED,
            reason="stub",
            t=np.empty(0),
            q=np.empty((0, N_JOINTS)),
            qd=np.empty((0, N_JOINTS)),
            qdd=np.empty((0, N_JOINTS)),
            qddd=np.empty((0, N_JOINTS)),
            duration_s=float("nan"),
            limit_ratio={},
            dt=dt,
        )

    def validate(out):
        registry.check_integer_options(out, (("level", 0),))
        return out

    method = registry.TimingMethod("rest", run_rest, ("level",), validate, ("velocity",), dt_max_s=0.01)
    registry.register_method(method)
    try:
        assert registry.available_methods() == (*builtin, "rest")
        assert method.display_name == "rest" and method.controller_rank is None
        assert "rest" not in registry.controller_methods() and "rest" not in registry.default_methods()
        traj = time_parametrize(curved_path(), LIMIT_SETS["uniform"], "rest", 0.004, level=2)
        assert traj.method == "rest" and calls == [((N_WAYPOINTS, N_JOINTS), 0.004, {"level": 2})]
        with pytest.raises(InputError, match="level"):
            time_parametrize(curved_path(), LIMIT_SETS["uniform"], "rest", 0.004, level=-1)
        with pytest.raises(InputError, match="valid options"):
            time_parametrize(curved_path(), LIMIT_SETS["uniform"], "rest", 0.004, gridpoints=5)
        with pytest.raises(InputError, match=r"<= 0.01 s of timing method 'rest'"):  # its own dt bound
            time_parametrize(curved_path(), LIMIT_SETS["uniform"], "rest", 0.02)
    finally:
        registry.unregister_method("rest")
    assert registry.available_methods() == builtin
    with pytest.raises(InputError, match="rest"):
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], "rest")


# --------------------------------------------------------------------------- #
# One status decision for every method; reasons do not repeat the status
# --------------------------------------------------------------------------- #


@pytest.mark.parametrize("method", METHODS)
def test_reasons_never_repeat_the_status(method):
    zero = time_parametrize(np.zeros((3, N_JOINTS)), LIMIT_SETS["uniform"], method)
    for traj in (run("curved", "uniform", method), zero):
        assert traj.reason and not traj.reason.startswith(traj.status.value), traj.reason
    assert zero.status is TimingStatus.INFEASIBLE and zero.reason.startswith("path has zero length")


def test_the_plan_names_a_failed_trajectory_status_once():
    """planner.plan composes "<method>: <status>: <reason>" without reading the reason."""
    from planner.plan import PlanStatus, plan
    from problems.problem import load_problem

    pr = load_problem("paper_4_4").with_timing(methods=("toppra",), toppra_max_iterations=1)
    res = plan(pr)
    tr = res.trajectories["toppra"]
    assert res.status is PlanStatus.TIMING_FAILED and tr.status is TimingStatus.LIMIT_EXCEEDED
    assert res.reason == f"toppra: limit_exceeded: {tr.reason}"
    assert "limit_exceeded" not in tr.reason


def test_finish_trajectory_decides_status_from_the_registry():
    """Every backend ends in verification.finish_trajectory: a law that moves backwards fails,
    an exceeded limit the method checks is LIMIT_EXCEEDED, an unchecked one (TOPP-RA's jerk) is not."""
    path = timing.SplinePath(curved_path())
    limits = LIMIT_SETS["uniform"]
    good = run("curved", "uniform", "toppra")
    duration = float(good.duration_s)

    def law(t):  # a slow, monotone law: s = (t / T)^2 (3 - 2 t / T)
        u = np.clip(t / duration, 0.0, 1.0)
        return (
            u**2 * (3 - 2 * u),
            6 * u * (1 - u) / duration,
            (6 - 12 * u) / duration**2,
            np.full_like(u, -12.0 / duration**3),
        )

    tc = verification.check_times(duration, good.dt)
    s, sd, sdd, sddd = law(tc)
    _, qd, qdd, qddd = path.evaluate(s, sd, sdd, sddd)
    ratio = verification.limit_ratios(qd, qdd, qddd, limits)
    common = {"check_sd": sd, "sd_scale": float(sd.max()), "iterations": 1}
    traj = verification.finish_trajectory("toppra", path, limits, good.dt, law, duration, ratio, "test", **common)
    exceeded = verification.exceeded_limits(traj.limit_ratio, ("velocity", "acceleration"))
    assert traj.status is (TimingStatus.LIMIT_EXCEEDED if exceeded else TimingStatus.OK)
    assert traj.reason.endswith("; test") and not traj.reason.startswith(traj.status.value)
    # the same law with every limit 100x tighter: over the limits the method checks
    tight = JointLimits(limits.velocity / 100, limits.acceleration / 100, limits.jerk / 100)
    tight_ratio = verification.limit_ratios(qd, qdd, qddd, tight)
    over = verification.finish_trajectory(
        "toppra", path, tight, good.dt, law, duration, tight_ratio, "x", **common, runs=" after 1 run(s)"
    )
    assert over.status is TimingStatus.LIMIT_EXCEEDED
    assert over.reason.startswith("velocity and acceleration ratio above 1 after 1 run(s); x")
    # a backwards path velocity fails, whatever the ratios
    back = verification.finish_trajectory(
        "ruckig", path, limits, good.dt, law, duration, ratio, "y", check_sd=-sd, sd_scale=float(sd.max()), iterations=1
    )
    assert back.status is TimingStatus.FAILED and back.reason.startswith("the Ruckig time law moves backwards")


# --------------------------------------------------------------------------- #
# Ruckig result codes are kept
# --------------------------------------------------------------------------- #


class _FailingRuckig:
    """Stand-in for ``ruckig.Ruckig`` whose calculation always returns an error code."""

    def __init__(self, dofs):
        self.dofs = dofs

    def calculate(self, inp, traj):
        return ruckig.Result.ErrorExecutionTimeCalculation


def test_ruckig_ok_has_no_solver_code():
    assert run("curved", "uniform", "ruckig").solver_code == ""
    assert run("curved", "uniform", "toppra").solver_code == ""


def test_ruckig_error_code_in_bound_search_is_kept(monkeypatch):
    monkeypatch.setattr(ruckig, "Ruckig", _FailingRuckig)
    traj = time_parametrize(curved_path(), LIMIT_SETS["uniform"], "ruckig")
    assert traj.status is TimingStatus.FAILED
    assert traj.solver_code == "ruckig.Result.ErrorExecutionTimeCalculation"
    assert "ruckig.Result.ErrorExecutionTimeCalculation" in traj.reason
    assert traj.t.size == 0 and np.isnan(traj.duration_s)


def test_ruckig_error_code_in_verification_run_is_kept(monkeypatch):
    monkeypatch.setattr(ruckig, "Ruckig", _FailingRuckig)
    monkeypatch.setattr(ruckig_method, "ruckig_bound_set", lambda p, lim, law: ((1.0, 1.0, 1.0), ""))
    traj = time_parametrize(curved_path(), LIMIT_SETS["uniform"], "ruckig")
    assert traj.status is TimingStatus.FAILED and traj.iterations == 1
    assert traj.solver_code == "ruckig.Result.ErrorExecutionTimeCalculation"
    assert traj.reason.startswith("Ruckig run 1 failed")
    assert traj.reason.endswith("returned ruckig.Result.ErrorExecutionTimeCalculation")


def test_ruckig_exception_is_kept_with_its_message(monkeypatch):
    # a negative bound makes the ruckig binding raise instead of returning a code
    monkeypatch.setattr(ruckig_method, "ruckig_bound_set", lambda p, lim, law: ((-1.0, 1.0, 1.0), ""))
    traj = time_parametrize(curved_path(), LIMIT_SETS["uniform"], "ruckig")
    assert traj.status is TimingStatus.FAILED
    assert traj.solver_code == "ruckig.RuckigError"
    assert "raised ruckig.RuckigError" in traj.reason and "velocity" in traj.reason


# --------------------------------------------------------------------------- #
# jerk_optimal: the NLP over the path-velocity profile
# --------------------------------------------------------------------------- #

#: jerk_optimal against TOPP-RA (jerk not limited) on the test paths: at most this much slower.
JERK_OPTIMAL_MAX_RATIO = 1.25


@pytest.mark.parametrize("path_name", list(PATHS))
def test_jerk_optimal_is_close_to_time_optimal_and_limits_jerk(path_name):
    opt = run(path_name, "varied", "toppra")
    jo = run(path_name, "varied", "jerk_optimal")
    rk = run(path_name, "varied", "ruckig")
    assert jo.status is TimingStatus.OK, jo.reason
    assert max(float(jo.limit_ratio[k].max()) for k in ("velocity", "acceleration", "jerk")) <= 1.0 + 1e-9
    assert opt.duration_s <= jo.duration_s <= JERK_OPTIMAL_MAX_RATIO * opt.duration_s
    # never slower than the global-bound Ruckig scheme (equal on a straight line, where it is optimal)
    assert jo.duration_s <= rk.duration_s + jo.dt
    # it uses its limits: some limit binds (ratio near 1) somewhere
    assert max(float(jo.limit_ratio[k].max()) for k in ("acceleration", "jerk")) > 0.95


def test_jerk_optimal_options_are_checked():
    with pytest.raises(InputError, match="gridpoints"):
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], "jerk_optimal", gridpoints=5)
    with pytest.raises(InputError, match="max_iterations"):
        time_parametrize(curved_path(), LIMIT_SETS["uniform"], "jerk_optimal", max_iterations=0)


def test_jerk_optimal_solver_failure_is_reported_not_raised():
    traj = time_parametrize(curved_path(), LIMIT_SETS["uniform"], "jerk_optimal", max_iterations=1)
    assert traj.status is not TimingStatus.OK and "IPOPT" in traj.reason
