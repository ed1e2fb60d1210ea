"""Measurement files as tracker software exports them: per-axis standard deviations, the
';'-separated decimal-comma dialect, date-times in ``t``, ROS joint names; and the CLI
options ``--csv-dialect`` / ``--joint-names`` of identify, predict and compensate."""

from __future__ import annotations

import datetime as dt
import math
import re
from pathlib import Path

import numpy as np
import pytest

from models.errors import InputError
from planner.cli import main as cli_main
from problems.measurements import (
    JOINT_NAME_PRESETS,
    Measurements,
    measurements_to_csv,
    parse_measurements,
    read_measurements,
    resolve_joint_names,
)

HEADER = "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz,x_mm,y_mm,z_mm"
ROWS = [
    "0.1,-1.2,1.3,-0.5,-1.5,0.2,0,0,-50,0,0,0,400.125,110.5,520.25",
    "0.2,-1.1,1.2,-0.6,-1.4,0.3,10,0,0,0,0,0,410.3,120.7,510.1",
    "0.3,-1.0,1.1,-0.7,-1.3,0.4,0,10,0,0,0,0,420.9,130.2,500.4",
]
ROS_UR = JOINT_NAME_PRESETS["ros-ur"]


def table(header: str, rows: list[str], extra_header: str = "", extra: list[str] | None = None) -> str:
    """Comma-dialect text with optional extra columns (one cell string per row)."""
    h = header + ("," + extra_header if extra_header else "")
    body = [r + ("," + e if extra_header else "") for r, e in zip(rows, extra or [""] * len(rows))]
    return h + "\n" + "\n".join(body) + "\n"


def to_semicolon(text: str) -> str:
    """The same table as a ';' export with decimal commas (comment lines kept as they are)."""
    out = []
    for ln in text.splitlines():
        out.append(ln if ln.startswith("#") else ln.replace(",", ";").replace(".", ","))
    return "\n".join(out) + "\n"


def raises(text: str, *needles: str, **kw) -> str:
    """Parse ``text`` as ``bad.csv``; the one-line error must start with the file and contain ``needles``."""
    with pytest.raises(InputError) as ei:
        parse_measurements(text, "bad.csv", **kw)
    msg = str(ei.value)
    assert msg.startswith("bad.csv"), msg
    assert "\n" not in msg
    for n in needles:
        assert n in msg, f"{n!r} not in: {msg}"
    return msg


# ------------------------------------------------------------------------------------------
# 1. per-axis standard deviations
# ------------------------------------------------------------------------------------------


def test_sigma_per_axis_with_units_and_rms() -> None:
    m = parse_measurements(
        table(HEADER, ROWS, "sigma_x_um,sigma_y_um,sigma_z_mm", ["10,20,0.03", "10,10,0.01", "5,5,0.005"]), "f.csv"
    )
    assert m.sigma_xyz.shape == (3, 3)
    assert m.sigma_xyz[0] == pytest.approx([1e-5, 2e-5, 3e-5])
    assert m.sigma.shape == (3,)
    assert m.sigma[0] == pytest.approx(math.sqrt((1e-10 + 4e-10 + 9e-10) / 3))
    assert m.sigma[2] == pytest.approx(5e-6)
    assert m.sigma_rot is None
    assert m.columns["sigma_z"] == "sigma_z_mm"


def test_single_sigma_is_broadcast_to_the_axes() -> None:
    m = parse_measurements(table(HEADER, ROWS, "sigma_um", ["10", "20", "30"]), "f.csv")
    assert m.sigma == pytest.approx([1e-5, 2e-5, 3e-5])
    assert np.array_equal(m.sigma_xyz, np.repeat(m.sigma[:, None], 3, axis=1))
    # the same filling for a table built in memory
    mem = Measurements(q=np.zeros((2, 6)), wrench=np.zeros((2, 6)), sigma=np.array([1e-5, 2e-5]))
    assert mem.sigma_xyz.shape == (2, 3)
    mem2 = Measurements(q=np.zeros((1, 6)), wrench=np.zeros((1, 6)), sigma_xyz=np.array([[1e-5, 1e-5, 4e-5]]))
    assert mem2.sigma == pytest.approx([math.sqrt(18e-10 / 3)])


def test_rotation_sigmas() -> None:
    rot = ["0.01,0.02,0.03", "0.02,0.03,0.04", "0.03,0.04,0.05"]
    m = parse_measurements(
        table(HEADER, ROWS, "rx,ry,rz,sigma_rx_urad,sigma_ry_mrad,sigma_rz_deg", [r + ",50,0.05,0.01" for r in rot]),
        "f.csv",
    )
    assert m.sigma_rot[0] == pytest.approx([5e-5, 5e-5, math.radians(0.01)])
    m = parse_measurements(table(HEADER, ROWS, "rx,ry,rz,sigma_r", [r + ",1e-4" for r in rot]), "f.csv")
    assert np.array_equal(m.sigma_rot, np.full((3, 3), 1e-4))
    assert m.sigma is None and m.sigma_xyz is None


ROT = "rx,ry,rz"
ROTV = ["0.01,0.02,0.03", "0.02,0.03,0.04", "0.03,0.04,0.05"]


@pytest.mark.parametrize(
    "extra_header, extra, needles",
    [
        ("sigma,sigma_x,sigma_y,sigma_z", ["1e-5,1e-5,1e-5,1e-5"] * 3, ["'sigma'", "'sigma_x'", "both"]),
        ("sigma_mm,sigma_x_um,sigma_y_um,sigma_z_um", ["0.01,1,1,1"] * 3, ["'sigma_mm'", "'sigma_x_um'"]),
        ("sigma_x,sigma_y", ["1e-5,1e-5"] * 3, ["sigma_x, sigma_y, sigma_z", "go together"]),
        (
            "sigma_x,sigma_y,sigma_z",
            ["1e-5,0,1e-5", "1e-5,1e-5,1e-5", "1e-5,1e-5,1e-5"],
            ["line 2", "column 'sigma_y'", "value 0", "> 0"],
        ),
        (
            "sigma_x_mm,sigma_y_mm,sigma_z_mm",
            ["0.01,0.01,0.01", "0.01,0.01,-0.02", "0.01,0.01,0.01"],
            ["line 3", "column 'sigma_z_mm'", "-0.02", "> 0"],
        ),
        (
            "sigma_x,sigma_y,sigma_z",
            ["1e-5,1e-5,1e-5", "1e-5,1e-5,1e-5", "0.02,1e-5,1e-5"],
            ["line 4", "column 'sigma_x'", "0.02", "implausible", "sigma_x_mm"],
        ),
        ("sigma_r", ["1e-4"] * 3, ["sigma_r", "rx, ry, rz"]),
        ("sigma_rx,sigma_ry,sigma_rz", ["1e-4,1e-4,1e-4"] * 3, ["sigma_rx, sigma_ry, sigma_rz", "rx, ry, rz"]),
        (
            ROT + ",sigma_r,sigma_rx,sigma_ry,sigma_rz",
            [r + ",1e-4,1e-4,1e-4,1e-4" for r in ROTV],
            ["'sigma_r'", "'sigma_rx'", "both"],
        ),
        (ROT + ",sigma_rx,sigma_ry", [r + ",1e-4,1e-4" for r in ROTV], ["go together"]),
        (ROT + ",sigma_r_deg", [r + ",10" for r in ROTV], ["line 2", "column 'sigma_r_deg'", "10", "implausible"]),
        (
            ROT + ",sigma_rx,sigma_ry,sigma_rz",
            [r + ",1e-4,1e-4,0.5" for r in ROTV],
            ["line 2", "column 'sigma_rz'", "0.5", "implausible"],
        ),
        (ROT + ",sigma_r_urad", [r + ",-3" for r in ROTV], ["line 2", "column 'sigma_r_urad'", "-3", "> 0"]),
    ],
)
def test_sigma_errors(extra_header: str, extra: list[str], needles: list[str]) -> None:
    raises(table(HEADER, ROWS, extra_header, extra), *needles)


def test_small_angle_units_are_not_joint_units() -> None:
    # q-columns keep their units (messages elsewhere quote them as deg or rad)
    m = parse_measurements(
        table(HEADER.replace("q1,", "q1_deg,"), [r.replace("0.1,", "5.7,", 1) for r in ROWS]), "f.csv"
    )
    assert m.q[0, 0] == pytest.approx(math.radians(5.7))
    raises(table(HEADER.replace("q1,", "q1_mrad,"), ROWS), "unknown column 'q1_mrad'")


def test_subset_and_csv_round_trip_carry_the_sigmas(tmp_path: Path) -> None:
    text = table(
        HEADER,
        ROWS,
        "rx,ry,rz,t,sigma_x,sigma_y,sigma_z,sigma_rx,sigma_ry,sigma_rz",
        [r + f",{i},1e-5,2e-5,3.5e-5,1e-4,2e-4,3e-4" for i, r in enumerate(ROTV)],
    )
    m = parse_measurements(text, "f.csv")
    s = m.subset(np.array([0, 2]))
    assert np.array_equal(s.sigma_xyz, m.sigma_xyz[[0, 2]])
    assert np.array_equal(s.sigma_rot, m.sigma_rot[[0, 2]])
    assert np.array_equal(s.sigma, m.sigma[[0, 2]])
    p = tmp_path / "rt.csv"
    p.write_text(measurements_to_csv(m))
    m2 = read_measurements(p)
    for a in ("q", "wrench", "p", "rotation", "t", "sigma_xyz", "sigma_rot", "sigma"):
        assert np.array_equal(getattr(m2, a), getattr(m, a)), a
    # a single sigma stays a single column; the mm variant round-trips to rounding
    m3 = parse_measurements(table(HEADER, ROWS, "sigma", ["1e-5", "2e-5", "3e-5"]), "f.csv")
    assert "sigma_x" not in measurements_to_csv(m3).splitlines()[0]
    p.write_text(measurements_to_csv(m, mm=True))
    m4 = read_measurements(p)
    assert np.allclose(m4.sigma_xyz, m.sigma_xyz, rtol=1e-12, atol=0)


# ------------------------------------------------------------------------------------------
# 2. dialects
# ------------------------------------------------------------------------------------------

COMMA = "# exported by the tracker\n" + table(
    HEADER, ROWS, "t_ms,sigma_um,temperature", ["0,12.5,21.25", "1500.5,12.5,21.3", "3000.25,7.75,21.375"]
)


def test_semicolon_export_reads_bit_identical_to_the_comma_file() -> None:
    a = parse_measurements(COMMA, "a.csv")
    b = parse_measurements(to_semicolon(COMMA), "b.csv")
    c = parse_measurements(to_semicolon(COMMA), "c.csv", dialect="semicolon")
    for name in ("q", "wrench", "p", "t", "sigma", "sigma_xyz", "temperature", "line"):
        va, vb, vc = getattr(a, name), getattr(b, name), getattr(c, name)
        assert va.tobytes() == vb.tobytes() == vc.tobytes(), name
    assert a.notes == [] and c.notes == []
    assert len(b.notes) == 1
    assert b.notes[0].startswith(
        "b.csv: read as ';'-separated with decimal commas (detected from the header line; declare --csv-dialect"
    )


def test_semicolon_dialect_reads_plain_points_and_notes_a_mix() -> None:
    text = to_semicolon(COMMA).replace("400,125", "400.125")
    m = parse_measurements(text, "f.csv", dialect="semicolon")
    assert m.p[0, 0] == pytest.approx(0.400125)
    assert len(m.notes) == 1 and "1 a decimal point" in m.notes[0]
    auto = parse_measurements(text, "f.csv")
    assert "1 cell(s) written with a decimal point" in auto.notes[0]


@pytest.mark.parametrize(
    "old, new, needles",
    [
        ("400,125", "1.400,125", ["line 3", "column 'x_mm'", "'1.400,125'", "both '.' and ','", "thousands"]),
        ("400,125", "1,400,125", ["line 3", "column 'x_mm'", "'1,400,125'", "more than one ','"]),
        (
            "400,125",
            "1 400,125",
            ["line 3", "column 'x_mm'", "'1 400,125'", "not a number", "thousands", "decimal comma"],
        ),
        ("410,3", "vier", ["line 4", "column 'x_mm'", "'vier'", "not a number", "expected a decimal number"]),
        ("410,3", "", ["line 4", "column 'x_mm'", "empty cell"]),
        ("410,3", "nan", ["line 4", "column 'x_mm'", "nan", "not finite"]),
    ],
)
def test_semicolon_bad_cells(old: str, new: str, needles: list[str]) -> None:
    text = to_semicolon(COMMA)
    assert old in text
    raises(text.replace(old, new, 1), *needles)


@pytest.mark.parametrize(
    "old, new, needles",
    [
        ("400.125", "1_400.125", ["line 3", "column 'x_mm'", "'1_400.125'", "not a number", "thousands"]),
        ("400.125", '"400,125"', ["line 3", "column 'x_mm'", "'400,125'", "decimal comma"]),
        ("400.125", "0x1f", ["line 3", "column 'x_mm'", "'0x1f'", "not a number", "expected a decimal number"]),
    ],
)
def test_comma_bad_cells(old: str, new: str, needles: list[str]) -> None:
    raises(COMMA.replace(old, new, 1), *needles)


def test_dialect_mismatch_and_ambiguity() -> None:
    semi = to_semicolon(COMMA)
    raises(semi, "line 2", "';'-separated", "--csv-dialect semicolon", dialect="comma")
    raises(COMMA, "line 2", "','-separated", "--csv-dialect comma", dialect="semicolon")
    ambiguous = COMMA.replace("q1,q2,q3", "q1;q2;q3", 1)
    raises(ambiguous, "line 2", "both ',' and ';'", "--csv-dialect")
    with pytest.raises(InputError, match="CSV dialect 'excel': expected one of auto, comma, semicolon"):
        parse_measurements(COMMA, "f.csv", dialect="excel")
    # a tab export is still refused under auto
    raises(COMMA.replace(",", "\t"), "tab")


# ------------------------------------------------------------------------------------------
# 3. date-times in t
# ------------------------------------------------------------------------------------------


def _times(cells: list[str], col: str = "t", **kw) -> Measurements:
    return parse_measurements(table(HEADER, ROWS, col, cells), "f.csv", **kw)


@pytest.mark.parametrize(
    "cells, expect",
    [
        (["2024-05-03T10:15:02.125", "2024-05-03T10:15:03", "2024-05-03T10:16:02.5"], [0.0, 0.875, 60.375]),
        (["2024-05-03 10:15:02", "2024-05-03 10:15:02", "2024-05-04 10:15:02"], [0.0, 0.0, 86400.0]),
        (["2024-05-03T10:15:02Z", "2024-05-03T12:15:03+02:00", "2024-05-03T10:15:04.25+00:00"], [0.0, 1.0, 2.25]),
        (["2024-12-31T23:59:59.9", "2025-01-01T00:00:00.1", "2025-01-01 00:00:01"], [0.0, 0.2, 1.1]),
    ],
)
def test_date_times_become_seconds_since_the_first_row(cells: list[str], expect: list[float]) -> None:
    m = _times(cells)
    assert m.t == pytest.approx(expect, abs=1e-9)
    assert m.t_origin is not None and m.t_origin.year in (2024,)
    assert any("column 't' read as date-times" in n for n in m.notes)


def test_date_times_with_decimal_comma_in_the_semicolon_dialect() -> None:
    text = to_semicolon(table(HEADER, ROWS, "t", ["2024-05-03 10:15:02", "2024-05-03 10:15:03", "2024-05-03 10:15:04"]))
    text = text.replace("10:15:03", "10:15:03,125")
    m = parse_measurements(text, "f.csv")
    assert m.t == pytest.approx([0.0, 1.125, 2.0])
    assert m.t_origin == dt.datetime(2024, 5, 3, 10, 15, 2)
    assert len(m.notes) == 2


@pytest.mark.parametrize(
    "col, cells, needles",
    [
        (
            "t",
            ["2024-05-03T10:15:02", "5", "2024-05-03T10:15:04"],
            ["line 3", "column 't'", "'5'", "line 2", "date-time"],
        ),
        ("t", ["0", "2024-05-03T10:15:03", "7"], ["line 3", "column 't'", "'2024-05-03T10:15:03'", "number"]),
        (
            "t_ms",
            ["2024-05-03T10:15:02", "2024-05-03T10:15:03", "2024-05-03T10:15:04"],
            ["line 2", "column 't_ms'", "date-time", "'t'"],
        ),
        (
            "t",
            ["2024-05-03T10:15:02", "2024-05-03T10:15:01", "2024-05-03T10:15:04"],
            ["line 3", "column 't'", "'2024-05-03T10:15:01'", "earlier", "line 2"],
        ),
        (
            "t",
            ["2024-05-03T10:15:02Z", "2024-05-03T10:15:03", "2024-05-03T10:15:04Z"],
            ["line 3", "column 't'", "time zone"],
        ),
        (
            "t",
            ["2024-05-03T10:15:02", "2024-13-03T10:15:03", "2024-05-03T10:15:04"],
            ["line 3", "column 't'", "'2024-13-03T10:15:03'", "not a valid date-time"],
        ),
        (
            "t",
            ["2024-05-03T10:15:02", "yesterday", "2024-05-03T10:15:04"],
            ["line 3", "column 't'", "'yesterday'", "neither a date-time"],
        ),
    ],
)
def test_date_time_errors(col: str, cells: list[str], needles: list[str]) -> None:
    raises(table(HEADER, ROWS, col, cells), *needles)


def test_numeric_times_keep_their_units() -> None:
    m = _times(["0", "1.5", "3"], col="t_min")
    assert m.t == pytest.approx([0.0, 90.0, 180.0]) and m.t_origin is None and m.notes == []


# ------------------------------------------------------------------------------------------
# 4. joint names
# ------------------------------------------------------------------------------------------


def _ros_header(names: tuple[str, ...] | list[str], suffix: str = "") -> str:
    return HEADER.replace("q1,q2,q3,q4,q5,q6", ",".join(n + suffix for n in names))


def test_ros_ur_preset() -> None:
    plain = parse_measurements(table(HEADER, ROWS), "f.csv")
    m = parse_measurements(table(_ros_header(ROS_UR), ROWS), "f.csv", joint_names="ros-ur")
    assert m.q.tobytes() == plain.q.tobytes()
    assert m.columns["q1"] == "shoulder_pan_joint"
    assert len(m.notes) == 1 and "preset 'ros-ur'" in m.notes[0] and "wrist_3_joint = q6" in m.notes[0]
    deg = [
        ",".join(f"{math.degrees(float(v))!r}" for v in r.split(",")[:6]) + "," + ",".join(r.split(",")[6:])
        for r in ROWS
    ]
    m = parse_measurements(table(_ros_header(ROS_UR, "_deg"), deg), "f.csv", joint_names="ros-ur")
    assert m.q == pytest.approx(plain.q, abs=1e-12)
    assert "shoulder_pan_joint_deg = q1" in m.notes[0]


@pytest.mark.parametrize("spec", [["j1", "j2", "j3", "j4", "j5", "j6"], "j1,j2,j3,j4,j5,j6", " j1, j2 ,j3,j4,j5,j6 "])
def test_explicit_joint_names(spec) -> None:
    plain = parse_measurements(table(HEADER, ROWS), "f.csv")
    m = parse_measurements(table(_ros_header([f"j{i}" for i in range(1, 7)]), ROWS), "f.csv", joint_names=spec)
    assert m.q.tobytes() == plain.q.tobytes()
    assert "joint names given" in m.notes[0]


def test_explicit_joint_names_keep_the_order() -> None:
    names = ["j6", "j5", "j4", "j3", "j2", "j1"]  # the file's 'j6' is joint 1
    m = parse_measurements(table(_ros_header([f"j{i}" for i in range(1, 7)]), ROWS), "f.csv", joint_names=names)
    plain = parse_measurements(table(HEADER, ROWS), "f.csv")
    assert np.array_equal(m.q, plain.q[:, ::-1])


def test_joint_name_errors() -> None:
    ros = table(_ros_header(ROS_UR), ROWS)
    # ROS names without the option: the unknown column suggests the preset
    raises(ros, "unknown column 'shoulder_pan_joint'", "--joint-names ros-ur")
    raises(table(_ros_header(ROS_UR, "_deg"), ROWS), "unknown column 'shoulder_pan_joint_deg'", "--joint-names ros-ur")
    # a mapped column missing: named, with the header
    missing = table(_ros_header(ROS_UR).replace("elbow_joint", "elbow"), ROWS)
    raises(missing, "unknown column 'elbow'", joint_names="ros-ur")
    short = "\n".join(",".join(ln.split(",")[:2] + ln.split(",")[3:]) for ln in ros.splitlines()) + "\n"
    raises(
        short, "missing required column(s) elbow_joint", "header on line 1: shoulder_pan_joint,", joint_names="ros-ur"
    )
    raises(
        table(HEADER, ROWS),
        "missing required column(s) shoulder_pan_joint",
        "header on line 1: q1, q2",
        joint_names="ros-ur",
    )
    both = table(_ros_header(ROS_UR), ROWS, "q1", ["0.1", "0.2", "0.3"])
    raises(
        both, "column(s) q1 besides the joint columns", "shoulder_pan_joint, shoulder_lift_joint", joint_names="ros-ur"
    )
    raises(
        table(HEADER, ROWS),
        "missing required column(s) shoulder_pan_joint",
        "the file has q1, q2",
        joint_names="ros-ur",
    )


@pytest.mark.parametrize(
    "spec, needle",
    [
        ("ros", "expected a preset (ros-ur)"),
        ("a,b,c", "3 name(s); expected six"),
        (["a", "b", "c", "d", "e", "a"], "'a' is given for joints 1 and 6"),
        ("a,b,,d,e,f", "name 3 is empty"),
        ("a,b,fx,d,e,f", "'fx' (joint 3) is the name of another column"),
        ("q2,q1,c,d,e,f", "'q2' (joint 1)"),
        ("a,b,c,x_mm,e,f", "'x_mm' (joint 4) is the name of another column"),
        ("q1_deg,b,c,d,e,f", "'q1_deg' (joint 1)"),
        ("a,b,c,d,e,point", "'point' (joint 6)"),
        ("a,a_deg,c,d,e,f", "'a_deg' reads as 'a' with a unit suffix"),
    ],
)
def test_bad_joint_name_options(spec, needle: str) -> None:
    with pytest.raises(InputError) as ei:
        resolve_joint_names(spec)
    assert needle in str(ei.value)
    with pytest.raises(InputError):
        parse_measurements(table(HEADER, ROWS), "f.csv", joint_names=spec)


def test_joint_names_none_means_q() -> None:
    assert resolve_joint_names(None) is None and resolve_joint_names("none") is None
    assert resolve_joint_names("ros-ur") == ROS_UR
    assert resolve_joint_names("q1,q2,q3,q4,q5,q6") == tuple(f"q{i}" for i in range(1, 7))


# ------------------------------------------------------------------------------------------
# 6. the documentation's examples parse
# ------------------------------------------------------------------------------------------


def test_documented_examples_parse() -> None:
    doc = Path(__file__).resolve().parents[1] / "docs" / "measurement-file.md"
    blocks = re.findall(r"```csv\n(.*?)```", doc.read_text(encoding="utf-8"), re.S)
    assert len(blocks) >= 2
    dialects = set()
    for b in blocks:
        m = parse_measurements(b, "doc.csv")
        dialects.add(bool(m.notes))
    assert dialects == {False, True}
    semi = parse_measurements(blocks[1], "doc.csv")
    assert semi.t[1] == pytest.approx(25.125) and semi.sigma_xyz[0] == pytest.approx([8e-6, 8e-6, 15e-6])


# ------------------------------------------------------------------------------------------
# 5. the CLI
# ------------------------------------------------------------------------------------------

CMD_HEADER = "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz"
CMD_ROWS = ["0.1,-1.2,1.4,-0.5,-1.5,0.3,0,0,-50,0,0,0", "0.2,-1.1,1.3,-0.6,-1.4,0.2,20,0,0,0,0,0"]
CMDS = CMD_HEADER + "\n" + "\n".join(CMD_ROWS) + "\n"


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    try:
        code = cli_main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code if isinstance(exc.code, int) else 2
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(code: int, err: str, *needles: str) -> str:
    assert code == 2, err
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("compplan: error: "), err
    for n in needles:
        assert n.lower() in lines[0].lower(), f"{n!r} not in {lines[0]}"
    return lines[0]


@pytest.fixture
def cli_env(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path / ".cache"))
    monkeypatch.setenv("COMPPLAN_NO_COMPILER", "1")
    (tmp_path / "c.csv").write_text(CMDS)
    (tmp_path / "semi.csv").write_text(to_semicolon(CMDS))
    (tmp_path / "ros.csv").write_text(to_semicolon(CMDS).replace("q1;q2;q3;q4;q5;q6", ";".join(ROS_UR)))
    return tmp_path


@pytest.mark.parametrize(
    "argv, needles",
    [
        (
            "predict --model ur5 --input {t}/c.csv --out {t}/o.csv --csv-dialect excel",
            ["--csv-dialect", "excel", "auto", "semicolon"],
        ),
        (
            "compensate --model ur5 --input {t}/semi.csv --out {t}/o.csv --csv-dialect comma",
            ["semi.csv", "';'-separated", "--csv-dialect semicolon"],
        ),
        (
            "predict --model ur5 --input {t}/c.csv --out {t}/o.csv --csv-dialect semicolon",
            ["c.csv", "','-separated", "--csv-dialect comma"],
        ),
        (
            "predict --model ur5 --input {t}/c.csv --out {t}/o.csv --joint-names a,b",
            ["--joint-names", "2 name(s)", "six"],
        ),
        (
            "compensate --model ur5 --input {t}/c.csv --out {t}/o.csv --joint-names rosur",
            ["--joint-names", "rosur", "ros-ur"],
        ),
        (
            "predict --model ur5 --input {t}/ros.csv --out {t}/o.csv",
            ["ros.csv", "shoulder_pan_joint", "--joint-names ros-ur"],
        ),
        (
            "compensate --model ur5 --input {t}/c.csv --out {t}/o.csv --joint-names ros-ur",
            ["c.csv", "missing required column(s) shoulder_pan_joint"],
        ),
        (
            "identify --robot ur5 --data {t}/d.csv --out {t}/m.toml --report {t}/rep --csv-dialect comma",
            ["d.csv", "';'"],
        ),
        (
            "identify --robot ur5 --data {t}/amb.csv --out {t}/m.toml --report {t}/rep",
            ["amb.csv", "both ',' and ';'", "--csv-dialect"],
        ),
        (
            "identify --robot ur5 --data {t}/pos.csv --out {t}/m.toml --report {t}/rep --joint-names a,b,c,d,e,f",
            ["pos.csv", "missing required column(s) a, b, c, d, e, f"],
        ),
    ],
)
def test_cli_bad_options_and_mismatches(argv: str, needles: list[str], cli_env: Path, capsys) -> None:
    (cli_env / "d.csv").write_text(to_semicolon(table(HEADER, ROWS)))
    (cli_env / "pos.csv").write_text(table(HEADER, ROWS))
    (cli_env / "amb.csv").write_text(table(HEADER, ROWS).replace("q1,q2", "q1;q2", 1))
    code, _out, err = run_cli(argv.format(t=cli_env).split(), capsys)
    one_line_error(code, err, *needles)
    assert not (cli_env / "o.csv").exists() and not (cli_env / "m.toml").exists()


def test_cli_reads_a_ros_semicolon_export_like_the_plain_file(cli_env: Path, capsys) -> None:
    code, _out, err = run_cli(f"predict --model ur5 --input {cli_env}/c.csv --out {cli_env}/o1.csv".split(), capsys)
    assert code == 0 and "c.csv" not in err, err
    code, out, err = run_cli(
        f"predict --model ur5 --input {cli_env}/ros.csv --out {cli_env}/o2.csv --joint-names ros-ur".split(), capsys
    )
    assert code == 0, err
    assert (cli_env / "o1.csv").read_bytes() == (cli_env / "o2.csv").read_bytes()
    assert all(ln.startswith("compplan: note: ") for ln in err.splitlines() if ln.strip()), err
    notes = [ln for ln in err.splitlines() if "ros.csv" in ln]  # (not the compiler's note)
    assert len(notes) == 2, err
    assert "read as ';'-separated with decimal commas" in notes[0]
    assert "preset 'ros-ur'" in notes[1]
    assert "note" not in out
    code, _out, err = run_cli(
        f"compensate --model ur5 --input {cli_env}/ros.csv --out {cli_env}/o3.csv "
        "--joint-names ros-ur --csv-dialect semicolon".split(),
        capsys,
    )
    assert code == 0, err
    notes = [ln for ln in err.splitlines() if ln.startswith("compplan: note: ") and "ros.csv" in ln]
    assert len(notes) == 1 and "ros-ur" in notes[0]  # declared dialect: no detection note
