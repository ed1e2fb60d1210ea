"""``compplan design``: choose the poses of a measurement campaign for a region (optimal experiment design).

The library (:func:`problems.identify.design.design_campaign`) chooses ``--n`` rows of a pool of
joint configurations (``--pool``, a measurement/command file) or of a pool around a task's path
(``--problem``); this module reads the files, writes the campaign CSV (the chosen rows in travel
order, ``x, y, z`` left empty for the measurements) and the optional report, and prints the summary.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
from pathlib import Path
from typing import Any

import numpy as np

from planner.commands.common import add_force_argument, check_output, releases_outputs
from planner.commands.identify import add_csv_options, known_arg, print_notes, read_table, seed_arg

#: Sub-commands defined here.
COMMANDS = ("design",)
#: ``--criterion`` words (problems.identify.design.DESIGN_CRITERIA, spelled here so that the
#: parser is built without importing the library).
CRITERIA = ("task", "d")
#: Load columns of the measurement file (docs/measurement-file.md), written when the pool has loads.
LOAD_COLUMNS = ("fx", "fy", "fz", "mx", "my", "mz")
#: Evaluation frame: a pool is predicted in the new campaign's measurement frame; a task runs in
#: the base frame (the registration does not act there).
POOL_FRAME, TASK_FRAME = "measurement", "base"


def _count(text: str) -> int:
    """``--n``: an integer >= 1."""
    try:
        k = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--n {text!r}: expected an integer >= 1") from None
    if k < 1:
        raise argparse.ArgumentTypeError(f"--n {k}: expected an integer >= 1 (the poses to measure)")
    return k


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``design`` sub-command."""
    p = sub.add_parser(
        "design",
        help="choose the poses of a measurement campaign for a region (optimal experiment design)",
        description="Choose N poses to measure from a pool of joint configurations (--pool) or from the "
        "region of a task (--problem): optimal experiment design on the model's identification Jacobian, "
        "task-oriented (the mean predicted variance over the region) or D-optimal; sequential on earlier "
        "campaigns (--data). Writes the chosen configurations in travel order, x, y, z left empty for "
        "the measurements (docs/cli.md).",
    )
    p.add_argument("--model", required=True, help="identified model file (format 2: with its parameter covariance)")
    p.add_argument(
        "--data",
        action="append",
        default=[],
        metavar="EARLIER.csv",
        help="a campaign measured so far (repeat for several): what it already determines counts",
    )
    p.add_argument("--pool", default=None, help="CSV of candidate configurations q1..q6 (optional load columns)")
    p.add_argument(
        "--problem",
        default=None,
        help="task problem file (or shipped name): the region is its path on the planner's branch, the pool "
        "configurations around it",
    )
    p.add_argument("--n", required=True, type=_count, help="poses to choose, 1 .. the usable pool rows")
    p.add_argument("--out", required=True, help="campaign CSV to write (chosen rows in travel order)")
    p.add_argument("--report", default=None, help="report folder (report.json, report.md, report.html)")
    p.add_argument(
        "--criterion",
        choices=CRITERIA,
        default="task",
        help="'task' (default): minimise the mean predicted variance of the position over the region "
        "(the task's path, or the pool); 'd': D-optimal (maximise log det of the information)",
    )
    p.add_argument(
        "--shared",
        type=known_arg,  # the words of identify's --known and --shared
        default=(),
        help="'registration': the new campaign will be measured in the frame of the model's own registration "
        "(its reference campaign, the last --data campaign for a model without campaigns) (the "
        "instrument does not move; identify it with --shared registration); default: a frame of its own",
    )
    p.add_argument("--seed", type=seed_arg, default=0, help="seed of the task pool and the random baseline (default 0)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (the design draws none)")
    add_csv_options(p, "--data and --pool")
    add_force_argument(p, "--report")
    p.set_defaults(func=run_design)


def _read_pool(args: argparse.Namespace, path: str) -> Any:
    """The pool: a measurement/command file read without requiring positions or loads."""
    from problems.measurements import read_measurements

    return read_measurements(
        path,
        require_position=False,
        require_wrench=False,
        dialect=args.csv_dialect,
        joint_names=args.joint_names,
        file_format=args.file_format,
    )


def _inputs(args: argparse.Namespace) -> dict[str, Any]:
    out: dict[str, Any] = {"--model": args.model, "--pool": args.pool, "--problem": args.problem}
    for i, d in enumerate(args.data):
        out["--data" if len(args.data) == 1 else f"--data #{i + 1}"] = d
    return out


@releases_outputs
def run_design(args: argparse.Namespace) -> int:
    """Design the campaign, write the CSV (and the report), print the summary."""
    from models.errors import InputError

    if (args.pool is None) == (args.problem is None):
        got = "neither" if args.pool is None else "both"
        raise InputError(f"give exactly one of --pool POSES.csv or --problem TASK.toml (got {got})")
    inputs = _inputs(args)
    check_output(args.out, inputs, kind="file", outputs={"--report": args.report})
    if args.report:
        check_output(
            args.report,
            inputs,
            "folder",
            "--report",
            {"--out": args.out},
            holds="campaign design report",
            force=args.force,
        )
    import numpy as np

    from models.arm_file import load_model
    from problems.identify.design import design_campaign, pool_guards
    from problems.identify.design_region import TASK_POOL_POSES, task_region

    model = load_model(args.model)
    if model.covariance is None or not model.covariance_names:
        raise InputError(
            f"--model {args.model}: has no parameter covariance (a nominal robot, or a model file written "
            "before format 2); re-identify it with this version of compplan (compplan identify)"
        )
    earlier = [read_table(args, d) for d in args.data]
    region = None
    if args.pool is not None:
        pool = _read_pool(args, args.pool)
        eval_q = eval_w = None
        frame = POOL_FRAME
    else:
        region = task_region(args.problem, model, TASK_POOL_POSES, args.seed)
        pool, eval_q, eval_w = region.pool, region.eval_q, region.eval_wrench
        frame = TASK_FRAME
    usable, guards = pool_guards(model, pool)
    n_usable = int(np.count_nonzero(usable))
    if args.n > n_usable:
        what = args.pool if args.pool is not None else f"the task region of {args.problem}"
        aside = sum(g.count for g in guards.values())
        raise InputError(
            f"--n {args.n}: more than the {n_usable} usable rows of the pool {what} ({pool.n} rows, {aside} set "
            f"aside by the guards); give --n between 1 and {n_usable}"
        )
    des = design_campaign(
        model,
        pool,
        args.n,
        eval_q=eval_q,
        eval_wrench=eval_w,
        eval_frame=frame,
        earlier=earlier,
        criterion=args.criterion,
        new_registration="registration" not in args.shared,
        seed=args.seed,
    )
    loads = bool(np.any(pool.wrench))
    data = _campaign_csv(des, pool, loads).encode()
    from planner.output import atomic_write_bytes, pending_file

    if args.report:
        with pending_file(args.out, data, "--out"):
            _write_report(args, des, pool, region, loads)
    else:
        atomic_write_bytes(args.out, data)
    print_notes(pool, *earlier)
    _print_summary(args, des, frame)
    return 0


def _campaign_csv(des: Any, pool: Any, loads: bool) -> str:
    """The campaign as a measurement file to complete: ``point`` (``design-001`` ..., in travel
    order), ``extra_pool_line`` (the pool file's line; an ``extra_`` column the reader carries along),
    ``q1..q6`` (rad), ``fx..mz`` (the pool row's load, zero when the pool has none: N, N*m, base
    frame) and empty ``x, y, z`` for the measured point.  Filled in, it is read by ``identify``."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["point", "extra_pool_line"] + [f"q{j}" for j in range(1, 7)] + list(LOAD_COLUMNS) + ["x", "y", "z"])
    width = max(3, len(str(len(des.chosen))))
    for k, i in enumerate(des.chosen):
        row = [f"design-{k + 1:0{width}d}", str(int(pool.line[i]))] + [repr(float(v)) for v in pool.q[i]]
        row += [repr(float(v)) for v in (pool.wrench[i] if loads else np.zeros(6))]
        w.writerow(row + ["", "", ""])
    return buf.getvalue()


def _region_text(des: Any, scratch: bool) -> str:
    mm = 1e3
    before = "nominal model, no earlier data" if scratch else "the earlier data"
    return (
        f"predicted sigma over the region {des.region_sigma_m(des.sigma_before_m) * mm:.4f} mm ({before}) -> "
        f"{des.region_sigma_m(des.sigma_after_m) * mm:.4f} mm with this campaign ({len(des.chosen)} random: "
        f"{des.region_sigma_m(des.sigma_random_m) * mm:.4f} mm)"
    )


def _print_summary(args: argparse.Namespace, des: Any, frame: str) -> None:
    aside = [f"{g.count} set aside {g.reason}" for g in des.guards.values() if g.count]
    extra = "; ".join([f"criterion {des.criterion}", f"{frame} frame", *aside])
    wrote = f"{args.out}" + (f" and {Path(args.report)}/: report.json, report.md, report.html" if args.report else "")
    print(
        f"design: {len(des.chosen)} of {des.n_pool} pool poses ({extra}); {_region_text(des, not args.data)}; "
        f"travel {des.travel_s:.0f} s; wrote {wrote}"
    )
    for note in des.notes:
        if "outside the joint ranges" in note:
            print(f"compplan: warning: {note}", file=sys.stderr)
        elif note.startswith(("loads:", "before: the nominal model")):
            print(f"  {note}")
    if des.status.value == "needs_loads":
        print(f"compplan: warning: design: {des.reason}", file=sys.stderr)
    if des.unidentifiable:
        det = [u.name for u in des.unidentifiable if u.determined_by_earlier]
        not_det = [u.name for u in des.unidentifiable if not u.determined_by_earlier]
        parts = []
        if not_det:
            parts.append(f"not determined by any data: {', '.join(not_det)}")
        if det:
            parts.append(f"determined by the earlier data: {', '.join(det)}")
        print(f"  parameters no pool pose can identify: {'; '.join(parts)}")


# ------------------------------------------------------------------------------ report
def _report_dict(args: argparse.Namespace, des: Any, pool: Any, region: Any, loads: bool) -> dict[str, Any]:
    rows = []
    for k, i in enumerate(des.chosen):
        r: dict[str, Any] = {"pose": k + 1, "pool_line": int(pool.line[i]), "q_rad": pool.q[i].tolist()}
        if loads:
            r["wrench"] = pool.wrench[i].tolist()
        rows.append(r)
    out: dict[str, Any] = {
        "command": "design",
        "units": "SI (m, rad, s); sigma: RMS over the three axes of the parameters' part, m",
        "model": str(args.model),
        "data": list(args.data),
        "pool": args.pool,
        "problem": args.problem,
        "n": len(des.chosen),
        "seed": args.seed,
        "design": des.to_dict(),
        "campaign": rows,
    }
    if region is not None:
        out["task"] = {
            "source": region.source,
            "branch": region.branch,
            "eval_q_rad": region.eval_q.tolist(),
            "eval_wrench": region.eval_wrench.tolist(),
        }
    return out


def _report_md(rep: dict[str, Any], des: Any) -> str:
    mm = 1e3
    d = rep["design"]
    src = f"pool {rep['pool']}" if rep["pool"] else f"task {rep['problem']}"
    lines = [
        "# compplan campaign design",
        "",
        "## Summary",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| status | {d['status']} ({d['reason']}) |",
        f"| model | {rep['model']} |",
        f"| region | {src} ({d['n_eval']} evaluation poses, {d['eval_frame']} frame) |",
        f"| earlier data | {', '.join(rep['data']) or 'none (a design from scratch: before is the nominal model)'} |",
        f"| criterion | {d['criterion']} |",
        f"| chosen | {rep['n']} of {d['n_pool']} pool rows ({d['n_usable']} usable) |",
        f"| predicted sigma over the region, before | {d['region_sigma_before_m'] * mm:.4f} mm |",
        f"| predicted sigma over the region, designed | {d['region_sigma_after_m'] * mm:.4f} mm |",
        f"| predicted sigma over the region, {rep['n']} random (mean of {d['random_trials']}) | "
        f"{d['region_sigma_random_m'] * mm:.4f} mm |",
        f"| log det gain of the information, designed / random | {d['logdet_gain_after']:.2f} / "
        f"{d['logdet_gain_random']:.2f} |",
        f"| travel (at the joint velocity limits) | {d['travel_s']:.1f} s |",
        "",
        "Sigma: the parameters' part of the predicted standard deviation of the position, RMS over the "
        "three axes at each evaluation pose, then RMS over the poses (linearised at the model's parameters).",
        "",
        "## Set aside",
        "",
    ]
    for g in d["guards"].values():
        shown = ", ".join(str(v) for v in g["lines"]) or "-"
        lines.append(f"- {g['count']} row(s) {g['reason']} (first lines: {shown})")
    lines += ["", "## Parameters no pool pose can identify", ""]
    if not d["unidentifiable"]:
        lines.append("- none")
    for u in d["unidentifiable"]:
        by = "determined by the earlier data" if u["determined_by_earlier"] else "not determined by the earlier data"
        lines.append(f"- {u['name']}: {u['reason']}; {by}")
    lines += ["", "## Notes", ""] + [f"- {n}" for n in d["notes"]]
    lines += ["", "## Campaign (travel order)", "", "| pose | pool line | q1..q6 (deg) |", "|---|---|---|"]
    import numpy as np

    for r in rep["campaign"]:
        q = ", ".join(f"{v:.2f}" for v in np.degrees(r["q_rad"]))
        lines.append(f"| {r['pose']} | {r['pool_line']} | {q} |")
    return "\n".join(lines) + "\n"


def _figure_png(des: Any) -> bytes:
    """Predicted sigma per evaluation pose, before / designed / random, mm."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 3.6), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    x = range(1, len(des.sigma_after_m) + 1)
    ax.plot(x, des.sigma_before_m * 1e3, lw=1.2, label="before")
    ax.plot(x, des.sigma_random_m * 1e3, lw=1.2, label=f"{len(des.chosen)} random (mean)")
    ax.plot(x, des.sigma_after_m * 1e3, lw=1.6, label="designed")
    ax.set_xlabel("evaluation pose")
    ax.set_ylabel("predicted sigma [mm]")
    ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _write_report(args: argparse.Namespace, des: Any, pool: Any, region: Any, loads: bool) -> None:
    import base64
    import html

    from planner.identify_report.html import md_block
    from planner.output import OutputSet
    from planner.report.page import PAGE_END, page_head

    rep = _report_dict(args, des, pool, region, loads)
    md = _report_md(rep, des)
    png = _figure_png(des)
    body = md.split("\n", 1)[1]
    page = "\n".join(
        page_head("compplan campaign design")
        + [
            '<figure><img alt="predicted sigma per evaluation pose" '
            f'src="data:image/png;base64,{base64.b64encode(png).decode()}"><figcaption>'
            + html.escape(
                "Predicted sigma (parameters' part, RMS over the axes) per evaluation pose: before the campaign, "
                "after the designed one, and after as many random pool poses (mean over the random subsets), mm."
            )
            + ' File: <a href="figures/sigma.png">PNG</a>.</figcaption></figure>',
            md_block(body),
            PAGE_END,
        ]
    )
    out = OutputSet(args.report)
    out.add_json("report.json", rep)
    out.add_bytes("report.md", md.encode())
    out.add_bytes("report.html", (page + "\n").encode())
    out.add_bytes("figures/sigma.png", png)
    out.publish()
