"""The measured point on the flange (declared model, measurement only).

The instrument measures a point (a reflector, a probe) whose position in the flange
frame is a parameter (m; its default is the robot file's TCP).  Planning uses the
robot file's TCP instead.  A 6-D instrument also measures the orientation of a frame
at that point: its rotation to the flange is ``R_tool0 R(r)`` (``measured_frame.R0`` a
fixed rotation, by default the robot file's TCP orientation or an initial fit to the
data; ``r`` a Cayley-vector correction, in use only with orientation data).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import MEASUREMENT, ConstGroup, Effect, ParamGroup, register, xyz_labels


@register
class MeasuredPoint(Effect):
    name = "measured_point"
    order = 1
    acts_on = MEASUREMENT
    declared = True
    groups = (
        ParamGroup("tool.p", xyz_labels("measured_point"), "m", scale=1e-3, default=lambda r: r.tcp2flange[:3, 3]),
        ParamGroup("tool.r", xyz_labels("measured_frame.w"), "1", scale=1e-3),
    )
    constants = (
        ConstGroup(
            "measured_frame.R0",
            9,
            lambda r: np.asarray(r.tcp2flange)[:3, :3].reshape(-1, order="F"),
            "rotation measured frame -> flange the correction r is applied to (3x3, column-major)",
        ),
        ConstGroup("measured_frame.on", 1, 0.0, "1 when the data measure orientation (tool.r in use)"),
    )
    formula = "the measured point (and, with orientation data, the measured frame), flange frame"
    simulation = "registration"

    def in_use(self, const: Any) -> dict[str, np.ndarray]:
        """The frame correction only with orientation data."""
        return {"tool.r": np.full(3, float(np.asarray(const("measured_frame.on")).reshape(-1)[0]) > 0.5)}
