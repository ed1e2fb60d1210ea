"""ABB RAPID: a module with ``CONST jointtarget`` data (degrees) and ``MoveAbsJ`` instructions.

One target per decimated sample (every ``step_s`` s); each ``MoveAbsJ`` after the first carries
``\\T:=`` the time the planned trajectory takes from the previous target (RAPID's own way to
give a move's duration; the ``speeddata`` ``v_fallback`` applies only if ``\\T`` is removed),
zone ``z1`` between targets and ``fine`` at the ends, tool ``tool0``.  External axes 9E+09
(none).  Angles in degrees in the controller's convention (ABB: axes 1-6, its own zero).
Checked (:func:`motion`): the targets at their times against every limit; ABB does not document
the joint motion between them, and the export warns so.

Big programs: more than ``max_targets`` targets (default :data:`RAPID_MAX_TARGETS`) are split
into numbered part modules ``NAME_p001.mod`` ... of at most ``max_targets`` targets, each with
one routine of the same name, and ``NAME.mod`` becomes the driver: it moves to the first target,
then loads the parts in turn from ``load_path`` with ``Load``/``StartLoad``/``WaitLoad`` (the next
part loads while the current one runs, the finished one is unloaded) and calls each by late
binding (``%"NAME_p001"%``), so only two parts are in program memory at a time
(``docs/export.md``, "Big programs").
"""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import (
    ControllerMotion,
    ExportData,
    ExportError,
    ExportFormat,
    Interpolation,
    counted,
    header_lines,
    part_label,
    part_ranges,
    ranged,
    register_format,
)
from planner.export.parts import decimation_change, parts_change

#: Printed decimals of joint angles (deg) and move times (s).
ANGLE_DECIMALS = 6
TIME_DECIMALS = 6
#: Module names are cut to this many characters.
MODULE_NAME_MAX = 16
#: Most targets (``CONST jointtarget`` + ``MoveAbsJ``) in one module; more are split into part
#: modules loaded in turn.  ABB publishes no per-module limit: the RAPID program memory of the
#: task is the limit (shared by every loaded module), so a CAM-sized path is run as modules
#: loaded and unloaded during execution (``Load``, ``StartLoad``, ``WaitLoad``, ``UnLoad``).
#: 5,000 targets are about 1 MB of module text.
RAPID_MAX_TARGETS = 5000
#: Most ``max_targets`` accepted (the option's range).
MAX_TARGETS_LIMIT = 10**9
#: Where the controller finds the part modules (``load_path`` default): the system's HOME folder.
LOAD_PATH = "HOME:"
#: The ``loadsession`` variable of the driver module.
LOAD_SESSION = "compplan_load"


def targets(data: ExportData, step_s: float, decimals: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Targets every ``step_s``: controller angles in degrees as printed (``decimals``), their times
    from the first as the controller adds up the printed move times (s), and the angles in the
    model's convention (rad).  Shared with KRL."""
    idx = data.decimated(step_s)
    deg = np.round(np.degrees(data.controller_q()[idx]), decimals)
    t = np.r_[0.0, np.cumsum(np.round(np.diff(data.t[idx]), TIME_DECIMALS))]
    return deg, t, (np.radians(deg) - data.offset) * data.sign


def motion(data: ExportData, o: Mapping[str, Any]) -> ControllerMotion:
    """The targets at their times; ABB does not document the joint motion between them."""
    _deg, t, q = targets(data, float(o["step_s"]), ANGLE_DECIMALS)
    return ControllerMotion(
        Interpolation.THROUGH_POINTS,
        "the MoveAbsJ targets",
        t,
        q,
        eps=math.radians(0.5 * 10.0**-ANGLE_DECIMALS),
        unchecked="ABB does not document the joint motion of MoveAbsJ with \\T between targets nor its z1 corner "
        "paths: between the targets the controller's own motion is not checked against the limits; the targets at "
        "their times are (docs/export.md)",
    )


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    qd, t, _model = targets(data, float(o["step_s"]), ANGLE_DECIMALS)
    mod = stem[:MODULE_NAME_MAX] if stem[:1].isalpha() else "M" + stem[: MODULE_NAME_MAX - 1]
    head = ["  " + ln for ln in header_lines(data, "abb rapid", "!")]
    v = int(o["v_fallback"])
    if len(t) > int(o["max_targets"]):
        return _parts(stem, mod, head, qd, t, v, int(o["max_targets"]), str(o["load_path"]))
    lines = [f"MODULE {mod}"] + head
    lines += [_target(k, q) for k, q in enumerate(qd)]
    lines.append("  PROC main()")
    lines.append(f"    MoveAbsJ jt0\\NoEOffs, v{v}, fine, tool0;")
    lines += _moves(t, v, range(1, len(t)))
    lines += ["  ENDPROC", "ENDMODULE", ""]
    return {f"{stem}.mod": "\n".join(lines)}


def _target(k: int, q: np.ndarray) -> str:
    vals = ",".join(f"{v:.{ANGLE_DECIMALS}f}" for v in q)
    return f"  CONST jointtarget jt{k}:=[[{vals}],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];"


def _moves(t: np.ndarray, v: int, ks: range) -> list[str]:
    """``MoveAbsJ jtk`` with ``\\T`` the time from target k - 1; ``fine`` at the last target."""
    return [
        f"    MoveAbsJ jt{k}\\NoEOffs, v{v}\\T:={t[k] - t[k - 1]:.{TIME_DECIMALS}f}, "
        f"{'fine' if k == len(t) - 1 else 'z1'}, tool0;"
        for k in ks
    ]


def _parts(
    stem: str, mod: str, head: list[str], qd: np.ndarray, t: np.ndarray, v: int, limit: int, path: str
) -> dict[str, str]:
    """The driver module ``NAME.mod`` (first target, then the parts loaded and called in turn) and
    the part modules of targets 1 ... (at most ``limit`` each)."""
    ranges = [(a + 1, b + 1) for a, b in part_ranges(len(t) - 1, limit)]
    n = len(ranges)
    label = [part_label(k, n) for k in range(1, n + 1)]
    files = [f"{stem}_{lab}.mod" for lab in label]
    procs = [f"{mod[: MODULE_NAME_MAX - len(lab) - 1]}_{lab}" for lab in label]
    p = f'"{path}"'
    out: dict[str, str] = {}
    drv = (
        [f"MODULE {mod}"]
        + head
        + [
            f'  ! {n} part modules of at most {limit} targets (max_targets; docs/export.md "Big programs"): copy '
            f"{files[0]} ... {files[-1]} to {path}",
            "  ! each is loaded while the previous one runs and unloaded when it is done",
            _target(0, qd[0]),
            f"  VAR loadsession {LOAD_SESSION};",
            "  PROC main()",
            f"    MoveAbsJ jt0\\NoEOffs, v{v}, fine, tool0;",
            f'    Load \\Dynamic, {p} \\File:="{files[0]}";',
        ]
    )
    for k in range(n):
        if k + 1 < n:
            drv.append(f'    StartLoad \\Dynamic, {p} \\File:="{files[k + 1]}", {LOAD_SESSION};')
        drv.append(f'    %"{procs[k]}"%;')
        if k + 1 < n:
            drv.append(f'    WaitLoad \\UnloadPath:={p} \\UnloadFile:="{files[k]}", {LOAD_SESSION};')
        else:
            drv.append(f'    UnLoad {p} \\File:="{files[k]}";')
    drv += ["  ENDPROC", "ENDMODULE", ""]
    out[f"{stem}.mod"] = "\n".join(drv)
    for k, (a, b) in enumerate(ranges):
        lines = [f"MODULE {procs[k]}"] + head
        lines.append(
            f"  ! part {k + 1} of {n}: targets {a} to {b - 1} of {len(t) - 1} (t = {t[a]:.6g} to {t[b - 1]:.6g} s)"
        )
        lines += [_target(j, qd[j]) for j in range(a, b)]
        lines.append(f"  PROC {procs[k]}()")
        lines += _moves(t, v, range(a, b))
        lines += ["  ENDPROC", "ENDMODULE", ""]
        out[files[k]] = "\n".join(lines)
    return out


def _path(v: Any) -> str:
    text = str(v).strip()
    if not text or '"' in text or "\\" in text or len(text) > 80:
        raise ExportError(
            f"export option load_path = {v!r}: expected a controller folder such as HOME: or HOME:/big "
            "(no quotes or backslashes)"
        )
    return text


def _speed(v: Any) -> float:
    x = ranged("v_fallback", 5, 7000)(v)
    return float(math.floor(x))


def changes(data: ExportData, o: Mapping[str, Any]) -> tuple[str, ...]:
    """Decimated to the targets, and split into part modules (``max_targets``)."""
    n = len(data.decimated(float(o["step_s"])))
    return (
        decimation_change(n, len(data.t), float(o["step_s"]), "MoveAbsJ"),
        *parts_change(n, int(o["max_targets"]), "targets", "max_targets", "part module"),
    )


register_format(
    ExportFormat(
        "rapid",
        (".mod",),
        write,
        {
            "step_s": (0.05, "time between the jointtargets, s", ranged("step_s", 0.004, 10.0)),
            "v_fallback": (1000.0, "speeddata vN used when \\T is removed, mm/s", _speed),
            "max_targets": (
                RAPID_MAX_TARGETS,
                "most targets in one module; more are split into part modules NAME_p001.mod ... loaded in turn",
                counted("max_targets", 2, MAX_TARGETS_LIMIT),
            ),
            "load_path": (LOAD_PATH, "controller folder the driver module loads the part modules from", _path),
        },
        "ABB RAPID module: CONST jointtarget (deg) and MoveAbsJ with \\T from the timing",
        motion=motion,
        timing_options=("step_s",),
        changes=changes,
    )
)
