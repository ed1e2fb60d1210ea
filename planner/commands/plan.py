"""``compplan plan`` and ``compplan pose``: stiffness-optimal posture, compensation and timing."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from planner.commands.common import add_force_argument, check_output, print_error_table, releases_outputs
from planner.commands.export import add_export_argument, plan_exports


def _dt(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--dt must be a number of seconds, got {text!r}") from None
    from problems.timing import DT_MAX_S

    if not (0.0 < v <= DT_MAX_S) or not math.isfinite(v):
        raise argparse.ArgumentTypeError(
            f"--dt must be in (0, {DT_MAX_S:g}] s (e.g. 0.002, 0.004, 0.008), got {text!r}"
        )
    return v


def with_dt(problem: Any, dt: float) -> Any:
    """The problem at the controller period ``--dt`` (s); a period one of its timing methods
    refuses is an error naming ``--dt``, the method and its bound."""
    from models.errors import InputError
    from problems.timing import get_method

    for m in problem.timing.methods:
        bound = get_method(m).dt_max_s
        if dt > bound:
            raise InputError(f"--dt {dt:g} s: timing method {m!r} accepts a controller period of at most {bound:g} s")
    return problem.with_timing(dt=dt)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plan",
        help="stiffness-optimal branch and posture, exact compensation and timing of a problem file",
        description="Plan a problem file (or a shipped problem): the stiffness-optimal IK branch and posture "
        "along its path, exact compensation of the load-induced deflection, timing of the controller's "
        "trajectory; writes summary.json, the CSV files, the report and any --export into --out (docs/cli.md).",
    )
    p.add_argument("problem", help="problem file (TOML) or the name of a shipped problem")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument(
        "--dt", type=_dt, default=None, help="controller period in s (default: the problem's timing.dt, else 0.008)"
    )
    p.add_argument(
        "--robot",
        default=None,
        help="arm model to plan with instead of the problem's robot: a built-in name, a robot file or "
        "an identified model file (compplan identify --out MODEL); the problem's tool is kept",
    )
    p.add_argument("--no-optimise", action="store_true", help="branch choice only: analytic postures, no NLP")
    p.add_argument(
        "--no-figures",
        action="store_true",
        help="skip branches.png and trajectory.png (written only with --no-report; the report has the same figures)",
    )
    p.add_argument(
        "--no-report", action="store_true", help="skip the report (report.html, report.md, figures/) written at the end"
    )
    add_export_argument(p)
    add_force_argument(p)
    p.set_defaults(func=run)

    q = sub.add_parser(
        "pose",
        help="single-pose query: the stiffness-optimal posture for one waypoint of a problem",
        description="The stiffness-optimal posture for one waypoint of a problem: every IK branch with its "
        "status, load-induced TCP error (analytic and optimised) and joint angles; --out writes pose.json.",
    )
    q.add_argument("problem", help="problem file (TOML) or the name of a shipped problem")
    q.add_argument("--waypoint", type=int, default=0, help="waypoint index k (default 0)")
    q.add_argument("--robot", default=None, help="arm model instead of the problem's robot (as for plan)")
    q.add_argument("--out", default=None, help="write pose.json into this folder")
    add_force_argument(q)
    q.set_defaults(func=run_pose)


#: A warning longer than this (characters) is cut on the terminal at a clause boundary; the summary
#: and the report keep it whole (a wall of text of ~2000 characters listing 21 parameters was one
#: "line" before).
WARNING_TERMINAL_CHARS = 300


def terminal_warning(text: str, limit: int = WARNING_TERMINAL_CHARS) -> str:
    """``text`` as one terminal line: whole when short, else cut after its last ``"; "`` or ``", "``
    before ``limit`` characters and pointed to its full text in ``summary.json``."""
    if len(text) <= limit:
        return text
    head = text[:limit]
    cut = max(head.rfind("; "), head.rfind(", "), head.rfind(": "))
    head = head[: cut if cut > limit // 2 else limit].rstrip(" ,;:")
    return f"{head} ... (in full: summary.json 'warnings')"


def print_plan(res: Any, out: str | Path | None, names: list[str], view: Any = None) -> None:
    """Print the branch table, the gains, the error table and the timing of a plan
    (``view``: its :class:`~planner.plan.RunView`, when the caller has it)."""
    from planner.report.tables import load_words

    s = (res.view() if view is None else view).summary
    _print_problem(res, s)
    _print_branches(res.posture, s)
    if "cell" in s:
        for line in cell_lines(s["cell"]):
            print(line)
    if s["model"].get("identified") and s.get("model_sigma"):
        print(s["model_sigma"]["text"])
    print_error_table(
        [
            ("before compensation", s["error_before"]["max_mm"], s["error_before"]["rms_mm"]),
            ("after closed form", s["error_after"]["closed_form"]["max_mm"], s["error_after"]["closed_form"]["rms_mm"]),
            ("after exact", s["error_after"]["exact"]["max_mm"], s["error_after"]["exact"]["rms_mm"]),
        ],
        f"TCP position error of the chosen posture, load: {load_words(s)}",
    )
    if res.trajectories:
        _print_timing(res, s)
    for w in s["warnings"]:
        print(f"warning: {terminal_warning(w)}")
    _print_headline(s["headline"])
    if out is not None:
        print(f"wrote {Path(out)}/: {', '.join(names)}")


def _print_problem(res: Any, s: dict[str, Any]) -> None:
    """The problem, the arm model and the program (``s``: the plan's summary)."""
    pr, md = res.problem, s["model"]
    print(
        f"problem {pr.name} ({pr.source}): robot {pr.robot.name}, {pr.n} waypoints, "
        f"rule {pr.rule.value}; {res.posture.freedom_note}"
    )
    print(f"arm model: {md['file'] or pr.robot.name}; effects: {', '.join(md['effects'])}")
    if "program" in s:
        pg = s["program"]
        print(
            f"program {pg['file']} ({pg['kind']}): {pg['n_lines']} lines with moves, {pg['n_waypoints']} waypoints, "
            f"{pg['n_stops']} stops, path tolerance {pg['path_tolerance_mm']:g} mm ({pg['path_tolerance_source']})"
            + (f"; {pg['units_note']}" if pg["units_note"] else "")
        )


def _print_branches(ps: Any, s: dict[str, Any]) -> None:
    """The branch table (``ps``: the posture result), the rejected branches and the chosen one's gains."""
    w = max([8] + [len(lab) + 2 for lab in ps.labels])
    print(
        f"  {'branch':<{w}}{'status':<21}{'analytic RMS':>14}{'optimised RMS':>15}{'cost [m^2]':>13}"
        f"{'iter':>6}{'NLP [ms]':>10}"
    )
    print(f"  {'':<{w}}{'':<21}{'(first order: |S C(q) F|, the NLP objective)':>29}")
    for r in ps.branches.values():
        mark = " *" if r.branch == ps.chosen else ("  (default)" if r.branch == ps.default else "")
        ana = f"{r.rms_error_analytic_m * 1e3:.4f} mm" if np.isfinite(r.rms_error_analytic_m) else "—"
        print(
            f"  {r.label:<{w}}{r.status.value:<21}{ana:>14}{r.rms_error_m * 1e3:>12.4f} mm{r.cost:>13.4g}"
            f"{r.iterations:>6}{r.solve_time_s * 1e3:>10.1f}{mark}"
        )
    for b, why in ps.rejected.items():
        print(f"  {ps.labels[b]:<{w}}rejected: {why}")
    g = s.get("gain", {})
    vs_default = g.get("vs_default")
    default = (
        f"gain x{vs_default:.3f} over the default branch at its analytic posture"
        if vs_default is not None and np.isfinite(vs_default)
        else "no gain over the default branch (the branch nearest home has no usable posture)"
    )
    print(
        f"chosen branch {s['chosen_branch']} (default {s['default_branch'] or 'none usable'}): RMS load-induced "
        f"error {ps.best.rms_error_m * 1e3:.4f} mm to first order (exact equilibrium: the table below); "
        f"{default}, x{g.get('vs_best_analytic', float('nan')):.3f} over the best analytic posture"
    )


def _print_timing(res: Any, s: dict[str, Any]) -> None:
    """Each method's duration, peak limit ratios, binding limit and, for a program, its feed."""
    from problems.timing.limit_use import describe_binding

    print(f"timing at dt = {res.problem.timing.dt * 1e3:g} ms (peak |value|/limit over the joints):")
    for m, tr in res.trajectories.items():
        lr = tr.limit_ratio
        print(
            f"  {m:<12} {tr.duration_s:8.3f} s   velocity {np.max(lr['velocity']):.3f}   acceleration "
            f"{np.max(lr['acceleration']):.3f}   jerk {np.max(lr['jerk']):.3f}"
            + ("   -> trajectory.csv" if m == res.controller else "")
        )
        print(f"  {'':<12} {describe_binding(s['timing'][m]['limit_use'])}")
        f = s.get("program", {}).get("feed", {}).get(m)
        if f:
            ratio = f["cutting_time_over_programmed"]
            print(
                f"  {'':<12} feed: cutting moves take {f['cutting_time_s']:.3f} s"
                + (f" = x{ratio:.3f} length/F" if ratio is not None else "")
                + f" (stops included); peak TCP speed {f['peak_feed_ratio']:.3f} F; "
                f"{len(f['slowed_lines'])} line(s) slowed"
                + (
                    f" ({len(f['slowed_by_limit'])} by a joint limit"
                    + (", the others by what surrounds them)" if f.get("n_lines_slowed_by_neighbours") else ")")
                    if f.get("slowed_by_limit") is not None and f["slowed_lines"]
                    else ""
                )
                + (
                    f"; samples at most {f['path_deviation_mm'] * 1e3:.2f} µm from the programmed path (tolerance "
                    f"{s['program']['path_tolerance_mm'] * 1e3:.3g} µm)"
                    if f.get("path_deviation_mm") is not None
                    else ""
                )
            )


def _print_headline(h: dict[str, Any]) -> None:
    """The summary's headline (``h``), and the dynamic compensation's when the plan ran it."""
    from planner.numbers import format_number, mm_text

    dur = (
        f", duration {format_number(h['duration_s'])} s ({h['duration_method']})"
        if h.get("duration_s") is not None
        else ""
    )
    print(
        f"headline: {h['status']}, branch {h['branch']} ({h.get('branch_posture') or ''}), TCP error max "
        f"{mm_text(h['error_before_max_mm'])} before -> {mm_text(h['error_after_max_mm'])} after exact "
        f"compensation{dur}"
    )
    if h.get("dynamic_compensation"):  # the stage's own headline (summary.json), not recomputed here
        from planner.dynamic import headline_text

        print(f"  dynamic compensation: {headline_text(h['dynamic_compensation'])}")


def cell_lines(c: dict[str, Any]) -> list[str]:
    """The terminal's lines for the cell (``summary.json`` ``cell``): the smallest clearance at the
    waypoints and along the controller's trajectory, with the pair and where; the choice's price."""
    objs = ", ".join(o["name"] + (" (workpiece)" if o["role"] == "workpiece" else "") for o in c["objects"])
    parts = []
    w, tr = c.get("waypoints"), c.get("trajectory")
    if w and w["min_clearance_mm"] is not None:
        parts.append(f"{w['min_clearance_mm']:.1f} mm at the waypoints ({w['pair']}, waypoint {w['index']})")
    if tr and tr["min_clearance_mm"] is not None:
        parts.append(f"{tr['min_clearance_mm']:.1f} mm along {tr['method']} ({tr['pair']}, t = {tr['time_s']:.3f} s)")
    out = [
        f"cell: {objs}; clearance {c['clearance_mm']:g} mm; smallest distance "
        + ("; ".join(parts) if parts else "not checked")
        + f"; load-induced deflection moves the arm by up to {c['deflection_margin_mm']:.3g} mm"
    ]
    if c.get("choice_note"):
        out.append(f"cell: {c['choice_note']}")
    return out


@releases_outputs
def run(args: argparse.Namespace) -> int:
    from planner.plan import plan
    from problems.problem import load_problem

    check_output(args.out, {"PROBLEM": args.problem, "--robot": args.robot}, holds="plan", force=args.force)
    from planner.progress import report_progress

    with report_progress() as bars:  # reading a program and predicting its cut takes seconds
        bars("reading the problem", 0, 1)
        problem = load_problem(args.problem)
        bars("reading the problem", 1, 1)
    if args.robot is not None:
        problem = problem.with_robot(args.robot)
    if args.dt is not None:
        problem = with_dt(problem, args.dt)
    with report_progress() as bars:
        res = plan(problem, verbose=args.verbose, optimise=not args.no_optimise, progress=bars)
    return finish_run(res.raise_for_status(), args)


def finish_run(res: Any, args: argparse.Namespace) -> int:
    """Write a successful plan's outputs, print its summary and write the report (plan, demo),
    all from one view of the run (summary and tables computed once)."""
    from planner.plan import output_names, write_outputs

    # The report draws the same figures (5 and 6) and more: the quick PNGs are only
    # worth their time when no report is written.
    quick_figures = args.no_report and not args.no_figures
    view = res.view()
    exports = plan_exports(res, getattr(args, "export", []))
    report: dict[str, bytes] = {}
    if not args.no_report:  # built first: the plan's files and its report are swapped in together
        from planner.progress import report_progress
        from planner.report.writer import report_files

        with report_progress() as prog:
            report = report_files(res.record(args.out, view), prog)
    write_outputs(res, args.out, with_figures=quick_figures, extra={**exports, **report}, view=view)
    print_plan(res, args.out, output_names(res, quick_figures) + list(exports), view)
    if report:
        out = Path(args.out)
        print(f"wrote {out / 'report.html'} (self-contained), report.md and {out / 'figures'}/ (PNG, PDF)")
    return 0


@releases_outputs
def run_pose(args: argparse.Namespace) -> int:
    from models.errors import InputError
    from planner.output import OutputSet
    from problems.posture import PostureStatus, optimal_pose
    from problems.problem import load_problem

    if args.out:
        check_output(args.out, {"PROBLEM": args.problem, "--robot": args.robot}, holds="pose", force=args.force)
    pr = load_problem(args.problem)
    if args.robot is not None:
        pr = pr.with_robot(args.robot)
    k = args.waypoint
    if not 0 <= k < pr.n:
        raise InputError(f"pose: --waypoint {k} is outside the problem's waypoints 0..{pr.n - 1}")
    res = optimal_pose(
        pr.model,
        pr.positions[k],
        pr.rotations[k],
        pr.rule,
        pr.load.rows(pr.n)[k],
        cone_half_angle=pr.cone_half_angle,
        home_q=pr.home_q,
        settings=pr.solver,
        scan=pr.scan,
        verbose=args.verbose,
    )
    if not res.ok:
        from models.errors import InfeasibleError, UnreachableError

        cls = UnreachableError if res.status is PostureStatus.UNREACHABLE else InfeasibleError
        raise cls(f"pose: waypoint {k} of '{pr.name}': {res.status.value}: {res.reason}")
    p = pr.positions[k]
    print(
        f"waypoint {k} of {pr.name}: TCP ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m, rule {pr.rule.value}, "
        f"F = [{', '.join(f'{float(v):g}' for v in pr.wrench[k])}] (N, N*m, {pr.wrench_frame} frame)"
        + (f" + payload {pr.payload_mass_kg:g} kg" if pr.payload_mass_kg else "")
    )
    entries = {}
    wl = max(len(r.label) for r in res.branches.values()) + 2  # aligned columns, whatever the labels
    ws = max(len(r.status.value) for r in res.branches.values()) + 2
    print(f"  {'branch':<{wl}}{'status':<{ws}}{'analytic [mm]':>15}{'optimised [mm]':>16}  q1..q6 [rad]")
    for r in res.branches.values():
        mark = " *" if r.branch == res.chosen else ""
        ana = f"{r.error_analytic_m[0] * 1e3:.4f}" if np.isfinite(r.error_analytic_m[0]) else "—"
        print(
            f"  {r.label:<{wl}}{r.status.value:<{ws}}{ana:>15}{r.error_m[0] * 1e3:>16.4f}  "
            f"{' '.join(f'{v:8.4f}' for v in r.q[0])}{mark}"
        )
        entries[r.label] = {
            "status": r.status.value,
            "reason": r.reason,
            "q": r.q[0],
            "error_m": float(r.error_m[0]),
            "error_analytic_m": float(r.error_analytic_m[0]),
        }
    if args.out:
        out = OutputSet(args.out)
        from planner.provenance import problem_input, provenance, robot_input

        md = pr.model.describe()
        prov = provenance(
            [problem_input(pr.source), robot_input(md.get("file") or pr.robot_spec, sha256=md.get("sha256"))]
        )
        out.add_json(
            "pose.json",
            {
                "provenance": prov,
                "problem": pr.name,
                "waypoint": k,
                "position": p,
                "rule": pr.rule.value,
                "wrench": pr.wrench[k],
                "chosen_branch": res.best.label,
                "branches": entries,
                "freedom": res.freedom_note,
            },
        )
        out.publish()
        print(f"wrote {Path(args.out)}/pose.json")
    return 0
