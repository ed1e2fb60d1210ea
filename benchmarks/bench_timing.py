"""Benchmark of :func:`planner.timing.time_parametrize`.

Times TOPP-RA and Ruckig on a seeded 40-waypoint, 6-joint curved path at
controller periods of 8, 4 and 2 ms and prints the median wall time of a few
runs, with the resulting trajectory duration and status.

Run from the repository root::

    python benchmarks/bench_timing.py
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.timing import JointLimits, time_parametrize  # noqa: E402

N_WAYPOINTS = 40
N_JOINTS = 6
PERIODS_S = (0.008, 0.004, 0.002)
METHODS = ("toppra", "ruckig")
REPEATS = 7
SEED = 1


def curved_path(seed: int = SEED, n_way: int = N_WAYPOINTS) -> np.ndarray:
    """(n_way, 6) rad, waypoints on a random smooth curve."""
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 1.0, n_way)[:, None]
    c = rng.uniform(-1.0, 1.0, (4, N_JOINTS))
    return (
        c[0]
        + c[1] * 1.5 * u
        + 0.6 * c[2] * np.sin(2.0 * np.pi * u)
        + 0.4 * c[3] * np.cos(np.pi * u)
    )


def main() -> None:
    q_path = curved_path()
    limits = JointLimits(
        velocity=np.full(N_JOINTS, 3.15),
        acceleration=np.full(N_JOINTS, 5.0),
        jerk=np.full(N_JOINTS, 50.0),
    )
    print(
        f"time_parametrize: {N_WAYPOINTS} waypoints x {N_JOINTS} joints, "
        f"median of {REPEATS} runs (1 warm-up)"
    )
    print(f"{'method':<8} {'dt [ms]':>7} {'median [ms]':>12} {'min [ms]':>9} "
          f"{'samples':>8} {'traj [s]':>9} {'runs':>5}  status")
    for method in METHODS:
        for dt in PERIODS_S:
            time_parametrize(q_path, limits, method=method, dt=dt)  # warm-up
            times = []
            traj = None
            for _ in range(REPEATS):
                t0 = time.perf_counter()
                traj = time_parametrize(q_path, limits, method=method, dt=dt)
                times.append(time.perf_counter() - t0)
            assert traj is not None
            print(
                f"{method:<8} {dt * 1e3:>7.0f} {statistics.median(times) * 1e3:>12.1f} "
                f"{min(times) * 1e3:>9.1f} {traj.t.size:>8d} {traj.duration_s:>9.3f} "
                f"{traj.iterations:>5d}  {traj.status.value}"
            )


if __name__ == "__main__":
    main()
