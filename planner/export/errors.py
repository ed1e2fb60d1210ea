"""The errors of an export (a leaf: every module of :mod:`planner.export` raises them)."""

from __future__ import annotations

from models.errors import InputError

__all__ = ["ExportError", "ExportLimitError", "ExportRefusal"]


class ExportError(InputError):
    """The trajectory cannot be exported (not ok, no trajectory, a bad option); the message says why."""


class ExportRefusal(ExportError):
    """The export is refused at these options, and the message says which option or plan writes it
    (``plan --export`` then leaves the format out, saying so, and writes the rest)."""


class ExportLimitError(ExportRefusal):
    """What a format would send its controller exceeds a limit (:func:`~planner.export.limits.check_motion`)."""
