"""An export's files: the options checked, what the controller runs checked against every limit
(refused, or slowed down and said so), the format's writer called; nothing written here."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Mapping

from models.status import Status

from planner.export.data import ExportData, program_name
from planner.export.errors import ExportError
from planner.export.limits import check_motion
from planner.export.registry import formats

__all__ = ["Export", "ExportStatus", "build_export", "export_files"]


class ExportStatus(Status):
    """How an export's files time the plan (a refusal raises instead: nothing to write)."""

    #: At the plan's timing (resampled, decimated or split as the changes say, never slower).
    OK = "ok"
    #: Slowed down uniformly (the changes say by how much): what the controller runs is slower than planned.
    SLOWED = "slowed"

    @property
    def usable(self) -> bool:
        return True


@dataclass(frozen=True)
class Export:
    """An export ready to write.

    Attributes
    ----------
    files : dict
        Path -> text, or bytes for binary formats.
    warnings : tuple of str
        What the vendor does not document (the command line prints them on stderr).
    status : ExportStatus
    reason : str
        One line: the status's why (the slow-down, or "at the plan's timing").
    changes : tuple of str
        What the export made of the plan's trajectory, one short line each (slowed down, resampled
        to the controller's period, decimated, split into parts, streamed or self-contained);
        empty when the files hold the plan's samples as they are.
    """

    files: dict[Path, str | bytes]
    warnings: tuple[str, ...] = ()
    status: ExportStatus = ExportStatus.OK
    reason: str = "at the plan's timing"
    changes: tuple[str, ...] = ()


def build_export(data: ExportData, fmt: str, out: str | Path, options: Mapping[str, Any] | None = None) -> Export:
    """The files of ``data`` in format ``fmt`` for output ``out`` (a file, or the folder of a
    folder format such as ``rosbag2``), after checking what the controller runs against every
    limit (:func:`~planner.export.limits.check_motion`: refused, or slowed down and said so).

    Options not given take the format's defaults; unknown options and bad values raise
    :class:`ExportError` naming them; options that cannot write the trajectory (a limit exceeded,
    a program plan's feed that a slow-down would change, a streamed program without its host)
    raise :class:`~planner.export.errors.ExportRefusal`.  Nothing is written here (the caller
    writes the set whole or not at all).
    """
    known = formats()
    f = known.get(fmt)
    if f is None:
        raise ExportError(f"export: unknown format {fmt!r}; formats: {', '.join(sorted(known))}")
    opts = dict(options or {})
    unknown = sorted(set(opts) - set(f.options))
    if unknown:
        raise ExportError(f"export: format {fmt} has no option(s) {unknown}; options: {sorted(f.options)}")
    values = {k: (check(opts[k]) if k in opts else default) for k, (default, _h, check) in f.options.items()}
    changes: list[str] = []
    if f.motion is None:
        notes = [
            f"{fmt}: the format declares no controller motion (ExportFormat.motion): what it writes is not checked "
            "against the limits beyond the trajectory's own samples (docs/export.md)"
        ]
    else:
        motion = f.motion
        data, notes, changes = check_motion(data, fmt, lambda d: motion(d, values), values.get("slow_down", "no"))
    if f.changes is not None:
        changes += f.changes(data, values)
    out = Path(out)
    stem = out.stem if out.suffix else out.name
    texts = f.write(data, program_name(stem), values)
    if f.folder:
        files = {out / name: text for name, text in texts.items()}
    else:
        files = {out.with_name(name): text for name, text in texts.items()}
    if data.slow_factor != 1.0:
        status, reason = ExportStatus.SLOWED, f"slowed down x{data.slow_factor:.4f} from the plan's timing"
    else:
        status, reason = ExportStatus.OK, "at the plan's timing"
    return Export(files, tuple(notes), status, reason, tuple(changes))


def export_files(
    data: ExportData, fmt: str, out: str | Path, options: Mapping[str, Any] | None = None
) -> dict[Path, str | bytes]:
    """The files of :func:`build_export` (its warnings and changes dropped)."""
    return build_export(data, fmt, out, options).files
