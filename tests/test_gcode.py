"""G-code reader (problems.toolpath.gcode): arcs against an analytic reference, units, modal state,
drilling cycles, refused words and bad files."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.errors import InputError
from problems.toolpath.arcs import CENTER_ARC_RADIUS_TOLERANCE_MM_M, Plane
from problems.toolpath.gcode import (
    Direction,
    EventKind,
    GCodeError,
    MoveKind,
    discretise,
    parse_gcode,
    read_gcode,
)

#: Points of an exact arc lie on the analytic circle within this (m).
ON_CIRCLE_TOL = 1e-12
#: Chord sagitta tolerance used in the tests (m).
SAG_TOL = 1e-5
#: Exactly representable conversions compare to this (m).
EXACT_TOL = 1e-15

_AXIS = {"X": 0, "Y": 1, "Z": 2}


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues rotation matrix about the unit ``axis`` (independent reference for the arcs)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def _check_arc(pts: np.ndarray, centre, normal, r: float, start, sweep: float, travel: float) -> None:
    """Every chord end on the analytic helix ``centre + R(n, θ)(start - centre) + n·travel·θ/sweep``,
    in order, and every chord's sagitta within SAG_TOL."""
    centre, normal, start = np.asarray(centre), np.asarray(normal, dtype=float), np.asarray(start)
    rel = pts - centre
    h = rel @ normal
    inplane = rel - np.outer(h, normal)
    np.testing.assert_allclose(np.linalg.norm(inplane, axis=1), r, rtol=0, atol=ON_CIRCLE_TOL)
    v0 = start - centre
    ang = np.unwrap(np.concatenate([[0.0], [math.atan2(np.cross(v0, p) @ normal, v0 @ p) for p in inplane]]))
    assert np.all(np.diff(ang) * np.sign(sweep) > 0)
    assert ang[-1] == pytest.approx(sweep, abs=1e-12)
    for a, p, hh in zip(ang[1:], inplane, h):
        np.testing.assert_allclose(p, _rot(normal, a) @ v0, atol=ON_CIRCLE_TOL)
        assert hh == pytest.approx(travel * a / sweep, abs=ON_CIRCLE_TOL)
    step = np.abs(np.diff(ang))
    assert np.all(r * (1 - np.cos(step / 2)) <= SAG_TOL * (1 + 1e-9))


def _arc_points(text: str) -> tuple:
    prog = parse_gcode(text)
    pts, line, rapid, feed = discretise(prog, SAG_TOL)
    arc = next(m for m in prog.moves if m.kind is MoveKind.ARC)
    k = np.flatnonzero(line == arc.line)
    return prog, arc, pts[k], pts


def test_ijk_incremental_quarter_cw():
    prog, arc, pts, _ = _arc_points("G21 G17 G90\nG0 X10 Y0 Z0\nG2 X0 Y-10 I-10 J0 F600\n")
    assert arc.direction is Direction.CW and arc.plane is Plane.XY
    assert arc.sweep_rad == pytest.approx(-math.pi / 2, abs=1e-15)
    np.testing.assert_array_equal(pts[-1], [0.0, -0.01, 0.0])
    _check_arc(pts, (0, 0, 0), (0, 0, 1), 0.01, (0.01, 0, 0), -math.pi / 2, 0.0)


def test_ijk_absolute_g90_1_same_arc():
    a = _arc_points("G0 X10 Y0 Z0\nG2 X0 Y-10 I-10 J0 F600\n")[2]
    b = _arc_points("G90.1\nG0 X10 Y0 Z0\nG2 X0 Y-10 I0 J0 F600\n")[2]
    np.testing.assert_allclose(a, b, atol=ON_CIRCLE_TOL)
    c = _arc_points("G90.1\nG91.1\nG0 X10 Y0 Z0\nG2 X0 Y-10 I-10 F600\n")[2]  # missing J is 0
    np.testing.assert_allclose(a, c, atol=ON_CIRCLE_TOL)


@pytest.mark.parametrize(
    ("code", "radius", "centre_y", "sweep"),
    [
        ("G2", 10, -math.sqrt(75), -math.pi / 3),
        ("G2", -10, math.sqrt(75), -(2 * math.pi - math.pi / 3)),
        ("G3", 10, math.sqrt(75), math.pi / 3),
        ("G3", -10, -math.sqrt(75), 2 * math.pi - math.pi / 3),
    ],
)
def test_r_form_sign_rule(code, radius, centre_y, sweep):
    prog, arc, pts, _ = _arc_points(f"G0 X0 Y0 Z1\n{code} X10 Y0 R{radius} F100\n")
    assert arc.centre == pytest.approx((0.005, centre_y * 1e-3, 0.001), abs=1e-15)
    assert arc.sweep_rad == pytest.approx(sweep, abs=1e-12)
    np.testing.assert_array_equal(pts[-1], [0.01, 0.0, 0.001])
    _check_arc(pts, arc.centre, (0, 0, 1), 0.01, (0, 0, 0.001), sweep, 0.0)


def test_r_form_half_circle_and_errors():
    prog, arc, pts, _ = _arc_points("G0 X0 Y0 Z0\nG3 X10 Y0 R5 F100\n")
    assert arc.sweep_rad == pytest.approx(math.pi, abs=1e-12)
    _check_arc(pts, (0.005, 0, 0), (0, 0, 1), 0.005, (0, 0, 0), math.pi, 0.0)
    with pytest.raises(GCodeError, match=r"<string>:2: word 'R4': radius 4 mm is too small"):
        parse_gcode("G0 X0 Y0 Z0\nG3 X10 Y0 R4 F100\n")
    with pytest.raises(GCodeError, match=r"<string>:2: word 'R5':.*needs an end point in the plane"):
        parse_gcode("G0 X0 Y0 Z0\nG3 R5 F100\n")


@pytest.mark.parametrize(
    ("plane", "a", "b", "n", "la", "lb"),
    [("G17", "X", "Y", "Z", "I", "J"), ("G18", "Z", "X", "Y", "K", "I"), ("G19", "Y", "Z", "X", "J", "K")],
)
def test_three_planes_ccw_about_the_normal(plane, a, b, n, la, lb):
    # start at (a=10, b=0), G3 a quarter to (a=0, b=10): counter-clockwise about +normal
    text = f"{plane}\nG0 {a}10 {b}0 {n}2\nG3 {a}0 {b}10 {la}-10 {lb}0 F300\n"
    prog, arc, pts, _ = _arc_points(text)
    normal = np.zeros(3)
    normal[_AXIS[n]] = 1.0
    start = np.zeros(3)
    start[_AXIS[a]], start[_AXIS[n]] = 0.01, 0.002
    centre = np.zeros(3)
    centre[_AXIS[n]] = 0.002
    assert arc.plane is Plane(int(plane[1:]))
    _check_arc(pts, centre, normal, 0.01, start, math.pi / 2, 0.0)
    end = np.zeros(3)
    end[_AXIS[b]], end[_AXIS[n]] = 0.01, 0.002
    np.testing.assert_array_equal(pts[-1], end)


def test_offset_of_another_plane_refused():
    with pytest.raises(GCodeError, match=r"<string>:2: word 'K1': not an offset of the G17 plane"):
        parse_gcode("G0 X0 Y0 Z0\nG2 X1 Y1 I1 K1 F100\n")


@pytest.mark.parametrize("plane", ["G17", "G18", "G19"])
def test_helical_arc(plane):
    a, b, n = {"G17": "XYZ", "G18": "ZXY", "G19": "YZX"}[plane]
    la = {"G17": "I", "G18": "K", "G19": "J"}[plane]
    prog, arc, pts, _ = _arc_points(f"{plane}\nG0 {a}10 {b}0 {n}0\nG3 {a}-10 {b}0 {n}-5 {la}-10 P2 F300\n")
    normal = np.zeros(3)
    normal[_AXIS[n]] = 1.0
    start = np.zeros(3)
    start[_AXIS[a]] = 0.01
    assert arc.turns == 2 and arc.helical_m == pytest.approx(-0.005, abs=EXACT_TOL)
    assert arc.sweep_rad == pytest.approx(3 * math.pi, abs=1e-12)
    _check_arc(pts, (0, 0, 0), normal, 0.01, start, 3 * math.pi, -0.005)


@pytest.mark.parametrize(("p", "turns"), [("", 1), ("P3", 3)])
def test_full_circle(p, turns):
    prog, arc, pts, _ = _arc_points(f"G0 X10 Y0 Z0\nG2 I-10 {p} F600\n")
    assert arc.sweep_rad == pytest.approx(-2 * math.pi * turns, abs=1e-12)
    np.testing.assert_array_equal(pts[-1], [0.01, 0, 0])
    _check_arc(pts, (0, 0, 0), (0, 0, 1), 0.01, (0.01, 0, 0), -2 * math.pi * turns, 0.0)
    with pytest.raises(GCodeError, match="full circle"):
        parse_gcode("G0 X10 Y0 Z0\nG2 X10 Y0 R10 F600\n")


def test_radius_mismatch_is_an_error_within_tolerance_is_accepted():
    with pytest.raises(GCodeError, match=r"<string>:2: word 'I5': the radius to the end .* differs"):
        parse_gcode("G0 X0 Y0 Z0\nG2 X10 Y1 I5 F100\n")
    prog = parse_gcode("G0 X0 Y0 Z0\nG2 X10 Y0.02 I5 F100\n")  # end radius 0.04 µm off: a spiral
    assert abs(math.hypot(5, 0.02) - 5) * 1e-3 < CENTER_ARC_RADIUS_TOLERANCE_MM_M
    pts, *_ = discretise(prog, SAG_TOL)
    np.testing.assert_array_equal(pts[-1], [0.01, 0.00002, 0])  # the programmed end, exactly
    with pytest.raises(GCodeError, match="zero-radius arc"):
        parse_gcode("G0 X0 Y0 Z0\nG2 X0 Y0 I0 J0.0001 F100\n")


def test_inches():
    prog = parse_gcode("G20\nG0 X1 Y2 Z3\nG1 X4 F10\nG2 X5 Y3 R1\n")
    assert prog.units == "inch" and prog.units_note == ""
    assert prog.start_m == (0.0254, 0.0508, 0.0762)
    m = prog.moves[0]
    assert m.end == (4 * 0.0254, 0.0508, 0.0762)
    assert m.feed_m_s == pytest.approx(10 * 0.0254 / 60, rel=1e-15)
    assert prog.moves[1].radius_m == pytest.approx(0.0254, abs=EXACT_TOL)
    # switching to mm mid-program keeps the position and the physical feed (as LinuxCNC does)
    prog = parse_gcode("G20 G0 X1 Y0 Z0\nG21 G1 X30 F1000\nG1 X40\n")
    assert prog.units == "mm and inch"
    assert prog.moves[0].start[0] == 0.0254 and prog.moves[0].end[0] == pytest.approx(0.030, abs=EXACT_TOL)


def test_no_units_word_means_millimetres_with_a_note():
    prog = parse_gcode("G0 X1 Y2 Z3\nG1 X2 F600\n")
    assert prog.units == "mm" and prog.units_note == "no G20/G21: millimetres"
    assert prog.moves[0].feed_m_s == pytest.approx(0.01, rel=1e-15)  # 600 mm/min = 10 mm/s


def test_modal_motion_and_axis_words():
    prog = parse_gcode("G0 X0 Y0 Z5\nG1 Z-1 F300\nX10\nY5\nG0 Z5\nX0 Y0\n")
    kinds = [m.kind for m in prog.moves]
    assert kinds == [MoveKind.LINEAR] * 3 + [MoveKind.RAPID] * 2
    assert [m.end for m in prog.moves] == [
        (0, 0, -0.001),
        (0.01, 0, -0.001),
        (0.01, 0.005, -0.001),
        (0.01, 0.005, 0.005),
        (0, 0, 0.005),
    ]
    assert [m.line for m in prog.moves] == [2, 3, 4, 5, 6]
    assert prog.moves[2].text == "Y5"
    assert prog.moves[3].feed_m_s is None and prog.moves[2].feed_m_s == pytest.approx(0.005)


def test_incremental_g91():
    prog = parse_gcode("G90 G0 X1 Y1 Z1\nG91 G1 X1 F60\nX1 Y-2\nG90 X0\n")
    assert [m.end for m in prog.moves] == [
        pytest.approx((0.002, 0.001, 0.001)),
        pytest.approx((0.003, -0.001, 0.001)),
        pytest.approx((0.0, -0.001, 0.001)),
    ]


def test_start_is_where_xyz_become_known():
    prog = parse_gcode("G0 Z50\nG0 X1 Y2\nG1 Z0 F100\n")
    assert prog.start_m == (0.001, 0.002, 0.05) and prog.start_line == 2
    assert len(prog.moves) == 1
    with pytest.raises(GCodeError, match=r"<string>:2: word 'G1': the start of this feed move is unknown \(XY"):
        parse_gcode("G0 Z5\nG1 Z0 F100\n")


def test_comments_n_numbers_block_delete_percent():
    text = "%\n(header (no nesting)\nN10 G0 X1 (move) Y2 Z3 ; the rest ( is ignored\n/N20 g1 x 4 f 6 0 0\n\n%\n"
    with pytest.raises(GCodeError, match="nested comment"):
        parse_gcode(text)
    prog = parse_gcode(text.replace("(header (no nesting)", "(header)"))
    assert prog.start_m == (0.001, 0.002, 0.003)
    assert prog.moves[0].end == (0.004, 0.002, 0.003) and prog.moves[0].line == 4
    assert prog.moves[0].feed_m_s == pytest.approx(0.01)


def test_events_and_recorded_words():
    prog = parse_gcode(
        "G21 G40 G49 G80 G94 G17 G54 G98\nT3 M6\nG43 H3\nS12000 M3\nG64 P0.02\nG0 X0 Y0 Z5\n"
        "G1 Z0 F100\nG4 P1.5\nG61\nG1 X1\nG64\nM5\nM30\nG1 X99\n"
    )
    assert [w.word for w in prog.words] == ["T3", "M6", "H3", "S12000", "M3", "M5", "M30"]
    assert prog.words[3].value == 12000 and prog.words[3].line == 4
    kinds = [(e.kind, e.line, e.after_move, e.value) for e in prog.events]
    assert kinds == [
        (EventKind.BLENDING, 5, 0, pytest.approx(2e-5)),
        (EventKind.DWELL, 8, 1, 1.5),
        (EventKind.EXACT_STOP, 9, 1, None),
        (EventKind.BLENDING, 11, 2, None),
        (EventKind.PROGRAM_END, 13, 2, None),
    ]
    assert prog.path_tolerance_m == pytest.approx(2e-5) and prog.work_offset == "G54"
    assert prog.end_line == 13 and len(prog.moves) == 2  # nothing after M30


@pytest.mark.parametrize(
    ("line", "word", "what"),
    [
        ("G41 D1", "G41", "cutter radius compensation"),
        ("G42", "G42", "cutter radius compensation"),
        ("G28", "G28", "stored position"),
        ("G30", "G30", "stored position"),
        ("G92 X0", "G92", "coordinate offsets"),
        ("G93", "G93", "G94"),
        ("G53 G0 X0", "G53", "machine coordinates"),
        ("G73 X0 Y0 Z-1 R1 Q1", "G73", "canned cycle is not supported"),
        ("G5.1 X1 Y1 I1 J1", "G5.1", "splines"),
        ("G0 A10", "A10", "rotary and extra axes"),
        ("G17.1", "G17.1", "not in the supported G-code subset"),
        ("O100 sub", "O100", "o-words"),
        ("o<sub> call", "O<SUB>", "o-words"),
        ("G0 X#1", "X#1", "parameters"),
        ("G0 X[1+2]", "X[1+2]", "expressions"),
        ("G0 X1.2.3", ".3", "unexpected character"),
        ("G0 X", "X", "not followed by a number"),
        ("G0 X1 X2", "X2", "two X words"),
        ("G0 G1 X1", "G1", "two motion codes"),
        ("M98 P100", "M98", "subprogram"),
        ("G0 X1 I2", "I2", "no G code on the line uses it"),
        ("G1 X1", "G1", "a feed move before any F word"),
        ("G2 X1 Y1 F100", "G2", "needs its centre"),
        ("G2 X1 Y1 I1 R1 F100", "R1", "both R and I/J/K"),
        ("G80\nX1", "X1", "no motion mode"),
        ("G55 G0 X1", "G55", "a second work offset"),
    ],
)
def test_refused_words_name_file_line_and_word(line, word, what):
    text = f"G54 G0 X0 Y0 Z0\n{line}\n"
    k = 2 + line.count("\n")
    with pytest.raises(GCodeError) as exc:
        parse_gcode(text, name="part.ngc")
    msg = str(exc.value)
    assert msg.startswith(f"part.ngc:{k}: word '{word}'"), msg
    assert what in msg
    assert isinstance(exc.value, InputError)


def test_g81_g98_g99():
    base = "G0 X0 Y0 Z10\nG1 F120\n"
    prog = parse_gcode(base + "G98 G81 X5 Y0 Z-3 R2\nX10\nG80\n")
    ends = [(m.kind, tuple(round(v * 1e3, 9) for v in m.end)) for m in prog.moves]
    R, L = MoveKind.RAPID, MoveKind.LINEAR
    assert ends == [
        (R, (5, 0, 10)), (R, (5, 0, 2)), (L, (5, 0, -3)), (R, (5, 0, 10)),
        (R, (10, 0, 10)), (R, (10, 0, 2)), (L, (10, 0, -3)), (R, (10, 0, 10)),
    ]  # fmt: skip
    assert {m.cycle for m in prog.moves} == {"G81"}
    assert prog.moves[2].feed_m_s == pytest.approx(0.002)
    prog = parse_gcode(base + "G99 G81 X5 Y0 Z-3 R2\nX10\n")
    ends = [tuple(round(v * 1e3, 9) for v in m.end) for m in prog.moves]
    assert ends == [(5, 0, 10), (5, 0, 2), (5, 0, -3), (5, 0, 2), (10, 0, 2), (10, 0, -3), (10, 0, 2)]


def test_g91_cycle_repeats_and_g82_dwell_and_g83_pecks():
    prog = parse_gcode("G0 X0 Y0 Z5\nG91 G99 G82 X10 Z-4 R-3 P0.5 L2 F60\n")
    ends = [tuple(round(v * 1e3, 9) for v in m.end) for m in prog.moves]
    # R = 5 - 3 = 2, bottom = 2 - 4 = -2, holes at X10 and X20, retract to R (G99)
    assert ends == [(10, 0, 5), (10, 0, 2), (10, 0, -2), (10, 0, 2), (20, 0, 2), (20, 0, -2), (20, 0, 2)]
    assert [e.value for e in prog.events if e.kind is EventKind.DWELL] == [0.5, 0.5]
    prog = parse_gcode("G0 X0 Y0 Z5\nG83 X1 Y1 Z-7 R1 Q3 F60\n")
    ends = [(m.kind.value, round(m.end[2] * 1e3, 9)) for m in prog.moves]
    assert ends == [
        ("rapid", 5), ("rapid", 1), ("linear", -2), ("rapid", 1), ("rapid", -1), ("linear", -5),
        ("rapid", 1), ("rapid", -4), ("linear", -7), ("rapid", 5),
    ]  # fmt: skip
    with pytest.raises(GCodeError, match=r"<string>:2: word 'G83': G83 needs its peck depth"):
        parse_gcode("G0 X0 Y0 Z5\nG83 X1 Y1 Z-7 R1 F60\n")
    with pytest.raises(GCodeError, match="G17"):
        parse_gcode("G0 X0 Y0 Z5\nG18 G81 X1 Z-7 R1 F60\n")


def test_empty_and_binary_files(tmp_path):
    empty = tmp_path / "empty.ngc"
    empty.write_text("(only a comment)\n%\n")
    with pytest.raises(GCodeError, match=r"empty.ngc: no moves"):
        read_gcode(empty)
    binary = tmp_path / "b.ngc"
    binary.write_bytes(b"G0 X1\x00\x01\x02")
    with pytest.raises(GCodeError, match="binary"):
        read_gcode(binary)
    with pytest.raises(GCodeError, match="cannot read"):
        read_gcode(tmp_path / "missing.ngc")
    good = tmp_path / "ok.ngc"
    good.write_text("G0 X0 Y0 Z0\r\nG1 X1 F100\r\n")
    assert read_gcode(good).moves[0].line == 2


def test_discretise_keeps_move_ends_and_marks_rapids():
    prog = parse_gcode("G0 X0 Y0 Z1\nG1 Z0 F600\nG2 X10 Y0 I5\nG0 Z5\n")
    pts, line, rapid, feed = discretise(prog, SAG_TOL)
    assert len(pts) == len(line) == len(rapid) == len(feed)
    for m in prog.moves:
        k = np.flatnonzero(line == m.line)[-1]
        np.testing.assert_array_equal(pts[k], m.end)
    assert rapid[0] and rapid[-1] and not rapid[1:-1].any()
    assert np.isnan(feed[rapid]).all() and np.allclose(feed[~rapid], 0.01)
    with pytest.raises(InputError, match="must be > 0"):
        discretise(prog, 0.0)


def test_scale_1e5_lines():
    n = 100_000
    xs = np.round(np.sin(np.arange(1, n + 1) * 1e-3) * 50, 3)
    text = "G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F1200\n" + "\n".join(f"G1 X{x:.3f} Y{k * 0.001:.3f}" for k, x in enumerate(xs))
    prog = parse_gcode(text)
    assert prog.n_moves == n + 1
    pts, line, rapid, feed = discretise(prog, SAG_TOL)
    assert pts.shape == (n + 2, 3) and line[-1] == n + 3 and not rapid[1:].any()
