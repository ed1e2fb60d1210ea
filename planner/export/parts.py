"""Big programs: the numbered parts a format writes above its size limit (``docs/export.md``,
"Big programs")."""

from __future__ import annotations

__all__ = ["PART_DIGITS", "decimation_change", "part_label", "part_ranges", "parts_change"]


#: Digits of the part number in a part's name (``NAME_p001``); more when there are more parts.
PART_DIGITS = 3


def part_ranges(n: int, limit: int) -> list[tuple[int, int]]:
    """``[start, stop)`` index ranges that cover ``range(n)`` in order, each at most ``limit`` long
    (all but the last exactly ``limit``)."""
    if limit < 1:
        raise ValueError(f"part size limit {limit}: expected at least 1")
    return [(a, min(a + limit, n)) for a in range(0, n, limit)]


def part_label(k: int, count: int) -> str:
    """The name tag of part ``k`` (1-based) of ``count``: ``p001`` ... (zero-padded to
    :data:`PART_DIGITS`, or to the digits of ``count``)."""
    return f"p{k:0{max(PART_DIGITS, len(str(count)))}d}"


def parts_change(n: int, limit: int, unit: str, option: str, part: str) -> tuple[str, ...]:
    """The change line of an export of ``n`` ``unit`` (points, targets) split at ``limit`` (option
    ``option``) into numbered ``part`` s (messages, modules); none when they fit in one."""
    if n <= limit:
        return ()
    return (f"split into {len(part_ranges(n, limit))} {part}s of at most {limit} {unit} ({option}): {n} {unit} in all",)


def decimation_change(n: int, total: int, step_s: float, what: str) -> str:
    """The change line of an export that keeps ``n`` of ``total`` samples, one every ``step_s`` s."""
    return (
        f"decimated to a {what} every ~{step_s:g} s: {n} of {total} samples, the controller's own motion between them"
    )
