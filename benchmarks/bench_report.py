"""The speed a user feels (issue 22): wall time of the commands beside the stage times they record.

For the current checkout ("after") and an earlier revision ("before", checked out with
``git worktree add`` into a temporary folder, removed at the end), in the same run, warm (one
untimed run of every case first fills the compile and map caches), each case run ``--repeat``
times as a fresh ``python -m planner ...`` process, the versions interleaved:

* ``compplan --version``;
* ``compplan plan paper_4_4 --no-report --no-figures``;
* ``compplan plan paper_4_4`` (with its report);
* ``compplan demo`` (with its report);
* ``compplan report RUN --no-map-cache`` on the folder of the last ``plan`` run of the same
  version: every figure and the compliance map rendered again, as for the report of a new run
  (no target; the plan and demo cases read the figures back from the figure cache, which only a
  run on the same data fills).

Per case and version: the wall time (min and median), the sum of the stage times the run records
in ``summary.json`` (``stage_times_s``: model, posture, compensation, timing, dynamic
compensation; the per-method ``timing_<method>_s`` are parts of ``timing_s``), the overhead
(wall minus stages, per run, median) and the CPU time of the process and its children (user +
sys, median: less sensitive than wall time to other load on a shared machine).  The targets are
printed beside the figures.  ``--tests`` also runs the test suite of both versions once
(``python -m pytest -q``) and prints its wall and CPU time: that takes many minutes.

Prints the figures; asserts nothing (``benchmarks/bench_startup.py`` checks the start-up limits of
the current checkout and exits non-zero over one).  Usage::

    python benchmarks/bench_report.py [--repeat 3] [--before REV | --no-before] [--tests]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The subject of the first commit of issue 22's work: the default "before" is its parent.
FIRST_COMMIT_SUBJECT = "Timing moves under problems/"
#: The shipped problem timed.
PROBLEM = "paper_4_4"
#: Targets of issue 22 ("Speed a user feels").
VERSION_MAX_S = 0.5
OVERHEAD_MAX_S = 1.0
REPORT_RATIO_MAX = 1.5
DEMO_MAX_S = 3.0


@dataclass(frozen=True)
class Case:
    """One command line; ``out`` says whether it takes ``--out FOLDER`` (and records stages);
    ``on_run``: its last argument is the folder of the version's last ``plan_report`` run."""

    key: str
    label: str
    args: tuple[str, ...]
    out: bool
    on_run: bool = False


CASES = (
    Case("version", "compplan --version", ("--version",), False),
    Case(
        "plan_bare", f"plan {PROBLEM} --no-report --no-figures", ("plan", PROBLEM, "--no-report", "--no-figures"), True
    ),
    Case("plan_report", f"plan {PROBLEM} (report)", ("plan", PROBLEM), True),
    Case("demo", "demo (report)", ("demo",), True),
    Case("report_fresh", "report RUN --no-map-cache (all drawn)", ("report", "--no-map-cache"), False, True),
)


@dataclass
class Runs:
    """The timed runs of one case and version (seconds)."""

    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    stages: list[float] = field(default_factory=list)

    def overhead(self) -> list[float]:
        return [w - s for w, s in zip(self.wall, self.stages)]


def stage_sum(summary: dict) -> float:
    """Sum of the stage times of a run's summary (s), without double-counting timing's parts."""
    times = summary.get("stage_times_s") or {}
    parts = {k for k in times if k.startswith("timing_") and k != "timing_s"} if "timing_s" in times else set()
    return float(sum(v for k, v in times.items() if k not in parts))


def child_env(code: Path) -> dict[str, str]:
    """The environment of a timed process: the package tree ``code`` first on ``PYTHONPATH``, and the
    bytecode cache on (without ``PYTHONDONTWRITEBYTECODE``, every run would compile the tree's
    modules again; an installed compplan has its bytecode, as the warm-up run gives the tree)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(code), os.environ.get("PYTHONPATH")) if p)
    return env


def run_case(code: Path, case: Case, out: Path, run: Path | None = None) -> tuple[float, float, float | None]:
    """Run ``case`` with the package tree ``code`` (``run``: the folder a ``on_run`` case reads);
    (wall s, CPU s of the children, stages s or None)."""
    env = child_env(code)
    cmd = [
        sys.executable,
        "-m",
        "planner",
        *case.args,
        *(("--out", str(out)) if case.out else ()),
        *((str(run),) if case.on_run else ()),
    ]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=out.parent, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(
            f"{' '.join(cmd)} (PYTHONPATH={code}) exited {proc.returncode}: {proc.stderr.strip()[-500:]}"
        )
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    stages = stage_sum(json.loads((out / "summary.json").read_text())) if case.out else None
    return wall, cpu, stages


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout


def default_before() -> str | None:
    """The parent of the commit whose subject starts with :data:`FIRST_COMMIT_SUBJECT`, or None."""
    for line in _git("log", "--format=%H %P %s").splitlines():
        _sha, parent, subject = (line.split(" ", 2) + ["", ""])[:3]
        if subject.startswith(FIRST_COMMIT_SUBJECT) and parent:
            return parent
    return None


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def _fmt(value: float | None, width: int = 9) -> str:
    return f"{'-':>{width}}" if value is None or math.isnan(value) else f"{value:>{width}.2f}"


def _target(case: Case, runs: dict[str, Runs], version: str) -> str:
    """The figure the target of ``case`` is about, the target, and whether it is met."""
    r = runs[f"{version}:{case.key}"]
    if case.key == "version":
        value, ok = min(r.wall), min(r.wall) <= VERSION_MAX_S
        return f"wall {value:.2f} s, target <= {VERSION_MAX_S} s: {'met' if ok else 'not met'}"
    if case.key == "plan_bare":
        value = _median(r.overhead())
        return (
            f"overhead {value:.2f} s, target <= {OVERHEAD_MAX_S} s: {'met' if value <= OVERHEAD_MAX_S else 'not met'}"
        )
    if case.key == "report_fresh":
        return "(no target: the cost of a report's figures when none is cached)"
    if case.key == "plan_report":
        ratio = _median(r.wall) / _median(runs[f"{version}:plan_bare"].wall)
        return (
            f"x{ratio:.2f} the run without report, target <= x{REPORT_RATIO_MAX}: "
            f"{'met' if ratio <= REPORT_RATIO_MAX else 'not met'}"
        )
    value = _median(r.wall)
    return f"wall {value:.2f} s, target <= {DEMO_MAX_S} s: {'met' if value <= DEMO_MAX_S else 'not met'}"


def measure(versions: dict[str, Path], repeat: int, tmp: Path) -> dict[str, Runs]:
    """Every case of every version: one untimed run, then ``repeat`` timed rounds (interleaved)."""
    runs = {f"{v}:{c.key}": Runs() for v in versions for c in CASES}
    last_plan: dict[str, Path] = {}
    n = 0
    for rnd in range(repeat + 1):
        for version, code in versions.items():
            for case in CASES:
                n += 1
                folder = tmp / f"run{n}"
                folder.mkdir()
                wall, cpu, stages = run_case(code, case, folder / "out", last_plan.get(version))
                if case.key == "plan_report":
                    last_plan[version] = folder / "out"
                if rnd == 0:
                    continue  # the warm-up run
                r = runs[f"{version}:{case.key}"]
                r.wall.append(wall)
                r.cpu.append(cpu)
                r.stages.append(stages if stages is not None else 0.0)
    return runs


def print_table(versions: dict[str, Path], runs: dict[str, Runs]) -> None:
    print(f"{'case':<42}{'version':<9}{'wall min':>9}{'median':>9}{'stages':>9}{'overhead':>9}{'CPU':>9}   (s)")
    for case in CASES:
        for version in versions:
            r = runs[f"{version}:{case.key}"]
            print(
                f"{case.label:<42}{version:<9}{_fmt(min(r.wall))}{_fmt(_median(r.wall))}"
                f"{_fmt(_median(r.stages) if case.out else None)}{_fmt(_median(r.overhead()) if case.out else None)}"
                f"{_fmt(_median(r.cpu))}   {_target(case, runs, version)}"
            )


def run_tests(versions: dict[str, Path]) -> None:
    """The test suite of each version, once: wall and CPU time (user + sys of all its processes)."""
    print("\ntest suite (python -m pytest -q), once per version:")
    for version, code in versions.items():
        env = {**os.environ, "PYTHONPATH": str(code)}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"],
            cwd=code,
            env=env,
            capture_output=True,
            text=True,
            check=False,
        )
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        last = next((ln for ln in reversed(proc.stdout.splitlines()) if ln.strip()), "")
        print(f"  {version:<8} wall {wall / 60:6.1f} min, CPU {cpu / 60:6.1f} min (exit {proc.returncode}: {last})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per case and version (default 3)")
    ap.add_argument(
        "--before",
        default=None,
        metavar="REV",
        help=f"the earlier revision (default: the parent of the commit '{FIRST_COMMIT_SUBJECT}...')",
    )
    ap.add_argument("--no-before", action="store_true", help="time the current checkout only")
    ap.add_argument("--tests", action="store_true", help="also time the test suite of each version (many minutes)")
    args = ap.parse_args()
    rev = None if args.no_before else (args.before or default_before())
    if not args.no_before and rev is None:
        sys.exit(f"no commit '{FIRST_COMMIT_SUBJECT}...' in this history: give --before REV or --no-before")
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="compplan-bench-") as tmp_name:
        tmp = Path(tmp_name)
        versions: dict[str, Path] = {}
        worktree = tmp / "before"
        if rev is not None:
            _git("worktree", "add", "--detach", str(worktree), rev)
            versions["before"] = worktree
        versions["after"] = ROOT
        try:
            label = f"before = {_git('rev-parse', '--short', rev).strip()}, " if rev else ""
            print(
                f"compplan speed, warm, {args.repeat} timed runs per case ({label}after = the working tree "
                f"of {ROOT}); {cpus} CPUs, load average {load0:.2f} at the start"
            )
            runs = measure(versions, args.repeat, tmp)
            print_table(versions, runs)
            print(
                f"load average {os.getloadavg()[0]:.2f} at the end (wall times on a shared machine vary with it; "
                "CPU times less)"
            )
            if args.tests:
                run_tests(versions)
        finally:
            if rev is not None:
                _git("worktree", "remove", "--force", str(worktree))


if __name__ == "__main__":
    main()
