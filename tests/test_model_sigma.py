"""Where the model holds, as the commands say it: predict / compensate write the predicted sigma and
flag rows outside the identified ranges; plan reports the sigma along its path and the waypoints where
the model extrapolates (problems/identify/uncertainty.py)."""

from __future__ import annotations

import csv
import json
import tomllib

import numpy as np
import pytest
import tomli_w

from models.arm_file import load_model, model_toml
from planner.cli import main as cli_main
from problems.identify.uncertainty import PATH_OUTSIDE_NAMED, outside_ranges, path_sigma, predicted_sigma

#: The sigma written in a CSV (repr of floats) against the library's, relative.
CSV_SIGMA_RTOL = 1e-9


@pytest.fixture(scope="module")
def model_file(tmp_path_factory, small_virtual_model):
    _robot, vr, _data, model = small_virtual_model
    d = tmp_path_factory.mktemp("sigma")
    path = d / "model.toml"
    path.write_text(model_toml(model))
    return path, vr


def _commands(path, q):
    lines = ["q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz"]
    lines += [",".join(repr(float(v)) for v in row) + ",0,0,0,0,0,0" for row in q]
    path.write_text("\n".join(lines) + "\n")


def _read_output(path):
    """A predict / compensate output: the numeric columns (N, k) and the ``outside_range`` texts."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0][-1] == "outside_range"
    return np.array([[float(v) for v in r[:-1]] for r in rows[1:]]), [r[-1] for r in rows[1:]]


def _inside_and_outside(model, n=4):
    rng = model.joint_range_rad
    q = np.tile(rng.mean(axis=1), (n, 1)) + np.linspace(0.0, 0.05, n)[:, None] * (rng[:, 1] - rng[:, 0])
    q[1, 0] = rng[0, 1] + 0.3  # joint 1 beyond its identified range (inside the limits)
    return q


def test_predict_writes_sigma_and_flags_rows(model_file, tmp_path, capsys):
    path, _vr = model_file
    model = load_model(path)
    q = _inside_and_outside(model)
    inp, out = tmp_path / "in.csv", tmp_path / "pred.csv"
    _commands(inp, q)
    assert cli_main(["predict", "--model", str(path), "--input", str(inp), "--out", str(out)]) == 0
    cap = capsys.readouterr()
    assert out.read_text().splitlines()[0] == "x,y,z,sigma_x,sigma_y,sigma_z,outside_range"
    t, flags = _read_output(out)
    expect = predicted_sigma(model, q, np.zeros((len(q), 6))).sigma_m
    np.testing.assert_allclose(t[:, 3:6], expect, rtol=CSV_SIGMA_RTOL)
    # row 2 (input line 3) has joint 1 beyond its identified range, the others are inside
    assert flags[0] == flags[2] == flags[3] == "" and flags[1] == outside_ranges(model, q[1])[0]
    assert flags[1].startswith(f"q1 {np.degrees(q[1, 0]):.1f} deg (identified ") and ";" not in flags[1]
    assert "predicted sigma (measurement frame" in cap.out
    assert "1 row(s) outside the joint ranges" in cap.err and "line 3: q1 " in cap.err  # header is line 1


def test_compensate_writes_base_frame_sigma(model_file, tmp_path):
    path, _vr = model_file
    model = load_model(path)
    q = _inside_and_outside(model)
    inp, out = tmp_path / "in.csv", tmp_path / "comp.csv"
    _commands(inp, q)
    assert cli_main(["compensate", "--model", str(path), "--input", str(inp), "--out", str(out)]) == 0
    t, flags = _read_output(out)
    expect = predicted_sigma(model, t[:, :6], np.zeros((len(q), 6)), frame="base").sigma_m
    np.testing.assert_allclose(t[:, 6:9], expect, rtol=CSV_SIGMA_RTOL)
    # flagged at the compensated commands (the compensation moves a joint by well under the margin)
    assert flags == outside_ranges(model, t[:, :6]) and flags[1].startswith("q1 ") and flags[0] == ""


def test_format_1_model_gives_nan_and_a_note(model_file, tmp_path, capsys):
    path, _vr = model_file
    d = tomllib.loads(path.read_text())
    for k in ("covariance", "residual_sigma_m", "joint_range_rad"):
        d["identified"].pop(k)
    d["identified"]["format"] = 1
    old = tmp_path / "old.toml"
    old.write_text(tomli_w.dumps(d))
    inp, out = tmp_path / "in.csv", tmp_path / "pred.csv"
    _commands(inp, _inside_and_outside(load_model(path)))
    assert cli_main(["predict", "--model", str(old), "--input", str(inp), "--out", str(out)]) == 0
    t, flags = _read_output(out)
    assert np.isnan(t[:, 3:6]).all() and flags == [""] * len(t)  # format 1 records no ranges
    assert "no parameter covariance" in capsys.readouterr().out


def test_unknown_campaign_is_one_line(model_file, tmp_path, capsys):
    path, _vr = model_file
    inp, out = tmp_path / "in.csv", tmp_path / "pred.csv"
    _commands(inp, _inside_and_outside(load_model(path)))
    for cmd in ("predict", "compensate"):
        code = cli_main([cmd, "--model", str(path), "--input", str(inp), "--out", str(out), "--campaign", "B"])
        err = capsys.readouterr().err
        assert code == 2 and not out.exists()
        assert err.count("\n") == 1 and "--campaign 'B'" in err and "one campaign" in err


def test_path_sigma_names_extrapolating_waypoints(model_file):
    path, _vr = model_file
    model = load_model(path)
    q = np.tile(model.joint_range_rad.mean(axis=1), (12, 1))
    q[:, 0] += np.linspace(0.0, 0.1, 12)
    q[3:10, 1] = model.joint_range_rad[1, 0] - 0.2
    ps = path_sigma(model, q)
    assert ps.available and ps.n_outside == 7
    assert [k for k, _t in ps.outside_text] == list(range(3, 3 + PATH_OUTSIDE_NAMED))
    w = ps.warning()
    assert "7 waypoint(s)" in w and "waypoint 3: q2 " in w and "and 2 more" in w
    np.testing.assert_allclose(ps.sigma_m, predicted_sigma(model, q, frame="base").sigma_m)
    d = ps.to_dict()
    assert d["n_outside_range"] == 7 and d["max_m"] == pytest.approx(ps.sigma_m.max())
    nominal = path_sigma(load_model("ur5"), q)
    assert not nominal.available and "nominal" in nominal.reason and nominal.n_outside == 0


def test_plan_reports_the_sigma_once(model_file, tmp_path, capsys):
    path, _vr = model_file
    out = tmp_path / "run"
    code = cli_main(["plan", "ur5_tool_thrust", "--robot", str(path), "--out", str(out), "--no-report"])
    assert code == 0
    printed = capsys.readouterr().out
    s = json.loads((out / "summary.json").read_text())
    sig = s["model_sigma"]
    assert sig["available"] and sig["frame"] == "base" and sig["text"] in printed
    # recomputed independently at the plan's compensated commands (path.csv) under its load
    t = np.genfromtxt(out / "path.csv", delimiter=",", names=True)
    q = np.column_stack([t[f"q{j}"] for j in range(1, 7)])
    model = load_model(path)
    assert sig["n_outside_range"] == int((path_sigma(model, q).outside.any(axis=1)).sum())
    ps = predicted_sigma(model, q, frame="base").sigma_m
    assert sig["mean_m"] == pytest.approx(ps.mean(), rel=0.05)  # the load changes the linearisation little


#: Held-out virtual campaigns (other seeds than the fixture's) pooled for the coverage check.
COVERAGE_SEEDS = (101, 102, 103)
#: Share of per-axis held-out errors within 2 sigma: 95 % for Gaussian errors; the band allows
#: the sampling spread of ~540 errors and a mildly mis-estimated residual sigma.
COVERAGE_BAND = (0.85, 0.995)


def test_sigma_covers_held_out_virtual_errors(small_virtual_model):
    """A geometric model of the virtual UR5 predicts held-out campaigns of the same robot (new poses,
    new noise): 85-99.5 % of the per-axis errors lie within 2 sigma of their axis."""
    from problems.identify import predict

    _robot, vr, _data, model = small_virtual_model
    errors, sigmas = [], []
    for seed in COVERAGE_SEEDS:
        held = vr.campaign(seed=seed)
        errors.append(held.p - predict(model, held))
        sigmas.append(predicted_sigma(model, held.q, held.wrench).sigma_m)
    e, s = np.vstack(errors), np.vstack(sigmas)
    assert np.isfinite(s).all() and (s > 0).all()
    share = float(np.mean(np.abs(e) <= 2.0 * s))
    assert COVERAGE_BAND[0] <= share <= COVERAGE_BAND[1], share
    # sigma is not the noise alone: the parameters' part adds to it (a check that can fail)
    assert (s > model.residual_sigma_m).all()


def test_nominal_robot_predict_gives_nan_quietly(tmp_path, capsys):
    q = np.radians([10.0, -60.0, 80.0, -100.0, -90.0, 0.0]) + np.linspace(0.0, 0.2, 3)[:, None]
    inp, out = tmp_path / "in.csv", tmp_path / "pred.csv"
    _commands(inp, q)
    assert cli_main(["predict", "--model", "ur5", "--input", str(inp), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    t, flags = _read_output(out)
    assert t.shape == (3, 6) and np.isfinite(t[:, :3]).all() and np.isnan(t[:, 3:6]).all()
    assert flags == [""] * 3  # a nominal robot file records no identified ranges: nothing flagged
    # a plain robot file has no covariance by nature: the nan columns say it (docs/cli.md), no note
    assert "note" not in printed and "sigma" not in printed.replace("sigma_x, sigma_y, sigma_z", "")


def test_plan_with_nominal_model_says_sigma_unavailable(fast_payload_run):
    sig = json.loads((fast_payload_run / "summary.json").read_text())["model_sigma"]
    assert sig["available"] is False and sig["reason"] == "nominal model: no covariance"
    assert sig["mean_m"] is None and sig["max_m"] is None and sig["n_outside_range"] == 0


def test_commands_csv_text_column_round_trips():
    """The text column of predict / compensate: quoted where the CSV needs it, read back unchanged."""
    from problems.measurements import commands_csv

    texts = ["", "q1 95.0 deg (identified -24.4..19.2); q2 1.0 deg (identified 2.0..3.0)", 'a, "b"']
    nums = np.array([[0.1, np.nan], [1e-17, -2.0], [3.0, 4.0]])
    rows = list(csv.reader(commands_csv(["a", "b"], nums, {"outside_range": texts}).splitlines()))
    assert rows[0] == ["a", "b", "outside_range"] and [r[2] for r in rows[1:]] == texts
    back = np.array([[float(v) for v in r[:2]] for r in rows[1:]])
    np.testing.assert_array_equal(back, nums)  # repr round trip, NaN included (assert_array_equal: nan == nan)
    with pytest.raises(ValueError, match="outside_range"):
        commands_csv(["a", "b"], nums, {"outside_range": texts[:2]})
