"""The dynamic-compensation stage of compplan plan ([timing] dynamic = true), checked through the
independent elastic-joint simulation (problems/virtual/elastic.py)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from models.dynamics import payload_vector
from planner.cli import main
from problems.problem import load_problem
from problems.virtual.elastic import simulate_elastic, tracking_error

#: Issue 13: during the motion the command cuts the simulated TCP error at least this much against
#: the static compensation alone; at rest (end of the settling) it is within this.
MOTION_GAIN_MIN = 10.0
REST_FINAL_MAX_M = 1e-6
#: The command's limit check is on central differences of its samples (planner/dynamic.py).
RATIO_TOL = 1e-9


@pytest.fixture
def fast_run(fast_payload_run):
    """``compplan plan ur5_fast_payload`` (once per session, with its report: conftest.py)."""
    return fast_payload_run


def _csv(path):
    rows = list(csv.reader(path.open(newline="")))
    a = np.array(rows[1:], dtype=float)
    return {h: a[:, i] for i, h in enumerate(rows[0])}


@pytest.mark.slow
def test_trajectory_csv_is_the_command_with_the_link_side_beside_it(fast_run):
    s = json.loads((fast_run / "summary.json").read_text())
    d = s["dynamic_compensation"]
    assert d["status"] == "ok" and d["passes"] >= 1
    pe = d["predicted_tcp_error"]
    assert pe["static"]["motion_max_mm"] > MOTION_GAIN_MIN * pe["static+dynamic"]["motion_max_mm"]
    assert pe["static"]["rest_max_mm"] == 0.0
    # the gain on arms 20 % off in stiffness and payload is reported (smaller: the static mismatch dominates)
    mm = {(c["stiffness_factor"], c["payload_factor"]): c for c in d["mismatch"]}
    assert set(mm) == {(0.8, 1.2), (1.2, 0.8), (0.8, 0.8), (1.2, 1.2)}
    assert all(
        0.5 < c["gain"] < pe["static"]["motion_max_mm"] / pe["static+dynamic"]["motion_max_mm"] for c in mm.values()
    )
    tr = _csv(fast_run / "trajectory.csv")
    t = tr["t"]
    dt = s["dt"]
    np.testing.assert_allclose(np.diff(t), dt, atol=1e-12)
    theta = np.column_stack([tr[f"q{i}"] for i in range(1, 7)])
    ql = np.column_stack([tr[f"ql{i}"] for i in range(1, 7)])
    assert 1e-5 < np.abs(theta - ql).max() < 1e-2  # the command differs from the link side
    # every limit holds on the command's samples (central differences computed here)
    v = np.gradient(theta, dt, axis=0)
    a = np.gradient(v, dt, axis=0)
    j = np.gradient(a, dt, axis=0)
    lim = s["limits"]
    for name, x in (("velocity", v), ("acceleration", a), ("jerk", j)):
        assert np.all(np.abs(x).max(axis=0) <= np.asarray(lim[name]) * (1 + RATIO_TOL)), name


@pytest.mark.slow
def test_the_simulated_arm_follows_the_link_plan(fast_run):
    """trajectory.csv's command through the elastic-joint simulation vs the static compensation."""
    from problems.dynamic import motor_command

    pr = load_problem("ur5_fast_payload")
    tr = _csv(fast_run / "trajectory.csv")
    t = tr["t"]
    theta = np.column_stack([tr[f"q{i}"] for i in range(1, 7)])
    ql = np.column_stack([tr[f"ql{i}"] for i in range(1, 7)])
    rows = np.repeat(pr.load.rows(pr.n)[:1], len(ql), axis=0)
    static = motor_command(pr.model, ql, np.zeros_like(ql), np.zeros_like(ql), pr.load, rows=rows).theta
    pl = payload_vector(pr.load.payload_mass_kg, pr.load.payload_com_m)
    err = {
        name: tracking_error(simulate_elastic(pr.robot, t, cmd, payload=pl), pr.robot, t, ql)
        for name, cmd in (("static", static), ("dynamic", theta))
    }
    assert err["static"].max_motion >= MOTION_GAIN_MIN * err["dynamic"].max_motion
    assert err["dynamic"].final <= REST_FINAL_MAX_M


@pytest.mark.parametrize(
    "edit,needle",
    [
        ('methods = ["toppra"]', "needs a jerk-limited controller trajectory"),
        ("dynamic = 1", "timing.dynamic' must be true or false"),
    ],
)
def test_dynamic_needs_a_jerk_limited_controller_and_a_boolean(edit, needle, tmp_path, capsys):
    from importlib import resources

    text = resources.files("problems").joinpath("files/ur5_fast_payload.toml").read_text(encoding="utf-8")
    key = edit.split(" = ")[0]
    text = "\n".join(edit if line.startswith(key + " =") else line for line in text.splitlines())
    f = tmp_path / "p.toml"
    f.write_text(text)
    assert main(["plan", str(f), "--out", str(tmp_path / "out"), "--no-report"]) == 2
    assert needle in capsys.readouterr().err


def test_dynamic_needs_link_masses(tmp_path, capsys):
    assert main(["plan", "ur5_fast_payload", "--robot", "ar5", "--out", str(tmp_path / "o"), "--no-report"]) == 2
    assert "no link masses" in capsys.readouterr().err


@pytest.mark.slow
def test_track_command_simulates_a_run(fast_run, tmp_path, capsys):
    out = tmp_path / "track.csv"
    assert main(["track", str(fast_run), "--out", str(out), "--settle", "0.2"]) == 0
    text = capsys.readouterr().out
    motion = float(text.split("during the motion: max ")[1].split(" mm")[0])
    assert 0 < motion < 0.05  # mm: the command's residual, not the 0.3 mm sag
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert rows.shape[1] == 2 and rows[-1, 0] > 1.0
    # an arm 20 % softer than the model: the error grows
    assert main(["track", str(fast_run), "--stiffness-scale", "0.8", "--settle", "0.2"]) == 0
    soft = float(capsys.readouterr().out.split("during the motion: max ")[1].split(" mm")[0])
    assert soft > 2 * motion


def test_track_refuses_an_arm_without_masses(paper_folder, capsys):
    assert main(["track", str(paper_folder)]) == 2  # the demo's ar5 has no link masses
    assert "no link masses" in capsys.readouterr().err
