"""Long commands off a terminal print one progress line per stage on stdout (planner/progress.py)."""

from __future__ import annotations

import io
import re
import subprocess
import sys
from pathlib import Path

from planner.progress import StageLines, TqdmProgress

ROOT = Path(__file__).resolve().parents[1]
STAGE_LINE = re.compile(r"^compplan: \[ *\d+\.\d s\] (.+)$")


def test_one_line_per_stage_with_its_count_and_the_first_words_of_a_keyed_stage():
    out = io.StringIO()
    lines = StageLines(out)
    for k in range(5):
        lines("figures", k, 4, "fig")
    lines("posture", 0, 1, "stage")
    keyed = StageLines(out, key=lambda m: m.split(":")[0])
    keyed("step 1: fitting gravity", 3, 9)
    keyed("step 1: fitting joint_springs", 3, 9)
    keyed("step 2: fitting gravity", 4, 9)
    got = [STAGE_LINE.match(line).group(1) for line in out.getvalue().splitlines()]
    assert got == ["figures (4 fig)", "posture", "step 1: fitting gravity", "step 2: fitting gravity"]


def test_no_bar_and_no_line_for_a_stage_twice_off_a_terminal(capsys):
    p = TqdmProgress()  # pytest's stderr is not a terminal
    for k in range(3):
        p("compliance map", k, 2)
    p.close()
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert len(lines) == 1 and STAGE_LINE.match(lines[0]) and "compliance map (2 pt)" in lines[0]
    assert err == ""  # stderr keeps only warnings and errors


def test_a_piped_plan_says_each_stage_as_it_starts(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "planner", "plan", "ur5_tool_thrust", "--out", str(tmp_path / "o"), "--no-report"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr
    stages = [m.group(1) for m in map(STAGE_LINE.match, r.stdout.splitlines()) if m]
    assert stages[:3] == ["reading the problem", "posture", "compensation"], r.stdout
    assert any(s.startswith("timing ") for s in stages), r.stdout
    assert len(stages) == len(set(stages))
    assert "\r" not in r.stderr + r.stdout  # no bar redrawn in a log
    assert not STAGE_LINE.search(r.stderr)
