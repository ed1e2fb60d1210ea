"""Values and Markdown table cells as text (shared by the Markdown of the report and of its maps)."""

from __future__ import annotations

from typing import Any


def fmt(v: Any, nd: int = 4) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{nd}g}"
    return str(v)


def md_cell(text: str) -> str:
    """Text for a Markdown table cell: its pipes escaped (``|f|`` stays one cell)."""
    return str(text).replace("|", "\\|")
