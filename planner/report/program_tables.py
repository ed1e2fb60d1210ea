"""The report's tables of a program path: the summary's ``program`` keys (file, waypoints, stops,
path tolerance; programmed against achieved time per timing method; the slowed program lines, by
cause when the summary has ``slowed_by_limit``, and the path deviation against the tolerance),
nothing recomputed."""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

from problems.toolpath.feed import FEED_SLOW_TOL

from planner.numbers import format_number
from planner.record.columns import PROGRAM_KEY
from planner.record.record import method_name
from planner.report.table_base import Cell, Table, value_cell
from planner.report.toolpath import (
    deviation_words,
    slowed_by_limit_worst_first,
    slowed_line_text,
    slowed_lines_worst_first,
)

__all__ = ["SLOWED_SHOWN", "program_tables"]

#: Slowed program lines listed in the program table (worst first).
SLOWED_SHOWN = 10

#: Header and note of the column of slowed lines (in the feed table of a summary without their
#: causes, else in the table of slowed lines).
_SLOWED_HEADER = f"slowed program lines (count: slowest {SLOWED_SHOWN}, % of F)"
_SLOWED_NOTE = (
    "Slowed lines: program lines with a move whose peak TCP speed stays below "
    f"{format_number(100.0 * (1.0 - FEED_SLOW_TOL))} % of F (the value: that peak on the line's slowest move), "
    "slowest first; the full list is summary.json program.feed.<method>.slowed_lines."
)


def _slowed_text(entry: Mapping[str, Any]) -> str:
    """All slowed lines: their count and the slowest :data:`SLOWED_SHOWN` with their fraction of F."""
    return _listed([slowed_line_text(L, f) for L, f in slowed_lines_worst_first(entry)])


def _by_limit_text(entry: Mapping[str, Any]) -> str:
    """The slowed lines a joint limit holds down: their count and the slowest :data:`SLOWED_SHOWN`
    with their fraction of F, joint and derivative."""
    return _listed([slowed_line_text(L, f, j, d) for L, f, j, d in slowed_by_limit_worst_first(entry) or []])


def _listed(texts: list[str]) -> str:
    """``"N: first, second, ... and M more"`` of at most :data:`SLOWED_SHOWN` texts; ``"none"``."""
    if not texts:
        return "none"
    more = len(texts) - SLOWED_SHOWN
    return f"{len(texts)}: " + ", ".join(texts[:SLOWED_SHOWN]) + (f" and {more} more" if more > 0 else "")


def _ratio_cell(entry: Mapping[str, Any]) -> Cell:
    prog, dur = entry.get("programmed_time_s"), entry.get("duration_s")
    if isinstance(prog, (int, float)) and isinstance(dur, (int, float)) and prog > 0 and math.isfinite(dur):
        return Cell(format_number(float(dur) / float(prog)), css="num")
    return Cell("n/a")


def program_tables(summary: Mapping[str, Any]) -> list[Table]:
    """The program's tables (file, waypoints, stops, path tolerance; programmed against achieved
    time per timing method; the slowed program lines: by cause, with the path deviation against
    the tolerance, in a table of their own for a summary with ``slowed_by_limit``, else a column of
    the feed table), from ``summary.json``'s ``program`` keys; none for a path that is not a program."""
    p = summary.get(PROGRAM_KEY)
    if not isinstance(p, Mapping):
        return []
    k = PROGRAM_KEY
    rows = [
        [Cell("program file"), value_cell(summary, f"{k}.file")],
        [Cell("kind"), value_cell(summary, f"{k}.kind")],
        [Cell("waypoints"), value_cell(summary, f"{k}.n_waypoints")],
        [Cell("program lines with moves"), value_cell(summary, f"{k}.n_lines")],
        [Cell("stops (arm at rest)"), value_cell(summary, f"{k}.n_stops")],
        [Cell("dwell [s]"), value_cell(summary, f"{k}.dwell_s")],
        [Cell("path tolerance [mm]"), value_cell(summary, f"{k}.path_tolerance_mm")],
        [Cell("path tolerance from"), value_cell(summary, f"{k}.path_tolerance_source")],
        [Cell("cutting length [m]"), value_cell(summary, f"{k}.cutting_length_m")],
    ]
    note = "The program read as the path (summary.json 'program')."
    if p.get("units_note"):
        note += f" {p['units_note']}"
    tables = [Table("Program", ["quantity", "value"], rows, note, anchor="program")]
    feed = p.get("feed") if isinstance(p.get("feed"), Mapping) else {}
    ctrl = summary.get("controller_trajectory")
    cutting = any(isinstance(e, Mapping) and "cutting_time_s" in e for e in feed.values())  # (newer summaries)
    split = any(isinstance(e, Mapping) and "slowed_by_limit" in e for e in feed.values())  # (newer still)
    frows = _feed_rows(summary, feed, ctrl, cutting, split)
    if frows:
        tables.append(_feed_table(frows, cutting, split))
    srows = _slowed_rows(summary, feed, ctrl) if split else []
    if srows:
        tables.append(_slowed_table(srows))
    return tables


def _method_cell(summary: Mapping[str, Any], m: str, ctrl: Any) -> Cell:
    return Cell(method_name(summary, m) + (" (controller)" if m == ctrl else ""))


def _feed_rows(
    summary: Mapping[str, Any], feed: Mapping[str, Any], ctrl: Any, cutting: bool, split: bool
) -> list[list[Cell]]:
    """One row of the feed table per timing method in ``program.feed`` (the controller's marked);
    the slowed lines in its last column unless ``split`` (a summary with ``slowed_by_limit``: they
    have a table of their own, :func:`_slowed_rows`)."""
    k = PROGRAM_KEY
    frows = []
    for m, entry in feed.items():
        if not isinstance(entry, Mapping):
            continue
        frows.append(
            [
                _method_cell(summary, m, ctrl),
                value_cell(summary, f"{k}.feed.{m}.programmed_time_s"),
                value_cell(summary, f"{k}.feed.{m}.duration_s"),
                _ratio_cell(entry),
            ]
            + (
                [
                    value_cell(summary, f"{k}.feed.{m}.cutting_time_s"),
                    value_cell(summary, f"{k}.feed.{m}.cutting_time_over_programmed"),
                ]
                if cutting
                else []
            )
            + [
                value_cell(summary, f"{k}.feed.{m}.peak_feed_ratio"),
                value_cell(summary, f"{k}.feed.{m}.n_stretches"),
            ]
            + ([] if split else [Cell(_slowed_text(entry))])
        )
    return frows


def _feed_table(frows: list[list[Cell]], cutting: bool, split: bool) -> Table:
    """The program's feed table: programmed against achieved time per method (and the slowed
    lines, unless ``split``)."""
    return Table(
        "Program: feed",
        [
            "method",
            "programmed time [s]",
            "achieved duration [s]",
            "achieved / programmed [×]",
        ]
        + (["time on cutting moves [s]", "cutting time / programmed [×]"] if cutting else [])
        + ["peak TCP speed / F", "stretches between stops"]
        + ([] if split else [_SLOWED_HEADER]),
        frows,
        "Programmed time: length / F summed over the cutting moves (rapids count 0). Achieved: the "
        "trajectory's duration, rapids and stops included"
        + (
            "; time on cutting moves: its samples on cutting moves, their accelerations and stops included"
            if cutting
            else ""
        )
        + "."
        + ("" if split else " " + _SLOWED_NOTE),
        anchor="program-feed",
    )


def _slowed_rows(summary: Mapping[str, Any], feed: Mapping[str, Any], ctrl: Any) -> list[list[Cell]]:
    """One row per timing method: its slowed lines, by cause, and its path deviation against the
    program's path tolerance."""
    k = PROGRAM_KEY
    tol = summary[k].get("path_tolerance_mm")
    return [
        [
            _method_cell(summary, m, ctrl),
            Cell(_slowed_text(entry)),
            Cell(_by_limit_text(entry)),
            value_cell(summary, f"{k}.feed.{m}.n_lines_slowed_by_neighbours"),
            value_cell(summary, f"{k}.feed.{m}.path_deviation_mm"),
            Cell(deviation_words(entry.get("path_deviation_mm"), tol)),
        ]
        for m, entry in feed.items()
        if isinstance(entry, Mapping)
    ]


def _slowed_table(srows: list[list[Cell]]) -> Table:
    """The program's slowed lines by cause and path deviation per timing method."""
    return Table(
        "Program: slowed lines and path deviation",
        [
            "method",
            _SLOWED_HEADER,
            f"of which held down by a joint limit (count: slowest {SLOWED_SHOWN}, % of F, joint and derivative)",
            "of which slowed only by their neighbours: a stop or a held line (count)",
            "largest path deviation of the samples [mm]",
            "path deviation against the path tolerance",
        ],
        srows,
        _SLOWED_NOTE + " Held down by a joint limit: the joints cannot cruise at F on the line (Jn: joint n, and "
        "the derivative, velocity, acceleration or jerk, that binds; the full list is summary.json "
        "program.feed.<method>.slowed_by_limit); the other slowed lines (summary.json "
        "n_lines_slowed_by_neighbours) are "
        "slowed only by the accelerations around them: out of or into a stop, or into or out of a neighbouring "
        "line a limit holds down. Path deviation: the largest distance of a trajectory "
        "sample's TCP (forward kinematics of the commands) from the programmed path, against the program's path "
        "tolerance (✓ within, ✗ OUTSIDE; 'not measured' for a method the feed law did not check).",
        anchor="program-slowed",
    )
