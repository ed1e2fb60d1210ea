"""The figures' canvas: a matplotlib Figure on the Agg canvas (no pyplot state), rendered to PNG and
PDF bytes (:class:`RenderedFigure`: the report embeds the PNG and writes both beside it)."""

from __future__ import annotations

import base64
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

#: PNG resolution of the identification figures (dots per inch).
REPORT_DPI = 90
#: Folder of the report's figure files, relative to the report folder (as the plan report's).
FIGURE_FOLDER = "figures"


@dataclass(frozen=True)
class RenderedFigure:
    """One figure of the report as files: ``png`` (embedded in the HTML, written as
    ``figures/<name>.png``) and ``pdf`` (vector, ``figures/<name>.pdf``)."""

    png: bytes
    pdf: bytes

    @property
    def b64(self) -> str:
        """The PNG as base64 text (the HTML's ``data:`` URL)."""
        return base64.b64encode(self.png).decode("ascii")


def figure_file(key: str) -> str:
    """The file stem of figure ``key`` (``diag_q3.xyz`` -> ``diag_q3_xyz``): letters, digits, ``_``
    and ``-`` only, so a link to it needs no escaping."""
    return re.sub(r"[^A-Za-z0-9_-]+", "_", key)


def render_figure(fig: Any) -> RenderedFigure:
    """PNG and PDF bytes of a figure (metadata fixed, so the same figure gives the same bytes)."""
    from planner.report.figure_base import pdf_bytes, png_bytes

    return RenderedFigure(png_bytes(fig, REPORT_DPI), pdf_bytes(fig))


def rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.asarray(v, float) ** 2))) if np.size(v) else float("nan")
