"""How to plan a program for a controller whose motion between the samples exceeds a limit
(``docs/export.md``, "A program plan's feed is not changed by default").

A controller that interpolates between the plan's samples (ROS 2's quintic spline) overshoots the
limits the plan kept at them by a ratio that hardly depends on the limits themselves (the 13-move
part of ``tests/test_program_path.py``: the spline's jerk 1.33x the plan's at ``jerk_scale = 1``,
1.37x at ``0.75``).  What the controller runs is checked against the robot's own limits
(:meth:`~planner.export.data.ExportData.robot_limit`), so a plan made with headroom, its
``[limits] <quantity>_scale`` below the robot's by that ratio, exports within them at its programmed
feed.  :func:`headroom_advice` names that scale for each quantity over its limit.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from planner.export.motion import RATES, Peak

if TYPE_CHECKING:
    from planner.export.data import ExportData

__all__ = ["HEADROOM_MARGIN", "headroom_advice", "suggested_scale"]

#: The advised scale leaves this much more headroom than the measured ratio asks: the ratio of the
#: controller's overshoot changes a little with the limits it is planned with (1.33x -> 1.37x
#: from ``jerk_scale`` 1 to 0.75 on the part of ``tests/test_program_path.py``).
HEADROOM_MARGIN = 0.05
#: Two limits agree (a uniform ``*_scale`` of the robot's) within this relative difference.
SCALE_RTOL = 1e-9
_NAMES = tuple(name for name, _u, _n in RATES)


def suggested_scale(data: ExportData, peak: Peak) -> tuple[float, float]:
    """The scale of the robot's limit to plan ``peak``'s quantity with, and the current one.

    The controller's motion reaches ``|peak.value|`` = ``r`` times the plan's limit on joint
    ``peak.joint``; planned at ``1 / (r (1 + HEADROOM_MARGIN))`` of the robot's limit, with the same
    ratio ``r``, it stays below the robot's limit by the margin.  Rounded down to two significant
    digits.

    Returns
    -------
    (float, float)
        The suggested scale and the plan's (its limit over the robot's, on that joint).
    """
    j = peak.joint
    plan = float(data.plan_limit(peak.quantity)[j])
    robot = float(data.robot_limit(peak.quantity)[j])
    r = abs(peak.value) / plan
    return _round_down(1.0 / (r * (1.0 + HEADROOM_MARGIN))), plan / robot


def _round_down(x: float) -> float:
    """``x`` > 0 rounded down to two significant digits."""
    step = 10.0 ** (math.floor(math.log10(x)) - 1)
    return math.floor(x / step * (1.0 + 1e-12)) * step


def _uniform(data: ExportData, name: str) -> bool:
    """The plan's limits of ``name`` are one scale of the robot's own (a ``*_scale`` or none)."""
    if not data.robot_limits_known:
        return False
    s = data.plan_limit(name) / data.robot_limit(name)
    return bool(np.allclose(s, s[0], rtol=SCALE_RTOL, atol=0.0))


def headroom_advice(data: ExportData, over: list[Peak]) -> str:
    """The end of a program plan's refusal: the ``[limits]`` scale to plan each quantity of
    ``over`` (rate peaks over the robot's limit, finite) with, or empty when none is.

    ``"; or plan it for this controller: in the problem's [limits] set jerk_scale = 0.71 (...)"``:
    with the ratio of the controller's motion to the plan's limit, the current scale, and that each
    quantity's scale gives only its own headroom.
    """
    worst: dict[str, Peak] = {}
    for p in over:
        if p.quantity in _NAMES and math.isfinite(p.value) and p.over:
            if p.quantity not in worst or p.ratio > worst[p.quantity].ratio:
                worst[p.quantity] = p
    if not worst:
        return ""
    sets, why = [], []
    for name in _NAMES:
        if name not in worst:
            continue
        p = worst[name]
        new, now = suggested_scale(data, p)
        reach = abs(p.value) / float(data.plan_limit(name)[p.joint])
        if _uniform(data, name):
            sets.append(f"{name}_scale = {new:.2g}" + (f" instead of {now:.4g}" if abs(now - 1.0) > SCALE_RTOL else ""))
        else:
            robot = f" ({new:.2g}x the robot's on joint {p.joint + 1})" if data.robot_limits_known else ""
            sets.append(f"{name} to x{_round_down(new / now):.2g} of the plan's {name} limits{robot}")
        why.append(f"{name} {reach:.4g}x the plan's limit on joint {p.joint + 1}")
    return (
        f"; or plan it for this controller: in the problem's [limits] set {' and '.join(sets)} (what the controller "
        f"runs reaches {', '.join(why)}; planned with that headroom it stays within the robot's limits, "
        f"{HEADROOM_MARGIN:.0%} to spare; velocity_scale, acceleration_scale and jerk_scale each give headroom "
        "to their own quantity only)"
    )
