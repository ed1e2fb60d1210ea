"""``compplan problem list | show NAME [--program]`` (issue 24: the shipped problems listed and printed
as ``compplan robot`` does for robots)."""

from __future__ import annotations

import numpy as np

from planner.cli import main
from problems.problem import load_problem, shipped_problems


def test_list_names_every_shipped_problem_with_its_robot(capsys):
    assert main(["problem", "list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines] == list(shipped_problems())
    row = next(ln for ln in lines if ln.startswith("milling_pocket"))
    assert "ur10" in row and "gcode (milling_pocket.ngc)" in row


def test_show_prints_a_file_that_plans_as_the_shipped_one(tmp_path, capsys):
    capsys.readouterr()
    assert main(["problem", "show", "milling_pocket"]) == 0
    out = capsys.readouterr()
    assert "--program > milling_pocket.ngc" in out.err
    (tmp_path / "my.toml").write_text(out.out)
    assert main(["problem", "show", "milling_pocket", "--program"]) == 0
    (tmp_path / "milling_pocket.ngc").write_text(capsys.readouterr().out)
    mine, shipped = load_problem(tmp_path / "my.toml"), load_problem("milling_pocket")
    assert mine.n == shipped.n
    np.testing.assert_array_equal(mine.positions, shipped.positions)


def test_an_unknown_problem_is_the_users_error(capsys):
    assert main(["problem", "show", "nope"]) == 2
    err = capsys.readouterr().err
    assert "'nope' is not a shipped problem" in err and "machining_offaxis" in err and "Traceback" not in err
    assert main(["problem", "show", "paper_4_4", "--program"]) == 2
    assert "has no program path" in capsys.readouterr().err


def test_verbose_is_accepted_after_the_sub_command(capsys):
    """Issue 24: ``compplan plan P --out D -v`` said "unrecognized arguments: -v"."""
    from planner.cli import build_parser

    p = build_parser()
    assert p.parse_args(["robot", "list", "-v"]).verbose is True
    assert p.parse_args(["-v", "robot", "list"]).verbose is True
    assert p.parse_args(["robot", "list"]).verbose is False
    assert p.parse_args(["plan", "paper_4_4", "--out", "x", "--verbose"]).verbose is True
    assert main(["problem", "list", "-v"]) == 0
