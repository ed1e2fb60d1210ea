"""The ``compplan`` command line (also ``python -m planner``).

Only this module prints.  User mistakes (bad files, unreachable targets,
infeasible problems) print one line ``compplan: error: ...`` and exit with
status 2; an unexpected internal failure exits with status 3 and a traceback
only under ``-v``.
"""

from __future__ import annotations

import argparse
import sys
import traceback
from pathlib import Path
from typing import Callable

import numpy as np

from models.errors import CompplanError

EXIT_OK = 0
EXIT_USER_ERROR = 2
EXIT_INTERNAL = 3


def _print_table(rows: list[tuple[str, float, float]], title: str) -> None:
    print(title)
    print(f"  {'case':<28}{'max [mm]':>12}{'RMS [mm]':>12}")
    for name, mx, rms in rows:
        print(f"  {name:<28}{mx:>12.6f}{rms:>12.6f}")


def cmd_demo(args: argparse.Namespace) -> int:
    from models import load_robot
    from planner.demo import run_demo
    from planner.output import OutputSet

    robot = load_robot(args.robot)
    res = run_demo(robot, n_points=args.points)
    summary = res.summary()
    out = OutputSet(args.out)
    out.add_json("summary.json", summary)
    rows = np.hstack([res.positions, res.exact.q_command])
    out.add_csv("path.csv", ["x", "y", "z", "q1", "q2", "q3", "q4", "q5", "q6"], rows)
    out.publish()
    s = summary
    _print_table([
        ("before compensation", s["error_before"]["max_mm"], s["error_before"]["rms_mm"]),
        ("after closed form", s["error_after"]["closed_form"]["max_mm"], s["error_after"]["closed_form"]["rms_mm"]),
        ("after exact", s["error_after"]["exact"]["max_mm"], s["error_after"]["exact"]["rms_mm"]),
    ], f"TCP position error, robot {robot.name}, branch {res.branch.label}, "
       f"F = {[float(v) for v in res.wrench]} (N, N*m, base frame), {len(res.positions)} waypoints")
    for w in s["warnings"]:
        print(f"warning: {w}")
    print(f"wrote {Path(args.out) / 'summary.json'} and {Path(args.out) / 'path.csv'}")
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="compplan",
                                description="Plan, compensate and time 6R arm paths under load.")
    p.add_argument("-v", "--verbose", action="store_true", help="verbose solver output and tracebacks")
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("demo", help="the paper's section-4.4 scenario on ar5")
    d.add_argument("--out", required=True, help="output folder")
    d.add_argument("--robot", default="ar5", help="built-in robot name or robot file (default ar5)")
    d.add_argument("--points", type=int, default=40, help="number of waypoints (default 40)")
    d.set_defaults(func=cmd_demo)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except CompplanError as exc:
        print(f"compplan: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("compplan: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - last-resort guard at the boundary
        if args.verbose:
            traceback.print_exc()
        print(f"compplan: internal error: {type(exc).__name__}: {exc} (run with -v for details)",
              file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
