"""What the user is told about campaigns (issue 34): repeated rows, the reference campaign, registrations
far apart, and the Euclidean position errors of ``identify --validation`` and ``predict``.

Small virtual-robot campaigns (geometric errors, 20 um noise, no load) keep the fits to seconds.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from models import load_robot
from models.arm_file import load_model
from models.errors import InputError
from models.transforms import rotvec_to_matrix
from planner.cli import main as cli_main
from problems.identify import DataError, identify, identify_campaigns, predict
from problems.identify.campaign_checks import (
    FRAME_STILL_M,
    FRAME_STILL_RAD,
    drop_repeated_rows,
    frame_warnings,
    reference_index,
)
from problems.identify.position_error import position_errors
from problems.measurements import Measurements, measurements_to_csv
from problems.virtual import VirtualRobot

CFG = {
    "seed": 3,
    "campaign": {"poses": 40, "loaded_rows": 0, "unloaded_rows": 1},
    "noise": {"sigma_m": 2e-5},
    "effects": {"geometric": {}},
}
NOISE_M = 2e-5
BIG, TINY = 40, 4
#: The re-positioned tracker of a moved campaign: rotation vector (rad) and translation (m).
MOVE_ROTVEC = np.array([0.0, 0.0, 0.1])
MOVE_T_M = np.array([0.2, -0.1, 0.05])
#: Fit options that keep the tests fast: geometric errors only.
FAST = {"candidates": ["geometric"]}


def _campaign(vr, rng, n, source, T=None, t0=0.0) -> Measurements:
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    q[:, 1] = rng.uniform(-2.0, -0.5, n)
    q[:, 2] = rng.uniform(-1.5, 1.5, n)
    F = np.zeros((n, 6))
    t = t0 + 10.0 * np.arange(n)
    p = vr.measure(q, F, t, None) + rng.normal(0.0, NOISE_M, (n, 3))
    if T is not None:
        p = p @ T[:3, :3].T + T[:3, 3]
    return Measurements(q=q, wrench=F, p=p, t=t, point=np.array([f"P{i}" for i in range(n)]), source=source)


def _move() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotvec_to_matrix(MOVE_ROTVEC)
    T[:3, 3] = MOVE_T_M
    return T


@pytest.fixture(scope="module")
def data():
    robot = load_robot("ur5")
    vr = VirtualRobot(robot, CFG, seed=3)
    rng = np.random.default_rng(11)
    big = _campaign(vr, rng, BIG, "big.csv")
    tiny = _campaign(vr, rng, TINY, "tiny.csv", t0=9000.0)
    tiny_moved = _campaign(vr, rng, TINY, "tiny.csv", T=_move(), t0=9000.0)
    held = _campaign(vr, rng, 12, "held.csv", t0=20000.0)
    return {"robot": robot, "big": big, "tiny": tiny, "tiny_moved": tiny_moved, "held": held}


# ----------------------------------------------------------------------------------
# Repeated rows
# ----------------------------------------------------------------------------------


def test_repeated_rows_within_and_across_campaigns_are_dropped_and_named(data) -> None:
    big = data["big"]
    a = big.subset(np.r_[np.arange(10), [3, 4]])  # rows 3 and 4 twice
    b = big.subset(np.r_[[5, 6, 7], np.arange(20, 30)])  # three rows of a again
    out, rep = drop_repeated_rows([a, b], ["a", "b"])
    assert [m.n for m in out] == [10, 10]
    assert rep.n_dropped == 5
    assert [(f["name"], f["n"], f["of"]) for f in rep.files] == [("a", 2, ["a"]), ("b", 3, ["a"])]
    assert rep.files[0]["lines"] == [int(x) for x in a.line[[10, 11]]]
    msg = rep.message()
    assert msg.startswith("5 row(s) repeat earlier rows exactly") and "2 in big.csv" in msg and "3 in big.csv" in msg
    assert "counted once" in msg
    # the same joints and load with another measured point is a new measurement, not a repeat
    c = b.subset(np.arange(b.n))
    c.p = c.p + 1e-6
    assert drop_repeated_rows([a, c], ["a", "c"])[1].n_dropped == 2


def test_the_same_campaign_twice_is_refused(data) -> None:
    big = data["big"]
    copy = big.subset(np.arange(big.n))
    copy.source = "copy.csv"
    with pytest.raises(DataError, match=r"copy\.csv: every row of campaign 'copy' repeats rows of 'big'.*give it once"):
        drop_repeated_rows([big, copy], ["big", "copy"])


def test_a_duplicated_row_does_not_double_its_weight(data) -> None:
    """Identify with two rows given twice = identify without the copies; the result warns."""
    robot, big = data["robot"], data["big"]
    doubled = big.subset(np.r_[np.arange(big.n), [0, 1]])
    res = identify_campaigns(robot, [doubled], **FAST)
    ref = identify(robot, big, **FAST)
    assert res.data.n == big.n
    assert np.allclose(res.model.theta, ref.model.theta, rtol=0, atol=1e-12)
    assert res.identifiability["repeated_rows"]["n_dropped"] == 2
    assert len(res.warnings) == 1 and "2 row(s) repeat earlier rows" in res.warnings[0]


# ----------------------------------------------------------------------------------
# The reference campaign and registrations far apart
# ----------------------------------------------------------------------------------


def test_reference_is_the_largest_unless_named(data) -> None:
    big, tiny = data["big"], data["tiny"]
    assert reference_index([big, tiny], ["big", "tiny"], None) == 0
    assert reference_index([tiny, big], ["tiny", "big"], None) == 1
    assert reference_index([big, big], ["x", "y"], None) == 1  # equally large: the last given
    assert reference_index([big, tiny], ["big", "tiny"], "tiny") == 1
    with pytest.raises(InputError, match="reference campaign 'nope': no such campaign; the campaigns are big, tiny"):
        reference_index([big, tiny], ["big", "tiny"], "nope")


def test_frame_warning_figures_and_threshold() -> None:
    row = {"name": "b", "file": "b.csv", "n_rows": 4, "n_poses": 4, "reference": False}
    near = {
        **row,
        "translation_from_reference_mm": 0.5 * FRAME_STILL_M * 1e3,
        "rotation_from_reference_deg": 0.5 * np.degrees(FRAME_STILL_RAD),
    }
    turned = {**near, "rotation_from_reference_deg": 2 * np.degrees(FRAME_STILL_RAD)}
    far = {**row, "translation_from_reference_mm": 12.5, "rotation_from_reference_deg": 3.9}
    ref = {**row, "name": "a", "reference": True, "translation_from_reference_mm": 0.0}
    assert frame_warnings([ref, near], "a") == []
    assert len(frame_warnings([ref, turned], "a")) == 1  # either figure over its threshold
    (w,) = frame_warnings([ref, far], "a")
    assert "12.500 mm and 3.900 deg from the reference campaign 'a''s" in w
    assert "rests on 4 poses" in w and "--shared registration" in w


def test_tiny_second_campaign_keeps_the_largest_as_reference(data) -> None:
    """A 4-pose campaign given last: the reference (the model's registration) stays the 40-pose one."""
    robot, big, tiny = data["robot"], data["big"], data["tiny"]
    res = identify_campaigns(robot, [big, tiny], **FAST)
    assert [c.name for c in res.model.campaigns] == ["big", "tiny"]  # the order given
    fr = {c.name: c for c in res.model.campaigns}
    assert np.allclose(res.model.base2meas(), fr["big"].base2meas, atol=1e-12)
    assert res.identifiability["campaign_fit"]["reference"] == "big"
    table = res.identifiability["campaigns"]
    assert [c["reference"] for c in table] == [True, False]
    # the same instrument: the tiny campaign's registration is close, so no warning
    assert table[1]["translation_from_reference_mm"] < FRAME_STILL_M * 1e3
    assert res.warnings == []


def test_tiny_moved_campaign_is_warned_with_figures(data) -> None:
    robot, big, tiny = data["robot"], data["big"], data["tiny_moved"]
    res = identify_campaigns(robot, [big, tiny], **FAST)
    row = res.identifiability["campaigns"][1]
    assert row["translation_from_reference_mm"] == pytest.approx(np.linalg.norm(MOVE_T_M) * 1e3, rel=0.2)
    assert row["rotation_from_reference_deg"] == pytest.approx(np.degrees(0.1), rel=0.05)
    (w,) = res.warnings
    assert f"{row['translation_from_reference_mm']:.3f} mm and {row['rotation_from_reference_deg']:.3f} deg" in w
    assert "campaign 'tiny' (tiny.csv, 4 rows, 4 poses)" in w and "reference campaign 'big'" in w
    # named by the user: the tiny campaign is the reference (the model's registration)
    named = identify_campaigns(robot, [big, tiny], reference="tiny", **FAST)
    fr = {c.name: c for c in named.model.campaigns}
    assert np.allclose(named.model.base2meas(), fr["tiny"].base2meas, atol=1e-12)
    assert named.identifiability["campaign_fit"]["reference"] == "tiny"


# ----------------------------------------------------------------------------------
# Euclidean errors
# ----------------------------------------------------------------------------------


def test_position_errors_are_euclidean() -> None:
    pred = np.zeros((3, 3))
    meas = np.array([[3e-3, 4e-3, 0.0], [0.0, 0.0, 1e-3], [0.0, 2e-3, 0.0]])
    e = position_errors(pred, meas, "some frame", np.array([7, 8, 9]))
    assert (e.n_rows, e.max_line, e.frame) == (3, 7, "some frame")
    assert e.mean_m == pytest.approx((5e-3 + 1e-3 + 2e-3) / 3)
    assert e.rms_m == pytest.approx(np.sqrt((25e-6 + 1e-6 + 4e-6) / 3))
    assert e.max_m == pytest.approx(5e-3)


def _numbers(line: str, key: str) -> list[float]:
    m = re.search(rf"{key} ([0-9.]+)(?: -> ([0-9.]+))?", line)
    assert m, (key, line)
    return [float(x) for x in m.groups() if x is not None]


def test_cli_same_file_twice_is_refused(data, tmp_path, capsys) -> None:
    path = tmp_path / "a.csv"
    path.write_text(measurements_to_csv(data["big"]))
    args = ["identify", "--robot", "ur5", "--data", str(path), "--data", str(tmp_path / "." / "a.csv")]
    assert cli_main(args + ["--out", str(tmp_path / "m.toml"), "--report", str(tmp_path / "r")]) != 0
    err = capsys.readouterr().err
    assert "compplan: error: --data" in err and "the same file as the earlier --data" in err
    assert not (tmp_path / "m.toml").exists()


def test_cli_identify_and_predict_print_the_euclidean_errors(data, tmp_path, capsys) -> None:
    big, tiny, held = data["big"], data["tiny"], data["held"]
    pa, pb, pv = tmp_path / "big.csv", tmp_path / "tiny.csv", tmp_path / "held.csv"
    # three rows measured twice to the nanometre, under other point names (a file's rows identical in every
    # column are refused by the reader): copies
    doubled = big.subset(np.r_[np.arange(big.n), [2, 3, 4]])
    doubled.t = None
    doubled.point = np.r_[doubled.point[: big.n], ["R2", "R3", "R4"]]
    pa.write_text(measurements_to_csv(doubled))
    pb.write_text(measurements_to_csv(tiny))
    pv.write_text(measurements_to_csv(held))
    out, rep = tmp_path / "m.toml", tmp_path / "rep"
    args = ["identify", "--robot", "ur5", "--data", str(pa), "--data", str(pb), "--validation", str(pv)]
    args += ["--out", str(out), "--report", str(rep), "--no-progress", "--candidates", "geometric"]
    assert cli_main(args) == 0
    cap = capsys.readouterr()
    assert f"identify: {BIG + TINY} rows" in cap.out
    assert "reference campaign: big (the campaign with the most rows, 40 rows)" in cap.out
    assert "campaign tiny" in cap.out and "deg from the reference campaign's" in cap.out
    assert "compplan: warning: 3 row(s) repeat earlier rows exactly" in cap.err and "3 in " in cap.err
    (line,) = [x for x in cap.out.splitlines() if "validation file: position error" in x]
    assert "Euclidean, mm (nominal -> identified)" in line and "12 rows" in line
    assert "measurement frame (the instrument's, via the reference campaign 'big''s identified registration)" in line
    model = load_model(out)
    d = np.linalg.norm(predict(model, held) - held.p, axis=1) * 1e3
    mean, rms, mx = _numbers(line, "mean"), _numbers(line, "RMS"), _numbers(line, "max")
    assert mean[1] == pytest.approx(d.mean(), abs=1e-4) and rms[1] == pytest.approx(np.sqrt(np.mean(d**2)), abs=1e-4)
    assert mx[1] == pytest.approx(d.max(), abs=1e-4) and mean[0] > mean[1]
    report = json.loads((rep / "report.json").read_text())
    assert report["validation"]["euclidean"]["mean_mm"] == pytest.approx(d.mean(), rel=1e-9)
    assert report["headline"]["validation_euclidean_mm"]["after"]["max"] == pytest.approx(d.max(), rel=1e-3)
    assert report["warnings"] and report["identifiability"]["repeated_rows"]["n_dropped"] == 3
    assert "## Warnings" in (rep / "report.md").read_text()

    # predict on measured rows: the same figures, in the words of the frame
    assert cli_main(["predict", "--model", str(out), "--input", str(pv), "--out", str(tmp_path / "p.csv")]) == 0
    (pline,) = [x for x in capsys.readouterr().out.splitlines() if "position error" in x]
    assert f"measured x, y, z of {pv}: position error |predicted - measured| (Euclidean, mm)" in pline
    assert _numbers(pline, "mean") == [pytest.approx(mean[1], abs=1e-4)]
    assert _numbers(pline, "RMS") == [pytest.approx(rms[1], abs=1e-4)]
    assert "reference campaign 'big'" in pline
    assert cli_main(["predict", "--model", str(out), "--input", str(pv), "--out", str(tmp_path / "p2.csv"),
                     "--campaign", "tiny"]) == 0  # fmt: skip
    assert "campaign 'tiny''s identified registration" in capsys.readouterr().out


def test_predict_without_measured_rows_prints_no_error(data, tmp_path, capsys) -> None:
    held = data["held"]
    pv = tmp_path / "q.csv"
    no_p = held.subset(np.arange(held.n))
    no_p.p = None
    pv.write_text(measurements_to_csv(no_p))
    assert cli_main(["predict", "--model", "ur5", "--input", str(pv), "--out", str(tmp_path / "p.csv")]) == 0
    assert "position error" not in capsys.readouterr().out
