"""Load offset: the external force acts at ``TCP + R_tcp r_tool + r_base`` rather than at the
TCP, which adds the moment ``r x f`` (and moves the point link compliance bends about)."""

from __future__ import annotations

from typing import Any

import casadi as ca

from .base import Effect, ParamGroup, register, xyz_labels


@register
class LoadOffset(Effect):
    name = "load_offset"
    order = 8
    groups = (
        ParamGroup("load_offset.r_tool", xyz_labels("load_offset.r_tool"), "m", scale=1e-2),
        ParamGroup("load_offset.r_base", xyz_labels("load_offset.r_base"), "m", scale=1e-2),
    )
    needs = ("load",)
    formula = "the force acts at TCP + R_tcp r_tool + r_base: extra moment r x f"
    simulation = "load_offset"

    def moment_arm(self, ctx: Any) -> Any:
        return ca.mtimes(ctx.R_tcp, ctx.p("load_offset.r_tool")) + ctx.p("load_offset.r_base")
