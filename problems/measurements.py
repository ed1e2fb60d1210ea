"""Measurement files: loading, validation and writing (see ``docs/measurement-file.md``).

A measurement file is a CSV table with one header row and one row per
measurement, in measurement order.  Lines starting with ``#`` are comments.
Column names carry their unit as a suffix (``x_mm``, ``q1_deg``, ``fx_N``);
a plain name is SI (m, rad, N, N*m, s, deg C).  Inside the library everything
is SI.

Every problem is an :class:`~models.errors.InputError` whose one-line message
names the file, the row (file line number) or column, the value and what was
expected; nothing is dropped silently.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError

#: A joint angle beyond this magnitude is implausible in radians (rad): two turns.
PLAUSIBLE_ANGLE_MAX_RAD = 4.0 * math.pi
#: A force beyond this is implausible (N); suggests a unit mistake.
PLAUSIBLE_FORCE_MAX_N = 1.0e5
#: A moment beyond this is implausible (N*m).
PLAUSIBLE_MOMENT_MAX_NM = 1.0e4
#: Plausible temperature range, deg C.
PLAUSIBLE_TEMPERATURE_C = (-50.0, 150.0)
#: A measurement standard deviation beyond this is implausible (m).
PLAUSIBLE_SIGMA_MAX_M = 0.01

# quantity -> {suffix: factor to SI}
_UNITS: dict[str, dict[str, float]] = {
    "angle": {"": 1.0, "_rad": 1.0, "_deg": math.pi / 180.0},
    "length": {"": 1.0, "_m": 1.0, "_mm": 1e-3, "_um": 1e-6},
    "force": {"": 1.0, "_N": 1.0, "_kN": 1e3},
    "moment": {"": 1.0, "_Nm": 1.0, "_Nmm": 1e-3},
    "time": {"": 1.0, "_s": 1.0, "_ms": 1e-3, "_min": 60.0, "_h": 3600.0},
    "temperature": {"": 1.0, "_C": 1.0, "_degC": 1.0},
}

#: Base column name -> quantity.
COLUMNS: dict[str, str] = {
    **{f"q{i}": "angle" for i in range(1, 7)},
    "fx": "force", "fy": "force", "fz": "force",
    "mx": "moment", "my": "moment", "mz": "moment",
    "x": "length", "y": "length", "z": "length",
    "rx": "angle", "ry": "angle", "rz": "angle",
    "t": "time", "temperature": "temperature", "sigma": "length",
}
Q_COLUMNS = tuple(f"q{i}" for i in range(1, 7))
WRENCH_COLUMNS = ("fx", "fy", "fz", "mx", "my", "mz")
POSITION_COLUMNS = ("x", "y", "z")
ROTATION_COLUMNS = ("rx", "ry", "rz")
#: Columns whose values are labels, not numbers.
LABEL_COLUMNS = ("point",)
#: Prefixes of columns that are carried along but ignored (user annotations).
IGNORED_PREFIXES = ("note", "extra_")

_UNIT_HINT = {"angle": "_deg", "length": "_mm", "force": "_kN", "moment": "_Nmm"}


@dataclass
class Measurements:
    """A validated measurement table in SI units.

    Attributes
    ----------
    q : ndarray, shape (N, 6)
        Commanded joint angles, rad.
    wrench : ndarray, shape (N, 6)
        ``[fx, fy, fz, mx, my, mz]`` on the TCP, base frame, N and N*m.
    p : ndarray, shape (N, 3) or None
        Measured point, measurement frame, m (None for command-only files).
    t : ndarray, shape (N,) or None
        Time, s.
    point : ndarray of str, shape (N,) or None
        Pose identifier.
    rotation : ndarray, shape (N, 3) or None
        Measured orientation as a rotation vector, rad (validated; not used by the fit).
    temperature : ndarray, shape (N,) or None
        deg C.
    sigma : ndarray, shape (N,) or None
        Measurement standard deviation per axis, m.
    line : ndarray of int, shape (N,)
        File line number of each row (1-based, header is line 1 of the table).
    source : str
        File name (for messages).
    units : dict
        Column actually read -> SI factor applied.
    """

    q: np.ndarray
    wrench: np.ndarray
    p: np.ndarray | None = None
    t: np.ndarray | None = None
    point: np.ndarray | None = None
    rotation: np.ndarray | None = None
    temperature: np.ndarray | None = None
    sigma: np.ndarray | None = None
    line: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    source: str = "<memory>"
    units: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.q)
        if len(self.line) != n:
            self.line = np.arange(2, n + 2)

    @property
    def n(self) -> int:
        return len(self.q)

    def subset(self, idx: np.ndarray) -> Measurements:
        """Rows ``idx`` (integer indices or boolean mask) as a new table."""
        def s(a: Any) -> Any:
            return None if a is None else a[idx]
        return Measurements(q=self.q[idx], wrench=self.wrench[idx], p=s(self.p), t=s(self.t),
                            point=s(self.point), rotation=s(self.rotation),
                            temperature=s(self.temperature), sigma=s(self.sigma),
                            line=self.line[idx], source=self.source, units=dict(self.units))

    def pose_groups(self) -> np.ndarray:
        """Integer pose id per row, shape (N,): the ``point`` column if given, else
        rows with identical commanded joints (to 1e-9 rad) form one pose."""
        if self.point is not None:
            _u, inv = np.unique(self.point, return_inverse=True)
            return inv.astype(int)
        key = np.round(self.q, 9)
        _u, inv = np.unique(key, axis=0, return_inverse=True)
        return np.asarray(inv, dtype=int).reshape(-1)

    def load_varies(self) -> bool:
        """True when the wrench is not the same on every row."""
        return bool(np.ptp(self.wrench, axis=0).max() > 0.0) if self.n else False


def _split_unit(where: str, col: str) -> tuple[str, float]:
    """Map a column header to (base name, SI factor); raise for unknown names."""
    if col in LABEL_COLUMNS:
        return col, 1.0
    for base, qty in COLUMNS.items():
        if col.startswith(base):
            suffix = col[len(base):]
            if suffix in _UNITS[qty]:
                return base, _UNITS[qty][suffix]
    # longest-prefix search for a helpful message
    known = ", ".join(list(COLUMNS) + list(LABEL_COLUMNS))
    raise InputError(f"{where}: unknown column '{col}'; expected one of {known} "
                     "(with an optional unit suffix such as _mm, _deg, _N), or a column starting with "
                     f"{' / '.join(IGNORED_PREFIXES)}")


def _parse_float(where: str, line: int, col: str, text: str) -> float:
    s = text.strip()
    if s == "":
        raise InputError(f"{where}: line {line}, column '{col}': empty cell; expected a number")
    try:
        v = float(s)
    except ValueError:
        raise InputError(f"{where}: line {line}, column '{col}': '{s}' is not a number") from None
    if not math.isfinite(v):
        raise InputError(f"{where}: line {line}, column '{col}': value {s} is not finite; "
                         "expected a finite number (remove or re-measure the row)")
    return v


def read_measurements(path: str | Path, require_position: bool = True,
                      require_wrench: bool = True) -> Measurements:
    """Read and validate a measurement file.

    Parameters
    ----------
    path : path
        CSV file (see ``docs/measurement-file.md``).
    require_position : bool
        Whether ``x, y, z`` are required (False for command files of ``predict``
        and ``compensate``).
    require_wrench : bool
        Whether ``fx..mz`` are required (a missing wrench is *not* assumed zero).

    Raises
    ------
    InputError
        Missing or duplicated columns, non-numeric, empty, NaN or infinite cells,
        implausible magnitudes (the message suggests the unit), duplicated rows,
        time running backwards.
    """
    from models.robot import read_text_file

    p = Path(path)
    text = read_text_file(p, "measurement file (CSV)")
    return parse_measurements(text, str(p), require_position, require_wrench)


#: Separators a spreadsheet may have written instead of ``,`` (name for the message).
_OTHER_SEPARATORS = {";": "';'", "\t": "tab", "|": "'|'"}


def _check_separator(where: str, header_line: int, header: list[str]) -> None:
    """Refuse a header that is one cell holding another separator (``;`` from a spreadsheet
    with a decimal comma, tabs): the message names the separator and asks for ``,``."""
    if len(header) > 2:
        return
    joined = ",".join(header)
    for sep, name in _OTHER_SEPARATORS.items():
        if joined.count(sep) >= 2:
            shown = joined[:60].replace("\t", "\\t")
            raise InputError(f"{where}: line {header_line}: the header '{shown}' looks {name}-separated; "
                             "use ',' as the separator (and '.' as the decimal point), e.g. export as "
                             "'CSV (comma delimited)'")


def parse_measurements(text: str, where: str = "<text>", require_position: bool = True,
                       require_wrench: bool = True) -> Measurements:
    """Parse measurement-file text; see :func:`read_measurements`."""
    lines = text.splitlines()
    table: list[tuple[int, list[str]]] = []
    reader = csv.reader(io.StringIO("\n".join(lines)))
    for lineno, cells in enumerate(reader, start=1):
        if not cells or (len(cells) == 1 and cells[0].strip() == ""):
            continue
        if cells[0].lstrip().startswith("#"):
            continue
        table.append((lineno, [c.strip() for c in cells]))
    if not table:
        raise InputError(f"{where}: empty file; expected a header row and measurement rows")
    header_line, header = table[0]
    _check_separator(where, header_line, header)
    rows = table[1:]
    if not rows:
        raise InputError(f"{where}: no measurement rows after the header (line {header_line})")
    # map columns
    colmap: dict[str, tuple[int, str, float]] = {}
    ignored: list[str] = []
    for k, col in enumerate(header):
        if col == "":
            raise InputError(f"{where}: line {header_line}: column {k + 1} has an empty name")
        if any(col.startswith(pfx) for pfx in IGNORED_PREFIXES):
            ignored.append(col)
            continue
        base, factor = _split_unit(where, col)
        if base in colmap:
            other = colmap[base][1]
            raise InputError(f"{where}: column '{base}' is given twice ('{other}' and '{col}'); "
                             "keep exactly one (with its unit suffix)")
        colmap[base] = (k, col, factor)
    required = list(Q_COLUMNS) + (list(WRENCH_COLUMNS) if require_wrench else []) \
        + (list(POSITION_COLUMNS) if require_position else [])
    missing = [c for c in required if c not in colmap]
    if missing:
        raise InputError(f"{where}: missing required column(s) {', '.join(missing)} "
                         f"(header on line {header_line}: {', '.join(header)})")
    for grp in (WRENCH_COLUMNS, POSITION_COLUMNS, ROTATION_COLUMNS):
        have = [c for c in grp if c in colmap]
        if have and len(have) != len(grp):
            raise InputError(f"{where}: columns {', '.join(grp)} go together; found only {', '.join(have)}")
    ncol = len(header)
    for lineno, cells in rows:
        if len(cells) != ncol:
            hint = ""
            if len(cells) > ncol and any(c.isdigit() and c.lstrip("-").isdigit() for c in cells):
                hint = "; a decimal comma (0,40)? write numbers with '.' (0.40)"
            raise InputError(f"{where}: line {lineno}: {len(cells)} cells, expected {ncol} (as the header){hint}")

    def column(base: str) -> np.ndarray:
        k, col, factor = colmap[base]
        return np.array([_parse_float(where, ln, col, cells[k]) for ln, cells in rows]) * factor

    line = np.array([ln for ln, _c in rows], dtype=int)
    units = {col: factor for (_k, col, factor) in colmap.values()}
    q = np.column_stack([column(c) for c in Q_COLUMNS])
    wrench = (np.column_stack([column(c) for c in WRENCH_COLUMNS]) if "fx" in colmap
              else np.zeros((len(rows), 6)))
    pos = np.column_stack([column(c) for c in POSITION_COLUMNS]) if "x" in colmap else None
    rot = np.column_stack([column(c) for c in ROTATION_COLUMNS]) if "rx" in colmap else None
    t = column("t") if "t" in colmap else None
    temp = column("temperature") if "temperature" in colmap else None
    sigma = column("sigma") if "sigma" in colmap else None
    point = None
    if "point" in colmap:
        k = colmap["point"][0]
        point = np.array([cells[k] for _ln, cells in rows], dtype=object)
        for ln, cells in rows:
            if cells[k] == "":
                raise InputError(f"{where}: line {ln}, column 'point': empty cell; expected a pose id")
        point = point.astype(str)
    m = Measurements(q=q, wrench=wrench, p=pos, t=t, point=point, rotation=rot, temperature=temp,
                     sigma=sigma, line=line, source=where, units=units)
    validate(m, colmap)
    return m


def _first_bad(values: np.ndarray, bad: np.ndarray) -> int:
    return int(np.argmax(bad))


def validate(m: Measurements, colmap: dict[str, tuple[int, str, float]] | None = None) -> None:
    """Check magnitudes and consistency of a table (raises :class:`InputError`)."""
    where = m.source

    def colname(base: str) -> str:
        return colmap[base][1] if colmap and base in colmap else base

    def factor(base: str) -> float:
        return colmap[base][2] if colmap and base in colmap else 1.0

    def check(base: str, values: np.ndarray, limit: float, qty: str) -> None:
        bad = np.abs(values) > limit
        if bad.any():
            i = _first_bad(values, bad)
            hint = _UNIT_HINT.get(qty)
            name = colname(base)
            unit_msg = (f"; if the column is in other units, declare them by the suffix (e.g. '{base}{hint}')"
                        if hint and name == base else "")
            raise InputError(f"{where}: line {m.line[i]}, column '{name}': value {values[i] / factor(base):g} "
                             f"is implausible (|value| above {limit:g} in SI units){unit_msg}")

    if m.n == 0:
        raise InputError(f"{where}: no measurement rows")
    for j, c in enumerate(Q_COLUMNS):
        check(c, m.q[:, j], PLAUSIBLE_ANGLE_MAX_RAD, "angle")
    for j, c in enumerate(WRENCH_COLUMNS):
        check(c, m.wrench[:, j], PLAUSIBLE_FORCE_MAX_N if j < 3 else PLAUSIBLE_MOMENT_MAX_NM,
              "force" if j < 3 else "moment")
    if m.p is not None:
        for j, c in enumerate(POSITION_COLUMNS):
            check(c, m.p[:, j], PLAUSIBLE_POSITION_MAX_M, "length")
    if m.rotation is not None:
        for j, c in enumerate(ROTATION_COLUMNS):
            check(c, m.rotation[:, j], 2 * math.pi, "angle")
    if m.sigma is not None:
        bad = ~(m.sigma > 0)
        if bad.any():
            i = _first_bad(m.sigma, bad)
            raise InputError(f"{where}: line {m.line[i]}, column '{colname('sigma')}': value "
                             f"{m.sigma[i]:g} m; expected a standard deviation > 0")
        check("sigma", m.sigma, PLAUSIBLE_SIGMA_MAX_M, "length")
    if m.temperature is not None:
        lo, hi = PLAUSIBLE_TEMPERATURE_C
        bad = (m.temperature < lo) | (m.temperature > hi)
        if bad.any():
            i = _first_bad(m.temperature, bad)
            raise InputError(f"{where}: line {m.line[i]}, column '{colname('temperature')}': value "
                             f"{m.temperature[i]:g} deg C is outside the plausible range [{lo:g}, {hi:g}] "
                             "(temperature is in deg C)")
    if m.t is not None and m.n > 1:
        back = np.diff(m.t) < 0
        if back.any():
            i = int(np.argmax(back)) + 1
            raise InputError(f"{where}: line {m.line[i]}, column '{colname('t')}': time {m.t[i]:g} s is "
                             f"earlier than the previous row ({m.t[i - 1]:g} s); rows must be in measurement order")
    # duplicated rows: every value equal (a copy, not a repeated measurement)
    parts = [m.q, m.wrench]
    for extra in (m.p, m.rotation):
        if extra is not None:
            parts.append(extra)
    for extra1 in (m.t, m.temperature, m.sigma):
        if extra1 is not None:
            parts.append(extra1[:, None])
    full = np.hstack(parts)
    if m.point is not None:
        _u, pid = np.unique(m.point, return_inverse=True)
        full = np.hstack([full, pid.reshape(-1, 1).astype(float)])
    _uniq, inv, counts = np.unique(full, axis=0, return_inverse=True, return_counts=True)
    inv = np.asarray(inv).reshape(-1)
    if (counts > 1).any():
        dup_rows = np.flatnonzero(counts[inv] > 1)
        a = dup_rows[0]
        b = next(r for r in dup_rows if r != a and inv[r] == inv[a])
        raise InputError(f"{where}: lines {m.line[a]} and {m.line[b]} are identical in every column "
                         "(a duplicated row); remove the copy, or if it is a genuine repeated measurement "
                         "its measured values cannot be bit-identical")


def measurements_to_csv(m: Measurements, mm: bool = False) -> str:
    """CSV text of a table (SI column names, or ``x_mm`` etc. when ``mm``)."""
    header: list[str] = list(Q_COLUMNS) + list(WRENCH_COLUMNS)
    cols: list[np.ndarray] = [m.q, m.wrench]
    if m.p is not None:
        header += [f"{c}_mm" if mm else c for c in POSITION_COLUMNS]
        cols.append(m.p * (1e3 if mm else 1.0))
    if m.rotation is not None:
        header += list(ROTATION_COLUMNS)
        cols.append(m.rotation)
    for name, arr in (("t", m.t), ("temperature", m.temperature), ("sigma", m.sigma)):
        if arr is not None:
            header.append(f"{name}_mm" if (mm and name == "sigma") else name)
            cols.append((arr * (1e3 if (mm and name == "sigma") else 1.0))[:, None])
    data = np.hstack(cols)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow((["point"] if m.point is not None else []) + header)
    for i, row in enumerate(data):
        w.writerow(([str(m.point[i])] if m.point is not None else []) + [repr(float(v)) for v in row])
    return buf.getvalue()


def commands_csv(header: Sequence[str], rows: np.ndarray) -> str:
    """CSV text of a numeric table (used by ``predict`` and ``compensate`` outputs)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(header))
    for row in np.asarray(rows, dtype=float):
        w.writerow([repr(float(v)) for v in row])
    return buf.getvalue()
