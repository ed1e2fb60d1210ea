"""Measured cutting forces: the CSV of steady cutting tests and the engagement of each test.

One row per **test**: a steady cut at one feed per tooth, axial depth and radial width, its forces
averaged over whole spindle revolutions by the dynamometer's software.  Columns (units in the names,
any order, ``#`` starts a comment line, ``,`` separates, ``.`` is the decimal point)::

    feed_per_tooth_mm   > 0, at most 1 mm (c, the feed per tooth)
    axial_depth_mm      > 0 (a_p, the depth along the tool axis)
    radial_width_mm     > 0 (a_e, the width of cut; may be empty for a slot, which cuts the diameter)
    milling             slot | up | down  (up = conventional, down = climb)
    Fx_N, Fy_N          mean force ON THE TOOL in the feed frame, N
    Fz_N                optional (column or cell empty: not measured)
    Mx_Nm, My_Nm, Mz_Nm optional mean moments on the tool about the tool tip, N·m
    spindle             optional: cw (M3, the default) | ccw (M4)
    test                optional: a label

Frame (``docs/cutting.md``): the **feed frame** has ``x`` along the feed, ``z`` along the tool axis
towards the spindle, ``y = z x x`` (left of the feed).  A dynamometer under the workpiece measures
the force on the workpiece: negate it to get the force on the tool.

The engagement of a test is built analytically (:func:`engagement_of_test`): an edge point at height
``z`` above the tip and immersion angle ``phi`` is in material when ``z < a_p``, ``0 <= phi <= pi``
and its lateral position ``rho(z) cos(phi)`` lies in the material left of the previous pass:
``>= R - a_e`` for up milling (``phi`` in ``[0, acos(1 - 2 a_e / D)]`` on the flank), ``<= -(R - a_e)``
for down milling (``[pi - acos(1 - 2 a_e / D), pi]``), anywhere for a slot (``[0, pi]``).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np

from models.cutting.cutter import EndMill
from models.cutting.engagement import ANGLE_BINS, SLICE_HEIGHT_M, EngagementBatch
from models.errors import InputError
from problems.measurements.cells import Cells

__all__ = [
    "FORCE_COLUMNS",
    "MOMENT_COLUMNS",
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "ForceTable",
    "ForceTest",
    "Milling",
    "Spindle",
    "engagement_mask",
    "immersion_range",
    "read_force_csv",
    "engagement_of_test",
]

#: Columns every file has.
REQUIRED_COLUMNS = ("feed_per_tooth_mm", "axial_depth_mm", "radial_width_mm", "milling", "Fx_N", "Fy_N")
#: Columns a file may have.
OPTIONAL_COLUMNS = ("Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm", "spindle", "test")
#: The force and moment columns, in the order of a wrench [Fx, Fy, Fz, Mx, My, Mz].
FORCE_COLUMNS = ("Fx_N", "Fy_N", "Fz_N")
MOMENT_COLUMNS = ("Mx_Nm", "My_Nm", "Mz_Nm")
#: Largest plausible feed per tooth, mm (a larger value is a feed per revolution or a unit mistake).
MAX_FEED_PER_TOOTH_MM = 1.0
#: Largest plausible axial depth and radial width, mm.
MAX_DEPTH_MM = 200.0
#: How closely a slot's radial width must match the cutter diameter (relative).
SLOT_WIDTH_RTOL = 1e-3
#: Slack on a radial width or axial depth beyond the cutter (relative) still taken as the cutter's.
ENGAGEMENT_RTOL = 1e-9


class Milling(Enum):
    """How the cutter meets the material (clockwise spindle: up = material on the left of the feed)."""

    SLOT = "slot"
    UP = "up"
    DOWN = "down"


class Spindle(Enum):
    """Spindle rotation seen from the spindle towards the work."""

    CW = "cw"
    CCW = "ccw"


@dataclass(frozen=True)
class ForceTest:
    """One steady cutting test (SI).

    Attributes
    ----------
    line : int
        Line of the file (1-based), for messages.
    label : str
        The ``test`` column, or ``"line N"``.
    feed_per_tooth_m, axial_depth_m : float
        c and a_p, m.
    radial_width_m : float or None
        a_e, m (None: a slot given without a width, the cutter diameter).
    milling : Milling
    spindle : Spindle
    wrench : ndarray, shape (6,)
        Mean [Fx, Fy, Fz (N), Mx, My, Mz (N·m)] on the tool in the feed frame, about the tool tip;
        NaN where not measured.
    """

    line: int
    label: str
    feed_per_tooth_m: float
    axial_depth_m: float
    radial_width_m: float | None
    milling: Milling
    spindle: Spindle
    wrench: np.ndarray


@dataclass(frozen=True)
class ForceTable:
    """The tests of one file.

    Attributes
    ----------
    where : str
        The file, as messages name it.
    tests : tuple of ForceTest
    """

    where: str
    tests: tuple[ForceTest, ...]

    @property
    def n(self) -> int:
        return len(self.tests)

    def wrenches(self) -> np.ndarray:
        """Measured wrenches, shape (n, 6), NaN where not measured."""
        return np.array([t.wrench for t in self.tests], dtype=float).reshape(-1, 6)

    def feeds_m(self) -> np.ndarray:
        """Feeds per tooth, m, shape (n,)."""
        return np.array([t.feed_per_tooth_m for t in self.tests], dtype=float)


def read_force_csv(path: str | Path) -> ForceTable:
    """Read a measured-force file (the columns of this module's docstring).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    ForceTable

    Raises
    ------
    InputError
        The file cannot be read, a column is missing, unknown or repeated, or a cell is not what its
        column holds; the message names the file, the line, the column, the value and what was expected.
    """
    where = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError(f"{where}: no such file (expected a measured-force CSV, docs/cutting.md)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{where}: cannot read it as UTF-8 text ({exc})") from None
    header_line, header, rows = _table(where, text)
    cols = _columns(where, header_line, header)
    cells = Cells(where, False)
    tests = []
    for line, row in rows:
        if len(row) != len(header):
            raise InputError(
                f"{where}: line {line}: {len(row)} cells; expected {len(header)}, one per column of the header "
                f"(line {header_line})"
            )
        tests.append(_test(where, cells, line, {name: row[k] for name, k in cols.items()}))
    return ForceTable(where, tuple(tests))


def _table(where: str, text: str) -> tuple[int, list[str], list[tuple[int, list[str]]]]:
    """(header line, header cells, rows as (line, cells)) of the non-empty, non-comment lines."""
    reader = csv.reader(io.StringIO(text))
    table: list[tuple[int, list[str]]] = []
    for cells in reader:
        if not cells or all(c.strip() == "" for c in cells) or cells[0].lstrip().startswith("#"):
            continue
        table.append((reader.line_num, [c.strip() for c in cells]))
    if not table:
        raise InputError(f"{where}: empty file; expected a header row ({', '.join(REQUIRED_COLUMNS)}) and test rows")
    header_line, header = table[0]
    if len(table) == 1:
        raise InputError(f"{where}: no test rows after the header (line {header_line})")
    return header_line, header, table[1:]


def _columns(where: str, line: int, header: list[str]) -> dict[str, int]:
    """Column name -> index; refuses unknown, repeated and missing columns."""
    known = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
    if len(header) == 1 and ";" in header[0]:
        raise InputError(f"{where}: line {line}: the header is separated by ';'; expected ',' between the columns")
    cols: dict[str, int] = {}
    for k, name in enumerate(header):
        if name not in known:
            lower = {c.lower(): c for c in known}
            hint = f" (did you mean '{lower[name.lower()]}'?)" if name.lower() in lower else ""
            units = " (units belong in the name: e.g. Fx_N, feed_per_tooth_mm)" if not hint else ""
            raise InputError(
                f"{where}: line {line}: unknown column '{name}'{hint}{units}; expected the columns "
                f"{', '.join(REQUIRED_COLUMNS)} and optionally {', '.join(OPTIONAL_COLUMNS)}"
            )
        if name in cols:
            raise InputError(f"{where}: line {line}: column '{name}' appears twice")
        cols[name] = k
    missing = [c for c in REQUIRED_COLUMNS if c not in cols]
    if missing:
        raise InputError(
            f"{where}: line {line}: missing column(s) {', '.join(missing)}; expected the columns "
            f"{', '.join(REQUIRED_COLUMNS)} and optionally {', '.join(OPTIONAL_COLUMNS)}"
        )
    return cols


def _test(where: str, cells: Cells, line: int, row: dict[str, str]) -> ForceTest:
    """One row as a test (SI), every cell checked."""

    def at(col: str) -> str:
        return f"{where}: line {line}, column '{col}'"

    feed = _bounded(cells, at, line, "feed_per_tooth_mm", row, MAX_FEED_PER_TOOTH_MM, "a feed per tooth")
    depth = _bounded(cells, at, line, "axial_depth_mm", row, MAX_DEPTH_MM, "an axial depth")
    milling = _choice(at("milling"), row["milling"], Milling, "slot, up (conventional) or down (climb)")
    width = None
    if row["radial_width_mm"] != "" or milling is not Milling.SLOT:
        width = _bounded(cells, at, line, "radial_width_mm", row, MAX_DEPTH_MM, "a radial width") * 1e-3
    spindle = Spindle.CW
    if row.get("spindle", "") != "":
        spindle = _choice(at("spindle"), row["spindle"], Spindle, "cw (M3, the default) or ccw (M4)")
    wrench = np.full(6, np.nan)
    for k, col in enumerate(FORCE_COLUMNS + MOMENT_COLUMNS):
        text = row.get(col, "")
        if col in REQUIRED_COLUMNS or text != "":
            wrench[k] = cells.number(line, col, text)
    label = row.get("test", "") or f"line {line}"
    return ForceTest(line, label, feed * 1e-3, depth * 1e-3, width, milling, spindle, wrench)


def _bounded(
    cells: Cells, at: Callable[[str], str], line: int, col: str, row: dict[str, str], most: float, what: str
) -> float:
    """A number in (0, most] (mm)."""
    v = cells.number(line, col, row[col])
    if not 0.0 < v <= most:
        raise InputError(f"{at(col)}: {row[col]} is out of range; expected {what} in (0, {most:g}] mm")
    return v


def _choice(where: str, text: str, kind: type[Enum], expected: str) -> Enum:
    """A word of ``kind`` (case-insensitive)."""
    try:
        return kind(text.strip().lower())
    except ValueError:
        raise InputError(f"{where}: '{text}' is not a choice; expected {expected}") from None


def immersion_range(diameter_m: float, radial_width_m: float, milling: Milling) -> tuple[float, float]:
    """The flank's engaged immersion angles ``(phi_st, phi_ex)``, rad, of a radial width.

    Up milling ``[0, acos(1 - 2 a_e / D)]``, down milling ``[pi - acos(1 - 2 a_e / D), pi]``, a slot
    ``[0, pi]`` (Altintas, *Manufacturing Automation*, 2nd ed., section 2.3).
    """
    if milling is Milling.SLOT:
        return 0.0, math.pi
    span = math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * radial_width_m / diameter_m)))
    return (0.0, span) if milling is Milling.UP else (math.pi - span, math.pi)


def engagement_mask(
    mill: EndMill,
    axial_depth_m: float,
    radial_width_m: float,
    milling: Milling,
    angle_bins: int = ANGLE_BINS,
    max_slice_m: float | None = SLICE_HEIGHT_M,
) -> EngagementBatch:
    """The engagement of a steady straight cut (one sample) by an end mill of any shape.

    The slice height is the largest ``<= max_slice_m`` that divides ``axial_depth_m`` (the cut's
    bottom falls on a slice boundary); ``None``: one slice of the whole depth (exact for the mean
    force of a flat end mill, whose flank is the same at every height).  The mask holds the slices of
    the cut only (``K = a_p / dz``): those above are never engaged.

    Parameters
    ----------
    mill : EndMill
    axial_depth_m : float
        a_p, m, in (0, flute length].
    radial_width_m : float
        a_e, m, in (0, D] (a slot: D).
    milling : Milling
    angle_bins : int
        J, angle bins of a revolution.
    max_slice_m : float or None
        Largest slice height, m (None: one slice).

    Returns
    -------
    EngagementBatch
        Mask (1, K, J), in the feed frame of a clockwise spindle (the mirrored one for M4).
    """
    K = 1 if max_slice_m is None else max(1, math.ceil(axial_depth_m / max_slice_m - ENGAGEMENT_RTOL))
    dz = axial_depth_m / K
    J = int(angle_bins)
    z = (np.arange(K) + 0.5) * dz
    phi = (np.arange(J) + 0.5) * (2.0 * math.pi / J)
    rho = mill.radius_at(z)[:, None]
    lateral = rho * np.cos(phi)[None, :]
    ahead = (phi <= math.pi)[None, :]
    wall = mill.radius_m - radial_width_m  # the previous pass's wall, from the axis
    if milling is Milling.SLOT:
        side = np.ones_like(lateral, dtype=bool)
    elif milling is Milling.UP:
        side = lateral >= wall
    else:
        side = lateral <= -wall
    mask = ahead & side
    return EngagementBatch(mask[None, :, :], dz)


def engagement_of_test(
    mill: EndMill, where: str, test: ForceTest, angle_bins: int = ANGLE_BINS, max_slice_m: float | None = SLICE_HEIGHT_M
) -> EngagementBatch:
    """The engagement of ``test`` cut by ``mill`` (:func:`engagement_mask`), the test checked against it.

    Raises
    ------
    InputError
        The depth beyond the flutes, the width beyond the diameter, or a slot's width not the
        diameter; the message names the file, the line and the column.
    """
    at = f"{where}: line {test.line}"
    D = mill.diameter_m
    if test.axial_depth_m > mill.flute_length_m * (1.0 + ENGAGEMENT_RTOL):
        raise InputError(
            f"{at}, column 'axial_depth_mm': {test.axial_depth_m * 1e3:g} mm is deeper than the cutter's flute "
            f"length {mill.flute_length_m * 1e3:g} mm"
        )
    width = D if test.radial_width_m is None else test.radial_width_m
    if test.milling is Milling.SLOT and abs(width - D) > SLOT_WIDTH_RTOL * D:
        raise InputError(
            f"{at}, column 'radial_width_mm': a slot cuts the cutter's diameter {D * 1e3:g} mm, got "
            f"{width * 1e3:g} mm; leave it empty, or give milling up or down for a partial immersion"
        )
    if width > D * (1.0 + SLOT_WIDTH_RTOL):
        raise InputError(
            f"{at}, column 'radial_width_mm': {width * 1e3:g} mm is wider than the cutter's diameter "
            f"{D * 1e3:g} mm; expected a radial width in (0, {D * 1e3:g}] mm"
        )
    return engagement_mask(mill, test.axial_depth_m, min(width, D), test.milling, angle_bins, max_slice_m)
