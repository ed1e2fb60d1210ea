"""The joint error maps in the report: the rows of their table, its Markdown section and the
figure of each map over its angle range with its band."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from planner.identify_report.canvas import RenderedFigure, render_figure
from planner.report.figure_base import new_figure
from planner.identify_report.text import md_cell
from planner.numbers import format_number
from problems.identify import IdentificationResult
from problems.identify.map_summary import MAP_BAND_SIGMAS, ErrorMapSummary

#: Joint error maps drawn (panels of one figure; the largest RMS at the TCP when there are more).
REPORT_MAP_PANELS = 6
#: Harmonics of a map listed in the tables (the largest first; every one is in ``report.json``).
REPORT_MAP_HARMONICS = 3
#: Components of a joint error map (``models.effects.joint_error_map.MAP_COMPONENTS``):
#: symbol and words.
MAP_COMPONENT_WORDS = {
    "theta": ("θ", "angular positioning error"),
    "d": ("d", "axial error (along the joint axis)"),
    "a": ("a", "radial error (along the link's x axis)"),
    "alpha": ("α", "tilt about the link's x axis"),
    "beta": ("β", "tilt about the link's y axis"),
}


def map_name(m: dict[str, Any]) -> str:
    """``joint 1 θ`` for a map of :func:`~planner.identify_report.data.report_dict`."""
    return f"joint {m['joint']} {MAP_COMPONENT_WORDS.get(m['component'], (m['component'], ''))[0]}"


def harmonic_freqs(m: dict[str, Any]) -> str:
    """``13.56, 13.35 cycles/rev`` (the largest harmonics of a map)."""
    hs = m["harmonics"][:REPORT_MAP_HARMONICS]
    more = len(m["harmonics"]) - len(hs)
    return (
        (", ".join(format_number(h["freq_cpr"], 4) for h in hs) + (f" (+{more} more)" if more else "") + " cycles/rev")
        if hs
        else "no harmonic"
    )


def _harmonic_text(m: dict[str, Any], h: dict[str, Any]) -> str:
    """One harmonic of a map: frequency, amplitude ± std (µrad or µm), and at the TCP (µm)."""
    u, key = ("µrad", "urad") if m["unit"] == "rad" else ("µm", "um")
    amp, std = h.get(f"amplitude_{key}"), h.get(f"amplitude_std_{key}")
    pm = f" ± {format_number(std, 2)}" if std is not None and math.isfinite(std) else " (std n/a)"
    tcp = h.get("amplitude_tcp_um")
    # a length moves the TCP by itself (lever 1): its size at the TCP only when it differs
    same = m["unit"] != "rad" and tcp is not None and amp is not None and abs(tcp - amp) <= 0.01 * abs(amp)
    at_tcp = "" if tcp is None or same else f" → {format_number(tcp, 3)} µm at the TCP"
    return f"{format_number(h['freq_cpr'], 4)} cycles/rev: {format_number(amp, 3)}{pm} {u}{at_tcp}"


def _map_rows(rep: dict[str, Any]) -> list[tuple[str, ...]]:
    """(joint, component, angle range, dominant harmonics, RMS at the TCP) rows of the maps table."""
    rows = []
    for m in rep.get("error_maps") or []:
        sym, words = MAP_COMPONENT_WORDS.get(m["component"], (m["component"], ""))
        hs = m["harmonics"][:REPORT_MAP_HARMONICS]
        more = len(m["harmonics"]) - len(hs)
        harm = "; ".join(_harmonic_text(m, h) for h in hs) + (f"; +{more} smaller" if more else "")
        lo, hi = m["range_deg"]
        name = sym if sym == m["component"] else f"{sym} ({m['component']})"
        rows.append(
            (
                str(m["joint"]),
                f"{name}: {words}",
                f"{format_number(lo, 3)} … {format_number(hi, 3)}",
                harm or "-",
                format_number(m["rms_tcp_um"], 3),
            )
        )
    return rows


#: What the maps table says about itself (Markdown and HTML).
MAP_TABLE_NOTE = (
    "Each map is the error of one joint, one component of its motion, as a function of its own "
    "commanded angle: a Fourier series in that angle with the harmonics (cycles per revolution of "
    "the joint) the spectrum search found, largest first. Amplitude of a harmonic ± 1 standard "
    "deviation (µrad for angles, µm for lengths); at the TCP: times the median lever of the "
    "component over the data. RMS at the TCP: the map's effect over the measured poses. A map is a "
    "function of its joint's angle everywhere: it continues beyond the angle range of the data, where the "
    "model's sigma grows with the distance."
)


def maps_markdown(rep: dict[str, Any]) -> list[str]:
    """The "Joint error maps" section (empty without maps)."""
    rows = _map_rows(rep)
    if not rows:
        return []
    L = [
        "## Joint error maps",
        "",
        MAP_TABLE_NOTE,
        "",
        "| joint | component | angle range (deg) | dominant harmonics | RMS at the TCP (µm) |",
        "|---|---|---|---|---|",
    ]
    L += ["| " + " | ".join(md_cell(c) for c in r) + " |" for r in rows]
    n = len(rows)
    if n > REPORT_MAP_PANELS:
        L += [
            "",
            f"The figure draws the {REPORT_MAP_PANELS} maps with the largest RMS at the TCP; "
            f"{n - REPORT_MAP_PANELS} more are in the table and in report.json.",
        ]
    return L + [""]


def maps_drawn(maps: list[Any]) -> list[Any]:
    """The maps drawn: all, or the :data:`REPORT_MAP_PANELS` largest at the TCP, in table order."""
    if len(maps) <= REPORT_MAP_PANELS:
        return list(maps)
    keep = sorted(range(len(maps)), key=lambda i: -float(maps[i].rms_tcp_m))[:REPORT_MAP_PANELS]
    return [maps[i] for i in sorted(keep)]


def _map_panel(ax: Any, m: ErrorMapSummary, q_data: np.ndarray) -> None:
    """One map's panel: the map and its band, continued beyond the range (grey), and the commanded angles of
    the data (ticks at the bottom)."""
    sym, words = MAP_COMPONENT_WORDS.get(m.component, (m.component, ""))
    unit = "µrad" if m.unit == "rad" else "µm"
    x = np.degrees(np.asarray(m.q_rad, dtype=float))
    y = np.asarray(m.value, dtype=float) * 1e6
    b = np.nan_to_num(np.asarray(m.band, dtype=float)) * 1e6
    lo, hi = (float(np.degrees(v)) for v in m.range_rad)
    ax.fill_between(x, y - b, y + b, color="tab:blue", alpha=0.22, lw=0)
    inside = (x >= lo) & (x <= hi)
    ax.plot(np.where(inside, x, np.nan), y, "-", color="tab:blue", lw=1.4)
    for side in (x <= lo, x >= hi):
        ax.axvspan(float(x[side].min()), float(x[side].max()), color="0.88", lw=0)
        ax.plot(x[side], y[side], "--", color="tab:blue", lw=1.1)
    if len(q_data):
        ax.plot(
            np.degrees(q_data[:, m.joint - 1]),
            np.zeros(len(q_data)),
            "|",
            ms=6,
            color="0.35",
            alpha=0.5,
            transform=ax.get_xaxis_transform(),
        )
    ax.set_xlim(float(x[0]), float(x[-1]))
    y_lo, y_hi = float(np.min(y - b)), float(np.max(y + b))
    span = max(y_hi - y_lo, 1e-9)
    ax.set_ylim(y_lo - 0.16 * span, y_hi + 0.06 * span)  # room for the ticks of the data
    ax.axhline(0.0, color="0.4", lw=0.6)
    freqs = ", ".join(format_number(hm.freq_cpr, 3) for hm in m.harmonics[:REPORT_MAP_HARMONICS])
    more = f" (+{len(m.harmonics) - REPORT_MAP_HARMONICS})" if len(m.harmonics) > REPORT_MAP_HARMONICS else ""
    ax.set_title(
        f"joint {m.joint} {sym}: {words}\n{freqs}{more} cycles/rev, "
        f"{format_number(m.rms_tcp_m * 1e6, 3)} µm RMS at the TCP"
    )
    ax.set_xlabel(f"commanded angle q{m.joint} [deg]")
    ax.set_ylabel(f"{sym} error of joint {m.joint} [{unit}]")
    ax.grid(alpha=0.3)


def _legend_handles(spare: bool) -> list[Any]:
    """The legend's entries (two-line labels for the narrow legend of a spare panel)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    br = "\n" if spare else " "  # the legend in a spare panel is narrow: two-line labels
    return [
        Line2D([], [], color="tab:blue", lw=1.4, label="identified map"),
        Patch(
            color="tab:blue",
            alpha=0.22,
            label=f"uncertainty band ±{MAP_BAND_SIGMAS:g}σ{br}({MAP_BAND_SIGMAS:g} standard deviations)",
        ),
        Line2D(
            [],
            [],
            color="tab:blue",
            lw=1.1,
            ls="--",
            label=f"beyond the range (grey): the map{br}continued (a function of the angle)",
        ),
        Line2D([], [], color="0.35", ls="none", marker="|", ms=6, label="commanded angles of the data"),
    ]


def maps_png(res: IdentificationResult) -> RenderedFigure:
    """The joint error maps over their angle ranges (one panel per map): the map, its band, the
    commanded angles of the data, and the map continued beyond the range."""
    maps_all = list(res.error_maps)
    maps = maps_drawn(maps_all)
    k = len(maps)
    ncols = min(3, k)
    nrows = math.ceil(k / ncols)
    spare = nrows * ncols > k  # an empty slot holds the legend
    # inches: panels 2.3 high, 1.05 between rows (x label and a two-line title), 1.15 on top
    # (figure title and the first titles), 0.55 below (x label) and 0.35 more for a legend there
    w = 3.9 * ncols + 0.5 if ncols > 1 else 7.5
    title = ["Joint error maps: the error of each joint against its commanded angle, over the data's range and beyond"]
    if w < 10:  # one or two panels: the title on two lines
        title = [
            "Joint error maps: the error of each joint against its commanded angle,",
            "over the data's range and beyond",
        ]
    if k < len(maps_all):
        title.append(f"{k} of {len(maps_all)} maps drawn (the largest RMS at the TCP); every map is in the table")
    panel, gap, top, bottom = 2.3, 1.05, 0.75 + 0.2 * len(title), 0.55 + (0.0 if spare else 0.35)
    h = nrows * panel + (nrows - 1) * gap + top + bottom
    fig = new_figure(
        w, h, left=0.75 / w, right=1 - 0.3 / w, top=1 - top / h, bottom=bottom / h, wspace=0.3, hspace=gap / panel
    )
    axs = np.atleast_1d(fig.subplots(nrows, ncols)).ravel()
    q_data = np.asarray(res.data.q, dtype=float)[np.asarray(res.inliers, dtype=bool)]
    for ax, m in zip(axs, maps):
        _map_panel(ax, m, q_data)
    handles = _legend_handles(spare)
    for ax in axs[k:]:
        ax.axis("off")
    if spare:
        axs[k].legend(handles=handles, loc="center", frameon=False, fontsize=9)
    else:
        fig.legend(
            handles=handles, loc="lower center", ncol=4 if w > 9 else 2, frameon=False, bbox_to_anchor=(0.5, 0.0)
        )
    fig.suptitle("\n".join(title))
    return render_figure(fig)
