"""Figure 8 of the report: TCP deviation from the planned path against time, with dynamic compensation.

Split from :mod:`planner.report.plots` (same style helpers): drawn only for runs planned with
``[timing] dynamic = true`` from their ``dynamic.csv``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import matplotlib
import matplotlib.ticker
import numpy as np
from matplotlib.figure import Figure

from planner.numbers import NUMERICAL_FLOOR_MM, format_number
from planner.report.figure_base import new_figure, styled

__all__ = [
    "dynamic_figure",
]


# ------------------------------------------------------------------- 8. dynamic compensation
#: Labels (the headline's words), colours and line styles of the three cases of figure 8: the link plan
#: commanded as is, the static command, the motor-side command.
DYNAMIC_STYLES = (
    ("uncompensated", "0.35", "-", 1.3),
    ("static command", "tab:orange", "-", 1.5),
    ("motor-side command", "tab:blue", "-", 1.6),
)
#: The log axis of figure 8 spans at most this many decades below the largest error; smaller
#: values (and the exact zeros at rest) are drawn on its floor.
DYNAMIC_DECADES = 5


def _rest_spans(t: np.ndarray, moving: np.ndarray) -> list[tuple[float, float]]:
    """The (start, end) times of the runs of samples at rest (``moving`` false); a run ends where
    the next sample moves."""
    rest = ~np.asarray(moving, bool)
    edges = np.flatnonzero(np.diff(np.r_[0, rest.astype(int), 0]))
    spans = []
    for i, j in zip(edges[::2], edges[1::2]):  # rest samples i .. j-1
        spans.append((float(t[i]), float(t[min(j, len(t) - 1)])))
    return spans


@styled
def dynamic_figure(
    t_s: np.ndarray, moving: np.ndarray, errors_m: Sequence[np.ndarray], speed_m_s: np.ndarray, *, title: str
) -> Figure:
    """TCP deviation from the planned path against time with no, static and static + dynamic
    compensation (µm, log axis), above the planned TCP speed (m/s); the rest phases shaded.

    Parameters
    ----------
    t_s : ndarray, shape (N,)
        Time of the command samples, s.
    moving : ndarray, shape (N,)
        1 while the arm moves, 0 at rest.
    errors_m : three ndarrays, shape (N,)
        Predicted TCP position error along the command, m: none, static only, static + dynamic.
    speed_m_s : ndarray, shape (N,)
        Planned TCP speed, m/s.
    """
    fig = new_figure(11.0, 7.0, left=0.075, right=0.985, bottom=0.08, top=0.8, hspace=0.1)
    a1, a2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (2.3, 1.0)})
    t = np.asarray(t_s, float)
    mv = np.asarray(moving, float) > 0.5
    um = [np.abs(np.asarray(e, float)) * 1e6 for e in errors_m]
    finite = np.concatenate([e[np.isfinite(e)] for e in um])
    top = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    positive = np.concatenate([e[mv & np.isfinite(e) & (e > 0)] for e in um])
    lowest = float(positive.min()) if positive.size else top * 1e-3
    floor = 10.0 ** math.floor(math.log10(max(lowest, top * 10.0**-DYNAMIC_DECADES, NUMERICAL_FLOOR_MM * 1e3)))
    spans = _rest_spans(t, mv)
    for a in (a1, a2):
        for i, (lo, hi) in enumerate(spans):
            a.axvspan(
                lo, hi, color="0.85", alpha=0.7, lw=0, zorder=0, label="at rest" if (a is a1 and i == 0) else None
            )
    for e, (label, colour, ls, lw) in zip(um, DYNAMIC_STYLES):
        em = e[mv]
        stats = (
            f": max {format_number(float(em.max()))} µm, RMS {format_number(float(np.sqrt(np.mean(em**2))))}"
            " µm during the motion"
            if em.size
            else ""
        )
        a1.plot(t, np.clip(e, floor, None), color=colour, ls=ls, lw=lw, label=label + stats, zorder=3)
    a1.set_yscale("log")
    a1.set_ylim(floor, top * 3.0)
    a1.yaxis.set_major_locator(matplotlib.ticker.LogLocator(numticks=12))
    a1.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _pos: f"{v:g}"))
    a1.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    a1.set_ylabel("TCP deviation from the planned path [µm], log scale")
    a1.set_title(
        f"(a) predicted TCP position error; values below {floor:g} µm (and 0) drawn at {floor:g} µm", loc="left"
    )
    a1.grid(alpha=0.3, which="major")
    a1.grid(alpha=0.12, which="minor")
    handles, labels = a1.get_legend_handles_labels()
    order = sorted(range(len(handles)), key=lambda i: labels[i] == "at rest")  # the cases, then rest
    fig.legend(
        [handles[i] for i in order],
        [labels[i] for i in order],
        loc="upper center",
        ncol=2,
        bbox_to_anchor=(0.5, 0.905),
        frameon=False,
    )
    a2.plot(t, np.asarray(speed_m_s, float), color="k", lw=1.3, label="planned TCP speed")
    a2.set_ylim(bottom=0.0)
    a2.set_ylabel("TCP speed [m/s]")
    a2.set_xlabel("time [s]")
    a2.set_title("(b) planned TCP speed", y=0.82, loc="left", x=0.01, fontsize=8.5)
    a2.grid(alpha=0.3)
    if len(t) > 1:
        a2.set_xlim(float(t[0]), float(t[-1]))
    fig.suptitle(title)
    return fig
