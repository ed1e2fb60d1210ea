"""The report's tables of a plan with dynamic compensation (``summary.json`` key
``dynamic_compensation``): the headline's rows and the stage's tables, shown as the plan computed
them."""

from __future__ import annotations

from typing import Any
from collections.abc import Mapping

from planner.numbers import NUMERICAL_FLOOR_MM, format_number
from planner.record.columns import DYNAMIC_KEY
from planner.report.table_base import RATIO_KINDS, Cell, Table, value_cell

__all__ = [
    "DYNAMIC_CASES",
    "dynamic_headline_note",
    "dynamic_headline_rows",
    "dynamic_tables",
]


#: The cases of the dynamic compensation: (summary.json key, row label); the headline's words
#: (planner.dynamic.HEADLINE_CASES) open each label.
DYNAMIC_CASES = (
    ("none", "uncompensated (link plan commanded as is)"),
    ("static", "static command (load and own weight, no inertial torques)"),
    ("static+dynamic", "motor-side command (static + dynamic: trajectory.csv)"),
)
#: The dynamic headline's rows: (key part of ``headline.dynamic_compensation``, case words, note).
DYNAMIC_HEADLINE_ROWS = (
    ("uncompensated", "uncompensated", "the link plan commanded as is"),
    ("static_command", "static command", "load and own weight compensated, no inertial torques"),
    ("motor_side_command", "motor-side command", "the dynamic compensation: what trajectory.csv holds"),
)


def dynamic_headline_rows(s: Mapping[str, Any]) -> list[list[Cell]]:
    """The headline table's rows of a plan with dynamic compensation (``headline.dynamic_compensation``,
    computed by the plan, shown as it is): the max predicted TCP error during the motion and at rest
    without, with the static and with the motor-side command; none without the block."""
    h = (s.get("headline") or {}).get(DYNAMIC_KEY) if isinstance(s.get("headline"), Mapping) else None
    if not isinstance(h, Mapping):
        return []
    below = set(h.get("below_numerical_floor") or [])
    floor = f"below the numerical floor {format_number(h.get('numerical_floor_mm', NUMERICAL_FLOOR_MM))} mm"
    rows = []
    for where, words in (("motion", "max during the motion"), ("rest", "max at rest (start, end, dwells)")):
        for key, case, note in DYNAMIC_HEADLINE_ROWS:
            k = f"error_{where}_max_{key}_mm"
            if k in h:
                text = f"TCP error along the trajectory, {words}: {case}"
                cell = value_cell(s, f"headline.{DYNAMIC_KEY}.{k}")
                rows.append([Cell(text), cell, Cell("mm"), Cell(floor if k in below else note)])
    return rows


def dynamic_headline_note(s: Mapping[str, Any]) -> str:
    """The headline note's sentence on the dynamic rows (their definition from summary.json), or ""."""
    h = (s.get("headline") or {}).get(DYNAMIC_KEY) if isinstance(s.get("headline"), Mapping) else None
    if not isinstance(h, Mapping):
        return ""
    return (
        " Trajectory rows (dynamic compensation): the predicted (quasi-static) TCP error at every sample of "
        "trajectory.csv under the load, the arm's own weight and the inertial torques, unlike the waypoint rows "
        "(the arm model's load alone); at rest the motor-side command is the static command. Definition: "
        "summary.json headline.dynamic_compensation.definition and the table 'Dynamic compensation: predicted "
        "TCP error'."
    )


#: The command table's smoothing columns: (``dynamic_compensation`` key, header); older summaries have
#: only the first.
DYNAMIC_SMOOTHING_COLUMNS = (
    ("smoothing_s", "smoothing, centred [s]"),
    ("smoothing_edge_s", "smoothing next to rest, one-sided [s]"),
    ("smoothing_blend_s", "hand-over [s]"),
)


def dynamic_tables(s: Mapping[str, Any]) -> list[Table]:
    """The predicted TCP error without, with static and with static + dynamic compensation, and
    the command's timing passes, limit scale and smoothing; no table when the run has no
    dynamic compensation (summary.json key ``dynamic_compensation``)."""
    d = s.get(DYNAMIC_KEY)
    if not isinstance(d, Mapping):
        return []
    k = f"{DYNAMIC_KEY}.predicted_tcp_error"
    rows = [
        [Cell(label)] + [value_cell(s, f"{k}.{case}.{m}") for m in ("motion_max_mm", "motion_rms_mm", "rest_max_mm")]
        for case, label in DYNAMIC_CASES
    ]
    note = " ".join(
        p
        for p in (
            f"Definition: {d['definition']}." if d.get("definition") else "",
            f"Assumptions: {d['assumptions']}." if d.get("assumptions") else "",
            f"Series against time: {d.get('file') or 'dynamic.csv'} (figure "
            "'TCP deviation from the planned path against time').",
            f"Below {format_number(NUMERICAL_FLOOR_MM)} mm: 0 (numerical).",
        )
        if p
    )
    errors = Table(
        "Dynamic compensation: predicted TCP error [mm]",
        ["case", "max during motion [mm]", "RMS during motion [mm]", "max at rest (start, end, dwells) [mm]"],
        rows,
        note.replace("..", "."),
        anchor="dynamic",
    )
    scale = d.get("limit_scale") if isinstance(d.get("limit_scale"), Mapping) else {}
    kinds = [kd for kd in RATIO_KINDS if kd in scale] + [kd for kd in scale if kd not in RATIO_KINDS]
    smoothing = [(key, text) for key, text in DYNAMIC_SMOOTHING_COLUMNS if key in d]
    command = Table(
        "Dynamic compensation: command",
        ["status", "timing passes"] + [f"limit scale: {kd} [×]" for kd in kinds] + [t for _k, t in smoothing],
        [
            [value_cell(s, f"{DYNAMIC_KEY}.status"), value_cell(s, f"{DYNAMIC_KEY}.passes")]
            + [value_cell(s, f"{DYNAMIC_KEY}.limit_scale.{kd}") for kd in kinds]
            + [value_cell(s, f"{DYNAMIC_KEY}.{key}") for key, _t in smoothing]
        ],
        str(d.get("reason") or ""),
        anchor="dynamic-command",
    )
    tables = [errors, command]
    mismatch = d.get("mismatch")
    if isinstance(mismatch, list) and mismatch:
        m = f"{DYNAMIC_KEY}.mismatch"
        cols = ("stiffness_factor", "payload_factor", "static_motion_max_mm", "static_dynamic_motion_max_mm", "gain")
        rows = [[value_cell(s, f"{m}.{i}.{c}") for c in cols] for i, e in enumerate(mismatch) if isinstance(e, Mapping)]
        tables.append(
            Table(
                "Dynamic compensation: model mismatch",
                [
                    "joint stiffness [× model]",
                    "payload mass [× model]",
                    "static command: max during motion [mm]",
                    "motor-side command: max during motion [mm]",
                    "gain [×]",
                ],
                rows,
                "The same command (planned on the model) run on an arm whose joint stiffness and "
                "payload mass are the factors times the model's: predicted TCP error during the "
                "motion; gain = static command / motor-side command.",
                anchor="dynamic-mismatch",
            )
        )
    return tables
