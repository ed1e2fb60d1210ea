"""Measurement files: units by suffix, validation errors (one line naming file, row,
column, value, expectation), round trip; data that cannot support the fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models import load_robot
from models.errors import CompplanError, InputError
from problems.identify import DataError, identify
from problems.measurements import (
    Measurements,
    measurements_to_csv,
    parse_measurements,
    read_measurements,
)
from problems.virtual import VirtualRobot

HEADER = "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz,x,y,z"
ROW = "0.1,-1.2,1.3,-0.5,-1.5,0.2,0,0,-50,0,0,0,0.40,0.11,0.52"
ROW2 = "0.2,-1.1,1.2,-0.6,-1.4,0.3,10,0,0,0,0,0,0.41,0.12,0.51"


def _one_line(msg: str) -> None:
    assert "\n" not in msg


def test_plain_names_are_si_and_suffixes_convert() -> None:
    text = (
        "# a comment line\n"
        "point,q1_deg,q2,q3,q4,q5,q6,fx_N,fy,fz,mx_Nmm,my,mz,x_mm,y_mm,z_mm,t_ms,temperature_C,sigma_um\n"
        "P1,90,-1.2,1.3,-0.5,-1.5,0.2,0,0,-50,1000,0,0,400,110,520,0,21.5,20\n"
        "P1,90,-1.2,1.3,-0.5,-1.5,0.2,10,0,-50,0,0,0,401,111,521,1500,21.6,20\n"
    )
    m = parse_measurements(text, "f.csv")
    assert m.n == 2
    assert m.q[0, 0] == pytest.approx(math.pi / 2)
    assert m.wrench[0, 3] == pytest.approx(1.0)
    assert m.p[0] == pytest.approx([0.4, 0.11, 0.52])
    assert m.t[1] == pytest.approx(1.5)
    assert m.sigma[0] == pytest.approx(2e-5)
    assert m.temperature[1] == pytest.approx(21.6)
    assert list(m.point) == ["P1", "P1"]
    assert list(m.line) == [3, 4]


def test_round_trip(tmp_path) -> None:
    m = parse_measurements(f"{HEADER},t\n{ROW},0\n{ROW2},1\n", "f.csv")
    for mm in (False, True):
        p = tmp_path / f"m{mm}.csv"
        p.write_text(measurements_to_csv(m, mm=mm))
        m2 = read_measurements(p)
        assert np.allclose(m2.p, m.p) and np.allclose(m2.q, m.q) and np.allclose(m2.wrench, m.wrench)


@pytest.mark.parametrize(
    "text, needle",
    [
        (f"q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz,x,y\n{ROW[:-5]}", "missing required column(s) z"),
        (f"{HEADER},x_mm\n{ROW},400", "column 'x' is given twice"),
        (f"{HEADER}\n{ROW.replace('0.40', 'nan')}", "line 2, column 'x': value nan is not finite"),
        (f"{HEADER}\n{ROW.replace('0.40', 'inf')}", "column 'x': value inf is not finite"),
        (f"{HEADER}\n{ROW.replace('0.40', '')}", "line 2, column 'x': empty cell"),
        (f"{HEADER}\n{ROW.replace('0.40', 'abc')}", "'abc' is not a number"),
        (f"{HEADER}\n{ROW.replace('0.40', '400')}", "x_mm"),
        (f"{HEADER}\n{ROW.replace('0.1,', '90,', 1)}", "q1_deg"),
        (f"{HEADER}\n{ROW}\n{ROW}", "lines 2 and 3 are identical"),
        (f"{HEADER},t\n{ROW},5\n{ROW2},4", "earlier than the previous row"),
        (f"{HEADER},temprature\n{ROW},20", "unknown column 'temprature'"),
        (f"{HEADER},temperature\n{ROW},2000", "outside the plausible range"),
        (f"{HEADER},sigma\n{ROW},0", "expected a standard deviation > 0"),
        (f"{HEADER}\n{ROW},1", "16 cells, expected 15"),
        (f"{HEADER}\n", "no measurement rows"),
        ("q1,q2,q3,q4,q5,q6,fx,fy,fz,x,y,z\n0,0,0,0,0,0,0,0,0,0.1,0.1,0.1", "missing required column(s) mx, my, mz"),
    ],
)
def test_bad_files_raise_one_line_input_errors(text: str, needle: str) -> None:
    with pytest.raises(InputError) as ei:
        parse_measurements(text, "bad.csv")
    msg = str(ei.value)
    assert needle in msg and msg.startswith("bad.csv")
    _one_line(msg)
    assert isinstance(ei.value, CompplanError)


def test_missing_file() -> None:
    with pytest.raises(InputError, match="no such measurement file"):
        read_measurements("/nonexistent/data.csv")


def test_command_file_without_positions() -> None:
    m = parse_measurements(
        "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz\n0,0,0,0,0,0,0,0,0,0,0,0\n", "in.csv", require_position=False
    )
    assert m.p is None and m.n == 1


def test_extra_annotation_columns_are_ignored() -> None:
    m = parse_measurements(f"{HEADER},note\n{ROW},first pose\n", "f.csv")
    assert m.n == 1


def _sim(poses: int, **extra) -> tuple[VirtualRobot, Measurements]:
    cfg = {"campaign": {"poses": poses}, "noise": {"sigma_m": 2e-5}, **extra}
    vr = VirtualRobot(load_robot("ur5"), cfg, seed=3)
    return vr, vr.campaign()


def test_too_few_poses_names_the_unidentifiable_parameters() -> None:
    _vr, m = _sim(2)
    with pytest.raises(DataError, match="at least 3 poses"):
        identify(load_robot("ur5"), m)


def test_included_effect_the_data_cannot_identify_is_an_error() -> None:
    # all-zero wrench: an included load effect cannot be identified -- named, not silently held
    _vr, m = _sim(12, campaign={"poses": 12, "loaded_rows": 0})
    with pytest.raises(DataError) as ei:
        identify(load_robot("ur5"), m, include=["load_offset"], candidates=[])
    assert "load_offset.r_tool" in str(ei.value)
    _one_line(str(ei.value))


def test_zero_wrench_self_weight_only_runs() -> None:
    """Real-data situation: absolute data, no load varies, self-weight only."""
    _vr, m = _sim(60, campaign={"poses": 60, "loaded_rows": 0, "unloaded_rows": 1}, effects={"gravity": {}})
    assert not m.load_varies()
    res = identify(load_robot("ur5"), m)
    assert any("stiffness is held" in n for n in res.notes)
    assert "gravity" in res.effects_added
    assert res.cv_rms_after_m < 1.5 * 2e-5
