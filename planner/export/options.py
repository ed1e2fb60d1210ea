"""Export options: validators that name the option and its range (and expose the range, so the
tests can export over it), and the ``slow_down`` option of the streamed formats."""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Callable

from planner.export.errors import ExportError

__all__ = ["SLOW_DOWN_OPTION", "choice", "counted", "ranged"]


def ranged(name: str, lo: float, hi: float) -> Callable[[Any], float]:
    """Validator: a number in [lo, hi], the message naming the option and the range."""

    def check(v: Any) -> float:
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ExportError(f"export option {name} = {v!r}: expected a number in [{lo:g}, {hi:g}]") from None
        if not (math.isfinite(x) and lo <= x <= hi):
            raise ExportError(f"export option {name} = {x:g}: expected a number in [{lo:g}, {hi:g}]")
        return x

    check.bounds = (lo, hi)  # type: ignore[attr-defined]  # the allowed range, for the tests
    return check


def counted(name: str, lo: int, hi: int) -> Callable[[Any], int]:
    """Validator: a whole number in [lo, hi], the message naming the option and the range."""

    def check(v: Any) -> int:
        x = ranged(name, lo, hi)(v)
        if x != int(x):
            raise ExportError(f"export option {name} = {x:g}: expected a whole number in [{lo}, {hi}]")
        return int(x)

    check.bounds = (lo, hi)  # type: ignore[attr-defined]
    check.whole = True  # type: ignore[attr-defined]
    return check


def choice(name: str, values: tuple[str, ...]) -> Callable[[Any], str]:
    """Validator: one of ``values`` (words), the message naming the option and the choices."""

    def check(v: Any) -> str:
        if str(v) not in values:
            raise ExportError(f"export option {name} = {v!r}: expected one of {', '.join(values)}")
        return str(v)

    check.choices = values  # type: ignore[attr-defined]  # the allowed values, for the tests
    return check


#: The ``slow_down`` option of the streamed formats: ``auto`` slows the whole trajectory down
#: uniformly by the least factor that keeps what the controller runs within every limit, saying
#: so; ``no`` refuses such an export (:func:`planner.export.limits.check_motion`).
SLOW_DOWN_OPTION: tuple[Any, str, Callable[[Any], str]] = (
    "auto",
    "auto: slow the trajectory down (saying so) when what the controller runs would exceed a limit; no: refuse",
    choice("slow_down", ("auto", "no")),
)
