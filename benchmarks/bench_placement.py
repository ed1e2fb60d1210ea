"""Benchmark of the base-placement sweep (``compplan place``, ``docs/placement.md``).

Run from the repository root::

    PYTHONPATH=. python benchmarks/bench_placement.py [--quick] [--grid SPEC] [--chunk N]

On the shipped ``placement_milling`` problem, over its ``[placement]`` grid with ``--grid``
applied (default ``yaw_deg=0:330:12``: 12 yaws instead of the file's, so that each mode runs
for about 10 s serially; ``--quick``: ``yaw_deg=0``, about 1 s), in one run:

* the sweep serially (``run_sweep(..., "serial")``) and on a Dask ``LocalCluster`` of 1 and 2
  single-threaded workers (``local:1``, ``local:2``), same chunking: poses per second, the
  scaling from 1 to 2 workers (target >= 1.6x) and serial against 1 worker, and whether the
  three give the same scores bit for bit (``ChunkScores.equal``);
* the per-pose cost (us per pose, us per pose and branch) and where it goes (IK, singularity
  guard factors, the model's ``load_error``, the Viterbi programme, the rest of the scoring,
  the NumPy glue), measured on a subset of the chunks with timers around those calls;
* anchors measured in the same run: the batch IK alone on one chunk's poses, and the model's
  ``load_error`` alone on one chunk's poses on every branch;
* Dask's per-task overhead: 500 trivial tasks on the ``local:2`` cluster (wall / tasks x
  workers), and the overhead the sweeps imply (their wall time beyond the serial time per worker,
  per chunk);
* the memory of a chunk (peak of the allocations while it is scored, ``tracemalloc``);
* the estimate for 1e8 and 1e9 poses on 100 single-core workers (see ``estimate`` for the model),
  with the per-pose cost of one core (the serial cost with the IK's OpenMP loop on one thread),
  for the default chunk, the chunk that keeps the per-task overhead under 1 % and the chunk that
  keeps the scheduler's serial per-task work under 10 % of the wall time.

``--nanny-default`` also runs ``local:1`` with the Dask nanny's default environment (row
``local:1*``): its ``MALLOC_TRIM_THRESHOLD_`` turns off glibc's dynamic mmap threshold, so the
kernel's large temporaries are mapped and faulted in afresh on every chunk; ``compplan place``'s
LocalCluster lifts it (``problems.placement.cluster.LOCAL_ENV_DROPPED``).

Prints figures only (no assertion).  The machine may be shared: the load average is printed
before and after; timings on a loaded machine are noisy, the scaling figure most of all.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import pickle
import platform
import sys
import time
import tracemalloc
from dataclasses import dataclass
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

PROBLEM = "placement_milling"
DEFAULT_GRID = "yaw_deg=0:330:12"
QUICK_GRID = "yaw_deg=0"
TARGET_SCALING = 1.6
TRIVIAL_TASKS = 500
WORKERS_ESTIMATE = 100
ESTIMATE_POSES = (1e8, 1e9)
#: Share of the wall time the per-task overhead may take for the chunk-size rule.
OVERHEAD_SHARE = 0.01
#: Share of the wall time the scheduler's serial per-task work may take (the second chunk-size rule).
SCHEDULER_SHARE = 0.1


def _identity(x):
    """A trivial Dask task: returns its argument."""
    return x


def _best(fn, repeat: int = 5) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


class _Timer:
    """Wraps a callable; sums its wall time and keeps its first arguments (for the anchors)."""

    def __init__(self, fn):
        self.fn, self.s, self.calls, self.first = fn, 0.0, 0, None

    def __call__(self, *args, **kw):
        if self.first is None:
            self.first = args
        t0 = time.perf_counter()
        out = self.fn(*args, **kw)
        self.s += time.perf_counter() - t0
        self.calls += 1
        return out


def breakdown(kernel, chunks: list) -> dict:
    """Wall time per part of ``PlacementKernel.evaluate`` over ``chunks`` (timers around the IK,
    the guard factors, the model's ``load_error_g``, ``_score`` and ``_viterbi``); the kernel is
    left as it was."""
    import problems.placement.kernel as kmod

    ik = kernel.ik
    t_ik, t_gf = _Timer(ik.solve), _Timer(ik.guard_factors)
    t_le = _Timer(kernel._model)
    t_sc, t_vi = _Timer(kernel._score), _Timer(kmod._viterbi)
    saved = kernel._model
    ik.solve, ik.guard_factors = t_ik, t_gf
    kernel._model = t_le
    kernel._score = t_sc
    kmod._viterbi = t_vi
    try:
        t0 = time.perf_counter()
        for c in chunks:
            kernel.evaluate(c)
        total = time.perf_counter() - t0
    finally:
        del ik.solve, ik.guard_factors, kernel._score
        kernel._model = saved
        kmod._viterbi = t_vi.fn
    return {
        "total": total,
        "ik": t_ik.s,
        "guard": t_gf.s,
        "load_error": t_le.s,
        "viterbi": t_vi.s,
        "score_rest": t_sc.s - t_vi.s,
        "glue": total - t_ik.s - t_gf.s - t_le.s - t_sc.s,
        "ik_arg": t_ik.first[0],
        "le_args": t_le.first,
    }


def chunk_memory(kernel, chunk) -> int:
    """Peak bytes of NumPy (and Python) allocations while one chunk is scored."""
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        kernel.evaluate(chunk)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak - base


def trivial_task_overhead(n: int, workers: int = 2) -> tuple[float, float]:
    """(wall per task, wall per task x workers), s, of ``n`` trivial tasks on ``local:workers``."""
    from problems.placement.cluster import dask_client

    with dask_client(f"local:{workers}") as client:
        client.gather([client.submit(_identity, i, pure=False) for i in range(50)])  # warm-up
        t0 = time.perf_counter()
        futs = [client.submit(_identity, i, pure=False) for i in range(n)]
        client.gather(futs)
        wall = time.perf_counter() - t0
    return wall / n, wall / n * workers


def estimate(
    poses: float, us_per_pose: float, chunk_poses: int, overhead_s: float, workers: int = WORKERS_ESTIMATE
) -> tuple[float, int]:
    """The model: time = poses x per-pose cost / workers + chunks x per-task overhead / workers,
    chunks = ceil(poses / chunk poses).  Returns (seconds, chunks)."""
    chunks = math.ceil(poses / chunk_poses)
    return poses * us_per_pose * 1e-6 / workers + chunks * overhead_s / workers, chunks


def _fmt_s(s: float) -> str:
    return f"{s:.3g} s" if s < 120 else (f"{s / 60:.3g} min" if s < 7200 else f"{s / 3600:.3g} h")


@dataclass
class Run:
    """What the parts of the benchmark share."""

    args: argparse.Namespace
    kernel: Any
    placements: Any
    chunks: list
    per: int
    poses: int
    serial: Any = None
    us_pose: float = 0.0  # serial cost per pose, us
    us_pose_1: float = 0.0  # the same with the IK on one thread (one core), us
    bytes_per_pose: float = 0.0


def _parse() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help=f"a small grid ({QUICK_GRID}) for development")
    ap.add_argument("--grid", default=None, help=f"grid spec over the problem's [placement] (default {DEFAULT_GRID})")
    ap.add_argument(
        "--chunk", type=int, default=None, help="placements per chunk (default: compplan's, chunk_placements_for)"
    )
    ap.add_argument("--tasks", type=int, default=TRIVIAL_TASKS, help="trivial tasks for Dask's per-task overhead")
    ap.add_argument("--skip-dask", action="store_true", help="serial figures only")
    ap.add_argument(
        "--nanny-default",
        action="store_true",
        help="also run local:1 with the Dask nanny's default MALLOC_TRIM_THRESHOLD_ (row local:1*)",
    )
    return ap.parse_args()


def setup(args: argparse.Namespace) -> Run:
    """The problem, grid, kernel and chunks; prints what is measured."""
    from problems.placement.grid import parse_grid_text
    from problems.placement.kernel import PlacementKernel
    from problems.placement.sweep import CHUNK_POSES, chunk_bounds, chunk_placements_for
    from problems.problem import load_problem

    la0 = os.getloadavg()
    print(
        f"bench_placement {datetime.date.today().isoformat()}, {os.cpu_count()} CPUs "
        f"({platform.processor() or platform.machine()}), load average {la0[0]:.2f} {la0[1]:.2f} {la0[2]:.2f} "
        "(timings on a shared machine vary with it)"
    )
    pr = load_problem(PROBLEM)
    spec = args.grid if args.grid is not None else (QUICK_GRID if args.quick else DEFAULT_GRID)
    grid = parse_grid_text(spec, base=pr.placement, where="--grid") if spec else pr.placement
    t0 = time.perf_counter()
    kernel = PlacementKernel(pr)
    t_build = time.perf_counter() - t0
    pl = grid.placements()
    ppp, B = kernel.poses_per_placement, kernel.n_branches
    per = args.chunk or chunk_placements_for(kernel, len(pl))
    chunks = [pl[a:b] for a, b in chunk_bounds(len(pl), per)]
    blob = pickle.dumps(kernel)
    print(
        f"problem {PROBLEM} (robot {pr.robot.name}, {kernel.n_waypoints} waypoints x {kernel.n_candidates} "
        f"scanned orientations = {ppp} poses per placement, {B} branches); grid {grid.describe()} "
        f"(spec {spec!r} over the file's [placement])"
    )
    print(
        f"{len(pl)} placements, {len(pl) * ppp:,} poses; chunks of {per} placements = {per * ppp:,} poses "
        f"(CHUNK_POSES = {CHUNK_POSES:,}), {len(chunks)} chunks; load_error_g and IK compiled: {kernel.compiled}; "
        f"kernel built in {t_build:.2f} s, pickled {len(blob) / 1024:.0f} KiB"
    )
    kernel.evaluate(chunks[0])  # warm-up (loads, first calls)
    t_unpickle = _best(lambda: pickle.loads(blob), 3)
    print(
        f"kernel unpickled (what each worker does once: library written and loaded, IK built): "
        f"{t_unpickle * 1e3:.0f} ms"
    )
    return Run(args, kernel, pl, chunks, per, len(pl) * ppp)


def serial_and_anchors(run: Run) -> None:
    """The serial sweep, where a pose's cost goes, the IK and model anchors, a chunk's memory."""
    import numpy as np

    from problems.placement.sweep import run_sweep

    kernel, B = run.kernel, run.kernel.n_branches
    ser = run.serial = run_sweep(kernel, run.placements, "serial", run.per)
    run.us_pose = ser.elapsed_s / run.poses * 1e6
    print(
        f"\nserial sweep: {ser.elapsed_s:.2f} s, {ser.poses_per_second:,.0f} poses/s = {run.us_pose:.2f} us per "
        f"pose = {run.us_pose / B:.3f} us per pose and branch; feasible placements "
        f"{int(ser.scores.feasible.sum())} of {len(run.placements)}"
    )

    sub = run.chunks[:: max(1, len(run.chunks) // 8)]
    bd = breakdown(kernel, sub)
    sub_poses = sum(len(c) for c in sub) * kernel.poses_per_placement
    print(
        f"\nwhere a pose's cost goes ({len(sub)} of the {len(run.chunks)} chunks, {sub_poses:,} poses, "
        f"timers around the calls):"
    )
    print(f"  {'part':<44}{'us/pose':>9}{'share':>8}")
    for key, label in (
        ("ik", "IK, all branches (ik.solve)"),
        ("guard", "singularity guard factors"),
        ("load_error", "model load_error (valid nodes only)"),
        ("viterbi", "Viterbi programme over the waypoints"),
        ("score_rest", "rest of scoring (unwrap, limits, gather)"),
        ("glue", "NumPy glue (transforms, masks, gathers)"),
    ):
        print(f"  {label:<44}{bd[key] / sub_poses * 1e6:>9.3f}{bd[key] / bd['total']:>8.1%}")
    print(f"  {'total (instrumented)':<44}{bd['total'] / sub_poses * 1e6:>9.3f}")

    T = bd["ik_arg"]
    t_ik = _best(lambda: kernel.ik.solve(T))
    ik_line = f"  batch IK alone, {len(T):,} poses (one chunk), all {B} branches: {t_ik / len(T) * 1e6:.3f} us per pose"
    run.us_pose_1 = run.us_pose
    ev = kernel.ik.evaluator if kernel.ik.function is not None else None
    if ev is not None and ev.compiled:
        from models.codegen import batch_function

        kernel.ik.use_evaluator(batch_function(kernel.ik.function, 1))
        try:
            t_ik1 = _best(lambda: kernel.ik.solve(T))
        finally:
            kernel.ik.use_evaluator(ev)
        ik_line += f" ({ev.threads} OpenMP threads as shipped; {t_ik1 / len(T) * 1e6:.3f} with 1 thread)"
        run.us_pose_1 = run.us_pose + max(0.0, t_ik1 - t_ik) / len(T) * 1e6
    print("\nanchors (same run):")
    print(ik_line)
    if bd["le_args"] is not None:
        q, L, G = bd["le_args"]
        n_rows = len(T) * B
        reps = max(1, math.ceil(n_rows / len(q)))
        qa, La, Ga = (np.tile(a, (reps, 1))[:n_rows] for a in (q, L, G))
        evl = kernel._model
        t_le = _best(lambda: evl(qa, La, Ga))
        print(
            f"  model load_error alone, {n_rows:,} evaluations (one chunk's poses x {B} branches): "
            f"{t_le / n_rows * 1e6:.3f} us per evaluation = {t_le / len(T) * 1e6:.3f} us per pose"
        )
        print(f"  kernel / (IK + load_error on every branch) = {run.us_pose / ((t_ik + t_le) / len(T) * 1e6):.2f}")
    print(f"  single-core per-pose cost (the serial cost with the IK on one thread): {run.us_pose_1:.2f} us")

    probe = [run.chunks[0], run.chunks[len(run.chunks) // 2], run.chunks[-1]]
    mems = [(chunk_memory(kernel, c), len(c) * kernel.poses_per_placement) for c in probe]
    run.bytes_per_pose = max(m / n for m, n in mems)
    print(
        f"\nmemory of a chunk (peak of the allocations while it is scored; first, middle and last chunk): "
        f"{', '.join(f'{m / 2**20:.0f} MiB' for m, _ in mems)}; at most {run.bytes_per_pose:,.0f} bytes per pose "
        f"(IK q (P,S,N,B,6) float64 is {8 * 6 * B} B/pose; T 128 B/pose; per valid node and branch its q, "
        "load row, index and output)"
    )


def dask_modes(run: Run) -> tuple[float | None, float | None]:
    """The sweep on local:1 and local:2 (and local:1 with the nanny's defaults), beside the serial
    one; returns Dask's per-task overhead (wall per task, per task x workers), s, or Nones."""
    from problems.placement.sweep import run_sweep

    args, ser = run.args, run.serial
    rows = [("serial", ser)]
    o_task = o_task_wall = None
    if args.skip_dask:
        print("\nDask: skipped (--skip-dask)")
    else:
        try:
            import distributed  # noqa: F401 - is the dask extra installed?
        except ImportError:
            print('\nDask: not installed (pip install "compplan[dask]"); serial figures only')
        else:
            for spec_s in ("local:1", "local:2"):
                rows.append((spec_s, run_sweep(run.kernel, run.placements, spec_s, run.per)))
            o_task_wall, o_task = trivial_task_overhead(args.tasks, 2)
            if args.nanny_default:
                import problems.placement.cluster as cluster

                saved, cluster.LOCAL_ENV_DROPPED = cluster.LOCAL_ENV_DROPPED, ()
                try:
                    rows.append(("local:1*", run_sweep(run.kernel, run.placements, "local:1", run.per)))
                finally:
                    cluster.LOCAL_ENV_DROPPED = saved

    print(f"\n{'mode':<9}{'wall [s]':>10}{'poses/s':>12}{'us/pose':>9}{'workers':>8}{'bit-equal to serial':>21}")
    for name, r in rows:
        eq = (
            "-"
            if name == "serial"
            else ("yes" if r.scores.equal(ser.scores) else f"NO (max diff {r.scores.max_difference(ser.scores):.3g})")
        )
        print(
            f"{name:<9}{r.elapsed_s:>10.2f}{r.poses_per_second:>12,.0f}{r.elapsed_s / run.poses * 1e6:>9.2f}"
            f"{r.workers:>8}{eq:>21}"
        )
    if len(rows) >= 3:
        t1, t2, n = rows[1][1].elapsed_s, rows[2][1].elapsed_s, len(run.chunks)
        print(
            f"scaling 1 -> 2 workers: {t1 / t2:.2f}x (target >= {TARGET_SCALING}x); serial / 1 worker: "
            f"{ser.elapsed_s / t1:.2f}"
        )
        print(
            f"Dask per-task overhead: {args.tasks} trivial tasks on local:2: {o_task_wall * 1e3:.2f} ms wall per "
            f"task, {o_task * 1e3:.2f} ms per task x workers"
        )
        print(
            f"overhead implied by the sweeps, per chunk: local:1 (wall - serial) / chunks = "
            f"{(t1 - ser.elapsed_s) / n * 1e3:.1f} ms; local:2 (wall - serial/2) x 2 / chunks = "
            f"{(t2 - ser.elapsed_s / 2) * 2 / n * 1e3:.1f} ms (on a 2-core machine the client and scheduler "
            "share the workers' cores)"
        )
    return o_task_wall, o_task


def large_sweep_estimate(run: Run, o_task_wall: float | None, o_task: float | None) -> None:
    """Time of 1e8 and 1e9 poses on WORKERS_ESTIMATE workers for compplan's default chunk and the
    chunks that keep the overhead under OVERHEAD_SHARE and the scheduler under SCHEDULER_SHARE."""
    from problems.placement.sweep import chunk_placements_for

    c, ppp = run.us_pose_1, run.kernel.poses_per_placement
    o = o_task if o_task is not None else 1e-3
    o_sched = o_task_wall or o / 2
    src = "measured" if o_task is not None else "assumed, Dask not run"
    print(
        f"\nestimate on {WORKERS_ESTIMATE} single-core workers: time = poses x {c:.2f} us (single-core "
        f"per-pose cost) / {WORKERS_ESTIMATE} + chunks x {o * 1e3:.2f} ms ({src} per-task overhead) / "
        f"{WORKERS_ESTIMATE}; the scheduler handles tasks one at a time: chunks x {o_sched * 1e3:.2f} ms is a floor"
    )
    min_chunk = math.ceil(o / (OVERHEAD_SHARE * c * 1e-6))
    print(
        f"chunk size for overhead < {OVERHEAD_SHARE:.0%}: chunk poses >= overhead / ({OVERHEAD_SHARE:g} x per-pose "
        f"cost) = {min_chunk:,} poses = {math.ceil(min_chunk / ppp):,} placements of this problem"
    )
    sched_chunk = math.ceil(WORKERS_ESTIMATE * o_sched / (SCHEDULER_SHARE * c * 1e-6))
    print(
        f"chunk size for the scheduler floor < {SCHEDULER_SHARE:.0%} of the time on {WORKERS_ESTIMATE} workers: "
        f"chunk poses >= {WORKERS_ESTIMATE} x {o_sched * 1e3:.2f} ms / ({SCHEDULER_SHARE:g} x per-pose cost) = "
        f"{sched_chunk:,} poses"
    )
    print(
        f"  {'poses':>8}{'chunk poses':>13}{'chunks':>10}{'time':>11}{'overhead':>10}{'sched. floor':>14}"
        f"{'MiB/chunk':>11}"
    )
    for P in ESTIMATE_POSES:
        default_chunk = chunk_placements_for(run.kernel, math.ceil(P / ppp)) * ppp  # compplan's default
        for cp in sorted({default_chunk, min_chunk, sched_chunk}):
            t, nch = estimate(P, c, cp, o)
            print(
                f"  {P:>8.0e}{cp:>13,}{nch:>10,}{_fmt_s(t):>11}{nch * o / WORKERS_ESTIMATE / t:>10.2%}"
                f"{_fmt_s(nch * o_sched):>14}{cp * run.bytes_per_pose / 2**20:>11.0f}"
                f"{'  (default)' if cp == default_chunk else ''}"
            )


#: The cell of the cell-vs-no-cell figure: placement_milling's table, fixture and part (m, cell frame).
CELL_TOML = """
[cell]
clearance = 0.005
[[cell.objects]]
name = "table"
shape = "box"
size = [0.60, 1.20, 0.70]
xyz = [0.75, 0.0, -0.38]
[[cell.objects]]
name = "fixture"
shape = "box"
size = [0.25, 0.80, 0.03]
xyz = [0.65, 0.0, -0.015]
[[cell.objects]]
name = "part"
shape = "box"
size = [0.15, 0.70, 0.10]
xyz = [0.65, 0.0, 0.05]
role = "workpiece"
"""
#: Target share of the no-cell rate the sweep keeps with the cell (issue 25).
TARGET_CELL_SHARE = 0.5


def cell_rates() -> None:
    """The sweep over the file's own grid, serially, without and with a cell (``CELL_TOML``): poses/s
    of both in the same run and their ratio (target ``TARGET_CELL_SHARE``)."""
    import tempfile
    from dataclasses import replace

    from problems.placement.kernel import PlacementKernel
    from problems.placement.sweep import run_sweep
    from problems.problem import load_problem

    text = (Path(__file__).resolve().parents[1] / "problems" / "files" / f"{PROBLEM}.toml").read_text() + CELL_TOML
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / f"{PROBLEM}_cell.toml"
        f.write_text(text)
        pr = load_problem(str(f))
    pl = pr.placement.placements()
    rates = {}
    for label, cell in (("no cell", None), ("cell", pr.cell)):
        k = PlacementKernel(replace(pr, cell=cell))
        k.evaluate(pl[:50])  # warm
        t0 = time.perf_counter()
        sw = run_sweep(k, pl)
        rates[label] = sw.poses / (time.perf_counter() - t0)
    print(f"\ncell vs no cell ({PROBLEM}, its own grid, serial, same run; 3 boxes, clearance 5 mm):")
    for label, r in rates.items():
        print(f"  {label:<8}{r:>12.0f} poses/s")
    share = rates["cell"] / rates["no cell"]
    print(f"  with the cell / without: {share:.0%} (target >= {TARGET_CELL_SHARE:.0%})")


def main() -> None:
    run = setup(_parse())
    serial_and_anchors(run)
    cell_rates()
    large_sweep_estimate(run, *dask_modes(run))
    la1 = os.getloadavg()
    print(f"\nload average at the end {la1[0]:.2f} {la1[1]:.2f} {la1[2]:.2f}")


if __name__ == "__main__":
    main()
