"""The figures' canvas: a matplotlib Figure on the Agg canvas (no pyplot state) and its base64 PNG."""

from __future__ import annotations

import base64
import io
from typing import Any

import numpy as np

#: PNG resolution of the identification figures (dots per inch).
REPORT_DPI = 90


def _figure(w: float, h: float, **adjust: float) -> Any:
    """A matplotlib Figure on the Agg canvas (no pyplot state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)
    if adjust:
        fig.subplots_adjust(**adjust)
    return fig


def _png(fig: Any) -> str:
    """Base64 PNG of a figure."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=REPORT_DPI, metadata={"Software": None})
    return base64.b64encode(buf.getvalue()).decode()


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.asarray(v, float) ** 2))) if np.size(v) else float("nan")
