"""URScript: ``urscript`` streams the trajectory by ``servoj``; ``urscript_movej`` is a list of
``movej`` moves with blend radii for low-rate use.

``urscript``: a ``movej`` to the first sample (joint speed ``approach_speed`` rad/s,
acceleration ``approach_acceleration`` rad/s^2), then one ``servoj(q, t=period,
lookahead_time=..., gain=...)`` per controller period (the trajectory is resampled to
``period`` by the quintic through its samples' positions, velocities and accelerations when its
own sample period differs; the default is the trajectory's own dt): e-series 0.002 s, CB3
0.008 s.  UR's documented ranges: ``lookahead_time`` 0.03 to 0.2 s, ``gain`` 100 to 2000.  The
setpoints as written are checked at the period (:func:`servoj_motion`; slowed down or refused).
``urscript_movej``: one ``movej(q, t=..., r=...)`` per decimated sample (every ``step_s`` s),
``t`` the time the trajectory takes between them, ``r`` the blend radius (m, 0 at the end);
without blend every move stops at its target (:func:`movej_motion`: refused for a jerk limit).
Angles are radians in the controller's convention (UR: base, shoulder, elbow, wrist 1-3).

Big programs: a program of more than ``max_motions`` motion statements (default
:data:`URSCRIPT_MAX_MOTIONS`) is too big to send to a UR controller as one script, so both
formats then *stream* the motions instead: ``NAME.script`` becomes a short program that
connects to a PC (``stream_host``:``stream_port``) and reads one setpoint per motion with
``socket_read_ascii_float``, and ``NAME_stream.txt`` holds the setpoints, one ``(...)`` line each,
for the PC to serve (``nc -l PORT < NAME_stream.txt``).  Such a program needs ``stream_host`` (an
IPv4 or IPv6 address or a host name): without it the export is refused, naming the options that
write it (the host, or ``max_motions`` for one self-contained program).  The changes line says
which of the two was written and why.  Why and the sources: ``docs/export.md``, "Big programs".
"""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import (
    SLOW_DOWN_OPTION,
    ControllerMotion,
    ExportData,
    ExportError,
    ExportFormat,
    ExportRefusal,
    Interpolation,
    counted,
    header_lines,
    network_host,
    ranged,
    register_format,
)
from planner.export.quintic import quintic_coefficients

#: servoj periods a UR controller runs (e-series 500 Hz, CB3 125 Hz), s.
PERIOD_MIN_S = 0.002
PERIOD_MAX_S = 0.008
#: Printed decimals of joint angles (rad) and times (s).
ANGLE_DECIMALS = 9
TIME_DECIMALS = 6

#: Most motion statements (``movej`` + ``servoj``) one program holds; a longer trajectory is streamed.
#: UR documents no program size limit; users report scripts sent to the controller failing from
#: about 1,000 (ros-industrial/universal_robot#411) or 2,500 (visose/Robots#55) moves up.
URSCRIPT_MAX_MOTIONS = 2000
#: Most ``max_motions`` accepted (the option's range).
MAX_MOTIONS_LIMIT = 10**9
#: TCP port on the PC that serves the stream (the robot connects to it with ``socket_open``).
STREAM_PORT = 50010
#: URScript socket name of the stream.
STREAM_SOCKET = "compplan_stream"
#: Seconds the program waits for the first setpoint (the PC may start serving late), then for
#: each further one (a stream that stalls this long stops the robot).
STREAM_FIRST_TIMEOUT_S = 10.0
STREAM_TIMEOUT_S = 0.5
#: ``stopj`` deceleration when the stream breaks off, rad/s^2.
STREAM_ABORT_DECELERATION = 4.0
#: Rows formatted at a time when writing the stream (bounds the temporary Python objects).
STREAM_CHUNK = 10_000


def _vec(q: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.{ANGLE_DECIMALS}f}" for v in q) + "]"


def resample(data: ExportData, period: float) -> np.ndarray:
    """Positions (model convention, rad) every ``period`` s from 0 to the first multiple of
    ``period`` at or after the trajectory's end (held there), (M', 6): the trajectory's own samples
    when ``period`` is its ``dt``, else the quintic through each pair of samples' positions,
    velocities and accelerations (exact at the samples, continuous to the acceleration)."""
    if abs(period - data.dt) < 1e-12:
        return data.q
    n = int(math.ceil(data.t[-1] / period - 1e-9))
    t = np.arange(n + 1) * period
    i = np.clip(np.searchsorted(data.t, t, side="right") - 1, 0, len(data.t) - 2)
    c, h = quintic_coefficients(data.t[i[0] : i[-1] + 2], *(a[i[0] : i[-1] + 2] for a in (data.q, data.qd, data.qdd)))
    k = i - i[0]
    tau = np.minimum(t - data.t[i], h[k, 0])[:, None]
    q = np.zeros((len(t), 6))
    for ck in reversed(c):
        q = q * tau + ck[k]
    q[t >= data.t[-1] - 1e-12] = data.q[-1]
    return q


def _period(data: ExportData, o: Mapping[str, Any]) -> float:
    """The servoj period, s, as printed (``t=``): the option, else the plan's own ``dt``."""
    return round(float(o["period"]) if o["period"] is not None else _period_of(data), TIME_DECIMALS)


def _written(data: ExportData, q_model: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Controller angles as printed (:data:`ANGLE_DECIMALS`) and the same in the model's convention."""
    c = np.round(data.controller_q(q_model), ANGLE_DECIMALS)
    return c, (c - data.offset) * data.sign


def servoj_motion(data: ExportData, o: Mapping[str, Any]) -> ControllerMotion:
    """The servoj setpoints as written, every period from the first (the movej's target)."""
    period = _period(data, o)
    _c, q = _written(data, resample(data, period))
    plan_dt = data.dt / data.slow_factor
    return ControllerMotion(
        Interpolation.SETPOINTS,
        f"the servoj setpoints every {period:g} s",
        np.arange(len(q)) * period,
        q,
        eps=0.5 * 10.0**-ANGLE_DECIMALS,
        advice=(
            ""
            if abs(period - plan_dt) < 1e-12
            else f"; or plan at the servoj period (compplan plan --dt {period:g}), or export at the plan's "
            f"(--set period={plan_dt:g})"
        ),
        approach=(float(o["approach_speed"]), float(o["approach_acceleration"])),
    )


def write_servoj(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str | bytes]:
    period = _period(data, o)
    q, _model = _written(data, resample(data, period))
    lines = [f"def {stem}():"] + ["  " + ln for ln in header_lines(data, "urscript (servoj)", "#")]
    lines.append(f"  # servoj every {period:g} s, lookahead_time {o['lookahead_time']:g} s, gain {o['gain']:g}")
    servo = f"t={period:.{TIME_DECIMALS}f}, lookahead_time={o['lookahead_time']:g}, gain={o['gain']:g}"
    if len(q) > int(o["max_motions"]):
        return _streamed(stem, lines, o, q, None, f"servoj({{q}}, {servo})")
    lines.append(f"  movej({_vec(q[0])}, a={o['approach_acceleration']:g}, v={o['approach_speed']:g})")
    for qi in q[1:]:
        lines.append(f"  servoj({_vec(qi)}, {servo})")
    lines += ["  stopj(2.0)", "end", ""]
    return {f"{stem}.script": "\n".join(lines)}


def stream_lines(q: np.ndarray, extra: np.ndarray | None = None, formats: tuple[str, ...] = ()) -> bytes:
    """The setpoints as ``socket_read_ascii_float`` reads them: one ``(q1,...,q6[,extra...])`` line
    per row of ``q`` (rad, :data:`ANGLE_DECIMALS` decimals), ``extra`` (rows, k) printed with the
    ``%``-formats ``formats``; formatted :data:`STREAM_CHUNK` rows at a time."""
    fmt = "(" + ",".join([f"%.{ANGLE_DECIMALS}f"] * 6 + list(formats)) + ")\n"
    rows = q if extra is None else np.column_stack([q, extra])
    return b"".join(
        "".join([fmt % tuple(r) for r in rows[a : a + STREAM_CHUNK].tolist()]).encode()
        for a in range(0, len(rows), STREAM_CHUNK)
    )


def _streamed(
    stem: str, lines: list[str], o: Mapping[str, Any], q: np.ndarray, extra: np.ndarray | None, motion: str
) -> dict[str, str | bytes]:
    """A program that reads its setpoints from a socket (``socket_read_ascii_float``) and the stream
    file the PC serves: the first setpoint is the ``movej`` target, each further one a ``motion``
    (``{q}`` is the joint vector; ``{t}``, ``{r}`` the extra values of a movej list)."""
    host, port, n = str(o["stream_host"]), int(o["stream_port"]), len(q)
    if not host:
        raise ExportRefusal(_no_host(motion.split("(", 1)[0], n, o, ""))  # the motion word: servoj or movej
    width = 6 if extra is None else 6 + extra.shape[1]
    data = f"{stem}_stream.txt"
    where = f"{host}:{port}"
    lines += [
        f"  # streamed: {n} setpoints, more than the {int(o['max_motions'])} motion statements one program "
        'should hold (max_motions; docs/export.md "Big programs")',
        f"  # before starting it, serve {data} on TCP port {port} of the PC at stream_host, e.g. nc -l {port} < {data}",
        f'  if not socket_open("{host}", {port}, "{STREAM_SOCKET}"):',
        f'    popup("compplan: cannot connect to {where}; serve {data} there first (docs/export.md)", '
        'title="compplan stream", error=True, blocking=True)',
        "    halt",
        "  end",
        f'  q = socket_read_ascii_float({width}, "{STREAM_SOCKET}", {STREAM_FIRST_TIMEOUT_S:g})',
        f"  if q[0] != {width}:",
        f'    popup("compplan: no setpoint from {where}", title="compplan stream", error=True, blocking=True)',
        "    halt",
        "  end",
        f"  movej({_qref()}, a={o['approach_acceleration']:g}, v={o['approach_speed']:g})",
        "  k = 1",
        f"  while k < {n}:",
        f'    q = socket_read_ascii_float({width}, "{STREAM_SOCKET}", {STREAM_TIMEOUT_S:g})',
        f"    if q[0] != {width}:",
        f"      stopj({STREAM_ABORT_DECELERATION:g})",
        f'      popup("compplan: the stream from {where} broke off before setpoint {n}", title="compplan stream", '
        "error=True, blocking=True)",
        "      halt",
        "    end",
        "    " + motion.format(q=_qref(), t="q[7]", r="q[8]"),
        "    k = k + 1",
        "  end",
    ]
    if extra is None:
        lines.append("  stopj(2.0)")
    lines += [f'  socket_close("{STREAM_SOCKET}")', "end", ""]
    if extra is None:
        stream = stream_lines(q)
    else:
        stream = stream_lines(q, extra, (f"%.{TIME_DECIMALS}f", "%g"))
    return {f"{stem}.script": "\n".join(lines), data: stream}


def _qref() -> str:
    return "[" + ", ".join(f"q[{i}]" for i in range(1, 7)) + "]"


def _period_of(data: ExportData) -> float:
    """The plan's own sample period (before any slow-down) as the servoj period, if UR accepts it."""
    dt = data.dt / data.slow_factor
    if not PERIOD_MIN_S - 1e-12 <= dt <= PERIOD_MAX_S + 1e-12:
        raise ExportError(
            f"urscript: the trajectory's period {dt:g} s is outside the servoj periods "
            f"[{PERIOD_MIN_S:g}, {PERIOD_MAX_S:g}] s; give one with --set period=0.002 (e-series) "
            "or 0.008 (CB3)"
        )
    return dt


def _movej_targets(data: ExportData, o: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The movej targets as printed: controller angles (rad), their times from the first as the
    controller adds up the printed ``t`` (s), and the same angles in the model's convention."""
    idx = data.decimated(float(o["step_s"]))
    c, q = _written(data, data.q[idx])
    t = np.r_[0.0, np.cumsum(np.round(np.diff(data.t[idx]), TIME_DECIMALS))]
    return c, t, q


def movej_motion(data: ExportData, o: Mapping[str, Any]) -> ControllerMotion:
    """The movej targets at their times: without blend each move goes from rest to rest on UR's
    trapezoidal speed profile; with one, what the controller does in the blends is not documented."""
    _c, t, q = _movej_targets(data, o)
    blended = float(o["blend_radius"]) > 0.0
    return ControllerMotion(
        Interpolation.THROUGH_POINTS if blended else Interpolation.REST_TO_REST,
        "the movej targets"
        if blended
        else "the movej moves (r = 0: each from rest to rest in its t on a trapezoidal speed profile)",
        t,
        q,
        eps=0.5 * 10.0**-ANGLE_DECIMALS,
        unchecked=(
            f"UR does not document the motion of movej blends (blend_radius {float(o['blend_radius']):g} m): between "
            "the targets the arm follows the controller's blends, not checked against the limits; the targets at "
            "their times are (docs/export.md)"
            if blended
            else ""
        ),
        advice=(
            ""
            if blended
            else "; blend_radius 0 stops the arm at every target: give blend_radius > 0 (m, under half the TCP "
            "distance between targets) or use the urscript format (servoj)"
        ),
        approach=(float(o["approach_speed"]), float(o["approach_acceleration"])),
    )


def write_movej(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str | bytes]:
    q, t, _model = _movej_targets(data, o)
    lines = [f"def {stem}():"] + ["  " + ln for ln in header_lines(data, "urscript (movej list)", "#")]
    lines.append(
        f"  # movej every ~{o['step_s']:g} s, t = the planned time between them, blend r = {o['blend_radius']:g} m"
    )
    if len(q) > int(o["max_motions"]):
        r = np.full(len(q), float(o["blend_radius"]))
        r[0] = r[-1] = 0.0
        dt = np.r_[0.0, np.diff(t)]  # the first line's t and r are not used (movej at approach speed)
        return _streamed(stem, lines, o, q, np.column_stack([dt, r]), "movej({q}, t={t}, r={r})")
    lines.append(f"  movej({_vec(q[0])}, a={o['approach_acceleration']:g}, v={o['approach_speed']:g})")
    for k in range(1, len(q)):
        r = 0.0 if k == len(q) - 1 else float(o["blend_radius"])
        lines.append(f"  movej({_vec(q[k])}, t={t[k] - t[k - 1]:.{TIME_DECIMALS}f}, r={r:g})")
    lines += ["end", ""]
    return {f"{stem}.script": "\n".join(lines)}


def _no_host(what: str, n: int, o: Mapping[str, Any], alternative: str) -> str:
    """The refusal of a streamed program of ``what`` (``servoj``, ``movej``) without ``stream_host``:
    the options that write it."""
    fmt = "urscript" if what == "servoj" else "urscript_movej"
    return (
        f"{fmt}: {n} {what} motions are more than max_motions {int(o['max_motions'])} (what one program should "
        "hold), so they are streamed from a PC, and stream_host is not set: give --set stream_host=IP (the PC that "
        f"serves NAME_stream.txt){alternative}, or --set max_motions={n} for one self-contained program (UR scripts "
        'are reported to fail from 1,000-2,500 moves; docs/export.md "Big programs")'
    )


def _program_line(what: str, n: int, o: Mapping[str, Any], alternative: str = "") -> str:
    """The change line of a URScript export: one self-contained program, or streamed (and from where);
    refused (:class:`ExportRefusal`) when streamed without ``stream_host``."""
    limit = int(o["max_motions"])
    if n <= limit:
        return f"one self-contained program: {n} {what} motions, within max_motions {limit}"
    if not o["stream_host"]:
        raise ExportRefusal(_no_host(what, n, o, alternative))
    return (
        f"streamed from {o['stream_host']}:{int(o['stream_port'])}: {n} {what} setpoints in the _stream.txt file, more "
        f"than max_motions {limit} (what one program should hold)"
    )


def servoj_changes(data: ExportData, o: Mapping[str, Any]) -> tuple[str, ...]:
    """Resampled to the servoj period (when it is not the trajectory's), and one program or a stream."""
    period = _period(data, o)
    n = _setpoints(data, period)
    out = []
    if abs(period - data.dt) >= 1e-12:
        out.append(
            f"resampled from {data.dt * 1e3:g} ms to the servoj period {period * 1e3:g} ms (the quintic through "
            f"the samples): {n} setpoints"
        )
    alternative = ""
    wide = _setpoints(data, PERIOD_MAX_S)
    if period < PERIOD_MAX_S and wide <= int(o["max_motions"]):
        alternative = f", or --set period={PERIOD_MAX_S:g} (CB3) for {wide} setpoints in one program"
    return (*out, _program_line("servoj", n, o, alternative))


def _setpoints(data: ExportData, period: float) -> int:
    """How many servoj setpoints :func:`resample` gives at ``period`` (without resampling)."""
    if abs(period - data.dt) < 1e-12:
        return len(data.t)
    return int(math.ceil(data.t[-1] / period - 1e-9)) + 1


def movej_changes(data: ExportData, o: Mapping[str, Any]) -> tuple[str, ...]:
    """Decimated to the movej targets, and one program or a stream."""
    n = len(data.decimated(float(o["step_s"])))
    between = f"blended r = {float(o['blend_radius']):g} m" if float(o["blend_radius"]) > 0.0 else "stopping at each"
    return (
        f"decimated to a movej every ~{float(o['step_s']):g} s: {n} targets of {len(data.t)} samples, the "
        f"controller's own motion between them ({between})",
        _program_line("movej", n, o, ", or a larger step_s"),
    )


_COMMON = {
    "approach_speed": (0.5, "joint speed of the movej to the start, rad/s", ranged("approach_speed", 0.01, 3.2)),
    "approach_acceleration": (
        1.0,
        "joint acceleration of the movej to the start, rad/s^2",
        ranged("approach_acceleration", 0.01, 40.0),
    ),
    "max_motions": (
        URSCRIPT_MAX_MOTIONS,
        "most motion statements in one program; more are streamed from a PC (NAME_stream.txt)",
        counted("max_motions", 2, MAX_MOTIONS_LIMIT),
    ),
    "stream_host": (
        "",
        "IPv4/IPv6 address or host name of the PC that serves NAME_stream.txt (needed by a streamed program)",
        network_host("stream_host"),
    ),
    "stream_port": (STREAM_PORT, "TCP port of the stream on that PC", counted("stream_port", 1, 65535)),
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
            "slow_down": SLOW_DOWN_OPTION,
            **_COMMON,
        },
        "URScript program streaming the trajectory by servoj at the controller period",
        motion=servoj_motion,
        timing_options=("period", "slow_down", "approach_speed", "approach_acceleration"),
        changes=servoj_changes,
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
        motion=movej_motion,
        timing_options=("step_s", "blend_radius", "approach_speed", "approach_acceleration"),
        changes=movej_changes,
    )
)
