"""Cells of a measurement file: numbers in either dialect, date-times, the ``t`` column.

Each error names the file, the line, the column and the cell as written.
"""

from __future__ import annotations

import datetime as _dt
import math
import re

import numpy as np

from models.errors import InputError

#: A decimal number as written with '.' (after a decimal comma was turned into '.').
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
#: An ISO-8601-like date-time: date, 'T' or space, hh:mm[:ss[.fff]], optional zone.
_DATETIME = re.compile(
    r"(\d{4})-(\d{2})-(\d{2})[Tt ](\d{2}):(\d{2})(?::(\d{2})(?:[.,](\d+))?)?"
    r"\s*(Z|z|[+-]\d{2}(?::?\d{2})?)?"
)


class Cells:
    """Cell parser of one dialect; counts how decimals were written (for the notes)."""

    def __init__(self, where: str, decimal_comma: bool) -> None:
        self.where = where
        self.decimal_comma = decimal_comma
        self.n_comma = 0  # cells read with a decimal comma
        self.n_point = 0  # cells read with a decimal point (in the decimal-comma dialect)

    def expected(self) -> str:
        return (
            "a decimal number with a decimal comma (1,5 or -2e-3; no thousands separators)"
            if self.decimal_comma
            else "a decimal number (1.5 or -2e-3; no thousands separators)"
        )

    def number(self, line: int, col: str, text: str) -> float:
        """The finite number of a cell (raises naming the file, line, column, value)."""
        s = text.strip()
        where = f"{self.where}: line {line}, column '{col}'"
        if s == "":
            raise InputError(f"{where}: empty cell; expected a number")
        t = s
        if self.decimal_comma:
            if "," in s and "." in s:
                raise InputError(
                    f"{where}: '{s}' has both '.' and ',' (a thousands separator?); expected {self.expected()}"
                )
            if s.count(",") > 1:
                raise InputError(
                    f"{where}: '{s}' has more than one ',' (a thousands separator?); expected {self.expected()}"
                )
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
            raise InputError(
                f"{where}: value {s} is not finite; expected a finite number (remove or re-measure the row)"
            )
        hint = ""
        if not self.decimal_comma and re.fullmatch(r"[+-]?\d*,\d+", s):
            hint = " (a decimal comma, or a thousands separator? this file is read with '.' as the decimal point)"
        elif re.fullmatch(r"[+-]?\d{1,3}(?:[ '_.,\u00a0\u202f]\d{3})+(?:[.,]\d*)?", s):
            hint = " (a thousands separator?)"
        raise InputError(f"{where}: '{s}' is not a number{hint}; expected {self.expected()}")


def _parse_float(where: str, line: int, col: str, text: str) -> float:
    """A cell of the comma dialect as a finite float (kept for callers of the old helper)."""
    return Cells(where, False).number(line, col, text)


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
            tz = _dt.UTC
        else:
            sign = -1 if zone[0] == "-" else 1
            digits = zone[1:].replace(":", "")
            hh, mm = int(digits[:2]), int(digits[2:] or 0)
            if hh > 23 or mm > 59:
                raise InputError(
                    f"{where}: line {line}, column '{col}': '{text.strip()}' has the time-zone offset "
                    f"'{zone}'; expected +hh:mm within a day"
                )
            tz = _dt.timezone(sign * _dt.timedelta(hours=hh, minutes=mm))
    try:
        stamp = _dt.datetime(int(y), int(mo), int(d), int(h), int(mi), int(sec or 0), tzinfo=tz)
    except ValueError as exc:
        raise InputError(
            f"{where}: line {line}, column '{col}': '{text.strip()}' is not a valid date-time "
            f"({exc}); expected e.g. 2024-05-03T10:15:02.125"
        ) from None
    return stamp, (float("0." + frac) if frac else 0.0)


def time_column(
    where: str, rows: list[tuple[int, list[str]]], k: int, col: str, factor: float, cells: Cells
) -> tuple[np.ndarray, _dt.datetime | None]:
    """The ``t`` column: numbers (times in the column's unit) or date-times (seconds since
    the first row).  Returns (t in s, shape (N,); first date-time or None)."""
    parsed = [_parse_datetime(where, ln, col, c[k]) for ln, c in rows]
    if parsed[0] is None:
        for (ln, c), p in zip(rows, parsed):
            if p is not None:
                raise InputError(
                    f"{where}: line {ln}, column '{col}': '{c[k].strip()}' is a date-time but line "
                    f"{rows[0][0]} holds a number ('{rows[0][1][k].strip()}'); expected the whole "
                    "column as numbers or the whole column as date-times"
                )
        return np.array([cells.number(ln, col, c[k]) for ln, c in rows]) * factor, None
    if col != "t":
        ln, c = rows[0]
        raise InputError(
            f"{where}: line {ln}, column '{col}': '{c[k].strip()}' is a date-time; a unit suffix "
            f"declares numeric times; name the column 't' for date-times"
        )
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
            raise InputError(
                f"{where}: line {ln}, column '{col}': '{cell}' {what} but line {first_ln} holds a "
                f"date-time ('{first}'); expected the whole column as date-times"
            )
        stamp, frac = p
        if (stamp.tzinfo is not None) != aware0:
            raise InputError(
                f"{where}: line {ln}, column '{col}': '{c[k].strip()}' "
                f"{'has' if not aware0 else 'has no'} time zone but line {first_ln} ('{first}') "
                f"{'has none' if not aware0 else 'has one'}; expected every date-time with a zone "
                "or every one without"
            )
        t[i] = (stamp - stamp0).total_seconds() + (frac - frac0)
        if i and t[i] < t[i - 1]:
            prev_ln, prev = rows[i - 1][0], rows[i - 1][1][k].strip()
            raise InputError(
                f"{where}: line {ln}, column '{col}': time '{c[k].strip()}' is earlier than the "
                f"previous row (line {prev_ln}: '{prev}'); rows must be in measurement order"
            )
    origin = stamp0 + _dt.timedelta(seconds=frac0)
    return t, origin
