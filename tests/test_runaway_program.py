"""A runaway program is refused from its moves alone, before any point is made of it, with its own
reason: its feed moves' time at the programmed feeds against the trajectory sample cap at dt."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import problems.toolpath.waypoints as waypoints_mod
from models.errors import InputError
from problems.problem import load_problem
from problems.timing.registry import MAX_TRAJECTORY_SAMPLES
from problems.toolpath.gcode import parse_gcode
from problems.toolpath.program import feed_seconds

ROOT = Path(__file__).resolve().parents[1]

PROBLEM = """\
name = "runaway"
[robot]
model = "ur10"
[path]
kind = "{kind}"
file = "{file}"
[workpiece]
xyz = [0.6, 0.0, 0.1]
[wrench]
force = [0.0, 0.0, 0.0]
[timing]
dt = {dt}
"""


def _problem(tmp_path: Path, program: str, name: str = "p.ngc", dt: float = 0.002) -> Path:
    (tmp_path / name).write_text(program)
    p = tmp_path / "p.toml"
    kind = "gcode" if name.endswith(".ngc") else "toolpath_csv"
    p.write_text(PROBLEM.format(kind=kind, file=name, dt=dt))
    return p


def _helix(turns: int) -> str:
    pitch = 50.0 / turns  # 50 mm down over all turns: within reach whatever the count
    return f"G21 G90 G17\nG0 X10 Y0 Z5\nG1 Z0 F600\nG2 X10 Y0 Z-{pitch * turns:g} I-10 J0 P{turns} F600\nG0 Z5\nM30\n"


def test_the_feed_time_of_a_helix_is_its_length_over_its_feed():
    prog = parse_gcode(_helix(7), "h.ngc")
    seconds, k = feed_seconds(prog)
    helix = ((2 * 3.141592653589793 * 10.0 * 7) ** 2 + 50.0**2) ** 0.5  # mm, independent of the reader
    assert prog.moves[k].line == 4
    assert seconds == pytest.approx((helix + 5.0) / 10.0, rel=1e-9)  # + the 5 mm plunge, both at 10 mm/s


def test_a_20000_turn_helix_is_refused_before_it_becomes_points(tmp_path, monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("the program was made into points before it was refused")

    monkeypatch.setattr(waypoints_mod, "discretise_moves", never)
    with pytest.raises(InputError) as exc:
        load_problem(_problem(tmp_path, _helix(20000)))
    msg = str(exc.value)
    assert "p.ngc" in msg and "line 4" in msg and "P20000" in msg and "h at their programmed feeds" in msg
    assert f"{MAX_TRAJECTORY_SAMPLES}" in msg and "dt = 0.002 s" in msg
    assert "wrong unit" not in msg  # not the advice of the joint limits' check


def test_the_same_program_is_accepted_with_a_feasible_turn_count(tmp_path):
    assert load_problem(_problem(tmp_path, _helix(3))).n > 10


def test_a_long_cl_file_is_refused_too(tmp_path, monkeypatch):
    monkeypatch.setattr(waypoints_mod, "_refine", lambda *a, **k: pytest.fail("made into points"))
    rows = ["x_mm,y_mm,z_mm,feed_mm_min"] + [f"{10 * (k % 2)},0,0,1" for k in range(400)]  # 4 m at 1 mm/min
    p = _problem(tmp_path, "\n".join(rows) + "\n", name="p.csv")
    with pytest.raises(InputError, match=r"p\.csv: the program's feed moves last 66\.5 h"):
        load_problem(p)


def test_the_command_line_refuses_it_in_one_line(tmp_path):
    p = _problem(tmp_path, _helix(20000))
    r = subprocess.run(
        [sys.executable, "-m", "planner", "plan", str(p), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("compplan: error: ")
    assert not (tmp_path / "out").exists()
