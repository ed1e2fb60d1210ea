"""Cost of a multi-campaign identification against one identification of the same rows.

The real UR5 tracker data (``grid.csv``, docs/real-data.md) are split as in
``benchmarks/real_ur5_design.py``: campaign A (joint 1 below :data:`SPLIT_JOINT1_DEG`) and
:data:`N_B` rows of the rest chosen at random (seed :data:`SEED`), B60.  In one run, with ``compplan``
as a user runs it (a subprocess, ``--no-progress``), it times

(a) ``identify --data AB.csv`` -- the rows of A and B60 in one file, one campaign;
(b) ``identify --data A.csv --data B60.csv`` -- the same rows as two campaigns (own registration each);

wall time and CPU time of the child (``resource.getrusage(RUSAGE_CHILDREN)``, user + system), and prints
the CPU ratio (b) / (a) beside the bar :data:`RATIO_BAR`.  Run::

    python benchmarks/bench_campaigns.py [--data /work/shared/data/ur5-laser-tracker] [--out out/bench_campaigns]

The ``PYTHONPATH`` of the run is passed to the children (to time another checkout's code).
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from real_ur5_design import SPLIT_JOINT1_DEG, split_grid, write_rows

#: Rows of the rest in campaign B, and the seed choosing them.
N_B, SEED = 60, 0
#: The bar: two campaigns cost at most this multiple of one identification of the same rows (CPU).
RATIO_BAR = 3.0
#: The dataset's measurement-file format (docs/real-data.md).
FMT = ("--format", "tracker-dif")


def _split(data: Path, out: Path) -> tuple[int, int]:
    """A.csv (and B.csv) as ``real_ur5_design.py`` splits the grid, then B60.csv (N_B rows of B, seed SEED) and
    AB.csv (A and B60 in measurement order) written to ``out``; their row counts (A, B60)."""
    header, A, rest = split_grid(data, out)
    idx = sorted(np.random.default_rng(SEED).choice(len(rest), N_B, replace=False).tolist())
    B = [rest[i] for i in idx]
    write_rows(out / "B60.csv", header, B)
    order = header.index("step_order")  # one file's rows are in measurement order
    write_rows(out / "AB.csv", header, sorted(A + B, key=lambda r: float(r[order])))
    return len(A), len(B)


def _timed(*args: str) -> tuple[float, float]:
    """``compplan identify ARGS --no-progress`` in a child: its wall and CPU time, s."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-m", "planner", "identify", *args, "--no-progress"], capture_output=True, text=True
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"bench_campaigns.py: compplan identify {' '.join(args)} failed:\n{r.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/shared/data/ur5-laser-tracker")
    ap.add_argument("--out", default="out/bench_campaigns")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    n_a, n_b = _split(Path(a.data), out)
    common = ("--robot", "ur5", *FMT, "--force")
    print(f"bench_campaigns: A {n_a} rows (joint 1 < {SPLIT_JOINT1_DEG} deg), B {n_b} rows (seed {SEED})", flush=True)
    one = _timed("--data", str(out / "AB.csv"), *common, "--out", str(out / "AB.toml"), "--report", str(out / "AB_r"))
    print(f"  (a) one campaign  A+B{n_b}: wall {one[0]:8.1f} s, CPU {one[1]:8.1f} s", flush=True)
    two = _timed(
        "--data", str(out / "A.csv"), "--data", str(out / "B60.csv"), *common,
        "--out", str(out / "A_B.toml"), "--report", str(out / "A_B_r"),
    )  # fmt: skip
    print(f"  (b) two campaigns A, B{n_b}: wall {two[0]:8.1f} s, CPU {two[1]:8.1f} s", flush=True)
    ratio = two[1] / one[1]
    print(
        f"CPU ratio (b)/(a) {ratio:.2f} (wall {two[0] / one[0]:.2f}); bar <= {RATIO_BAR:g}: "
        f"{'met' if ratio <= RATIO_BAR else 'NOT met'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
