"""``compplan report DIR``: the report of an existing output folder."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from models.errors import InputError
from planner.commands.common import check_output, releases_outputs
from planner.progress import report_progress


def add_map_arguments(p: argparse.ArgumentParser, *, prefix: str = "", optional: bool = False) -> None:
    """Options of the compliance-map plane (shared by ``report`` and ``map``).

    ``optional``: options not given are left out of the namespace (``report``: without any of
    them the map is drawn on the plane of the run's own path, as ``plan`` and ``demo`` draw it).
    """
    from planner.compliance_map import DEFAULT_POINTS
    from problems import paper

    x0 = paper.SECTION_4_3_X_M
    lo, hi = paper.SECTION_4_3_RANGE_M
    title = (
        "compliance map (default: the plane of the run's path; with any of these options: that "
        "plane, the paper's section-4.3 values for the others)"
        if optional
        else "compliance map (default: the paper's section-4.3 plane)"
    )
    g = p.add_argument_group(title)
    g.add_argument(
        f"--{prefix}plane",
        choices=("x", "y", "z"),
        default="x" if not optional else argparse.SUPPRESS,
        help="base axis normal to the plane (default x; in-plane axes: x->(y,z), y->(x,z), z->(x,y))",
    )
    g.add_argument(
        f"--{prefix}offset-m",
        type=float,
        default=x0 if not optional else argparse.SUPPRESS,
        metavar="M",
        help=f"plane position along its normal, m (default {x0:g})",
    )
    g.add_argument(
        f"--{prefix}u-range-m",
        type=float,
        nargs=2,
        default=(lo, hi) if not optional else argparse.SUPPRESS,
        metavar=("LO", "HI"),
        help=f"first in-plane axis range, m (default {lo:g} {hi:g})",
    )
    g.add_argument(
        f"--{prefix}v-range-m",
        type=float,
        nargs=2,
        default=(lo, hi) if not optional else argparse.SUPPRESS,
        metavar=("LO", "HI"),
        help=f"second in-plane axis range, m (default {lo:g} {hi:g})",
    )
    g.add_argument(
        f"--{prefix}points",
        type=int,
        default=DEFAULT_POINTS if not optional else argparse.SUPPRESS,
        metavar="N",
        help=f"grid points per in-plane axis (default {DEFAULT_POINTS})",
    )
    att = g.add_mutually_exclusive_group()
    att.add_argument(
        f"--{prefix}rpy-rad",
        type=float,
        nargs=3,
        metavar=("ROLL", "PITCH", "YAW"),
        help="end attitude, rad, R = Rz(yaw) Ry(pitch) Rx(roll) (default "
        f"{' '.join(f'{a:g}' for a in paper.SECTION_4_3_RPY)}, the paper's)",
    )
    att.add_argument(
        f"--{prefix}rpy-deg",
        type=float,
        nargs=3,
        metavar=("ROLL", "PITCH", "YAW"),
        help="end attitude in degrees (same convention)",
    )
    g.add_argument(
        f"--{prefix}branch",
        default="home" if not optional else argparse.SUPPRESS,
        help="IK branch rule: 'home' (per point, the branch nearest the home "
        "configuration; default) or a label such as s+w-e+",
    )


def map_options(args: argparse.Namespace, prefix: str = "") -> dict[str, Any]:
    """Keyword arguments of :func:`planner.compliance_map.compliance_map` from parsed options."""
    import math

    from problems import paper

    a = vars(args)
    pre = prefix.replace("-", "_")
    if a.get(f"{pre}rpy_deg") is not None:
        rpy = [math.radians(v) for v in a[f"{pre}rpy_deg"]]
    elif a.get(f"{pre}rpy_rad") is not None:
        rpy = list(a[f"{pre}rpy_rad"])
    else:
        rpy = [float(v) for v in paper.SECTION_4_3_RPY]
    from planner.compliance_map import DEFAULT_POINTS

    x0, rng = paper.SECTION_4_3_X_M, tuple(paper.SECTION_4_3_RANGE_M)
    return {
        "plane": a.get(f"{pre}plane", "x"),
        "offset_m": a.get(f"{pre}offset_m", x0),
        "u_range_m": tuple(a.get(f"{pre}u_range_m", rng)),
        "v_range_m": tuple(a.get(f"{pre}v_range_m", rng)),
        "points": a.get(f"{pre}points", DEFAULT_POINTS),
        "rpy_rad": rpy,
        "branch": a.get(f"{pre}branch", "home"),
    }


def map_options_given(args: argparse.Namespace, prefix: str) -> bool:
    """Whether any option added by ``add_map_arguments(..., optional=True)`` was given."""
    pre = prefix.replace("-", "_")
    keys = ("plane", "offset_m", "u_range_m", "v_range_m", "points", "branch", "rpy_rad", "rpy_deg")
    return any(vars(args).get(f"{pre}{k}") is not None for k in keys)


def write_run_report(folder: str | Path, **kwargs: Any) -> Path:
    """Write the report of a run folder with progress bars and print where it went.

    ``kwargs`` go to :func:`planner.report.write_report`.  The commands that produce
    a run (demo, plan) call it at the end with ``record=`` the run record of their in-memory
    :class:`~planner.plan_result.PlanResult`, so the report is built from it rather than
    from the files they just wrote; ``compplan report`` reads the folder.
    """
    from planner.report import write_report

    with report_progress() as prog:
        html = write_report(Path(folder), progress=prog, **kwargs)
    print(f"wrote {html} (self-contained), {html.with_suffix('.md').name} and {html.parent / 'figures'}/ (PNG, PDF)")
    return html


def register(sub: argparse._SubParsersAction) -> None:
    r = sub.add_parser(
        "report",
        help="write report.html/report.md/figures for an output folder",
        description="Write report.html (self-contained), report.md and "
        "figures/*.png|pdf into an output folder of compplan demo "
        "or compplan plan. Absent pieces (no trajectory, ...) are "
        "stated in the report.",
    )
    r.add_argument("folder", help="output folder of compplan demo / plan")
    r.add_argument("--no-map", action="store_true", help="leave out the compliance map (figure 1)")
    r.add_argument(
        "--no-map-cache",
        action="store_true",
        help="draw the compliance map and the figures again even if they are cached for "
        "this robot and these options or data ($COMPPLAN_CACHE/maps and /figures, "
        "default ~/.cache/compplan)",
    )
    r.add_argument(
        "--jobs", type=int, default=None, metavar="N", help="processes that render the figures (default: up to 2)"
    )
    add_map_arguments(r, prefix="map-", optional=True)
    r.set_defaults(func=run)


@releases_outputs
def run(args: argparse.Namespace) -> int:
    check_output(args.folder, kind="update", option="FOLDER")
    if args.jobs is not None and args.jobs < 1:
        raise InputError(f"--jobs = {args.jobs}; expected an integer >= 1")
    opts: Any = (
        False if args.no_map else (map_options(args, prefix="map-") if map_options_given(args, "map-") else None)
    )
    if opts:
        from planner.compliance_map import validate_map_options

        validate_map_options(**opts)  # a bad --map-* option is the user's error: exit 2
    write_run_report(args.folder, map_options=opts, workers=args.jobs, map_cache=not args.no_map_cache)
    return 0
