"""``compplan demo``: ``compplan plan`` on the paper's section-4.4 problem (``paper_4_4``)."""

from __future__ import annotations

import argparse

from planner.commands.common import add_force_argument, check_output, releases_outputs
from planner.commands.export import add_export_argument


def register(sub: argparse._SubParsersAction) -> None:
    d = sub.add_parser(
        "demo",
        help="plan the paper's section-4.4 problem (shipped problem paper_4_4) on ar5",
        description="compplan plan on the paper's section-4.4 problem (the shipped problem paper_4_4: a 40-point "
        "line on ar5): branch and posture, exact compensation and timing, written into --out with its report.",
    )
    d.add_argument("--out", required=True, help="output folder")
    d.add_argument("--robot", default=None, help="built-in robot name or robot file (default: the problem's, ar5)")
    d.add_argument("--points", type=int, default=None, help="number of waypoints (default: the problem's, 40)")
    d.add_argument(
        "--no-figures",
        action="store_true",
        help="skip branches.png and trajectory.png (written only with --no-report; the report has the same figures)",
    )
    d.add_argument(
        "--no-report", action="store_true", help="skip the report (report.html, report.md, figures/) written at the end"
    )
    add_export_argument(d)
    add_force_argument(d)
    d.set_defaults(func=run)


@releases_outputs
def run(args: argparse.Namespace) -> int:
    from planner.commands.plan import finish_run
    from planner.demo import demo_problem
    from planner.plan import plan

    check_output(args.out, {"--robot": args.robot}, holds="plan", force=args.force)
    problem = demo_problem(args.robot, args.points)
    return finish_run(plan(problem, verbose=args.verbose).raise_for_status(), args)
