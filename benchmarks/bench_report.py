"""How long report generation adds to a run (issue 3 budget: <= 3 s for the demo).

Runs the demo (the plan of section 4.4 on ar5, timed) into a temporary folder, then times, in a
fresh interpreter that has already imported the pipeline (as ``compplan demo``
has when it calls the report):

* importing :mod:`planner.report` (matplotlib),
* :func:`planner.report.write_report` of the demo built from its in-memory plan
  result (as ``compplan demo`` does: the child plans first, untimed), with the
  compliance map drawn (first run) and cached (later runs),
* the same built from the demo folder's files (as ``compplan report`` does),
  serial and with the default number of rendering processes, with a per-stage
  breakdown,
* the same on the demo folder stripped of its trajectories (figure 6 absent).

Prints the figures; asserts nothing.  Usage::

    PYTHONPATH=. python benchmarks/bench_report.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = textwrap.dedent("""
    import json, sys, time
    from planner.demo import run_demo            # what a demo run has imported already
    folder, workers = sys.argv[1], (None if sys.argv[2] == "auto" else int(sys.argv[2]))
    map_cache = sys.argv[3] == "cached"
    if sys.argv[4] == "plan":                    # the demo's result, as compplan demo has it
        from models import load_robot
        result = run_demo(load_robot("ar5"))
    else:                                        # the folder's files, as compplan report reads them
        result = None
    t0 = time.perf_counter()
    from planner.report import write_report, default_workers
    t_import = time.perf_counter() - t0
    marks = []
    def progress(stage, done, total):
        marks.append((stage, done, total, time.perf_counter()))
    t1 = time.perf_counter()
    write_report(folder, progress=progress, workers=workers, map_cache=map_cache, result=result)
    t2 = time.perf_counter()
    map_end = max([m[3] for m in marks if m[0] == "compliance map"], default=t1)
    print(json.dumps({"import_s": t_import, "write_s": t2 - t1, "map_s": map_end - t1,
                      "figures_s": t2 - map_end,
                      "workers": default_workers() if workers is None else workers}))
""")


def _untimed(src: Path, dst: Path) -> None:
    """The same run without trajectories (figure 6 absent)."""
    shutil.copytree(src, dst)
    for p in dst.glob("trajectory*.csv"):
        p.unlink()
    s = json.loads((dst / "summary.json").read_text())
    for k in ("duration_s", "limit_ratio", "timing", "controller_trajectory"):
        s.pop(k, None)
    (dst / "summary.json").write_text(json.dumps(s))


def _time(folder: Path, workers: str, cache: str, source: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", _CHILD, str(folder), workers, cache, source],
                         env=env, capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs per case (best and median printed)")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT))
    from models import load_robot
    from planner.demo import run_demo, write_outputs

    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"CPUs available: {len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()}, "
          f"load average {load[0]:.2f} (timings on a shared machine vary with it)")
    with tempfile.TemporaryDirectory() as tmp:
        demo = Path(tmp) / "demo"
        write_outputs(run_demo(load_robot("ar5")), demo)
        untimed = Path(tmp) / "untimed"
        _untimed(demo, untimed)
        _time(demo, "1", "cached", "folder")     # warm the compiled kernels and the map cache
        print(f"{'case':<52}{'workers':>8}{'import':>9}{'map':>8}{'figures':>9}{'total':>9}   (s)")
        cases = (("demo from its result, map drawn (first run)", demo, "auto", "cold", "plan"),
                 ("demo from its result, map cached", demo, "auto", "cached", "plan"),
                 ("demo folder, map cached", demo, "auto", "cached", "folder"),
                 ("demo folder, map cached", demo, "1", "cached", "folder"),
                 ("demo folder untimed (6 figures), map cached", untimed, "auto", "cached", "folder"))
        for label, folder, workers, cache, source in cases:
            runs = [_time(folder, workers, cache, source) for _ in range(args.repeat)]
            runs.sort(key=lambda r: r["import_s"] + r["write_s"])
            best, med = runs[0], runs[len(runs) // 2]
            for tag, r in (("best", best), ("median", med)):
                print(f"{label + ' ' + tag:<52}{r['workers']:>8}{r['import_s']:>9.2f}"
                      f"{r['map_s']:>8.2f}{r['figures_s']:>9.2f}"
                      f"{r['import_s'] + r['write_s']:>9.2f}")
        print("budget: <= 3 s added to a demo run (import + write_report)")


if __name__ == "__main__":
    main()
