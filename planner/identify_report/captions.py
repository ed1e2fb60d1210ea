"""Titles and captions of the report's figures (:func:`figure_text`), their order (:func:`figure_order`)
and the file of each (``figures/<stem>.png|pdf``, :func:`figure_entries`): shared by the Markdown,
the HTML and ``report.json``."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from planner.identify_report.canvas import FIGURE_FOLDER, figure_file
from planner.identify_report.diagnostics import is_angle, var_name
from problems.identify.map_summary import MAP_BAND_SIGMAS

#: Figures of the report with a fixed text, in the order they are numbered: key -> (title, caption).
#: The diagnostic figures (``diag_<variable>``) follow them (:func:`figure_text`).
FIGURE_TEXT = {
    "error_maps": (
        "Joint error maps over the angle range of the data and beyond",
        "Each panel: the identified error of one joint (one component of its motion) against its "
        "commanded angle (deg), µrad for angles, µm for lengths; shaded, the uncertainty band of "
        f"±{MAP_BAND_SIGMAS:g} standard deviations from the fit's covariance; ticks at the bottom, the "
        "commanded angles of the measured rows; grey, beyond the range: the map continued (dashed), a "
        "function of the joint's angle everywhere; the model's sigma there also grows with the distance "
        "beyond the range.",
    ),
    "residuals": (
        "Residual per axis, before and after",
        "Histograms of predicted − measured per axis of the measurement frame (mm; µm where every residual is "
        "below 0.1 mm), inlier rows: top, "
        "the nominal model (registration and measured point fitted); bottom, the identified model.",
    ),
    "history": (
        "Selection history",
        "Per-axis RMS (mm) at each step of the selection: held-out (cross-validated over poses) and "
        "in-sample; the label names the effect added at that step.",
    ),
    "compensation": (
        "Compensation re-measured on the virtual robot",
        "RMS TCP error (mm) of new poses and loads before and after compensation with the identified "
        "model: left, in the measurement frame (the measured point against its target mapped by the "
        "identified registration: what an instrument checks, the figure to read); right, in the virtual "
        "robot's base frame (the TCP). With unregistered data the parameters that alias with the "
        "registration and the measured point are held at nominal: the base frame keeps their true values "
        "while the predictions in the measurement frame agree with the truth.",
    ),
}


def figure_text(key: str) -> tuple[str, str]:
    """(title, caption) of figure ``key``: :data:`FIGURE_TEXT`, or a diagnostic figure ``diag_<variable>``."""
    if key in FIGURE_TEXT:
        return FIGURE_TEXT[key]
    v = key[5:]
    if v.endswith(".xyz"):
        j = v[1]
        return (
            f"Residual per axis against joint {j} angle",
            f"The residual after identification (predicted − measured, one panel per axis of the measurement "
            f"frame) against the commanded angle of joint {j} in degrees (dots: rows; line: binned mean); "
            "each panel names the cross-validated share of that axis a smooth function of the angle explains.",
        )
    if is_angle(v):
        return (
            f"Equivalent error of joint {v[1]} against its angle",
            f"The residual after identification projected on joint {v[1]}'s column of the positional "
            f"Jacobian (the joint-{v[1]} error that would explain it) against the commanded angle in degrees "
            "(dots: rows; line: binned mean).",
        )
    return (
        f"Residual against {var_name(v)}",
        "The residual after identification against a diagnostic variable (dots: rows; line: binned mean); "
        "one panel per axis of the measurement frame, or the residual projected on the joint.",
    )


def figure_order(keys: Iterable[str]) -> list[str]:
    """The figure keys in the order they are numbered: those of :data:`FIGURE_TEXT` in its order,
    then the diagnostic figures as drawn."""
    keys = list(keys)
    return [k for k in FIGURE_TEXT if k in keys] + [k for k in keys if k not in FIGURE_TEXT]


def figure_entries(keys: Iterable[str]) -> list[dict[str, Any]]:
    """``report.json`` → ``figures``: per figure, in order, its key, number, title and files (paths
    relative to the report folder)."""
    out = []
    for n, k in enumerate(figure_order(keys), start=1):
        stem = f"{FIGURE_FOLDER}/{figure_file(k)}"
        out.append({"key": k, "number": n, "title": figure_text(k)[0], "png": f"{stem}.png", "pdf": f"{stem}.pdf"})
    return out
