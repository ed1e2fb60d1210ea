"""A plan's predicted cut as the run shows it: the ``cut`` block of ``summary.json``, the rows of
``cut.csv`` and the stock images of ``cut_stock.npz`` (:mod:`planner.record.columns`), from the
:class:`~planner.plan_result.PlanResult` in memory.  Prints nothing.
"""

from __future__ import annotations

import io
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from planner.record.columns import CUT_COLUMNS

if TYPE_CHECKING:
    from planner.plan_result import PlanResult

__all__ = ["cut_rows", "cut_stock_bytes", "cut_summary"]


def _norm_mm(result: Any, n: int) -> np.ndarray:
    """A compensation's or the stand-in comparison's TCP error norms (``error_norm_m``), mm; NaN without one."""
    return np.full(n, np.nan) if result is None else np.asarray(result.error_norm_m) * 1e3


def cut_rows(res: PlanResult) -> np.ndarray:
    """The rows of ``cut.csv`` (:data:`~planner.record.columns.CUT_COLUMNS`), one per waypoint."""
    c = res.problem.cut
    way = res.problem.program.waypoints
    W = np.asarray(c.wrench_program)
    cols = [
        way.line,
        W,
        np.linalg.norm(W[:, :3], axis=1),
        c.peak_force_N,
        c.axial_depth_m * 1e3,
        c.radial_width_m * 1e3,
        np.degrees(c.entry_rad),
        np.degrees(c.exit_rad),
        c.milling,
        c.feed_per_tooth_m * 1e3,
        c.spindle_rad_s * 60.0 / (2.0 * math.pi),
        _norm_mm(res.before, c.n),
        _norm_mm(res.exact, c.n),
        _norm_mm(res.cut_comparison, c.n),
    ]
    rows = np.column_stack(cols).astype(float)
    assert rows.shape[1] == len(CUT_COLUMNS)
    return rows


def cut_stock_bytes(res: PlanResult) -> bytes:
    """``cut_stock.npz``: the stock's top before and after, and the grid's extent."""
    c = res.problem.cut
    buf = io.BytesIO()
    np.savez_compressed(
        buf,
        before=np.asarray(c.heights_before, dtype=np.float32),
        after=np.asarray(c.heights_after, dtype=np.float32),
        extent=np.asarray(c.grid_extent_m, dtype=float),
    )
    return buf.getvalue()


def _stats(v: np.ndarray) -> dict[str, float]:
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return {"max": 0.0, "rms": 0.0}
    return {"max": float(v.max()), "rms": float(np.sqrt(np.mean(v**2)))}


def _range(v: np.ndarray, where: np.ndarray) -> dict[str, float] | None:
    """``{"min", "max"}`` of the positive values of ``v`` over the waypoints ``where`` (bool, shape of
    ``v``; a plunge has no horizontal feed per tooth); None for none."""
    v = np.asarray(v, dtype=float)[np.asarray(where, dtype=bool)]
    v = v[np.isfinite(v) & (v > 0.0)]
    return {"min": float(v.min()), "max": float(v.max())} if v.size else None


def cut_summary(res: PlanResult) -> dict[str, Any]:
    """The ``cut`` block of ``summary.json`` (units in the keys)."""
    from problems.cutting.prediction import MILLING_CODES

    pr = res.problem
    c, setup = pr.cut, pr.cut_setup
    way = pr.program.waypoints
    F = np.linalg.norm(np.asarray(c.wrench_program)[:, :3], axis=1)
    cutting = c.cutting()
    k = int(np.argmax(F)) if F.size else 0
    m = c.material
    out: dict[str, Any] = {
        "model": "mechanistic linear edge-force model (Altintas, Manufacturing Automation, 2nd ed., 2012, ch. 2)",
        "frame": "program frame; force on the tool, moment about the tool tip (the TCP); mean over a revolution",
        "cutter": c.mill.to_dict(),
        "material": {
            "name": m.name,
            "source": m.source,
            "Ktc_N_m2": m.Ktc,
            "Krc_N_m2": m.Krc,
            "Kac_N_m2": m.Kac,
            "Kte_N_m": m.Kte,
            "Kre_N_m": m.Kre,
            "Kae_N_m": m.Kae,
        },
        "stock": dict(setup.table["stock"]),
        "stock_volume_mm3": c.stock_volume_m3 * 1e9,
        "removed_mm3": c.removed_m3 * 1e9,
        "resolution_mm": float(c.extra.get("resolution_m", math.nan)) * 1e3,
        "samples": int(c.extra.get("samples", 0)),
        "cutting_waypoints": int(np.count_nonzero(cutting)),
        "milling_codes": [v.value for v in MILLING_CODES],
        "force_N": {
            "max": float(F.max()) if F.size else 0.0,
            "max_line": int(way.line[k]) if F.size else 0,
            "mean_cutting": float(F[cutting].mean()) if cutting.any() else 0.0,
            "peak_max": float(np.max(c.peak_force_N)) if c.n else 0.0,
        },
        "error_mm": {
            "uncompensated": _stats(_norm_mm(res.before, c.n)),
            "compensated": _stats(_norm_mm(res.exact, c.n)),
        },
        "spindle_rpm": _range(np.asarray(c.spindle_rad_s) * 60.0 / (2.0 * math.pi), cutting),
        "feed_per_tooth_mm": _range(np.asarray(c.feed_per_tooth_m) * 1e3, cutting),
        "warnings": list(c.warnings),
        "file": "cut.csv",
        "stock_file": "cut_stock.npz",
    }
    if res.cut_comparison is not None:
        out["stand_in"] = {
            "frame": c.stand_in_frame,
            "F_N": np.asarray(c.stand_in[:3]).tolist(),
            "M_Nm": np.asarray(c.stand_in[3:]).tolist(),
        }
        out["error_mm"]["stand_in_compensated"] = _stats(_norm_mm(res.cut_comparison, c.n))
    return out
