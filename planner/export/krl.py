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

Sample by sample reproduction needs streaming (RSI), not a program.  Checked (:func:`motion`): the
points (and, for ``spline``, their times) against every limit; KUKA does not publish what its
controller does between them, and the export warns so.

Big programs: more than ``max_points`` points (default :data:`KRL_MAX_POINTS`) are split into
numbered part modules ``NAME_p001.src``/``.dat`` ... of at most ``max_points`` points each (one
``PTP_SPLINE`` block with its own ``TIME_BLOCK``, or the ``PTP`` motions); ``NAME.src`` becomes
the main program that moves to the first point and calls the parts in order
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
    ExportFormat,
    Interpolation,
    choice,
    counted,
    header_lines,
    part_label,
    part_ranges,
    ranged,
    register_format,
)
from planner.export.parts import decimation_change, parts_change
from planner.export.rapid import targets

#: Printed decimals of joint angles (deg) and of the time-block parts (s).
ANGLE_DECIMALS = 6
TIME_DECIMALS = 6
#: KRL names: at most 24 characters.
NAME_MAX = 24
MOTIONS = ("spline", "ptp")
#: Most points (E6AXIS declarations and motions) in one module pair; more are split into part
#: modules called in order.  KUKA publishes no line limit for a module; what runs out is the
#: controller's RAM for loaded programs (a few MB in all on KSS 8.3, users report) and the
#: spline planner's buffer for one spline block, so each part is one block of modest size.
#: 1,000 points are about 190 kB of .src + .dat.
KRL_MAX_POINTS = 1000
#: Most ``max_points`` accepted (the option's range).
MAX_POINTS_LIMIT = 10**9


def _pct(x: np.ndarray) -> list[int]:
    return [int(min(100, max(1, math.ceil(100.0 * float(v) - 1e-9)))) for v in x]


def _axis_lines(vel: list[int], acc: list[int]) -> list[str]:
    return [f"  $VEL_AXIS[{i + 1}]={vel[i]}" for i in range(6)] + [f"  $ACC_AXIS[{i + 1}]={acc[i]}" for i in range(6)]


def _dat(name: str, qd: np.ndarray, first: int = 0) -> list[str]:
    """The data list: ``E6AXIS XPk`` for the rows of ``qd`` (deg), ``k`` from ``first``; declared
    without ``GLOBAL``, so each module's points are its own."""
    dat = ["&ACCESS RVP", "&REL 1", f"DEFDAT {name} PUBLIC"]
    for k, q in enumerate(qd, first):
        axes = ",".join(f"A{i + 1} {v:.{ANGLE_DECIMALS}f}" for i, v in enumerate(q))
        dat.append(f"  DECL E6AXIS XP{k}={{{axes},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}")
    return dat + ["ENDDAT", ""]


def _ptp(
    data: ExportData, idx: np.ndarray, o: Mapping[str, Any], ks: range | None = None, apo: bool = True
) -> list[str]:
    """``PTP XPk`` for ``k`` in ``ks`` (default 1 ... last), each after the axis percentages of
    its segment; ``C_PTP`` on all but the trajectory's last point."""
    src = [f"  $APO.CPTP={int(o['approximation_percent'])}"] if apo else []
    for k in ks if ks is not None else range(1, len(idx)):
        lo, hi = idx[k - 1], idx[k]
        src += _axis_lines(
            _pct(np.abs(data.qd[lo : hi + 1]).max(axis=0) / data.robot_limit("velocity")),
            _pct(np.abs(data.qdd[lo : hi + 1]).max(axis=0) / data.robot_limit("acceleration")),
        )
        src.append(f"  PTP XP{k}" + (" C_PTP" if k < len(idx) - 1 else ""))
    return src


def _spline(t: np.ndarray, ks: range | None = None, axes: bool = True) -> list[str]:
    """A ``PTP_SPLINE`` block of ``SPTP XPk`` for ``k`` in ``ks`` (default 1 ... last) in a
    ``TIME_BLOCK`` of their planned durations (``t``: the points' times, s)."""
    ks = ks if ks is not None else range(1, len(t))
    src = (_axis_lines([100] * 6, [100] * 6) if axes else []) + ["  PTP_SPLINE", "    TIME_BLOCK START"]
    for k in ks:
        src += [f"    SPTP XP{k}", f"    TIME_BLOCK PART = {t[k] - t[k - 1]:.{TIME_DECIMALS}f}"]
    src += [f"    TIME_BLOCK END = {t[ks[-1]] - t[ks[0] - 1]:.{TIME_DECIMALS}f}", "  ENDSPLINE"]
    return src


#: Why the motion between the points is not checked, by ``motion``.
UNCHECKED = {
    "spline": "KUKA does not publish the shape of SPTP splines in a TIME_BLOCK, and $VEL_AXIS/$ACC_AXIS 100 leave "
    "the controller's machine data as their only bound: between the points the motion is not checked against the "
    "limits; the points at their times are (docs/export.md)",
    "ptp": "KUKA plans each PTP's profile itself within $VEL_AXIS/$ACC_AXIS, percentages of its machine data set "
    "from the robot file's limits (within those limits only if they are the machine data); its jerk, the C_PTP "
    "approximation and the times are the controller's: not checked against the limits; the points are "
    "(docs/export.md)",
}


def motion(data: ExportData, o: Mapping[str, Any]) -> ControllerMotion:
    """The points (and, for ``spline``, their times); KUKA does not document the motion between them."""
    _deg, t, q = targets(data, float(o["step_s"]), ANGLE_DECIMALS)
    return ControllerMotion(
        Interpolation.THROUGH_POINTS,
        "the E6AXIS points",
        t if o["motion"] == "spline" else None,
        q,
        eps=math.radians(0.5 * 10.0**-ANGLE_DECIMALS),
        unchecked=UNCHECKED[str(o["motion"])],
    )


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    idx = data.decimated(float(o["step_s"]))
    qd, t, _model = targets(data, float(o["step_s"]), ANGLE_DECIMALS)
    name = stem[:NAME_MAX]
    src = ["&ACCESS RVP", "&REL 1", f"DEF {name}( )"] + ["  " + ln for ln in header_lines(data, "kuka krl", ";")]
    src += [f"  ; motion {o['motion']}, a point every ~{o['step_s']:g} s"]
    src += ["  BAS(#INITMOV, 0)"] + _axis_lines([int(o["approach_percent"])] * 6, [int(o["approach_percent"])] * 6)
    src.append("  PTP XP0")
    if len(idx) > int(o["max_points"]):
        return _parts(data, idx, qd, t, stem, src, o)
    src += _spline(t) if o["motion"] == "spline" else _ptp(data, idx, o)
    src += ["END", ""]
    return {f"{name}.src": "\n".join(src), f"{name}.dat": "\n".join(_dat(name, qd))}


def _parts(
    data: ExportData, idx: np.ndarray, qd: np.ndarray, t: np.ndarray, stem: str, src: list[str], o: Mapping[str, Any]
) -> dict[str, str]:
    """The main pair ``NAME.src``/``.dat`` (XP0, then a call of each part) and the part pairs of
    points 1 ... (at most ``max_points`` each)."""
    limit = int(o["max_points"])
    name = stem[:NAME_MAX]
    ranges = [(a + 1, b + 1) for a, b in part_ranges(len(idx) - 1, limit)]
    n = len(ranges)
    labels = [part_label(k, n) for k in range(1, n + 1)]
    parts = [f"{stem[: NAME_MAX - len(lab) - 1]}_{lab}" for lab in labels]
    spline = o["motion"] == "spline"
    src.insert(
        src.index("  PTP XP0"),
        f'  ; {n} part modules of at most {limit} points (max_points; docs/export.md "Big programs"): '
        f"{parts[0]} ... {parts[-1]}, .src and .dat each, in the folder of this program",
    )
    src += _axis_lines([100] * 6, [100] * 6) if spline else [f"  $APO.CPTP={int(o['approximation_percent'])}"]
    src += [f"  {p}( )" for p in parts] + ["END", ""]
    out = {f"{name}.src": "\n".join(src), f"{name}.dat": "\n".join(_dat(name, qd[:1]))}
    head = ["  " + ln for ln in header_lines(data, "kuka krl", ";")]
    for k, ((a, b), part) in enumerate(zip(ranges, parts), 1):
        body = ["&ACCESS RVP", "&REL 1", f"DEF {part}( )"] + head
        body.append(f"  ; part {k} of {n}: points XP{a} to XP{b - 1} of XP{len(idx) - 1}, motion {o['motion']}")
        body.append(f"  ; called by {name}")
        if spline:
            body += _spline(t, range(a, b), axes=False)
        else:
            body += _ptp(data, idx, o, range(a, b), apo=False)
        body += ["END", ""]
        out[f"{part}.src"] = "\n".join(body)
        out[f"{part}.dat"] = "\n".join(_dat(part, qd[a:b], first=a))
    return out


def _percent(name: str) -> Any:
    return lambda v: int(ranged(name, 1, 100)(v))


def changes(data: ExportData, o: Mapping[str, Any]) -> tuple[str, ...]:
    """Decimated to the points, split into part modules (``max_points``), and, for ``ptp``, timed by KUKA."""
    n = len(data.decimated(float(o["step_s"])))
    out = [decimation_change(n, len(data.t), float(o["step_s"]), "SPTP" if o["motion"] == "spline" else "PTP")]
    out += parts_change(n, int(o["max_points"]), "points", "max_points", "part module pair")
    if o["motion"] == "ptp":
        out.append("motion ptp: KUKA plans each PTP within $VEL_AXIS/$ACC_AXIS, so the timing is approximate")
    return tuple(out)


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
                choice("motion", MOTIONS),
            ),
            "approach_percent": (10, "$VEL_AXIS / $ACC_AXIS of the PTP to the start, %", _percent("approach_percent")),
            "approximation_percent": (
                50,
                "$APO.CPTP of the C_PTP approximation (motion ptp), % (1-100)",
                _percent("approximation_percent"),
            ),
            "max_points": (
                KRL_MAX_POINTS,
                "most points in one module; more are split into part modules NAME_p001.src/.dat ... called in order",
                counted("max_points", 2, MAX_POINTS_LIMIT),
            ),
        },
        "KUKA KRL .src/.dat pair: E6AXIS points (deg), a PTP_SPLINE time block or PTP with axis percentages",
        motion=motion,
        timing_options=("step_s", "motion"),
        changes=changes,
    )
)
