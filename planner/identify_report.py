"""Report of ``compplan identify``: ``report.json``, ``report.md`` and ``report.html``.

The JSON holds every figure of the identification (see ``docs/identification.md``,
section "Report"), opened by a ``headline`` (status, RMS before/after in-sample and
held-out, noise floor, effects added, and the compensation check in one sentence
that says what it can and cannot show) and a ``provenance`` block (compplan
version, command line, date, input files with SHA-256).  The Markdown and HTML say
the same for people, the HTML styled like the plan report (headline table first)
with embedded figures (PNG, base64, matplotlib's Agg canvas, no pyplot): the
residuals per axis before and after, the cross-validated RMS at each selection
step, the compensation re-measured on the virtual robot (base and measurement
frame), and the residual against the diagnostic variables, one panel per axis
(the one that shows unexplained structure first).  Every axis names its unit.
Files are written through :class:`planner.output.OutputSet` (all or nothing).
Lengths in the report are in mm (names end in ``_mm``).  Nothing here prints.
"""

from __future__ import annotations

import base64
import html
import io
import itertools
from pathlib import Path
from typing import Any

import numpy as np

from planner.numbers import format_number
from planner.output import OutputSet
from planner.provenance import builtin_robot_file, input_file, provenance
from problems.identify import Diagnostic, IdentificationResult

#: Diagnostic variables drawn in the HTML report (the strongest first).
REPORT_DIAGNOSTIC_PLOTS = 4
#: Bins of the binned-mean curves in the diagnostic plots.
REPORT_BINS = 12
#: PNG resolution of the identification figures (dots per inch).
REPORT_DPI = 90
#: Names and units of the diagnostic variables (x axes and titles of the diagnostic figures).
VARIABLE_LABELS = {"time": ("time", "s, or row number without a t column"),
                   "load_magnitude": ("applied force |f|", "N"),
                   "load_sign": ("sign pattern of the force components", "-"),
                   "joint_torque": ("largest joint torque |τ_j| of the applied wrench", "N·m"),
                   "gravity_torque": ("nominal gravity torque of the joint that varies most", "N·m"),
                   "temperature": ("temperature", "°C"),
                   "position": ("horizontal distance of the nominal TCP from the base axis", "m"),
                   "pose": ("pose index", "-"),
                   **{f"q{j}": (f"joint angle q{j}", "rad") for j in range(1, 7)}}
#: Units of the diagnostic variables (kept for callers of the unit alone).
VARIABLE_UNITS = {k: u for k, (_name, u) in VARIABLE_LABELS.items()}
#: Axis colours (x, y, z), as in the plan report.
AXIS_COLOURS = ("tab:blue", "tab:orange", "tab:green")


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
    out["base_frame_aliases"] = _aliases(res)
    head = {"headline": _headline(out), "provenance": provenance(_inputs(res, data_path))}
    return {**head, **out}


def _aliases(res: IdentificationResult) -> list[str]:
    """Parameters an unregistered identification cannot tell from the registration or the
    measured point (held at nominal): the base frame is not checkable through them."""
    try:
        from problems.identify import unobservable_in_base
        return list(unobservable_in_base(res.model))
    except Exception:  # noqa: BLE001 - a description only
        return []


def _inputs(res: IdentificationResult, data_path: str | None) -> list[dict[str, Any]]:
    """Provenance inputs: the declared robot (its file when it is a built-in one unchanged), the
    measurement file and the validation file."""
    from models import load_robot
    nominal = res.model.nominal
    robot_file = builtin_robot_file(nominal.name)
    if robot_file is not None and load_robot(nominal.name).to_dict() != nominal.to_dict():
        robot_file = None
    entries = [input_file("declared robot", robot_file, name=nominal.name)]
    if robot_file is None:
        entries[0]["note"] = "a robot file of the user's (its path is the command line's --robot)"
    for role, f in (("measurements", data_path or res.data.source),
                    ("validation measurements", (res.validation or {}).get("file"))):
        if not f:
            continue
        path = Path(str(f))
        entries.append(input_file(role, path if path.is_file() else None, name=path.name or str(f)))
    return entries


def compensation_sentence(rep: dict[str, Any]) -> str:
    """The compensation check in one sentence that says what it shows and what it cannot."""
    c = rep.get("compensation_check")
    if not c:
        return ("compensation not re-measured (no --truth): the held-out RMS is the estimate of what the "
                "model predicts on new poses")
    meas = (f"measurement frame {format_number(c['meas_frame_rms_before_mm'])} → "
            f"{format_number(c['meas_frame_rms_after_mm'])} mm RMS "
            f"({format_number(100 * c['meas_frame_fraction_left'], 3)} % left)")
    aliases = rep.get("base_frame_aliases") or []
    if aliases and not rep["data"]["registered"]:
        return (f"base-frame error cannot be checked with unregistered data: {', '.join(aliases)} cannot be told "
                "apart from the registration or the measured point and are held at nominal, so the base-frame "
                f"result ({format_number(c['rms_before_mm'])} → {format_number(c['rms_after_mm'])} mm RMS on the "
                "virtual robot) reflects their true values, not the data; see the measurement-frame figure: "
                f"{meas}, {c['n_poses']} new poses")
    return (f"TCP error in the virtual robot's base frame {format_number(c['rms_before_mm'])} → "
            f"{format_number(c['rms_after_mm'])} mm RMS ({format_number(100 * c['fraction_left'], 3)} % left), "
            f"{meas}, {c['n_poses']} new poses")


def _headline(rep: dict[str, Any]) -> dict[str, Any]:
    """What an engineer reads first: status, RMS before/after, noise floor, effects, compensation."""
    def r4(v: float | None) -> float | None:
        from planner.numbers import round_sig
        return None if v is None else round_sig(float(v))
    return {"status": rep["status"], "reason": rep["reason"],
            "rms_before_mm": r4(rep["rms_before_mm"]), "rms_after_mm": r4(rep["rms_after_mm"]),
            "heldout_rms_before_mm": r4(rep["heldout_rms_before_mm"]),
            "heldout_rms_after_mm": r4(rep["heldout_rms_after_mm"]),
            "noise_sigma_mm": r4(rep["noise_sigma_mm"]), "noise_source": rep["noise_source"],
            "effects_added": list(rep["effects_added"]), "registered": bool(rep["data"]["registered"]),
            "compensation": compensation_sentence(rep),
            "definition": "per-axis RMS of predicted - measured, measurement frame, mm, 4 significant digits"}


# ----------------------------------------------------------------------------------
# Figures
# ----------------------------------------------------------------------------------

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


def _figures(res: IdentificationResult, rep: dict[str, Any] | None = None) -> dict[str, str]:
    """The report's figures as base64 PNGs: residuals per axis, selection history, compensation
    check, diagnostics."""
    import matplotlib

    figs: dict[str, str] = {}
    with matplotlib.rc_context({"font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8}):
        figs["residuals"] = _residual_png(res)
        if res.history:
            figs["history"] = _history_png(res)
        if res.compensation_check is not None:
            figs["compensation"] = _compensation_png(res, rep or {})
        diags = [d for d in res.diagnostics if d.x is not None]
        want = res.unexplained.get("variable")
        diags.sort(key=lambda d: (d.variable != want, -d.explained_fraction))
        for d in diags[:REPORT_DIAGNOSTIC_PLOTS]:
            figs[f"diag_{d.variable}"] = _diag_png(res, d)
    return figs


#: Residual histograms whose largest value is below this (m) are drawn in micrometres.
RESIDUAL_UM_BELOW_M = 1e-4


def _residual_png(res: IdentificationResult) -> str:
    """Histograms of the residual per axis (x, y, z), before (nominal) and after (identified)."""
    inl = res.inliers
    fig = _figure(11.0, 5.4, left=0.07, right=0.985, bottom=0.1, top=0.86, wspace=0.25, hspace=0.55)
    axs = fig.subplots(2, 3)
    for row, (name, R, colour) in enumerate((("before: nominal model", res.residual_before[inl], "tab:red"),
                                             ("after: identified model", res.residual_after[inl], "tab:green"))):
        # residuals below 0.1 mm are drawn in um, so the tick labels stay short and readable
        um = bool(np.max(np.abs(R[:, :3]), initial=0.0) < RESIDUAL_UM_BELOW_M)
        unit, k = ("µm", 1e6) if um else ("mm", 1e3)
        for j, ax_name in enumerate("xyz"):
            ax = axs[row, j]
            r = R[:, j] * k
            ax.hist(r, bins=40, color=colour, alpha=0.8)
            ax.axvline(0.0, color="0.3", lw=0.8)
            ax.set_title(f"{ax_name} axis, {name}: RMS {format_number(_rms(r))} {unit}")
            ax.set_xlabel(f"residual r_{ax_name} = predicted − measured [{unit}]")
            ax.set_ylabel("rows [count]")
            ax.grid(alpha=0.3)
    fig.suptitle(f"Residual per axis of the measurement frame, {int(np.count_nonzero(inl))} inlier rows "
                 f"(RMS per axis over x, y, z: before {format_number(res.rms_before_mm)} mm, after "
                 f"{format_number(res.rms_after_mm)} mm)")
    return _png(fig)


def _history_png(res: IdentificationResult) -> str:
    """Cross-validated and in-sample RMS at each selection step."""
    steps = list(res.history)
    fig = _figure(8.0, 3.8, left=0.1, right=0.98, bottom=0.24, top=0.88)
    ax = fig.subplots()
    labels = ["nominal", "declared"]
    for prev, st in itertools.pairwise(steps):
        labels.append(f"+{prev.accepted}" if prev.accepted else
                      ("backward" if st.reason.startswith("backward") else "(no change)"))
    cv = [res.cv_rms_before_m * 1e3] + [st.cv_rms_m * 1e3 for st in steps]
    ins = [res.rms_before_mm] + [st.rms_m * 1e3 for st in steps]
    xs = list(range(len(cv)))
    ax.plot(xs, cv, "o-", label="held-out (cross-validated) RMS")
    ax.plot(xs, ins, "s--", label="in-sample RMS")
    if res.noise_sigma_m:
        ax.axhline(res.noise_sigma_m * 1e3, color="k", lw=0.8, ls=":", label="noise floor")
    ax.set_xticks(xs, labels[:len(cv)], fontsize=8, rotation=20)
    ax.set_xlabel("selection step (effect added at that step)")
    ax.set_ylabel("RMS per axis [mm]" + (", log scale" if max(cv) > 5 * min(cv) else ""))
    if max(cv) > 5 * min(cv):
        import matplotlib.ticker as mt
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(mt.LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(mt.FuncFormatter(lambda v, _pos: f"{v:g}"))
        ax.yaxis.set_minor_formatter(mt.NullFormatter())
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    ax.set_title("Selection history")
    return _png(fig)


def _compensation_png(res: IdentificationResult, rep: dict[str, Any]) -> str:
    """The compensation re-measured on the virtual robot: RMS before/after, base frame and
    measurement frame (the base frame marked not checkable for unregistered data with aliases)."""
    c = res.compensation_check or {}
    aliases = rep.get("base_frame_aliases") or []
    blind = bool(aliases) and not res.model.registered
    fig = _figure(9.0, 3.8, left=0.08, right=0.98, bottom=0.14, top=0.8, wspace=0.3)
    axs = fig.subplots(1, 2)
    for ax, title, b, a, note in (
            (axs[0], "base frame of the virtual robot (TCP)", c.get("rms_before_mm"), c.get("rms_after_mm"),
             "not checkable with unregistered data:\nthe aliased parameters are held at nominal" if blind else ""),
            (axs[1], "measurement frame (measured point)", c.get("meas_frame_rms_before_mm"),
             c.get("meas_frame_rms_after_mm"), "")):
        vals = [float(b or 0.0), float(a or 0.0)]
        bars = ax.bar([0, 1], vals, color=["tab:red", "tab:green"], alpha=0.35 if note else 0.85,
                      hatch="//" if note else None)
        for rect, v in zip(bars, vals):
            ax.text(rect.get_x() + rect.get_width() / 2, v, f"{format_number(v)} mm", ha="center", va="bottom",
                    fontsize=8)
        ax.set_xticks([0, 1], ["before (command as is)", "after compensation"])
        ax.set_ylabel("TCP position error, RMS [mm]")
        ax.set_title(title)
        ax.set_ylim(0, max(vals + [1e-9]) * 1.2)
        ax.grid(alpha=0.3, axis="y")
        if note:
            ax.text(0.5, 0.55, note, transform=ax.transAxes, ha="center", va="center", fontsize=8,
                    bbox={"facecolor": "#fff4e0", "edgecolor": "#e0a030"})
    fig.suptitle(f"Compensation re-measured on the virtual robot: {c.get('n_poses', '?')} new poses and loads")
    return _png(fig)


def _var_name(variable: str) -> str:
    """The words for a diagnostic variable (its key when it has none)."""
    return VARIABLE_LABELS.get(variable, (variable, "-"))[0]


def _diag_png(res: IdentificationResult, d: Diagnostic) -> str:
    """Residual (one panel per axis) or its projected joint error against a diagnostic variable."""
    if d.y is not None:
        R = np.asarray(d.y, dtype=float)[:, None] * 1e3
        names = [d.y_label.replace("(mrad)", "[mrad]")]
        titles = [d.y_label.split(" (")[0]]
        colours: tuple[str, ...] = ("tab:purple",)
    else:
        R = res.residual_after[res.inliers] * 1e3
        names = [f"residual r_{c} [mm]" for c in "xyz"]
        titles = [f"{c} axis of the measurement frame" for c in "xyz"]
        colours = AXIS_COLOURS
    x = np.asarray(d.x, dtype=float)
    k = len(names)
    fig = _figure(3.7 * k + 0.6 if k > 1 else 7.0, 3.4, left=0.08 if k > 1 else 0.1, right=0.985,
                  bottom=0.16, top=0.76, wspace=0.3)
    axs = np.atleast_1d(fig.subplots(1, k))
    edges = np.unique(np.quantile(x, np.linspace(0, 1, REPORT_BINS + 1))) if d.variable != "pose" and \
        np.ptp(x) > 0 else np.array([])
    for j, ax in enumerate(axs):
        ax.plot(x, R[:, j], ".", ms=2.5, color=colours[j], alpha=0.35)
        if len(edges) > 2:
            idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
            centres = 0.5 * (edges[:-1] + edges[1:])
            means = np.array([R[idx == b, j].mean() if np.any(idx == b) else np.nan
                              for b in range(len(edges) - 1)])
            ax.plot(centres, means, "-", color="k", lw=1.6, label="binned mean")
            ax.legend(loc="best")
        ax.axhline(0.0, color="0.4", lw=0.6)
        ax.set_xlabel(f"{_var_name(d.variable)} [{VARIABLE_UNITS.get(d.variable, '-')}]")
        ax.set_ylabel(names[j])
        ax.set_title(titles[j])
        ax.grid(alpha=0.3)
    flag = "significant structure" if d.significant else "no significant structure"
    fig.suptitle(f"Residual after identification against {_var_name(d.variable)}\ncross-validated explained share "
                 f"{100 * d.explained_fraction:.0f} % (p = {d.p_value:.2g}, {flag})")
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


def _headline_rows(rep: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(quantity, value, note) rows of the headline table."""
    h = rep.get("headline") or _headline(rep)
    d = rep["data"]
    rows = [("status", str(h["status"]), str(h["reason"])),
            ("residual RMS per axis, before → after (in-sample)",
             f"{_fmt(h['rms_before_mm'])} → {_fmt(h['rms_after_mm'])} mm",
             "before: the nominal robot file with only the registration and the measured point fitted"),
            ("residual RMS per axis, before → after (held-out)",
             f"{_fmt(h['heldout_rms_before_mm'])} → {_fmt(h['heldout_rms_after_mm'])} mm",
             "cross-validated over whole poses: what the model predicts on poses it has not seen"),
            ("noise floor", "unknown" if h["noise_sigma_mm"] is None else f"{_fmt(h['noise_sigma_mm'])} mm",
             str(h["noise_source"])),
            ("effects added (in order)", ", ".join(h["effects_added"]) or "none", ""),
            ("data", f"{d['n_rows']} rows, {d['n_poses']} poses",
             "registered: the measurement frame is the base frame and the measured point the TCP"
             if d["registered"] else "unregistered: the registration and the measured point are identified too"),
            ("compensation check", "re-measured" if rep.get("compensation_check") else "not run",
             str(h["compensation"]))]
    return rows


def _provenance_rows(rep: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(item, value, SHA-256) rows of the provenance table."""
    p = rep.get("provenance") or {}
    rows = [("compplan version", str(p.get("compplan_version")), ""),
            ("command line", str(p.get("command_line") or "none: written by a library call"), ""),
            ("date (UTC, ISO 8601)", str(p.get("date_utc")), "")]
    for e in p.get("inputs") or []:
        name = f" '{e['name']}'" if e.get("name") else ""
        rows.append((f"input: {e.get('role')}{name}", str(e.get("path") or e.get("note") or "-"),
                     str(e.get("sha256") or "-")))
    if rep.get("model_file"):
        rows.append(("output: identified model", str(rep["model_file"]), ""))
    return rows


def report_markdown(rep: dict[str, Any]) -> str:
    """Markdown rendering of :func:`report_dict`: the headline table first."""
    L = ["# Identification report", "", "| quantity | value | note |", "|---|---|---|"]
    L += [f"| {q} | {v} | {n.replace('|', '/')} |" for q, v, n in _headline_rows(rep)]
    L += ["", f"- data: `{rep['data']['file']}`, registered: {rep['data']['registered']}",
          f"- RMS definition: {rep['rms_definition']}", ""]
    u = rep["unexplained"]
    L += ["## Unexplained structure", "",
          (f"**Present.** {u.get('message')}" if u.get("present") else f"None: {u.get('message')}"), ""]
    if rep.get("compensation_check"):
        c = rep["compensation_check"]
        L += ["## Compensation re-measured on the virtual robot", "",
              f"- {compensation_sentence(rep)}",
              (f"- base frame: RMS of the 3-D TCP position error in the true base frame of the virtual robot, "
               f"{_fmt(c['rms_before_mm'])} → {_fmt(c['rms_after_mm'])} mm "
               f"({_fmt(100 * c['fraction_left'], 3)} % left)"),
              (f"- measurement frame: the measured point against its nominal target mapped by the identified "
               f"registration (what a tracker checks), {_fmt(c['meas_frame_rms_before_mm'])} → "
               f"{_fmt(c['meas_frame_rms_after_mm'])} mm ({_fmt(100 * c['meas_frame_fraction_left'], 3)} % left)"),
              ""]
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
    L += ["", "## Provenance", "", "| item | value | SHA-256 |", "|---|---|---|"]
    L += [f"| {a} | {b} | {c} |" for a, b, c in _provenance_rows(rep)]
    return "\n".join(L) + "\n"


#: Figures of the HTML report, in order: key -> (title, caption).
FIGURE_TEXT = {
    "residuals": ("Residual per axis, before and after",
                  "Histograms of predicted − measured per axis of the measurement frame (mm; µm where every residual is below 0.1 mm), inlier rows: top, "
                  "the nominal model (registration and measured point fitted); bottom, the identified model."),
    "history": ("Selection history",
                "Per-axis RMS (mm) at each step of the selection: held-out (cross-validated over poses) and "
                "in-sample; the label names the effect added at that step."),
    "compensation": ("Compensation re-measured on the virtual robot",
                     "RMS TCP error (mm) of new poses and loads before and after compensation with the identified "
                     "model: in the virtual robot's base frame (the TCP) and in the measurement frame (the "
                     "measured point against its target mapped by the identified registration). With "
                     "unregistered data the base frame is not checkable through the parameters that alias with "
                     "the registration: judge the measurement frame."),
}


def _html_table(header: list[str], rows: list[tuple[str, ...]], css: str = "summary",
                mono_cols: tuple[int, ...] = ()) -> str:
    out = [f'<table class="{css}"><tr>' + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>"]
    mono = ' class="mono"'
    for r in rows:
        out.append("<tr>" + "".join(f"<td{mono if i in mono_cols else ''}>{html.escape(c)}</td>"
                                    for i, c in enumerate(r)) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def report_html(rep: dict[str, Any], figs: dict[str, str]) -> str:
    """Self-contained HTML, styled like the plan report: headline table, figures with captions,
    then the tables of the selection, parameters and diagnostics, and the provenance."""
    from planner.report.rendering import _CSS
    md = report_markdown(rep)
    sections = md.split("\n## ")
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>compplan identification report</title><style>{_CSS}</style></head><body>",
             "<h1>compplan identification report</h1>", '<h3 id="headline">Headline</h3>',
             _html_table(["quantity", "value", "note"], _headline_rows(rep), "summary headline"),
             f'<p class="note">Data: {html.escape(str(rep["data"]["file"]))}. {html.escape(rep["rms_definition"])}. '
             "Lengths in mm.</p>", "<h2>Figures</h2>"]
    order = ["residuals", "history", "compensation"] + [k for k in figs if k.startswith("diag_")]
    n = 0
    for k in order:
        if k not in figs:
            continue
        n += 1
        title, caption = FIGURE_TEXT.get(k, (f"Residual against {_var_name(k[5:])}",
                                             "The residual after identification against a diagnostic variable "
                                             "(dots: rows; line: binned mean); one panel per axis of the "
                                             "measurement frame, or the residual projected on the joint."))
        parts.append(f'<h3 id="{html.escape(k)}">Figure {n}. {html.escape(title)}</h3>'
                     f'<figure><img data-figure="{html.escape(k)}" alt="{html.escape(title)}" '
                     f'src="data:image/png;base64,{figs[k]}"><figcaption>{html.escape(caption)}</figcaption>'
                     "</figure>")
    for sec in sections[1:]:
        if sec.startswith("Provenance"):
            continue
        parts.append(_md_block("## " + sec))
    parts.append('<h2 id="provenance">Provenance</h2>')
    parts.append(_html_table(["item", "value", "SHA-256"], _provenance_rows(rep), mono_cols=(1, 2)))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


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
                out.append('<table class="summary"><tr>' + "".join(f"<th>{c}</th>" for c in rows[0]) + "</tr>"
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
    out.add_bytes("report.html", report_html(rep, _figures(res, rep)).encode())
    out.publish()
    return rep
