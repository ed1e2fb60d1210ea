"""The report's table cells: a value of ``summary.json`` shown with where it comes from.

Every number in the HTML tables is machine-checkable: its :class:`Cell` carries ``data-key`` (the
dotted path into ``summary.json``; list items by index, e.g. ``provenance.inputs.0.sha256``),
``data-value`` (the JSON value, full precision) and, when the cell shows the maximum over joints of
a list, ``data-agg="max"``.  :class:`Table` renders rows of cells as HTML and Markdown.  Shared by
the plan, placement and program tables.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.numbers import format_value

__all__ = ["RATIO_KINDS", "Cell", "Table", "flat_numbers", "fmt", "lookup", "value_cell"]

#: Kinds of limit ratio, in table order.
RATIO_KINDS = ("velocity", "acceleration", "jerk")


def lookup(summary: Mapping[str, Any], key: str) -> Any:
    """Value at a dotted path in ``summary`` (``KeyError`` if absent); a numeric part indexes a list."""
    cur: Any = summary
    for part in key.split("."):
        if isinstance(cur, Mapping) and part in cur:
            cur = cur[part]
        elif isinstance(cur, list) and part.isdigit() and int(part) < len(cur):
            cur = cur[int(part)]
        else:
            raise KeyError(key)
    return cur


def fmt(v: Any, key: str = "") -> str:
    """Display text of a table value (see :func:`planner.numbers.format_value`)."""
    return format_value(v, key)


def flat_numbers(v: Any) -> list[float]:
    """The numbers of a (nested) list or array, flattened; other values are skipped."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (list, tuple)):
        return [x for item in v for x in flat_numbers(item)]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return [float(v)]
    return []


@dataclass
class Cell:
    """One table cell: display text and, for values from summary.json, where they come from."""

    text: str
    key: str | None = None
    value: Any = None
    agg: str | None = None
    #: Extra CSS class (e.g. ``"hash"`` for monospace digests).
    css: str = ""

    def html(self) -> str:
        cls = f' class="{self.css}"' if self.css else ""
        if self.key is None:
            return f"<td{cls}>{html.escape(self.text)}</td>"
        attrs = f' data-key="{html.escape(self.key)}" data-value="{html.escape(json.dumps(self.value))}"'
        if self.agg:
            attrs += f' data-agg="{self.agg}"'
        css = ("text" if isinstance(self.value, str) else "num") + (f" {self.css}" if self.css else "")
        return f'<td class="{css}"{attrs}>{html.escape(self.text)}</td>'


def value_cell(summary: Mapping[str, Any], key: str, agg: str | None = None, css: str = "") -> Cell:
    """A cell showing ``summary[key]`` (or the max of its numbers with ``agg="max"``)."""
    try:
        v = lookup(summary, key)
    except KeyError:
        return Cell("absent")
    if agg == "max":
        nums = [x for x in flat_numbers(v) if math.isfinite(x)]
        if not nums:
            return Cell("n/a")
        shown = max(nums)
        return Cell(fmt(shown, key), key, shown, "max", css)
    if isinstance(v, Mapping):
        return Cell(json.dumps(v))
    return Cell(fmt(v, key), key, v, css=css)


@dataclass
class Table:
    title: str
    header: list[str]
    rows: list[list[Cell]]
    note: str = ""
    #: CSS class of the HTML table (``summary``; the headline is ``summary headline``).
    css: str = "summary"
    #: HTML id (anchor) of the table.
    anchor: str = ""

    def html(self) -> str:
        anchor = f' id="{self.anchor}"' if self.anchor else ""
        out = [
            f"<h3{anchor}>{html.escape(self.title)}</h3>",
            f'<table class="{self.css}">',
            "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in self.header) + "</tr>",
        ]
        out += ["<tr>" + "".join(c.html() for c in row) + "</tr>" for row in self.rows]
        out.append("</table>")
        if self.note:
            out.append(f'<p class="note">{html.escape(self.note)}</p>')
        return "\n".join(out)

    def markdown(self) -> str:
        def esc(s: str) -> str:
            return s.replace("|", "\\|")

        out = [
            f"### {self.title}",
            "",
            "| " + " | ".join(esc(h) for h in self.header) + " |",
            "|" + "---|" * len(self.header),
        ]
        out += ["| " + " | ".join(esc(c.text) for c in row) + " |" for row in self.rows]
        if self.note:
            out += ["", self.note]
        return "\n".join(out)
