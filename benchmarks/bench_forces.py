"""The cutting force of a program at real size: removal, engagement and force of 10^3, 10^4 and 10^5
moves, with the peak memory of each run (issue 35).

The program (``pocket_points``): a pocket cleared level by level in an aluminium block, zig-zag rows
of 1 mm G1 moves 1 mm deep, rows 4 mm apart (the first row of a level a full slot, the others half
the Ø8 cutter's width, up- and down-milling in turn), 4 moves of 1 mm between rows, a 1 mm plunge
between levels (the next level's rows in the opposite direction); rows 200 mm long over a 200 x 96 mm
pocket, so 10^5 moves go 20 levels (20 mm) deep.  The cutter: Ø8 flat, 3 flutes, 30 deg helix, 26 mm
of flutes, 35 mm out; Al7075-T6 from the shipped table; S12000 M3, F1200 (feed per tooth 0.033 mm).

Each size runs in a process of its own (its peak resident memory is its own, ``ru_maxrss``) and calls
:func:`problems.cutting.program_cut.predict_cut` (what loading a problem with ``[material]`` and
``[stock]`` does) on the waypoints directly (no G-code parsing): ``rem+eng`` is the time of the
removal and the engagement masks (the z-map simulation, the force's time taken out), ``mean`` and
``peak`` the time of the force model's mean wrench and peak force (:mod:`models.cutting.force`),
``total`` the whole prediction; ``x10`` the growth of ``total`` from the size ten times smaller.

Anchor, measured in the same run: ``compplan plan --no-report`` of the same program as G-code on a
UR10 with an off-axis spindle (as ``milling_pocket``) at 10^3 moves (and 10^4 unless ``--quick``),
once with a constant wrench and no cut, once with ``[material]`` and ``[stock]`` (the cut predicted
at load), wall time of the command each.

Usage: ``python benchmarks/bench_forces.py [--quick] [--sizes 1000 10000 100000] [--no-anchor]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The pocket (program frame, mm): rows along x from -ROW/2 to ROW/2, y from -WIDTH/2 up.
ROW_MM, WIDTH_MM, STEPOVER_MM, STEP_MM, DEPTH_MM = 200.0, 96.0, 4.0, 1.0, 1.0
#: The block (program frame, mm): the pocket with 10 mm of wall around it, 30 mm deep.
STOCK_MIN_MM = (-ROW_MM / 2 - 10.0, -WIDTH_MM / 2 - 10.0, -30.0)
STOCK_MAX_MM = (ROW_MM / 2 + 10.0, WIDTH_MM / 2 + 10.0, 0.0)
SPINDLE_RPM, FEED_MM_MIN, PLUNGE_MM_MIN = 12000.0, 1200.0, 300.0
CUTTER = {"shape": "flat", "diameter": 0.008, "flutes": 3, "helix_deg": 30.0, "flute_length": 0.026, "length": 0.035}
MATERIAL = "al7075_t6"
#: Above the block, mm: where the program starts and ends (rapids).
CLEAR_MM = 5.0

PROBLEM = """\
name = "bench_forces"
description = "pocket of {n} G1 moves of 1 mm, 1 mm deep, Al7075-T6"
[robot]
model = "ur10"
[robot.tool]
xyz = [0.08, 0.0, 0.12]
[robot.tool.cutter]
shape = "flat"
diameter = 0.008
flutes = 3
helix_deg = 30.0
flute_length = 0.026
length = 0.035
[path]
kind = "gcode"
file = "pocket.ngc"
[workpiece]
xyz = [0.65, 0.0, 0.10]
[orientation]
rule = "free_tool_axis"
[limits]
max_joint_step = 0.3
"""
NO_CUT = """\
[wrench]
frame = "tool"
force = [40.0, 25.0, 30.0]
"""
CUT = f"""\
[material]
name = "{MATERIAL}"
[stock]
box_min = [{STOCK_MIN_MM[0] / 1e3}, {STOCK_MIN_MM[1] / 1e3}, {STOCK_MIN_MM[2] / 1e3}]
box_max = [{STOCK_MAX_MM[0] / 1e3}, {STOCK_MAX_MM[1] / 1e3}, {STOCK_MAX_MM[2] / 1e3}]
resolution = 0.0001
"""


def pocket_points(n_moves: int) -> list[tuple[float, float, float, bool]]:
    """The tool tip after each move, mm, and whether the move is a plunge: ``n_moves`` G1 moves after a
    rapid to above the start (the first point)."""
    x0, y0 = -ROW_MM / 2, -WIDTH_MM / 2
    rows = int(WIDTH_MM / STEPOVER_MM) + 1
    pts: list[tuple[float, float, float, bool]] = [(x0, y0, CLEAR_MM, False)]
    x, y, z = x0, y0, CLEAR_MM
    level, k = 0, 0
    while k < n_moves:
        level += 1
        z = -level * DEPTH_MM
        pts.append((x, y, z, True))  # the plunge to the level (the first one from above the block)
        k += 1
        ydir = 1.0 if level % 2 else -1.0
        for r in range(rows):
            xdir = 1.0 if (r + level) % 2 else -1.0
            for _ in range(int(ROW_MM / STEP_MM)):
                if k >= n_moves:
                    return pts
                x += xdir * STEP_MM
                pts.append((x, y, z, False))
                k += 1
            if r < rows - 1:
                for _ in range(int(STEPOVER_MM / STEP_MM)):
                    if k >= n_moves:
                        return pts
                    y += ydir * STEP_MM
                    pts.append((x, y, z, False))
                    k += 1
    return pts


def gcode(pts: list[tuple[float, float, float, bool]]) -> str:
    """The points as a LinuxCNC program (mm), a rapid to the start and back up at the end."""
    x, y, z, _ = pts[0]
    out = ["%", "(bench_forces pocket)", "G21 G90 G17 G94 G40 G49 G80 G54", "G64 P0.01", f"S{SPINDLE_RPM:.0f} M3"]
    out += [f"G0 X{x:.3f} Y{y:.3f} Z{z:.3f}"]
    for x, y, z, plunge in pts[1:]:
        out.append(f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f} F{PLUNGE_MM_MIN if plunge else FEED_MM_MIN:.0f}")
    out += [f"G0 Z{CLEAR_MM:.3f}", "M5", "M30", "%"]
    return "\n".join(out) + "\n"


def one(n: int) -> dict:
    """Predict the cut of ``n`` moves in this process; the figures as a dict."""
    sys.path.insert(0, str(ROOT))
    import math
    from types import SimpleNamespace

    import numpy as np

    import models.cutting.force as force
    import problems.cutting.simulate as simulate_module
    from models.cutting.material import material
    from problems.cutting.program_cut import predict_cut
    from problems.cutting.stock import StockBox
    from problems.problem_file.cut_section import CutSetup
    from problems.problem_file.cutter_section import parse_cutter_table

    clock = {"simulate": 0.0, "cut_wrench": 0.0, "mean": 0.0, "peak": 0.0}

    def timed(fn, key):
        def run(*a, **k):
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                clock[key] += time.perf_counter() - t0

        return run

    # the stages' clocks: module attributes looked up at call time by predict_cut and cut_wrench
    simulate_module.simulate = timed(simulate_module.simulate, "simulate")
    force.cut_wrench = timed(force.cut_wrench, "cut_wrench")
    force.mean_force_design = timed(force.mean_force_design, "mean")
    force.instantaneous_wrench = timed(force.instantaneous_wrench, "peak")

    pts = pocket_points(n)
    P = np.array([p[:3] for p in pts]) * 1e-3
    rapid = np.zeros(len(pts), dtype=bool)
    rapid[0] = True
    feed = np.array([(PLUNGE_MM_MIN if p[3] else FEED_MM_MIN) / 60e3 for p in pts])
    way = SimpleNamespace(
        n=len(pts), points_m=P, rapid=rapid, feed_m_s=feed, spindle=None, move=None, tool_axis=None,
        source="bench_forces", line=np.arange(len(pts)) + 1, stop=np.arange(len(pts)) % (len(pts) - 1) == 0,
    )  # fmt: skip
    setup = CutSetup(
        mill=parse_cutter_table("bench_forces", CUTTER, "cutter"),
        coefficients=material(MATERIAL),
        stock=StockBox(tuple(v * 1e-3 for v in STOCK_MIN_MM), tuple(v * 1e-3 for v in STOCK_MAX_MM)),
        resolution_m=1e-4,
        spindle_rpm=SPINDLE_RPM,
        spindle_cw=True,
        slice_height_m=None,
        stand_in=None,
        stand_in_frame="tool",
        table={},
    )
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    t0 = time.perf_counter()
    cut = predict_cut(setup, way, np.eye(3))
    total = time.perf_counter() - t0
    f = np.linalg.norm(cut.wrench_program[:, :3], axis=1)
    cutting = cut.axial_depth_m > 0.0
    return {
        "moves": n,
        "samples": int(cut.extra["samples"]),
        "engaged": int(np.count_nonzero(cutting)),
        "total_s": total,
        "rem_eng_s": clock["simulate"] - clock["cut_wrench"],
        "mean_s": clock["mean"],
        "peak_s": clock["peak"],
        "force_s": clock["cut_wrench"],
        "rss_before_gib": rss0,
        "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        "mean_force_N": float(np.mean(f[cutting])) if cutting.any() else math.nan,
        "max_peak_N": float(np.max(cut.peak_force_N)),
        "removed_cm3": cut.removed_m3 * 1e6,
    }


def anchor(n: int, folder: Path) -> dict:
    """``compplan plan --no-report`` of ``n`` moves without and with the cut; wall times, s."""
    (folder / "pocket.ngc").write_text(gcode(pocket_points(n)))
    out = {"moves": n}
    for key, extra in (("no_cut_s", NO_CUT), ("cut_s", CUT)):
        (folder / f"{key}.toml").write_text(PROBLEM.format(n=n) + extra)
        cmd = [sys.executable, "-m", "planner", "plan", str(folder / f"{key}.toml"), "--out", str(folder / key)]
        t0 = time.perf_counter()
        r = subprocess.run([*cmd, "--no-report", "--no-figures"], capture_output=True, text=True, cwd=ROOT)
        out[key] = time.perf_counter() - t0
        if r.returncode:
            print(r.stdout[-2000:], r.stderr[-4000:], file=sys.stderr)
            out[key] = float("nan")
    return out


def run_json(args: list[str]) -> dict | None:
    r = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True, cwd=ROOT)
    if r.returncode:
        print(r.stderr, file=sys.stderr)
        return None
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=None, help="moves (default 1000 10000 100000)")
    ap.add_argument("--quick", action="store_true", help="10^3 and 10^4 moves only (anchor: 10^3)")
    ap.add_argument("--no-anchor", action="store_true", help="skip the compplan plan anchor")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--anchor-one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one)))
        return 0
    if args.anchor_one:
        with tempfile.TemporaryDirectory() as d:
            print(json.dumps(anchor(args.anchor_one, Path(d))))
        return 0
    sizes = args.sizes or ([1000, 10000] if args.quick else [1000, 10000, 100000])
    print(
        f"pocket, 1 mm moves 1 mm deep, Ø8 flat 3 flutes, {MATERIAL}, S{SPINDLE_RPM:.0f} F{FEED_MM_MIN:.0f}; "
        "predict_cut on the waypoints, each size in a process of its own"
    )
    print(
        f"{'moves':>7} {'samples':>8} {'engaged':>8} {'rem+eng':>8} {'mean':>7} {'peak':>7} {'force':>7} "
        f"{'total':>8} {'x10':>6} {'RSS0':>7} {'peakRSS':>8} {'|F| mean':>9} {'peak max':>9} {'removed':>9}"
    )
    prev = None
    for n in sizes:
        r = run_json(["--one", str(n)])
        if r is None:
            return 1
        growth = f"{r['total_s'] / prev['total_s']:6.2f}" if prev and r["moves"] == 10 * prev["moves"] else f"{'-':>6}"
        print(
            f"{r['moves']:>7} {r['samples']:>8} {r['engaged']:>8} {r['rem_eng_s']:7.2f}s {r['mean_s']:6.2f}s "
            f"{r['peak_s']:6.2f}s {r['force_s']:6.2f}s {r['total_s']:7.2f}s {growth} {r['rss_before_gib']:5.2f}Gi "
            f"{r['peak_rss_gib']:6.2f}Gi {r['mean_force_N']:8.1f}N {r['max_peak_N']:8.1f}N "
            f"{r['removed_cm3']:6.2f}cm3"
        )
        prev = r
    print(
        "rem+eng: removal and engagement masks (z-map simulation); mean, peak: the force model's mean wrench and "
        "peak force; force: all of cut_wrench; RSS0: resident memory before the prediction (imports); "
        "|F| mean: mean |F| of the engaged waypoints"
    )
    if args.no_anchor:
        return 0
    print("anchor: compplan plan --no-report (UR10, off-axis spindle), wall time of the command")
    print(f"{'moves':>7} {'no cut':>8} {'cut':>8} {'extra':>8}")
    for n in [1000] if args.quick else [1000, 10000]:
        a = run_json(["--anchor-one", str(n)])
        if a is None:
            return 1
        print(f"{a['moves']:>7} {a['no_cut_s']:7.1f}s {a['cut_s']:7.1f}s {a['cut_s'] - a['no_cut_s']:7.1f}s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
