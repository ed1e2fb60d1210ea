"""Instrument drift (measurement only): ``p_meas += v tn + a tn^2``, ``tn`` the time since
the first measurement over the campaign span (zero at the first measurement)."""

from __future__ import annotations

from typing import Any

from .base import MEASUREMENT, Effect, ParamGroup, register, xyz_labels


@register
class Drift(Effect):
    name = "drift"
    order = 10
    acts_on = MEASUREMENT
    groups = (
        ParamGroup("drift.v", xyz_labels("drift.v"), "m", scale=1e-4),
        ParamGroup("drift.a", xyz_labels("drift.a"), "m", scale=1e-4),
    )
    needs = ("time",)
    formula = "measurement drift p_meas += v tn + a tn^2, tn = time since the first row over the campaign span"
    simulation = "drift"

    def measurement(self, ctx: Any, p: Any) -> Any:
        return p + ctx.p("drift.v") * ctx.tn + ctx.p("drift.a") * ctx.tn * ctx.tn
