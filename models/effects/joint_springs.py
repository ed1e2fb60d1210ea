"""Linear joint springs: the paper's model (declared; always part of the arm model).

``dq_i = c_i tau_i`` with ``c_i = c0_i (1 + s_i)``, ``c0 = 1/k`` the robot file's
joint compliance (rad/(N*m)) and ``s_i`` the identified relative change
(dimensionless; ``s_i > -0.95``).  A joint yields in the direction of the torque
applied to it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .base import Effect, ParamGroup, joint_labels, register


@register
class JointSprings(Effect):
    name = "joint_springs"
    order = 2
    declared = True
    groups = (ParamGroup("stiffness.s", joint_labels("stiffness.s"), "1", scale=0.1, bounds=(-0.95, np.inf)),)
    formula = "dq_i = c0_i (1 + s_i) tau_i (linear joint springs, c0 = 1/k)"
    simulation = "stiffness"

    def compliance(self, ctx: Any) -> Any:
        """Joint compliances ``c0 (1 + s)``, rad/(N*m), (6,)."""
        return ctx.c("compliance0") * (1.0 + ctx.p("stiffness.s"))

    def joint_deflection(self, ctx: Any, tau: Any) -> Any:
        return self.compliance(ctx) * tau
