"""KUKA KRL: a ``.src``/``.dat`` pair, axis-specific motions through the sampled trajectory.

The ``.dat`` declares one ``E6AXIS`` per decimated sample (every ``step_s`` s; degrees, the
controller's convention, external axes 0).  The ``.src`` moves ``PTP`` to the first one at
``approach_percent`` of the axis limits, then, by ``motion``:

* ``"spline"`` (default; KSS 8.3 and later): one ``PTP_SPLINE`` block of ``SPTP`` motions
  through the other points inside a ``TIME_BLOCK``: after each ``SPTP`` a ``TIME_BLOCK PART``
  equal to that segment's planned duration (s), and ``TIME_BLOCK END`` the total, so the
  controller gives each segment its planned share of the planned time (the spline passes
  through the points; between them KUKA's spline shapes the motion).
* ``"ptp"``: ``PTP ... C_PTP`` through the points (approximated by ``$APO.CPTP``), each
  preceded by ``$VEL_AXIS[i]`` and ``$ACC_AXIS[i]``: the percentage of the robot file's
  velocity and acceleration limits the planned trajectory uses on that segment (rounded up,
  1 to 100); KUKA's PTP plans its own profile within those, so the timing is approximate.

Sample by sample reproduction needs streaming (RSI), not a program.
"""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import ExportData, ExportError, ExportFormat, header_lines, ranged, register_format

#: Printed decimals of joint angles (deg) and of the time-block parts (s).
ANGLE_DECIMALS = 6
TIME_DECIMALS = 6
#: KRL names: at most 24 characters.
NAME_MAX = 24
MOTIONS = ("spline", "ptp")


def _pct(x: np.ndarray) -> list[int]:
    return [int(min(100, max(1, math.ceil(100.0 * float(v) - 1e-9)))) for v in x]


def _axis_lines(vel: list[int], acc: list[int]) -> list[str]:
    return [f"  $VEL_AXIS[{i + 1}]={vel[i]}" for i in range(6)] + [f"  $ACC_AXIS[{i + 1}]={acc[i]}" for i in range(6)]


def _dat(name: str, qd: np.ndarray) -> list[str]:
    dat = ["&ACCESS RVP", "&REL 1", f"DEFDAT {name} PUBLIC"]
    for k, q in enumerate(qd):
        axes = ",".join(f"A{i + 1} {v:.{ANGLE_DECIMALS}f}" for i, v in enumerate(q))
        dat.append(f"  DECL E6AXIS XP{k}={{{axes},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}")
    return dat + ["ENDDAT", ""]


def _ptp(data: ExportData, idx: np.ndarray, o: Mapping[str, Any]) -> list[str]:
    src = [f"  $APO.CPTP={int(o['approximation_percent'])}"]
    for k in range(1, len(idx)):
        lo, hi = idx[k - 1], idx[k]
        src += _axis_lines(
            _pct(np.abs(data.qd[lo : hi + 1]).max(axis=0) / data.v_max),
            _pct(np.abs(data.qdd[lo : hi + 1]).max(axis=0) / data.a_max),
        )
        src.append(f"  PTP XP{k}" + (" C_PTP" if k < len(idx) - 1 else ""))
    return src


def _spline(data: ExportData, idx: np.ndarray) -> list[str]:
    t = data.t[idx]
    src = _axis_lines([100] * 6, [100] * 6) + ["  PTP_SPLINE", "    TIME_BLOCK START"]
    for k in range(1, len(idx)):
        src += [f"    SPTP XP{k}", f"    TIME_BLOCK PART = {t[k] - t[k - 1]:.{TIME_DECIMALS}f}"]
    src += [f"    TIME_BLOCK END = {t[-1] - t[0]:.{TIME_DECIMALS}f}", "  ENDSPLINE"]
    return src


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    idx = data.decimated(float(o["step_s"]))
    qd = np.degrees(data.controller_q()[idx])
    name = stem[:NAME_MAX]
    src = ["&ACCESS RVP", "&REL 1", f"DEF {name}( )"] + ["  " + ln for ln in header_lines(data, "kuka krl", ";")]
    src += [f"  ; motion {o['motion']}, a point every ~{o['step_s']:g} s"]
    src += ["  BAS(#INITMOV, 0)"] + _axis_lines([int(o["approach_percent"])] * 6, [int(o["approach_percent"])] * 6)
    src.append("  PTP XP0")
    src += _spline(data, idx) if o["motion"] == "spline" else _ptp(data, idx, o)
    src += ["END", ""]
    return {f"{name}.src": "\n".join(src), f"{name}.dat": "\n".join(_dat(name, qd))}


def _percent(name: str) -> Any:
    return lambda v: int(ranged(name, 1, 100)(v))


def _motion(v: Any) -> str:
    if str(v) not in MOTIONS:
        raise ExportError(f"export option motion = {v!r}: expected one of {', '.join(MOTIONS)}")
    return str(v)


register_format(
    ExportFormat(
        "krl",
        (".src", ".dat"),
        write,
        {
            "step_s": (0.1, "time between the E6AXIS points, s", ranged("step_s", 0.012, 10.0)),
            "motion": (
                "spline",
                "spline: PTP_SPLINE with TIME_BLOCK (planned times, KSS 8.3+); ptp: PTP C_PTP with "
                "$VEL_AXIS/$ACC_AXIS percentages",
                _motion,
            ),
            "approach_percent": (10, "$VEL_AXIS / $ACC_AXIS of the PTP to the start, %", _percent("approach_percent")),
            "approximation_percent": (
                50,
                "$APO.CPTP of the C_PTP approximation (motion ptp), % (1-100)",
                _percent("approximation_percent"),
            ),
        },
        "KUKA KRL .src/.dat pair: E6AXIS points (deg), a PTP_SPLINE time block or PTP with axis percentages",
    )
)
