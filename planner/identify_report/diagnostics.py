"""Which diagnostics of the final residual the report shows (figures and table) and the words and
units of their variables."""

from __future__ import annotations

import re
from typing import Any

from problems.identify import Diagnostic, IdentificationResult
from problems.identify.results import joints_text

#: Diagnostic figures drawn in the report, at most (the one behind the unexplained structure first,
#: then the other significant ones; the per-axis diagnostics of one joint share a figure).  A
#: diagnostic that is not significant is not drawn: the report names them in one line.
REPORT_DIAGNOSTIC_PLOTS = 4
#: Diagnostics listed in the report's table besides the significant ones (the strongest first).
REPORT_DIAGNOSTIC_ROWS = 5
#: Names and units of the diagnostic variables (x axes and titles of the diagnostic figures).
VARIABLE_LABELS = {
    "time": ("time", "s, or row number without a t column"),
    "load_magnitude": ("applied force |f|", "N"),
    "load_sign": ("sign pattern of the force components", "-"),
    "joint_torque": ("largest joint torque |τ_j| of the applied wrench", "N·m"),
    "gravity_torque": ("nominal gravity torque of the joint that varies most", "N·m"),
    "temperature": ("temperature", "°C"),
    "position": ("horizontal distance of the nominal TCP from the base axis", "m"),
    "pose": ("pose index", "-"),
    # joint angles: SI (rad) in the library, drawn in degrees
    **{f"q{j}": (f"joint {j} angle (error of joint {j})", "deg") for j in range(1, 7)},
    **{f"q{j}.{a}": (f"joint {j} angle (residual {a})", "deg") for j in range(1, 7) for a in "xyz"},
}
#: Units of the diagnostic variables (kept for callers of the unit alone).
VARIABLE_UNITS = {k: u for k, (_name, u) in VARIABLE_LABELS.items()}


def axis_diag(variable: str) -> tuple[int, str] | None:
    """(joint, axis) of a per-axis joint-angle diagnostic ``q3.x``, else None."""
    m = re.fullmatch(r"q([1-6])\.([xyz])", variable)
    return (int(m.group(1)), m.group(2)) if m else None


def is_angle(variable: str) -> bool:
    """Whether a diagnostic variable is a joint angle (rad inside, drawn in degrees)."""
    return re.fullmatch(r"q[1-6](\.[xyz])?", variable) is not None


def var_name(variable: str) -> str:
    """The words for a diagnostic variable (its key when it has none)."""
    return VARIABLE_LABELS.get(variable, (variable, "-"))[0]


def diag_groups(res: IdentificationResult) -> list[tuple[str, list[Diagnostic]]]:
    """The diagnostic figures to draw, at most :data:`REPORT_DIAGNOSTIC_PLOTS`, significant ones
    only: the variable behind the unexplained structure first, then the others by explained
    fraction.  The per-axis diagnostics of one joint (``q3.x``, ``q3.y``, ``q3.z``) share one figure
    (key ``q3.xyz``, one panel per axis, the non-significant axes drawn beside the significant)."""
    diags = [d for d in res.diagnostics if d.x is not None and d.significant]
    want = res.unexplained.get("variable")
    diags.sort(key=lambda d: (d.variable != want, -d.explained_fraction))
    groups: dict[str, list[Diagnostic]] = {}
    for d in diags:
        ax = axis_diag(d.variable)
        key = f"q{ax[0]}.xyz" if ax else d.variable
        if key in groups:
            groups[key].append(d)
        elif len(groups) < REPORT_DIAGNOSTIC_PLOTS:
            groups[key] = [d]
    return list(groups.items())


def _joint_of(variable: str) -> int | None:
    """The joint of a joint-angle diagnostic (``q3``, ``q3.x``, ``q3.rz``), else None."""
    m = re.fullmatch(r"q([1-6])(\.r?[xyz])?", variable)
    return int(m.group(1)) if m else None


def not_significant_line(diags: list[dict[str, Any]]) -> str:
    """One line naming where nothing is significant (those are not drawn): the joints none of whose
    angle diagnostics is significant, then the other variables (``report.json`` diagnostics)."""
    sig_joints = {_joint_of(d["variable"]) for d in diags if d["significant"]} - {None}
    joints = sorted({j for d in diags if (j := _joint_of(d["variable"])) is not None} - sig_joints)
    others = [d["variable"] for d in diags if _joint_of(d["variable"]) is None and not d["significant"]]
    where = []
    if joints:
        where.append(joints_text(joints))
    if others:
        where.append(", ".join(others))
    if not where:
        return ""
    head = "no diagnostic is significant" if not any(d["significant"] for d in diags) else "nothing significant"
    return f"{head} on {' or on '.join(where)}: not drawn"


def shown_diagnostics(diags: list[dict[str, Any]]) -> tuple[list[dict[str, Any]], int]:
    """The diagnostics the report's table lists (every significant one, then the
    :data:`REPORT_DIAGNOSTIC_ROWS` strongest others) and how many others it leaves out."""
    sig = [d for d in diags if d["significant"]]
    rest = sorted((d for d in diags if not d["significant"]), key=lambda d: -(d["explained_fraction"] or 0.0))
    return sig + rest[:REPORT_DIAGNOSTIC_ROWS], max(len(rest) - REPORT_DIAGNOSTIC_ROWS, 0)
