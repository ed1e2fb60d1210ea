"""``report.md``: :func:`report_markdown` of :func:`~planner.identify_report.data.report_dict`,
the headline table first (its rows and those of the provenance table are shared with the HTML)."""

from __future__ import annotations

from typing import Any

from planner.identify_report.captions import figure_text
from planner.identify_report.data import headline, structure_value, compensation_sentence, structure_sentence
from planner.identify_report.diagnostics import not_significant_line, shown_diagnostics, var_name
from planner.identify_report.maps import harmonic_freqs, map_name, maps_markdown
from planner.identify_report.text import fmt, md_cell
from planner.numbers import format_number


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


def _validation_rows(rep: dict[str, Any], h: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The headline's rows of the validation file (none without one): RMS, Euclidean error, 2-sigma coverage."""
    rows: list[tuple[str, str, str]] = []
    v = rep.get("validation")
    if v:
        rows.append(
            (
                "validation file RMS per axis, before → after",
                f"{fmt(h.get('validation_rms_before_mm'))} → {fmt(h.get('validation_rms_after_mm'))} mm",
                f"{v['n_rows']} rows of {v['file']}, "
                + ("never used in the fit" if h.get("validation_held_out") else "the --data file itself: not held out")
                + "; before: the nominal robot file with the identified registration and measured point",
            )
        )
        e = h.get("validation_euclidean_mm")
        if e:
            rows.append(
                (
                    "validation file Euclidean error mean / RMS / max, before → after",
                    " / ".join(f"{fmt(e['before'][q])} → {fmt(e['after'][q])}" for q in ("mean", "rms", "max")) + " mm",
                    f"|predicted − measured| per row, as calibration results are quoted; in the {v['frame']}",
                )
            )
        cov = h.get("validation_coverage_2sigma")
        if cov is not None:
            w = v.get("where_it_holds") or {}
            rows.append(
                (
                    "validation file 2σ coverage",
                    f"{100 * cov:.1f} % per axis",
                    "share of per-axis errors within twice the model's predicted σ (95 % expected); "
                    + (
                        f"{w['n_outside']} rows beyond the identified joint ranges: see 'Where the model holds'"
                        if w.get("joints")
                        else "every row inside the identified joint ranges"
                    ),
                )
            )
    return rows


def headline_rows(rep: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(quantity, value, note) rows of the headline table."""
    h = rep.get("headline") or headline(rep)
    d = rep["data"]
    rows = [("status", str(h["status"]), str(h["reason"]))]
    rows += _validation_rows(rep, h)
    rows += [
        (
            "residual RMS per axis, before → after (in-sample)",
            f"{fmt(h['rms_before_mm'])} → {fmt(h['rms_after_mm'])} mm",
            "before: the nominal robot file with only the registration and the measured point fitted",
        ),
        (
            "residual RMS per axis, before → after (held-out)",
            f"{fmt(h['heldout_rms_before_mm'])} → {fmt(h['heldout_rms_after_mm'])} mm",
            "cross-validated over whole poses: what the model predicts on poses it has not seen",
        ),
        (
            "noise floor",
            "unknown" if h["noise_sigma_mm"] is None else f"{fmt(h['noise_sigma_mm'])} mm",
            str(h["noise_source"]),
        ),
        ("effects added (in order)", ", ".join(h["effects_added"]) or "none", ""),
        (
            "structure left in the residual",
            structure_value(rep),
            "as the status says" if structure_sentence(rep) == str(h["reason"]) else structure_sentence(rep),
        ),
        ("data", f"{d['n_rows']} rows, {d['n_poses']} poses", _setup_note(rep)),
        _held_row(rep),
        ("compensation check", "re-measured" if rep.get("compensation_check") else "not run", str(h["compensation"])),
    ]
    ori = (rep.get("identifiability") or {}).get("orientation")
    names = [r[0] for r in rows]
    if ori:
        gained = ori.get("identifiable_thanks_to_orientation") or []
        rows.insert(
            names.index("residual RMS per axis, before → after (held-out)") + 1,
            (
                "orientation residual per axis, before → after (in-sample)",
                f"{fmt(ori['rms_before_rad'] * 1e6)} → {fmt(ori['rms_after_rad'] * 1e6)} µrad",
                f"{ori['n_rows']} orientation rows (rx, ry, rz); identifiable only thanks to them: "
                + (", ".join(gained) if gained else "none"),
            ),
        )
    maps = rep.get("error_maps") or []
    if maps:
        top = max(maps, key=lambda m: m["rms_tcp_um"] or 0.0)
        joints = sorted({m["joint"] for m in maps})
        rows.insert(
            [r[0] for r in rows].index("structure left in the residual"),
            (
                "joint error maps",
                f"{len(maps)} on joint{'s' if len(joints) > 1 else ''} {', '.join(map(str, joints))}",
                f"largest at the TCP: {map_name(top)} ({harmonic_freqs(top)}), "
                f"{format_number(top['rms_tcp_um'], 3)} µm RMS; see 'Joint error maps'",
            ),
        )
    return rows


def _held_row(rep: dict[str, Any]) -> tuple[str, str, str]:
    """The headline row of the held parameters: how many per group, and the one line of what they
    mean and what to do."""
    hp = rep.get("held_parameters") or {}
    groups = hp.get("groups") or []
    if not groups:
        return ("parameters held at nominal", "none", "the data determine every parameter of the model")
    words = {"setup_alias": "alias with the set-up", "redundant": "redundant", "undetermined": "undetermined"}
    value = f"{hp['count']}: " + ", ".join(f"{g['count']} {words.get(g['kind'], g['kind'])}" for g in groups)
    todo = [f"{words.get(g['kind'], g['kind'])}: {g['action']}" for g in groups if g["action"] != "none"]
    return ("parameters held at nominal", value, "; ".join(todo + ["see 'Held parameters'"]))


def _held_markdown(rep: dict[str, Any]) -> list[str]:
    """The "Held parameters" section: per group its parameters, what it means and what to do (each
    parameter's own reason is in the parameter table)."""
    groups = (rep.get("held_parameters") or {}).get("groups") or []
    if not groups:
        return []
    L = ["## Held parameters", "", "| parameters | what it means | what to do |", "|---|---|---|"]
    L += [f"| {md_cell(', '.join(g['names']))} | {md_cell(g['meaning'])} | {md_cell(g['action'])} |" for g in groups]
    return L + [""]


def _compensation_markdown(rep: dict[str, Any]) -> list[str]:
    """The "Compensation re-measured on the virtual robot" section: the sentence (the figure to read
    first, why the other differs), then both frames."""
    c = rep.get("compensation_check")
    if not c:
        return []
    aliases = rep.get("base_frame_aliases") or []
    alias_note = (
        f"; parameters held at nominal that alias with the registration and the measured point: {', '.join(aliases)}"
        if aliases and not rep["data"]["registered"]
        else ""
    )
    return [
        "## Compensation re-measured on the virtual robot",
        "",
        f"- {compensation_sentence(rep)}",
        (
            f"- measurement frame (read this): the measured point against its nominal target mapped by the identified "
            f"registration (what an instrument checks), {fmt(c['meas_frame_rms_before_mm'])} → "
            f"{fmt(c['meas_frame_rms_after_mm'])} mm ({fmt(100 * c['meas_frame_fraction_left'], 3)} % left)"
        ),
        (
            f"- base frame: RMS of the 3-D TCP position error in the true base frame of the virtual robot, "
            f"{fmt(c['rms_before_mm'])} → {fmt(c['rms_after_mm'])} mm "
            f"({fmt(100 * c['fraction_left'], 3)} % left){alias_note}"
        ),
        "",
    ]


def _figures_markdown(rep: dict[str, Any]) -> list[str]:
    """The "Figures" section: each figure file (``report.json`` → ``figures``), its caption and its PDF."""
    figs = rep.get("figures") or []
    if not figs:
        return []
    L = ["## Figures", ""]
    for f in figs:
        title, caption = figure_text(f["key"])
        L += [f"### Figure {f['number']}. {title}", "", f"![Figure {f['number']}. {title}]({f['png']})", ""]
        L += [f"{caption} ([PDF]({f['pdf']}))", ""]
    return L


def _unexplained_markdown(rep: dict[str, Any]) -> list[str]:
    """The "Unexplained structure" section: none, weak (status stays OK) or present."""
    u = rep["unexplained"]
    if not u.get("present"):
        text = f"None: {u.get('message')}"
    elif u.get("weak"):
        sentence = structure_sentence(rep)
        text = (
            f"{sentence[:1].upper()}{sentence[1:]}. It is significant but explains only a small share of the "
            f"residual, so the status stays {rep['status']}; the variable named is where to look if the "
            "accuracy matters."
        )
    else:
        text = f"**Present.** {u.get('message')}"
    return ["## Unexplained structure", "", text, ""]


def provenance_rows(rep: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(item, value, SHA-256) rows of the provenance table."""
    p = rep.get("provenance") or {}
    rows = [
        ("compplan version", str(p.get("compplan_version")), ""),
        ("command line", str(p.get("command_line") or "none: written by a library call"), ""),
        ("date (UTC, ISO 8601)", str(p.get("date_utc")), ""),
    ]
    for e in p.get("inputs") or []:
        name = f" '{e['name']}'" if e.get("name") else ""
        rows.append(
            (f"input: {e.get('role')}{name}", str(e.get("path") or e.get("note") or "-"), str(e.get("sha256") or "-"))
        )
    if rep.get("model_file"):
        rows.append(("output: identified model", str(rep["model_file"]), ""))
    return rows


def campaigns_text(rep: dict[str, Any]) -> str:
    """The campaigns of a several-campaign identification on one line: name, rows, RMS after and the
    registration's difference from the reference campaign's (mm, deg)."""
    camps = rep.get("campaigns") or []
    shared = "shared" in ((rep.get("identifiability") or {}).get("campaign_fit") or {})
    out = []
    for c in camps:
        rms = "" if c.get("rms_after_mm") is None else f", RMS after {c['rms_after_mm']:.4f} mm"
        where = (
            "shared frame"
            if shared
            else "reference: the model's registration"
            if c.get("reference")
            else f"registration {c['translation_from_reference_mm']:.3f} mm, "
            f"{c['rotation_from_reference_deg']:.4f} deg from the reference's"
        )
        out.append(f"{c['name']} ({c['n_rows']} rows{rms}; {where})")
    return "; ".join(out)


def _validation_markdown(rep: dict[str, Any]) -> list[str]:
    """The held-out validation file's section (none without one)."""
    if not rep.get("validation"):
        return []
    v = rep["validation"]
    out = [
        "## Validation file",
        "",
        (
            f"- `{v['file']}` (held out: never used in the fit): {v['n_rows']} rows, RMS per axis "
            f"{fmt(v.get('rms_nominal_mm'))} → {fmt(v['rms_mm'])} mm (nominal robot file with the identified "
            "registration and measured point → identified model)"
        ),
    ]
    e, e0 = v.get("euclidean"), v.get("euclidean_nominal")
    if e and e0:  # reports written before the Euclidean figures have none
        out.append(
            f"- Euclidean position error |predicted − measured| (as calibration results are quoted), nominal → "
            f"identified: mean {fmt(e0['mean_mm'])} → {fmt(e['mean_mm'])} mm, RMS {fmt(e0['rms_mm'])} → "
            f"{fmt(e['rms_mm'])} mm, max {fmt(e0['max_mm'])} → {fmt(e['max_mm'])} mm (line {e['max_line']}); "
            f"in the {e['frame']}"
        )
    return out + [""] + _holds_markdown(v.get("where_it_holds"))


def _holds_markdown(w: dict[str, Any] | None) -> list[str]:
    """Where the model holds: the validation rows by each joint's distance beyond its identified range."""
    if not w or not w.get("joints"):
        return []
    cov = w.get("coverage_2sigma")
    out = [
        "### Where the model holds",
        "",
        "The validation rows by how far each joint lies beyond the range the identification data covered: "
        "mean Euclidean error, mean predicted sigma per axis and the share of per-axis errors within 2 sigma"
        + (f" (all rows: {100 * cov:.1f} %)." if cov is not None else "."),
        "",
        "| joint | identified range (deg) | beyond the range (deg) | rows | mean error (mm) | mean sigma (mm) "
        "| 2σ coverage |",
        "|---|---|---|---|---|---|---|",
    ]
    ins = w.get("inside")
    if ins:
        out.append(
            f"| all | – | inside every range | {ins['n_rows']} | {fmt(ins['mean_error_mm'])} | "
            f"{fmt(ins['mean_sigma_mm'])} | {_pct(ins['coverage_2sigma'])} |"
        )
    for jt in w["joints"]:
        lo, hi = jt["range_deg"]
        for b in jt["bins"]:
            out.append(
                f"| {jt['joint']} | {lo:.1f} … {hi:.1f} | {b['beyond_deg'][0]:g} – {b['beyond_deg'][1]:g} "
                f"| {b['n_rows']} | "
                f"{fmt(b['mean_error_mm'])} | {fmt(b['mean_sigma_mm'])} | {_pct(b['coverage_2sigma'])} |"
            )
    return out + [""]


def _pct(v: float | None) -> str:
    return "–" if v is None else f"{100 * v:.0f} %"


def _history_markdown(rep: dict[str, Any]) -> list[str]:
    """The selection history table, then each step's candidates."""
    L = [
        "## Selection history",
        "",
        "| step | effects | CV RMS (mm) | RMS (mm) | excluded | decision |",
        "|---|---|---|---|---|---|",
    ]
    for h in rep["history"]:
        L.append(
            f"| {h['step']} | {', '.join(h['effects']) or '(declared)'} | {fmt(h['cv_rms_mm'])} | "
            f"{fmt(h['rms_mm'])} | {h['n_excluded']} | {h['reason']} |"
        )
    for h in rep["history"]:
        if h["candidates"]:
            L += _candidates_markdown(h)
    return L


def _candidates_markdown(h: dict[str, Any]) -> list[str]:
    """One selection step's candidates table (best CV RMS first) and their details."""
    L = [
        "",
        f"### Step {h['step']} candidates",
        "",
        "| effect | new params | CV RMS (mm) | dBIC | F-test p | share | accepted | reason |",
        "|---|---|---|---|---|---|---|---|",
    ]
    cands = sorted(h["candidates"], key=lambda c: (c["cv_rms_mm"] is None, c["cv_rms_mm"] or 0))
    for c in cands:
        L.append(
            f"| {c['effect']} | {c['n_params']} | {fmt(c['cv_rms_mm'])} | {fmt(c['delta_bic'], 3)} | "
            f"{fmt(c['f_pvalue'], 2)} | {fmt(c['explained_share'], 2)} | {c['accepted']} | "
            f"{md_cell(c['reason'])} |"
        )
    details = [c for c in cands if c.get("detail")]
    if details:
        L += [""] + [f"- {c['effect']}: {c['detail']}" for c in details]
    return L


def _parameters_markdown(rep: dict[str, Any]) -> list[str]:
    """The parameters table (SI units), then the held parameters."""
    L = [
        "",
        "## Parameters (SI units)",
        "",
        "| name | value | std | unit | status | note |",
        "|---|---|---|---|---|---|",
    ]
    for p in rep["parameters"]:
        L.append(
            f"| {p['name']} | {fmt(p['value'], 6)} | {fmt(p['std'], 3)} | {p['unit']} | {p['status']} | {p['reason']} |"
        )
    held_md = _held_markdown(rep)
    if held_md:
        L += [""] + held_md[:-1]
    return L


def _identifiability_markdown(rep: dict[str, Any]) -> list[str]:
    """The identifiability section, then the excluded rows (outliers)."""
    idf = rep["identifiability"]
    L = [
        "",
        "## Identifiability",
        "",
        f"- rank {idf['rank']}, condition number (column-normalised) {fmt(idf['condition_number'], 3)}",
        f"- saturated library model: {_saturated_words(idf.get('saturated_model'))}",
        "",
    ]
    L += ["## Excluded rows (outliers)", ""]
    if rep["excluded_rows"]:
        L += ["| row | file line | |residual| (mm) |", "|---|---|---|"]
        for e in rep["excluded_rows"]:
            L.append(f"| {e['row']} | {e['line']} | {fmt(e['residual_mm'])} |")
    else:
        L.append("none")
    return L


def _diagnostics_markdown(rep: dict[str, Any]) -> list[str]:
    """The diagnostics of the final residual (the significant and largest shown) and what the figures draw."""
    shown, hidden = shown_diagnostics(rep["diagnostics"])
    L = [
        "",
        "## Diagnostics of the final residual",
        "",
        "| variable | what | CV explained fraction | p-value | significant |",
        "|---|---|---|---|---|",
    ]
    for d in shown:
        L.append(
            f"| {d['variable']} | {md_cell(var_name(d['variable']))} | {fmt(d['explained_fraction'], 3)} | "
            f"{fmt(d['p_value'], 2)} | {d['significant']} |"
        )
    if hidden:
        L += [
            "",
            f"{hidden} other diagnostic{'s' if hidden > 1 else ''} not shown (not significant, explaining "
            "less than those listed); every diagnostic is in report.json.",
        ]
    drawn_line = not_significant_line(rep["diagnostics"])
    if drawn_line:
        L += ["", f"Figures: only significant diagnostics are drawn; {drawn_line}."]
    return L


def report_markdown(rep: dict[str, Any]) -> str:
    """Markdown rendering of :func:`~planner.identify_report.data.report_dict`: the headline table first."""
    L = ["# Identification report", "", "| quantity | value | note |", "|---|---|---|"]
    L += [f"| {q} | {md_cell(v)} | {md_cell(n)} |" for q, v, n in headline_rows(rep)]
    L += [
        "",
        f"- data: `{rep['data']['file']}`, registered: {rep['data']['registered']}",
        f"- RMS definition: {rep['rms_definition']}",
        "",
    ]
    if rep.get("campaigns"):  # several campaigns: one line, the figures in report.json 'campaigns'
        L[-1:-1] = [f"- campaigns: {campaigns_text(rep)}"]
    L += maps_markdown(rep)
    L += _unexplained_markdown(rep)
    L += _compensation_markdown(rep)
    L += _validation_markdown(rep)
    L += _history_markdown(rep)
    L += _parameters_markdown(rep)
    L += _identifiability_markdown(rep)
    L += _diagnostics_markdown(rep)
    if rep.get("warnings"):
        L += ["", "## Warnings", ""] + [f"- {w}" for w in rep["warnings"]]
    if rep["notes"]:
        L += ["", "## Notes", ""] + [f"- {n}" for n in rep["notes"]]
    fig_md = _figures_markdown(rep)
    if fig_md:
        L += [""] + fig_md[:-1]
    L += ["", "## Provenance", "", "| item | value | SHA-256 |", "|---|---|---|"]
    L += [f"| {a} | {b} | {c} |" for a, b, c in provenance_rows(rep)]
    return "\n".join(L) + "\n"


def _saturated_words(info: Any) -> str:
    """The saturated library model (every testable effect at once) in words, not a Python dict."""
    if not isinstance(info, dict) or not info.get("effects"):
        return "not fitted"
    words = f"effects {', '.join(map(str, info['effects']))}"
    if "cv_rms_mm" not in info:
        return words + " (no effect beyond the declared model: not fitted separately)"
    structure = var_name(str(info.get("structure")))
    left = "leaves no structure" if info.get("clean") else f"leaves structure in {structure}"
    return (
        f"{words}; CV RMS {fmt(info['cv_rms_mm'], 4)} mm; {left}; "
        f"{info.get('n_excluded', 0)} rows excluded as outliers against it"
    )
