"""The start-up guard (issue 36): what a command costs before and after its stages, against limits.

For the current checkout, warm (one untimed run of every case first), each case run ``--repeat``
times as a fresh ``python -m planner ...`` process (as :mod:`bench_report` runs them, with the
bytecode cache on):

* ``compplan --help`` and ``compplan plan --help``: the wall time, and what they import (read from
  ``-X importtime``): SciPy, matplotlib and the timing libraries are not allowed;
* ``compplan --version``: the wall time;
* ``compplan plan paper_4_4 --no-report --no-figures``: the overhead, the process's wall time minus
  the stage times it records in ``summary.json`` (:func:`bench_report.stage_sum`), per run, median;
  and, printed beside it, the same on the CPU clock in one process (:func:`cpu_overhead`);
* ``compplan plan paper_4_4`` (with its report): its median wall time over the bare plan's.

Prints the figures beside the limits (``bench_report``'s targets: :data:`~bench_report.OVERHEAD_MAX_S`,
:data:`~bench_report.REPORT_RATIO_MAX`, :data:`~bench_report.VERSION_MAX_S`) and exits with status 1
if one is exceeded.  Wall times on a machine shared with other work run long: the load average is
printed at the start and the end.  Usage::

    python benchmarks/bench_startup.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from statistics import median

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_report import (
    OVERHEAD_MAX_S,
    PROBLEM,
    REPORT_RATIO_MAX,
    ROOT,
    VERSION_MAX_S,
    Case,
    Runs,
    child_env,
    run_case,
    stage_sum,
)

#: Top-level packages the command line's help must not import.
HELP_FORBIDDEN = ("scipy", "matplotlib", "toppra", "ruckig", "dask", "eaik")

HELP_CASES = (("compplan --help", ("--help",)), ("compplan plan --help", ("plan", "--help")))
CASES = (
    Case("version", "compplan --version", ("--version",), False),
    Case(
        "plan_bare", f"plan {PROBLEM} --no-report --no-figures", ("plan", PROBLEM, "--no-report", "--no-figures"), True
    ),
    Case("plan_report", f"plan {PROBLEM} (report)", ("plan", PROBLEM), True),
)


def help_imports(args: tuple[str, ...]) -> tuple[float, list[str]]:
    """The wall time (s) of ``python -X importtime -m planner ARGS`` and the forbidden top-level
    packages (:data:`HELP_FORBIDDEN`) it imported."""
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "planner", *args],
        env=child_env(ROOT),
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"compplan {' '.join(args)} exited {proc.returncode}: {proc.stderr.strip()[-500:]}")
    modules = {
        line.split("|")[-1].strip()
        for line in proc.stderr.splitlines()
        if line.startswith("import time:") and "self [us]" not in line
    }
    return wall, sorted({m.split(".")[0] for m in modules} & set(HELP_FORBIDDEN))


#: A bare plan in one process, its stage clock (``planner.plan``'s ``time.perf_counter``) swapped for
#: the process's CPU clock: prints ``[CPU s of the process from before its imports, CPU s of the
#: stages, calls of the stage clock]``.
CPU_PROBE = r"""
import json, sys, time, types
t0 = time.process_time()
import planner.plan as plan_module
calls = []
plan_module.time = types.SimpleNamespace(perf_counter=lambda: calls.append(1) or time.process_time())
from planner.cli import main
assert main(["plan", sys.argv[1], "--out", sys.argv[2], "--no-report", "--no-figures"]) == 0
total = time.process_time() - t0
stages = json.load(open(sys.argv[2] + "/summary.json"))["stage_times_s"]
print(json.dumps([total, stages, len(calls)]))
"""


def cpu_overhead(tmp: Path) -> float | None:
    """The CPU time (s) of a bare plan's process outside its stages, measured on the CPU clock in one
    process (:data:`CPU_PROBE`; the interpreter's own start, before the probe, is not counted): less
    sensitive than the wall time to other work on a shared machine.  None if the plan's stages were
    not timed on the swapped clock (the plan module times them otherwise)."""
    out = tmp / "cpu"
    proc = subprocess.run(
        [sys.executable, "-c", CPU_PROBE, PROBLEM, str(out)],
        env=child_env(ROOT),
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        raise RuntimeError(f"the CPU probe exited {proc.returncode}: {proc.stderr.strip()[-500:]}")
    total, stages, calls = json.loads(proc.stdout.strip().splitlines()[-1])
    return total - stage_sum({"stage_times_s": stages}) if calls else None


def measure(repeat: int, tmp: Path) -> dict[str, Runs]:
    """Every case: one untimed run, then ``repeat`` timed rounds."""
    runs = {c.key: Runs() for c in CASES}
    n = 0
    for rnd in range(repeat + 1):
        for case in CASES:
            n += 1
            folder = tmp / f"run{n}"
            folder.mkdir()
            wall, cpu, stages = run_case(ROOT, case, folder / "out")
            if rnd:
                runs[case.key].wall.append(wall)
                runs[case.key].cpu.append(cpu)
                runs[case.key].stages.append(stages if stages is not None else 0.0)
    return runs


def verdict(ok: bool) -> str:
    return "met" if ok else "EXCEEDED"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per case (default 5)")
    args = ap.parse_args()
    print(f"compplan start-up, warm, {args.repeat} timed runs per case ({ROOT}); load average {os.getloadavg()[0]:.2f}")
    failed = []
    for label, argv in HELP_CASES:
        help_imports(argv)  # warm
        wall, bad = help_imports(argv)
        print(
            f"{label:<42} wall {wall:5.2f} s   imports {', '.join(bad) or 'no SciPy, matplotlib or timing library'}"
            f"   limit: none of {', '.join(HELP_FORBIDDEN)}: {verdict(not bad)}"
        )
        if bad:
            failed.append(label)
    with tempfile.TemporaryDirectory(prefix="compplan-startup-") as tmp:
        runs = measure(args.repeat, Path(tmp))
        cpu = [cpu_overhead(Path(tmp)) for _ in range(args.repeat)]
    version = min(runs["version"].wall)
    bare, report = runs["plan_bare"], runs["plan_report"]
    overhead = median(bare.overhead())
    ratio = median(report.wall) / median(bare.wall)
    rows = (
        ("compplan --version", f"wall min {version:5.2f} s", f"<= {VERSION_MAX_S} s", version <= VERSION_MAX_S),
        (
            CASES[1].label,
            f"wall {median(bare.wall):5.2f} s, stages {median(bare.stages):5.2f} s, overhead {overhead:5.2f} s",
            f"overhead <= {OVERHEAD_MAX_S} s",
            overhead <= OVERHEAD_MAX_S,
        ),
        (
            CASES[2].label,
            f"wall {median(report.wall):5.2f} s, x{ratio:.2f} the bare plan",
            f"<= x{REPORT_RATIO_MAX}",
            ratio <= REPORT_RATIO_MAX,
        ),
    )
    for label, figure, limit, ok in rows:
        print(f"{label:<42} {figure}   limit {limit}: {verdict(ok)}")
        if not ok:
            failed.append(label)
    cpu_text = "n/a (the stages are not timed on planner.plan's clock)" if None in cpu else f"{median(cpu):5.2f} s"
    print(f"{'':<42} overhead on the CPU clock {cpu_text} (for a loaded machine; the limit is on the wall time)")
    print(f"load average {os.getloadavg()[0]:.2f} at the end (wall times on a shared machine vary with it)")
    if failed:
        print(f"start-up limits exceeded: {'; '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
