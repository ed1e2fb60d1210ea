"""What the user is told is true: report figures numbered as their files, rapid moves counted as
moves, the slowed-feed warning naming the limit that binds with advice, and a G-code program that
is not UTF-8 read as documented (``docs/gcode.md``, "Frame and units")."""

from __future__ import annotations

import numpy as np
import pytest

from planner.plan import _held_feed_warning
from planner.record.record import ProgramRecord
from planner.report.rendering import FigureItem, _html_figure, figure_number
from planner.report.toolpath import rapid_move_count
from problems.toolpath.gcode import GCodeError, read_gcode


def test_a_figure_is_shown_with_the_number_of_its_file():
    assert figure_number("fig9_toolpath", 8) == 9  # figure 8 (dynamic) absent: it was "Figure 8"
    assert figure_number("fig11_cell", 3) == 11
    assert figure_number("placement_error_map.png", 2) == 2  # a name without a number: its place
    html = "".join(_html_figure(8, FigureItem("fig9_toolpath", "Toolpath", "", absent="no program")))
    assert "Figure 9. Toolpath" in html and "Figure 8" not in html


def test_rapid_moves_are_counted_as_moves_not_pieces():
    # waypoint 0; a G0 (line 2) split into 3 pieces; a cut (line 3); two G0 lines (4, 5), 2 pieces each
    rapid = np.array([False, True, True, True, False, True, True, True, True])
    line = np.array([1, 2, 2, 2, 3, 4, 4, 5, 5])
    view = ProgramRecord(np.zeros((9, 3)), line, rapid, np.full(9, np.nan))
    assert rapid_move_count(view) == 3  # counting pieces said 7


def test_the_feed_warning_names_the_limit_and_what_to_do():
    jerk = _held_feed_warning({5: (0.16, 6, "jerk"), 7: (0.2, 6, "jerk"), 9: (0.5, 2, "velocity")}, 3)
    assert "joint 6's jerk limit on 2, joint 2's velocity limit on 1" in jerk
    assert "raise those limits (j_max in the robot file or [limits] jerk, v_max" in jerk
    assert "lower F there" in jerk and "larger path tolerance (G64 P)" in jerk
    assert "slowest (peak TCP speed / F): line 5: 16 % (joint 6 jerk)" in jerk
    assert "3 more line(s) are slowed only by what surrounds them" in jerk
    assert "the joint limits" not in jerk
    velocity = _held_feed_warning({4: (0.5, 1, "velocity")}, 0)
    assert "raise that limit (v_max in the robot file or [limits] velocity), lower F there" in velocity
    assert "path tolerance" not in velocity  # a straight line's cruising speed: no corner to round


def test_a_gcode_program_that_is_not_utf8_is_read_as_latin1(tmp_path):
    ok = tmp_path / "old.ngc"
    ok.write_bytes("G21 G90\n(FR\xc4SER \xd8 6)\nG0 X0 Y0 Z5\nG1 Z0 F600\nG1 X10\n".encode("latin-1"))
    assert len(read_gcode(ok).moves) == 2
    bad = tmp_path / "bad.ngc"
    bad.write_bytes("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F600 \xe4\n".encode("latin-1"))
    with pytest.raises(GCodeError, match=r"bad.ngc:3: word"):
        read_gcode(bad)


def test_a_failed_solve_names_the_pair_its_last_iterate_comes_too_close_with():
    from problems.posture import BranchStatus
    from problems.posture.solve import _branch_verdict

    clear = ["waypoint 4: 3.2 mm inside the cell's clearance (link 3 – table 1.8 mm apart, clearance 5 mm)"]
    st, why = _branch_verdict("Infeasible_Problem_Detected", 40, clear, "analytic posture", clear)
    assert st is BranchStatus.SOLVER_FAILED
    assert why == (
        "IPOPT: Infeasible_Problem_Detected after 40 iterations; its last iterate: waypoint 4: 3.2 mm inside "
        "the cell's clearance (link 3 – table 1.8 mm apart, clearance 5 mm); the analytic posture is kept"
    )
    st, why = _branch_verdict("Maximum_Iterations_Exceeded", 3000, [], "warm start")
    assert why == "IPOPT: Maximum_Iterations_Exceeded after 3000 iterations; the warm start is kept"
