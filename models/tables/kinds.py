"""The declarative kinds of value a document (``summary.json``, a JSON or TOML table) may hold at a
key, and their checks.

A document's shape is declared once as a tree of specs (:mod:`planner.summary_schema` declares
``summary.json``'s; the value readers of the input files are :mod:`models.tables.values`): a
:class:`Table` of named keys, a :class:`MapOf` of entries under any name (``timing.<method>``), a
:class:`ListOf` items, a :class:`Vector` of n numbers, a :class:`Row` of fixed positions, a
:class:`Number` with its range and unit, a :class:`Text` (free, from a set, a file name, a pattern,
the name of another table's entry), a :class:`Flag`, :class:`Either` of two shapes, and
:class:`External` (a block checked by its own reader, e.g. a robot file). Keys a table does not
declare are allowed and not checked. A key is optional unless a command ``need``s it.

:func:`check` walks a value against its spec and raises :class:`Refused` at the first key that
does not fit: its path (``timing.ruckig.file``, ``provenance.inputs[0].sha256``), the value and
what was expected; the caller words the message (file, command). The same tree gives the tests
their cases: :func:`templates` lists every declared key, :meth:`Spec.bad_values` the values each
refuses, :meth:`Spec.example` a value each accepts.  The module is silent and imports nothing of
the project (the lowest layer).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "MAGNITUDE_MAX",
    "SHOWN_CHARS",
    "Ctx",
    "Either",
    "External",
    "Flag",
    "ListOf",
    "MapOf",
    "Number",
    "Refused",
    "Row",
    "Spec",
    "Table",
    "Text",
    "Vector",
    "check",
    "dotted",
    "shown",
    "template_text",
    "templates",
]

#: Characters of a refused value shown in a message (the rest is cut: "...").
SHOWN_CHARS = 60
#: Largest magnitude of a number anywhere in a run's files (SI): no quantity of a run comes near it
#: (joint stiffness ~1e7 N*m/rad, jerk limits ~1e4 rad/s^3, a long program ~1e5 s), and its square
#: and sums stay far from overflow (a tampered 1e300 squared is infinite).
MAGNITUDE_MAX = 1e12

#: A path into a document: table keys (str) and list indices (int).
KeyPath = tuple[Any, ...]


def dotted(path: Iterable[Any]) -> str:
    """``("timing", "ruckig", "file")`` -> ``timing.ruckig.file``; a list index as ``[0]``."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


def shown(value: Any) -> str:
    """A value as JSON text (NaN and Infinity as such), cut to :data:`SHOWN_CHARS`."""
    try:
        text = json.dumps(value, allow_nan=True, ensure_ascii=False)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= SHOWN_CHARS else text[: SHOWN_CHARS - 3] + "..."


class Refused(Exception):
    """A value that does not fit its spec: ``path``, ``value``, ``expected`` (what fits);
    ``missing`` when the key is absent; ``detail``: an external reader's own message."""

    def __init__(self, path: KeyPath, value: Any, expected: str, *, missing: bool = False, detail: str = "") -> None:
        super().__init__(detail or f"{dotted(path)}: {expected}")
        self.path, self.value, self.expected, self.missing, self.detail = tuple(path), value, expected, missing, detail


@dataclass(frozen=True, kw_only=True)
class Ctx:
    """What a check needs besides the value: the command reading (its ``need``s apply) and the
    whole document (for :class:`Text` ``key_of``)."""

    command: str
    root: Mapping[str, Any]


@dataclass(frozen=True, kw_only=True)
class Spec:
    """One declared kind of value.

    ``nullable``: JSON null is accepted (what was not computed; non-finite numbers are written as
    null). ``need``: the commands that refuse the document when the key is absent or null.
    """

    nullable: bool = False
    need: frozenset[str] = frozenset()

    def expected(self) -> str:
        """What fits, in words ("a number >= 0 (s)")."""
        raise NotImplementedError

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        """Raise :class:`Refused` unless ``value`` (not None) fits."""
        raise NotImplementedError

    def bad_values(self) -> list[Any]:
        """Values this key refuses (for the tests; nested keys have their own)."""
        return [] if self.nullable else [None]

    def example(self) -> Any:
        """A value this key accepts."""
        raise NotImplementedError

    def children(self) -> Iterator[tuple[Any, Spec]]:
        """The declared keys below (``(step, spec)``; :func:`templates`)."""
        return iter(())

    def refuse(self, path: KeyPath, value: Any) -> Refused:
        """The refusal of ``value`` at ``path`` (what fits: :meth:`expected`)."""
        return Refused(path, value, self.expected())


def check(spec: Spec, value: Any, path: KeyPath, ctx: Ctx) -> None:
    """Check ``value`` at ``path`` against ``spec`` (null: against ``nullable`` and ``need``)."""
    if value is None:
        if spec.nullable and ctx.command not in spec.need:
            return
        raise Refused(path, value, spec.expected() + (f" ({ctx.command} needs it)" if spec.nullable else ""))
    spec.check_value(value, path, ctx)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _num(x: float) -> str:
    return f"{x:g}"


@dataclass(frozen=True, kw_only=True)
class Number(Spec):
    """A finite number (JSON int or float, not a bool) in a range, in ``unit``; ``integer``: a
    whole number (an integral float such as 3.0 too)."""

    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    integer: bool = False

    def expected(self) -> str:
        kind = "a whole number" if self.integer else "a finite number"
        if self.lo is not None and self.hi is not None:
            rng = f" in {'(' if self.lo_open else '['}{_num(self.lo)}, {_num(self.hi)}]"
        elif self.lo is not None:
            rng = f" {'>' if self.lo_open else '>='} {_num(self.lo)}"
        elif self.hi is not None:
            rng = f" <= {_num(self.hi)}"
        else:
            rng = ""
        return kind + rng + (f" ({self.unit})" if self.unit else "")

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not _is_number(value) or not math.isfinite(value):
            raise self.refuse(path, value)
        if abs(value) > MAGNITUDE_MAX:
            raise Refused(path, value, f"{self.expected()}, at most {MAGNITUDE_MAX:g} in magnitude")
        if self.integer and float(value) != int(value):
            raise self.refuse(path, value)
        if self.lo is not None and (value <= self.lo if self.lo_open else value < self.lo):
            raise self.refuse(path, value)
        if self.hi is not None and value > self.hi:
            raise self.refuse(path, value)

    def bad_values(self) -> list[Any]:
        bad: list[Any] = ["lots", [1.0], {"value": 1.0}, True, math.nan, math.inf, -math.inf, 1e300]
        if self.lo is not None:
            bad.append(self.lo if self.lo_open else self.lo - 1.0)
        if self.hi is not None:
            bad.append(self.hi + 1.0)
        if self.integer:
            bad.append(self.example() + 0.5)
        return super().bad_values() + bad

    def example(self) -> Any:
        v = 1.0 if self.lo is None else self.lo + (1.0 if self.lo_open else 0.0)
        v = v if self.hi is None else min(v, self.hi)
        return int(v) if self.integer else v


@dataclass(frozen=True, kw_only=True)
class Text(Spec):
    """A string: any, one of ``choices`` (a tuple, or a function giving them: an enum's values), a
    plain ``file_name`` (no folder part), one matching ``pattern`` (said as ``pattern_text``), or
    the name of an entry of the table at ``key_of`` (a top-level key)."""

    choices: tuple[str, ...] | Callable[[], Iterable[str]] | None = None
    file_name: bool = False
    pattern: str = ""
    pattern_text: str = ""
    key_of: str = ""
    #: A value it accepts, where the others do not give one (a ``pattern``'s).
    sample: str = ""

    def options(self) -> tuple[str, ...] | None:
        if self.choices is None:
            return None
        return tuple(self.choices() if callable(self.choices) else self.choices)

    def expected(self) -> str:
        opts = self.options()
        if opts is not None:
            return "one of " + ", ".join(repr(o) for o in opts)
        if self.file_name:
            return "the name of a file in the run folder (no folder part)"
        if self.pattern:
            return self.pattern_text or f"a string matching {self.pattern}"
        if self.key_of:
            return f"the name of an entry of {self.key_of}"
        return "a string"

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, str):
            raise self.refuse(path, value)
        opts = self.options()
        if opts is not None and value not in opts:
            raise self.refuse(path, value)
        if self.file_name and (not value or value in (".", "..") or "/" in value or "\\" in value):
            raise self.refuse(path, value)
        if self.pattern and not re.fullmatch(self.pattern, value):
            raise self.refuse(path, value)
        if self.key_of:
            table = ctx.root.get(self.key_of)
            if isinstance(table, Mapping) and value not in table:
                raise Refused(path, value, f"{self.expected()} ({', '.join(repr(k) for k in table) or 'it is empty'})")

    def bad_values(self) -> list[Any]:
        bad: list[Any] = [5, ["x"], {"x": "y"}]
        if self.choices is not None or self.pattern or self.key_of:
            bad.append("lots")
        if self.file_name:
            bad += ["../summary.json", "sub/x.csv", ""]
        return super().bad_values() + bad

    def example(self) -> Any:
        opts = self.options()
        if opts:
            return opts[0]
        return self.sample or ("x.csv" if self.file_name else "x")


@dataclass(frozen=True, kw_only=True)
class Flag(Spec):
    """true or false."""

    def expected(self) -> str:
        return "true or false"

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, bool):
            raise self.refuse(path, value)

    def bad_values(self) -> list[Any]:
        return super().bad_values() + ["lots", 2, [True]]

    def example(self) -> Any:
        return False


@dataclass(frozen=True, kw_only=True)
class Vector(Spec):
    """A list of exactly ``n`` values of ``item`` (a :class:`Number`; null items if it is nullable)."""

    n: int = 6
    item: Number = field(default_factory=Number)

    def expected(self) -> str:
        return f"a list of {self.n} numbers, each {self.item.expected()}" + (" or null" if self.item.nullable else "")

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, list) or len(value) != self.n:
            raise self.refuse(path, value)
        for i, v in enumerate(value):
            if v is None and self.item.nullable:
                continue
            check(self.item, v, (*path, i), ctx)

    def bad_values(self) -> list[Any]:
        ok = self.item.example()
        bad: list[Any] = ["lots", ok, [ok] * (self.n + 1), {"x": ok}]
        bad += [[b] + [ok] * (self.n - 1) for b in self.item.bad_values() if b is not None or not self.item.nullable]
        return super().bad_values() + bad

    def example(self) -> Any:
        return [self.item.example()] * self.n


@dataclass(frozen=True, kw_only=True)
class ListOf(Spec):
    """A list of any length of ``item`` values."""

    item: Spec = field(default_factory=Text)

    def expected(self) -> str:
        return f"a list, each item {self.item.expected()}"

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, list):
            raise self.refuse(path, value)
        for i, v in enumerate(value):
            check(self.item, v, (*path, i), ctx)

    def children(self) -> Iterator[tuple[Any, Spec]]:
        if isinstance(self.item, (Table, MapOf, ListOf, Row, Either)):
            yield 0, self.item

    def bad_values(self) -> list[Any]:
        bad: list[Any] = ["lots", {"x": 1}]
        if not any(True for _ in self.children()):  # a list of plain values: a bad item here
            bad += [[b] for b in self.item.bad_values()]
        return super().bad_values() + bad

    def example(self) -> Any:
        return []


@dataclass(frozen=True, kw_only=True)
class Row(Spec):
    """A list of fixed length whose positions hold ``items`` (e.g. ``[program line, fraction]``)."""

    items: tuple[Spec, ...] = ()

    def expected(self) -> str:
        return "a list [" + ", ".join(s.expected() for s in self.items) + "]"

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, list) or len(value) != len(self.items):
            raise self.refuse(path, value)
        for i, (s, v) in enumerate(zip(self.items, value)):
            check(s, v, (*path, i), ctx)

    def bad_values(self) -> list[Any]:
        ok = self.example()
        bad: list[Any] = ["lots", ok[:-1], {"x": 1}]
        for i, s in enumerate(self.items):
            bad += [ok[:i] + [b] + ok[i + 1 :] for b in s.bad_values()]
        return super().bad_values() + bad

    def example(self) -> Any:
        return [s.example() for s in self.items]


@dataclass(frozen=True, kw_only=True)
class Table(Spec):
    """A JSON object whose ``fields`` are declared (other keys are allowed, not checked);
    ``rules``: checks across its keys, ``rule(table, path, ctx)`` raising :class:`Refused`."""

    fields: Mapping[str, Spec] = field(default_factory=dict)
    rules: tuple[Callable[[Mapping[str, Any], KeyPath, Ctx], None], ...] = ()

    def expected(self) -> str:
        return "a table (JSON object)"

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, Mapping):
            raise self.refuse(path, value)
        for key, spec in self.fields.items():
            if key in value:
                check(spec, value[key], (*path, key), ctx)
            elif ctx.command in spec.need:
                raise Refused((*path, key), None, f"{spec.expected()} ({ctx.command} needs it)", missing=True)
        for rule in self.rules:
            rule(value, path, ctx)

    def children(self) -> Iterator[tuple[Any, Spec]]:
        yield from self.fields.items()

    def bad_values(self) -> list[Any]:
        return super().bad_values() + ["lots", [1.0]]

    def example(self) -> Any:
        return {k: s.example() for k, s in self.fields.items()}


@dataclass(frozen=True, kw_only=True)
class MapOf(Spec):
    """A JSON object of entries under any name (a method, a branch label), each ``item``;
    ``name`` says what the names are (``timing.<method>``)."""

    item: Spec = field(default_factory=Text)
    name: str = "name"

    def expected(self) -> str:
        return f"a table of {self.name} -> {self.item.expected()}"

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, Mapping):
            raise self.refuse(path, value)
        for key, v in value.items():
            check(self.item, v, (*path, key), ctx)

    def children(self) -> Iterator[tuple[Any, Spec]]:
        yield f"<{self.name}>", self.item

    def bad_values(self) -> list[Any]:
        bad: list[Any] = ["lots", [1.0]]
        if not isinstance(self.item, (Table, MapOf, ListOf, Row, Either)):  # plain entries: one bad here
            bad += [{"x": b} for b in self.item.bad_values()]
        return super().bad_values() + bad

    def example(self) -> Any:
        return {}


@dataclass(frozen=True, kw_only=True)
class Either(Spec):
    """One of two shapes (a summary written before a key changed shape), chosen by
    ``pick(value)`` -> 0 or 1 (the test of the later shape's keys)."""

    first: Spec = field(default_factory=Text)
    second: Spec = field(default_factory=Text)
    pick: Callable[[Any], int] = lambda v: 0

    def expected(self) -> str:
        return f"{self.first.expected()}, or {self.second.expected()}"

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        try:
            check((self.first, self.second)[self.pick(value)], value, path, ctx)
        except Refused as exc:
            if exc.path == tuple(path):  # the shape itself does not fit: say both
                raise self.refuse(path, value) from None
            raise

    def children(self) -> Iterator[tuple[Any, Spec]]:
        yield "#0", self.first
        yield "#1", self.second

    def bad_values(self) -> list[Any]:
        return super().bad_values() + ["lots", [1.0]]

    def example(self) -> Any:
        return self.first.example()


@dataclass(frozen=True, kw_only=True)
class External(Spec):
    """A block with its own reader (a robot file): ``reader(value, where)`` raises an exception
    of ``errors`` whose message names the key inside; ``what`` says what the block is."""

    reader: Callable[[Any, str], Any] = lambda v, where: v
    what: str = "a table"
    errors: tuple[type[Exception], ...] = (ValueError,)

    def expected(self) -> str:
        return self.what

    def check_value(self, value: Any, path: KeyPath, ctx: Ctx) -> None:
        if not isinstance(value, Mapping):
            raise self.refuse(path, value)
        try:
            self.reader(value, dotted(path))
        except self.errors as exc:
            raise Refused(path, value, self.expected(), detail=str(exc)) from None

    def bad_values(self) -> list[Any]:
        return super().bad_values() + ["lots", [1.0], {}]


def templates(spec: Spec, prefix: KeyPath = ()) -> Iterator[tuple[KeyPath, Spec]]:
    """Every declared key below ``spec``: ``(steps, spec)``; a step is a table key, ``0`` (an item
    of a list), ``"<name>"`` (any entry of a :class:`MapOf`) or ``"#0"``/``"#1"`` (a shape of an
    :class:`Either`)."""
    for step, sub in spec.children():
        here = (*prefix, step)
        if not (isinstance(step, str) and step.startswith("#")):
            yield here, sub
        yield from templates(sub, here)


def template_text(steps: KeyPath) -> str:
    """The dotted form of a template (``timing.<method>.file``, ``provenance.inputs[0].sha256``)."""
    return dotted(s for s in steps if not (isinstance(s, str) and s.startswith("#")))
