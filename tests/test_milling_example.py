"""The shipped milling example: ``problems/files/milling_pocket.ngc`` (made by
``benchmarks/make_milling_program.py``) and the problem ``milling_pocket`` that runs it.

* the generator is deterministic and the shipped program is its output, byte for byte;
* the program reads (``read_gcode``) into the operations the generator writes: its moves, arcs,
  helical arcs, full circles and drilling cycles counted;
* the shipped problem loads by name, the program found next to it, with its 10^4+ waypoints placed
  by the workpiece frame.

No plan here (a plan of its ~30 200 waypoints takes 10-25 s); parsing and loading are fast.
"""

from __future__ import annotations

import collections
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from problems.problem import load_problem, shipped_problems
from problems.toolpath.gcode import read_gcode
from problems.toolpath.program import Direction, EventKind, MoveKind

ROOT = Path(__file__).resolve().parents[1]
GENERATOR = ROOT / "benchmarks" / "make_milling_program.py"
PROGRAM = ROOT / "problems" / "files" / "milling_pocket.ngc"


def _generator():
    spec = importlib.util.spec_from_file_location("make_milling_program", GENERATOR)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def program():
    return read_gcode(PROGRAM)


def test_generator_is_deterministic_and_made_the_shipped_program():
    gen = _generator()
    text = gen.generate()
    assert gen.generate() == text
    assert text.encode("ascii") == PROGRAM.read_bytes(), (
        "problems/files/milling_pocket.ngc differs from the generator's output: "
        "run PYTHONPATH=. python benchmarks/make_milling_program.py"
    )
    assert gen.main(["--check"]) == 0


def test_program_has_the_operations_the_generator_writes(program):
    moves = program.moves
    plain = [m for m in moves if m.cycle is None]
    kinds = collections.Counter(m.kind for m in plain)
    assert kinds == {MoveKind.LINEAR: 9259, MoveKind.ARC: 478, MoveKind.RAPID: 106}
    # about 10^4 moves: the G0/G1/G2/G3 moves and the drilling-cycle holes
    holes = {c: len({m.line for m in moves if m.cycle == c}) for c in ("G81", "G82", "G83")}
    assert holes == {"G81": 2, "G82": 1, "G83": 4}
    assert 9_000 <= len(plain) + sum(holes.values()) <= 11_000

    arcs = [m for m in plain if m.kind is MoveKind.ARC]
    full = [m for m in arcs if math.isclose(abs(m.sweep_rad), 2 * math.pi, abs_tol=1e-9)]
    helical = [m for m in arcs if m.helical_m != 0.0]
    # pocket: 12 levels x 5 helical half turns (G2, 3 deg ramp) + 8 boss levels x 1 helical full circle
    assert len(helical) == 68 and all(m.direction is Direction.CW and m.helical_m < 0 for m in helical)
    assert sum(1 for m in helical if m in full) == 8
    # full circles: 12 pocket ramp floors, 8 x 3 in the boss recess, 2 finishing the boss and the recess
    assert len(full) == 38
    assert sum(1 for m in arcs if m.direction is Direction.CW) == 101
    # the pocket's corner radii (tool centre): 5.75, 3.25 and the 2 mm smoothing of the inner passes
    radii = collections.Counter(round(m.radius_m * 1e3, 3) for m in arcs)
    assert radii[5.75] == radii[3.25] == 48 and radii[2.0] == 242

    # G83 pecks Q3 to Z-25 from R2: 9 pecks a hole, each down, up to R and back near the last depth
    assert sum(1 for m in moves if m.cycle == "G83") == 123
    deepest = min(m.end[2] for m in moves if m.cycle == "G83")
    assert deepest == pytest.approx(-0.025, abs=1e-12)

    feeds = {round(m.feed_m_s * 60e3) for m in moves if m.feed_m_s}
    assert feeds == {600, 900, 1000, 1500, 1600, 1800, 2500}  # mm/min
    assert program.units == "mm" and program.units_note == "" and program.work_offset == "G54"
    assert program.path_tolerance_m == pytest.approx(1e-5)  # G64 P0.01 (roughing runs under P0.05)
    blending = [e.value for e in program.events if e.kind is EventKind.BLENDING]
    assert blending == pytest.approx([5e-5, 1e-5])
    assert [e.value for e in program.events if e.kind is EventKind.DWELL] == [0.3]  # G82 spot
    assert program.events[-1].kind is EventKind.PROGRAM_END
    words = [w.word for w in program.words]
    assert words == ["T1", "M6", "S12000", "M3", "H1", "M8", "M5", "M9", "M30"]
    # within the 120 x 80 block (plus the tool's approach), from Z-25 to the clearance plane Z15
    pts = np.array([m.end for m in moves])
    assert np.all(np.abs(pts[:, 0]) <= 0.0677) and np.all(np.abs(pts[:, 1]) <= 0.0477)
    assert pts[:, 2].min() == pytest.approx(-0.025) and pts[:, 2].max() == pytest.approx(0.015)


def test_shipped_problem_loads_the_program_next_to_it():
    assert "milling_pocket" in shipped_problems()
    pr = load_problem("milling_pocket")
    assert pr.path_kind == "gcode" and Path(pr.program.file).resolve() == PROGRAM.resolve()
    assert pr.n == pr.program.waypoints.n and 10_000 <= pr.n <= 40_000  # 30 204 when written
    assert pr.positions.shape == (pr.n, 3) and pr.wrench.shape == (pr.n, 6)
    # the program zero at (0.65, 0, 0.10) m in the base frame, program axes = base axes
    assert pr.positions[:, 2].min() == pytest.approx(0.10 - 0.025)
    assert pr.positions[:, 2].max() == pytest.approx(0.10 + 0.015)
    assert np.allclose(pr.positions.mean(axis=0)[:2], [0.65, 0.0], atol=0.01)
    # 3-axis: the tool points down at every waypoint
    assert np.allclose(pr.rotations[:, :, 2], [0.0, 0.0, -1.0])
    # the load is the predicted cut (docs/cutting.md): no [wrench], the old constant kept as the stand-in
    assert not np.any(pr.wrench) and pr.cut is not None and pr.cut.n == pr.n
    assert np.allclose(pr.cut.stand_in[:3], [40.0, 25.0, 30.0]) and pr.cut.stand_in_frame == "tool"
    F = np.linalg.norm(pr.cut.wrench_program[:, :3], axis=1)
    rapid = pr.program.waypoints.rapid
    assert np.all(F[:-1][rapid[:-1] & rapid[1:]] == 0.0) and F.max() > 10.0  # between rapids: in the air
    assert np.allclose(pr.load.wrench_base, pr.cut.wrench_base)  # program axes = base axes
