"""Printing helpers shared by the sub-commands (the CLI is the only place that prints)."""

from __future__ import annotations


def print_error_table(rows: list[tuple[str, float, float]], title: str) -> None:
    """Print a small table of (case, max mm, RMS mm)."""
    print(title)
    print(f"  {'case':<28}{'max [mm]':>12}{'RMS [mm]':>12}")
    for name, mx, rms in rows:
        print(f"  {name:<28}{mx:>12.6f}{rms:>12.6f}")
