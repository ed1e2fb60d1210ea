"""Printing helpers and output-path checks shared by the sub-commands (the CLI is the only place that prints)."""

from __future__ import annotations

import functools
import os
from pathlib import Path
from collections.abc import Callable, Mapping

from planner.output import (
    OutputError,
    OutputKind,
    acquire_output_lock,
    check_output_path,
    release_output_lock,
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
) -> Path:
    """Check an output path before a command's long work, and lock it until the command ends.

    Call it at the top of a sub-command's ``run`` (decorated with :func:`releases_outputs`)
    for every output the command writes.

    Parameters
    ----------
    path : str or Path
        The output.
    inputs : mapping of str to path or None, optional
        The command's inputs by option name (e.g. ``{"--data": args.data}``); ``None`` values
        and names that are not existing paths (built-in robots, shipped problems) are skipped.
        The output may not be one of them, nor (a folder) contain one.
    kind : {"file", "folder", "update"}
        See :func:`planner.output.check_output_path`.
    option : str
        How messages name the output.
    outputs : mapping of str to path or None, optional
        The command's other outputs by option name: the output may not be one of them, nor
        (a folder) contain one, whether they exist yet or not.

    Returns
    -------
    Path

    Raises
    ------
    OutputError
        One line: the output is an input (or holds one), another output, a file where a
        folder is expected (or the reverse), not writable, or being written by another run.
    """
    p = Path(path)
    for opt, other in (inputs or {}).items():
        if other is None or not Path(other).exists():
            continue
        _refuse_overlap(p, option, kind, Path(other), opt, "the input")
    for opt, other in (outputs or {}).items():
        if other is not None:
            _refuse_overlap(p, option, kind, Path(other), opt, "the output")
    check_output_path(p, kind, option)
    if kind == "update" and not p.is_dir():
        return p  # the command reports the missing folder itself
    acquire_output_lock(p, option)
    _COMMAND_OUTPUTS.append(p)
    return p


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
    """Decorator of a sub-command's ``run``: release the outputs :func:`check_output` locked."""

    @functools.wraps(run)
    def wrapper(*args: object, **kwargs: object) -> int:
        mark = len(_COMMAND_OUTPUTS)
        try:
            return run(*args, **kwargs)
        finally:
            while len(_COMMAND_OUTPUTS) > mark:
                release_output_lock(_COMMAND_OUTPUTS.pop())

    return wrapper


def print_error_table(rows: list[tuple[str, float, float]], title: str) -> None:
    """Print a small table of (case, max mm, RMS mm)."""
    print(title)
    print(f"  {'case':<28}{'max [mm]':>12}{'RMS [mm]':>12}")
    for name, mx, rms in rows:
        print(f"  {name:<28}{mx:>12.6f}{rms:>12.6f}")
