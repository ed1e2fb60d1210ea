"""The report's tables: the numbers of ``summary.json`` that head the report.

Every number in the HTML tables is machine-checkable: its cell carries
``data-key`` (the dotted path into ``summary.json``), ``data-value`` (the JSON
value, full precision) and, when the cell shows the maximum over joints of a
list, ``data-agg="max"``.  The text shows 7 significant digits.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from planner.report.run import METHOD_NAMES

#: Kinds of limit ratio, in table order.
RATIO_KINDS = ("velocity", "acceleration", "jerk")

#: Columns of the branch table when summary.json's branch entries have them (plan, issue 5).
_BRANCH_KEYS = ("status", "rms_error_analytic_mm", "rms_error_mm", "max_error_mm", "cost",
                "iterations")
_BRANCH_HEADERS = {"rms_error_analytic_mm": "RMS error, analytic posture [mm]",
                   "rms_error_mm": "RMS error, optimised posture [mm]",
                   "max_error_mm": "max error, optimised [mm]", "cost": "cost [m²]",
                   "iterations": "solver iterations"}


# ------------------------------------------------------------------------------- value helpers
def lookup(summary: Mapping[str, Any], key: str) -> Any:
    """Value at a dotted path in ``summary`` (``KeyError`` if absent)."""
    cur: Any = summary
    for part in key.split("."):
        if not isinstance(cur, Mapping) or part not in cur:
            raise KeyError(key)
        cur = cur[part]
    return cur


def fmt(v: Any) -> str:
    """Display text of a table value: numbers with 7 significant digits."""
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "n/a" if not math.isfinite(float(v)) else f"{float(v):.7g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    return str(v)


def flat_numbers(v: Any) -> list[float]:
    """The numbers of a (nested) list, flattened; other values are skipped."""
    if isinstance(v, (list, tuple)):
        return [x for item in v for x in flat_numbers(item)]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return [float(v)]
    return []


@dataclass
class Cell:
    """One table cell: display text and, for values from summary.json, where they come from."""

    text: str
    key: str | None = None
    value: Any = None
    agg: str | None = None

    def html(self) -> str:
        if self.key is None:
            return f"<td>{html.escape(self.text)}</td>"
        attrs = f' data-key="{html.escape(self.key)}" data-value="{html.escape(json.dumps(self.value))}"'
        if self.agg:
            attrs += f' data-agg="{self.agg}"'
        cls = "text" if isinstance(self.value, str) else "num"
        return f'<td class="{cls}"{attrs}>{html.escape(self.text)}</td>'


def value_cell(summary: Mapping[str, Any], key: str, agg: str | None = None) -> Cell:
    """A cell showing ``summary[key]`` (or the max of its numbers with ``agg="max"``)."""
    try:
        v = lookup(summary, key)
    except KeyError:
        return Cell("absent")
    if agg == "max":
        nums = [x for x in flat_numbers(v) if math.isfinite(x)]
        if not nums:
            return Cell("n/a")
        shown = max(nums)
        return Cell(fmt(shown), key, shown, "max")
    if isinstance(v, Mapping):
        return Cell(json.dumps(v))
    return Cell(fmt(v), key, v)


@dataclass
class Table:
    title: str
    header: list[str]
    rows: list[list[Cell]]
    note: str = ""

    def html(self) -> str:
        out = [f"<h3>{html.escape(self.title)}</h3>", '<table class="summary">',
               "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in self.header) + "</tr>"]
        out += ["<tr>" + "".join(c.html() for c in row) + "</tr>" for row in self.rows]
        out.append("</table>")
        if self.note:
            out.append(f'<p class="note">{html.escape(self.note)}</p>')
        return "\n".join(out)

    def markdown(self) -> str:
        def esc(s: str) -> str:
            return s.replace("|", "\\|")
        out = [f"### {self.title}", "", "| " + " | ".join(esc(h) for h in self.header) + " |",
               "|" + "---|" * len(self.header)]
        out += ["| " + " | ".join(esc(c.text) for c in row) + " |" for row in self.rows]
        if self.note:
            out += ["", self.note]
        return "\n".join(out)


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
    """The tables that head the report (numbers traceable to summary.json)."""
    tables = [_run_table(summary), _error_table(summary), _timing_table(summary, absent)]
    branches = _branch_table(summary)
    if branches is not None:
        tables.append(branches)
    return tables


def _run_table(s: Mapping[str, Any]) -> Table:
    branch_key = "chosen_branch" if "chosen_branch" in s else "branch"
    rows = [
        [Cell("robot"), value_cell(s, "robot"), Cell("")],
        [Cell("scenario"), value_cell(s, _scenario_key(s)), Cell("")],
        [Cell("process wrench: force F"), value_cell(s, "wrench.F_N"), Cell("N")],
        [Cell("process wrench: moment M"), value_cell(s, "wrench.M_Nm"), Cell("N·m")],
        [Cell("process wrench: frame / point"),
         Cell(f"{s.get('wrench', {}).get('frame', '?')} frame"
              + (" (turns with the tool)" if s.get("wrench", {}).get("frame") == "tool" else "")
              + f", at the {s.get('wrench', {}).get('point', '?')}"), Cell("")],
        *_payload_rows(s),
        *_model_rows(s),
        [Cell("IK branch used"), value_cell(s, branch_key), Cell("")],
        [Cell("waypoints"), value_cell(s, "n_waypoints"), Cell("")],
        [Cell("compensation status, closed form"), value_cell(s, "status.closed_form"), Cell("")],
        [Cell("compensation status, exact"), value_cell(s, "status.exact"), Cell("")],
    ]
    optional = (("plan status", "plan_status", ""), ("reason", "reason", ""),
                ("default IK branch (nearest home)", "default_branch", ""),
                ("error gain vs default branch", "gain.vs_default", "×"),
                ("error gain vs best analytic posture", "gain.vs_best_analytic", "×"),
                ("controller trajectory", "controller_trajectory", ""))
    for label, key, unit in optional:
        try:
            v = lookup(s, key)
        except KeyError:
            continue
        if v is None or v == "":
            continue
        rows.append([Cell(label), value_cell(s, key), Cell(unit)])
    return Table("Run", ["quantity", "value", "unit"], rows)


def _payload_rows(s: Mapping[str, Any]) -> list[list[Cell]]:
    """Payload mass and centre of mass, when the problem has one."""
    if not s.get("payload"):
        return []
    return [[Cell("payload: mass"), value_cell(s, "payload.mass_kg"), Cell("kg")],
            [Cell("payload: centre of mass (TCP frame)"), value_cell(s, "payload.com_m_tcp_frame"), Cell("m")]]


def _model_rows(s: Mapping[str, Any]) -> list[list[Cell]]:
    """Which arm model planned: its file (and hash) and its effects."""
    md = s.get("model")
    if not isinstance(md, Mapping):
        return []
    src = md.get("file") or f"robot file '{s.get('robot', '?')}' (nominal)"
    rows = [[Cell("arm model"), Cell(str(src)), Cell("")],
            [Cell("arm model: effects"), Cell(", ".join(md.get("effects", [])) or "joint_springs"), Cell("")]]
    if md.get("sha256"):
        rows.append([Cell("arm model: SHA-256"), Cell(str(md["sha256"])[:16] + "…"), Cell("")])
    return rows


def _error_table(s: Mapping[str, Any]) -> Table:
    rows = []
    for label, key in (("before compensation", "error_before"),
                       ("after closed form (paper eqs. 32/47)", "error_after.closed_form"),
                       ("after exact compensation", "error_after.exact")):
        rows.append([Cell(label), value_cell(s, f"{key}.max_mm"), value_cell(s, f"{key}.rms_mm")])
    return Table("TCP position error under load [mm]", ["case", "max [mm]", "RMS [mm]"], rows,
                 "Euclidean norm of (reached - target) TCP position over the waypoints, at the exact "
                 "deflected equilibrium of the arm model named above (its effects, under the whole load).")


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
        rows.append([Cell(METHOD_NAMES.get(m, m)), dcell]
                    + [value_cell(s, f"{prefix}.{k}", agg="max") for k in RATIO_KINDS]
                    + [value_cell(s, f"timing.{m}.status")])
    note = ("Limit ratio: peak |value| / limit, maximum over the joints (1 = at the limit). "
            "TOPP-RA limits velocity and acceleration only; its jerk ratio is reported, not "
            "enforced.")
    if not rows:
        rows = [[Cell(absent.get("trajectory", "no trajectory in this run"))] + [Cell("—")] * 5]
        note = "No trajectory in this run: durations and limit ratios are not available."
    return Table("Timing", ["method", "duration [s]", "velocity ratio", "acceleration ratio",
                            "jerk ratio", "status"], rows, note)


def _branch_table(s: Mapping[str, Any]) -> Table | None:
    br = s.get("branches")
    if not (isinstance(br, Mapping) and br):
        return None
    keys: list[str] = []
    for info in br.values():
        if isinstance(info, Mapping):
            for k, v in info.items():
                if k not in keys and (isinstance(v, (int, float, str, bool)) or v is None):
                    keys.append(k)
    preferred = [k for k in _BRANCH_KEYS if k in keys]
    keys = preferred or keys[:8]
    rows = []
    chosen = s.get("chosen_branch")
    for label in br:
        name = f"{label} (chosen)" if label == chosen else str(label)
        rows.append([Cell(name)] + [value_cell(s, f"branches.{label}.{k}") for k in keys])
    return Table("IK branches", ["branch"] + [_BRANCH_HEADERS.get(k, k) for k in keys], rows)
