"""Benchmark of the dynamic-compensation stage (issue 13 target: <= 50 ms for a 2 s trajectory at 2 ms).

Run from the repository root::

    PYTHONPATH=. python benchmarks/bench_dynamic.py [--repeat 5]

On the shipped problem ``ur5_fast_payload`` (its link-side path, limits scaled so that the motion
lasts about 2 s at dt = 2 ms), it prints the time of

* the motor-side command of the timed trajectory (``planner.dynamic._command``: inertial torques,
  static torques and the deflection law for the command and the static compensation, smoothing,
  predicted errors) and its limit check (the command's quintic-spline derivatives and their peaks
  between samples): what the stage adds per pass;
* the whole stage (``dynamic_stage``: every link-side timing pass included);
* the anchor, measured in the same run: the same inertial torques by a Python loop over pinocchio's
  ``rnea`` (compiled C++) when pinocchio is installed, and the jerk_optimal timing of the same path.

Prints figures only.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

TARGET_S = 0.050


def _best(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, min(times), statistics.median(times)


def main() -> None:
    import numpy as np

    from planner.dynamic import _command, dynamic_stage
    from planner.plan import plan
    from problems.timing import JointLimits, time_parametrize
    from problems.dynamic import command_derivatives, curve_peaks
    from problems.problem import load_problem

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} (timings on a shared machine vary with it)")
    pr = load_problem("ur5_fast_payload").with_timing(dynamic=False)
    res = plan(pr)
    path_q, dt = res.exact.q_deflected, 0.002
    lim = JointLimits(pr.limits.velocity, 0.55 * pr.limits.acceleration, 0.4 * pr.limits.jerk)
    link, t_timing, _ = _best(lambda: time_parametrize(path_q, lim, "jerk_optimal", dt), args.repeat)
    arm = pr.model
    _command(arm, link, pr.load, path_q)  # build the functions once

    def stage_per_pass():
        ps = _command(arm, link, pr.load, path_q)
        d = command_derivatives(link.t, ps.theta, ~ps.moving)
        return curve_peaks(link.t, ps.theta, d[0], d[1])

    _, best, med = _best(stage_per_pass, args.repeat)
    print(f"link-side trajectory: {link.duration_s:.3f} s, {len(link.t)} samples at {dt * 1e3:g} ms")
    print(
        f"  motor-side command + check (per pass): best {best * 1e3:.1f} ms, median {med * 1e3:.1f} ms "
        f"(target <= {TARGET_S * 1e3:.0f} ms)"
    )
    full, fb, fm = _best(lambda: dynamic_stage(arm, path_q, lim, dt, "jerk_optimal", {}, pr.load), args.repeat)
    print(
        f"  whole stage ({full.passes} timing pass(es) of the link side included): best {fb * 1e3:.0f} ms, "
        f"median {fm * 1e3:.0f} ms; {full.status.value}"
    )
    print(f"  anchor: jerk_optimal timing of the same path: best {t_timing * 1e3:.0f} ms")
    try:
        import pinocchio as pin

        from models.dynamics import payload_vector
        from tests.test_dynamics import pinocchio_from_dh
    except ImportError:
        print("  anchor: pinocchio not installed")
        return
    robot = arm.robot()
    model, _j, _tcp = pinocchio_from_dh(robot, payload_vector(pr.load.payload_mass_kg, pr.load.payload_com_m))
    model.gravity.linear = np.zeros(3)
    data = model.createData()
    qs, vs, accs = link.q, link.qd, link.qdd
    _, pb, _ = _best(lambda: [pin.rnea(model, data, qs[k], vs[k], accs[k]) for k in range(len(qs))], args.repeat)
    print(f"  anchor: inertial torques alone by a loop over pinocchio.rnea: best {pb * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
