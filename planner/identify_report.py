"""Report of ``compplan identify``: ``report.json``, ``report.md`` and ``report.html``.

The JSON holds every figure of the identification (see ``docs/identification.md``,
section "Report"), opened by a ``headline`` (status, RMS before/after in-sample and
held-out, noise floor, effects added, the structure left -- "weak structure remains"
when a significant but small one does -- the joint error maps, and the compensation
check in one sentence that says what it can and cannot show) and a ``provenance``
block (compplan version, command line, date, input files with SHA-256).  The
Markdown and HTML say the same for people, the HTML styled like the plan report
(headline table first, then the joint error maps when the model has any: a table of
their harmonics and sizes at the TCP and a figure of each map over its angle range
with its band) with embedded figures (PNG, base64, matplotlib's Agg canvas, no
pyplot): the residuals per axis before and after, the cross-validated RMS at each
selection step, the compensation re-measured on the virtual robot (base and
measurement frame), and the residual against the diagnostic variables (the one
that shows unexplained structure first, then the significant ones; joint angles in
degrees).  Every axis names its unit.
Files are written through :class:`planner.output.OutputSet` (all or nothing).
Lengths in the report are in mm (names end in ``_mm``).  Nothing here prints.
"""

from __future__ import annotations

import base64
import html
import io
import itertools
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from planner.numbers import format_number
from planner.output import OutputSet
from planner.provenance import builtin_robot_file, input_file, provenance
from problems.identify import Diagnostic, IdentificationResult
from problems.identify.map_summary import MAP_BAND_SIGMAS

#: Diagnostic figures drawn in the HTML report (the one behind the unexplained structure first,
#: then the significant ones, then the strongest others; the per-axis diagnostics of one joint
#: share a figure).
REPORT_DIAGNOSTIC_PLOTS = 4
#: Diagnostics listed in the report's table besides the significant ones (the strongest first).
REPORT_DIAGNOSTIC_ROWS = 5
#: Bins of the binned-mean curves in the diagnostic plots.
REPORT_BINS = 12
#: Joint-angle plots use finer bins, up to this many (about 20 rows each), so the binned mean
#: follows harmonics of several cycles per revolution.
REPORT_ANGLE_BINS_MAX = 48
#: Joint error maps drawn (panels of one figure; the largest RMS at the TCP when there are more).
REPORT_MAP_PANELS = 6
#: Harmonics of a map listed in the tables (the largest first; every one is in ``report.json``).
REPORT_MAP_HARMONICS = 3
#: Components of a joint error map (``models.effects.joint_error_map.MAP_COMPONENTS``):
#: symbol and words.
MAP_COMPONENT_WORDS = {"theta": ("θ", "angular positioning error"),
                       "d": ("d", "axial error (along the joint axis)"),
                       "a": ("a", "radial error (along the link's x axis)"),
                       "alpha": ("α", "tilt about the link's x axis"),
                       "beta": ("β", "tilt about the link's y axis")}
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
                   # joint angles: SI (rad) in the library, drawn in degrees
                   **{f"q{j}": (f"joint {j} angle (error of joint {j})", "deg") for j in range(1, 7)},
                   **{f"q{j}.{a}": (f"joint {j} angle (residual {a})", "deg") for j in range(1, 7) for a in "xyz"}}
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
                "reason": c.reason, "detail": getattr(c, "detail", "") or "", "held": c.held}
                for c in st.candidates],
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
        "error_maps": [s.to_dict() for s in getattr(res, "error_maps", None) or []],
        "unexplained": {**res.unexplained, "weak": bool(res.unexplained.get("weak", False))},
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


def structure_sentence(rep: dict[str, Any]) -> str:
    """The structure left in the residual in one sentence: "no structure ...", "weak structure
    remains ..." (significant but small: the status stays OK) or "structure remains ..."."""
    u = rep.get("unexplained") or {}
    msg = str(u.get("message") or "").strip()
    if not u.get("present"):
        return msg if msg.startswith("no ") else "no structure left" + (f": {msg}" if msg else "")
    if u.get("weak"):
        return msg if msg.startswith("weak structure remains") else "weak structure remains" + (
            f": {msg}" if msg else "")
    return msg if msg.startswith("structure remains") else "structure remains" + (f": {msg}" if msg else "")


def _structure_value(rep: dict[str, Any]) -> str:
    """The short value of the headline's structure row."""
    u = rep.get("unexplained") or {}
    if not u.get("present"):
        return "none"
    return "weak structure remains" if u.get("weak") else "structure remains"


def _map_name(m: dict[str, Any]) -> str:
    """``joint 1 θ`` for a map of :func:`report_dict`."""
    return f"joint {m['joint']} {MAP_COMPONENT_WORDS.get(m['component'], (m['component'], ''))[0]}"


def _headline(rep: dict[str, Any]) -> dict[str, Any]:
    """What an engineer reads first: status, RMS before/after, noise floor, effects, structure left,
    joint error maps, compensation."""
    def r4(v: float | None) -> float | None:
        from planner.numbers import round_sig
        return None if v is None else round_sig(float(v))
    maps = [{"joint": m["joint"], "component": m["component"],
             "main_freq_cpr": r4(m["harmonics"][0]["freq_cpr"]) if m["harmonics"] else None,
             "rms_tcp_um": r4(m["rms_tcp_um"])} for m in rep.get("error_maps") or []]
    return {"status": rep["status"], "reason": rep["reason"],
            "rms_before_mm": r4(rep["rms_before_mm"]), "rms_after_mm": r4(rep["rms_after_mm"]),
            "heldout_rms_before_mm": r4(rep["heldout_rms_before_mm"]),
            "heldout_rms_after_mm": r4(rep["heldout_rms_after_mm"]),
            "noise_sigma_mm": r4(rep["noise_sigma_mm"]), "noise_source": rep["noise_source"],
            "effects_added": list(rep["effects_added"]), "registered": bool(rep["data"]["registered"]),
            "unexplained": structure_sentence(rep),
            "error_maps": maps,
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
        if getattr(res, "error_maps", None):
            figs["error_maps"] = _maps_png(res)
        figs["residuals"] = _residual_png(res)
        if res.history:
            figs["history"] = _history_png(res)
        if res.compensation_check is not None:
            figs["compensation"] = _compensation_png(res, rep or {})
        for key, group in _diag_groups(res):
            figs[f"diag_{key}"] = _axes_png(res, group) if key.endswith(".xyz") else _diag_png(res, group[0])
    return figs


def _axis_diag(variable: str) -> tuple[int, str] | None:
    """(joint, axis) of a per-axis joint-angle diagnostic ``q3.x``, else None."""
    m = re.fullmatch(r"q([1-6])\.([xyz])", variable)
    return (int(m.group(1)), m.group(2)) if m else None


def _is_angle(variable: str) -> bool:
    """Whether a diagnostic variable is a joint angle (rad inside, drawn in degrees)."""
    return re.fullmatch(r"q[1-6](\.[xyz])?", variable) is not None


def _diag_groups(res: IdentificationResult) -> list[tuple[str, list[Diagnostic]]]:
    """The diagnostic figures to draw, at most :data:`REPORT_DIAGNOSTIC_PLOTS`: the variable behind
    the unexplained structure first, then the significant ones, then the strongest others, each by
    explained fraction.  The per-axis diagnostics of one joint (``q3.x``, ``q3.y``, ``q3.z``) share
    one figure (key ``q3.xyz``, one panel per axis)."""
    diags = [d for d in res.diagnostics if d.x is not None]
    want = res.unexplained.get("variable")
    diags.sort(key=lambda d: (d.variable != want, not d.significant, -d.explained_fraction))
    groups: dict[str, list[Diagnostic]] = {}
    for d in diags:
        ax = _axis_diag(d.variable)
        key = f"q{ax[0]}.xyz" if ax else d.variable
        if key in groups:
            groups[key].append(d)
        elif len(groups) < REPORT_DIAGNOSTIC_PLOTS:
            groups[key] = [d]
    return list(groups.items())


def _shown_diagnostics(diags: list[dict[str, Any]]) -> tuple[list[dict[str, Any]], int]:
    """The diagnostics the report's table lists (every significant one, then the
    :data:`REPORT_DIAGNOSTIC_ROWS` strongest others) and how many others it leaves out."""
    sig = [d for d in diags if d["significant"]]
    rest = sorted((d for d in diags if not d["significant"]), key=lambda d: -(d["explained_fraction"] or 0.0))
    return sig + rest[:REPORT_DIAGNOSTIC_ROWS], max(len(rest) - REPORT_DIAGNOSTIC_ROWS, 0)


def _maps_drawn(maps: list[Any]) -> list[Any]:
    """The maps drawn: all, or the :data:`REPORT_MAP_PANELS` largest at the TCP, in table order."""
    if len(maps) <= REPORT_MAP_PANELS:
        return list(maps)
    keep = sorted(range(len(maps)), key=lambda i: -float(maps[i].rms_tcp_m))[:REPORT_MAP_PANELS]
    return [maps[i] for i in sorted(keep)]


def _maps_png(res: IdentificationResult) -> str:
    """The joint error maps over their angle ranges (one panel per map): the map, its band, the
    commanded angles of the data, and the map held at its end values beyond the range."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    maps_all = list(res.error_maps)
    maps = _maps_drawn(maps_all)
    k = len(maps)
    ncols = min(3, k)
    nrows = math.ceil(k / ncols)
    spare = nrows * ncols > k                  # an empty slot holds the legend
    # inches: panels 2.3 high, 1.05 between rows (x label and a two-line title), 1.15 on top
    # (figure title and the first titles), 0.55 below (x label) and 0.35 more for a legend there
    w = 3.9 * ncols + 0.5 if ncols > 1 else 7.5
    title = ["Joint error maps: the error of each joint against its commanded angle, over the angle range of "
             "the data"]
    if w < 10:                                 # one or two panels: the title on two lines
        title = ["Joint error maps: the error of each joint against its commanded angle,",
                 "over the angle range of the data"]
    if k < len(maps_all):
        title.append(f"{k} of {len(maps_all)} maps drawn (the largest RMS at the TCP); every map is in the table")
    panel, gap, top, bottom = 2.3, 1.05, 0.75 + 0.2 * len(title), 0.55 + (0.0 if spare else 0.35)
    h = nrows * panel + (nrows - 1) * gap + top + bottom
    fig = _figure(w, h, left=0.75 / w, right=1 - 0.3 / w, top=1 - top / h, bottom=bottom / h,
                  wspace=0.3, hspace=gap / panel)
    axs = np.atleast_1d(fig.subplots(nrows, ncols)).ravel()
    q_data = np.asarray(res.data.q, dtype=float)[np.asarray(res.inliers, dtype=bool)]
    for ax, m in zip(axs, maps):
        sym, words = MAP_COMPONENT_WORDS.get(m.component, (m.component, ""))
        unit = "µrad" if m.unit == "rad" else "µm"
        x = np.degrees(np.asarray(m.q_rad, dtype=float))
        y = np.asarray(m.value, dtype=float) * 1e6
        b = np.nan_to_num(np.asarray(m.band, dtype=float)) * 1e6
        lo, hi = (float(np.degrees(v)) for v in m.range_rad)
        pad = max(0.08 * (hi - lo), 4.0)
        ax.fill_between(x, y - b, y + b, color="tab:blue", alpha=0.22, lw=0)
        ax.plot(x, y, "-", color="tab:blue", lw=1.4)
        for xa, xb, v in ((lo - pad, lo, y[0]), (hi, hi + pad, y[-1])):
            ax.axvspan(xa, xb, color="0.88", lw=0)
            ax.plot([xa, xb], [v, v], "--", color="tab:blue", lw=1.1)
        if len(q_data):
            ax.plot(np.degrees(q_data[:, m.joint - 1]), np.zeros(len(q_data)), "|", ms=6, color="0.35",
                    alpha=0.5, transform=ax.get_xaxis_transform())
        ax.set_xlim(lo - pad, hi + pad)
        y_lo, y_hi = float(np.min(y - b)), float(np.max(y + b))
        span = max(y_hi - y_lo, 1e-9)
        ax.set_ylim(y_lo - 0.16 * span, y_hi + 0.06 * span)       # room for the ticks of the data
        ax.axhline(0.0, color="0.4", lw=0.6)
        freqs = ", ".join(format_number(hm.freq_cpr, 3) for hm in m.harmonics[:REPORT_MAP_HARMONICS])
        more = f" (+{len(m.harmonics) - REPORT_MAP_HARMONICS})" if len(m.harmonics) > REPORT_MAP_HARMONICS else ""
        ax.set_title(f"joint {m.joint} {sym}: {words}\n{freqs}{more} cycles/rev, "
                     f"{format_number(m.rms_tcp_m * 1e6, 3)} µm RMS at the TCP")
        ax.set_xlabel(f"commanded angle q{m.joint} [deg]")
        ax.set_ylabel(f"{sym} error of joint {m.joint} [{unit}]")
        ax.grid(alpha=0.3)
    br = "\n" if spare else " "           # the legend in a spare panel is narrow: two-line labels
    handles = [Line2D([], [], color="tab:blue", lw=1.4, label="identified map"),
               Patch(color="tab:blue", alpha=0.22, label=f"uncertainty band ±{MAP_BAND_SIGMAS:g}σ{br}"
                     f"({MAP_BAND_SIGMAS:g} standard deviations)"),
               Line2D([], [], color="tab:blue", lw=1.1, ls="--", label=f"beyond the range (grey): held at{br}"
                      "the end value, not extrapolated"),
               Line2D([], [], color="0.35", ls="none", marker="|", ms=6, label="commanded angles of the data")]
    for ax in axs[k:]:
        ax.axis("off")
    if spare:
        axs[k].legend(handles=handles, loc="center", frameon=False, fontsize=9)
    else:
        fig.legend(handles=handles, loc="lower center", ncol=4 if w > 9 else 2, frameon=False,
                   bbox_to_anchor=(0.5, 0.0))
    fig.suptitle("\n".join(title))
    return _png(fig)


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


def _length_scale(R: np.ndarray) -> tuple[str, float]:
    """Unit and factor from metres for residuals drawn: µm when every value is below 0.1 mm."""
    small = bool(np.max(np.abs(np.nan_to_num(R)), initial=0.0) < RESIDUAL_UM_BELOW_M)
    return ("µm", 1e6) if small else ("mm", 1e3)


def _bin_edges(x: np.ndarray, variable: str) -> np.ndarray:
    """Edges of the binned-mean curve (none for the pose index); joint angles get finer bins."""
    if variable == "pose" or np.ptp(x) <= 0:
        return np.array([])
    bins = max(REPORT_BINS, min(REPORT_ANGLE_BINS_MAX, len(x) // 20)) if _is_angle(variable) else REPORT_BINS
    return np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))


def _scatter_panel(ax: Any, x: np.ndarray, y: np.ndarray, edges: np.ndarray, colour: str) -> None:
    """Rows as dots and their binned mean, the zero line and the grid."""
    ax.plot(x, y, ".", ms=2.5, color=colour, alpha=0.35)
    if len(edges) > 2:
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
        centres = 0.5 * (edges[:-1] + edges[1:])
        means = np.array([y[idx == b].mean() if np.any(idx == b) else np.nan for b in range(len(edges) - 1)])
        ax.plot(centres, means, "-", color="k", lw=1.6, label="binned mean")
        ax.legend(loc="best")
    ax.axhline(0.0, color="0.4", lw=0.6)
    ax.grid(alpha=0.3)


def _x_of(d: Diagnostic) -> tuple[np.ndarray, str]:
    """The diagnostic's x for a plot and its axis label: joint angles in degrees."""
    x = np.asarray(d.x, dtype=float)
    if _is_angle(d.variable):
        return np.degrees(x), f"joint {d.variable[1]} angle q{d.variable[1]} [deg]"
    return x, f"{_var_name(d.variable)} [{VARIABLE_UNITS.get(d.variable, '-')}]"


def _diag_png(res: IdentificationResult, d: Diagnostic) -> str:
    """Residual (one panel per axis) or its projected joint error against a diagnostic variable."""
    if d.y is not None:
        y = np.asarray(d.y, dtype=float)
        label = re.sub(r"\s*\((m|µ|u)?rad\)\s*$", "", d.y_label or "projected residual")
        if "rad" in (d.y_label or ""):       # an equivalent joint error, rad: µrad when small
            unit, k = ("µrad", 1e6) if np.max(np.abs(np.nan_to_num(y)), initial=0.0) < 1e-4 else ("mrad", 1e3)
        else:
            unit, k = "-", 1.0
        R = y[:, None] * k
        names = [f"{label} [{unit}]"]
        titles = [label]
        colours: tuple[str, ...] = ("tab:purple",)
    else:
        Rm = res.residual_after[res.inliers]
        unit, k = _length_scale(Rm[:, :3])
        R = Rm * k
        names = [f"residual r_{c} [{unit}]" for c in "xyz"]
        titles = [f"{c} axis of the measurement frame" for c in "xyz"]
        colours = AXIS_COLOURS
    x, xlabel = _x_of(d)
    n = len(names)
    fig = _figure(3.7 * n + 0.6 if n > 1 else 7.0, 3.4, left=0.08 if n > 1 else 0.1, right=0.985,
                  bottom=0.16, top=0.76, wspace=0.3)
    axs = np.atleast_1d(fig.subplots(1, n))
    edges = _bin_edges(x, d.variable)
    for j, ax in enumerate(axs):
        _scatter_panel(ax, x, R[:, j], edges, colours[j])
        if n == 1 or j == n // 2:         # one x label under the middle panel: long names do not collide
            ax.set_xlabel(xlabel)
        ax.set_ylabel(names[j])
        ax.set_title(titles[j])
    flag = "significant structure" if d.significant else "no significant structure"
    fig.suptitle(f"Residual after identification against {_var_name(d.variable)}\ncross-validated explained share "
                 f"{100 * d.explained_fraction:.0f} % (p = {d.p_value:.2g}, {flag})")
    return _png(fig)


def _axes_png(res: IdentificationResult, group: list[Diagnostic]) -> str:
    """The residual per axis against one joint angle (the per-axis diagnostics ``q{j}.x/y/z``, one
    panel each, with its own explained share and significance)."""
    joint = _axis_diag(group[0].variable)[0]           # type: ignore[index]
    by_axis: dict[str, Diagnostic] = {}
    for d in res.diagnostics:
        ad = _axis_diag(d.variable)
        if ad is not None and ad[0] == joint:
            by_axis[ad[1]] = d
    Rm = np.asarray(res.residual_after, dtype=float)[res.inliers]
    x_rad = np.asarray(group[0].x, dtype=float)
    if len(Rm) != len(x_rad):                          # not the inlier rows: draw the tested y
        Rm = np.column_stack([np.asarray(by_axis[a].y if a in by_axis and by_axis[a].y is not None
                                         else np.full(len(x_rad), np.nan), dtype=float) for a in "xyz"])
    unit, k = _length_scale(Rm)
    x = np.degrees(x_rad)
    fig = _figure(11.7, 3.4, left=0.06, right=0.985, bottom=0.16, top=0.74, wspace=0.3)
    axs = fig.subplots(1, 3)
    edges = _bin_edges(x, group[0].variable)
    for i, (ax, a) in enumerate(zip(axs, "xyz")):
        _scatter_panel(ax, x, Rm[:, i] * k, edges, AXIS_COLOURS[i])
        d = by_axis.get(a)
        if d is None:
            ax.set_title(f"{a} axis")
        else:
            ax.set_title(f"{a} axis: {100 * d.explained_fraction:.0f} % explained, p = {d.p_value:.2g}"
                         + (" (significant)" if d.significant else ""))
        ax.set_xlabel(f"joint {joint} angle q{joint} [deg]")
        ax.set_ylabel(f"residual r_{a} = predicted − measured [{unit}]")
    sig = [a for a in "xyz" if a in by_axis and by_axis[a].significant]
    weighted = " (tested on the residual weighted by 1/σ)" if res.data.sigma is not None else ""
    fig.suptitle(f"Residual after identification per axis against joint {joint} angle alone{weighted}\n"
                 + (f"significant structure on {', '.join(sig)}" if sig else "no significant structure on any axis")
                 + " (cross-validated P-spline of each axis on the angle)")
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


def _setup_note(rep: dict[str, Any]) -> str:
    """What was known of the measurement set-up and what was identified."""
    known = (rep.get("identifiability") or {}).get("known")
    if known is None:
        known = "registration and measured point" if rep["data"]["registered"] else "nothing"
    if known == "registration and measured point":
        return "registered: the measurement frame is the base frame and the measured point the TCP"
    if known == "nothing":
        return "unregistered: the registration and the measured point are identified too"
    other = "measured point" if known == "registration" else "registration"
    return f"{known} declared known (held); the {other} is identified"


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
            ("structure left in the residual", _structure_value(rep),
             "as the status says" if structure_sentence(rep) == str(h["reason"]) else structure_sentence(rep)),
            ("data", f"{d['n_rows']} rows, {d['n_poses']} poses", _setup_note(rep)),
            ("compensation check", "re-measured" if rep.get("compensation_check") else "not run",
             str(h["compensation"]))]
    ori = (rep.get("identifiability") or {}).get("orientation")
    if ori:
        gained = ori.get("identifiable_thanks_to_orientation") or []
        rows.insert(3, ("orientation residual per axis, before → after (in-sample)",
                        f"{_fmt(ori['rms_before_rad'] * 1e6)} → {_fmt(ori['rms_after_rad'] * 1e6)} µrad",
                        f"{ori['n_rows']} orientation rows (rx, ry, rz); identifiable only thanks to them: "
                        + (", ".join(gained) if gained else "none")))
    maps = rep.get("error_maps") or []
    if maps:
        top = max(maps, key=lambda m: m["rms_tcp_um"] or 0.0)
        joints = sorted({m["joint"] for m in maps})
        rows.insert(5, ("joint error maps", f"{len(maps)} on joint{'s' if len(joints) > 1 else ''} "
                        f"{', '.join(map(str, joints))}",
                        f"largest at the TCP: {_map_name(top)} ({_harmonic_freqs(top)}), "
                        f"{format_number(top['rms_tcp_um'], 3)} µm RMS; see 'Joint error maps'"))
    return rows


def _harmonic_freqs(m: dict[str, Any]) -> str:
    """``13.56, 13.35 cycles/rev`` (the largest harmonics of a map)."""
    hs = m["harmonics"][:REPORT_MAP_HARMONICS]
    more = len(m["harmonics"]) - len(hs)
    return (", ".join(format_number(h["freq_cpr"], 4) for h in hs) + (f" (+{more} more)" if more else "")
            + " cycles/rev") if hs else "no harmonic"


def _harmonic_text(m: dict[str, Any], h: dict[str, Any]) -> str:
    """One harmonic of a map: frequency, amplitude ± std (µrad or µm), and at the TCP (µm)."""
    u, key = ("µrad", "urad") if m["unit"] == "rad" else ("µm", "um")
    amp, std = h.get(f"amplitude_{key}"), h.get(f"amplitude_std_{key}")
    pm = f" ± {format_number(std, 2)}" if std is not None and math.isfinite(std) else " (std n/a)"
    tcp = h.get("amplitude_tcp_um")
    # a length moves the TCP by itself (lever 1): its size at the TCP only when it differs
    same = m["unit"] != "rad" and tcp is not None and amp is not None and abs(tcp - amp) <= 0.01 * abs(amp)
    at_tcp = "" if tcp is None or same else f" → {format_number(tcp, 3)} µm at the TCP"
    return f"{format_number(h['freq_cpr'], 4)} cycles/rev: {format_number(amp, 3)}{pm} {u}{at_tcp}"


def _map_rows(rep: dict[str, Any]) -> list[tuple[str, ...]]:
    """(joint, component, angle range, dominant harmonics, RMS at the TCP) rows of the maps table."""
    rows = []
    for m in rep.get("error_maps") or []:
        sym, words = MAP_COMPONENT_WORDS.get(m["component"], (m["component"], ""))
        hs = m["harmonics"][:REPORT_MAP_HARMONICS]
        more = len(m["harmonics"]) - len(hs)
        harm = "; ".join(_harmonic_text(m, h) for h in hs) + (f"; +{more} smaller" if more else "")
        lo, hi = m["range_deg"]
        name = sym if sym == m["component"] else f"{sym} ({m['component']})"
        rows.append((str(m["joint"]), f"{name}: {words}",
                     f"{format_number(lo, 3)} … {format_number(hi, 3)}", harm or "-",
                     format_number(m["rms_tcp_um"], 3)))
    return rows


#: What the maps table says about itself (Markdown and HTML).
MAP_TABLE_NOTE = ("Each map is the error of one joint, one component of its motion, as a function of its own "
                  "commanded angle: a Fourier series in that angle with the harmonics (cycles per revolution of "
                  "the joint) the spectrum search found, largest first. Amplitude of a harmonic ± 1 standard "
                  "deviation (µrad for angles, µm for lengths); at the TCP: times the median lever of the "
                  "component over the data. RMS at the TCP: the map's effect over the measured poses. Beyond "
                  "the angle range of the data a map is held at its end value (not extrapolated).")


def _maps_markdown(rep: dict[str, Any]) -> list[str]:
    """The "Joint error maps" section (empty without maps)."""
    rows = _map_rows(rep)
    if not rows:
        return []
    L = ["## Joint error maps", "", MAP_TABLE_NOTE, "",
         "| joint | component | angle range (deg) | dominant harmonics | RMS at the TCP (µm) |",
         "|---|---|---|---|---|"]
    L += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in rows]
    n = len(rows)
    if n > REPORT_MAP_PANELS:
        L += ["", f"The figure draws the {REPORT_MAP_PANELS} maps with the largest RMS at the TCP; "
              f"{n - REPORT_MAP_PANELS} more are in the table and in report.json."]
    return L + [""]


def _unexplained_markdown(rep: dict[str, Any]) -> list[str]:
    """The "Unexplained structure" section: none, weak (status stays OK) or present."""
    u = rep["unexplained"]
    if not u.get("present"):
        text = f"None: {u.get('message')}"
    elif u.get("weak"):
        sentence = structure_sentence(rep)
        text = (f"{sentence[:1].upper()}{sentence[1:]}. It is significant but explains only a small share of the "
                f"residual, so the status stays {rep['status']}; the variable named is where to look if the "
                "accuracy matters.")
    else:
        text = f"**Present.** {u.get('message')}"
    return ["## Unexplained structure", "", text, ""]


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
    L += [f"| {q} | {_md_cell(v)} | {_md_cell(n)} |" for q, v, n in _headline_rows(rep)]
    L += ["", f"- data: `{rep['data']['file']}`, registered: {rep['data']['registered']}",
          f"- RMS definition: {rep['rms_definition']}", ""]
    L += _maps_markdown(rep)
    L += _unexplained_markdown(rep)
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
        cands = sorted(h["candidates"], key=lambda c: (c["cv_rms_mm"] is None, c["cv_rms_mm"] or 0))
        for c in cands:
            L.append(f"| {c['effect']} | {c['n_params']} | {_fmt(c['cv_rms_mm'])} | {_fmt(c['delta_bic'], 3)} | "
                     f"{_fmt(c['f_pvalue'], 2)} | {_fmt(c['explained_share'], 2)} | {c['accepted']} | "
                     f"{_md_cell(c['reason'])} |")
        details = [c for c in cands if c.get("detail")]
        if details:
            L += [""] + [f"- {c['effect']}: {c['detail']}" for c in details]
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
    shown, hidden = _shown_diagnostics(rep["diagnostics"])
    L += ["", "## Diagnostics of the final residual", "",
          "| variable | what | CV explained fraction | p-value | significant |", "|---|---|---|---|---|"]
    for d in shown:
        L.append(f"| {d['variable']} | {_md_cell(_var_name(d['variable']))} | {_fmt(d['explained_fraction'], 3)} | "
                 f"{_fmt(d['p_value'], 2)} | {d['significant']} |")
    if hidden:
        L += ["", f"{hidden} other diagnostic{'s' if hidden > 1 else ''} not shown (not significant, explaining "
              "less than those listed); every diagnostic is in report.json."]
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
    "error_maps": ("Joint error maps over the angle range of the data",
                   "Each panel: the identified error of one joint (one component of its motion) against its "
                   "commanded angle (deg), µrad for angles, µm for lengths; shaded, the uncertainty band of "
                   f"±{MAP_BAND_SIGMAS:g} standard deviations from the fit's covariance; ticks at the bottom, the "
                   "commanded angles of the measured rows; grey, beyond the range: there the map is held at its "
                   "end value (dashed), not extrapolated."),
    "compensation": ("Compensation re-measured on the virtual robot",
                     "RMS TCP error (mm) of new poses and loads before and after compensation with the identified "
                     "model: in the virtual robot's base frame (the TCP) and in the measurement frame (the "
                     "measured point against its target mapped by the identified registration). With "
                     "unregistered data the base frame is not checkable through the parameters that alias with "
                     "the registration: judge the measurement frame."),
}


def _diag_figure_text(key: str) -> tuple[str, str]:
    """(title, caption) of a diagnostic figure ``diag_<variable>``."""
    v = key[5:]
    if v.endswith(".xyz"):
        j = v[1]
        return (f"Residual per axis against joint {j} angle",
                f"The residual after identification (predicted − measured, one panel per axis of the measurement "
                f"frame) against the commanded angle of joint {j} in degrees (dots: rows; line: binned mean); "
                "each panel names the cross-validated share of that axis a smooth function of the angle explains.")
    if _is_angle(v):
        return (f"Equivalent error of joint {v[1]} against its angle",
                f"The residual after identification projected on joint {v[1]}'s column of the positional "
                f"Jacobian (the joint-{v[1]} error that would explain it) against the commanded angle in degrees "
                "(dots: rows; line: binned mean).")
    return (f"Residual against {_var_name(v)}",
            "The residual after identification against a diagnostic variable (dots: rows; line: binned mean); "
            "one panel per axis of the measurement frame, or the residual projected on the joint.")


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
             "Lengths in mm.</p>"]
    n = 0

    def figure(k: str) -> None:
        nonlocal n
        n += 1
        title, caption = FIGURE_TEXT.get(k) or _diag_figure_text(k)
        parts.append(f'<h3 id="{html.escape(k)}">Figure {n}. {html.escape(title)}</h3>'
                     f'<figure><img data-figure="{html.escape(k)}" alt="{html.escape(title)}" '
                     f'src="data:image/png;base64,{figs[k]}"><figcaption>{html.escape(caption)}</figcaption>'
                     "</figure>")
    maps_sec = next((sec for sec in sections[1:] if sec.startswith("Joint error maps")), None)
    if maps_sec is not None:              # what an engineer looks for when a map was added: near the top
        parts.append('<h2 id="error_maps">Joint error maps</h2>')
        parts.append(_md_block(maps_sec.split("\n", 1)[1]))
        if "error_maps" in figs:
            figure("error_maps")
    parts.append("<h2>Figures</h2>")
    for k in ["residuals", "history", "compensation"] + [k for k in figs if k.startswith("diag_")]:
        if k in figs:
            figure(k)
    for sec in sections[1:]:
        if sec.startswith("Provenance") or sec is maps_sec:
            continue
        parts.append(_md_block("## " + sec))
    parts.append('<h2 id="provenance">Provenance</h2>')
    parts.append(_html_table(["item", "value", "SHA-256"], _provenance_rows(rep), mono_cols=(1, 2)))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _md_cell(text: str) -> str:
    """Text for a Markdown table cell: its pipes escaped (``|f|`` stays one cell)."""
    return str(text).replace("|", "\\|")


def _md_cells(line: str) -> list[str]:
    """The cells of a Markdown table row (escaped pipes ``\\|`` are text)."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]


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
                    rows.append([html.escape(c) for c in _md_cells(lines[i])])
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
