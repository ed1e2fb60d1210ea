"""How numbers are shown: significant digits and the numerical floor.

The summaries keep every number at full precision; the *headline* of a summary
and every display (report tables, figure titles) round a number to what it
means: :data:`DISPLAY_DIGITS` significant digits, and a TCP error below the
numerical floor :data:`NUMERICAL_FLOOR_MM` is "0 (numerical)" rather than a
rounding residue such as ``5.55e-14 mm``.  The floor is the contract of exact
compensation (:data:`models.constants.EXACT_COMPENSATION_TOL`, 1e-9 m): a
residual below it is the accuracy of the equilibrium solve, not an error of the
arm.  The module is pure (no printing, no I/O).
"""

from __future__ import annotations

import math
from typing import Any

from models.constants import EXACT_COMPENSATION_TOL

#: Significant digits of a displayed (and of a headline) number.
DISPLAY_DIGITS = 4
#: TCP position errors below this (mm) are numerically zero: the exact-compensation
#: contract (1e-9 m = 1e-6 mm), the accuracy the deflected equilibrium is solved to.
NUMERICAL_FLOOR_MM = float(f"{EXACT_COMPENSATION_TOL * 1e3:.12g}")
#: The same floor in metres (for keys in SI, e.g. ``exact_residual_max_m``).
NUMERICAL_FLOOR_M = EXACT_COMPENSATION_TOL
#: Joint angles (rad) below this are numerically zero (double rounding of angles of order 1 rad).
NUMERICAL_FLOOR_RAD = 1e-12
#: What a value below the numerical floor is shown as.
NUMERICAL_ZERO_TEXT = "0 (numerical)"


def round_sig(x: float, digits: int = DISPLAY_DIGITS) -> float:
    """``x`` rounded to ``digits`` significant digits (non-finite and zero unchanged).

    Examples
    --------
    >>> round_sig(1.779017464983031)
    1.779
    >>> round_sig(0.025092427957477882)
    0.02509
    """
    x = float(x)
    if x == 0.0 or not math.isfinite(x):
        return x
    return round(x, digits - 1 - int(math.floor(math.log10(abs(x)))))


def below_floor(value_mm: float, floor_mm: float = NUMERICAL_FLOOR_MM) -> bool:
    """True when a length in mm is numerically zero (below the floor in magnitude)."""
    return math.isfinite(value_mm) and abs(value_mm) < floor_mm


def headline_mm(value_mm: float | None) -> float | None:
    """A length in mm for a headline: 0.0 below the numerical floor, else 4 significant digits."""
    if value_mm is None or not math.isfinite(float(value_mm)):
        return None
    return 0.0 if below_floor(float(value_mm)) else round_sig(float(value_mm))


def format_number(v: float, digits: int = DISPLAY_DIGITS) -> str:
    """Display text of a float: ``digits`` significant digits, no trailing zeros (``%g``)."""
    if not math.isfinite(v):
        return "n/a"
    text = f"{v:.{digits}g}"
    if "e" in text:  # 1e-06 -> 1e-6, 6.8e+05 -> 6.8e5
        mant, exp = text.split("e")
        text = f"{mant}e{int(exp)}"
    return text


def format_mm(value_mm: float, digits: int = DISPLAY_DIGITS) -> str:
    """Display text of a length in mm: "0 (numerical)" below the floor, else significant digits."""
    if below_floor(value_mm):
        return NUMERICAL_ZERO_TEXT
    return format_number(value_mm, digits)


def mm_text(value_mm: float, digits: int = DISPLAY_DIGITS) -> str:
    """A length in mm with its unit (``"1.779 mm"``), or ``"0 (numerical)"`` below the floor."""
    text = format_mm(value_mm, digits)
    return text if text == NUMERICAL_ZERO_TEXT else f"{text} mm"


def error_key_mm(key: str) -> float | None:
    """Millimetres per unit of the TCP error length a dotted summary key holds (1 for mm, 1000 for
    m), or None when it holds none.  The unit is the last part's (``exact_residual_max_m``) or, for
    the entries of an error table, the table's (``cut.error_mm.compensated.max``)."""
    parts = key.split(".")
    last = parts[-1]
    if ("error" in key or "residual" in key) and (last.endswith("_mm") or last.endswith("_m")):
        return 1.0 if last.endswith("_mm") else 1e3
    for part in reversed(parts[:-1]):
        if ("error" in part or "residual" in part) and (part.endswith("_mm") or part.endswith("_m")):
            return 1.0 if part.endswith("_mm") else 1e3
    return None


def is_error_key(key: str) -> bool:
    """Whether a dotted summary key holds a TCP error length (mm or m) the floor applies to."""
    return error_key_mm(key) is not None


def format_value(v: Any, key: str = "") -> str:
    """Display text of a summary value named by its dotted ``key``.

    Numbers get :data:`DISPLAY_DIGITS` significant digits; TCP errors (keys with
    ``error``/``residual`` ending in ``_mm`` or ``_m``) below the numerical floor
    are "0 (numerical)"; lists are shown element by element.
    """
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, int) or (hasattr(v, "dtype") and v.dtype.kind in "iu"):
        return str(int(v))
    if isinstance(v, float) or (hasattr(v, "dtype") and v.dtype.kind == "f"):
        f = float(v)
        per = error_key_mm(key) if key else None
        if per is not None and math.isfinite(f):
            if below_floor(f * per):
                return NUMERICAL_ZERO_TEXT
        return format_number(f)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(format_value(x, key) for x in v) + "]"
    return str(v)


__all__ = [
    "DISPLAY_DIGITS",
    "NUMERICAL_FLOOR_M",
    "NUMERICAL_FLOOR_MM",
    "NUMERICAL_FLOOR_RAD",
    "NUMERICAL_ZERO_TEXT",
    "format_mm",
    "format_number",
    "format_value",
    "headline_mm",
    "error_key_mm",
    "is_error_key",
    "mm_text",
    "round_sig",
]
