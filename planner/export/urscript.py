"""URScript: ``urscript`` streams the trajectory by ``servoj``; ``urscript_movej`` is a list of
``movej`` moves with blend radii for low-rate use.

``urscript``: a ``movej`` to the first sample (joint speed ``approach_speed`` rad/s,
acceleration ``approach_acceleration`` rad/s^2), then one ``servoj(q, t=period,
lookahead_time=..., gain=...)`` per controller period (the trajectory is resampled to
``period`` by cubic Hermite interpolation of its positions and velocities when its own
sample period differs; the default is the trajectory's own dt): e-series 0.002 s, CB3 0.008 s.  UR's documented ranges:
``lookahead_time`` 0.03 to 0.2 s, ``gain`` 100 to 2000.
``urscript_movej``: one ``movej(q, t=..., r=...)`` per decimated sample (every ``step_s`` s),
``t`` the time the trajectory takes between them, ``r`` the blend radius (m, 0 at the end).
Angles are radians in the controller's convention (UR: base, shoulder, elbow, wrist 1-3).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import ExportData, ExportError, ExportFormat, header_lines, ranged, register_format

#: servoj periods a UR controller runs (e-series 500 Hz, CB3 125 Hz), s.
PERIOD_MIN_S = 0.002
PERIOD_MAX_S = 0.008
#: Printed decimals of joint angles (rad) and times (s).
ANGLE_DECIMALS = 9
TIME_DECIMALS = 6


def _vec(q: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.{ANGLE_DECIMALS}f}" for v in q) + "]"


def resample(data: ExportData, period: float) -> np.ndarray:
    """Positions (model convention, rad) every ``period`` s over the trajectory, (M', 6):
    cubic Hermite through the samples' positions and velocities; the last sample is kept."""
    if abs(period - data.dt) < 1e-12:
        return data.q
    t = np.arange(0.0, data.t[-1] + 0.5 * period, period)
    t[-1] = min(t[-1], data.t[-1])
    i = np.clip(np.searchsorted(data.t, t, side="right") - 1, 0, len(data.t) - 2)
    h = data.t[i + 1] - data.t[i]
    s = ((t - data.t[i]) / h)[:, None]
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    hh = h[:, None]
    q = h00 * data.q[i] + h10 * hh * data.qd[i] + h01 * data.q[i + 1] + h11 * hh * data.qd[i + 1]
    q[-1] = data.q[-1]
    return q


def write_servoj(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    period = float(o["period"]) if o["period"] is not None else _period_of(data)
    q = data.controller_q(resample(data, period))
    lines = [f"def {stem}():"] + ["  " + ln for ln in header_lines(data, "urscript (servoj)", "#")]
    lines.append(f"  # servoj every {period:g} s, lookahead_time {o['lookahead_time']:g} s, gain {o['gain']:g}")
    lines.append(f"  movej({_vec(q[0])}, a={o['approach_acceleration']:g}, v={o['approach_speed']:g})")
    for qi in q[1:]:
        lines.append(
            f"  servoj({_vec(qi)}, t={period:.{TIME_DECIMALS}f}, "
            f"lookahead_time={o['lookahead_time']:g}, gain={o['gain']:g})"
        )
    lines += ["  stopj(2.0)", "end", ""]
    return {f"{stem}.script": "\n".join(lines)}


def _period_of(data: ExportData) -> float:
    """The trajectory's own sample period as the servoj period, if UR accepts it."""
    if not PERIOD_MIN_S - 1e-12 <= data.dt <= PERIOD_MAX_S + 1e-12:
        raise ExportError(
            f"urscript: the trajectory's period {data.dt:g} s is outside the servoj periods "
            f"[{PERIOD_MIN_S:g}, {PERIOD_MAX_S:g}] s; give one with --set period=0.002 (e-series) "
            "or 0.008 (CB3)"
        )
    return data.dt


def write_movej(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    idx = data.decimated(float(o["step_s"]))
    q = data.controller_q()[idx]
    t = data.t[idx]
    lines = [f"def {stem}():"] + ["  " + ln for ln in header_lines(data, "urscript (movej list)", "#")]
    lines.append(
        f"  # movej every ~{o['step_s']:g} s, t = the planned time between them, blend r = {o['blend_radius']:g} m"
    )
    lines.append(f"  movej({_vec(q[0])}, a={o['approach_acceleration']:g}, v={o['approach_speed']:g})")
    for k in range(1, len(idx)):
        r = 0.0 if k == len(idx) - 1 else float(o["blend_radius"])
        lines.append(f"  movej({_vec(q[k])}, t={t[k] - t[k - 1]:.{TIME_DECIMALS}f}, r={r:g})")
    lines += ["end", ""]
    return {f"{stem}.script": "\n".join(lines)}


_COMMON = {
    "approach_speed": (0.5, "joint speed of the movej to the start, rad/s", ranged("approach_speed", 0.01, 3.2)),
    "approach_acceleration": (
        1.0,
        "joint acceleration of the movej to the start, rad/s^2",
        ranged("approach_acceleration", 0.01, 40.0),
    ),
}

register_format(
    ExportFormat(
        "urscript",
        (".script",),
        write_servoj,
        {
            "period": (
                None,
                "servoj period, s (e-series 0.002, CB3 0.008)",
                ranged("period", PERIOD_MIN_S, PERIOD_MAX_S),
            ),
            "lookahead_time": (0.1, "servoj lookahead_time, s (UR: 0.03-0.2)", ranged("lookahead_time", 0.03, 0.2)),
            "gain": (300.0, "servoj gain (UR: 100-2000)", ranged("gain", 100.0, 2000.0)),
            **_COMMON,
        },
        "URScript program streaming the trajectory by servoj at the controller period",
    )
)

register_format(
    ExportFormat(
        "urscript_movej",
        (".script",),
        write_movej,
        {
            "step_s": (0.1, "time between the movej targets, s", ranged("step_s", 0.008, 10.0)),
            "blend_radius": (0.0, "blend radius of the intermediate moves, m", ranged("blend_radius", 0.0, 0.5)),
            **_COMMON,
        },
        "URScript program of movej moves with blend radii (low-rate use)",
    )
)
