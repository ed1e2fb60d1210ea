"""The figure base of compplan's three reports (the plan's, the placement study's, the
identification's): a matplotlib Figure on the Agg canvas (no pyplot state, no display) and its PNG
and PDF bytes with fixed metadata, so the same figure always gives the same bytes.

The plan and placement reports draw and save under :data:`STYLE` at :data:`PNG_DPI`; the
identification report saves at its own resolution without a style.  matplotlib is imported when a
figure is made, not with this module.
"""

from __future__ import annotations

import contextlib
import functools
import io
from typing import Any
from collections.abc import Callable, Mapping

__all__ = [
    "PNG_COMPRESS_LEVEL",
    "PNG_DPI",
    "STYLE",
    "new_figure",
    "pdf_bytes",
    "png_bytes",
    "styled",
]

#: PNG resolution (dots per inch) of the plan and placement reports: modest, keeps the report small and fast.
PNG_DPI = 100
#: PNG compression level (zlib, 0-9) of the plan and placement reports: 6 is matplotlib's default;
#: 3 writes about twice as fast for files a few per cent larger.
PNG_COMPRESS_LEVEL = 3
#: Style applied while a figure of the plan and placement reports is built and saved (text sizes are
#: fixed at creation).  A fixed ``axes.titley`` spares matplotlib placing every axes title around the
#: tick labels above it (about a sixth of the drawing time; no panel here has decorations on top).
STYLE = {
    "pdf.compression": 3,
    "font.size": 9,
    "axes.titlesize": 9,
    "legend.fontsize": 8,
    "figure.titlesize": 10,
    "axes.titley": 1.0,
    "axes.titlepad": 5.0,
}
#: The PDF metadata left out (dates and software), so a PDF's bytes depend on its figure only.
PDF_METADATA = {"CreationDate": None, "Creator": None, "Producer": None}


def _style(style: Mapping[str, Any] | None) -> contextlib.AbstractContextManager[Any]:
    if style is None:
        return contextlib.nullcontext()
    import matplotlib

    return matplotlib.rc_context(style)


def styled(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Build the figure under :data:`STYLE` without touching the global rc settings."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with _style(STYLE):
            return fn(*args, **kwargs)

    return wrapper


def new_figure(width_in: float, height_in: float, **adjust: float) -> Any:
    """A matplotlib Figure of ``width_in`` x ``height_in`` inches on the Agg canvas, with fixed
    margins (``subplots_adjust`` keywords).

    Margins are set by hand rather than by the constrained-layout engine, which would double the
    drawing time (report generation has a time budget).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**adjust)
    return fig


def png_bytes(fig: Any, dpi: float, compress_level: int | None = None, style: Mapping[str, Any] | None = None) -> bytes:
    """PNG bytes of ``fig`` at ``dpi`` without software metadata (zlib ``compress_level``, default
    matplotlib's; under rc ``style`` when given)."""
    buf = io.BytesIO()
    extra = {} if compress_level is None else {"pil_kwargs": {"compress_level": compress_level}}
    with _style(style):
        fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None}, **extra)
    return buf.getvalue()


def pdf_bytes(fig: Any, style: Mapping[str, Any] | None = None) -> bytes:
    """PDF bytes of ``fig`` without dates or software (:data:`PDF_METADATA`; under rc ``style``
    when given)."""
    buf = io.BytesIO()
    with _style(style):
        fig.savefig(buf, format="pdf", metadata=PDF_METADATA)
    return buf.getvalue()
