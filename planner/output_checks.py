"""Checks of an output path before anything is written, and what an existing output folder holds.

An output folder of compplan is recognised by its marker file (:data:`FOLDER_KIND_MARKERS`,
:func:`output_folder_kind`).  :func:`check_output_path` refuses, with one line naming the path:
a file where a folder is expected (or the reverse), the current folder, a folder holding files
compplan did not write, a folder holding another command's output (unless forced: the
``--force`` of the commands), a folder whose previous contents could not be removed once
replaced (a read-only sub-folder), and a parent that is not writable.  Re-exported by
:mod:`planner.output`.
"""

from __future__ import annotations

import json
import os
import shlex
from collections.abc import Iterable
from enum import Enum
from pathlib import Path
from typing import Any, Literal

from planner.output_siblings import FOLDER_MODE, OutputError, os_error_cause, real_path

OutputKind = Literal["file", "folder", "update"]


class FolderKind(Enum):
    """What an output folder of compplan holds; the value is its name in messages."""

    PLAN = "plan"
    PLACEMENT = "placement study"
    IDENTIFICATION = "identification report"
    DESIGN = "campaign design report"
    MAP = "compliance map"
    POSE = "pose"
    EXPORT = "trajectory export"

    @property
    def command(self) -> str:
        """The command that writes it."""
        return _KIND_COMMANDS[self]

    @property
    def phrase(self) -> str:
        """The kind with its article, e.g. ``"an identification report"``."""
        return f"{'an' if self.value[0] in 'aeiou' else 'a'} {self.value}"


_KIND_COMMANDS = {
    FolderKind.PLAN: "compplan plan or demo",
    FolderKind.PLACEMENT: "compplan place",
    FolderKind.IDENTIFICATION: "compplan identify --report",
    FolderKind.DESIGN: "compplan design --report",
    FolderKind.MAP: "compplan map",
    FolderKind.POSE: "compplan pose --out",
    FolderKind.EXPORT: "compplan export",
}

#: The marker file of each kind of output folder, checked in this order (a plan's folder also
#: holds a compliance map's CSV, never its JSON).  A folder holding one is an output folder of
#: compplan, which a new run may replace whole.  An export folder (rosbag2) has no marker: it is
#: recognised by holding only the names the export writes.
FOLDER_KIND_MARKERS = {
    "summary.json": FolderKind.PLAN,
    "report.json": FolderKind.IDENTIFICATION,
    "compliance_map.json": FolderKind.MAP,
    "pose.json": FolderKind.POSE,
}
#: ``summary.json`` is shared by plans and placement studies: its ``"command"`` tells them apart.
SUMMARY_COMMAND_KINDS = {"place": FolderKind.PLACEMENT}
#: ``report.json`` is shared by identification and design reports: its ``"command"`` tells them apart.
REPORT_COMMAND_KINDS = {"design": FolderKind.DESIGN}
#: A file of one of these names marks an existing folder as an output folder of compplan.
OUTPUT_FOLDER_MARKERS = tuple(FOLDER_KIND_MARKERS)
#: Entries of a foreign folder named in the refusal message.
FOREIGN_SHOWN = 3


# ------------------------------------------------------------------------------ checks
def output_folder_kind(folder: str | Path) -> FolderKind | None:
    """What the output folder ``folder`` holds, by its marker file (:data:`FOLDER_KIND_MARKERS`);
    None for a folder without one (new, empty, an export folder or not compplan's)."""
    p = Path(folder)
    for marker, kind in FOLDER_KIND_MARKERS.items():
        if (p / marker).is_file():
            if kind is FolderKind.PLAN:
                return SUMMARY_COMMAND_KINDS.get(_summary_command(p / marker), kind)
            if kind is FolderKind.IDENTIFICATION:
                return REPORT_COMMAND_KINDS.get(_summary_command(p / marker), kind)
            return kind
    return None


def _summary_command(path: Path) -> Any:
    """The ``"command"`` of a ``summary.json`` or ``report.json`` (None when unreadable or absent: an
    earlier plan, an identification report)."""
    try:
        s = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return s.get("command") if isinstance(s, dict) else None


def _may_empty(folder: Path) -> bool:
    """Whether this process may list and remove the entries of ``folder``."""
    return os.access(folder, os.R_OK | os.W_OK | os.X_OK)


def _unremovable(folder: Path) -> Path | None:
    """The first folder of the tree ``folder`` (itself included; symbolic links not followed)
    whose entries this process may not remove, or None when the whole tree can be removed."""
    if not _may_empty(folder):
        return folder
    for root, dirs, _files in os.walk(folder):
        for d in sorted(dirs):
            sub = Path(root, d)
            if not sub.is_symlink() and not _may_empty(sub):
                return sub
    return None


def _check_replaced_folder(
    p: Path, kind: OutputKind, what: str, writes: Iterable[str], holds: FolderKind | None, force: bool
) -> None:
    """The checks of an existing folder that a set replaces (whole, or some entries with ``"update"``).

    Raises
    ------
    OutputError
        It holds files compplan did not write, another command's output (without ``force``), or a
        sub-folder whose entries cannot be removed (the previous output could not be removed).
    """
    if kind == "folder":
        try:
            entries = sorted(os.listdir(p))
        except OSError as exc:
            raise OutputError(f"{what} {p}: cannot read the folder ({os_error_cause(exc)})") from None
        if entries and not any(m in entries for m in OUTPUT_FOLDER_MARKERS) and not set(entries) <= set(writes):
            shown = ", ".join(entries[:FOREIGN_SHOWN]) + (", ..." if len(entries) > FOREIGN_SHOWN else "")
            raise OutputError(
                f"{what} {p}: holds files compplan did not write ({shown}), and an output "
                "folder is replaced whole; give a new or empty folder"
            )
        found = output_folder_kind(p)
        if holds is not None and found is not None and found is not holds and not force:
            raise OutputError(
                f"{what} {p}: holds {found.phrase} ({found.command}), which {holds.phrase} would replace "
                f"whole; use --force to replace it, or another {what}"
            )
    bad = _unremovable(p)
    if bad is not None:
        raise OutputError(
            f"{what} {p}: {bad} is read-only, and the previous output is removed when it is replaced; "
            f"make it writable (chmod -R u+w {shlex.quote(os.fspath(p))}) or give another {what}"
        )


def check_output_path(
    path: str | Path,
    kind: OutputKind = "folder",
    what: str = "--out",
    writes: Iterable[str] = (),
    *,
    holds: FolderKind | str | None = None,
    force: bool = False,
) -> Path:
    """Check that ``path`` can be written as an output of the given kind; nothing is created.

    Call it before long computations so that a bad output path fails at once.

    Parameters
    ----------
    path : str or Path
        The output.
    kind : {"file", "folder", "update"}
        ``"file"``: one file (not an existing folder).  ``"folder"``: a folder a run
        replaces whole: new, empty, or an output folder of compplan (it holds one of
        :data:`OUTPUT_FOLDER_MARKERS`, or only entries named in ``writes``).  ``"update"``:
        an existing folder some of whose entries are replaced (the report of a run folder).
        An existing folder (both kinds) must be removable as a whole: its previous version
        is removed once the new one is in place.
    what : str
        How messages name the output (``"--out"``, ``"--report"``, ...).
    writes : iterable of str
        Top-level names the output set writes (a folder holding only these is one it wrote).
    holds : FolderKind or str, optional
        What the set is (``"plan"``, ``"placement study"``, ... ; :class:`FolderKind`): a
        ``"folder"`` holding another kind of output is refused unless ``force``.  None: not checked.
    force : bool
        Replace a folder holding another kind of output.

    Returns
    -------
    Path

    Raises
    ------
    OutputError
        One line naming the path and what is wrong with it.
    ValueError
        ``holds`` is not a :class:`FolderKind` value.
    """
    p = Path(path)
    real = real_path(p)
    want = None if holds is None else FolderKind(holds)
    if real.parent == real:
        raise OutputError(f"{what} {p}: is the root folder; give a folder below it")
    if kind == "file":
        if p.is_dir():
            raise OutputError(f"{what} {p}: is an existing folder; give the path of the file to write")
        if p.exists() and not p.is_file():
            raise OutputError(f"{what} {p}: exists and is not a regular file")
    else:
        if p.exists() and not p.is_dir():
            raise OutputError(f"{what} {p}: exists and is not a folder; give a folder path")
        cwd = real_path(os.getcwd())
        if cwd == real or real in cwd.parents:
            raise OutputError(
                f"{what} {p}: is the current folder or contains it, and it is replaced whole "
                "when written; run from outside it (e.g. its parent)"
            )
        if p.is_dir():
            _check_replaced_folder(p, kind, what, writes, want, force)
    parent = real.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(f"{what} {p}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {p}: {parent} is not writable")
    return p


def check_output_folder(folder: str | Path, create: bool = False) -> Path:
    """Check that ``folder`` can be written as a whole output folder (see :func:`check_output_path`).

    Kept for callers of earlier versions; nothing is created unless ``create``.

    Raises
    ------
    OutputError
        Naming the folder and what is wrong with it.
    """
    p = check_output_path(folder, "folder", "--out")
    if create:
        try:
            p.mkdir(FOLDER_MODE, parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"--out {p}: cannot create the folder ({os_error_cause(exc)})") from None
    return p


__all__ = [
    "FOLDER_KIND_MARKERS",
    "OUTPUT_FOLDER_MARKERS",
    "SUMMARY_COMMAND_KINDS",
    "FolderKind",
    "OutputKind",
    "check_output_folder",
    "check_output_path",
    "output_folder_kind",
]
