"""Writing tables as CSV text: measurement tables and plain numeric command tables."""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence

import numpy as np

from .columns import (
    POSITION_COLUMNS,
    Q_COLUMNS,
    ROTATION_COLUMNS,
    SIGMA_ROT_COLUMNS,
    SIGMA_XYZ_COLUMNS,
    WRENCH_COLUMNS,
)
from .table import Measurements


def measurements_to_csv(m: Measurements, mm: bool = False) -> str:
    """CSV text of a table (comma dialect; SI column names, or ``x_mm`` etc. when ``mm``).

    The position standard deviation is written as one ``sigma`` column when every row
    has the same value on the three axes (exactly ``sigma``), else as ``sigma_x,
    sigma_y, sigma_z``; the orientation one as ``sigma_r`` or ``sigma_rx, sigma_ry,
    sigma_rz`` (rad) likewise.  Times are written in seconds (``t``; date-times as
    seconds since the first row)."""
    header: list[str] = list(Q_COLUMNS) + list(WRENCH_COLUMNS)
    cols: list[np.ndarray] = [m.q, m.wrench]
    length = 1e3 if mm else 1.0
    if m.p is not None:
        header += [f"{c}_mm" if mm else c for c in POSITION_COLUMNS]
        cols.append(m.p * length)
    if m.rotation is not None:
        header += list(ROTATION_COLUMNS)
        cols.append(m.rotation)
    for name, arr in (("t", m.t), ("temperature", m.temperature)):
        if arr is not None:
            header.append(name)
            cols.append(arr[:, None])
    if m.sigma_xyz is not None and not (
        m.sigma is not None and np.array_equal(m.sigma_xyz, m.sigma[:, None] * np.ones((1, 3)))
    ):
        header += [f"{c}_mm" if mm else c for c in SIGMA_XYZ_COLUMNS]
        cols.append(m.sigma_xyz * length)
    elif m.sigma is not None:
        header.append("sigma_mm" if mm else "sigma")
        cols.append((m.sigma * length)[:, None])
    if m.sigma_rot is not None:
        if np.array_equal(m.sigma_rot, m.sigma_rot[:, :1] * np.ones((1, 3))):
            header.append("sigma_r")
            cols.append(m.sigma_rot[:, :1])
        else:
            header += list(SIGMA_ROT_COLUMNS)
            cols.append(m.sigma_rot)
    data = np.hstack(cols)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow((["point"] if m.point is not None else []) + header)
    for i, row in enumerate(data):
        w.writerow(([str(m.point[i])] if m.point is not None else []) + [repr(float(v)) for v in row])
    return buf.getvalue()


def commands_csv(header: Sequence[str], rows: np.ndarray, text: Mapping[str, Sequence[str]] | None = None) -> str:
    """CSV text of a numeric table (used by ``predict`` and ``compensate`` outputs).

    Parameters
    ----------
    header : sequence of str
        Names of the numeric columns.
    rows : ndarray, shape (N, len(header))
        The numbers (written as Python ``repr``: exact round trip; NaN as ``nan``).
    text : mapping of str to sequence of str, optional
        Text columns after the numeric ones, name -> N strings (quoted by the CSV writer where a
        value holds a comma, quote or line break; an empty string is an empty field).
    """
    text = dict(text or {})
    rows = np.asarray(rows, dtype=float)
    for name, values in text.items():
        if len(values) != len(rows):
            raise ValueError(f"text column {name!r}: {len(values)} values for {len(rows)} rows")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(header) + list(text))
    for i, row in enumerate(rows):
        w.writerow([repr(float(v)) for v in row] + [str(values[i]) for values in text.values()])
    return buf.getvalue()
