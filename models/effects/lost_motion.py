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

#: A joint torque within this many transition torques ``tau_0`` of zero leaves the joint inside
#: its dead band (tanh(3) = 0.995: beyond it the band is taken up).
DEAD_BAND_MARGIN = 3.0

#: Initial shape: ``tau_0 = exp(rho) tau_s``.
LOST_MOTION_RHO_INIT = float(np.log(0.01))


@register
class LostMotion(Effect):
    name = "lost_motion"
    order = 7
    groups = (
        ParamGroup("lost_motion.b", joint_labels("lost_motion.b"), "rad", scale=1e-4),
        ParamGroup(
            "lost_motion.rho",
            ("lost_motion.rho",),
            "1",
            scale=1.0,
            default=LOST_MOTION_RHO_INIT,
            bounds=LOST_MOTION_RHO_BOUNDS,
        ),
    )
    needs = ("load",)
    formula = "smooth dead band dq_i += b_i tanh(tau_i / (exp(rho) tau_s,i)), b = half the lost motion"
    simulation = "lost_motion"

    def joints_acting(self, param: Any) -> np.ndarray:
        return np.asarray(param("lost_motion.b")).reshape(6) != 0.0

    def caveats(self, param: Any, const: Any, tau: np.ndarray, lever_m: np.ndarray) -> list[str]:
        """Joints whose torque stays inside the dead band's transition along the path: there the
        joint can sit anywhere in +-b (its side depends on the motion history), so neither the
        model nor any static compensation fixes it; the TCP error can reach b times the lever."""
        b = np.abs(np.asarray(param("lost_motion.b")).reshape(6))
        tau0 = float(np.exp(np.asarray(param("lost_motion.rho")).reshape(-1)[0])) * np.asarray(const("tau_scale"))
        out = []
        for j in range(6):
            inside = np.abs(tau[:, j]) < DEAD_BAND_MARGIN * tau0[j]
            if b[j] > 0 and inside.any():
                k = np.flatnonzero(inside)
                err = float(np.max(b[j] * lever_m[k, j]))
                out.append(
                    f"joint {j + 1}: its torque stays within {DEAD_BAND_MARGIN:g} x {tau0[j]:.3g} N*m of zero at "
                    f"{len(k)} waypoint(s) (first {int(k[0])}), inside its identified lost motion "
                    f"(+-{b[j] * 1e6:.3g} urad): the joint's side of the dead band is not determined, "
                    f"up to {err * 1e3:.3g} mm at the TCP; load that joint (a bias force or another "
                    "posture) to make the compensation hold"
                )
        return out

    def joint_deflection(self, ctx: Any, tau: Any) -> Any:
        tau0 = ca.exp(ctx.p("lost_motion.rho")) * ctx.c("tau_scale")
        return ctx.p("lost_motion.b") * ca.tanh(tau / tau0)
