"""Machining programs at real size: parse, posture, compensation and timing of 10^3, 10^4 and 10^5
G1 moves, with the peak memory of each run.

The program is a freeform raster (``raster_program``): rows of 0.5 mm G1 moves over a 2 mm wavy
surface at 1500 mm/min, a 1 mm step between rows, stops at the row ends; planned on a UR10 with an
off-axis spindle (0.1 m) and a milling force of [30, 20, 40] N in the tool frame, at dt = 2 ms.
Each size runs in a fresh process (so its peak resident memory is its own); the stage times are the
plan's ``stage_times_s`` and the parse time is ``load_problem`` (G-code read, waypoints, placement).

``Tcut/Tp``: the time of the samples on cutting moves (accelerations at stops included) over the
programmed time length / F (issue 23's bound: 1.15 where the limits allow the feed).

Anchor, measured in the same run (in a process of its own, so the peak memory above is the plan's):
the posture NLP over every waypoint (the method before this one for long paths; feasible to 10^4)
against the nodes-and-densify posture used above
``POSTURE_MAX_NODES`` waypoints, time and load-induced error.

``write`` and ``w.peak``: writing the run's output files (summary, path, waypoints, branches,
trajectory CSV; no figures) and the process's peak memory once they are written (not in the budget:
the budget is the plan).

Budgets (issue 23): growth from 10^4 to 10^5 moves at most 12x; 10^5 moves planned in at most
60 s and 4 GiB on the 2-core machine. The script prints each with its figure.

The 3-D finishing case (issue 33, ``--case finishing``; ``both`` by default): a CAM-style ball-nose
parallel finishing program of about 10^3, 10^4, 10^5 G1 moves (``benchmarks/cam_finishing.py``:
drop-cutter CL points reduced to chords within 0.01 mm, 20 µm to 17 mm long, G64 P0.02, F1200 on
the rows and F600 over the step-overs) on the UR10 with its off-axis spindle and milling force,
timed by the controller's look-ahead (jerk-limited) and, in a process of its own in the same run,
by TOPP-RA on the same path (velocity and acceleration only): the cutting time over TOPP-RA's and
over length / F, the samples' distance from the path over the tolerance, the plan's time and peak
memory (budget: 10^5 moves in 60 s and 4 GiB).

Usage: ``python benchmarks/bench_toolpath.py [--sizes 1000 10000 100000] [--no-anchor] [--case both]``.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GROWTH_BUDGET = 12.0
TIME_BUDGET_S = 60.0
MEMORY_BUDGET_GIB = 4.0

PROBLEM = """\
name = "bench_raster"
description = "freeform raster, {n} G1 moves"
[robot]
model = "ur10"
tool = {{ xyz = [0.1, 0.0, 0.05] }}
[path]
kind = "gcode"
file = "raster.ngc"
[workpiece]
xyz = [0.6, -0.1, 0.05]
[wrench]
frame = "tool"
force = [30.0, 20.0, 40.0]
[limits]
max_joint_step = 0.3
[timing]
dt = 0.002
"""


def raster_program(n_moves: int, step_mm: float = 0.5, width_mm: float = 80.0, feed: int = 1500) -> str:
    """A freeform raster of ``n_moves`` G1 moves (mm): zig-zag rows over z = 2 sin(x/15) cos(y/20)."""
    per_row = int(width_mm / step_mm)
    out = ["%", "(freeform raster)", "G21 G90 G17 G94 G40 G49 G80", "G54", f"F{feed}", "G0 X0 Y0 Z5", "G1 Z0"]
    y, k, row = 0.0, 0, 0
    while k < n_moves:
        xs = [i * step_mm for i in range(1, per_row + 1)]
        if row % 2:
            xs = [width_mm - x for x in xs]
        for x in xs:
            z = 2.0 * math.sin(x / 15.0) * math.cos(y / 20.0)
            out.append(f"G1 X{x:.3f} Y{y:.3f} Z{z:.4f}")
            k += 1
            if k >= n_moves:
                break
        if k >= n_moves:
            break
        y += 1.0
        out.append(f"G1 Y{y:.3f}")
        k += 1
        row += 1
    out += ["G0 Z5", "M30", "%"]
    return "\n".join(out) + "\n"


def one(n: int, folder: Path, anchor: bool) -> dict:
    """Plan one size in this process; the figures as a dict."""
    sys.path.insert(0, str(ROOT))
    import numpy as np

    from planner.plan import plan
    from problems.posture import optimise_postures
    from problems.problem import load_problem

    (folder / "raster.ngc").write_text(raster_program(n))
    (folder / "p.toml").write_text(PROBLEM.format(n=n))
    t0 = time.perf_counter()
    pr = load_problem(folder / "p.toml")
    parse = time.perf_counter() - t0
    res = plan(pr)
    st = res.stage_times_s
    fl = res.feed[res.controller]
    out = {
        "moves": n,
        "waypoints": pr.n,
        "status": res.status.value,
        "parse_s": parse,
        "posture_s": st.get("posture_s", float("nan")),
        "compensation_s": st.get("compensation_s", float("nan")),
        "timing_s": st.get("timing_s", float("nan")),
        "samples": int(len(fl.trajectory.t)),
        "time_over_programmed": res.view().summary["program"]["feed"][res.controller]["cutting_time_over_programmed"],
        "rms_error_um": res.posture.best.rms_error_m * 1e6,
    }
    out["total_s"] = parse + out["posture_s"] + out["compensation_s"] + out["timing_s"] + st.get("model_s", 0.0)
    if anchor:  # in its own process: only the anchor, its time and error
        from problems.posture import dense

        out = {"status": res.status.value, "dense_cost": res.posture.best.cost}
        dense.POSTURE_MAX_NODES = 10**9  # the NLP over every waypoint
        t0 = time.perf_counter()
        full = optimise_postures(pr.model, pr.task(), pr.home_q, pr.solver)
        out["anchor_posture_s"] = time.perf_counter() - t0
        out["anchor_rms_error_um"] = full.best.rms_error_m * 1e6 if full.ok else float("nan")
        out["anchor_cost_ratio"] = float(res.posture.best.cost / full.best.cost) if full.ok else float("nan")
        return out
    out["peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    from planner.plan import write_outputs

    t0 = time.perf_counter()  # the output files (no figures): summary, path, waypoints, branches, trajectory
    write_outputs(res, folder / "out", with_figures=False)
    out["write_s"] = time.perf_counter() - t0
    out["write_peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    del np
    return out


FINISHING_PROBLEM = """\
name = "bench_finishing"
description = "3-D ball-nose parallel finishing, {n} G1 moves"
[robot]
model = "ur10"
tool = {{ xyz = [0.08, 0.0, 0.12] }}
[path]
kind = "gcode"
file = "finishing.ngc"
[workpiece]
xyz = [0.65, 0.0, 0.10]
[wrench]
frame = "tool"
force = [40.0, 25.0, 30.0]
[limits]
max_joint_step = 0.3
[timing]
methods = ["{method}"]
"""
#: Rows of the finishing program per G1 move wanted (about 45 moves a 60 mm row), and its step-over, mm.
FINISHING_MOVES_PER_ROW = 45
FINISHING_STEPOVER_MM = 0.2


def finishing_case(n: int, folder: Path, method: str) -> dict:
    """Plan the CAM-style finishing program of about ``n`` moves (``benchmarks/cam_finishing.py``)
    with one timing method, in this process; the figures as a dict."""
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from cam_finishing import finishing_program

    from planner.plan import plan
    from problems.problem import load_problem

    rows = max(2, round(n / FINISHING_MOVES_PER_ROW))
    t0 = time.perf_counter()
    text = finishing_program(n_rows=rows, depth_mm=(rows - 1) * FINISHING_STEPOVER_MM)
    gen = time.perf_counter() - t0
    (folder / "finishing.ngc").write_text(text)
    (folder / "p.toml").write_text(FINISHING_PROBLEM.format(n=n, method=method))
    t0 = time.perf_counter()
    pr = load_problem(folder / "p.toml")
    parse = time.perf_counter() - t0
    res = plan(pr)
    st = res.stage_times_s
    f = res.view().summary["program"]["feed"][method]
    total = parse + sum(st.get(k, 0.0) for k in ("model_s", "posture_s", "compensation_s", f"timing_{method}_s"))
    return {
        "moves": sum(1 for ln in text.splitlines() if ln[:1] == "X"),
        "waypoints": pr.n,
        "status": res.status.value,
        "generate_s": gen,
        "total_s": total,
        "timing_s": st.get(f"timing_{method}_s", float("nan")),
        "cutting_s": f["cutting_time_s"],
        "over_programmed": f["cutting_time_over_programmed"],
        "deviation_mm": f.get("path_deviation_mm"),
        "tolerance_mm": res.view().summary["program"]["path_tolerance_mm"],
        "slowed": len(f["slowed_lines"]),
        "slowed_by_limit": len(f.get("slowed_by_limit") or []),
        "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        # the stretches' worker processes (problems/toolpath/stretch_pool.py): the largest one's peak
        "worker_peak_gib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20,
    }


def finishing_rows(sizes: list[int]) -> int:
    """The finishing case at each size: the look-ahead (the controller's, jerk-limited) and, in a
    process of its own in the same run, TOPP-RA on the same path (velocity and acceleration only)."""
    print("3-D finishing (ball-nose parallel, chordal tol 0.01 mm, G64 P0.02, F1200 / F600), UR10, milling force")
    print(
        f"{'moves':>7} {'waypts':>7} {'plan':>7} {'timing':>7} {'peak':>7} {'Tcut/Tp':>7} {'Tcut/TOPP-RA':>12} "
        f"{'dev/tol':>7} {'slowed (limit)':>14} | {'TOPP-RA: Tcut/Tp':>16} {'plan':>7}"
    )
    ok = True
    for n in sizes:
        got = {}
        for m in ("lookahead", "toppra"):
            r = subprocess.run(
                [sys.executable, __file__, "--finishing", str(n), "--method", m],
                capture_output=True,
                text=True,
                cwd=ROOT,
            )
            if r.returncode:
                print(r.stderr, file=sys.stderr)
                return 1
            got[m] = json.loads(r.stdout.strip().splitlines()[-1])
        la, tp = got["lookahead"], got["toppra"]
        dev = la["deviation_mm"] / la["tolerance_mm"] if la["deviation_mm"] is not None else float("nan")
        print(
            f"{la['moves']:>7} {la['waypoints']:>7} {la['total_s']:6.1f}s {la['timing_s']:6.1f}s "
            f"{la['peak_rss_gib']:5.2f}Gi {la['over_programmed']:7.3f} {la['cutting_s'] / tp['cutting_s']:12.3f} "
            f"{dev:7.3f} {la['slowed']:>6} ({la['slowed_by_limit']:>4}) | {tp['over_programmed']:16.3f} "
            f"{tp['total_s']:6.1f}s"
        )
        if la["worker_peak_gib"] > 0.0:
            print(f"  (largest worker process's peak: {la['worker_peak_gib']:.2f} GiB)")
        if la["moves"] >= 0.9 * 100000:
            # the planning process and, at most, every worker at the largest one's peak
            from problems.toolpath.stretch_pool import worker_count

            mem = la["peak_rss_gib"] + worker_count(10**6) * la["worker_peak_gib"]
            t_ok = la["total_s"] <= TIME_BUDGET_S and mem <= MEMORY_BUDGET_GIB
            ok &= t_ok
            print(
                f"  10^5 moves: {la['total_s']:.1f} s (budget {TIME_BUDGET_S:g} s), {mem:.2f} GiB with its workers "
                f"(budget {MEMORY_BUDGET_GIB:g}): {'ok' if t_ok else 'MISS'}"
            )
    print(
        "Tcut: time of the samples on cutting moves (accelerations at stops included); Tp: length / F; "
        "dev/tol: the samples' largest distance from the programmed path over the tolerance; plan: parse, "
        "posture, compensation and timing (the program's generation, 'generate_s', not included)"
    )
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--no-anchor", action="store_true", help="skip the full-NLP anchor")
    ap.add_argument("--case", choices=("raster", "finishing", "both"), default="both")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--anchor", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--finishing", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--method", default="lookahead", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        with tempfile.TemporaryDirectory() as d:
            print(json.dumps(one(args.one, Path(d), args.anchor)))
        return 0
    if args.finishing:
        with tempfile.TemporaryDirectory() as d:
            print(json.dumps(finishing_case(args.finishing, Path(d), args.method)))
        return 0
    if args.case in ("finishing", "both"):
        if finishing_rows(args.sizes):
            return 1
        if args.case == "finishing":
            return 0
    rows = []
    for n in args.sizes:
        runs = [[sys.executable, __file__, "--one", str(n)]]
        if not args.no_anchor and n <= 10000:
            runs.append(runs[0] + ["--anchor"])
        row: dict = {}
        for cmd in runs:
            r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            if r.returncode:
                print(r.stderr, file=sys.stderr)
                return 1
            got = json.loads(r.stdout.strip().splitlines()[-1])
            row.update({k: v for k, v in got.items() if k.startswith("anchor_")} if "--anchor" in cmd else got)
        rows.append(row)
    print(
        f"{'moves':>7} {'waypts':>7} {'parse':>7} {'posture':>8} {'comp':>6} {'timing':>7} {'total':>7} "
        f"{'peak':>8} {'samples':>9} {'Tcut/Tp':>7} {'RMS err':>8} {'write':>7} {'w.peak':>7} | "
        f"{'anchor: NLP everywhere':>24}"
    )
    for r in rows:
        anc = (
            f"{r['anchor_posture_s']:7.2f} s, {r['anchor_rms_error_um']:6.1f} um, cost x{r['anchor_cost_ratio']:.4f}"
            if "anchor_posture_s" in r
            else "-"
        )
        print(
            f"{r['moves']:>7} {r['waypoints']:>7} {r['parse_s']:6.2f}s {r['posture_s']:7.2f}s "
            f"{r['compensation_s']:5.2f}s "
            f"{r['timing_s']:6.2f}s {r['total_s']:6.2f}s {r['peak_rss_gib']:6.2f}Gi {r['samples']:>9} "
            f"{r['time_over_programmed']:7.3f} {r['rms_error_um']:6.1f}um {r['write_s']:6.2f}s "
            f"{r['write_peak_rss_gib']:5.2f}Gi | {anc}"
        )
    by = {r["moves"]: r for r in rows}
    if 10000 in by and 100000 in by:
        g = by[100000]["total_s"] / by[10000]["total_s"]
        print(
            f"growth 10^4 -> 10^5 moves: x{g:.2f} (budget x{GROWTH_BUDGET:g}) {'ok' if g <= GROWTH_BUDGET else 'MISS'}"
        )
    if 100000 in by:
        r = by[100000]
        t_ok = "ok" if r["total_s"] <= TIME_BUDGET_S else "MISS"
        m_ok = "ok" if r["peak_rss_gib"] <= MEMORY_BUDGET_GIB else "MISS"
        print(
            f"10^5 moves: {r['total_s']:.1f} s (budget {TIME_BUDGET_S:g} s) {t_ok}, "
            f"{r['peak_rss_gib']:.2f} GiB (budget {MEMORY_BUDGET_GIB:g}) {m_ok}"
        )
    print("anchor cost ratio: the nodes-and-densify posture's summed squared load error over the NLP's")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
