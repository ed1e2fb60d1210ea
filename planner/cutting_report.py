"""The outputs of ``compplan cutting fit``: ``coefficients.toml``, ``fit.json`` and ``report.html``.

* ``coefficients.toml``: a ``[material]`` table (the six coefficients in SI, ``name``, ``source``)
  ready to paste into a problem file.
* ``fit.json``: the coefficients and their standard errors, R^2 and RMS residual per axis, every
  test's measured, fitted and residual wrench, the status, the condition number, the provenance.
* ``report.html``: one figure (mean Fx, Fy, Fz against the feed per tooth: the measured points and
  the fitted lines of each engagement), the coefficients +- 2 sigma, the tests' residuals.

The three are built in memory and published together (:class:`planner.output.OutputSet`): the
folder holds all three new files or is left as it was.
"""

from __future__ import annotations

import base64
import dataclasses
import datetime as _dt
import html
from pathlib import Path
from typing import Any

import numpy as np

from models.cutting.cutter import EndMill
from planner.output import OutputSet
from planner.provenance import input_file, invocation, version
from problems.cutting.coefficient_fit import AXES, COEFFICIENT_NAMES, COEFFICIENT_UNITS, CoefficientFit
from problems.cutting.force_data import ForceTest

__all__ = ["CUTTING_FIT_FILES", "cutting_fit_outputs", "material_toml", "source_text"]

#: The files ``compplan cutting fit`` writes into its folder (a folder holding only these is its own
#: earlier output).
CUTTING_FIT_FILES = ("coefficients.toml", "fit.json", "report.html")
#: Units of the wrench components.
AXIS_UNITS = ("N", "N", "N", "N·m", "N·m", "N·m")
#: Figure size (inches) and resolution.
FIGURE_SIZE_IN = (10.0, 3.4)
FIGURE_DPI = 110
#: Points of each fitted line (a straight line: two would do; more keep the dashes even).
LINE_POINTS = 2


def source_text(data_path: str | Path, today: _dt.date | None = None) -> str:
    """``"fitted from FILE on DATE"`` (the file's name, the UTC date)."""
    day = today or _dt.datetime.now(_dt.UTC).date()
    return f"fitted from {Path(data_path).name} on {day.isoformat()}"


def _toml_float(v: float) -> str:
    """A TOML float of 6 significant digits (always with a '.' or an exponent)."""
    return repr(float(f"{v:.6g}"))


def material_toml(fit: CoefficientFit, name: str, source: str) -> str:
    """The ``[material]`` table of a complete fit (SI; a comment gives each +- 2 sigma)."""
    import tomli_w  # the strings; the numbers are written by hand to carry their comments

    lines = [
        "# Mechanistic cutting coefficients fitted by `compplan cutting fit` (docs/cutting.md).",
        "# Paste the [material] table into a problem file.  SI units: N/m^2 (K.c) and N/m (K.e).",
        f"# status: {fit.status.value}{' (' + fit.reason + ')' if fit.reason else ''}",
        "[material]",
        tomli_w.dumps({"name": name, "source": source}).rstrip("\n"),
    ]
    for n, v, s, u in zip(COEFFICIENT_NAMES, fit.values, fit.std_errors, COEFFICIENT_UNITS):
        sigma = f"  # +- {2.0 * s:.3g} {u} (2 sigma)" if np.isfinite(s) else f"  # {u}"
        lines.append(f"{n} = {_toml_float(v)}{sigma}")
    return "\n".join(lines) + "\n"


def _test_record(t: ForceTest, measured: np.ndarray, fitted: np.ndarray, resid: np.ndarray) -> dict[str, Any]:
    def wrench(w: np.ndarray) -> dict[str, float | None]:
        return {
            f"{a}_{u.replace('·', '')}": (float(x) if np.isfinite(x) else None) for a, u, x in zip(AXES, AXIS_UNITS, w)
        }

    return {
        "label": t.label,
        "line": t.line,
        "feed_per_tooth_mm": t.feed_per_tooth_m * 1e3,
        "axial_depth_mm": t.axial_depth_m * 1e3,
        "radial_width_mm": None if t.radial_width_m is None else t.radial_width_m * 1e3,
        "milling": t.milling.value,
        "spindle": t.spindle.value,
        "measured": wrench(measured),
        "fitted": wrench(fitted),
        "residual": wrench(resid),
    }


def fit_record(fit: CoefficientFit, mill: EndMill, data_path: str, cutter_path: str, name: str) -> dict[str, Any]:
    """What ``fit.json`` holds."""
    rms = fit.rms()
    return {
        "status": fit.status.value,
        "reason": fit.reason,
        "notes": list(fit.notes),
        "material": name,
        "coefficients": {
            n: {"value": v, "std_error": s, "unit": u, "identified": bool(ok)}
            for n, v, s, u, ok in zip(COEFFICIENT_NAMES, fit.values, fit.std_errors, COEFFICIENT_UNITS, fit.identified)
        },
        "axes": {
            a: {"r_squared": r, "rms_residual": e, "unit": u}
            for a, r, e, u in zip(AXES, fit.r_squared, rms, AXIS_UNITS)
        },
        "condition_number": fit.condition_number,
        "rank": fit.rank,
        "n_rows": fit.n_rows,
        "dof": fit.dof,
        "cutter": {k: (v.value if hasattr(v, "value") else v) for k, v in dataclasses.asdict(mill).items()},
        "tests": [
            _test_record(t, fit.measured[i], fit.fitted[i], fit.residuals[i]) for i, t in enumerate(fit.table.tests)
        ],
        "provenance": {
            "compplan_version": version(),
            **invocation(),
            "inputs": [input_file("measured forces", data_path), input_file("cutter", cutter_path)],
        },
    }


def _groups(tests: tuple[ForceTest, ...]) -> dict[tuple, list[int]]:
    """Tests of one engagement (depth, width, milling, spindle) by key, in file order."""
    out: dict[tuple, list[int]] = {}
    for i, t in enumerate(tests):
        key = (t.axial_depth_m, t.radial_width_m, t.milling, t.spindle)
        out.setdefault(key, []).append(i)
    return out


def _group_label(t: ForceTest) -> str:
    width = "" if t.radial_width_m is None else f", ae {t.radial_width_m * 1e3:g} mm"
    ccw = ", ccw" if t.spindle.value == "ccw" else ""
    return f"{t.milling.value}, ap {t.axial_depth_m * 1e3:g} mm{width}{ccw}"


def figure_png(fit: CoefficientFit, mill: EndMill) -> bytes:
    """Mean Fx, Fy, Fz against the feed per tooth: measured points, fitted lines (from feed 0, so
    the intercept, the edge force, shows) per engagement."""
    from planner.report.figure_base import new_figure, png_bytes
    from problems.cutting.coefficient_fit import design_of_tests

    fig = new_figure(*FIGURE_SIZE_IN, left=0.07, right=0.99, bottom=0.15, top=0.80, wspace=0.3)
    axes = [fig.add_subplot(1, 3, k + 1) for k in range(3)]
    tests = fit.table.tests
    top = max(t.feed_per_tooth_m for t in tests) * 1e3 * 1.05
    for g, (_, idx) in enumerate(_groups(tests).items()):
        colour = f"C{g % 10}"
        t0 = tests[idx[0]]
        D = design_of_tests(mill, [t0], fit.table.where)[0]
        cut, edge = D[:3, :3] @ fit.values[:3] / t0.feed_per_tooth_m, D[:3, 3:] @ fit.values[3:]
        c_mm = np.linspace(0.0, top, LINE_POINTS)
        for k, ax in enumerate(axes):
            ax.plot(c_mm, edge[k] + cut[k] * c_mm * 1e-3, "-", color=colour, lw=1.2)
            feeds = [tests[i].feed_per_tooth_m * 1e3 for i in idx]
            ax.plot(feeds, fit.measured[idx, k], "o", color=colour, ms=4, label=_group_label(t0) if k == 0 else None)
    for k, ax in enumerate(axes):
        ax.set_title(f"mean {AXES[k]} on the tool")
        ax.set_xlabel("feed per tooth c [mm]")
        ax.set_ylabel(f"{AXES[k]} [N]")
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle("Measured mean forces (points) and the fitted model (lines)", fontsize=10)
    return png_bytes(fig, FIGURE_DPI)


def _td(text: str) -> str:
    return f"<td>{html.escape(text)}</td>"


def _fmt(v: float, spec: str = ".4g") -> str:
    return "–" if not np.isfinite(v) else format(v, spec)


def report_html(fit: CoefficientFit, mill: EndMill, data_path: str, name: str, png: bytes) -> str:
    """The report page: status, figure, coefficient table (+- 2 sigma), per-axis fit, tests."""
    rows = "".join(
        f"<tr>{_td(n)}{_td(_fmt(v))}{_td(_fmt(2 * s, '.3g'))}{_td(u)}</tr>"
        for n, v, s, u in zip(COEFFICIENT_NAMES, fit.values, fit.std_errors, COEFFICIENT_UNITS)
    )
    rms = fit.rms()
    axes = "".join(
        f"<tr>{_td(a)}{_td(_fmt(r, '.4f'))}{_td(_fmt(e, '.3g'))}{_td(u)}</tr>"
        for a, r, e, u in zip(AXES, fit.r_squared, rms, AXIS_UNITS)
        if np.isfinite(e)
    )
    tests = "".join(
        "<tr>"
        + _td(t.label)
        + _td(f"{t.feed_per_tooth_m * 1e3:g}")
        + _td(_group_label(t))
        + "".join(_td(_fmt(fit.measured[i, k], ".2f")) + _td(_fmt(fit.residuals[i, k], ".2f")) for k in range(3))
        + "</tr>"
        for i, t in enumerate(fit.table.tests)
    )
    status = fit.status.value + (f": {fit.reason}" if fit.reason else "")
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in fit.notes)
    cutter = (
        f"{mill.shape.value} end mill, D {mill.diameter_m * 1e3:g} mm, "
        f"corner radius {mill.corner_radius_m * 1e3:g} mm, "
        f"{mill.flutes} flutes, helix {np.degrees(mill.helix_rad):g} deg"
    )
    png64 = base64.b64encode(png).decode("ascii")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Cutting coefficients: {html.escape(name)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:1em auto}}table{{border-collapse:collapse}}
td,th{{border:1px solid #bbb;padding:2px 8px;text-align:right}}td:first-child{{text-align:left}}</style></head>
<body><h1>Cutting coefficients: {html.escape(name)}</h1>
<p>Data: {html.escape(str(data_path))} ({fit.table.n} tests). Cutter: {html.escape(cutter)}.</p>
<p><b>Status: {html.escape(status)}</b>. Condition number (column-scaled design) {_fmt(fit.condition_number, ".3g")};
{fit.n_rows} measured components, {fit.dof} degrees of freedom.</p>{f"<ul>{notes}</ul>" if notes else ""}
<h2>Figure 1. Mean forces against the feed per tooth</h2>
<img alt="mean Fx, Fy, Fz against the feed per tooth, measured and fitted" src="data:image/png;base64,{png64}">
<p>Points: the measured mean forces on the tool (feed frame); lines: the fitted model for each engagement,
drawn from feed 0 (the intercept is the edge force).</p>
<h2>Coefficients</h2>
<table><tr><th>coefficient</th><th>value</th><th>± 2σ</th><th>unit</th></tr>{rows}</table>
<h2>Fit per axis</h2>
<table><tr><th>axis</th><th>R²</th><th>RMS residual</th><th>unit</th></tr>{axes}</table>
<h2>Tests (N; residual = measured − fitted)</h2>
<table><tr><th>test</th><th>c [mm]</th><th>engagement</th><th>Fx</th><th>res.</th><th>Fy</th><th>res.</th>
<th>Fz</th><th>res.</th></tr>{tests}</table>
</body></html>
"""


def cutting_fit_outputs(
    fit: CoefficientFit, mill: EndMill, folder: str | Path, data_path: str, cutter_path: str, name: str
) -> OutputSet:
    """The three files of a complete fit, as an output set to publish into ``folder``."""
    out = OutputSet(folder)
    out.add_bytes("coefficients.toml", material_toml(fit, name, source_text(data_path)).encode())
    out.add_json("fit.json", fit_record(fit, mill, data_path, cutter_path, name))
    png = figure_png(fit, mill)
    out.add_bytes("report.html", report_html(fit, mill, data_path, name, png).encode())
    return out
