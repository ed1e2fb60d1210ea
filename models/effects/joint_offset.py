"""Joint zero offsets: ``theta_i = q_i + theta_offset_i + dtheta_i`` (rad)."""

from __future__ import annotations

from typing import Any

from .base import Effect, ParamGroup, joint_labels, register


@register
class JointOffset(Effect):
    name = "joint_offset"
    order = 3
    groups = (ParamGroup("joint_offset.dtheta", joint_labels("dtheta"), "rad", scale=1e-3),)
    formula = "theta_i = q_i + theta_offset_i + dtheta_i"
    simulation = "joint_offset"

    def geometry(self, ctx: Any, dh: dict[str, Any]) -> dict[str, Any]:
        return {**dh, "theta_offset": dh["theta_offset"] + ctx.p("joint_offset.dtheta")}
