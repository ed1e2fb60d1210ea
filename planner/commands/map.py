"""``compplan map``: the compliance map C11..C66 over a plane (paper section 4.3, Fig. 5)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from planner.commands.common import add_force_argument, check_output, releases_outputs
from planner.commands.report import add_map_arguments, map_options
from planner.progress import report_progress


def register(sub: argparse._SubParsersAction) -> None:
    m = sub.add_parser(
        "map",
        help="compliance map C11..C66 over a plane (paper Fig. 5)",
        description="Diagonal compliance C11..C66 of C = J K^-1 J^T over a plane "
        "of TCP positions at a fixed end attitude. Writes "
        "compliance_map.csv (SI), compliance_map.json and "
        "figures/fig1_compliance_map.png|pdf.",
    )
    m.add_argument(
        "--robot", default="ar5", help="built-in robot name, robot file or identified model file (default ar5)"
    )
    m.add_argument("--out", required=True, help="output folder")
    add_map_arguments(m)
    add_force_argument(m)
    m.set_defaults(func=run)


@releases_outputs
def run(args: argparse.Namespace) -> int:
    from models.arm import load_arm
    from planner.compliance_map import ELEMENT_NAMES
    from planner.report import write_map

    check_output(args.out, {"--robot": args.robot}, holds="compliance map", force=args.force)
    arm = load_arm(args.robot)
    robot = arm.nominal
    with report_progress() as prog:
        cm, written = write_map(arm, Path(args.out), progress=prog, **map_options(args))
    s = cm.summary()
    print(
        f"compliance map, robot {robot.name}, plane {s['plane']}, "
        f"{s['points'][0]}x{s['points'][1]} points, attitude rpy [{', '.join(f'{v:.5g}' for v in s['rpy_rad'])}] rad "
        f"= [{', '.join(f'{math.degrees(v):.4g}' for v in s['rpy_rad'])}] deg ({s['rpy_convention']}), "
        f"branch rule {cm.branch_rule}"
    )
    used = ", ".join(f"{label} ({n} points)" for label, n in s["branches_used"].items()) or "none"
    print(f"  branches used: {used}; unreachable points: {cm.n_unreachable} of {cm.n_points}")
    for i, name in enumerate(ELEMENT_NAMES):
        lo, hi = s["diag_range_SI"][name]
        if lo is None:
            print(f"  {name}: no reachable point")
            continue
        unit, scale = ("mm/N", 1e3) if i < 3 else ("deg/(N*m)", math.degrees(1.0))
        print(f"  {name}: {lo * scale:.6g} .. {hi * scale:.6g} {unit}")
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0
