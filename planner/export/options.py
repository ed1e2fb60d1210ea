"""Export options: validators that name the option and its range (and expose the range, so the
tests can export over it), the network host of a streamed program, and the ``slow_down`` option of
the streamed formats."""

from __future__ import annotations

import ipaddress
import math
import re
from typing import Any
from collections.abc import Callable

from planner.export.errors import ExportError

__all__ = ["HOST_NAME_MAX", "SLOW_DOWN_CHOICES", "SLOW_DOWN_OPTION", "choice", "counted", "network_host", "ranged"]


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


#: Longest host name (RFC 1123: 255 octets on the wire, 253 characters written).
HOST_NAME_MAX = 253
#: One label of a host name (RFC 1123, 2.1): 1 to 63 letters, digits or hyphens, not starting or
#: ending with a hyphen.
_LABEL = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?")


def network_host(name: str) -> Callable[[Any], str]:
    """Validator: empty (not set), an IPv4 address (4 numbers 0-255), an IPv6 address, or a host
    name of RFC 1123 labels whose last label is not all digits (so ``999.1.1.1``, a mistyped
    address, is not taken for a name); the message names the option, the value and what is expected."""

    def check(v: Any) -> str:
        text = str(v).strip()
        if not text:
            return ""
        try:
            return str(ipaddress.ip_address(text))
        except ValueError:
            pass
        labels = text.rstrip(".").split(".")
        if all(lab.isdigit() for lab in labels):
            raise ExportError(
                f"export option {name} = {v!r}: not an IPv4 address; expected 4 numbers 0-255 separated by "
                "dots (e.g. 192.168.1.10), an IPv6 address or a host name"
            )
        if len(text) > HOST_NAME_MAX or not all(_LABEL.fullmatch(lab) for lab in labels) or labels[-1].isdigit():
            raise ExportError(
                f"export option {name} = {v!r}: expected an IPv4 address (4 numbers 0-255, e.g. 192.168.1.10), "
                f"an IPv6 address or a host name (labels of 1-63 letters, digits and '-', not starting or ending "
                f"with '-', separated by dots, at most {HOST_NAME_MAX} characters; RFC 1123)"
            )
        return text

    return check


#: The values of ``slow_down`` (:func:`planner.export.limits.check_motion`).
SLOW_DOWN_CHOICES = ("auto", "yes", "no")

#: The ``slow_down`` option of the streamed formats: ``auto`` slows the whole trajectory down
#: uniformly by the least factor that keeps what the controller runs within every limit, saying
#: so, except a program plan's (a CAM program at its programmed feed: slowing it changes the feed),
#: which it refuses; ``yes`` slows any plan down; ``no`` refuses such an export
#: (:func:`planner.export.limits.check_motion`).
SLOW_DOWN_OPTION: tuple[Any, str, Callable[[Any], str]] = (
    "auto",
    "auto: slow the trajectory down (saying so) when what the controller runs would exceed a limit, but refuse "
    "for a program plan (its programmed feed); yes: slow down, a program plan too; no: refuse",
    choice("slow_down", SLOW_DOWN_CHOICES),
)
