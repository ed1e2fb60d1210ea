"""The one kind of status enum: every result's outcome derives from :class:`Status`.

A status's ``.value`` is the string written to ``summary.json``, CSV files and reports (and
``str(status)`` / ``f"{status}"`` give it too); library code compares statuses as enum members
(``status is PlanStatus.UNREACHABLE``), never as strings.  ``ok`` is true for the member named
``OK``; ``usable`` (the result may be used, possibly with a caveat) is ``ok`` unless a subclass
widens it.

Statuses held per element in NumPy integer arrays (IK branches, placement grids) or computed in
CasADi expressions derive from :class:`CodedStatus`: each member is written ``NAME = "value", code``;
``member.code`` is the integer stored in such arrays and ``cls.from_code(c)`` maps it back to the
member.  Array code compares codes (``sol.status == IKStatus.OK.code``); what leaves the array is
the enum.
"""

from __future__ import annotations

import enum
from typing import Any

__all__ = ["CodedStatus", "Status"]


class Status(enum.Enum):
    """Base of every status enum (string values, compared as members)."""

    @property
    def ok(self) -> bool:
        """True for the member named ``OK`` (a full success)."""
        return self.name == "OK"

    @property
    def usable(self) -> bool:
        """True if the result may be used (``ok`` unless a subclass widens it)."""
        return self.ok

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)


class CodedStatus(Status):
    """A :class:`Status` also stored as an integer code in arrays.

    Members are declared as ``NAME = "value", code``; the value is the string, the code the
    integer of the arrays (unique within the enum).
    """

    _code: int

    def __new__(cls, value: str, code: int) -> Any:
        obj = object.__new__(cls)
        obj._value_ = value
        obj._code = int(code)
        return obj

    @property
    def code(self) -> int:
        """The integer stored for this status in arrays and CasADi expressions."""
        return self._code

    @classmethod
    def from_code(cls, code: Any) -> Any:
        """The member whose :attr:`code` is ``code`` (an int or a NumPy integer/float scalar).

        Raises
        ------
        ValueError
            If no member has that code (a programming error: arrays hold only members' codes).
        """
        c = int(code)
        for member in cls:
            if member._code == c:
                return member
        # Not user input: the arrays are filled with members' codes only.
        raise ValueError(f"{cls.__name__}: no status with code {c}; codes are {sorted(m._code for m in cls)}")
