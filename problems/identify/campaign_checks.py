"""What the campaigns of an identification must not hide (:mod:`.campaigns`): repeated rows, the
reference campaign, and registrations that differ by more than an instrument that stayed put moves.

* :func:`drop_repeated_rows` -- a row identical to an earlier one (the same joint angles, load and
  measured point, within a campaign or across campaigns) is a copy, not a new measurement: it is
  counted once (the repeats dropped) and :class:`RepeatedRows` says how many and where.  A campaign
  whose every row repeats an earlier campaign's is the same campaign twice: :class:`DataError`.
* :func:`reference_index` -- the reference campaign (the model's own registration): the one named,
  else the one with the most rows.
* :func:`frame_warnings` -- a campaign with its own registration that differs from the reference's by
  more than :data:`FRAME_STILL_M` or :data:`FRAME_STILL_RAD`: the figures, and what to give if the
  instrument did not move.

Everything is SI; the library prints nothing (the warnings are returned as text).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.errors import InputError

from ..measurements import Measurements
from .results import DataError

#: Rows are identical when their joint angles (rad), load (N, N m) and measured point (m) agree to this
#: many decimals (1 nrad, 1 nm: far below any instrument; a CSV written and read back still agrees).
REPEAT_DECIMALS = 9
#: Lines of a file named in a repeated-rows message (the rest counted).
REPEAT_LINES_NAMED = 5
#: A registration of its own farther than this from the reference campaign's (translation, m) ...
FRAME_STILL_M = 1e-4
#: ... or rotated by more than this (rad) is more than an instrument that was not moved shows
#: (a laser tracker's volumetric accuracy is some 15 um + 6 um/m: a frame that stayed put is found again
#: to well under 0.1 mm and 0.01 deg, 0.17 mm at 1 m): warned.
FRAME_STILL_RAD = float(np.radians(0.01))
#: A campaign with its own registration and fewer distinct poses than this: the warning says its
#: registration rests on few poses (6 parameters from 3 coordinates per pose).
FEW_POSES = 10


@dataclass
class RepeatedRows:
    """Rows dropped as repeats of earlier rows.

    Attributes
    ----------
    n_dropped : int
        Rows dropped (every repeat after the first occurrence).
    files : list of dict
        Per campaign with repeats: ``name``, ``file``, ``n`` (rows dropped from it), ``lines`` (their
        file lines) and ``of`` (the names of the campaigns holding the first occurrences).
    """

    n_dropped: int = 0
    files: list[dict[str, Any]] = field(default_factory=list)

    def message(self) -> str:
        """One line: how many rows, which files and lines, what was done ('' without repeats)."""
        if not self.n_dropped:
            return ""
        parts = []
        for f in self.files:
            lines = ", ".join(str(x) for x in f["lines"][:REPEAT_LINES_NAMED])
            more = f" and {len(f['lines']) - REPEAT_LINES_NAMED} more" if len(f["lines"]) > REPEAT_LINES_NAMED else ""
            of = ", ".join(f"'{o}'" for o in f["of"])
            parts.append(f"{f['n']} in {f['file']} (lines {lines}{more}) repeating rows of {of}")
        return (
            f"{self.n_dropped} row(s) repeat earlier rows exactly (the same joint angles, load and measured point): "
            + "; ".join(parts)
            + "; each counted once (the repeats dropped), so a copy does not double its weight"
        )

    def to_dict(self) -> dict[str, Any]:
        """``identifiability['repeated_rows']`` of the result."""
        return {"n_dropped": self.n_dropped, "files": self.files}


def _row_keys(m: Measurements) -> list[bytes]:
    """One hashable key per row: joint angles, load and measured point rounded to :data:`REPEAT_DECIMALS`."""
    cols = [m.q, m.wrench] + ([m.p] if m.p is not None else [])
    arr = np.round(np.hstack([np.asarray(c, dtype=float) for c in cols]), REPEAT_DECIMALS) + 0.0  # no -0.0
    return [row.tobytes() for row in arr]


def drop_repeated_rows(
    campaigns: Sequence[Measurements], names: Sequence[str]
) -> tuple[list[Measurements], RepeatedRows]:
    """The campaigns without rows that repeat an earlier row (in the order given), and what was dropped.

    Raises
    ------
    DataError
        A campaign whose every row repeats an earlier campaign's (the same campaign given twice).
    """
    seen: dict[bytes, int] = {}  # row key -> the campaign of its first occurrence
    out: list[Measurements] = []
    rep = RepeatedRows()
    for c, (m, name) in enumerate(zip(campaigns, names)):
        keep = np.ones(m.n, dtype=bool)
        of: set[int] = set()
        for i, key in enumerate(_row_keys(m)):
            if key in seen:
                keep[i] = False
                of.add(seen[key])
            else:
                seen[key] = c
        if not keep.any():
            firsts = ", ".join(f"'{names[o]}'" for o in sorted(of))
            raise DataError(
                f"{m.source}: every row of campaign '{name}' repeats rows of {firsts} (the same joint angles, "
                "load and measured point): the same campaign given twice; give it once"
            )
        if not keep.all():
            dropped = np.flatnonzero(~keep)
            rep.n_dropped += len(dropped)
            rep.files.append(
                {
                    "name": name,
                    "file": m.source,
                    "n": int(len(dropped)),
                    "lines": [int(x) for x in m.line[dropped]],
                    "of": [names[o] for o in sorted(of)],
                }
            )
            m = m.subset(keep)
        out.append(m)
    return out, rep


def reference_index(campaigns: Sequence[Measurements], names: Sequence[str], reference: str | None) -> int:
    """Index of the reference campaign: ``reference`` by name, else the one with the most rows (of
    several equally large, the last given).  An unknown name is an :class:`InputError` naming the campaigns."""
    if reference is not None:
        if reference not in names:
            raise InputError(
                f"reference campaign {reference!r}: no such campaign; the campaigns are {', '.join(names)}"
            )
        return list(names).index(reference)
    sizes = [m.n for m in campaigns]
    return max(range(len(sizes)), key=lambda k: (sizes[k], k))


def frame_warnings(table: Sequence[Mapping[str, Any]], reference: str) -> list[str]:
    """Warnings for campaigns whose registration differs from the reference's by more than
    :data:`FRAME_STILL_M` or :data:`FRAME_STILL_RAD` (rows of ``identifiability['campaigns']``)."""
    out = []
    for c in table:
        if c["name"] == reference:
            continue
        t_mm, r_deg = c["translation_from_reference_mm"], c["rotation_from_reference_deg"]
        if t_mm <= FRAME_STILL_M * 1e3 and r_deg <= np.degrees(FRAME_STILL_RAD):
            continue
        few = (
            f"; its registration rests on {c['n_poses']} poses (6 parameters from {3 * c['n_poses']} coordinates)"
            if c["n_poses"] < FEW_POSES
            else ""
        )
        out.append(
            f"campaign '{c['name']}' ({c['file']}, {c['n_rows']} rows, {c['n_poses']} poses): its registration is "
            f"{t_mm:.3f} mm and {r_deg:.3f} deg from the reference campaign '{reference}''s (more than the "
            f"{FRAME_STILL_M * 1e3:g} mm / {np.degrees(FRAME_STILL_RAD):g} deg an instrument that was not moved "
            f"shows){few}; it was fitted as a moved instrument (no --shared registration): if the instrument did "
            "not move between the campaigns, give --shared registration"
        )
    return out
