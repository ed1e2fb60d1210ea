"""CL data (cutter-location points) as CSV: what CAM exports from 3- and 5-axis strategies.

One row a point of the tool tip, in the program (workpiece) frame, in program order:

=================================  ========================================================
column                             meaning
=================================  ========================================================
``x_mm, y_mm, z_mm`` or            the tool tip (required; the unit is in the name: a bare
``x_m, y_m, z_m``                  ``x`` is refused, CAM data is usually in mm)
``i, j, k``                        optional tool axis, from the tip towards the spindle (the
                                   CL convention); the TCP's z axis is ``-(i, j, k)``.
                                   Normalised when within :data:`CL_AXIS_NORM_TOL` of 1
``feed_mm_min`` or ``feed_m_s``    optional programmed feed of the move that ends at the row
``rapid``                          optional 0/1: the move that ends at the row is a rapid
``fx_N, fy_N, fz_N, mx_Nm,``       optional process wrench at the row, at the TCP, in the TCP
``my_Nm, mz_Nm``                   frame (N, N·m); all six or none
=================================  ========================================================

Blank lines and lines starting with ``#`` are skipped; other columns are an error (a typo would
otherwise drop data silently). Every error names the file, the line and the column.
SI inside: positions in m, feeds in m/s.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from models.errors import InputError
from models.tables import TableReader

from .textfile import PROGRAM_MAX_BYTES, read_program_text

__all__ = [
    "CL_AXIS_NORM_TOL",
    "ClPath",
    "parse_cl_csv",
    "read_cl_csv",
]

#: A tool-axis row whose norm is within this of 1 is normalised (CAM rounds to ~6 digits);
#: further off it is an error (not a unit vector: probably another column).
CL_AXIS_NORM_TOL = 1e-3
#: Largest CL file read (bytes): the limit of every program file.
CL_MAX_BYTES = PROGRAM_MAX_BYTES

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_POSITION = {"_mm": 1e-3, "_m": 1.0}
_FEED = {"feed_mm_min": 1e-3 / 60.0, "feed_m_s": 1.0}
_WRENCH = ("fx_n", "fy_n", "fz_n", "mx_nm", "my_nm", "mz_nm")
_AXIS = ("i", "j", "k")


class ClDataError(InputError):
    """A CL file that cannot be read; the message names the file, the line and the column."""


@dataclass(frozen=True)
class ClPath:
    """The points of a CL file, in the program (workpiece) frame.

    Attributes
    ----------
    points_m : np.ndarray
        Shape ``(N, 3)``, m: the tool tip.
    tool_axis : np.ndarray or None
        Shape ``(N, 3)``, unit vectors from the tip towards the spindle (TCP z = ``-tool_axis``),
        or None for a 3-axis file (no ``i, j, k``).
    feed_m_s : np.ndarray or None
        Shape ``(N,)``, m/s: the programmed feed of the move ending at each row (every row
        gives one; a rapid row's is not used), or None without a feed column.
    rapid : np.ndarray
        Shape ``(N,)``, bool: the move ending at the row is a rapid.
    wrench : np.ndarray or None
        Shape ``(N, 6)``, N and N·m, TCP frame, or None.
    line : np.ndarray
        Shape ``(N,)``, int: the 1-based line of each row in the file.
    source : str
        The file the data came from.
    """

    points_m: np.ndarray
    tool_axis: np.ndarray | None
    feed_m_s: np.ndarray | None
    rapid: np.ndarray
    wrench: np.ndarray | None
    line: np.ndarray
    source: str

    @property
    def n(self) -> int:
        """Number of points N."""
        return len(self.points_m)


def read_cl_csv(path: str | Path) -> ClPath:
    """Read a CL file (see the module docstring for the columns).

    Raises
    ------
    ClDataError
        Missing, unreadable, binary, empty or too large file, or any bad header or cell.
    """
    text = read_program_text(path, "CL", "CL data as CSV text", ClDataError)
    return parse_cl_csv(text, str(path))


def _columns(where: str, line: int, header: list[str]) -> dict[str, int]:
    """Column name (lower case) -> index, checked: position with a unit, no unknown or repeated name."""
    names = [h.strip().lower() for h in header]
    known = {f"{a}{u}" for a in "xyz" for u in _POSITION} | set(_AXIS) | set(_FEED) | {"rapid"} | set(_WRENCH)
    cols: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in ("x", "y", "z"):
            raise ClDataError(
                f"{where}: line {line}: column '{header[i].strip()}' has no unit; name it {name}_mm or {name}_m"
            )
        if name not in known:
            raise ClDataError(
                f"{where}: line {line}: unknown column '{header[i].strip()}'; expected x_mm, y_mm, z_mm (or _m), "
                "optional i, j, k, feed_mm_min (or feed_m_s), rapid, fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm"
            )
        if name in cols:
            raise ClDataError(f"{where}: line {line}: column '{header[i].strip()}' given twice")
        cols[name] = i
    units = {u for u in _POSITION if all(f"{a}{u}" in cols for a in "xyz")}
    if len(units) != 1 or sum(f"{a}{u}" in cols for a in "xyz" for u in _POSITION) != 3:
        raise ClDataError(
            f"{where}: line {line}: the tool tip needs the columns x_mm, y_mm, z_mm (or x_m, y_m, z_m), "
            "one unit for all three"
        )
    for group, what in ((_AXIS, "the tool axis i, j, k"), (_WRENCH, "the wrench fx_N … mz_Nm")):
        present = [g for g in group if g in cols]
        if present and len(present) != len(group):
            missing = [g for g in group if g not in cols]
            raise ClDataError(f"{where}: line {line}: {what} needs all its columns; missing {missing}")
    if sum(f in cols for f in _FEED) > 1:
        raise ClDataError(f"{where}: line {line}: give the feed once, as feed_mm_min or feed_m_s")
    return cols


#: The value kinds of a CL file.
VALUES = TableReader(ClDataError)


def _column(name: str, lines: np.ndarray, col: str, cells: list[str]) -> np.ndarray:
    """The numbers of one column (vectorised; a bad cell is found and named cell by cell)."""
    try:
        out = np.array(cells, dtype=float)
        if np.all(np.isfinite(out)) and all(_NUMBER.fullmatch(c.strip()) for c in cells):
            return out
    except ValueError:
        pass
    for line, cell in zip(lines, cells):
        VALUES.text_number(f"{name}: line {int(line)}, column '{col}'", cell, _NUMBER)
    raise AssertionError("unreachable: a column that does not convert has a bad cell")  # pragma: no cover


def parse_cl_csv(text: str, name: str = "<string>") -> ClPath:
    """Parse CL data given as CSV text (``name`` is the file named in errors).

    Raises
    ------
    ClDataError
        Bad header or cell, a zero or non-unit tool axis, a feed ``<= 0``, a ``rapid`` other than
        0/1, or no data row.
    """
    rows = [(i + 1, r) for i, r in enumerate(csv.reader(io.StringIO(text))) if r and any(c.strip() for c in r)]
    rows = [(i, r) for i, r in rows if not r[0].lstrip().startswith("#")]
    if not rows:
        raise ClDataError(f"{name}: no header and no data; expected a CSV header (x_mm, y_mm, z_mm, ...) and rows")
    header_line, header = rows[0]
    cols = _columns(name, header_line, header)
    data = rows[1:]
    if not data:
        raise ClDataError(f"{name}: a header and no data rows")
    for line, row in data:
        if len(row) != len(header):
            raise ClDataError(f"{name}: line {line}: {len(row)} cells, the header has {len(header)}")
    lines = np.array([line for line, _ in data], dtype=int)
    v = {col: _column(name, lines, col, [row[i] for _, row in data]) for col, i in cols.items()}
    unit = next(u for u in _POSITION if f"x{u}" in cols)
    points = np.column_stack([v[f"{a}{unit}"] for a in "xyz"]) * _POSITION[unit]
    return ClPath(
        points_m=points,
        tool_axis=_tool_axis(name, lines, v) if "i" in cols else None,
        feed_m_s=_feed(name, lines, v),
        rapid=_rapid(name, lines, v),
        wrench=np.column_stack([v[w] for w in _WRENCH]) if "fx_n" in cols else None,
        line=lines,
        source=name,
    )


def _tool_axis(name: str, lines: np.ndarray, v: dict[str, np.ndarray]) -> np.ndarray:
    axis = np.column_stack([v[a] for a in _AXIS])
    norm = np.linalg.norm(axis, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > CL_AXIS_NORM_TOL)
    if bad.size:
        k = int(bad[0])
        raise ClDataError(
            f"{name}: line {lines[k]}, columns 'i, j, k': the tool axis {axis[k].tolist()} has norm {norm[k]:.6g}; "
            f"expected a unit vector (within {CL_AXIS_NORM_TOL:g})"
        )
    return axis / norm[:, None]


def _feed(name: str, lines: np.ndarray, v: dict[str, np.ndarray]) -> np.ndarray | None:
    key = next((f for f in _FEED if f in v), None)
    if key is None:
        return None
    feed = v[key]
    bad = np.flatnonzero(~(feed > 0.0))
    if bad.size:
        k = int(bad[0])
        raise ClDataError(f"{name}: line {lines[k]}, column '{key}': feed {feed[k]:g} must be > 0")
    return feed * _FEED[key]


def _rapid(name: str, lines: np.ndarray, v: dict[str, np.ndarray]) -> np.ndarray:
    if "rapid" not in v:
        return np.zeros(len(lines), dtype=bool)
    r = v["rapid"]
    bad = np.flatnonzero((r != 0.0) & (r != 1.0))
    if bad.size:
        k = int(bad[0])
        raise ClDataError(f"{name}: line {lines[k]}, column 'rapid': {r[k]:g}; expected 0 or 1")
    return r == 1.0
