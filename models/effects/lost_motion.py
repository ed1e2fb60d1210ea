"""Lost motion (backlash): a smooth dead band ``dq_i += b_i tanh(tau_i / (exp(rho) tau_s,i))``,
``b`` half the lost motion (rad); ``exp(rho) <= 5 %`` keeps the band sharp (a gradual change
of compliance with torque is ``stiffness_hardening``)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .base import Effect, ParamGroup, joint_labels, register

#: Bounds of the shape parameter ``rho = ln(tau_0 / tau_s)``.
LOST_MOTION_RHO_BOUNDS = (float(np.log(1e-3)), float(np.log(0.05)))

#: Initial shape: ``tau_0 = exp(rho) tau_s``.
LOST_MOTION_RHO_INIT = float(np.log(0.01))


@register
class LostMotion(Effect):
    name = "lost_motion"
    order = 7
    groups = (ParamGroup("lost_motion.b", joint_labels("lost_motion.b"), "rad", scale=1e-4),
              ParamGroup("lost_motion.rho", ("lost_motion.rho",), "1", scale=1.0, default=LOST_MOTION_RHO_INIT,
                         bounds=LOST_MOTION_RHO_BOUNDS))
    needs = ("load",)
    formula = "smooth dead band dq_i += b_i tanh(tau_i / (exp(rho) tau_s,i)), b = half the lost motion"
    simulation = "lost_motion"

    def joints_acting(self, param: Any) -> np.ndarray:
        return np.asarray(param("lost_motion.b")).reshape(6) != 0.0

    def joint_deflection(self, ctx: Any, tau: Any) -> Any:
        tau0 = ca.exp(ctx.p("lost_motion.rho")) * ctx.c("tau_scale")
        return ctx.p("lost_motion.b") * ca.tanh(tau / tau0)
