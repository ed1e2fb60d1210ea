"""Torque-dependent joint compliance (gear hardening), an odd quadratic spline of the torque:

``dq_i += c0_i (b_i0 tau_i |tau_i| + sum_k b_ik sign(tau_i) (|tau_i| - kappa_ik)_+^2) / tau_s,i``

with knots ``kappa_ik`` (N*m, constants) at quantiles of the joint torques the model applies,
``tau_s`` the joint torque scale.  ``b < 0``: stiffer under load.  Linear in ``b``.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .base import ConstGroup, Effect, ParamGroup, register

#: Knots of the spline, as quantiles of the nonzero joint torques of the data (per joint).
HARDENING_KNOT_QUANTILES = (0.1, 0.3, 0.55, 0.8, 0.95)
#: Number of knots per joint.
N_KNOTS = len(HARDENING_KNOT_QUANTILES)
#: Terms per joint: ``tau|tau|`` and one quadratic hinge per knot.
N_HARDENING = 1 + N_KNOTS


@register
class StiffnessHardening(Effect):
    name = "stiffness_hardening"
    order = 6
    groups = (
        ParamGroup(
            "hardening.b",
            tuple(
                f"hardening.b[{i + 1}].{'quad' if k == 0 else f'knot{k}'}" for i in range(6) for k in range(N_HARDENING)
            ),
            "1",
            scale=0.1,
        ),
    )
    constants = (
        ConstGroup(
            "hardening.knots",
            6 * N_KNOTS,
            lambda r: np.outer(np.ones(6), HARDENING_KNOT_QUANTILES).reshape(-1),
            "spline knots kappa (6 x N_KNOTS, joint-major), N*m",
        ),
    )
    needs = ("load",)
    formula = (
        "torque-dependent compliance, an odd quadratic spline: dq_i = c_i tau_i + c0_i (b_i0 tau_i|tau_i| "
        "+ sum_k b_ik sign(tau_i) (|tau_i| - kappa_ik)_+^2) / tau_s,i, knots kappa_ik at torque quantiles"
    )
    simulation = "stiffness_hardening"

    def joints_acting(self, param: Any) -> np.ndarray:
        return np.any(np.asarray(param("hardening.b")).reshape(6, N_HARDENING) != 0.0, axis=1)

    def joint_deflection(self, ctx: Any, tau: Any) -> Any:
        b, ts, knots, c0 = ctx.p("hardening.b"), ctx.c("tau_scale"), ctx.c("hardening.knots"), ctx.c("compliance0")
        terms = []
        for i in range(6):
            a = ca.fabs(tau[i])
            acc = b[N_HARDENING * i] * tau[i] * a
            for k in range(N_KNOTS):
                acc = acc + b[N_HARDENING * i + 1 + k] * ca.sign(tau[i]) * ca.fmax(a - knots[N_KNOTS * i + k], 0) ** 2
            terms.append(acc / ts[i])
        return c0 * ca.vertcat(*terms)
