"""The report's tables: the numbers of ``summary.json`` that head the report.

Every number in the HTML tables is machine-checkable: its cell carries
``data-key`` (the dotted path into ``summary.json``; list items by index, e.g.
``provenance.inputs.0.sha256``), ``data-value`` (the JSON value, full
precision) and, when the cell shows the maximum over joints of a list,
``data-agg="max"``.  The text is rounded to what it means
(:mod:`planner.numbers`): 4 significant digits, and a TCP error below the
numerical floor (1e-6 mm) reads "0 (numerical)".

The first table is the headline (status, IK branch, TCP error before and after,
duration); the provenance table (version, command line, date, input files with
SHA-256) closes the summary.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Mapping


from planner import branches as branch_words
from planner.numbers import NUMERICAL_FLOOR_MM, format_number
from planner.record.record import method_name
from planner.report.dynamic_tables import dynamic_headline_note, dynamic_headline_rows, dynamic_tables
from planner.report.cut_tables import cut_tables
from planner.report.program_tables import program_tables
from planner.report.table_base import RATIO_KINDS, Cell, Table, flat_numbers, lookup, value_cell

#: Columns of the branch table when summary.json's branch entries have them (plan, issue 5).
_BRANCH_KEYS = (
    "rms_error_equilibrium_mm",
    "max_error_equilibrium_mm",
    "rms_error_analytic_mm",
    "rms_error_mm",
    "cost",
    "iterations",
)
_BRANCH_HEADERS = {
    "rms_error_equilibrium_mm": "RMS error, exact equilibrium [mm]",
    "max_error_equilibrium_mm": "max error, exact equilibrium [mm]",
    "rms_error_analytic_mm": "RMS error, first order, analytic posture [mm]",
    "rms_error_mm": "RMS error, first order, optimised posture [mm]",
    "max_error_mm": "max error, first order, optimised [mm]",
    "cost": "NLP cost [m²]",
    "iterations": "solver iterations",
}


# ------------------------------------------------------------------------------------ tables
def ratio_methods(lr: Any) -> dict[str, str]:
    """Method name -> dotted key prefix of the limit ratios (per-method or single)."""
    if not isinstance(lr, Mapping):
        return {}
    if any(k in lr for k in RATIO_KINDS):
        return {"trajectory": "limit_ratio"}
    return {m: f"limit_ratio.{m}" for m, v in lr.items() if isinstance(v, Mapping)}


def _scenario_key(s: Mapping[str, Any]) -> str:
    """Where the run names its scenario: ``scenario`` (demo) or ``problem.name`` (plan)."""
    if "scenario" not in s and isinstance(s.get("problem"), Mapping) and "name" in s["problem"]:
        return "problem.name"
    return "scenario"


def report_title(s: Mapping[str, Any]) -> str:
    """The report's title: robot and scenario."""
    try:
        scen = str(lookup(s, _scenario_key(s)))
    except KeyError:
        scen = "unnamed run"
    return f"compplan report: {s.get('robot', '?')}, {scen}"


def summary_tables(summary: Mapping[str, Any], absent: Mapping[str, str]) -> list[Table]:
    """The tables of the report, headline first and provenance last (numbers traceable to
    summary.json)."""
    tables = [headline_table(summary), _run_table(summary), _error_table(summary), _timing_table(summary, absent)]
    tables += program_tables(summary)
    tables += cut_tables(summary)
    tables += dynamic_tables(summary)
    branches = _branch_table(summary)
    if branches is not None:
        tables.append(branches)
    tables.append(provenance_table(summary))
    return tables


def load_words(s: Mapping[str, Any]) -> str:
    """The load of a run in words: payload, tool-frame or base-frame wrench (never a misleading
    base-frame ``F = [0, 0, 0]`` for a run whose load is a payload or a tool-frame wrench)."""
    w = s.get("wrench") if isinstance(s.get("wrench"), Mapping) else {}
    parts = []
    F, M = flat_numbers(w.get("F_N")), flat_numbers(w.get("M_Nm"))
    frame = w.get("frame", "base")
    per_wp = bool(w.get("per_waypoint"))
    nonzero = any(abs(v) > 0 for v in F + M) or per_wp
    if nonzero and F and M:
        vec = f"F = [{', '.join(format_number(v) for v in F)}] N, M = [{', '.join(format_number(v) for v in M)}] N·m"
        where = "tool-frame wrench (turns with the tool)" if frame == "tool" else "base-frame wrench"
        parts.append(f"{where} {vec}" + (" at waypoint 0 (per-waypoint wrench)" if per_wp else ""))
    cut = s.get("cut")
    if isinstance(cut, Mapping) and isinstance(cut.get("force_N"), Mapping):
        f = cut["force_N"]
        parts.append(
            f"the predicted cut (force on the tool up to {format_number(float(f.get('max', 0.0)))} N, "
            f"{format_number(float(f.get('mean_cutting', 0.0)))} N on average while cutting)"
        )
    p = s.get("payload")
    if isinstance(p, Mapping) and p.get("mass_kg"):
        com = flat_numbers(p.get("com_m_tcp_frame"))
        parts.append(
            f"payload {format_number(float(p['mass_kg']))} kg"
            + (
                f" (centre of mass [{', '.join(format_number(v) for v in com)}] m, TCP frame)"
                if com and any(com)
                else ""
            )
        )
    return " + ".join(parts) if parts else "no load"


def headline_table(s: Mapping[str, Any]) -> Table:
    """The headline: status, IK branch, TCP error before / after, duration (one short table)."""
    h = s.get("headline")
    if not isinstance(h, Mapping):
        return Table(
            "Headline",
            ["quantity", "value", "unit", "note"],
            [
                [
                    Cell("headline"),
                    Cell("absent"),
                    Cell(""),
                    Cell("summary.json has no headline block (written by an earlier compplan)"),
                ]
            ],
            css="summary headline",
            anchor="headline",
        )
    label = h.get("branch")
    branch_note = h.get("branch_posture") or ""
    if label and h.get("default_branch") and h.get("default_branch") != label and h.get("gain_vs_default"):
        branch_note += (
            f"{'; ' if branch_note else ''}{format_number(h['gain_vs_default'])}× less RMS error than "
            f"the default branch {h['default_branch']} (nearest home)"
        )
    elif label and h.get("default_branch") == label:
        branch_note += f"{'; ' if branch_note else ''}the default branch (nearest home)"
    floor = f"below the numerical floor {format_number(h.get('numerical_floor_mm', NUMERICAL_FLOOR_MM))} mm"
    rows = [
        [Cell("status"), value_cell(s, "headline.status"), Cell(""), Cell(str(h.get("reason") or ""))],
        [
            Cell("IK branch"),
            value_cell(s, "headline.branch"),
            Cell(""),
            Cell(f"{branch_words.short(label) if label else ''}{': ' if branch_note else ''}{branch_note}"),
        ],
    ]
    below = set(h.get("below_numerical_floor") or [])
    for text, key, note in (
        (
            "TCP error before compensation, max",
            "error_before_max_mm",
            "the chosen posture commanded as is, exact deflected equilibrium",
        ),
        ("TCP error before compensation, RMS", "error_before_rms_mm", ""),
        ("TCP error after exact compensation, max", "error_after_max_mm", ""),
        ("TCP error after exact compensation, RMS", "error_after_rms_mm", ""),
        (
            "TCP error after closed-form compensation (paper), max",
            "error_after_closed_form_max_mm",
            "first-order compensation q − K⁻¹Jᵀ(q)F, for comparison",
        ),
    ):
        if key not in h:
            continue
        rows.append([Cell(text), value_cell(s, f"headline.{key}"), Cell("mm"), Cell(floor if key in below else note)])
    rows += dynamic_headline_rows(s)
    if h.get("duration_s") is not None:
        note = str(h.get("duration_note") or "")
        if h.get("duration_time_optimal_s") is not None:
            ref = str(h.get("duration_time_optimal_method") or "toppra")  # summaries before the key: TOPP-RA
            enforced = ((s.get("timing") or {}).get(ref) or {}).get("limits_enforced") or ()
            free = "" if "jerk" in enforced else ", jerk not limited"
            note += f"; time-optimal ({method_name(s, ref)}{free}): {format_number(h['duration_time_optimal_s'])} s"
        rows.append([Cell("duration"), value_cell(s, "headline.duration_s"), Cell("s"), Cell(note)])
    else:
        rows.append([Cell("duration"), Cell("not timed"), Cell(""), Cell(str(h.get("duration_note") or ""))])
    return Table(
        "Headline",
        ["quantity", "value", "unit", "note"],
        rows,
        "TCP error = |reached − target| TCP position over the waypoints at the exact deflected "
        f"equilibrium under the whole load ({load_words(s)}); rounded to 4 significant digits, "
        f"and an error below {format_number(h.get('numerical_floor_mm', NUMERICAL_FLOOR_MM))} mm "
        "(the exact-compensation contract) is 0: the accuracy of the equilibrium solve, not an "
        "error of the arm. Full precision: the tables below and summary.json." + dynamic_headline_note(s),
        css="summary headline",
        anchor="headline",
    )


def provenance_table(s: Mapping[str, Any]) -> Table:
    """compplan version, command line, date (UTC) and input files with their SHA-256."""
    p = s.get("provenance")
    if not isinstance(p, Mapping):
        return Table(
            "Provenance",
            ["item", "value", "SHA-256"],
            [[Cell("provenance"), Cell("absent: summary.json written by an earlier compplan"), Cell("")]],
            anchor="provenance",
        )
    rows = [
        [Cell("compplan version"), value_cell(s, "provenance.compplan_version"), Cell("")],
        [
            Cell("command line"),
            value_cell(s, "provenance.command_line", css="mono")
            if p.get("command_line")
            else Cell("none: written by a library call"),
            Cell(""),
        ],
        [Cell("date (UTC, ISO 8601)"), value_cell(s, "provenance.date_utc"), Cell("")],
    ]
    for i, e in enumerate(p.get("inputs") or []):
        if not isinstance(e, Mapping):
            continue
        name = f" '{e['name']}'" if e.get("name") else ""
        where = (
            value_cell(s, f"provenance.inputs.{i}.path", css="mono")
            if e.get("path")
            else Cell(str(e.get("note") or "not a file"))
        )
        digest = value_cell(s, f"provenance.inputs.{i}.sha256", css="mono hash") if e.get("sha256") else Cell("—")
        rows.append([Cell(f"input: {e.get('role', '?')}{name}"), where, digest])
    return Table(
        "Provenance",
        ["item", "value", "SHA-256"],
        rows,
        "Inputs as read by this run; their SHA-256 identifies the exact files (built-in robots and "
        "shipped problems are hashed from the installed package).",
        anchor="provenance",
    )


def _run_table(s: Mapping[str, Any]) -> Table:
    branch_key = "chosen_branch" if "chosen_branch" in s else "branch"
    w = s.get("wrench") if isinstance(s.get("wrench"), Mapping) else {}
    frame = w.get("frame", "?")
    rows = [
        [Cell("robot"), value_cell(s, "robot"), Cell("")],
        [Cell("scenario"), value_cell(s, _scenario_key(s)), Cell("")],
        [Cell("load"), Cell(load_words(s)), Cell("")],
        *_wrench_rows(s, w, frame),
        *_payload_rows(s),
        *_model_rows(s),
        [Cell("IK branch used"), value_cell(s, branch_key), Cell("")],
        [Cell("waypoints"), value_cell(s, "n_waypoints"), Cell("")],
        [Cell("compensation status, closed form"), value_cell(s, "status.closed_form"), Cell("")],
        [Cell("compensation status, exact"), value_cell(s, "status.exact"), Cell("")],
    ]
    optional = (
        ("plan status", "plan_status", ""),
        ("reason", "reason", ""),
        ("default IK branch (nearest home)", "default_branch", ""),
        ("error gain vs default branch", "gain.vs_default", "×"),
        ("error gain vs best analytic posture", "gain.vs_best_analytic", "×"),
        ("controller trajectory", "controller_trajectory", ""),
    )
    for label, key, unit in optional:
        try:
            v = lookup(s, key)
        except KeyError:
            continue
        if v is None or v == "":
            continue
        rows.append([Cell(label), value_cell(s, key), Cell(unit)])
    return Table("Run", ["quantity", "value", "unit"], rows)


def _wrench_rows(s: Mapping[str, Any], w: Mapping[str, Any], frame: str) -> list[list[Cell]]:
    """The process wrench: force, moment, frame and point; one row "none" when it is zero."""
    values = flat_numbers(w.get("F_N")) + flat_numbers(w.get("M_Nm"))
    if values and not any(values) and not w.get("per_waypoint"):
        return [
            [
                Cell("process wrench"),
                Cell("none" + (" (the payload is the load)" if s.get("payload") else "")),
                Cell(""),
            ]
        ]
    return [
        [Cell(f"process wrench: force F ({frame} frame)"), value_cell(s, "wrench.F_N"), Cell("N")],
        [Cell(f"process wrench: moment M ({frame} frame)"), value_cell(s, "wrench.M_Nm"), Cell("N·m")],
        [
            Cell("process wrench: frame / point"),
            Cell(
                f"{frame} frame"
                + (" (turns with the tool)" if frame == "tool" else "")
                + f", at the {w.get('point', '?')}"
                + ("; per-waypoint: the values are waypoint 0's" if w.get("per_waypoint") else "")
            ),
            Cell(""),
        ],
    ]


def _payload_rows(s: Mapping[str, Any]) -> list[list[Cell]]:
    """Payload mass and centre of mass, when the problem has one."""
    if not s.get("payload"):
        return []
    return [
        [Cell("payload: mass"), value_cell(s, "payload.mass_kg"), Cell("kg")],
        [Cell("payload: centre of mass (TCP frame)"), value_cell(s, "payload.com_m_tcp_frame"), Cell("m")],
    ]


def _model_rows(s: Mapping[str, Any]) -> list[list[Cell]]:
    """Which arm model planned: its file (and hash) and its effects."""
    md = s.get("model")
    if not isinstance(md, Mapping):
        return []
    src = md.get("file") or f"robot file '{s.get('robot', '?')}' (nominal)"
    rows = [
        [Cell("arm model"), Cell(str(src)), Cell("")],
        [Cell("arm model: effects"), Cell(", ".join(md.get("effects", [])) or "joint_springs"), Cell("")],
    ]
    if md.get("sha256"):
        rows.append([Cell("arm model: SHA-256"), Cell(str(md["sha256"])[:16] + "…"), Cell("")])
    sig = s.get("model_sigma")
    if isinstance(sig, Mapping) and sig.get("text"):
        rows.append([Cell("arm model: where it holds"), Cell(str(sig["text"])), Cell("")])
    return rows


def _error_table(s: Mapping[str, Any]) -> Table:
    rows = []
    for label, key in (
        ("before compensation", "error_before"),
        ("after closed form (paper eqs. 32/47)", "error_after.closed_form"),
        ("after exact compensation", "error_after.exact"),
    ):
        rows.append([Cell(label), value_cell(s, f"{key}.max_mm"), value_cell(s, f"{key}.rms_mm")])
    return Table(
        "TCP position error under load [mm]",
        ["case", "max [mm]", "RMS [mm]"],
        rows,
        "Euclidean norm of (reached − target) TCP position over the waypoints, at the exact "
        "deflected equilibrium of the arm model named above (its effects, under the whole load). "
        "'Before' is the chosen posture commanded as is; the IK branch table's first-order "
        "errors (|S·C(q)·F|, the NLP's objective) differ from it by the second-order terms, its "
        "'exact equilibrium' column is this same measure. "
        f"Below {format_number(NUMERICAL_FLOOR_MM)} mm: 0 (numerical).",
    )


def _timing_table(s: Mapping[str, Any], absent: Mapping[str, str]) -> Table:
    methods = ratio_methods(s.get("limit_ratio"))
    dur = s.get("duration_s")
    if isinstance(dur, Mapping):
        for m in dur:
            methods.setdefault(m, f"limit_ratio.{m}")
    rows = []
    for m, prefix in methods.items():
        if isinstance(dur, Mapping):
            dcell = value_cell(s, f"duration_s.{m}")
        elif dur is not None and m == "trajectory":
            dcell = value_cell(s, "duration_s")
        else:
            dcell = Cell("absent")
        name = method_name(s, m) + (" (controller)" if s.get("controller_trajectory") == m else "")
        rows.append(
            [Cell(name), dcell]
            + [value_cell(s, f"{prefix}.{k}", agg="max") for k in RATIO_KINDS]
            + [value_cell(s, f"timing.{m}.status"), _binding_cell(s, m)]
        )
    note = (
        "Limit ratio: peak |value| / limit, maximum over the joints (1 = at the limit). "
        + "".join(_partial_limits(s, m) for m in methods)
        + "Binds: the limit and joint at ≥ 98 % of its limit for the largest share of the motion."
    )
    if not rows:
        rows = [[Cell(absent.get("trajectory", "no trajectory in this run"))] + [Cell("—")] * 6]
        note = "No trajectory in this run: durations and limit ratios are not available."
    return Table(
        "Timing",
        ["method", "duration [s]", "velocity ratio", "acceleration ratio", "jerk ratio", "status", "binds"],
        rows,
        note,
    )


def _words(keys: list[str]) -> str:
    return keys[0] if len(keys) == 1 else ", ".join(keys[:-1]) + " and " + keys[-1]


def _partial_limits(s: Mapping[str, Any], method: str) -> str:
    """``"TOPP-RA limits velocity and acceleration only; its jerk ratio is reported, not enforced. "``
    for a method that does not enforce every limit (``timing.<m>.limits_enforced``), else ``""``."""
    info = (s.get("timing") or {}).get(method) if isinstance(s.get("timing"), Mapping) else None
    enforced = info.get("limits_enforced") if isinstance(info, Mapping) else None
    if not isinstance(enforced, list) or not enforced:
        return ""
    free = [k for k in RATIO_KINDS if k not in enforced]
    if not free:
        return ""
    verb = "is" if len(free) == 1 else "are"
    return (
        f"{method_name(s, method)} limits {_words([k for k in RATIO_KINDS if k in enforced])} only; its "
        f"{_words(free)} ratio{'' if len(free) == 1 else 's'} {verb} reported, not enforced. "
    )


def _binding_cell(s: Mapping[str, Any], method: str) -> Cell:
    """The most often binding limit of a method's trajectory (``timing.<m>.limit_use``)."""
    use = ((s.get("timing") or {}).get(method) or {}).get("limit_use")
    if not isinstance(use, Mapping):
        return Cell("—")
    if use.get("under_half"):
        return Cell(f"none: under half of every limit (peak {use.get('peak')})")
    b = use.get("binding") or []
    if not b or not isinstance(b[0], Mapping):
        return Cell("—")
    return Cell(
        f"{b[0].get('limit')} of joint {b[0].get('joint')} "
        f"({100 * float(b[0].get('fraction_of_time', 0)):.0f} % of the time)"
    )


def _branch_table(s: Mapping[str, Any]) -> Table | None:
    br = s.get("branches")
    if not (isinstance(br, Mapping) and br):
        return None
    keys: list[str] = []
    for info in br.values():
        if isinstance(info, Mapping):
            for k, v in info.items():
                if k not in keys and (isinstance(v, (int, float, bool)) or v is None) and k != "status":
                    keys.append(k)
    preferred = [k for k in _BRANCH_KEYS if k in keys]
    keys = preferred or keys[:8]
    rows = []
    chosen, default = s.get("chosen_branch"), s.get("default_branch")
    for label, info in br.items():
        info = info if isinstance(info, Mapping) else {}
        marks = [m for m, on in (("chosen", label == chosen), ("default", label == default)) if on]
        name = f"{label} ({', '.join(marks)})" if marks else str(label)
        posture = str(info.get("posture") or branch_words.short(str(label)))
        status = str(info.get("status", "?"))
        text = branch_words.status_text(status)
        reason = info.get("reason")
        if status == "collision" and isinstance(reason, str) and reason:
            text = f"set aside: {reason.split(' (posture NLP')[0]}"  # the pair, the waypoint, the overlap
        rows.append([Cell(name), Cell(posture), Cell(text)] + [value_cell(s, f"branches.{label}.{k}") for k in keys])
    diff = ""
    ci = br.get(chosen) if isinstance(br.get(chosen), Mapping) else {}
    a, b = ci.get("rms_error_mm"), ci.get("rms_error_equilibrium_mm")
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and b:
        diff = f" ({format_number(100.0 * (a - b) / b, 2)} % for the chosen branch)"
    note = (
        branch_words.legend(list(br)) + " Posture at waypoint 0, seen from above from the base. "
        "'Exact equilibrium': the load-induced TCP error of the branch's posture at the deflected "
        "equilibrium (the measure of the error table and of figure 5); 'first order': |S·C(q)·F|, "
        "the posture NLP's objective, which neglects the change of C over the deflection"
        f"{diff}. Status 'fixed orientation: the IK solution, nothing to optimise' (no_freedom) is "
        "not a failure: six equations fix the six joints and only the branch is chosen."
    )
    return Table("IK branches", ["branch", "posture", "status"] + [_BRANCH_HEADERS.get(k, k) for k in keys], rows, note)
