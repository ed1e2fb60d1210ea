"""``compplan demo``: the paper's section-4.4 scenario."""

from __future__ import annotations

import argparse
from pathlib import Path

from planner.commands.common import print_error_table


def register(sub: argparse._SubParsersAction) -> None:
    d = sub.add_parser("demo", help="the paper's section-4.4 scenario on ar5")
    d.add_argument("--out", required=True, help="output folder")
    d.add_argument("--robot", default="ar5", help="built-in robot name or robot file (default ar5)")
    d.add_argument("--points", type=int, default=40, help="number of waypoints (default 40)")
    d.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from models import load_robot
    from planner.demo import run_demo, write_outputs

    robot = load_robot(args.robot)
    res = run_demo(robot, n_points=args.points)
    summary = write_outputs(res, args.out)
    s = summary
    print_error_table([
        ("before compensation", s["error_before"]["max_mm"], s["error_before"]["rms_mm"]),
        ("after closed form", s["error_after"]["closed_form"]["max_mm"], s["error_after"]["closed_form"]["rms_mm"]),
        ("after exact", s["error_after"]["exact"]["max_mm"], s["error_after"]["exact"]["rms_mm"]),
    ], f"TCP position error, robot {robot.name}, branch {res.branch.label}, "
       f"F = {[float(v) for v in res.wrench]} (N, N*m, base frame), {len(res.positions)} waypoints")
    for w in s["warnings"]:
        print(f"warning: {w}")
    print(f"wrote {Path(args.out)}/: summary.json, path.csv, waypoints.csv, branches.csv")
    return 0
