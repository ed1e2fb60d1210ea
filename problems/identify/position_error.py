"""The position error of a model against measured points, as calibration results are quoted: the mean,
RMS and largest Euclidean distance ``|p_predicted - p_measured|`` over the rows (``compplan identify
--validation`` and ``compplan predict`` on measured rows; ``docs/identification.md``).

Not the per-axis RMS of the identification (``sqrt(mean over rows and x, y, z of r^2)``): the
Euclidean RMS is ``sqrt(3)`` times it for an isotropic residual.  SI inside; the ``*_mm`` dictionary
is for reports.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PositionErrors:
    """Euclidean position errors over rows.

    Attributes
    ----------
    n_rows : int
    mean_m, rms_m, max_m : float
        Mean, root mean square and largest ``|p_predicted - p_measured|``, m.
    max_line : int
        File line of the largest error (-1 without lines).
    frame : str
        Words for the frame both points are in (e.g. "measurement frame: the instrument's, with the
        identified registration").
    """

    n_rows: int
    mean_m: float
    rms_m: float
    max_m: float
    max_line: int
    frame: str

    def to_mm_dict(self) -> dict[str, Any]:
        """The figures in mm (report.json): ``n_rows``, ``mean_mm``, ``rms_mm``, ``max_mm``, ``max_line``, ``frame``."""
        return {
            "n_rows": self.n_rows,
            "mean_mm": self.mean_m * 1e3,
            "rms_mm": self.rms_m * 1e3,
            "max_mm": self.max_m * 1e3,
            "max_line": self.max_line,
            "frame": self.frame,
        }


def position_errors(
    predicted: np.ndarray, measured: np.ndarray, frame: str, lines: np.ndarray | None = None
) -> PositionErrors:
    """Mean, RMS and largest Euclidean error of ``predicted`` against ``measured`` ((N, 3), m, one frame).

    Rows with a non-finite coordinate are left out (``n_rows`` counts the others)."""
    d = np.linalg.norm(np.asarray(predicted, dtype=float) - np.asarray(measured, dtype=float), axis=1)
    ok = np.isfinite(d)
    if not ok.any():
        return PositionErrors(0, float("nan"), float("nan"), float("nan"), -1, frame)
    k = int(np.flatnonzero(ok)[np.argmax(d[ok])])
    return PositionErrors(
        n_rows=int(ok.sum()),
        mean_m=float(np.mean(d[ok])),
        rms_m=float(np.sqrt(np.mean(d[ok] ** 2))),
        max_m=float(d[k]),
        max_line=int(lines[k]) if lines is not None else -1,
        frame=frame,
    )


def frame_words(model: Any, campaign: str | None = None) -> str:
    """The frame a model's predictions are in, in words: the base frame for registered data, else the
    instrument's measurement frame with the registration identified (of ``campaign``, or the
    reference campaign's for a model of several campaigns)."""
    if getattr(model, "registered", False):
        return "base frame (the data declared registered: measurement frame = base frame)"
    names = model.campaign_names() if hasattr(model, "campaign_names") else []
    if campaign:
        whose = f"campaign '{campaign}''s identified registration"
    elif names and all(np.allclose(c.base2meas, model.base2meas(), atol=1e-12) for c in model.campaigns):
        whose = "the campaigns' shared identified registration"
    elif names:
        ref = _reference_name(model)
        whose = f"the reference campaign '{ref}''s identified registration" if ref else "the model's registration"
    else:
        whose = "the identified registration"
    return f"measurement frame (the instrument's, via {whose})"


def _reference_name(model: Any) -> str | None:
    """The campaign whose registration is the model's own (None when none matches)."""
    own = model.base2meas()
    for c in model.campaigns:
        if np.allclose(c.base2meas, own, rtol=0.0, atol=1e-12):
            return str(c.name)
    return None
