"""Measurement-file formats and whether the data fit the robot: the tracker-dif formats (a tracker
export of targets and deviations, read as it is), the unknown-column message of every format, and
identify's refusal of data in another unit (metres under ``x_mm``) or from another arm."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from models.errors import InputError
from planner.cli import main as cli_main
from problems.identify.nominal_check import NominalFit
from problems.measurements import (
    PLAUSIBLE_NOMINAL_DEVIATION_M,
    TRACKER_COLUMNS,
    TRACKER_FORMATS,
    measurements_to_csv,
    parse_measurements,
    read_measurements,
)

#: The shipped real data (docs/real-data.md), beside the checkout; tests that read it are skipped
#: without it.
REAL_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "ur5-laser-tracker"

TRACKER_HEADER = ",".join(TRACKER_COLUMNS)
#: Three rows of the shipped grid.csv (mm, deg), as written there.
TRACKER_ROWS = [
    "0,-430.32784075885013,-6.2740647628546,-98.6368469428076,-2.144122241149887,-3.5212622371454003,"
    "0.8144149428075877,-22.933297010882566,-43.71915584236375,135.39784676276338,-94.74032099477175,"
    "55.416784894781806,-5.552224723991238",
    "1,-463.68352728363686,-3.9434217627609005,-104.9310396449369,-2.072599716363129,-2.8804462372390995,"
    "-0.030132355063102523,-19.715908717115287,-45.88433417627589,127.58673648525605,-71.44195245436593,"
    "63.25406825744212,-12.680515922984348",
    "2,-401.2,50.5,-120.25,1.5,-0.75,2.0,-10.5,-50.25,120.0,-80.5,70.25,3.5",
]


def tracker_text(rows: list[str] | None = None, header: str = TRACKER_HEADER) -> str:
    return header + "\n" + "\n".join(TRACKER_ROWS if rows is None else rows) + "\n"


def cells(rows: list[str]) -> np.ndarray:
    """The rows' numbers (N, 13), as written."""
    return np.array([[float(c) for c in r.split(",")] for r in rows])


def raises(text: str, *needles: str, **kw) -> str:
    """Parse ``text`` as ``bad.csv``; the one-line error must name the file and contain ``needles``."""
    with pytest.raises(InputError) as ei:
        parse_measurements(text, "bad.csv", **kw)
    msg = str(ei.value)
    assert msg.startswith("bad.csv") and "\n" not in msg, msg
    for n in needles:
        assert n in msg, f"{n!r} not in: {msg}"
    return msg


# ------------------------------------------------------------------------------------------
# 1. reading the tracker-dif formats
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["auto", *TRACKER_FORMATS])
def test_tracker_formats_read_targets_deviations_and_degrees(fmt: str) -> None:
    m = parse_measurements(tracker_text(), "t.csv", file_format=fmt)
    v = cells(TRACKER_ROWS)
    sign = TRACKER_FORMATS["tracker-dif" if fmt == "auto" else fmt]
    assert m.file_format == ("tracker-dif" if fmt == "auto" else fmt)
    np.testing.assert_array_equal(m.q, np.radians(v[:, 7:13]))
    np.testing.assert_allclose(m.p, (v[:, 1:4] + sign * v[:, 4:7]) * 1e-3, rtol=1e-15)
    np.testing.assert_allclose(m.target, v[:, 1:4] * 1e-3, rtol=1e-15)
    assert not m.wrench.any() and m.t is None and m.point is None
    assert list(m.line) == [2, 3, 4]
    assert m.columns["q1"] == "joint_1" and m.columns["x"] == ("x_t + x_dif" if sign > 0 else "x_t - x_dif")
    # a detected format is noted (naming it and the way to declare it); a declared one is not
    assert len(m.notes) == (1 if fmt == "auto" else 0)
    if fmt == "auto":
        assert "t.csv" in m.notes[0] and "tracker-dif" in m.notes[0] and "--format" in m.notes[0]
    sub = m.subset(np.array([2, 0]))
    np.testing.assert_array_equal(sub.target, m.target[[2, 0]])
    assert sub.file_format == m.file_format


def test_tracker_file_reads_as_the_compplan_file_of_the_same_measurements(tmp_path: Path) -> None:
    """The tracker file gives the numbers a compplan file with q_deg, zero wrench and
    x_mm = target + dif gives (what benchmarks/real_ur5_tracker.py wrote before)."""
    v = cells(TRACKER_ROWS)
    head = "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx,fy,fz,mx,my,mz,x_mm,y_mm,z_mm"
    body = [
        ",".join([repr(float(x)) for x in r[7:13]] + ["0"] * 6 + [repr(float(a + b)) for a, b in zip(r[1:4], r[4:7])])
        for r in v
    ]
    (tmp_path / "c.csv").write_text(head + "\n" + "\n".join(body) + "\n")
    (tmp_path / "t.csv").write_text(tracker_text())
    a, b = read_measurements(tmp_path / "t.csv"), read_measurements(tmp_path / "c.csv")
    np.testing.assert_array_equal(a.p, b.p)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.wrench, b.wrench)


def test_tracker_file_in_the_semicolon_dialect() -> None:
    semi = tracker_text().replace(",", ";").replace(".", ",")
    m = parse_measurements(semi, "s.csv")
    ref = parse_measurements(tracker_text(), "c.csv")
    np.testing.assert_array_equal(m.p, ref.p)
    assert len(m.notes) == 2 and "';'-separated" in m.notes[0] and "tracker-dif" in m.notes[1]


def test_tracker_annotations_are_carried_and_ignored() -> None:
    m = parse_measurements(tracker_text([r + ",first" for r in TRACKER_ROWS], TRACKER_HEADER + ",note"), "n.csv")
    assert m.n == 3 and m.file_format == "tracker-dif"


# ------------------------------------------------------------------------------------------
# 2. errors of the tracker formats and the unknown-column message of every format
# ------------------------------------------------------------------------------------------


def _swap(row: int, col: int, value: str) -> list[str]:
    rows = [r.split(",") for r in TRACKER_ROWS]
    rows[row][col] = value
    return [",".join(r) for r in rows]


@pytest.mark.parametrize("fmt", list(TRACKER_FORMATS))
@pytest.mark.parametrize(
    "text, needles",
    [
        (tracker_text([r + ",1" for r in TRACKER_ROWS], TRACKER_HEADER + ",sigma"), ["unknown column 'sigma'"]),
        (tracker_text([r.rsplit(",", 1)[0] for r in TRACKER_ROWS], TRACKER_HEADER.rsplit(",", 1)[0]), ["joint_6"]),
        (tracker_text(_swap(2, 0, "0.5")), ["line 4", "step_order", "measurement order"]),
        (tracker_text(_swap(1, 5, "60")), ["line 3", "x_dif, y_dif, z_dif", "mm", "50 mm"]),
        (tracker_text(_swap(0, 8, "abc")), ["line 2", "joint_2", "abc"]),
        (tracker_text(_swap(0, 2, "")), ["line 2", "y_t", "empty"]),
    ],
    ids=["unknown", "missing", "order", "deviation", "text-cell", "empty-cell"],
)
def test_tracker_errors_name_the_file_line_and_column(fmt: str, text: str, needles: list[str]) -> None:
    msg = raises(text, *needles, file_format=fmt)
    if "unknown" in needles[0] or "joint_6" in needles:
        assert "step_order" in msg and "x_dif" in msg and "joint_1..joint_6" in msg  # the format's columns


def test_unknown_columns_list_what_every_format_expects() -> None:
    # a tracker header read as compplan: the unknown column says which format has it
    msg = raises(tracker_text(), "unknown column 'step_order'", "--format tracker-dif", file_format="compplan")
    for fmt in ("compplan", *TRACKER_FORMATS):
        assert fmt in msg
    assert "q1" in msg and "x_dif" in msg and "joint_1" in msg
    # a typo in a compplan file lists the tracker format's columns too
    head = "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz,x,y,z,temprature"
    msg = raises(head + "\n" + "0,0,0,0,0,0,0,0,0,0,0,0,0.4,0,0.5,20\n", "unknown column 'temprature'", "x_dif")
    assert "--format tracker-dif" not in msg  # no hint: 'temprature' is no tracker column
    # a partial tracker header is no tracker file under auto
    raises(tracker_text([r.split(",", 1)[1] for r in TRACKER_ROWS], TRACKER_HEADER.split(",", 1)[1]), "x_t")


@pytest.mark.parametrize(
    "kw, needles",
    [
        ({"file_format": "tracker"}, ["file format 'tracker'", "tracker-dif", "compplan"]),
        ({"file_format": "tracker-dif", "joint_names": "ros-ur"}, ["--joint-names", "compplan", "joint_1"]),
        ({"joint_names": "ros-ur"}, ["--joint-names", "tracker-dif", "joint_1"]),
    ],
)
def test_bad_format_options(kw: dict, needles: list[str]) -> None:
    with pytest.raises(InputError) as ei:
        parse_measurements(tracker_text(), "bad.csv", **kw)
    for n in needles:
        assert n in str(ei.value), str(ei.value)


# ------------------------------------------------------------------------------------------
# 3. identify: data in another unit, or from another arm
# ------------------------------------------------------------------------------------------


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
        assert n in lines[0], f"{n!r} not in {lines[0]}"
    return lines[0]


@pytest.fixture(scope="module")
def ur5_campaign():
    """A small unloaded UR5 campaign of the virtual robot (SI)."""
    from problems.virtual import simulator

    cfg = {"seed": 5, "campaign": {"poses": 40, "loaded_rows": 0}, "noise": {"sigma_m": 2e-5}}
    return simulator("ur5", cfg).campaign()


def _identify(tmp_path: Path, data: Path, robot: str, *extra: str) -> list[str]:
    return [
        "identify",
        "--robot",
        robot,
        "--data",
        str(data),
        "--out",
        str(tmp_path / "m.toml"),
        "--report",
        str(tmp_path / "rep"),
        "--no-progress",
        *extra,
    ]


@pytest.fixture
def cli_env(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path / ".cache"))
    monkeypatch.setenv("COMPPLAN_NO_COMPILER", "1")
    return tmp_path


def _write_positions(path: Path, m, suffix: str, written_in: float) -> None:
    """The campaign ``m`` with its positions written in ``written_in`` metres per number: under
    columns ``x{suffix}``.. of the compplan format, or as the targets of a tracker-dif file
    (``suffix`` "tracker", deviations zero)."""
    p = m.p / written_in
    if suffix == "tracker":
        rows = [",".join(repr(float(v)) for v in [i, *p[i], 0, 0, 0, *np.degrees(m.q[i])]) for i in range(m.n)]
        path.write_text(TRACKER_HEADER + "\n" + "\n".join(rows) + "\n")
        return
    head = "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz," + ",".join(f"{c}{suffix}" for c in "xyz")
    rows = [",".join(repr(float(v)) for v in [*m.q[i], *m.wrench[i], *p[i]]) for i in range(m.n)]
    path.write_text(head + "\n" + "\n".join(rows) + "\n")


@pytest.mark.parametrize(
    "suffix, written_in, word, columns",
    [
        ("_mm", 1.0, "metres", "x_mm, y_mm, z_mm"),
        ("_um", 1e-3, "millimetres", "x_um, y_um, z_um"),
        ("_um", 1.0, "metres", "x_um, y_um, z_um"),
        ("tracker", 1.0, "metres", "x_t, y_t, z_t, x_dif, y_dif, z_dif"),
    ],
    ids=["m-under-mm", "mm-under-um", "m-under-um", "m-in-tracker-dif"],
)
def test_positions_in_another_unit_are_named(
    suffix: str, written_in: float, word: str, columns: str, ur5_campaign, cli_env: Path, capsys
) -> None:
    """Positions written in another unit than their columns declare (metres under x_mm ...): the
    one-line error names the columns, the unit they look like and the way out."""
    data = cli_env / "d.csv"
    _write_positions(data, ur5_campaign, suffix, written_in)
    code, _out, err = run_cli(_identify(cli_env, data, "ur5"), capsys)
    fix = "write millimetres" if suffix in ("_mm", "tracker") else "write micrometres"
    one_line_error(code, err, "d.csv", f"columns {columns} look like {word}", "robot 'ur5'", fix)
    assert not (cli_env / "m.toml").exists()


def test_the_right_robot_and_unit_pass_the_check(ur5_campaign) -> None:
    """The same campaign in its declared unit, with its own robot: no refusal, no note."""
    from models import load_robot
    from problems.identify.fit_setup import setup_fit
    from problems.identify.identifiability import Known
    from problems.identify.nominal_check import check_nominal_fit

    robot, known = load_robot("ur5"), Known(False, False)
    s = setup_fit(robot, parse_measurements(measurements_to_csv(ur5_campaign), "ok.csv"), known, 5, 1, lambda *a: None)
    nf = check_nominal_fit(robot, s.prob, s.fit_b, s.theta, known, True)
    assert nf.plausible and nf.miss_m < 1e-3 and nf.notes() == []


@pytest.mark.parametrize(
    "robot, extra, needles",
    [
        ("kr6_r900", [], ["even with every DH parameter fitted"]),
        ("ur10", ["--candidates", "none"], ["--candidates", "cannot change its geometry"]),
    ],
)
def test_data_of_another_arm_are_refused(
    robot: str, extra: list[str], needles: list[str], ur5_campaign, cli_env: Path, capsys
) -> None:
    data = cli_env / "ur5.csv"
    data.write_text(measurements_to_csv(ur5_campaign))
    code, _out, err = run_cli(_identify(cli_env, data, robot, *extra), capsys)
    line = one_line_error(
        code,
        err,
        "ur5.csv",
        f"the measured points do not fit robot '{robot}'",
        "median distance",
        f"expected < {PLAUSIBLE_NOMINAL_DEVIATION_M * 1e3:g} mm",
        "is --robot right?",
        *needles,
    )
    miss = float(line.split("median distance ")[1].split(" mm")[0])
    assert miss > PLAUSIBLE_NOMINAL_DEVIATION_M * 1e3
    assert not (cli_env / "m.toml").exists() and not (cli_env / "rep").exists()


@pytest.mark.parametrize(
    "miss_dh, needles",
    [
        (None, ["cannot change its geometry"]),
        (0.2, ["200 mm even with every DH parameter fitted"]),
        (1e-4, ["fit only with DH corrections", "0.1 mm"]),
    ],
)
def test_refusal_says_why_nothing_fits(miss_dh: float | None, needles: list[str]) -> None:
    nf = NominalFit("d.csv", "ur10", "registration and measured point fitted", 0.115, miss_dh)
    assert not nf.plausible
    msg = nf.refusal()
    for n in ["d.csv", "robot 'ur10'", "median distance 115 mm", "expected < 50 mm", "is --robot right?", *needles]:
        assert n in msg, msg
    # a run that goes on (DH corrections fit) carries a note; one that fits has none
    assert bool(nf.notes()) == (miss_dh is not None and miss_dh < PLAUSIBLE_NOMINAL_DEVIATION_M)
    assert NominalFit("d.csv", "ur5", "", 0.002).notes() == []


# ------------------------------------------------------------------------------------------
# 4. the shipped real data
# ------------------------------------------------------------------------------------------

needs_real_data = pytest.mark.skipif(not (REAL_DATA / "grid.csv").is_file(), reason=f"no {REAL_DATA}")


@needs_real_data
def test_the_shipped_tracker_files_read_as_they_are() -> None:
    for name, n in (("grid.csv", 1000), ("random.csv", 20)):
        m = read_measurements(REAL_DATA / name)
        assert m.n == n and m.file_format == "tracker-dif" and len(m.notes) == 1
        dif = (m.p - m.target) * 1e3
        assert 0.1 < np.median(np.linalg.norm(dif, axis=1)) < 10.0  # millimetres from the nominal: a UR5's


@needs_real_data
def test_the_shipped_targets_are_the_ur5_nominal_kinematics() -> None:
    """The file's targets against each robot's nominal FK: the UR5's to micrometres (measured point
    31 mm along the flange z), another arm's not."""
    from models import load_robot
    from problems.identify.nominal_check import TARGET_AGREE_RMS_M, target_note

    m = read_measurements(REAL_DATA / "random.csv")
    note = target_note(load_robot("ur5"), m)
    assert "are the nominal forward kinematics of robot 'ur5'" in note and "31.000) mm" in note, note
    rms_mm = float(note.split("joints (")[1].split(" mm")[0])
    assert rms_mm < TARGET_AGREE_RMS_M * 1e3
    note = target_note(load_robot("ar5"), m)
    assert "differ from the nominal forward kinematics of robot 'ar5'" in note and "--robot" in note, note


@needs_real_data
def test_the_shipped_data_under_another_arm_is_one_line(cli_env: Path, capsys) -> None:
    """Every 25th pose of grid.csv (a tracker file, auto-detected) identified with the UR10 file:
    a median miss of more than 50 mm, refused in one line."""
    lines = (REAL_DATA / "grid.csv").read_text().splitlines()
    data = cli_env / "excerpt.csv"
    data.write_text("\n".join([lines[0], *lines[1::25]]) + "\n")
    code, _out, err = run_cli(_identify(cli_env, data, "ur10"), capsys)
    one_line_error(code, err, "excerpt.csv", "do not fit robot 'ur10'", "median distance", "is --robot right?")
    assert math.isfinite(float(err.split("median distance ")[1].split(" mm")[0]))
