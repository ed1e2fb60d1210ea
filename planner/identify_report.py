"""Report of ``compplan identify``: ``report.json``, ``report.md`` and ``report.html``.

The JSON holds every figure of the identification (see ``docs/identification.md``,
section "Report"); the Markdown and HTML say the same for people, the HTML with
embedded figures (PNG, base64, matplotlib's Agg backend): residual histograms
before and after, the cross-validated RMS at each selection step, and the
residual against the diagnostic variables (the one that shows unexplained
structure first).  Files are written through :class:`planner.output.OutputSet`
(all or nothing).  Lengths in the report are in mm (names end in ``_mm``).
"""

from __future__ import annotations

import base64
import html
import io
import itertools
from pathlib import Path
from typing import Any

import numpy as np

from planner.output import OutputSet
from problems.identify import Diagnostic, IdentificationResult

#: Diagnostic variables drawn in the HTML report (the strongest first).
REPORT_DIAGNOSTIC_PLOTS = 4
#: Bins of the binned-mean curves in the diagnostic plots.
REPORT_BINS = 12


def _mm(v: float | None) -> float | None:
    return None if v is None else float(v) * 1e3


def report_dict(res: IdentificationResult, model_path: str | None = None,
                data_path: str | None = None) -> dict[str, Any]:
    """The content of ``report.json`` (SI inside the library, mm in the report)."""
    m = res.data
    hist = []
    for st in res.history:
        hist.append({
            "step": st.index, "effects": st.effects, "n_params": st.n_params,
            "rms_mm": _mm(st.rms_m), "cv_rms_mm": _mm(st.cv_rms_m), "bic": st.bic,
            "n_excluded": st.n_excluded, "accepted": st.accepted, "reason": st.reason,
            "candidates": [{
                "effect": c.effect, "n_params": c.n_params, "cv_rms_mm": _mm(c.cv_rms_m),
                "rms_mm": _mm(c.rms_m), "bic": c.bic, "delta_bic": c.delta_bic, "f_pvalue": c.f_pvalue,
                "explained_share": c.explained_share, "refined": c.refined, "accepted": c.accepted,
                "reason": c.reason, "held": c.held} for c in st.candidates],
        })
    out: dict[str, Any] = {
        "status": res.status.value,
        "reason": res.reason,
        "rms_before_mm": res.rms_before_mm,
        "rms_after_mm": res.rms_after_mm,
        "heldout_rms_before_mm": _mm(res.cv_rms_before_m),
        "heldout_rms_after_mm": _mm(res.cv_rms_after_m),
        "rms_definition": ("per-axis RMS sqrt(mean over rows and x, y, z of r^2), r = predicted - measured, "
                           "inlier rows; 'before': nominal robot file with only the registration and the "
                           "measured point fitted; 'heldout': K-fold cross-validation over whole poses"),
        "noise_sigma_mm": _mm(res.noise_sigma_m),
        "noise_source": res.noise_source,
        "effects_added": list(res.effects_added),
        "unexplained": res.unexplained,
        "excluded_rows": res.excluded,
        "parameters": [{"name": p.name, "effect": p.effect, "value": p.value, "std": p.std, "unit": p.unit,
                        "status": p.status, "reason": p.reason} for p in res.parameters],
        "identifiability": res.identifiability,
        "diagnostics": [{"variable": d.variable, "explained_fraction": d.explained_fraction,
                         "p_value": d.p_value, "significant": d.significant, "description": d.description}
                        for d in res.diagnostics],
        "history": hist,
        "notes": res.notes,
        "data": {"file": data_path or m.source, "n_rows": m.n, "n_poses": res.identifiability.get("n_poses"),
                 "registered": res.model.registered, "columns": sorted(m.units)},
        "model_file": model_path,
    }
    if res.validation is not None:
        out["validation"] = res.validation
    if res.compensation_check is not None:
        out["compensation_check"] = res.compensation_check
    return out


# ----------------------------------------------------------------------------------
# Figures
# ----------------------------------------------------------------------------------

def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def _figures(res: IdentificationResult) -> dict[str, str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs: dict[str, str] = {}
    inl = res.inliers
    nb = np.linalg.norm(res.residual_before[inl], axis=1) * 1e3
    na = np.linalg.norm(res.residual_after[inl], axis=1) * 1e3
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.2))
    ax[0].hist(nb, bins=40, color="tab:red", alpha=0.8)
    ax[0].set_title(f"before: RMS {res.rms_before_mm:.4g} mm (per axis)")
    ax[0].set_xlabel("|residual| (mm)")
    ax[1].hist(na, bins=40, color="tab:green", alpha=0.8)
    ax[1].set_title(f"after: RMS {res.rms_after_mm:.4g} mm (per axis)")
    ax[1].set_xlabel("|residual| (mm)")
    figs["histograms"] = _png(fig)

    steps = [st for st in res.history]
    if steps:
        fig, ax = plt.subplots(figsize=(7, 3.2))
        labels = ["nominal", "declared"]
        for prev, st in itertools.pairwise(steps):
            labels.append(f"+{prev.accepted}" if prev.accepted else
                          ("backward" if st.reason.startswith("backward") else ""))
        cv = [res.cv_rms_before_m * 1e3] + [st.cv_rms_m * 1e3 for st in steps]
        ins = [res.rms_before_mm] + [st.rms_m * 1e3 for st in steps]
        xs = range(len(cv))
        ax.plot(xs, cv, "o-", label="held-out (CV) RMS")
        ax.plot(xs, ins, "s--", label="in-sample RMS")
        if res.noise_sigma_m:
            ax.axhline(res.noise_sigma_m * 1e3, color="k", lw=0.8, ls=":", label="noise floor")
        ax.set_xticks(list(xs))
        ax.set_xticklabels(labels[:len(cv)], fontsize=7, rotation=20)
        ax.set_ylabel("RMS per axis (mm)")
        if max(cv) > 5 * min(cv):
            ax.set_yscale("log")
        ax.legend(fontsize=7)
        ax.set_title("selection history (label: effect added at that step)")
        figs["history"] = _png(fig)

    diags = [d for d in res.diagnostics if d.x is not None]
    want = res.unexplained.get("variable")
    diags.sort(key=lambda d: (d.variable != want, -d.explained_fraction))
    for d in diags[:REPORT_DIAGNOSTIC_PLOTS]:
        figs[f"diag_{d.variable}"] = _diag_png(res, d)
    return figs


def _diag_png(res: IdentificationResult, d: Diagnostic) -> str:
    import matplotlib.pyplot as plt

    if d.y is not None:
        R = np.asarray(d.y, dtype=float)[:, None] * 1e3
        names = [d.y_label]
        colours: tuple[str, ...] = ("tab:purple",)
    else:
        R = res.residual_after[res.inliers] * 1e3
        names = [f"r_{c}" for c in "xyz"]
        colours = ("tab:red", "tab:green", "tab:blue")
    x = np.asarray(d.x, dtype=float)
    fig, ax = plt.subplots(figsize=(7, 3.2))
    for k, (c, lab) in enumerate(zip(colours, names)):
        ax.plot(x, R[:, k], ".", ms=2.5, color=c, alpha=0.35, label=lab)
    if d.variable != "pose" and np.ptp(x) > 0:
        edges = np.quantile(x, np.linspace(0, 1, REPORT_BINS + 1))
        edges = np.unique(edges)
        if len(edges) > 2:
            idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
            centres = 0.5 * (edges[:-1] + edges[1:])
            for k, c in enumerate(colours):
                means = np.array([R[idx == b, k].mean() if np.any(idx == b) else np.nan
                                  for b in range(len(edges) - 1)])
                ax.plot(centres, means, "-", color=c, lw=2)
    ax.set_xlabel(d.variable)
    ax.set_ylabel(d.y_label if d.y is not None else "residual (mm), measurement frame")
    flag = "significant structure" if d.significant else "no significant structure"
    ax.set_title(f"residual vs {d.variable}: CV explained {100 * d.explained_fraction:.0f} % "
                 f"(p = {d.p_value:.2g}, {flag})", fontsize=9)
    ax.legend(fontsize=7, markerscale=3)
    return _png(fig)


# ----------------------------------------------------------------------------------
# Markdown and HTML
# ----------------------------------------------------------------------------------

def _fmt(v: Any, nd: int = 4) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{nd}g}"
    return str(v)


def report_markdown(rep: dict[str, Any]) -> str:
    """Markdown rendering of :func:`report_dict`."""
    L = ["# Identification report", "",
         f"- status: **{rep['status']}** — {rep['reason']}",
         (f"- data: `{rep['data']['file']}`, {rep['data']['n_rows']} rows, {rep['data']['n_poses']} poses, "
          f"registered: {rep['data']['registered']}"),
         (f"- RMS before: **{_fmt(rep['rms_before_mm'])} mm**, after: **{_fmt(rep['rms_after_mm'])} mm** "
          f"(held-out: {_fmt(rep['heldout_rms_before_mm'])} -> {_fmt(rep['heldout_rms_after_mm'])} mm)"),
         f"- noise floor: {_fmt(rep['noise_sigma_mm'])} mm ({rep['noise_source']})",
         f"- effects added (in order): {', '.join(rep['effects_added']) or 'none'}",
         f"- RMS definition: {rep['rms_definition']}", ""]
    u = rep["unexplained"]
    L += ["## Unexplained structure", "",
          (f"**Present.** {u.get('message')}" if u.get("present") else f"None: {u.get('message')}"), ""]
    if rep.get("compensation_check"):
        c = rep["compensation_check"]
        L += ["## Compensation re-measured on the virtual robot", "",
              (f"- {c['n_poses']} new poses; TCP error RMS before {_fmt(c['rms_before_mm'])} mm, after "
               f"{_fmt(c['rms_after_mm'])} mm ({_fmt(100 * c['fraction_left'], 3)} % left); measurement frame: "
               f"{_fmt(c['meas_frame_rms_before_mm'])} -> {_fmt(c['meas_frame_rms_after_mm'])} mm "
               f"({_fmt(100 * c['meas_frame_fraction_left'], 3)} % left)"), f"- {c['metric']}", ""]
    if rep.get("validation"):
        v = rep["validation"]
        L += ["## Validation file", "", (f"- `{v['file']}`: {v['n_rows']} rows, RMS {_fmt(v['rms_mm'])} mm "
                                          f"(nominal model: {_fmt(v.get('rms_nominal_mm'))} mm)"), ""]
    L += ["## Selection history", "", "| step | effects | CV RMS (mm) | RMS (mm) | excluded | decision |",
          "|---|---|---|---|---|---|"]
    for h in rep["history"]:
        L.append(f"| {h['step']} | {', '.join(h['effects']) or '(declared)'} | {_fmt(h['cv_rms_mm'])} | "
                 f"{_fmt(h['rms_mm'])} | {h['n_excluded']} | {h['reason']} |")
    for h in rep["history"]:
        if not h["candidates"]:
            continue
        L += ["", f"### Step {h['step']} candidates", "",
              "| effect | new params | CV RMS (mm) | dBIC | F-test p | share | accepted | reason |",
              "|---|---|---|---|---|---|---|---|"]
        for c in sorted(h["candidates"], key=lambda c: (c["cv_rms_mm"] is None, c["cv_rms_mm"] or 0)):
            L.append(f"| {c['effect']} | {c['n_params']} | {_fmt(c['cv_rms_mm'])} | {_fmt(c['delta_bic'], 3)} | "
                     f"{_fmt(c['f_pvalue'], 2)} | {_fmt(c['explained_share'], 2)} | {c['accepted']} | "
                     f"{c['reason']} |")
    L += ["", "## Parameters (SI units)", "", "| name | value | std | unit | status | note |", "|---|---|---|---|---|---|"]
    for p in rep["parameters"]:
        L.append(f"| {p['name']} | {_fmt(p['value'], 6)} | {_fmt(p['std'], 3)} | {p['unit']} | {p['status']} | "
                 f"{p['reason']} |")
    idf = rep["identifiability"]
    L += ["", "## Identifiability", "",
          f"- rank {idf['rank']}, condition number (column-normalised) {_fmt(idf['condition_number'], 3)}",
          f"- saturated library model: {idf.get('saturated_model')}", ""]
    L += ["## Excluded rows (outliers)", ""]
    if rep["excluded_rows"]:
        L += ["| row | file line | |residual| (mm) |", "|---|---|---|"]
        for e in rep["excluded_rows"]:
            L.append(f"| {e['row']} | {e['line']} | {_fmt(e['residual_mm'])} |")
    else:
        L.append("none")
    L += ["", "## Diagnostics of the final residual", "",
          "| variable | CV explained fraction | p-value | significant |", "|---|---|---|---|"]
    for d in rep["diagnostics"]:
        L.append(f"| {d['variable']} | {_fmt(d['explained_fraction'], 3)} | {_fmt(d['p_value'], 2)} | "
                 f"{d['significant']} |")
    if rep["notes"]:
        L += ["", "## Notes", ""] + [f"- {n}" for n in rep["notes"]]
    return "\n".join(L) + "\n"


def report_html(rep: dict[str, Any], figs: dict[str, str]) -> str:
    """Self-contained HTML: the Markdown content as preformatted sections plus figures."""
    md = report_markdown(rep)
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>compplan identification report</title>",
             ("<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
              "font-size:12px}td,th{border:1px solid #ccc;padding:2px 5px}pre{white-space:pre-wrap}</style>"),
             "</head><body>"]
    sections = md.split("\n## ")
    parts.append(_md_block(sections[0]))
    order = ["histograms", "history"] + [k for k in figs if k.startswith("diag_")]
    parts.append("<h2>Figures</h2>")
    for k in order:
        if k in figs:
            parts.append(f"<div><img alt='{html.escape(k)}' src='data:image/png;base64,{figs[k]}'/></div>")
    for sec in sections[1:]:
        parts.append(_md_block("## " + sec))
    parts.append("</body></html>")
    return "\n".join(parts)


def _md_block(text: str) -> str:
    """Tiny Markdown subset -> HTML (headings, bullet lists, pipe tables, paragraphs)."""
    out: list[str] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        ln = lines[i]
        if ln.startswith("#"):
            lvl = len(ln) - len(ln.lstrip("#"))
            out.append(f"<h{lvl}>{html.escape(ln[lvl:].strip())}</h{lvl}>")
        elif ln.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                if not set(lines[i].replace("|", "").strip()) <= set("-"):
                    rows.append([html.escape(c.strip()) for c in lines[i].strip().strip("|").split("|")])
                i += 1
            if rows:
                out.append("<table><tr>" + "".join(f"<th>{c}</th>" for c in rows[0]) + "</tr>"
                           + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows[1:])
                           + "</table>")
            continue
        elif ln.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{html.escape(lines[i][2:]).replace('**', '')}</li>")
                i += 1
            out.append("<ul>" + "".join(items) + "</ul>")
            continue
        elif ln.strip():
            out.append(f"<p>{html.escape(ln).replace('**', '')}</p>")
        i += 1
    return "\n".join(out)


def write_report(res: IdentificationResult, folder: str | Path, model_path: str | None = None,
                 data_path: str | None = None) -> dict[str, Any]:
    """Write ``report.json``, ``report.md`` and ``report.html`` to ``folder`` (all or nothing)."""
    rep = report_dict(res, model_path, data_path)
    out = OutputSet(folder)
    out.add_json("report.json", rep)
    out.add_bytes("report.md", report_markdown(rep).encode())
    out.add_bytes("report.html", report_html(rep, _figures(res)).encode())
    out.publish()
    return rep
