"""``compplan place``: where to put the robot for a task (base-placement sweep, ``docs/placement.md``)."""

from __future__ import annotations

import argparse
from typing import Any

from planner.commands.common import add_force_argument, check_output, releases_outputs
from planner.progress import report_progress


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "place",
        help="base-placement study: sweep base positions and yaws for a task, rank them, "
        "plan the best in full (optionally on a Dask cluster)",
        description="Scores every base placement of a grid (reachability on each IK branch, no "
        "flip, joint-limit and singularity margins, the load-induced TCP error of the "
        "best branch), ranks them and plans the best few and the problem as written in "
        "full. Writes summary.json, scores.csv, ranking.csv, report.html and figures/.",
    )
    p.add_argument("problem", help="problem file (TOML) or the name of a shipped problem (e.g. placement_milling)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="SPEC",
        help="grid axes over the problem's [placement] table (or the default grid): comma-separated "
        "KEY=VALUE or KEY=START:STOP:COUNT with KEY in x_m, y_m, z_m, yaw_deg, tilt_deg, top; "
        "repeatable (e.g. --grid x_m=-0.4:0.4:9,y_m=-0.6:0.6:13 --grid yaw_deg=0:270:4)",
    )
    p.add_argument(
        "--scheduler",
        default="serial",
        help="serial (default), local:N (a Dask LocalCluster of N workers) or tcp://HOST:PORT "
        '(an existing Dask scheduler); Dask is the extra: pip install "compplan[dask]"',
    )
    p.add_argument(
        "--chunk",
        type=int,
        default=None,
        metavar="N",
        help="placements per chunk (one task); default: about 32,768 poses per chunk, larger for a "
        "sweep that would need over 1,000 chunks (at most 262,144 poses)",
    )
    p.add_argument(
        "--top",
        type=int,
        default=None,
        metavar="N",
        help="how many of the best placements to plan in full (0..10; default: the grid's top, 3)",
    )
    p.add_argument(
        "--robot",
        default=None,
        help="arm model to study instead of the problem's robot (built-in name, robot file or "
        "identified model file); the problem's tool is kept",
    )
    p.add_argument(
        "--no-optimise",
        action="store_true",
        help="full plans without the posture NLP: each branch at the problem's nominal orientation "
        "(faster; the plans then do not use the orientation freedom the sweep scanned)",
    )
    p.add_argument("--no-report", action="store_true", help="skip report.html and figures/")
    add_force_argument(p)
    p.set_defaults(func=run)


def grid_for(problem: Any, specs: list[str], top: int | None) -> Any:
    """The study's grid: the problem's ``[placement]`` (or the default grid) with ``--grid`` and
    ``--top`` applied."""
    import dataclasses

    from models.errors import InputError
    from problems.placement.grid import MAX_TOP, default_grid, parse_grid_text

    if problem.placement is not None:
        grid = problem.placement
    else:
        grid = default_grid(problem.positions, _reach_m(problem))
    for s in specs:
        grid = parse_grid_text(s, base=grid, where=f"--grid {s!r}")
    if top is not None:
        if not 0 <= top <= MAX_TOP:
            raise InputError(f"--top {top}: expected an integer in [0, {MAX_TOP}]")
        grid = dataclasses.replace(grid, top=int(top))
    return grid


def _reach_m(problem: Any) -> float:
    """A generous reach of the arm, m: the sum of its link lengths and offsets plus the tool."""
    import numpy as np

    r = problem.robot
    dh = np.abs(np.array([[j.a, j.d] for j in r.joints])).sum()
    return float(dh + np.linalg.norm(r.tcp2flange[:3, 3]))


@releases_outputs
def run(args: argparse.Namespace) -> int:
    from models.errors import InfeasibleError, InputError
    from planner.placement import StudyStatus, study, write_study
    from problems.placement.cluster import ClusterError
    from problems.placement.sweep import parse_scheduler
    from problems.problem import load_problem

    check_output(args.out, {"PROBLEM": args.problem, "--robot": args.robot}, holds="placement study", force=args.force)
    spec = parse_scheduler(args.scheduler)
    if spec != "serial":
        from problems.placement.cluster import require_dask

        require_dask()
    from problems.placement.sweep import CHUNK_MAX_PLACEMENTS

    if args.chunk is not None and not 1 <= args.chunk <= CHUNK_MAX_PLACEMENTS:
        raise InputError(
            f"--chunk {args.chunk}: expected a positive number of placements per chunk, at most {CHUNK_MAX_PLACEMENTS}"
        )
    problem = load_problem(args.problem)
    if args.robot is not None:
        problem = problem.with_robot(args.robot)
    grid = grid_for(problem, args.grid, args.top)
    print(
        f"placement study of {problem.name} (robot {problem.robot.name}): {grid.size} placements "
        f"({' × '.join(f'{n} {k}' for k, n in zip(('x', 'y', 'z', 'yaw', 'tilt'), grid.shape))}), scheduler {spec}"
    )
    with report_progress() as prog:
        st = study(problem, grid, spec, args.chunk, progress=prog, optimise=not args.no_optimise)
        if st.status is StudyStatus.SWEEP_FAILED:  # the cluster failed (no workers, died, gone)
            raise ClusterError(f"place: {st.reason}")
        if not st.ok:
            raise InfeasibleError(f"place: {st.reason}{_collision_reason(st)}")
        written = write_study(st, args.out, with_report=not args.no_report)
    print_study(st)
    print(
        f"wrote {len(written)} files into {args.out} (summary.json, scores.csv, ranking.csv"
        f"{', report.html, figures/' if not args.no_report else ''})"
    )
    return 0


def print_study(st: Any) -> None:
    """The sweep's figures, the ranking head, the full plans and the improvement."""
    from planner.placement import collision_lines, distinct_positions
    from problems.placement.grid import placement_label

    s = st.summary()
    sw = s["sweep"]
    print(
        f"  {sw['poses']:,} poses ({sw['poses_per_placement']} per placement) in {sw['elapsed_s']:.3g} s: "
        f"{sw['poses_per_second']:,.0f} poses/s on {sw['workers']} worker(s), {sw['chunks']} chunk(s) of "
        f"{sw['chunk_placements']} placements{'' if sw['compiled'] else ' (CasADi virtual machine)'}"
    )
    counts = {k: v for k, v in sw["status_counts"].items() if k != "collision" or s["collisions"]["checked"]}
    print("  placements: " + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in counts.items()))
    for line in collision_lines(s):
        print(f"  {line}")
    print(
        "  best base positions (sweep: RMS / max load-induced TCP error of the best branch; rank among all placements):"
    )
    rank_of = {int(i): r + 1 for r, i in enumerate(st.ranked)}
    for i in distinct_positions(st.ranked, st.sweep.placements, max(3, st.grid.top)):
        e = st.scores_of(i)
        print(
            f"    {rank_of[i]:>3}. {placement_label(st.sweep.placements[i])}: branch {e['best_branch']}, "
            f"{e['rms_error_mm']:.4g} / {e['max_error_mm']:.4g} mm, joint margin {e['joint_margin_deg']:.3g} deg, "
            f"singular margin {e['singular_margin']:.3g}"
        )
    b = s["baseline"]
    if st.baseline.status_of(0).ok:
        print(
            f"  as written (x=0, y=0): branch {b['best_branch']}, {b['rms_error_mm']:.4g} / {b['max_error_mm']:.4g} mm"
        )
    else:
        print(f"  as written (x=0, y=0): infeasible ({b['status_reason']})")
    if s["improvement_rms_factor"] is not None:
        print(
            f"  the best placement cuts the RMS load-induced error {s['improvement_rms_factor']:.3g}x "
            "against the problem as written (sweep)"
        )
    for w in s["warnings"]:
        print(f"  warning: {w}")
    with_cell = s["collisions"]["checked"]
    print(
        "  full plans (error before compensation max / RMS, after compensation max, duration"
        + (", smallest clearance to the cell):" if with_cell else "):")
    )
    for plan, p in zip(st.plans, s["plans"]):
        h = p["plan"]
        if not plan.result.ok:
            print(f"    {p['label']:<10} {p['placement_text']}: {p['plan_status']}: {h.get('reason')}")
            continue
        dur = "not timed" if h.get("duration_s") is None else f"{_num(h['duration_s'])} s"
        print(
            f"    {p['label']:<10} {p['placement_text']}: branch {h['branch']}, {_num(h['error_before_max_mm'])} / "
            f"{_num(h['error_before_rms_mm'])} mm -> {_num(h['error_after_max_mm'])} mm, {dur}"
            + (_clearance_text(p.get("clearance")) if with_cell else "")
        )


def _clearance_text(c: dict[str, Any] | None) -> str:
    """``, clearance 23.4 mm (link 3 – table)`` of a full plan's entry (empty when none recorded)."""
    if c is None or c["min_clearance_mm"] is None:
        return ", clearance not recorded"
    return f", clearance {c['min_clearance_mm']:.1f} mm ({c['pair']})"


def _collision_reason(st: Any) -> str:
    """The tail of the no-feasible error with a cell: the placements set aside for collision, by reason."""
    c = st.collisions()
    if not c["checked"] or not c["set_aside"] or c["base_on_object"] is None:
        return ""
    return (
        f"; of the {c['set_aside']} set aside for collision, {c['base_on_object']} have the base overlapping an "
        f"object and {c['every_branch_colliding']} every flip-free branch colliding"
    )


def _num(v: Any) -> str:
    """A headline value as printed: a number to 4 significant digits, a word (``0 (numerical)``) as is."""
    return f"{v:.4g}" if isinstance(v, (int, float)) and not isinstance(v, bool) else str(v)
