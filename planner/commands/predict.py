"""``compplan predict`` and ``compplan compensate``: an identified model applied to commands, with the
predicted standard deviation of every row and the rows where the model extrapolates
(``docs/cli.md``, ``docs/identification.md`` sections 8 and 10)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from planner.commands.common import check_output, releases_outputs
from planner.commands.identify import add_csv_options, print_notes, read_table

#: Sub-commands defined here.
COMMANDS = ("predict", "compensate")
#: Rows outside the identified joint ranges named in the warning of predict / compensate (the rest counted).
OUTSIDE_ROWS_NAMED = 5
#: The text column naming a row's joints outside the identified ranges (empty inside).
OUTSIDE_COLUMN = "outside_range"


def _add_campaign_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--campaign",
        default=None,
        help="with a model identified from several campaigns: the campaign whose registration to use "
        "(default: the reference campaign's, the model's own)",
    )


def _model_for(args: argparse.Namespace) -> Any:
    """The model of ``--model`` with the registration of ``--campaign`` (an unknown name is an
    :class:`InputError` naming the campaigns the model has)."""
    from models.arm_file import load_model
    from models.errors import InputError

    model = load_model(args.model)
    if args.campaign is None:
        return model
    try:
        return model.for_campaign(args.campaign)
    except KeyError:
        names = model.campaign_names()
        has = (
            f"its campaigns are {', '.join(names)}"
            if names
            else "it was identified from one campaign (its registration is the model's own)"
        )
        raise InputError(f"--campaign {args.campaign!r}: model {args.model} has no such campaign; {has}") from None


def _sigma_outputs(model: Any, m: Any, q: np.ndarray, frame: str) -> tuple[np.ndarray, list[str], list[str]]:
    """Predicted sigma (N, 3), m, in ``frame`` at the commands ``q``, the rows' ``outside_range``
    texts, and the lines to print: the sigma's summary (or why there is none) and a warning naming
    up to :data:`OUTSIDE_ROWS_NAMED` rows outside the identified ranges."""
    from problems.identify.uncertainty import calibration_text, outside_ranges, predicted_sigma

    ps = predicted_sigma(model, q, m.wrench, frame=frame)
    flags = outside_ranges(model, q)
    lines = []
    out = [i for i, f in enumerate(flags) if f]
    if ps.available:
        norm = np.linalg.norm(ps.sigma_m, axis=1)
        k = int(np.argmax(norm))
        lines.append(
            f"  predicted sigma ({frame} frame, per axis): mean {ps.sigma_m.mean() * 1e3:.4f} mm, largest "
            f"{ps.sigma_m.max() * 1e3:.4f} mm (line {int(m.line[k])}); {len(out)} row(s) outside the "
            f"identified joint ranges; {calibration_text(model)}"
        )
        if ps.excluded:
            lines.append(f"  {ps.excluded_text()}")
    elif model.effects or not model.is_nominal:  # a plain robot file: the columns say nan (docs/cli.md)
        lines.append(
            "  note: no predicted sigma (columns nan): the model file has no parameter covariance (written "
            "before format 2); identify again to get it"
        )
    if out:
        named = "; ".join(f"line {int(m.line[i])}: {flags[i]}" for i in out[:OUTSIDE_ROWS_NAMED])
        more = f" and {len(out) - OUTSIDE_ROWS_NAMED} more" if len(out) > OUTSIDE_ROWS_NAMED else ""
        lines.append(
            f"compplan: warning: {len(out)} row(s) outside the joint ranges the model was identified on "
            f"(extrapolated; column outside_range): {named}{more}"
        )
    return ps.sigma_m, flags, lines


def _print_lines(lines: list[str]) -> None:
    for line in lines:
        print(line, file=sys.stderr if line.startswith("compplan: warning") else sys.stdout)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "predict",
        help="predicted measurement of commands under loads",
        description="The predicted measurement (x, y, z of the measured point, measurement frame) of joint "
        "commands under loads, by an identified model: one output row per input row (docs/cli.md).",
    )
    p.add_argument("--model", required=True, help="identified model file (or a plain robot file)")
    p.add_argument("--input", required=True, help="CSV with q1..q6 and fx..mz (optional t, temperature)")
    p.add_argument(
        "--out",
        required=True,
        help="CSV to write: x, y, z and sigma_x, sigma_y, sigma_z (m, measurement frame); outside_range "
        "(text: the joints outside the identified ranges, empty inside)",
    )
    _add_campaign_option(p)
    add_csv_options(p, "--input")
    p.set_defaults(func=run_predict)

    p = sub.add_parser(
        "compensate",
        help="commands that put the real TCP on its targets under the load",
        description="Joint commands that put the real TCP on its targets under the load, by an identified "
        "model: one compensated q1..q6 row per input row; the targets as --targets-frame says (docs/cli.md).",
    )
    p.add_argument("--model", required=True, help="identified model file (or a plain robot file)")
    p.add_argument(
        "--input",
        required=True,
        help="CSV with q1..q6 (commands) and fx..mz; x, y, z for --targets-frame base/measurement",
    )
    p.add_argument(
        "--out",
        required=True,
        help="CSV to write: q1..q6 (rad), compensated; sigma_x, sigma_y, sigma_z (m, base frame); outside_range "
        "(as for predict)",
    )
    _add_campaign_option(p)
    p.add_argument(
        "--targets-frame",
        choices=("nominal", "base", "measurement"),
        default="nominal",
        help="the targets: 'nominal' (default), the nominal-FK TCP poses of q1..q6; 'base', TCP "
        "positions x, y, z in the robot base frame; 'measurement', positions x, y, z of the "
        "measured point in the measurement frame (exact there even for unregistered data). "
        "Orientation: that of the nominal TCP of q1..q6, which also seed the solve",
    )
    p.add_argument(
        "--strict",
        action="store_true",
        help="fail (nothing written) if any row cannot be compensated; default: write every row "
        "(the best command) and warn naming the rows",
    )
    add_csv_options(p, "--input")
    p.set_defaults(func=run_compensate)


@releases_outputs
def run_predict(args: argparse.Namespace) -> int:
    """Predicted measurement (measurement frame) of the commands of ``--input``."""
    check_output(args.out, {"--model": args.model, "--input": args.input}, kind="file")
    from planner.output import atomic_write_bytes
    from models.effects import effect as fx_effect
    from models.effects import get_const
    from problems.identify import check_command_limits, predict
    from problems.measurements import commands_csv

    model = _model_for(args)
    m = read_table(args, args.input, require_position=False)
    check_command_limits(model, m)  # a command the robot cannot run has no prediction
    p = predict(model, m)
    sigma, flags, lines = _sigma_outputs(model, m, m.q, "measurement")
    header = ["x", "y", "z", "sigma_x", "sigma_y", "sigma_z"]
    table = np.hstack([p, sigma])
    atomic_write_bytes(args.out, commands_csv(header, table, {OUTSIDE_COLUMN: flags}).encode())
    print_notes(m)
    for name in model.active_effects:  # an effect's caveats about the commanded angles (none ships one now)
        for line in fx_effect(name).angle_caveats(model.parameter, lambda k: get_const(model.const, k), m.q):
            print(f"compplan: warning: {line.replace('waypoint', 'row')}", file=sys.stderr)
    print(
        f"predict: {m.n} rows, effects {', '.join(model.effects) or 'none'}"
        + (f", campaign {args.campaign}" if args.campaign else "")
        + f"; wrote {args.out} (x, y, z and sigma_x, sigma_y, sigma_z in m, measurement frame)"
    )
    _print_lines(lines)
    if m.p is not None:  # measured rows: the error of the prediction, as calibration results are quoted
        from planner.commands.identify import euclidean_line
        from problems.identify.position_error import frame_words, position_errors

        from problems.identify.transfer import holds_text, where_it_holds

        err = position_errors(p, m.p, frame_words(model, args.campaign), m.line)
        print(f"  {euclidean_line(None, err.to_mm_dict(), f'measured x, y, z of {args.input}')}")
        holds = where_it_holds(model, m.q, m.wrench, p - m.p, sigma)  # the sigma written above, not recomputed
        print(f"  measured x, y, z of {args.input}: {holds_text(holds)}")
    return 0


@releases_outputs
def run_compensate(args: argparse.Namespace) -> int:
    """Compensated commands for the targets of ``--input`` (``--targets-frame``); warnings on stderr."""
    check_output(args.out, {"--model": args.model, "--input": args.input}, kind="file")
    from models.errors import InfeasibleError
    from planner.output import atomic_write_bytes
    from problems.identify import compensate_targets
    from problems.measurements import commands_csv

    model = _model_for(args)
    m = read_table(args, args.input, require_position=False)
    out = compensate_targets(model, m, args.targets_frame)
    failed = not out.status.usable
    if failed and args.strict:
        raise InfeasibleError(f"{args.input}: {out.reason}; nothing written")
    sigma, flags, lines = _sigma_outputs(model, m, out.q_command, "base")
    header = [f"q{i}" for i in range(1, 7)] + ["sigma_x", "sigma_y", "sigma_z"]
    table = np.hstack([out.q_command, sigma])
    atomic_write_bytes(args.out, commands_csv(header, table, {OUTSIDE_COLUMN: flags}).encode())
    if failed:
        lines = ", ".join(str(int(m.line[i])) for i in out.failed_rows[:10])
        print(f"compplan: warning: {out.reason}; input lines {lines}", file=sys.stderr)
    for w in out.warnings:
        print(f"compplan: warning: {w}", file=sys.stderr)
    print_notes(m)
    print(
        f"compensate: {m.n} rows, targets {out.targets_frame.value} frame, status {out.status.value}; "
        f"wrote {args.out} (q1..q6 in rad; sigma_x, sigma_y, sigma_z in m, base frame)"
    )
    _print_lines(lines)
    return 0
