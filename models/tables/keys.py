"""Tables declared key by key: each key's name, how its value is read and checked, its default and its
unit, in one declaration from which a format's allowed keys and its reader both follow.

A format declares a table as a :class:`KeyTable` of :class:`Key` entries whose ``read`` is one of its
:class:`~models.tables.values.TableReader`'s kinds (so the format's error class and the key path in
the message come with it)::

    SOLVER = KeyTable("solver", (
        Key("max_iter", lambda w, k, v: VALUES.integer(w, k, v, 0), default=3000),
        Key("tol", VALUES.positive, default=1e-8),
    ))
    TABLE_KEYS["solver"] = SOLVER.names          # the unknown-key check
    settings = SolverSettings(**SOLVER.read(where, tab))

A new key of such a table is one :class:`Key` (and the field that receives it).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["ABSENT", "Key", "KeyTable"]


class _Absent:
    """The default of a key without one: absent from the table, it is not read (``None`` results),
    unless the key is ``required``."""

    def __repr__(self) -> str:
        return "ABSENT"


#: A key's default when an absent key stays absent (its value is ``None``).
ABSENT: Any = _Absent()


@dataclass(frozen=True)
class Key:
    """One key of an input table.

    Attributes
    ----------
    name : str
        The key as written in the file.
    read : callable
        ``read(where, key_path, value) -> value``: the value read and checked (SI), raising the
        format's error naming ``where`` and ``key_path`` (``"<table>.<name>"``).
    default : Any
        The value read when the key is absent (it goes through ``read`` too); :data:`ABSENT`: the result
        is ``None``.
    required : callable or None
        ``required(where, key_path)`` returns the error to raise when the key is absent (then ``default``
        is not used).
    unit : str
        The value's unit in the file, for documentation (``"kg"``, ``"m"``; ``""``: none).
    """

    name: str
    read: Callable[[str, str, Any], Any]
    default: Any = ABSENT
    required: Callable[[str, str], Exception] | None = None
    unit: str = ""


@dataclass(frozen=True)
class KeyTable:
    """A table declared key by key (:class:`Key`), in the order its keys are listed and read."""

    name: str
    keys: tuple[Key, ...]

    @property
    def names(self) -> tuple[str, ...]:
        """The keys the table may hold, in declaration order (the unknown-key message lists them)."""
        return tuple(k.name for k in self.keys)

    def read(self, where: str, table: Mapping[str, Any]) -> dict[str, Any]:
        """Every key's value, read and checked in declaration order.

        Parameters
        ----------
        where : str
            The file (and what the format puts before the key in its messages).
        table : mapping
            The table as parsed (its unknown keys already refused by the format).

        Returns
        -------
        dict
            Key name -> value (``None`` for an absent key whose default is :data:`ABSENT`).
        """
        out: dict[str, Any] = {}
        for k in self.keys:
            path = f"{self.name}.{k.name}"
            if k.name in table:
                out[k.name] = k.read(where, path, table[k.name])
            elif k.required is not None:
                raise k.required(where, path)
            elif k.default is ABSENT:
                out[k.name] = None
            else:
                out[k.name] = k.read(where, path, k.default)
        return out
