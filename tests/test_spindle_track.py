"""The spindle along a G-code program (issue 35): S and M3/M4/M5 per move, LinuxCNC's order (a
line's S and M words act before its motion), modal."""

from __future__ import annotations

import math

import numpy as np
import pytest

from problems.toolpath.gcode import parse_gcode
from problems.toolpath.spindle import spindle_track
from problems.toolpath.waypoints import program_waypoints

RPM = 2.0 * math.pi / 60.0


def _track(text: str):
    prog = parse_gcode(text, name="t.ngc")
    return prog, spindle_track(prog)


def test_speed_and_turning_per_move_are_modal_and_act_before_the_lines_motion():
    prog, t = _track(
        "G21 G90\nG0 X0 Y0 Z5\nS8000 M3\nG1 X10 F600\nG1 X20 S9000\nM4\nG1 X30\nM5\nG0 Z10\nG1 X40 S100 M3\n"
    )
    assert prog.n_moves == 5  # the first G0 names X, Y and Z: it is the start, not a move
    np.testing.assert_allclose(t.speed_rad_s / RPM, [8000, 9000, 9000, 9000, 100])
    assert t.sense.tolist() == [1, 1, -1, 0, 1]
    assert t.s_line.tolist() == [3, 5, 5, 5, 10] and t.m_line.tolist() == [3, 3, 6, 8, 10]


def test_a_program_without_spindle_words_has_speed_zero_and_no_turning():
    _, t = _track("G21 G90\nG0 X0 Y0 Z5\nG1 X10 F600\n")
    assert not t.speed_rad_s.any() and not t.sense.any()


def test_waypoints_carry_their_move_and_the_track():
    prog = parse_gcode("G21 G90\nG0 X0 Y0 Z5\nS6000 M4\nG1 X7 F600\nG1 Y7\n", name="t.ngc")
    w = program_waypoints(prog)
    assert w.move[0] == -1 and set(w.move[1:].tolist()) == {0, 1}
    k = np.maximum(w.move, 0)
    assert np.all(w.spindle.sense[k][w.move >= 0] == -1)
    assert w.spindle.speed_rad_s[k][-1] == pytest.approx(6000 * RPM)
