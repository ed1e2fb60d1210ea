"""The measured point on the flange (declared model, measurement only).

The instrument measures a point (a reflector, a probe) whose position in the flange
frame is a parameter (m; its default is the robot file's TCP).  Planning uses the
robot file's TCP instead.
"""

from __future__ import annotations

from .base import MEASUREMENT, Effect, ParamGroup, register, xyz_labels


@register
class MeasuredPoint(Effect):
    name = "measured_point"
    order = 1
    acts_on = MEASUREMENT
    declared = True
    groups = (ParamGroup("tool.p", xyz_labels("measured_point"), "m", scale=1e-3,
                         default=lambda r: r.tcp2flange[:3, 3]),)
    formula = "the measured point, flange frame"
