"""The look-ahead timing method (``problems.timing.lookahead``) and the stretch fit
(``problems.toolpath.smoothing``, ``problems.toolpath.stretch_fit``), issue 33: the filtered law
against finite differences, its bounds local along the path, against Ruckig (one bound set) and
the jerk-limited NLP, and the smoothing's budget checked by forward kinematics."""

from __future__ import annotations

import numpy as np
import pytest

from problems.timing import JointLimits, time_parametrize
from problems.timing import lookahead as la
from problems.timing.path import SplinePath
from problems.timing.registry import LIMIT_RATIO_TOL

LIMITS = JointLimits(np.full(6, 2.0), np.full(6, 4.0), np.full(6, 40.0))
#: Relative error of a central difference of the filtered law (its derivatives are exact).
FD_TOL = 1e-5
#: The look-ahead's own (filtered) law on a rest-to-rest straight move, against Ruckig's
#: time-optimal jerk-limited profile: the filter costs at most this factor (3 / 4^(2/3) = 1.19 when
#: the jerk alone binds).
FIR_OVERHEAD = 1.20


def _line(n: int = 40, length: float = 0.5) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)[:, None]
    return s * np.array([[length, -0.5 * length, 0.3 * length, 0.0, 0.2 * length, 0.1 * length]])


def test_the_filtered_law_is_consistent_with_its_derivatives():
    path = SplinePath(np.c_[np.sin(np.linspace(0, 2, 50))[:, None] * np.ones(6)])
    grid = la._grid(path, LIMITS, la.CELLS_PER_KNOT)
    law = la._best_law(grid, 0.004)
    t = np.linspace(0.01, law.duration - 0.01, 400)
    h = 1e-6
    for k in range(3):  # s -> sd -> sdd -> sddd
        lo, hi, mid = law(t - h)[k], law(t + h)[k], law(t)[k + 1]
        scale = np.max(np.abs(mid)) + 1e-12
        assert np.max(np.abs((hi - lo) / (2 * h) - mid)) <= FD_TOL * scale * 10 + 1e-6, k
    s, sd, _, _ = law(np.array([0.0, law.duration + 1.0]))
    assert s[0] == 0.0 and s[1] == pytest.approx(1.0, abs=1e-12) and sd[0] == 0.0 and sd[1] == 0.0  # rest to rest
    assert np.all(np.diff(law(np.linspace(0, law.duration, 2000))[0]) >= -1e-15)  # never backwards


def test_a_straight_move_is_within_the_filters_overhead_of_the_optimal_s_curve():
    path = SplinePath(_line())
    grid = la._grid(path, LIMITS, la.CELLS_PER_KNOT)
    own = la._best_law(grid, 0.002).duration
    ruckig = time_parametrize(_line(), LIMITS, "ruckig", 0.002).duration_s  # constant bounds: optimal here
    assert own <= FIR_OVERHEAD * ruckig, (own, ruckig)
    tr = time_parametrize(_line(), LIMITS, "lookahead", 0.002)
    assert tr.status.value == "ok" and tr.duration_s <= ruckig + 1e-9  # the shorter kept


def _bend() -> np.ndarray:
    """A long path with one tight bend in its middle: Ruckig's one bound set is held down by the
    bend everywhere, local bounds only there."""
    s = np.linspace(0.0, 1.0, 400)
    bump = 0.02 * np.exp(-(((s - 0.5) / 0.01) ** 2))
    return np.c_[2.0 * s, bump, -1.0 * s, 0.5 * s, bump, s]


def test_bounds_are_local_so_one_bend_does_not_slow_the_whole_path():
    q = _bend()
    look = time_parametrize(q, LIMITS, "lookahead", 0.004)
    ruck = time_parametrize(q, LIMITS, "ruckig", 0.004)
    for tr in (look, ruck):
        assert tr.status.value == "ok", tr.reason
    for k in ("velocity", "acceleration", "jerk"):
        assert np.max(look.limit_ratio[k]) <= 1.0 + LIMIT_RATIO_TOL
    assert look.duration_s < 0.8 * ruck.duration_s, (look.duration_s, ruck.duration_s)
    # (the jerk-limited NLP, jerk_optimal, takes 2.4 s here against the look-ahead's 5.8 s: the filter's
    # erosion spreads the bend's small acceleration bound over the distance mixed at full speed;
    # docs/gcode.md, "Limits")


def test_local_bounds_name_the_joint_and_derivative():
    q = _line()
    q[:, 1] *= 10.0  # joint 2 travels most: its velocity limit binds on a straight move
    path = SplinePath(q)
    lb = la.local_bounds(path, LIMITS, np.array([0.3, 0.5]))
    assert np.all(lb.joint == 1) and np.all(lb.kind == la.BOUND_KINDS.index("velocity"))
    d1 = np.abs(path.spline.derivative(1)(0.5))
    assert lb.speed[1] == pytest.approx(np.min(LIMITS.velocity[d1 > 0] / d1[d1 > 0]))
    lb2 = la.local_bounds(path, LIMITS, np.array([0.5]), joints=1)  # joint 1 alone
    assert lb2.joint[0] == 0 and lb2.speed[0] > lb.speed[1]


def _planar_tcp(q: np.ndarray) -> np.ndarray:
    """A planar 3-link arm's TCP frame (links 0.4, 0.3, 0.1 m about z), homogeneous (M, 4, 4); the
    other joints do nothing (a free rotation the smoothing may use)."""
    a = np.cumsum(q[:, :3], axis=1)
    x = 0.4 * np.cos(a[:, 0]) + 0.3 * np.cos(a[:, 1]) + 0.1 * np.cos(a[:, 2])
    y = 0.4 * np.sin(a[:, 0]) + 0.3 * np.sin(a[:, 1]) + 0.1 * np.sin(a[:, 2])
    T = np.tile(np.eye(4), (len(q), 1, 1))
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, 0, 3], T[:, 1, 3] = x, y
    return T


def test_smoothing_stays_within_its_budget_and_keeps_the_ends():
    from problems.toolpath.smoothing import smooth_stretch

    rng = np.random.default_rng(3)
    tau = np.cumsum(np.r_[0.0, rng.uniform(0.001, 0.05, 120)])  # uneven steps
    q = np.c_[0.3 + 0.4 * tau, 0.5 - 0.2 * tau, 0.1 * np.sin(tau), np.zeros((len(tau), 3))]
    q[:, :3] += rng.normal(0.0, 2e-5, (len(tau), 3))  # facets and rounding
    budget = 1e-5
    out = smooth_stretch(tau, q, _planar_tcp, budget)
    moved = np.linalg.norm(_planar_tcp(out)[:, :3, 3] - _planar_tcp(q)[:, :3, 3], axis=1)
    assert moved.max() <= budget * (1 + 1e-9)
    assert np.array_equal(out[0], q[0]) and np.array_equal(out[-1], q[-1])
    from scipy.interpolate import CubicSpline

    def jerk_at_feed(x: np.ndarray) -> float:  # the spline's largest |d3q/dtau3|: the joints' jerk at F
        return float(np.abs(6.0 * CubicSpline(tau, x[:, :3]).c[0]).max())

    # the noise (about 8 µm at the TCP) is near the budget (10 µm): a fourfold cut is what the room allows
    assert jerk_at_feed(out) < 0.25 * jerk_at_feed(q)
    pinned = np.ones(len(tau))
    pinned[60] = 1e12
    out2 = smooth_stretch(tau, q, _planar_tcp, budget, pinned)
    assert np.linalg.norm(out2[60] - q[60]) < 1e-9


def test_the_fit_keeps_the_spline_within_the_tolerance_between_waypoints():
    from problems.toolpath.stretch_fit import fit_stretch

    rng = np.random.default_rng(5)
    tau = np.cumsum(np.r_[0.0, rng.uniform(0.0002, 0.003, 80)])  # chords of 0.1-1.3 mm, as a program's
    q = np.c_[0.3 + 0.6 * tau, 0.5 - 0.4 * tau**2, 0.2 * np.sin(3 * tau), np.zeros((len(tau), 3))]
    q[40:, 1] += 3e-3  # a kink: a corner the spline would round off beyond the tolerance
    q[:, :3] += rng.normal(0.0, 1e-5, (len(tau), 3))
    rows = np.c_[q, 100.0 * tau]
    tol = 1.5e-5
    from problems.toolpath.stretch_fit import _interval_deviation

    assert _interval_deviation(rows, 6, _planar_tcp, _planar_tcp(q)[:, :3, 3])[0].max() > tol  # not vacuous
    fitted, dev, kept = fit_stretch(rows, 6, tau, _planar_tcp, tol, time_column=6)
    assert len(kept) == len(rows) and np.all(np.diff(kept) > 0) and dev <= tol
    # independently: the spline through the fitted rows, densely, against the original polyline
    path = SplinePath(fitted)
    x = _planar_tcp(path.spline(np.linspace(0.0, 1.0, 4000))[:, :6])[:, :3, 3]
    P = _planar_tcp(q)[:, :3, 3]
    a, b = P[:-1], P[1:]
    ab = b - a
    t = np.clip(np.einsum("mkj,kj->mk", x[:, None, :] - a[None], ab) / np.einsum("kj,kj->k", ab, ab), 0.0, 1.0)
    d = np.linalg.norm(x[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
    assert d.max() <= tol, d.max()
    # the programmed-time column follows the fitted TCP path's length
    assert np.all(np.diff(fitted[:, 6]) > 0.0)


def test_stretches_timed_in_worker_processes_give_the_same_trajectory(tmp_path, monkeypatch):
    """The stretches are timed in forked workers when there are many (problems.toolpath.stretch_pool):
    the joined trajectory is the one timed in this process, sample for sample."""
    import importlib.util
    from pathlib import Path

    from planner.plan import plan
    from problems.problem import load_problem
    from problems.toolpath import stretch_pool

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("cam_finishing", root / "benchmarks" / "cam_finishing.py")
    cam = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cam)
    (tmp_path / "part.ngc").write_text(cam.finishing_program(n_rows=4))
    (tmp_path / "p.toml").write_text(
        'name = "f"\n[robot]\nmodel = "ur10"\ntool = { xyz = [0.08, 0.0, 0.12] }\n[path]\nkind = "gcode"\n'
        'file = "part.ngc"\n[workpiece]\nxyz = [0.65, 0.0, 0.10]\n[wrench]\nframe = "tool"\n'
        "force = [40.0, 25.0, 30.0]\n"
    )
    pr = load_problem(tmp_path / "p.toml")
    monkeypatch.setenv(stretch_pool.WORKERS_ENV, "1")
    one = plan(pr).feed["lookahead"]
    monkeypatch.setenv(stretch_pool.WORKERS_ENV, "2")
    monkeypatch.setattr(stretch_pool, "PARALLEL_MIN_STRETCHES", 2)
    assert stretch_pool.worker_count(one.n_stretches) == 2
    two = plan(pr).feed["lookahead"]
    assert one.n_stretches == two.n_stretches > 2
    assert np.array_equal(one.trajectory.q, two.trajectory.q) and np.array_equal(one.trajectory.t, two.trajectory.t)
    assert one.path_deviation_m == two.path_deviation_m and one.slowed == two.slowed


@pytest.mark.parametrize("raw", ["0", "two", "-1"])
def test_a_bad_worker_count_is_named(monkeypatch, raw):
    from models.errors import InputError
    from problems.toolpath import stretch_pool

    monkeypatch.setenv(stretch_pool.WORKERS_ENV, raw)
    with pytest.raises(InputError, match="COMPPLAN_WORKERS"):
        stretch_pool.worker_count(1000)


_AFTER_OPENMP = """
import sys
import numpy as np
from planner.plan import plan
from problems.problem import load_problem
from problems.toolpath import stretch_pool
stretch_pool.PARALLEL_MIN_STRETCHES = 2
pr = load_problem(sys.argv[1])
pr.model.kinematics.tcp(np.zeros((6000, 6)))  # a batch large enough to start an OpenMP team here
res = plan(pr)
print(res.status.value, res.feed["lookahead"].n_stretches)
"""


def test_workers_forked_after_openmp_do_not_hang(tmp_path):
    """GNU OpenMP does not survive a fork: a worker forked after the parent ran an OpenMP team waited
    forever in its first batch evaluation (now single-threaded in workers). In a subprocess with a
    time-out, so that a hang fails the test instead of the suite."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    (tmp_path / "part.ngc").write_text(
        "G21 G90 G94 G64 P0.02\nG0 X0 Y0 Z5\nG1 Z0 F300\n"
        + "".join(f"X{10 * (k % 2)} Y{k} F{1200 if k % 2 else 600}\n" for k in range(1, 6))
        + "X-150 F200\nG0 Z5\nM30\n"  # a long slow move: more samples than an OpenMP batch's threshold
    )
    (tmp_path / "p.toml").write_text(
        'name = "f"\n[robot]\nmodel = "ur10"\ntool = { xyz = [0.08, 0.0, 0.12] }\n[path]\nkind = "gcode"\n'
        'file = "part.ngc"\n[workpiece]\nxyz = [0.65, 0.0, 0.10]\n[wrench]\nforce = [0.0, 0.0, 0.0]\n'
    )
    env = dict(os.environ, COMPPLAN_WORKERS="2", PYTHONPATH=str(root))
    out = subprocess.run(
        [sys.executable, "-c", _AFTER_OPENMP, str(tmp_path / "p.toml")],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        cwd=root,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    status, n = out.stdout.split()
    assert status == "ok" and int(n) > 2
