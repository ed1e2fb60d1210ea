"""An export's files: the options checked, what the controller runs checked against every limit
(refused, or slowed down and said so), the format's writer called; nothing written here."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Mapping

from planner.export.data import ExportData, program_name
from planner.export.errors import ExportError
from planner.export.limits import check_motion
from planner.export.registry import formats

__all__ = ["Export", "build_export", "export_files"]


@dataclass(frozen=True)
class Export:
    """An export ready to write: ``files`` (path -> text, or bytes for binary formats) and the
    ``warnings`` the command line prints (what the vendor does not document, a slow-down)."""

    files: dict[Path, str | bytes]
    warnings: tuple[str, ...] = ()


def build_export(data: ExportData, fmt: str, out: str | Path, options: Mapping[str, Any] | None = None) -> Export:
    """The files of ``data`` in format ``fmt`` for output ``out`` (a file, or the folder of a
    folder format such as ``rosbag2``), after checking what the controller runs against every
    limit (:func:`~planner.export.limits.check_motion`: refused, or slowed down and said so).

    Options not given take the format's defaults; unknown options and bad values raise
    :class:`ExportError` naming them.  Nothing is written here (the caller writes the set
    whole or not at all).
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
    if f.motion is None:
        notes = [
            f"{fmt}: the format declares no controller motion (ExportFormat.motion): what it writes is not checked "
            "against the limits beyond the trajectory's own samples (docs/export.md)"
        ]
    else:
        motion = f.motion
        data, notes = check_motion(data, fmt, lambda d: motion(d, values), values.get("slow_down") == "auto")
    out = Path(out)
    stem = out.stem if out.suffix else out.name
    texts = f.write(data, program_name(stem), values)
    if f.folder:
        files = {out / name: text for name, text in texts.items()}
    else:
        files = {out.with_name(name): text for name, text in texts.items()}
    return Export(files, tuple(notes))


def export_files(
    data: ExportData, fmt: str, out: str | Path, options: Mapping[str, Any] | None = None
) -> dict[Path, str | bytes]:
    """The files of :func:`build_export` (its warnings dropped)."""
    return build_export(data, fmt, out, options).files
