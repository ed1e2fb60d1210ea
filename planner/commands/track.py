"""``compplan track RUN_DIR``: run a plan's trajectory through the elastic-joint simulation.

The controller's command of a ``plan``/``demo`` run folder (``trajectory.csv``) drives the
virtual robot's elastic-joint simulation (``problems/virtual/elastic.py``: the robot, stiffness,
payload and wrench the run's ``summary.json`` records; Radau); the TCP tracking error against
the planned link side (``ql1..ql6`` with dynamic compensation, otherwise the static equilibrium
of every command sample) is printed during the motion and at rest, and written per sample with
``--out``.  ``--stiffness-scale`` and ``--payload-scale`` simulate an arm that differs from the
model.  See ``docs/elastic-simulation.md``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from planner.commands.common import check_output, releases_outputs


def _positive(name: str):
    def check(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not (math.isfinite(v) and v > 0):
            raise argparse.ArgumentTypeError(f"{name} must be > 0, got {text!r}")
        return v

    return check


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``compplan track``."""
    p = sub.add_parser(
        "track",
        help="simulate a run's trajectory on the elastic-joint arm and print the TCP "
        "tracking error (during the motion and at rest)",
        description="Run the controller trajectory of a plan or demo output folder through the elastic-joint "
        "simulation of the arm it records and print the TCP tracking error during the motion and at rest; "
        "--out writes it per sample (docs/elastic-simulation.md).",
    )
    p.add_argument("run_dir", metavar="RUN_DIR", help="output folder of compplan plan or demo")
    p.add_argument("--out", default=None, help="CSV of the tracking error per simulated sample (t, error_m)")
    p.add_argument("--settle", type=_positive("--settle"), default=0.5, help="rest simulated after the motion, s")
    p.add_argument(
        "--damping-ratio",
        type=_positive("--damping-ratio"),
        default=0.05,
        help="joint damping ratio of the simulated arm (default 0.05)",
    )
    p.add_argument(
        "--stiffness-scale",
        type=_positive("--stiffness-scale"),
        default=1.0,
        help="simulated joint stiffness over the robot file's (e.g. 0.8)",
    )
    p.add_argument(
        "--payload-scale",
        type=_positive("--payload-scale"),
        default=1.0,
        help="simulated payload mass over the run's (e.g. 1.2)",
    )
    p.set_defaults(func=run)


def _wrench(summary: dict) -> np.ndarray:
    from models.errors import InputError

    w = summary.get("wrench") or {}
    F, M = np.asarray(w.get("F_N", [0, 0, 0]), float), np.asarray(w.get("M_Nm", [0, 0, 0]), float)
    if not np.any(F) and not np.any(M):
        return np.zeros(6)
    if w.get("frame") != "base" or w.get("per_waypoint"):
        raise InputError(
            f"track: the simulation takes one constant base-frame wrench; this run's wrench is "
            f"{'per waypoint' if w.get('per_waypoint') else 'in the ' + str(w.get('frame')) + ' frame'}"
        )
    return np.r_[F, M]


@releases_outputs
def run(args: argparse.Namespace) -> int:
    from models.dynamics import payload_vector
    from models.errors import InputError
    from models.robot import robot_from_dict
    from planner.export import ExportError, data_from_run
    from planner.output import atomic_write_bytes, csv_bytes
    from problems.virtual.elastic import ElasticArm, simulate_elastic, tracking_error

    run_dir = Path(args.run_dir)
    if args.out:
        check_output(args.out, {"RUN_DIR": run_dir}, kind="file")
    from planner.summary_schema import read_summary

    summary = read_summary(run_dir, "track")  # every key of summary.json track reads, checked (exit 2)
    try:
        data = data_from_run(run_dir)  # checks status, limits and sampling
    except ExportError as exc:
        raise InputError(str(exc).replace("export", "track")) from None
    robot = robot_from_dict(summary["robot_file"], where=f"{run_dir}/summary.json robot_file")
    if not robot.has_masses:
        raise InputError(
            f"track: robot {robot.name} of {run_dir} has no link masses (robot file keys mass, com, "
            "inertia); the elastic-joint simulation needs them"
        )
    pl = summary.get("payload") or {}
    payload = payload_vector(float(pl.get("mass_kg", 0.0)) * args.payload_scale, pl.get("com_m_tcp_frame", [0, 0, 0]))
    wrench = _wrench(summary)
    K = np.array([j.stiffness for j in robot.joints]) * args.stiffness_scale
    ql = data.link_q
    if ql is None:  # no dynamic compensation: the static equilibria
        arm = ElasticArm(robot, payload, wrench)
        ql = np.array([arm.equilibrium(th, K)[0] for th in data.q])
    sim = simulate_elastic(
        robot,
        data.t,
        data.q,
        payload=payload,
        wrench=wrench,
        stiffness=K,
        damping_ratio=args.damping_ratio,
        settle_s=args.settle,
    )
    if not sim.ok:
        raise InputError(f"track: the simulation failed: {sim.reason}")
    e = tracking_error(sim, robot, data.t, ql)
    print(
        f"track {run_dir}: robot {robot.name}, {len(data.t)} command samples ({data.t[-1]:.3f} s) + {args.settle:g} s "
        f"rest; stiffness x{args.stiffness_scale:g}, payload x{args.payload_scale:g}, damping ratio "
        f"{args.damping_ratio:g}; solver {sim.cpu_s:.1f} s CPU"
    )
    print(f"  TCP tracking error during the motion: max {e.max_motion * 1e3:.4f} mm, RMS {e.rms_motion * 1e3:.4f} mm")
    print(f"  at rest: max {e.max_rest * 1e3:.4f} mm, final {e.final * 1e3:.6f} mm")
    if args.out:
        atomic_write_bytes(args.out, csv_bytes(["t", "error_m"], np.column_stack([e.t, e.error])))
        print(f"wrote {args.out}")
    return 0
