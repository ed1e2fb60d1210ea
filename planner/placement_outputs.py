"""The files of a placement study (:func:`write_study`): ``summary.json``, ``scores.csv`` and
``ranking.csv`` (:func:`scores_csv`, the columns of :data:`SCORE_COLUMNS`) and the report."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING
from collections.abc import Iterator

import numpy as np

from problems.placement.grid import GRID_AXES
from problems.placement.scores import PlacementStatus

if TYPE_CHECKING:
    from planner.placement_result import PlacementStudy

__all__ = [
    "SCORE_COLUMNS",
    "scores_csv",
    "write_study",
]


#: Columns of ``scores.csv`` (one row per placement, grid order; edge units in the names; ``status``
#: a :class:`PlacementStatus` value, ``best_branch`` an IK branch label; empty cells where a value
#: does not exist).
SCORE_COLUMNS = (
    "index",
    "x_m",
    "y_m",
    "z_m",
    "yaw_deg",
    "tilt_deg",
    "status",
    "best_branch",
    "feasible_branches",
    "rms_error_mm",
    "max_error_mm",
    "joint_margin_deg",
    "singular_margin",
    "blocked_waypoint",
)
#: Decimals of the grid coordinates in the CSV files (m, deg): the grid's own values, without the
#: round-off of ``linspace`` (-0.19999999999999996 -> -0.2).
GRID_DIGITS = 12


def _text(values: np.ndarray, finite: np.ndarray | None = None) -> np.ndarray:
    """Numbers as CSV text (shortest round-trip form), an object array; empty where ``finite`` is
    False."""
    out = np.asarray(values).astype(str).astype(object)
    if finite is not None:
        out[~finite] = ""
    return out


#: Rows of the CSV files formatted at a time (about 40 MB of text objects in memory).
CSV_BLOCK_ROWS = 50_000


def scores_csv(st: PlacementStudy, rows: np.ndarray | None = None, rank: bool = False) -> Iterator[bytes]:
    """``scores.csv`` (every placement, grid order) or, with ``rows`` and ``rank``, ``ranking.csv``
    (the feasible placements best first, with a ``rank`` column), in parts of
    :data:`CSV_BLOCK_ROWS` rows: the columns of :data:`SCORE_COLUMNS`, edge units in the names (m,
    deg, mm), ``status`` and ``best_branch`` by name, empty cells where a value does not exist (an
    infeasible placement's errors and margins, no blocked waypoint).  A sweep may hold millions of
    placements: only one block is formatted at a time."""
    sc, pl = st.sweep.scores, st.sweep.placements
    idx_all = np.arange(len(pl)) if rows is None else np.asarray(rows, dtype=int)
    scale = np.array([GRID_AXES[k][0] for k in GRID_AXES])
    labels = np.array(list(st.branch_labels) + [""], dtype=object)
    names = np.array([PlacementStatus.from_code(c).value for c in range(len(PlacementStatus))], dtype=object)
    yield (",".join((["rank"] if rank else []) + list(SCORE_COLUMNS)) + "\n").encode()
    for a in range(0, len(idx_all), CSV_BLOCK_ROWS):
        idx = idx_all[a : a + CSV_BLOCK_ROWS]
        grid = np.round(pl[idx] / scale, GRID_DIGITS) + 0.0  # -0.0 -> 0.0
        cols = [_text(idx)] + [_text(grid[:, j]) for j in range(grid.shape[1])]
        cols += [
            names[sc.status[idx].astype(int)],
            labels[sc.best_branch[idx].astype(int)],
            _text(sc.feasible_branches[idx]),
        ]
        for v, f in (
            (sc.rms_error_m, 1e3),
            (sc.max_error_m, 1e3),
            (sc.joint_margin_rad, 180.0 / np.pi),
            (sc.singular_margin, 1.0),
        ):
            x = v[idx] * f
            cols.append(_text(x, np.isfinite(x)))
        bw = sc.blocked_waypoint[idx]
        cols.append(_text(bw, bw >= 0))
        if rank:
            cols.insert(0, _text(np.arange(a + 1, a + len(idx) + 1)))
        lines = map(",".join, zip(*(c.tolist() for c in cols)))
        yield ("\n".join(lines) + "\n").encode()


def write_study(st: PlacementStudy, folder: str | Path, with_report: bool = True) -> list[Path]:
    """Write ``summary.json``, ``scores.csv``, ``ranking.csv`` and, with ``with_report``, the report
    (``report.html`` and ``figures/``), whole or not at all."""
    from planner.output import OutputSet

    out = OutputSet(folder)
    summary = st.summary()
    out.add_json("summary.json", summary)
    out.add_bytes("scores.csv", lambda: scores_csv(st))
    out.add_bytes("ranking.csv", lambda: scores_csv(st, st.ranked, rank=True))
    if with_report:
        from planner.report.placement import figures, html

        figs = figures(st)
        for name, data in figs.items():
            out.add_bytes(f"figures/{name}", data)
        out.add_bytes("report.html", html(st, sorted(figs), summary).encode("utf-8"))
    return out.publish()
