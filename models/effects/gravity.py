"""Self-weight: the links' weight adds joint torques, which the joint compliance (and the
other torque effects) turn into deflection.

``tau_g,i = z_i . ((S_i - M_i p_i) x g)``, ``S_i = sum_{j>=i} (m_j p_j + R_j h_j)``,
``M_i = sum_{j>=i} m_j``: link masses ``m_j`` (kg) and first moments ``h_j = m_j r_j``
(kg*m, DH link frame j), linear; defaults from the robot file (zero without masses).
The constant ``gravity.on`` switches the term in the identification graph (where every
effect is present); a planning model with ``gravity`` active always includes it.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from models.robot import Robot

from .base import ConstGroup, Effect, ParamGroup, joint_labels, register


def _masses(r: Robot) -> np.ndarray:
    return r.masses if r.has_masses else np.zeros(6)


def _moments(r: Robot) -> np.ndarray:
    return (r.masses[:, None] * r.coms).reshape(-1) if r.has_masses else np.zeros(18)


@register
class Gravity(Effect):
    name = "gravity"
    order = 5
    groups = (
        ParamGroup(
            "gravity.m",
            joint_labels("gravity.mass"),
            "kg",
            default=_masses,
            scale=lambda r: max(1.0, float(np.mean(r.masses))) if r.has_masses else 1.0,
        ),
        ParamGroup(
            "gravity.h",
            tuple(f"gravity.first_moment[{i + 1}].{c}" for i in range(6) for c in "xyz"),
            "kg*m",
            default=_moments,
            scale=0.1,
        ),
    )
    constants = (ConstGroup("gravity.on", 1, 0.0, "1: self-weight torques in the identification graph"),)
    formula = (
        "self-weight joint deflection dq += C tau_g(q; m_j, m_j r_j), tau_g from link masses and "
        "first moments (barycentric, linear), C the joint compliance"
    )
    simulation = "gravity"

    def joint_torque(self, ctx: Any) -> Any:
        mass, h, g = ctx.p("gravity.m"), ctx.p("gravity.h"), ctx.c("gravity")
        S, M = ca.DM.zeros(3), 0
        tau = [None] * 6
        for j in range(5, -1, -1):
            Rj, pj = ctx.frames[j][:3, :3], ctx.frames[j][:3, 3]
            S = S + mass[j] * pj + ca.mtimes(Rj, h[3 * j : 3 * j + 3])
            M = M + mass[j]
            tau[j] = ca.dot(ctx.zs[j], ca.cross(S - M * ctx.ps[j], g))
        return ctx.c("gravity.on") * ca.vertcat(*tau)
