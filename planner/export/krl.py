"""KUKA KRL: a ``.src``/``.dat`` pair with axis-specific ``PTP`` motions.

The ``.dat`` declares one ``E6AXIS`` per decimated sample (every ``step_s`` s; degrees, the
controller's convention, external axes 0); the ``.src`` moves ``PTP`` to the first one, then
``PTP ... C_PTP`` through the others (approximated by ``$APO.CPTP``, an option).  Before each motion ``$VEL_AXIS[i]`` and ``$ACC_AXIS[i]``
are set to the percentage of the robot file's velocity and acceleration limits that the
planned trajectory uses on that segment (rounded up, 1 to 100): KUKA's PTP then plans its own
profile within those, so the timing is reproduced approximately, not sample by sample
(stream the samples by RSI for that).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from planner.export import ExportData, ExportFormat, header_lines, ranged, register_format

#: Printed decimals of joint angles (deg).
ANGLE_DECIMALS = 6


def _pct(x: np.ndarray) -> list[int]:
    return [int(min(100, max(1, math.ceil(100.0 * float(v) - 1e-9)))) for v in x]


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    idx = data.decimated(float(o["step_s"]))
    qd = np.degrees(data.controller_q()[idx])
    name = stem[:24]
    src = ["&ACCESS RVP", "&REL 1", f"DEF {name}( )"] + ["  " + ln for ln in header_lines(data, "kuka krl", ";")]
    src += ["  BAS(#INITMOV, 0)", f"  $APO.CPTP={int(o['approximation_percent'])}"]
    dat = ["&ACCESS RVP", "&REL 1", f"DEFDAT {name} PUBLIC"]
    for k, q in enumerate(qd):
        axes = ",".join(f"A{i + 1} {v:.{ANGLE_DECIMALS}f}" for i, v in enumerate(q))
        dat.append(f"  DECL E6AXIS XP{k}={{{axes},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}")
    for k in range(len(idx)):
        lo, hi = (idx[k - 1], idx[k]) if k else (0, 1)
        v = np.abs(data.qd[lo:hi + 1]).max(axis=0) / data.v_max
        a = np.abs(data.qdd[lo:hi + 1]).max(axis=0) / data.a_max
        vs, as_ = (_pct(v), _pct(a)) if k else ([int(o["approach_percent"])] * 6, [int(o["approach_percent"])] * 6)
        src += [f"  $VEL_AXIS[{i + 1}]={vs[i]}" for i in range(6)] + [f"  $ACC_AXIS[{i + 1}]={as_[i]}" for i in range(6)]
        src.append(f"  PTP XP{k}" + (" C_PTP" if 0 < k < len(idx) - 1 else ""))
    src += ["END", ""]
    dat += ["ENDDAT", ""]
    return {f"{name}.src": "\n".join(src), f"{name}.dat": "\n".join(dat)}


def _percent(name: str) -> Any:
    return lambda v: int(ranged(name, 1, 100)(v))


register_format(ExportFormat(
    "krl", (".src", ".dat"), write,
    {"step_s": (0.1, "time between the E6AXIS points, s", ranged("step_s", 0.012, 10.0)),
     "approach_percent": (10, "$VEL_AXIS / $ACC_AXIS of the PTP to the start, %", _percent("approach_percent")),
     "approximation_percent": (50, "$APO.CPTP of the C_PTP approximation, % (1-100)",
                               _percent("approximation_percent"))},
    "KUKA KRL .src/.dat pair: E6AXIS points (deg), PTP with $VEL_AXIS/$ACC_AXIS percentages"))
