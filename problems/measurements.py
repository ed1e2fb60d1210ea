"""Measurement files: loading, validation and writing (see ``docs/measurement-file.md``).

A measurement file is a CSV table with one header row and one row per
measurement, in measurement order.  Lines starting with ``#`` are comments.
Column names carry their unit as a suffix (``x_mm``, ``q1_deg``, ``fx_N``);
a plain name is SI (m, rad, N, N*m, s, deg C).  Inside the library everything
is SI.

Two CSV dialects are read (``dialect``): ``comma`` (``,`` separator, ``.``
decimal point) and ``semicolon`` (``;`` separator, decimal comma ``1,5``; a
spreadsheet's or tracker software's export in a German/French locale); ``auto``
tells them apart by the header line and records that it did in
:attr:`Measurements.notes`.  Joint columns may carry other names than
``q1..q6`` (``joint_names``: the ROS preset ``"ros-ur"`` or six names).

Every problem is an :class:`~models.errors.InputError` whose one-line message
names the file, the row (file line number) or column, the value and what was
expected; nothing is dropped silently.  The library prints nothing: what it
decided on its own (a detected dialect, date-times read as times, a joint-name
mapping) is stored in :attr:`Measurements.notes` for the caller to show.
"""

from __future__ import annotations

import csv
import datetime as _dt
import io
import math
import re
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
#: An orientation-measurement standard deviation beyond this is implausible (rad, about 5.7 deg).
PLAUSIBLE_SIGMA_ROT_MAX_RAD = 0.1

# quantity -> {suffix: factor to SI}
_UNITS: dict[str, dict[str, float]] = {
    "angle": {"": 1.0, "_rad": 1.0, "_deg": math.pi / 180.0},
    # small angles (orientation standard deviations): also milli- and microradians.  Not
    # offered for q1..q6, whose messages elsewhere quote a column's unit as deg or rad.
    "small_angle": {"": 1.0, "_rad": 1.0, "_deg": math.pi / 180.0, "_mrad": 1e-3, "_urad": 1e-6},
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
    "sigma_x": "length", "sigma_y": "length", "sigma_z": "length",
    "sigma_r": "small_angle",
    "sigma_rx": "small_angle", "sigma_ry": "small_angle", "sigma_rz": "small_angle",
}
Q_COLUMNS = tuple(f"q{i}" for i in range(1, 7))
WRENCH_COLUMNS = ("fx", "fy", "fz", "mx", "my", "mz")
POSITION_COLUMNS = ("x", "y", "z")
ROTATION_COLUMNS = ("rx", "ry", "rz")
#: Per-axis standard deviations of the position measurement (length).
SIGMA_XYZ_COLUMNS = ("sigma_x", "sigma_y", "sigma_z")
#: Per-axis standard deviations of the orientation measurement (angle).
SIGMA_ROT_COLUMNS = ("sigma_rx", "sigma_ry", "sigma_rz")
#: Columns whose values are labels, not numbers.
LABEL_COLUMNS = ("point",)
#: Prefixes of columns that are carried along but ignored (user annotations).
IGNORED_PREFIXES = ("note", "extra_")

#: CSV dialects: name -> (separator, decimal comma).
DIALECTS: dict[str, tuple[str, bool]] = {"comma": (",", False), "semicolon": (";", True)}
#: Values of the ``dialect`` parameter.
DIALECT_CHOICES = ("auto", *DIALECTS)

#: Presets of ``joint_names``: name -> the six joint column names mapped to q1..q6 in order.
JOINT_NAME_PRESETS: dict[str, tuple[str, ...]] = {
    "ros-ur": ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
               "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"),
}

_UNIT_HINT = {"angle": "_deg", "length": "_mm", "force": "_kN", "moment": "_Nmm",
              "small_angle": "_urad"}


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
        Time, s.  When the file gave date-times, seconds since :attr:`t_origin`
        (the first row's date-time, so ``t[0] == 0``).
    point : ndarray of str, shape (N,) or None
        Pose identifier.
    rotation : ndarray, shape (N, 3) or None
        Measured orientation as a rotation vector, rad (validated; not used by the fit).
    temperature : ndarray, shape (N,) or None
        deg C.
    sigma : ndarray, shape (N,) or None
        Standard deviation of the position measurement, m, one value per row that
        stands for every axis.  From the ``sigma`` column; when the file gives
        ``sigma_x, sigma_y, sigma_z`` instead, the per-row RMS over the three axes,
        ``sqrt((sx**2 + sy**2 + sz**2) / 3)`` (see :attr:`sigma_xyz` for the axes).
    line : ndarray of int, shape (N,)
        File line number of each row (1-based, header is line 1 of the table).
    source : str
        File name (for messages).
    units : dict
        Column actually read (as written in the file) -> SI factor applied.
    sigma_xyz : ndarray, shape (N, 3) or None
        Standard deviation of the position measurement per axis ``x, y, z`` of the
        measurement frame, m.  From ``sigma_x, sigma_y, sigma_z``, or ``sigma``
        broadcast to the three axes when only ``sigma`` is given.
    sigma_rot : ndarray, shape (N, 3) or None
        Standard deviation of the orientation measurement per component of the
        rotation vector ``rx, ry, rz``, rad.  From ``sigma_rx, sigma_ry, sigma_rz``,
        or ``sigma_r`` broadcast to the three; only with ``rotation``.
    notes : list of str
        What the reader decided by itself and the user should know (a detected CSV
        dialect, date-times read as times, a joint-name mapping), one line each,
        starting with the file name.  The library never prints them.
    columns : dict
        Quantity (``q1``, ``x``, ``sigma_x`` ...) -> the column that held it, as
        written in the file (``q1_deg``, ``shoulder_pan_joint``, ``x_mm`` ...).
    t_origin : datetime.datetime or None
        The first row's date-time when ``t`` was given as date-times (aware when the
        file gave a time zone, naive otherwise); ``None`` for numeric times.
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
    sigma_xyz: np.ndarray | None = None
    sigma_rot: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    columns: dict[str, str] = field(default_factory=dict)
    t_origin: _dt.datetime | None = None

    def __post_init__(self) -> None:
        n = len(self.q)
        if len(self.line) != n:
            self.line = np.arange(2, n + 2)
        # the single sigma and the per-axis sigmas describe the same thing: fill the missing one
        if self.sigma_xyz is None and self.sigma is not None:
            s = np.asarray(self.sigma, dtype=float).reshape(-1)
            self.sigma_xyz = np.repeat(s[:, None], 3, axis=1)
        elif self.sigma_xyz is not None:
            self.sigma_xyz = np.asarray(self.sigma_xyz, dtype=float).reshape(-1, 3)
            if self.sigma is None:
                self.sigma = sigma_rms(self.sigma_xyz)
        if self.sigma_rot is not None:
            self.sigma_rot = np.asarray(self.sigma_rot, dtype=float).reshape(-1, 3)

    @property
    def n(self) -> int:
        return len(self.q)

    def subset(self, idx: np.ndarray) -> Measurements:
        """Rows ``idx`` (integer indices or boolean mask) as a new table (notes, column
        names and the date-time origin carried along)."""
        def s(a: Any) -> Any:
            return None if a is None else a[idx]
        return Measurements(q=self.q[idx], wrench=self.wrench[idx], p=s(self.p), t=s(self.t),
                            point=s(self.point), rotation=s(self.rotation),
                            temperature=s(self.temperature), sigma=s(self.sigma),
                            line=self.line[idx], source=self.source, units=dict(self.units),
                            sigma_xyz=s(self.sigma_xyz), sigma_rot=s(self.sigma_rot),
                            notes=list(self.notes), columns=dict(self.columns), t_origin=self.t_origin)

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


def sigma_rms(sigma_xyz: np.ndarray) -> np.ndarray:
    """Per-row RMS of per-axis standard deviations.

    Parameters
    ----------
    sigma_xyz : ndarray, shape (N, 3)
        Standard deviations per axis, m.

    Returns
    -------
    ndarray, shape (N,)
        ``sqrt(mean(sigma_xyz**2, axis=1))``, m: the one standard deviation per axis
        with the same total variance.
    """
    s = np.asarray(sigma_xyz, dtype=float).reshape(-1, 3)
    return np.sqrt(np.mean(s ** 2, axis=1))


# ----------------------------------------------------------------------------------
# Options: dialect and joint names
# ----------------------------------------------------------------------------------

def resolve_joint_names(joint_names: str | Sequence[str] | None, where: str = "joint_names") \
        -> tuple[str, ...] | None:
    """The six joint column names of a ``joint_names`` option, or None for ``q1..q6``.

    Parameters
    ----------
    joint_names : str, sequence of str or None
        ``None`` (or ``"none"``): the plain ``q1..q6``.  A preset name of
        :data:`JOINT_NAME_PRESETS` (``"ros-ur"``), six comma-separated names
        (``"a,b,c,d,e,f"``) or a sequence of six names: the columns read as
        ``q1..q6`` in this order.
    where : str
        What the option is called, for messages.

    Raises
    ------
    InputError
        Unknown preset, not six names, an empty or repeated name, a name that is
        another column of the format (``fx``, ``x``, ``t``, ``q3`` for joint 1 ...).
    """
    if joint_names is None:
        return None
    if isinstance(joint_names, str):
        spec = joint_names.strip()
        if spec in ("", "none"):
            return None
        if spec in JOINT_NAME_PRESETS:
            return JOINT_NAME_PRESETS[spec]
        if "," not in spec:
            raise InputError(f"{where} {joint_names!r}: expected a preset ({', '.join(JOINT_NAME_PRESETS)}), "
                             "'none' (q1..q6) or six comma-separated column names (joint 1 to joint 6)")
        names = [n.strip() for n in spec.split(",")]
    else:
        names = [str(n).strip() for n in joint_names]
    shown = ",".join(names)
    if len(names) != 6:
        raise InputError(f"{where} '{shown}': {len(names)} name(s); expected six column names, joint 1 to joint 6 "
                         f"(or a preset: {', '.join(JOINT_NAME_PRESETS)})")
    for i, name in enumerate(names):
        if name == "":
            raise InputError(f"{where} '{shown}': name {i + 1} is empty; expected six column names")
        if names.index(name) != i:
            raise InputError(f"{where} '{shown}': '{name}' is given for joints {names.index(name) + 1} and {i + 1}; "
                             "expected six different column names")
        for other in names:
            if other != name and name.startswith(other) and name[len(other):] in _UNITS["angle"]:
                raise InputError(f"{where} '{shown}': '{name}' reads as '{other}' with a unit suffix; "
                                 "expected six column names without unit suffixes (a column may add one)")
        try:
            as_column = _split_unit(where, name)[0]
        except InputError:
            as_column = None
        taken = (as_column is not None and not (as_column == Q_COLUMNS[i] and name == Q_COLUMNS[i])) \
            or any(name.startswith(pfx) for pfx in IGNORED_PREFIXES)
        if taken:
            raise InputError(f"{where} '{shown}': '{name}' (joint {i + 1}) is the name of another column of the "
                             "measurement file format; expected the file's own names of the six joint columns")
    return tuple(names)


def _joint_map(joint_names: tuple[str, ...] | None) -> dict[str, str]:
    """Joint column name -> ``q<i>`` (empty for the plain names)."""
    if joint_names is None:
        return {}
    return {name: Q_COLUMNS[i] for i, name in enumerate(joint_names)}


def _ros_hint(col: str) -> str:
    """The hint for an unknown column that is a ROS UR joint name."""
    for preset, names in JOINT_NAME_PRESETS.items():
        for name in names:
            if col.startswith(name) and col[len(name):] in _UNITS["angle"]:
                return (f"; '{name}' is a ROS joint name: read the joint columns with --joint-names {preset} "
                        f"(joint_names='{preset}': {', '.join(names)} -> q1..q6)")
    return ""


# ----------------------------------------------------------------------------------
# Cells
# ----------------------------------------------------------------------------------

#: A decimal number as written with '.' (after a decimal comma was turned into '.').
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
#: An ISO-8601-like date-time: date, 'T' or space, hh:mm[:ss[.fff]], optional zone.
_DATETIME = re.compile(r"(\d{4})-(\d{2})-(\d{2})[Tt ](\d{2}):(\d{2})(?::(\d{2})(?:[.,](\d+))?)?"
                       r"\s*(Z|z|[+-]\d{2}(?::?\d{2})?)?")


class _Cells:
    """Cell parser of one dialect; counts how decimals were written (for the notes)."""

    def __init__(self, where: str, decimal_comma: bool) -> None:
        self.where = where
        self.decimal_comma = decimal_comma
        self.n_comma = 0        # cells read with a decimal comma
        self.n_point = 0        # cells read with a decimal point (in the decimal-comma dialect)

    def expected(self) -> str:
        return ("a decimal number with a decimal comma (1,5 or -2e-3; no thousands separators)"
                if self.decimal_comma else "a decimal number (1.5 or -2e-3; no thousands separators)")

    def number(self, line: int, col: str, text: str) -> float:
        """The finite number of a cell (raises naming the file, line, column, value)."""
        s = text.strip()
        where = f"{self.where}: line {line}, column '{col}'"
        if s == "":
            raise InputError(f"{where}: empty cell; expected a number")
        t = s
        if self.decimal_comma:
            if "," in s and "." in s:
                raise InputError(f"{where}: '{s}' has both '.' and ',' (a thousands separator?); expected "
                                 f"{self.expected()}")
            if s.count(",") > 1:
                raise InputError(f"{where}: '{s}' has more than one ',' (a thousands separator?); expected "
                                 f"{self.expected()}")
            t = s.replace(",", ".")
        if _NUMBER.fullmatch(t):
            if self.decimal_comma:
                if "," in s:
                    self.n_comma += 1
                elif "." in s:
                    self.n_point += 1
            return float(t)
        try:
            v = float(t)
        except ValueError:
            v = 0.0
        if not math.isfinite(v):
            raise InputError(f"{where}: value {s} is not finite; "
                             "expected a finite number (remove or re-measure the row)")
        hint = ""
        if not self.decimal_comma and re.fullmatch(r"[+-]?\d*,\d+", s):
            hint = (" (a decimal comma, or a thousands separator? this file is read with '.' as the decimal "
                    "point)")
        elif re.fullmatch(r"[+-]?\d{1,3}(?:[ '_.,\u00a0\u202f]\d{3})+(?:[.,]\d*)?", s):
            hint = " (a thousands separator?)"
        raise InputError(f"{where}: '{s}' is not a number{hint}; expected {self.expected()}")


def _parse_float(where: str, line: int, col: str, text: str) -> float:
    """A cell of the comma dialect as a finite float (kept for callers of the old helper)."""
    return _Cells(where, False).number(line, col, text)


def _parse_datetime(where: str, line: int, col: str, text: str) -> tuple[_dt.datetime, float] | None:
    """``(whole-second date-time, fraction of a second)`` of an ISO-8601-like cell, or None
    when the cell does not look like a date-time (raises for a malformed one)."""
    mt = _DATETIME.fullmatch(text.strip())
    if mt is None:
        return None
    y, mo, d, h, mi, sec, frac, zone = mt.groups()
    tz: _dt.tzinfo | None = None
    if zone:
        if zone in ("Z", "z"):
            tz = _dt.timezone.utc
        else:
            sign = -1 if zone[0] == "-" else 1
            digits = zone[1:].replace(":", "")
            hh, mm = int(digits[:2]), int(digits[2:] or 0)
            if hh > 23 or mm > 59:
                raise InputError(f"{where}: line {line}, column '{col}': '{text.strip()}' has the time-zone offset "
                                 f"'{zone}'; expected +hh:mm within a day")
            tz = _dt.timezone(sign * _dt.timedelta(hours=hh, minutes=mm))
    try:
        stamp = _dt.datetime(int(y), int(mo), int(d), int(h), int(mi), int(sec or 0), tzinfo=tz)
    except ValueError as exc:
        raise InputError(f"{where}: line {line}, column '{col}': '{text.strip()}' is not a valid date-time "
                         f"({exc}); expected e.g. 2024-05-03T10:15:02.125") from None
    return stamp, (float("0." + frac) if frac else 0.0)


def _time_column(where: str, rows: list[tuple[int, list[str]]], k: int, col: str, factor: float,
                 cells: _Cells) -> tuple[np.ndarray, _dt.datetime | None]:
    """The ``t`` column: numbers (times in the column's unit) or date-times (seconds since
    the first row).  Returns (t in s, shape (N,); first date-time or None)."""
    parsed = [_parse_datetime(where, ln, col, c[k]) for ln, c in rows]
    if parsed[0] is None:
        for (ln, c), p in zip(rows, parsed):
            if p is not None:
                raise InputError(f"{where}: line {ln}, column '{col}': '{c[k].strip()}' is a date-time but line "
                                 f"{rows[0][0]} holds a number ('{rows[0][1][k].strip()}'); expected the whole "
                                 "column as numbers or the whole column as date-times")
        return np.array([cells.number(ln, col, c[k]) for ln, c in rows]) * factor, None
    if col != "t":
        ln, c = rows[0]
        raise InputError(f"{where}: line {ln}, column '{col}': '{c[k].strip()}' is a date-time; a unit suffix "
                         f"declares numeric times; name the column 't' for date-times")
    first_ln, first = rows[0][0], rows[0][1][k].strip()
    stamp0, frac0 = parsed[0]  # type: ignore[misc]
    aware0 = stamp0.tzinfo is not None
    t = np.empty(len(rows))
    for i, ((ln, c), p) in enumerate(zip(rows, parsed)):
        if p is None:
            cell = c[k].strip()
            try:
                cells.number(ln, col, cell)
                what = "is a number"
            except InputError:
                what = "is neither a date-time (e.g. 2024-05-03T10:15:02.125) nor a number"
            raise InputError(f"{where}: line {ln}, column '{col}': '{cell}' {what} but line {first_ln} holds a "
                             f"date-time ('{first}'); expected the whole column as date-times")
        stamp, frac = p
        if (stamp.tzinfo is not None) != aware0:
            raise InputError(f"{where}: line {ln}, column '{col}': '{c[k].strip()}' "
                             f"{'has' if not aware0 else 'has no'} time zone but line {first_ln} ('{first}') "
                             f"{'has none' if not aware0 else 'has one'}; expected every date-time with a zone "
                             "or every one without")
        t[i] = (stamp - stamp0).total_seconds() + (frac - frac0)
        if i and t[i] < t[i - 1]:
            prev_ln, prev = rows[i - 1][0], rows[i - 1][1][k].strip()
            raise InputError(f"{where}: line {ln}, column '{col}': time '{c[k].strip()}' is earlier than the "
                             f"previous row (line {prev_ln}: '{prev}'); rows must be in measurement order")
    origin = stamp0 + _dt.timedelta(seconds=frac0)
    return t, origin


# ----------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------

def _split_unit(where: str, col: str, joint_map: dict[str, str] | None = None) -> tuple[str, float]:
    """Map a column header to (base name, SI factor); raise for unknown names."""
    if col in LABEL_COLUMNS:
        return col, 1.0
    for name, base in (joint_map or {}).items():
        if col.startswith(name) and col[len(name):] in _UNITS["angle"]:
            return base, _UNITS["angle"][col[len(name):]]
    for base, qty in COLUMNS.items():
        if col.startswith(base):
            suffix = col[len(base):]
            if suffix in _UNITS[qty]:
                return base, _UNITS[qty][suffix]
    known = ", ".join(list(COLUMNS) + list(LABEL_COLUMNS))
    hint = _ros_hint(col) if not joint_map else ""
    raise InputError(f"{where}: unknown column '{col}'{hint}; expected one of {known} "
                     "(with an optional unit suffix such as _mm, _deg, _N), or a column starting with "
                     f"{' / '.join(IGNORED_PREFIXES)}")


def read_measurements(path: str | Path, require_position: bool = True, require_wrench: bool = True, *,
                      dialect: str = "auto",
                      joint_names: str | Sequence[str] | None = None) -> Measurements:
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
    dialect : {"auto", "comma", "semicolon"}
        ``comma``: ``,`` separates cells, ``.`` is the decimal point.  ``semicolon``:
        ``;`` separates cells, numbers have a decimal comma (``1,5``; ``1.5`` is read
        too, a cell with both ``,`` and ``.`` is an error).  ``auto`` (default): the
        ``semicolon`` dialect when the header line has ``;`` and no ``,``, an error
        when it has both, else ``comma``; choosing ``semicolon`` adds a note.
    joint_names : str, sequence of str or None
        Columns read as ``q1..q6``: None for ``q1..q6`` themselves, ``"ros-ur"`` for
        ``shoulder_pan_joint, shoulder_lift_joint, elbow_joint, wrist_1_joint,
        wrist_2_joint, wrist_3_joint`` (rad; ``_deg`` suffix allowed), or six names
        (a sequence or one comma-separated string).  See :func:`resolve_joint_names`.

    Returns
    -------
    Measurements
        SI units; :attr:`Measurements.notes` lists what was detected or mapped.

    Raises
    ------
    InputError
        Missing or duplicated columns, non-numeric, empty, NaN or infinite cells,
        implausible magnitudes (the message suggests the unit), duplicated rows,
        time running backwards, a separator other than the dialect's, an ambiguous
        header under ``auto``, a bad ``dialect`` or ``joint_names``.
    """
    from models.robot import read_text_file

    p = Path(path)
    _check_dialect(dialect)
    names = resolve_joint_names(joint_names)
    text = read_text_file(p, "measurement file (CSV)")
    return parse_measurements(text, str(p), require_position, require_wrench, dialect=dialect,
                              joint_names=names)


#: Separators a spreadsheet may have written instead of the dialect's (name for the message).
_OTHER_SEPARATORS = {",": "','", ";": "';'", "\t": "tab", "|": "'|'"}


def _check_dialect(dialect: str) -> None:
    if dialect not in DIALECT_CHOICES:
        raise InputError(f"CSV dialect {dialect!r}: expected one of {', '.join(DIALECT_CHOICES)}")


def _check_separator(where: str, header_line: int, header: list[str], dialect: str = "comma") -> None:
    """Refuse a header that is one cell holding another separator (``;`` from a spreadsheet
    with a decimal comma, tabs): the message names the separator and the way out."""
    if len(header) > 2:
        return
    sep_ok = DIALECTS[dialect][0]
    joined = sep_ok.join(header)
    for sep, name in _OTHER_SEPARATORS.items():
        if sep == sep_ok:
            continue
        if joined.count(sep) >= 2:
            shown = joined[:60].replace("\t", "\\t")
            if sep == ";":
                way = ("use ',' as the separator (and '.' as the decimal point), e.g. export as "
                       "'CSV (comma delimited)', or read the file as it is with --csv-dialect semicolon "
                       "(or auto)")
            elif sep == ",":
                way = "read it with --csv-dialect comma (or auto), or export it with ';' as the separator"
            else:
                way = (f"use '{sep_ok}' as the separator, e.g. export as 'CSV (comma delimited)'"
                       if sep_ok == "," else f"use '{sep_ok}' as the separator")
            raise InputError(f"{where}: line {header_line}: the header '{shown}' looks {name}-separated, but the "
                             f"file is read as the {dialect} dialect ('{sep_ok}'-separated); {way}")


def _header_text(lines: list[str]) -> tuple[int, str] | None:
    """(line number, text) of the first line that is neither empty nor a comment."""
    for i, ln in enumerate(lines, start=1):
        s = ln.strip()
        if not s or s.startswith("#") or s.startswith('"#'):
            continue
        return i, ln
    return None


def _detect_dialect(where: str, lines: list[str]) -> str:
    """``semicolon`` when the header line has ';' and no ',', an error when it has both, else ``comma``."""
    head = _header_text(lines)
    if head is None:
        return "comma"
    ln, text = head
    if ";" in text and "," in text:
        raise InputError(f"{where}: line {ln}: the header has both ',' and ';', so the separator cannot be told "
                         "apart; declare the dialect (--csv-dialect comma or --csv-dialect semicolon)")
    return "semicolon" if ";" in text else "comma"


def parse_measurements(text: str, where: str = "<text>", require_position: bool = True,
                       require_wrench: bool = True, *, dialect: str = "auto",
                       joint_names: str | Sequence[str] | None = None) -> Measurements:
    """Parse measurement-file text; see :func:`read_measurements` (same parameters;
    ``where`` names the text in messages and notes)."""
    _check_dialect(dialect)
    names = resolve_joint_names(joint_names)
    jmap = _joint_map(names)
    lines = text.splitlines()
    notes: list[str] = []
    detected = dialect == "auto"
    if detected:
        dialect = _detect_dialect(where, lines)
    sep, decimal_comma = DIALECTS[dialect]
    cells_parser = _Cells(where, decimal_comma)
    table: list[tuple[int, list[str]]] = []
    reader = csv.reader(io.StringIO("\n".join(lines)), delimiter=sep)
    for lineno, cells in enumerate(reader, start=1):
        if not cells or (len(cells) == 1 and cells[0].strip() == ""):
            continue
        if cells[0].lstrip().startswith("#"):
            continue
        table.append((lineno, [c.strip() for c in cells]))
    if not table:
        raise InputError(f"{where}: empty file; expected a header row and measurement rows")
    header_line, header = table[0]
    _check_separator(where, header_line, header, dialect)
    rows = table[1:]
    if not rows:
        raise InputError(f"{where}: no measurement rows after the header (line {header_line})")
    # map columns
    colmap: dict[str, tuple[int, str, float]] = {}
    ignored: list[str] = []
    unmapped_q: list[str] = []          # q1..q6 columns when joint_names names the joint columns
    for k, col in enumerate(header):
        if col == "":
            raise InputError(f"{where}: line {header_line}: column {k + 1} has an empty name")
        if any(col.startswith(pfx) for pfx in IGNORED_PREFIXES):
            ignored.append(col)
            continue
        base, factor = _split_unit(where, col, jmap)
        if jmap and base in Q_COLUMNS and not any(col.startswith(n) and col[len(n):] in _UNITS["angle"]
                                                  for n in jmap):
            unmapped_q.append(col)
            continue
        if base in colmap:
            other = colmap[base][1]
            raise InputError(f"{where}: column '{base}' is given twice ('{other}' and '{col}'); "
                             "keep exactly one (with its unit suffix)")
        colmap[base] = (k, col, factor)
    required = list(Q_COLUMNS) + (list(WRENCH_COLUMNS) if require_wrench else []) \
        + (list(POSITION_COLUMNS) if require_position else [])
    missing = [c for c in required if c not in colmap]
    if missing:
        qname = {q: n for n, q in jmap.items()}
        shown = ", ".join(qname.get(c, c) for c in missing)
        via = (f" (joint columns named by joint_names / --joint-names: {', '.join(names or ())})"
               if any(c in qname for c in missing) else "")
        also = (f"; the file has {', '.join(unmapped_q)}: to read those, leave the joint names at q1..q6"
                if unmapped_q else "")
        raise InputError(f"{where}: missing required column(s) {shown}{via} "
                         f"(header on line {header_line}: {', '.join(header)}){also}")
    if unmapped_q:
        raise InputError(f"{where}: column(s) {', '.join(unmapped_q)} besides the joint columns named by "
                         f"joint_names / --joint-names ({', '.join(colmap[q][1] for q in Q_COLUMNS)}); "
                         "keep one set of joint columns")
    for grp in (WRENCH_COLUMNS, POSITION_COLUMNS, ROTATION_COLUMNS, SIGMA_XYZ_COLUMNS, SIGMA_ROT_COLUMNS):
        have = [c for c in grp if c in colmap]
        if have and len(have) != len(grp):
            raise InputError(f"{where}: columns {', '.join(grp)} go together; found only "
                             f"{', '.join(colmap[c][1] for c in have)}")
    for single, per_axis, what in (("sigma", "sigma_x", "position"), ("sigma_r", "sigma_rx", "orientation")):
        if single in colmap and per_axis in colmap:
            grp = SIGMA_XYZ_COLUMNS if single == "sigma" else SIGMA_ROT_COLUMNS
            raise InputError(f"{where}: columns '{colmap[single][1]}' and '{colmap[per_axis][1]}' are both given; "
                             f"give either '{single}' (one {what} standard deviation for every axis) or "
                             f"{', '.join(grp)} (per axis), not both")
    rot_sigma = [colmap[c][1] for c in ("sigma_r", *SIGMA_ROT_COLUMNS) if c in colmap]
    if rot_sigma and "rx" not in colmap:
        raise InputError(f"{where}: column(s) {', '.join(rot_sigma)} (orientation standard deviation) need the "
                         "measured orientation rx, ry, rz, which the file does not have")
    ncol = len(header)
    for lineno, cells in rows:
        if len(cells) != ncol:
            hint = ""
            if not decimal_comma and len(cells) > ncol \
                    and any(c.isdigit() and c.lstrip("-").isdigit() for c in cells):
                hint = "; a decimal comma (0,40)? write numbers with '.' (0.40)"
            raise InputError(f"{where}: line {lineno}: {len(cells)} cells, expected {ncol} (as the header){hint}")

    def column(base: str) -> np.ndarray:
        k, col, factor = colmap[base]
        return np.array([cells_parser.number(ln, col, cells[k]) for ln, cells in rows]) * factor

    line = np.array([ln for ln, _c in rows], dtype=int)
    units = {col: factor for (_k, col, factor) in colmap.values()}
    q = np.column_stack([column(c) for c in Q_COLUMNS])
    wrench = (np.column_stack([column(c) for c in WRENCH_COLUMNS]) if "fx" in colmap
              else np.zeros((len(rows), 6)))
    pos = np.column_stack([column(c) for c in POSITION_COLUMNS]) if "x" in colmap else None
    rot = np.column_stack([column(c) for c in ROTATION_COLUMNS]) if "rx" in colmap else None
    t = t_origin = None
    if "t" in colmap:
        k, col, factor = colmap["t"]
        t, t_origin = _time_column(where, rows, k, col, factor, cells_parser)
    temp = column("temperature") if "temperature" in colmap else None
    sigma = column("sigma") if "sigma" in colmap else None
    sigma_xyz = (np.column_stack([column(c) for c in SIGMA_XYZ_COLUMNS]) if "sigma_x" in colmap
                 else None)
    if sigma_xyz is not None:
        sigma = sigma_rms(sigma_xyz)
    sigma_rot = None
    if "sigma_rx" in colmap:
        sigma_rot = np.column_stack([column(c) for c in SIGMA_ROT_COLUMNS])
    elif "sigma_r" in colmap:
        sigma_rot = np.repeat(column("sigma_r")[:, None], 3, axis=1)
    point = None
    if "point" in colmap:
        k = colmap["point"][0]
        point = np.array([cells[k] for _ln, cells in rows], dtype=object)
        for ln, cells in rows:
            if cells[k] == "":
                raise InputError(f"{where}: line {ln}, column 'point': empty cell; expected a pose id")
        point = point.astype(str)
    # what was decided without the user saying so
    if detected and dialect == "semicolon":
        extra = ""
        if cells_parser.n_point:
            extra = (f"; {cells_parser.n_point} cell(s) written with a decimal point (e.g. 1.5) were read with "
                     "'.' as the decimal point too")
        notes.append(f"{where}: read as ';'-separated with decimal commas (detected from the header line; "
                     f"declare --csv-dialect to fix it){extra}")
    elif decimal_comma and cells_parser.n_point and cells_parser.n_comma:
        notes.append(f"{where}: {cells_parser.n_comma} cell(s) have a decimal comma and {cells_parser.n_point} a "
                     "decimal point; both were read as the decimal separator")
    if t_origin is not None:
        zone = ("" if t_origin.tzinfo is not None
                else "; no time zone given: local clock times are taken as they are (a daylight-saving change "
                     "inside the file would shift them by 1 h)")
        notes.append(f"{where}: column 't' read as date-times: t = seconds since this file's first row "
                     f"(line {int(line[0])}, {t_origin.isoformat()}){zone}")
    if names is not None:
        preset = next((p for p, v in JOINT_NAME_PRESETS.items() if v == names), None)
        how = f"preset '{preset}'" if preset else "joint names given"
        mapping = ", ".join(f"{colmap[q][1]} = {q}" for q in Q_COLUMNS)
        notes.append(f"{where}: joint columns read as q1..q6 ({how}): {mapping}")
    m = Measurements(q=q, wrench=wrench, p=pos, t=t, point=point, rotation=rot, temperature=temp,
                     sigma=sigma, line=line, source=where, units=units, sigma_xyz=sigma_xyz, sigma_rot=sigma_rot,
                     notes=notes, columns={base: col for base, (_k, col, _f) in colmap.items()},
                     t_origin=t_origin)
    validate(m, colmap, _plain=frozenset(c for c in header if c in COLUMNS or c in jmap))
    return m


def _first_bad(values: np.ndarray, bad: np.ndarray) -> int:
    return int(np.argmax(bad))


def validate(m: Measurements, colmap: dict[str, tuple[int, str, float]] | None = None, *,
             _plain: frozenset[str] | None = None) -> None:
    """Check magnitudes and consistency of a table (raises :class:`InputError`).

    ``colmap`` (quantity -> (column index, column as written, SI factor)) lets the
    messages quote the file's column and unit."""
    where = m.source

    def colname(base: str) -> str:
        return colmap[base][1] if colmap and base in colmap else base

    def factor(base: str) -> float:
        return colmap[base][2] if colmap and base in colmap else 1.0

    def is_plain(name: str, base: str) -> bool:
        return name == base or (_plain is not None and name in _plain)

    def check(base: str, values: np.ndarray, limit: float, qty: str) -> None:
        bad = np.abs(values) > limit
        if bad.any():
            i = _first_bad(values, bad)
            hint = _UNIT_HINT.get(qty)
            name = colname(base)
            unit_msg = (f"; if the column is in other units, declare them by the suffix (e.g. '{name}{hint}')"
                        if hint and is_plain(name, base) else "")
            raise InputError(f"{where}: line {m.line[i]}, column '{name}': value {values[i] / factor(base):g} "
                             f"is implausible (|value| above {limit:g} in SI units){unit_msg}")

    def positive(base: str, values: np.ndarray, unit: str) -> None:
        bad = ~(values > 0)
        if bad.any():
            i = _first_bad(values, bad)
            name = colname(base)
            shown = f"{values[i] / factor(base):g}" + (f" {unit}" if is_plain(name, base) else "")
            raise InputError(f"{where}: line {m.line[i]}, column '{name}': value {shown}; "
                             "expected a standard deviation > 0")

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
    if colmap is not None:
        per_axis = "sigma_x" in colmap
    else:
        per_axis = m.sigma_xyz is not None and not (
            m.sigma is not None and np.array_equal(m.sigma_xyz, np.repeat(m.sigma[:, None], 3, axis=1)))
    if per_axis:
        assert m.sigma_xyz is not None
        for j, c in enumerate(SIGMA_XYZ_COLUMNS):
            positive(c, m.sigma_xyz[:, j], "m")
            check(c, m.sigma_xyz[:, j], PLAUSIBLE_SIGMA_MAX_M, "length")
    elif m.sigma is not None:
        positive("sigma", m.sigma, "m")
        check("sigma", m.sigma, PLAUSIBLE_SIGMA_MAX_M, "length")
    if m.sigma_rot is not None:
        if m.rotation is None:
            raise InputError(f"{where}: orientation standard deviations without the measured orientation "
                             "rx, ry, rz")
        single = colmap is not None and "sigma_r" in colmap
        for j, c in enumerate(SIGMA_ROT_COLUMNS):
            base = "sigma_r" if single else c
            positive(base, m.sigma_rot[:, j], "rad")
            check(base, m.sigma_rot[:, j], PLAUSIBLE_SIGMA_ROT_MAX_RAD, "small_angle")
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
    for extra in (m.p, m.rotation, m.sigma_xyz, m.sigma_rot):
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
    if m.sigma_xyz is not None and not (m.sigma is not None and np.array_equal(m.sigma_xyz, m.sigma[:, None]
                                                                               * np.ones((1, 3)))):
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


def commands_csv(header: Sequence[str], rows: np.ndarray) -> str:
    """CSV text of a numeric table (used by ``predict`` and ``compensate`` outputs)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(header))
    for row in np.asarray(rows, dtype=float):
        w.writerow([repr(float(v)) for v in row])
    return buf.getvalue()
