"""ABB RAPID: a module with ``CONST jointtarget`` data (degrees) and ``MoveAbsJ`` instructions.

One target per decimated sample (every ``step_s`` s); each ``MoveAbsJ`` after the first carries
``\\T:=`` the time the planned trajectory takes from the previous target (RAPID's own way to
give a move's duration; the ``speeddata`` ``v_fallback`` applies only if ``\\T`` is removed),
zone ``z1`` between targets and ``fine`` at the ends, tool ``tool0``.  External axes 9E+09
(none).  Angles in degrees in the controller's convention (ABB: axes 1-6, its own zero).
"""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import ExportData, ExportFormat, header_lines, ranged, register_format

#: Printed decimals of joint angles (deg) and move times (s).
ANGLE_DECIMALS = 6
TIME_DECIMALS = 6


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    idx = data.decimated(float(o["step_s"]))
    qd = np.degrees(data.controller_q()[idx])
    t = data.t[idx]
    mod = stem[:16] if stem[:1].isalpha() else "M" + stem[:15]
    lines = [f"MODULE {mod}"] + ["  " + ln for ln in header_lines(data, "abb rapid", "!")]
    for k, q in enumerate(qd):
        vals = ",".join(f"{v:.{ANGLE_DECIMALS}f}" for v in q)
        lines.append(f"  CONST jointtarget jt{k}:=[[{vals}],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
    lines.append("  PROC main()")
    lines.append(f"    MoveAbsJ jt0\\NoEOffs, v{int(o['v_fallback'])}, fine, tool0;")
    for k in range(1, len(idx)):
        zone = "fine" if k == len(idx) - 1 else "z1"
        lines.append(
            f"    MoveAbsJ jt{k}\\NoEOffs, v{int(o['v_fallback'])}\\T:={t[k] - t[k - 1]:.{TIME_DECIMALS}f}, "
            f"{zone}, tool0;"
        )
    lines += ["  ENDPROC", "ENDMODULE", ""]
    return {f"{stem}.mod": "\n".join(lines)}


def _speed(v: Any) -> float:
    x = ranged("v_fallback", 5, 7000)(v)
    return float(math.floor(x))


register_format(
    ExportFormat(
        "rapid",
        (".mod",),
        write,
        {
            "step_s": (0.05, "time between the jointtargets, s", ranged("step_s", 0.004, 10.0)),
            "v_fallback": (1000.0, "speeddata vN used when \\T is removed, mm/s", _speed),
        },
        "ABB RAPID module: CONST jointtarget (deg) and MoveAbsJ with \\T from the timing",
    )
)
