"""The report's table of the predicted cut: summary.json's ``cut`` block at a glance (cutter,
material, stock, spindle and feed per tooth, force, TCP errors, the cut's warnings), nothing
recomputed; none for a run without a cut."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from planner.numbers import format_number
from planner.record.columns import CUT_KEY
from planner.report.table_base import Cell, Table, lookup, value_cell

__all__ = ["SOURCE_CHARS", "cut_tables", "cutter_words"]

#: Longest material source shown (the full text is summary.json cut.material.source).
SOURCE_CHARS = 160


def _short(text: str, n: int = SOURCE_CHARS) -> str:
    """``text`` cut at a word boundary to at most ``n`` characters, with "…" when cut."""
    text = " ".join(str(text).split())
    if len(text) <= n:
        return text
    return text[: text.rfind(" ", 0, n) if " " in text[:n] else n].rstrip(" ,;:") + " …"


def cutter_words(cutter: Mapping[str, Any]) -> str:
    """The end mill in words: ``"flat end mill Ø8 mm, 3 flutes, helix 30°"``."""
    shape = str(cutter.get("shape", "?")).replace("_", "-")
    parts = [f"{shape} end mill"]
    d = cutter.get("diameter")
    if isinstance(d, (int, float)):
        parts[0] += f" Ø{format_number(float(d) * 1e3)} mm"
    r = cutter.get("corner_radius")
    if shape == "bull-nose" and isinstance(r, (int, float)):
        parts.append(f"corner radius {format_number(float(r) * 1e3)} mm")
    if isinstance(cutter.get("flutes"), (int, float)):
        parts.append(f"{int(cutter['flutes'])} flutes")
    if isinstance(cutter.get("helix_deg"), (int, float)):
        parts.append(f"helix {format_number(float(cutter['helix_deg']), 3)}°")
    return ", ".join(parts)


def _range_cell(summary: Mapping[str, Any], key: str) -> list[Cell]:
    """The min and max of a range entry (``{"min", "max"}``; null: no cutting waypoint)."""
    try:
        v = lookup(summary, key)
    except KeyError:
        return [Cell("absent"), Cell("")]
    if v is None:
        return [Cell("n/a (no cutting waypoint)"), Cell("")]
    return [value_cell(summary, f"{key}.min"), value_cell(summary, f"{key}.max")]


def cut_tables(summary: Mapping[str, Any]) -> list[Table]:
    """The cut at a glance (summary.json ``cut``); none for a run without a cut."""
    c = summary.get(CUT_KEY)
    if not isinstance(c, Mapping):
        return []
    k = CUT_KEY
    cutter = c.get("cutter") if isinstance(c.get("cutter"), Mapping) else {}
    mat = c.get("material") if isinstance(c.get("material"), Mapping) else {}
    rows = [
        [Cell("cutter"), Cell(cutter_words(cutter)), Cell("")],
        [Cell("material"), value_cell(summary, f"{k}.material.name"), Cell(_short(mat.get("source", "")))],
        [
            Cell("stock volume / removed [mm³]"),
            value_cell(summary, f"{k}.stock_volume_mm3"),
            value_cell(summary, f"{k}.removed_mm3"),
        ],
        [Cell("stock grid resolution [mm]"), value_cell(summary, f"{k}.resolution_mm"), Cell("")],
        [Cell("cutting waypoints"), value_cell(summary, f"{k}.cutting_waypoints"), Cell("")],
        [Cell("spindle while cutting, min / max [rev/min]"), *_range_cell(summary, f"{k}.spindle_rpm")],
        [Cell("feed per tooth while cutting, min / max [mm]"), *_range_cell(summary, f"{k}.feed_per_tooth_mm")],
        [
            Cell("|F| mean while cutting / max [N]"),
            value_cell(summary, f"{k}.force_N.mean_cutting"),
            value_cell(summary, f"{k}.force_N.max"),
        ],
        [Cell("program line of the max |F|"), value_cell(summary, f"{k}.force_N.max_line"), Cell("")],
        [Cell("peak |F| over a revolution, max [N]"), value_cell(summary, f"{k}.force_N.peak_max"), Cell("")],
    ]
    err = c.get("error_mm") if isinstance(c.get("error_mm"), Mapping) else {}
    for key, label in (
        ("uncompensated", "TCP error uncompensated, RMS / max [mm]"),
        ("compensated", "TCP error compensated for the predicted force, RMS / max [mm]"),
        ("stand_in_compensated", "TCP error compensated for the constant stand-in, RMS / max [mm]"),
    ):
        if key in err:
            rows.append(
                [
                    Cell(label),
                    value_cell(summary, f"{k}.error_mm.{key}.rms"),
                    value_cell(summary, f"{k}.error_mm.{key}.max"),
                ]
            )
    stand = c.get("stand_in")
    if isinstance(stand, Mapping):
        rows.append([Cell("stand-in wrench"), Cell(_stand_text(stand)), Cell("")])
    warn = [str(w) for w in c.get("warnings") or []]
    rows.append([Cell("the cut's warnings"), Cell(str(len(warn))), Cell("; ".join(warn) if warn else "none")])
    note = (
        "The load predicted from the cut (summary.json 'cut'): the mean force over a spindle revolution on the "
        "tool, program frame, from the mechanistic edge-force model and the stock simulated along the program. "
        "TCP errors: norm of the load-induced TCP position error under the predicted wrench at every waypoint, "
        "the arm commanded as planned (uncompensated), with the plan's compensation for the predicted wrench, and "
        "with a compensation for the constant stand-in wrench ([cut] stand_in) instead. Spindle and feed per tooth "
        "over the cutting waypoints (a plunge has no feed per tooth across the cutter). Material source shortened; "
        "in full: summary.json cut.material.source."
    )
    return [Table("The cut", ["quantity", "value", "value / detail"], rows, note, anchor="cut")]


def _stand_text(stand: Mapping[str, Any]) -> str:
    F = [format_number(float(v)) for v in stand.get("F_N") or []]
    M = [format_number(float(v)) for v in stand.get("M_Nm") or []]
    frame = "tool frame" if stand.get("frame") == "tool" else "base frame"
    return f"F = [{', '.join(F)}] N, M = [{', '.join(M)}] N·m, {frame}"
