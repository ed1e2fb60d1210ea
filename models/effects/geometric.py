"""Geometric (DH) errors: ``da, dalpha, dd, dtheta`` per joint, plus the Hayati angle ``dbeta``
(rotation about y after link i) where consecutive axes are nominally parallel and DH is singular.

Subsumes ``joint_offset`` (its ``dtheta`` are the same parameters).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from models.robot import Robot

from .base import PARALLEL_AXIS_TOL, Effect, ParamGroup, joint_labels, register


def parallel_joints(robot: Robot) -> list[int]:
    """Rows i (0-based) whose axes z_{i-1}, z_i are parallel and a following joint exists."""
    return [i for i in range(5) if abs(np.sin(robot.alpha[i])) < PARALLEL_AXIS_TOL]


def _beta_eligible(robot: Robot) -> np.ndarray:
    el = np.zeros(6, dtype=bool)
    el[parallel_joints(robot)] = True
    return el


@register
class Geometric(Effect):
    name = "geometric"
    order = 4
    groups = (
        ParamGroup("geometric.da", joint_labels("da"), "m", scale=1e-3),
        ParamGroup("geometric.dalpha", joint_labels("dalpha"), "rad", scale=1e-3),
        ParamGroup("geometric.dd", joint_labels("dd"), "m", scale=1e-3),
        ParamGroup("geometric.dbeta", joint_labels("dbeta"), "rad", scale=1e-3, eligible=_beta_eligible),
    )
    frees = ("joint_offset.dtheta", "geometric.da", "geometric.dalpha", "geometric.dd", "geometric.dbeta")
    subsumes = ("joint_offset",)
    formula = "full DH error set (da, dalpha, dd, dtheta per joint; Hayati dbeta about y for parallel axes)"
    simulation = "geometric"

    def geometry(self, ctx: Any, dh: dict[str, Any]) -> dict[str, Any]:
        return {
            **dh,
            "a": dh["a"] + ctx.p("geometric.da"),
            "alpha": dh["alpha"] + ctx.p("geometric.dalpha"),
            "d": dh["d"] + ctx.p("geometric.dd"),
            "beta": dh["beta"] + ctx.p("geometric.dbeta"),
        }
