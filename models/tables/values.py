"""The value kinds of the input files (robot, URDF-based robot, problem, simulation, placement grid):
one reader, each format raising its own error class.

Every input format reads its tables through a :class:`TableReader` bound to the format's
:class:`~models.errors.InputError` subclass (``RobotFileError``, ``ProblemFileError``,
``SimConfigError``, ``PlacementGridError``), so callers and tests keep catching the error they
know, and every message reads the same: ``"<where>: key '<key>' <what was expected>, got <value>"``,
``where`` naming the file (and table), ``key`` the key path (dotted, ``path.points``; an item
``[i]``; a row ``[i][j]``).

The kinds: a number (finite), a positive number, a number at least a bound, an integer in a
range, true or false, a string (non-empty), a vector of ``n`` numbers (or one number for all),
rows of ``width`` numbers, a number written as text (a CSV cell), a table's unknown keys.  The
declarative kinds of a whole document (a tree of specs with units, ranges and the commands that
need a key: ``summary.json``) are :mod:`models.tables.kinds`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from models.errors import InputError

__all__ = ["TableReader", "is_number"]


def is_number(v: Any) -> bool:
    """An int or float, not a bool (TOML and JSON numbers)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


@dataclass(frozen=True)
class TableReader:
    """The value kinds, raising ``error`` with the key path in the message.

    Attributes
    ----------
    error : type of InputError
        The format's error class.
    lists : tuple of type
        What a list may be (TOML gives ``list``; a dictionary built in Python may hold tuples).
    not_number, not_finite : str
        The words after ``key '<key>'`` for a value that is no number / not finite
        (``{v!r}``: the value); a format may say both at once ("must be a finite number").
    """

    error: type[InputError]
    lists: tuple[type, ...] = (list,)
    not_number: str = "must be a number, got {v!r}"
    not_finite: str = "must be finite, got {v!r}"

    def fail(self, where: str, key: str, msg: str) -> InputError:
        """The error ``"<where>: key '<key>' <msg>"`` (to raise)."""
        return self.error(f"{where}: key '{key}' {msg}")

    def unknown_keys(self, where: str, table: Mapping[str, Any], allowed: Iterable[str]) -> None:
        """Refuse keys of ``table`` not in ``allowed`` (the message lists ``allowed`` in its order)."""
        allowed = list(allowed)
        unknown = sorted(set(table) - set(allowed))
        if unknown:
            raise self.error(f"{where}: unknown key(s) {unknown}; allowed: {allowed}")

    def number(self, where: str, key: str, v: Any) -> float:
        """A finite number (int or float, not a bool), as float."""
        if not is_number(v):
            raise self.fail(where, key, self.not_number.format(v=v))
        f = float(v)
        if not math.isfinite(f):
            raise self.fail(where, key, self.not_finite.format(v=v))
        return f

    def positive(self, where: str, key: str, v: Any, show: Callable[[Any], str] = repr) -> float:
        """A finite number > 0; ``show`` writes the refused value (default ``repr`` of the value given)."""
        f = self.number(where, key, v)
        if f <= 0.0:
            raise self.fail(where, key, f"must be > 0, got {show(v)}")
        return f

    def at_least(
        self, where: str, key: str, v: float | np.ndarray, lo: float, strict: bool = False, what: str = ""
    ) -> None:
        """Refuse numbers below ``lo`` (or equal to it when ``strict``); an array names its first
        bad item (``key[i]``); ``what`` follows the bound (a unit, what it is)."""
        arr = np.atleast_1d(np.asarray(v, dtype=float))
        bad = np.flatnonzero(arr <= lo) if strict else np.flatnonzero(arr < lo)
        if bad.size:
            i = int(bad[0])
            k = key if arr.size == 1 and np.ndim(v) == 0 else f"{key}[{i}]"
            raise self.fail(
                where, k, f"must be {'>' if strict else '>='} {lo:g}{' ' + what if what else ''}, got {float(arr[i]):g}"
            )

    def integer(self, where: str, key: str, v: Any, lo: int, hi: int | None = None) -> int:
        """An integer in ``[lo, hi]`` (``hi`` None: ``>= lo``); a float such as 20.0 or a bool is refused."""
        if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
            rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
            raise self.fail(where, key, f"must be an integer {rng}, got {v!r}")
        return int(v)

    def flag(self, where: str, key: str, v: Any) -> bool:
        """true or false."""
        if not isinstance(v, bool):
            raise self.fail(where, key, f"must be true or false, got {v!r}")
        return v

    def text(self, where: str, key: str, v: Any, empty: bool = True) -> str:
        """A string (non-empty unless ``empty``)."""
        if not isinstance(v, str) or (not empty and not v):
            raise self.fail(where, key, f"must be a {'' if empty else 'non-empty '}string, got {v!r}")
        return v

    def vector(self, where: str, key: str, v: Any, n: int, scalar: bool = False) -> np.ndarray:
        """A list of ``n`` finite numbers, shape (n,); ``scalar``: one number stands for all ``n``."""
        if scalar and is_number(v):
            return np.full(n, self.number(where, key, v))
        if not isinstance(v, self.lists) or len(v) != n:
            raise self.fail(where, key, f"must be {'a number or ' if scalar else ''}a list of {n} numbers, got {v!r}")
        return np.array([self.number(where, f"{key}[{i}]", x) for i, x in enumerate(v)])

    def text_number(self, where: str, text: str, pattern: re.Pattern[str]) -> float:
        """A number written as text (a CSV cell), stripped, of the form ``pattern`` and finite;
        ``where`` names the place (``"<file>: line 3, column 'x_mm'"``)."""
        s = text.strip()
        if not pattern.fullmatch(s):
            raise self.error(f"{where}: '{s}' is not a number (expected e.g. 12.5 or -3e-2)")
        v = float(s)
        if not math.isfinite(v):
            raise self.error(f"{where}: '{s}' is not finite")
        return v

    def rows(self, where: str, key: str, v: Any, width: int) -> np.ndarray:
        """A non-empty list of rows of ``width`` finite numbers, shape (N, width)."""
        if not isinstance(v, self.lists) or not v:
            raise self.fail(where, key, f"must be a non-empty list of rows of {width} numbers, got {v!r}")
        out = np.empty((len(v), width))
        for i, row in enumerate(v):
            if not isinstance(row, self.lists) or len(row) != width:
                raise self.error(f"{where}: key '{key}' row {i}: must be a list of {width} numbers, got {row!r}")
            for j, x in enumerate(row):
                out[i, j] = self.number(where, f"{key}[{i}][{j}]", x)
        return out
