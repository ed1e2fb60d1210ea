"""``compplan identify | predict | compensate | simulate``: close the loop with measured data.

* ``identify``: fit the declared model (joint stiffness, registration, measured
  point) to a measurement file, add library effects while they explain a
  significant, cross-validated share of the residual, and write the identified
  model (a robot file with an ``[identified]`` table) and a report.
* ``predict``: predicted measurement (measurement frame) of commands under loads.
* ``compensate``: commands that put the real TCP on its targets: the nominal-FK TCP of
  the input's commands (default), TCP positions in the base frame, or positions of the
  measured point in the measurement frame (``--targets-frame``).
* ``simulate``: a measurement campaign from the virtual robot (and its truth file).

Only this module prints; the library reports progress through a callback.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


from planner.commands.common import add_force_argument, check_output, releases_outputs

#: Sub-commands defined here.
COMMANDS = ("identify", "simulate")


def _effects_arg(text: str | None) -> list[str] | None:
    """Effect list of ``--candidates``/``--include`` (``all``, ``none`` or comma-separated)."""
    if text is None:
        return None
    t = text.strip()
    if t in ("", "none"):
        return []
    if t == "all":
        from models.effects import LIBRARY

        return list(LIBRARY)
    return [e.strip() for e in t.split(",") if e.strip()]


def _folds(text: str) -> int:
    """``--folds``: an integer >= 2 (one fold is held out at a time; one fold leaves nothing to fit)."""
    try:
        k = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--folds {text!r}: expected an integer >= 2") from None
    if k < 2:
        raise argparse.ArgumentTypeError(
            f"--folds {k}: expected an integer >= 2 (the cross-validation holds out one fold of poses at a "
            "time and fits the others)"
        )
    return k


def seed_arg(text: str) -> int:
    """``--seed``: an integer >= 0 (NumPy's generators take no negative seed)."""
    try:
        k = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed {text!r}: expected an integer >= 0") from None
    if k < 0:
        raise argparse.ArgumentTypeError(f"--seed {k}: expected an integer >= 0")
    return k


def _joint_names(text: str) -> tuple[str, ...] | None:
    """``--joint-names``: ``none`` (q1..q6), a preset (``ros-ur``) or six comma-separated column names."""
    from models.errors import InputError
    from problems.measurements import resolve_joint_names

    try:
        return resolve_joint_names(text, where="--joint-names")
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_csv_options(p: argparse.ArgumentParser, files: str) -> None:
    """``--format``, ``--csv-dialect`` and ``--joint-names``: how the measurement/command files ``files`` are read."""
    from problems.measurements import DIALECT_CHOICES, FORMAT_CHOICES, JOINT_NAME_PRESETS

    p.add_argument(
        "--format",
        dest="file_format",
        choices=FORMAT_CHOICES,
        default="auto",
        help=f"format of {files}: 'compplan' (the columns of docs/measurement-file.md), 'tracker-dif' (a "
        "tracker export step_order, x_t.., x_dif.., joint_1..joint_6: measured point = target + dif in mm, "
        "joints in deg, no load), 'tracker-dif-reversed' (the same, measured point = target - dif), 'auto' "
        "(default: tracker-dif when the header has all its columns, noted on stderr; else compplan)",
    )
    p.add_argument(
        "--csv-dialect",
        choices=DIALECT_CHOICES,
        default="auto",
        help=f"CSV dialect of {files}: 'comma' (',' separator, '.' decimal point), 'semicolon' (';' "
        "separator, decimal comma), 'auto' (default: ';' in the header and no ',' means "
        "semicolon; a header with both is an error; a detected dialect is noted on stderr)",
    )
    p.add_argument(
        "--joint-names",
        type=_joint_names,
        default=None,
        metavar="NAMES",
        help=f"columns read as q1..q6 in {files}: 'none' (default: q1..q6), a preset "
        f"({', '.join(JOINT_NAME_PRESETS)}: the ROS UR names shoulder_pan_joint, ..., "
        "wrist_3_joint, rad or with _deg) or six comma-separated names, joint 1 first",
    )


def read_table(args: argparse.Namespace, path: str, require_position: bool = True) -> Any:
    """A measurement/command file read with the options ``--format``, ``--csv-dialect`` and ``--joint-names``."""
    from problems.measurements import read_measurements

    return read_measurements(
        path,
        require_position=require_position,
        dialect=args.csv_dialect,
        joint_names=args.joint_names,
        file_format=args.file_format,
    )


def print_notes(*tables: Any) -> None:
    """The readers' notes (a detected dialect, date-times, a joint-name mapping) on stderr,
    one ``compplan: note:`` line each, as the CLI's other notes."""
    for m in tables:
        if m is not None:
            for n in m.notes:
                print(f"compplan: note: {n}", file=sys.stderr)


#: ``--known`` words and the part of the set-up each declares (``identify(known=...)``).
KNOWN_WORDS = {"registration": "registration", "measured-point": "measured_point"}


def known_arg(text: str) -> tuple[str, ...]:
    """``--known`` value: comma-separated words of :data:`KNOWN_WORDS`."""
    words = [w.strip() for w in text.split(",") if w.strip()]
    bad = [w for w in words if w not in KNOWN_WORDS]
    if not words or bad:
        raise argparse.ArgumentTypeError(f"got {text!r}; expected a comma-separated list of {', '.join(KNOWN_WORDS)}")
    return tuple(KNOWN_WORDS[w] for w in words)


def _map_components(text: str) -> tuple[str, ...]:
    """``--map-components`` value: comma-separated components of a joint error map."""
    from models.effects.joint_error_map import MAP_COMPONENTS

    words = [w.strip() for w in text.split(",") if w.strip()]
    bad = [w for w in words if w not in MAP_COMPONENTS]
    if not words or bad:
        raise argparse.ArgumentTypeError(
            f"got {text!r}; expected a comma-separated list of {', '.join(MAP_COMPONENTS)}"
        )
    return tuple(words)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the sub-commands of this module."""
    _add_identify(sub)
    _add_simulate(sub)


def _add_identify(sub: argparse._SubParsersAction) -> None:
    """Add the ``identify`` sub-command."""
    p = sub.add_parser(
        "identify",
        help="identify the model from measurements and report before/after",
        description="Identify joint stiffness (+ registration and measured point for absolute "
        "data) and add library effects while they explain a significant "
        "cross-validated share of the residual.",
    )
    p.add_argument("--robot", required=True, help="built-in robot name or robot file (the declared model)")
    _add_campaign_arguments(p)
    p.add_argument("--out", required=True, help="identified model file to write (robot TOML)")
    p.add_argument("--report", required=True, help="report folder (report.json, report.md, report.html)")
    p.add_argument(
        "--registered",
        action="store_true",
        help="the measurement frame is the base frame and the measured point is the robot's TCP",
    )
    p.add_argument(
        "--known",
        type=known_arg,
        default=(),
        help="comma-separated parts of the set-up known from a calibration and held: 'registration' "
        "(measurement frame = base frame, e.g. a tracker base calibration) and/or 'measured-point' "
        "(measured point, and frame with orientation data, = the robot file's TCP, e.g. a tool "
        "calibration); both = --registered",
    )
    p.add_argument(
        "--map-components",
        type=_map_components,
        default=("theta",),
        help="components of the joint error maps the search proposes, comma-separated from "
        "theta (angular error; the default), d (axial), a (radial), alpha, beta (tilts): runout "
        "and wobble are searched only on request, because from position data their signatures "
        "can absorb structure of other origins",
    )
    p.add_argument(
        "--candidates",
        default=None,
        help="comma-separated library effects the selection may add (default: all; 'none')",
    )
    p.add_argument(
        "--include",
        default=None,
        help="comma-separated effects added without a test (must be identifiable from the data)",
    )
    p.add_argument(
        "--folds",
        type=_folds,
        default=None,
        help="folds of the cross-validation over poses, an integer >= 2 and at most the number "
        "of poses (default 5, fewer when the data have fewer poses)",
    )
    p.add_argument("--validation", default=None, help="held-out measurement CSV to report the RMS on")
    p.add_argument(
        "--truth", default=None, help="truth file of a virtual robot (compplan simulate): compensate and re-measure"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress (bar or stage lines)")
    add_csv_options(p, "--data and --validation")
    add_force_argument(p, "--report")
    p.set_defaults(func=run_identify)


def _add_campaign_arguments(p: argparse.ArgumentParser) -> None:
    """``identify``'s options of its campaigns: the files, the reference, what they share."""
    p.add_argument(
        "--data",
        required=True,
        action="append",
        help="measurement CSV (docs/measurement-file.md); repeat for several campaigns (one robot model, one "
        "registration per campaign named by the file stem; the reference, the model's own, is the campaign "
        "with the most rows unless --reference-campaign names one). The same file twice is refused; rows "
        "that repeat earlier rows exactly are counted once, with a warning",
    )
    p.add_argument(
        "--reference-campaign",
        default=None,
        metavar="NAME",
        help="with several --data campaigns: the campaign (file stem) whose registration is the model's own, "
        "what predict and compensate use without --campaign (default: the one with the most rows)",
    )
    p.add_argument(
        "--shared",
        type=known_arg,  # the words of --known
        default=(),
        help="comma-separated parts of the set-up shared by every --data campaign: 'registration' (the "
        "instrument did not move: one measurement frame, the campaigns are concatenated); 'measured-point' "
        "is always shared",
    )


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` sub-command."""
    p = sub.add_parser(
        "simulate",
        help="measurement campaign from the virtual robot",
        description="A measurement campaign from the virtual robot (poses, loads, effects and noise as the "
        "configuration says): writes the measurement CSV and its truth file (docs/identification.md).",
    )
    p.add_argument("--robot", required=True, help="built-in robot name or robot file")
    p.add_argument("--config", required=True, help="simulation configuration TOML (docs/identification.md)")
    p.add_argument("--out", required=True, help="measurement CSV to write")
    p.add_argument("--truth", default=None, help="truth file to write (default: OUT with .truth.toml)")
    p.add_argument(
        "--seed", type=seed_arg, default=None, help="random seed, an integer >= 0 (default: the config's, else 0)"
    )
    p.set_defaults(func=run_simulate)


class _Bar:
    """The library's ``progress(message, done, total)`` callback: a tqdm bar on a terminal; in a log
    or a pipe one line per stage (the message's part before ``:``, e.g. ``step 3``) when it starts."""

    def __init__(self, enabled: bool) -> None:
        from planner.progress import StageLines, on_terminal

        self.bar: Any = None
        self.enabled = enabled
        # "step 3: fitting joint_springs" and "step 3: fitting gravity" are one stage
        self.lines = None if on_terminal() else StageLines(key=lambda msg: msg.split(":")[0])

    def __call__(self, msg: str, done: int, total: int) -> None:
        from models.interrupts import raise_if_pending

        raise_if_pending()  # a signal lost in a destructor: stop at the next tick
        if not self.enabled:
            return
        if self.lines is not None:
            self.lines(msg, done, total)
            return
        from tqdm import tqdm

        if self.bar is None:
            self.bar = tqdm(total=total, desc="identify", unit="step", leave=False, file=sys.stderr)
        if self.bar.total != total:
            self.bar.total = total
        self.bar.n = min(done, total)
        self.bar.set_postfix_str(msg[:60])
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


@releases_outputs
def run_identify(args: argparse.Namespace) -> int:
    """Identify, write the model file and the report, print the summary."""
    paths = list(args.data) if isinstance(args.data, (list, tuple)) else [args.data]
    inputs = {"--robot": args.robot, "--validation": args.validation, "--truth": args.truth}
    inputs.update({"--data" if k == 0 else f"--data ({k + 1})": p for k, p in enumerate(paths)})
    check_output(args.out, inputs, kind="file", outputs={"--report": args.report})
    check_output(
        args.report, inputs, "folder", "--report", {"--out": args.out}, holds="identification report", force=args.force
    )
    from models import load_robot
    from models.errors import InputError
    from planner.identify_report import write_report
    from planner.output import pending_file
    from models.arm_file import model_toml
    from problems.identify import (
        CV_FOLDS,
        compensation_check,
        validate_on,
    )
    from problems.identify.campaign_merge import campaign_names
    from problems.identify.campaigns import identify_campaigns

    _check_distinct_files(paths)
    robot = load_robot(args.robot)
    datas = [read_table(args, p) for p in paths]
    if args.folds is not None:
        n_poses = sum(len(set(d.pose_groups().tolist())) for d in datas)
        if args.folds > n_poses:
            raise InputError(
                f"--folds {args.folds}: more folds than the {n_poses} poses of {', '.join(paths)} "
                f"(a fold holds whole poses); give --folds between 2 and {n_poses}"
            )
    val = read_table(args, args.validation) if args.validation else None
    truth = None
    if args.truth:
        from problems.virtual import load_truth

        truth = load_truth(args.truth)
    bar = _Bar(not args.no_progress)
    try:
        kwargs = {
            "registered": args.registered,
            "candidates": _effects_arg(args.candidates),
            "include": _effects_arg(args.include) or [],
            "folds": args.folds or CV_FOLDS,
            "progress": bar,
            "known": args.known,
            "map_components": args.map_components,
        }
        # one campaign: the engine as it is (--shared changes nothing), repeated rows dropped
        res = identify_campaigns(
            robot, datas, names=campaign_names(paths), shared=args.shared, reference=args.reference_campaign, **kwargs
        )
    finally:
        bar.close()
    if val is not None:
        res.validation = validate_on(res.model, val)
    if truth is not None:
        res.compensation_check = compensation_check(truth, res.model)
    text = model_toml(res.model)
    with pending_file(args.out, text.encode(), "--out"):  # the model goes in once the report is written
        rep = write_report(res, args.report, model_path=str(args.out), data_path=", ".join(map(str, paths)))
    _print_identify(res, rep, res.data, val, args)
    return 0


def _check_distinct_files(paths: list[str]) -> None:
    """Refuse the same ``--data`` file given twice (its rows would count twice)."""
    from models.errors import InputError

    seen: dict[Path, int] = {}
    for k, p in enumerate(paths):
        key = Path(p).resolve()
        if key in seen:
            raise InputError(
                f"--data {p}: the same file as the earlier --data {paths[seen[key]]}; its rows would count twice "
                "(one campaign given twice): give each campaign once"
            )
        seen[key] = k


def _print_identify(res: Any, rep: dict[str, Any], data: Any, val: Any, args: argparse.Namespace) -> None:
    """The summary of ``identify``, one line per fact (the report holds the lists): RMS, validation,
    held parameters, the compensation check (the figure to read first), notes and warnings."""
    from planner.identify_report import compensation_sentence
    from problems.identify import IdentifyStatus
    from problems.identify.transfer import holds_text

    print(f"identify: {data.n} rows, {rep['data']['n_poses']} poses, status {res.status.value}")
    _print_campaigns(res, args)
    if res.validation is not None:
        v = res.validation
        held_out = "held out" if rep["headline"]["validation_held_out"] else "the --data file itself"
        print(
            f"  validation file ({held_out}, {v['n_rows']} rows): RMS {v['rms_nominal_mm']:.4f} -> {v['rms_mm']:.4f} "
            "mm per axis (nominal -> identified)"
        )
        print(f"  {euclidean_line(v['euclidean_nominal'], v['euclidean'], 'validation file')}")
        if v.get("where_it_holds"):
            print(f"  validation file: {holds_text(v['where_it_holds'])}")
    print(
        f"  RMS before {res.rms_before_mm:.4f} mm -> after {res.rms_after_mm:.4f} mm "
        f"(held-out {rep['heldout_rms_before_mm']:.4f} -> {rep['heldout_rms_after_mm']:.4f} mm, per axis)"
    )
    if res.noise_sigma_m is not None:
        print(f"  noise floor {res.noise_sigma_m * 1e3:.4f} mm ({res.noise_source})")
    print(f"  effects added: {', '.join(res.effects_added) or 'none'}")
    if res.excluded:
        print(f"  {len(res.excluded)} row(s) excluded as outliers (listed in the report)")
    if res.unexplained.get("present"):
        print(f"  unexplained: {res.unexplained['message']}")
    held = (rep.get("held_parameters") or {}).get("message")
    if held:
        print(f"  {held}")
    if res.compensation_check is not None:
        print(f"  compensation on the virtual robot: {compensation_sentence(rep, arrow='->')}")
    for n in res.notes:
        print(f"  note: {n}")
    for w in res.warnings:
        print(f"compplan: warning: {w}", file=sys.stderr)
    print_notes(data, val)
    if res.status in (IdentifyStatus.IMPLAUSIBLE, IdentifyStatus.DOES_NOT_GENERALISE):
        print(f"compplan: warning: {res.reason}", file=sys.stderr)
    print(f"wrote {args.out} and {Path(args.report)}/: report.json, report.md, report.html, figures/")


def _print_campaigns(res: Any, args: argparse.Namespace) -> None:
    """One line per campaign of a several-campaign identification, and which is the reference and why."""
    camps = res.identifiability.get("campaigns") or []
    fit = res.identifiability.get("campaign_fit") or {}
    shared = "shared" in fit
    for c in camps:
        where = (
            "shared frame"
            if shared
            else "reference (the model's registration)"
            if c["reference"]
            else f"registration {c['translation_from_reference_mm']:.3f} mm, {c['rotation_from_reference_deg']:.4f} "
            "deg from the reference campaign's"
        )
        rms = "" if c["rms_after_mm"] is None else f", RMS after {c['rms_after_mm']:.4f} mm"
        print(f"  campaign {c['name']} ({c['file']}): {c['n_rows']} rows, {c['n_poses']} poses{rms}; {where}")
    if camps and not shared:
        ref = next(c for c in camps if c["reference"])
        why = "named by --reference-campaign" if args.reference_campaign else "the campaign with the most rows"
        print(
            f"  reference campaign: {ref['name']} ({why}, {ref['n_rows']} rows): its registration is the model's "
            "own, what predict and compensate use without --campaign"
        )


def euclidean_line(before: dict[str, Any] | None, after: dict[str, Any], what: str) -> str:
    """One line of Euclidean position errors (mean, RMS, max, mm) as calibration results are quoted:
    ``before -> after`` with ``before`` (nominal -> identified), else the model's alone."""

    def fig(key: str) -> str:
        if before is None:
            return f"{after[key]:.4f}"
        return f"{before[key]:.4f} -> {after[key]:.4f}"

    arrow = " (nominal -> identified)" if before is not None else ""
    return (
        f"{what}: position error |predicted - measured| (Euclidean, mm{arrow}): mean {fig('mean_mm')}, "
        f"RMS {fig('rms_mm')}, max {fig('max_mm')} (line {after['max_line']}); {after['n_rows']} rows, in the "
        f"{after['frame']}"
    )


@releases_outputs
def run_simulate(args: argparse.Namespace) -> int:
    """Simulate a measurement campaign and write it with its truth file."""
    inputs = {"--robot": args.robot, "--config": args.config}
    truth_out = args.truth or Path(args.out).with_name(Path(args.out).stem + ".truth.toml")
    check_output(args.out, inputs, kind="file", outputs={"--truth": truth_out})
    check_output(truth_out, inputs, kind="file", option="--truth", outputs={"--out": args.out})
    import tomli_w

    from models import load_robot
    from models.errors import InputError
    from planner.output import atomic_write_bytes
    from problems.measurements import measurements_to_csv
    from problems.virtual import VirtualRobot, load_config

    cfg = load_config(args.config)
    robot = load_robot(args.robot)
    vr = VirtualRobot(robot, cfg, seed=args.seed, where=str(args.config))
    m = vr.campaign()
    units = str(cfg.get("units", "SI"))
    if units not in ("SI", "mm"):
        raise InputError(f"{args.config}: key 'units' must be 'SI' or 'mm', got {units!r}")
    out = Path(args.out)
    truth = Path(args.truth) if args.truth else out.with_name(out.stem + ".truth.toml")
    data = measurements_to_csv(m, mm=(units == "mm")).encode()
    truth_text = tomli_w.dumps(_toml_safe(vr.truth())).encode()
    atomic_write_bytes(truth, truth_text)
    atomic_write_bytes(out, data)
    print(
        f"simulate: robot {robot.name}, {m.n} rows, {len(set(m.point))} poses, effects "
        f"{', '.join(sorted(vr.effects)) or 'none'}; wrote {out} and {truth}"
    )
    return 0


def _toml_safe(obj: Any) -> Any:
    """Drop None values (TOML has no null) recursively."""
    if isinstance(obj, dict):
        return {k: _toml_safe(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, (list, tuple)):
        return [_toml_safe(v) for v in obj if v is not None]
    return obj
