"""Thermal expansion: link lengths ``a_i, d_i`` scaled by ``1 + alpha_i (T - 20 C)``
(links longer than :data:`THERMAL_MIN_LINK_LENGTH_M`)."""

from __future__ import annotations

from typing import Any

from models.robot import Robot

from .base import Effect, ParamGroup, joint_labels, link_lengths, register

#: Reference temperature of the nominal link lengths (ISO 1), deg C.
THERMAL_REFERENCE_C = 20.0

#: A link takes part in ``thermal`` when its length exceeds this (m).
THERMAL_MIN_LINK_LENGTH_M = 0.01


def thermal_links(robot: Robot) -> list[int]:
    return [i for i in range(6) if link_lengths(robot)[i] > THERMAL_MIN_LINK_LENGTH_M]


@register
class Thermal(Effect):
    name = "thermal"
    order = 11
    groups = (
        ParamGroup(
            "thermal.alpha",
            joint_labels("thermal.alpha"),
            "1/K",
            scale=1e-5,
            eligible=lambda r: link_lengths(r) > THERMAL_MIN_LINK_LENGTH_M,
        ),
    )
    needs = ("temperature",)
    formula = "link lengths a_i, d_i scaled by (1 + alpha_i (T - 20 C))"
    simulation = "thermal"

    def geometry(self, ctx: Any, dh: dict[str, Any]) -> dict[str, Any]:
        s = 1.0 + ctx.p("thermal.alpha") * ctx.dT
        return {**dh, "a": dh["a"] * s, "d": dh["d"] * s}
