"""``compplan export RUN_DIR --format FORMAT --out FILE``: a run's trajectory for a controller.

Reads the run folder of ``compplan plan`` / ``demo`` (``summary.json`` and the controller's
``trajectory.csv``), refuses a trajectory that is not ok or leaves its limits, writes
the format's file(s) whole or not at all (KRL: the ``.src`` and its ``.dat``), and prints what the
export changed, one line each (:func:`print_changes`).  Format
options are ``--set KEY=VALUE`` (``compplan export --list`` prints formats and options).
Conventions: ``docs/export.md``.
"""

from __future__ import annotations

import sys

import argparse
from pathlib import Path
from typing import Any

from planner.commands.common import add_force_argument, check_output, releases_outputs


def _format_names() -> list[str]:
    """The ``--format``/``--export`` choices, without importing the format modules unless plug-in
    folders are named (:func:`planner.export.format_names`)."""
    from planner.export import format_names

    return list(format_names())


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``compplan export``."""
    e = sub.add_parser(
        "export",
        help="write a run's controller trajectory as URScript, ROS 2 YAML, ABB RAPID or KUKA KRL",
        description="Export the controller trajectory of a plan or demo run folder "
        "(docs/export.md). Example: compplan export out/demo --format urscript "
        "--out out/demo.script",
    )
    e.add_argument("run_dir", nargs="?", metavar="RUN_DIR", help="output folder of compplan plan or demo")
    e.add_argument("--format", choices=_format_names(), help="export format")
    e.add_argument(
        "--out",
        help="file to write (its suffix is added when missing; KRL also writes the .dat; rosbag2: the bag folder)",
    )
    e.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="format option, repeatable (e.g. --set period=0.008 --set gain=500)",
    )
    e.add_argument("--list", action="store_true", help="print the formats and their options, and exit")
    add_force_argument(e)
    e.set_defaults(func=run)


def parse_options(items: list[str]) -> dict[str, str]:
    """``KEY=VALUE`` strings to a dict (values checked by the format)."""
    from planner.export import ExportError

    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ExportError(f"export: --set {item!r}: expected KEY=VALUE (compplan export --list shows the keys)")
        out[key.strip()] = value.strip()
    return out


def print_formats() -> None:
    """The formats, their files and options (defaults and help)."""
    from planner.export import formats

    for name, f in formats().items():
        print(f"{name} ({', '.join(f.suffixes)}): {f.description}")
        for key, (default, text, _check) in f.options.items():
            shown = (
                "the trajectory's dt" if default is None else f"{default:g}" if isinstance(default, float) else default
            )
            print(f"  --set {key}=...  {text} (default {shown})")


def out_path(out: str, fmt: str) -> Path:
    """``--out`` with the format's suffix when it has none; another suffix is refused."""
    from planner.export import ExportError, formats

    p = Path(out)
    suffixes = formats()[fmt].suffixes
    if formats()[fmt].folder:
        return p
    if not p.suffix:
        return p.with_name(p.name + suffixes[0])
    if p.suffix.lower() not in suffixes:
        raise ExportError(f"export: --out {out}: a {fmt} file ends in {' or '.join(suffixes)}, not {p.suffix!r}")
    return p


@releases_outputs
def run(args: argparse.Namespace) -> int:
    from models.errors import InputError
    from planner.export import build_export, data_from_run, formats
    from planner.output import OutputSet, atomic_write_files

    if args.list:
        print_formats()
        return 0
    missing = [n for n, v in (("RUN_DIR", args.run_dir), ("--format", args.format), ("--out", args.out)) if not v]
    if missing:
        raise InputError(
            f"export: {', '.join(missing)} required (compplan export RUN_DIR --format FORMAT "
            "--out FILE; compplan export --list)"
        )
    options = parse_options(args.set)
    out = out_path(args.out, args.format)
    run_dir = Path(args.run_dir)
    from planner.summary_schema import read_summary

    read_summary(run_dir, "export")  # every key of summary.json the export reads, checked (exit 2)
    data = data_from_run(run_dir)
    export = build_export(data, args.format, out, options)  # refused, or slowed down, over a limit
    files = export.files
    inputs = {f"RUN_DIR {p.name}": p for p in data.inputs}
    if formats()[args.format].folder:
        names = {p.relative_to(out).parts[0] for p in files}
        check_output(out, inputs, kind="folder", holds="trajectory export", force=args.force, writes=names)
        folder = OutputSet(out)
        for path, content in files.items():
            folder.add_bytes(path.relative_to(out).as_posix(), _bytes(content))
        folder.publish()
    else:
        for path in files:
            check_output(path, inputs, kind="file")
        atomic_write_files({p: _bytes(content) for p, content in files.items()})
    print(
        f"{args.format}: {len(data.t)} samples, {data.t[-1]:.4f} s at {data.dt * 1e3:g} ms from {run_dir} "
        f"(robot {data.robot}) -> {', '.join(str(p) for p in files)}"
    )
    print_changes(args.format, export)
    from planner.export import controller_warning

    for warn in (controller_warning(data, args.format), *export.warnings):
        if warn:
            print(f"compplan: warning: {warn}", file=sys.stderr)
    return 0


def print_changes(fmt: str, export: Any) -> None:
    """What ``export`` (a :class:`planner.export.Export`) made of the plan's trajectory, one
    ``FORMAT: change`` line each, or one line saying it holds the plan's samples unchanged."""
    for change in export.changes or ("unchanged: the plan's samples at its timing",):
        print(f"{fmt}: {change}")


def _bytes(content: str | bytes) -> bytes:
    return content if isinstance(content, bytes) else content.encode()


# ------------------------------------------------------------------ plan / demo --export
def add_export_argument(parser: argparse.ArgumentParser) -> None:
    """``--export FORMAT`` (repeatable) of ``plan`` and ``demo``."""
    parser.add_argument(
        "--export",
        action="append",
        default=[],
        choices=_format_names(),
        metavar="FORMAT",
        help="also write the controller trajectory in this format into the output folder "
        f"(repeatable; {', '.join(_format_names())}; default options, see compplan export)",
    )


def plan_exports(res: Any, fmts: list[str]) -> dict[str, bytes]:
    """The files of ``plan --export``: ``<problem>_<format>.<suffix>`` (a folder for rosbag2) by name, from the plan in
    memory (refused, before anything is written, if the trajectory is not ok or leaves its limits).  A format refused at
    its default options (a limit exceeded, a program's feed a slow-down would change, a streamed program without its
    host) is left out with a warning that says why and how ``compplan export`` writes it with other options; the plan
    and the other formats are written, and what each export changed is printed (:func:`print_changes`)."""
    from planner.export import ExportRefusal, build_export, controller_warning, data_from_plan

    if not fmts:
        return {}
    data = data_from_plan(res)
    out: dict[str, bytes] = {}
    for fmt in dict.fromkeys(fmts):
        try:
            export = build_export(data, fmt, Path(f"{data.name}_{fmt}"))
        except ExportRefusal as exc:
            print(
                f"compplan: warning: --export {fmt} not written: {exc}; compplan export RUN_DIR --format {fmt} "
                "--set KEY=VALUE writes it with other options (docs/export.md)",
                file=sys.stderr,
            )
            continue
        for warn in (controller_warning(data, fmt), *export.warnings):
            if warn:
                print(f"compplan: warning: {warn}", file=sys.stderr)
        print_changes(f"--export {fmt}", export)
        for path, content in export.files.items():
            out[path.as_posix()] = _bytes(content)
    return out
