"""The tracker-dif formats: a laser-tracker export of targets and deviations.

Columns (``docs/measurement-file.md``, "Tracker exports"): ``step_order`` (the measurement
order), ``x_t, y_t, z_t`` (the target of the measured point, mm, robot base frame: the
acquisition software's nominal forward kinematics of the commands), ``x_dif, y_dif, z_dif``
(the deviation of the measured point from its target, mm) and ``joint_1..joint_6`` (the
commanded joint angles, deg).  The measured point is ``target + sign * dif``
(:data:`~.columns.TRACKER_FORMATS`: ``tracker-dif`` +1, ``tracker-dif-reversed`` -1); no
external load acts (the wrench is zero).  Units are the format's: the names carry none.
"""

from __future__ import annotations

import numpy as np

from models.errors import InputError

from .cells import Cells
from .columns import (
    IGNORED_PREFIXES,
    POSITION_COLUMNS,
    Q_COLUMNS,
    TRACKER_ANGLE_FACTOR,
    TRACKER_COLUMNS,
    TRACKER_DIF_COLUMNS,
    TRACKER_FORMATS,
    TRACKER_JOINT_COLUMNS,
    TRACKER_LENGTH_FACTOR,
    TRACKER_ORDER_COLUMN,
    TRACKER_TARGET_COLUMNS,
    tracker_columns_text,
)
from .table import Measurements
from .validation import PLAUSIBLE_NOMINAL_DEVIATION_M

Rows = list[tuple[int, list[str]]]


def is_tracker_header(header: list[str]) -> bool:
    """True when ``header`` has every column of the tracker-dif layout (``auto`` reads it so)."""
    return all(c in header for c in TRACKER_COLUMNS)


def position_name(file_format: str, axis: int) -> str:
    """How the measured coordinate ``axis`` (0..2) is formed, e.g. ``x_t + x_dif``."""
    op = "+" if TRACKER_FORMATS[file_format] > 0 else "-"
    return f"{TRACKER_TARGET_COLUMNS[axis]} {op} {TRACKER_DIF_COLUMNS[axis]}"


def tracker_columns(where: str, header_line: int, header: list[str], file_format: str) -> dict[str, int]:
    """Column name -> index of a tracker-dif header; raises for an unknown, repeated or missing
    column, listing what the format expects."""
    index: dict[str, int] = {}
    for k, col in enumerate(header):
        if any(col.startswith(pfx) for pfx in IGNORED_PREFIXES):
            continue
        if col not in TRACKER_COLUMNS:
            raise InputError(
                f"{where}: line {header_line}: unknown column '{col}' for the {file_format} format; it "
                f"expects {tracker_columns_text()} and columns starting with {' / '.join(IGNORED_PREFIXES)}; "
                "a file with other columns (loads, times, sigmas) is the compplan format (--format compplan, "
                "docs/measurement-file.md)"
            )
        if col in index:
            raise InputError(f"{where}: line {header_line}: column '{col}' is given twice; keep exactly one")
        index[col] = k
    missing = [c for c in TRACKER_COLUMNS if c not in index]
    if missing:
        raise InputError(
            f"{where}: missing column(s) {', '.join(missing)} of the {file_format} format (header on line "
            f"{header_line}: {', '.join(header)}); it expects {tracker_columns_text()}"
        )
    return index


def _numbers(rows: Rows, cells: Cells, index: dict[str, int], cols: tuple[str, ...]) -> np.ndarray:
    """The columns ``cols`` as written (file units), shape (N, len(cols))."""
    return np.array([[cells.number(ln, c, row[index[c]]) for c in cols] for ln, row in rows], dtype=float).reshape(
        len(rows), len(cols)
    )


def _check_order(where: str, line: np.ndarray, order: np.ndarray) -> None:
    """Rows in measurement order: ``step_order`` never decreases."""
    back = np.flatnonzero(np.diff(order) < 0)
    if len(back):
        i = int(back[0]) + 1
        raise InputError(
            f"{where}: line {line[i]}, column '{TRACKER_ORDER_COLUMN}': {order[i]:g} is below the previous "
            f"row's {order[i - 1]:g}; rows must be in measurement order (sort the file by {TRACKER_ORDER_COLUMN})"
        )


def _check_deviation(where: str, line: np.ndarray, dif_mm: np.ndarray) -> None:
    """A deviation from the nominal target beyond :data:`PLAUSIBLE_NOMINAL_DEVIATION_M` is not a
    robot's error: other units, or target and measurement in different frames."""
    gap = np.linalg.norm(dif_mm, axis=1) * TRACKER_LENGTH_FACTOR
    bad = np.flatnonzero(gap > PLAUSIBLE_NOMINAL_DEVIATION_M)
    if len(bad):
        i = int(bad[np.argmax(gap[bad])])
        vals = ", ".join(f"{v:g}" for v in dif_mm[i])
        raise InputError(
            f"{where}: line {line[i]}, columns {', '.join(TRACKER_DIF_COLUMNS)}: deviation ({vals}) mm is "
            f"{gap[i] * 1e3:.1f} mm from the target ({len(bad)} row(s) beyond "
            f"{PLAUSIBLE_NOMINAL_DEVIATION_M * 1e3:g} mm); a robot misses its nominal pose by millimetres: "
            "expected deviations in mm, with target and measurement in the robot base frame"
        )


def read_tracker(
    where: str, header_line: int, header: list[str], rows: Rows, cells: Cells, file_format: str
) -> tuple[Measurements, dict[str, tuple[int, str, float]]]:
    """The table of a tracker-dif file, and its column map for :func:`~.validation.validate`.

    Parameters
    ----------
    where : str
        The file, for messages.
    header_line, header, rows
        The header's line number and cells, and the rows as (line, cells); row lengths checked.
    cells : Cells
        The cell parser of the file's dialect.
    file_format : str
        A key of :data:`~.columns.TRACKER_FORMATS`.

    Returns
    -------
    Measurements
        ``q`` (rad), zero wrench, ``p`` = target + sign * dif (m, base frame of the targets),
        ``target`` (m), no ``t`` (the row order is the time order).
    colmap : dict
        Quantity -> (column index, name as shown, SI factor).
    """
    index = tracker_columns(where, header_line, header, file_format)
    sign = TRACKER_FORMATS[file_format]
    line = np.array([ln for ln, _c in rows], dtype=int)
    _check_order(where, line, _numbers(rows, cells, index, (TRACKER_ORDER_COLUMN,))[:, 0])
    q = _numbers(rows, cells, index, TRACKER_JOINT_COLUMNS) * TRACKER_ANGLE_FACTOR
    target_mm = _numbers(rows, cells, index, TRACKER_TARGET_COLUMNS)
    dif_mm = _numbers(rows, cells, index, TRACKER_DIF_COLUMNS)
    _check_deviation(where, line, dif_mm)
    colmap = {q_col: (index[c], c, TRACKER_ANGLE_FACTOR) for q_col, c in zip(Q_COLUMNS, TRACKER_JOINT_COLUMNS)}
    for axis, base in enumerate(POSITION_COLUMNS):
        colmap[base] = (index[TRACKER_TARGET_COLUMNS[axis]], position_name(file_format, axis), TRACKER_LENGTH_FACTOR)
    units = {c: 1.0 for c in (TRACKER_ORDER_COLUMN,)}
    units.update({c: TRACKER_LENGTH_FACTOR for c in TRACKER_TARGET_COLUMNS + TRACKER_DIF_COLUMNS})
    units.update({c: TRACKER_ANGLE_FACTOR for c in TRACKER_JOINT_COLUMNS})
    m = Measurements(
        q=q,
        wrench=np.zeros((len(rows), 6)),
        p=(target_mm + sign * dif_mm) * TRACKER_LENGTH_FACTOR,
        target=target_mm * TRACKER_LENGTH_FACTOR,
        line=line,
        source=where,
        units=units,
        columns={base: col for base, (_k, col, _f) in colmap.items()},
        file_format=file_format,
    )
    return m, colmap
