"""Printing helpers and output-path checks shared by the sub-commands (the CLI is the only place that prints)."""

from __future__ import annotations

import argparse
import functools
import os
import sys
from pathlib import Path
from collections.abc import Callable, Iterable, Mapping

from planner.output import (
    FolderKind,
    OutputError,
    OutputKind,
    acquire_output_lock,
    check_output_path,
    release_output_lock,
    take_output_notes,
)

#: Outputs locked by the running command (released when its ``run`` returns or raises).
_COMMAND_OUTPUTS: list[Path] = []


def _same(a: Path, b: Path) -> bool:
    """Whether two paths name the same file or folder (links and hard links resolved)."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _inside(inner: Path, outer: Path) -> bool:
    """Whether ``inner`` lies inside the folder ``outer`` (symbolic links resolved)."""
    return Path(os.path.realpath(outer)) in Path(os.path.realpath(inner)).parents


def check_output(
    path: str | Path,
    inputs: Mapping[str, str | Path | None] | None = None,
    kind: OutputKind = "folder",
    option: str = "--out",
    outputs: Mapping[str, str | Path | None] | None = None,
    *,
    holds: FolderKind | str | None = None,
    force: bool = False,
    writes: Iterable[str] = (),
) -> Path:
    """Check an output path before a command's long work, and lock it until the command ends.

    Call it at the top of a sub-command's ``run`` (decorated with :func:`releases_outputs`)
    for every output the command writes.  Hidden siblings an earlier, stopped run left beside
    the output are removed once it is locked; one that cannot be removed is named in a warning.

    Parameters
    ----------
    path : str or Path
        The output.
    inputs : mapping of str to path or None, optional
        The command's input files by option name (e.g. ``{"--data": args.data}``); ``None``
        values and names that are not existing files (built-in robots, shipped problems, also
        when a folder of that name exists: ``plan drilling_cone --out drilling_cone``) are
        skipped.  The output may not be one of them, nor (a folder) contain one.
    kind : {"file", "folder", "update"}
        See :func:`planner.output.check_output_path`.
    option : str
        How messages name the output.
    outputs : mapping of str to path or None, optional
        The command's other outputs by option name: the output may not be one of them, nor
        (a folder) contain one, whether they exist yet or not.
    holds : FolderKind or str, optional
        What the command writes into an output folder (``"plan"``, ``"placement study"``, ...):
        a folder holding another command's output is refused unless ``force``.
    force : bool
        The command's ``--force`` (:func:`add_force_argument`).
    writes : iterable of str
        Top-level names the command writes into an output folder without a marker file (an
        export folder): a folder holding only these is its own earlier output.

    Returns
    -------
    Path

    Raises
    ------
    OutputError
        One line: the output is an input (or holds one), another output, a file where a
        folder is expected (or the reverse), not writable, holding another command's output
        (without ``force``), or being written by another run.
    """
    p = Path(path)
    for opt, other in (inputs or {}).items():
        if other is None or not Path(other).is_file():  # a folder of a shipped problem's name is no input
            continue
        _refuse_overlap(p, option, kind, Path(other), opt, "the input")
    for opt, other in (outputs or {}).items():
        if other is not None:
            _refuse_overlap(p, option, kind, Path(other), opt, "the output")
    check_output_path(p, kind, option, writes, holds=holds, force=force)
    if kind == "update" and not p.is_dir():
        return p  # the command reports the missing folder itself
    acquire_output_lock(p, option)
    _COMMAND_OUTPUTS.append(p)
    print_output_notes()
    return p


def add_force_argument(parser: argparse.ArgumentParser, what: str = "--out") -> None:
    """``--force``: replace an output folder that holds another command's output."""
    parser.add_argument(
        "--force",
        action="store_true",
        help=f"replace {what} even when it holds another command's output (a plan, a placement study, a map, "
        "a pose, an identification report); a folder of files compplan did not write is never replaced",
    )


def print_output_notes() -> None:
    """One warning line per note the output library recorded (a hidden sibling it could not remove)."""
    for note in take_output_notes():
        print(f"compplan: warning: {note}", file=sys.stderr)


def _refuse_overlap(out: Path, option: str, kind: str, other: Path, opt: str, role: str) -> None:
    """Refuse an output that is, or (a folder) contains, another path of the command."""
    if _same(out, other):
        raise OutputError(f"{option} {out}: is also {role} {opt} ({other}); choose another path for {option}")
    if kind != "file" and _inside(other, out):
        raise OutputError(
            f"{option} {out}: contains {role} {opt} ({other}), and an output folder is "
            f"replaced whole; choose another folder for {option}"
        )


def releases_outputs(run: Callable[..., int]) -> Callable[..., int]:
    """Decorator of a sub-command's ``run``: release the outputs :func:`check_output` locked and
    print the warnings of the output library (hidden siblings it could not remove)."""

    @functools.wraps(run)
    def wrapper(*args: object, **kwargs: object) -> int:
        mark = len(_COMMAND_OUTPUTS)
        take_output_notes()  # notes of earlier library calls in this process are not this command's
        try:
            return run(*args, **kwargs)
        finally:
            while len(_COMMAND_OUTPUTS) > mark:
                release_output_lock(_COMMAND_OUTPUTS.pop())
            print_output_notes()

    return wrapper


def print_error_table(rows: list[tuple[str, float, float]], title: str) -> None:
    """Print a small table of (case, max mm, RMS mm)."""
    print(title)
    print(f"  {'case':<28}{'max [mm]':>12}{'RMS [mm]':>12}")
    for name, mx, rms in rows:
        print(f"  {name:<28}{mx:>12.6f}{rms:>12.6f}")
