"""Registration of the measurement frame (declared model, measurement only).

``p_meas = R(w) R0 p_base + t``: ``R0`` a fixed rotation (Kabsch fit of the nominal
model), ``w`` a Cayley-vector correction (exactly orthogonal, about a rotation by
``2 w``), ``t`` a translation (m).  Not part of planning: the arm model plans in
its base frame.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .base import MEASUREMENT, ConstGroup, Effect, ParamGroup, register, xyz_labels


def cayley(w: Any) -> Any:
    """Rotation matrix of the Cayley vector ``w``: ``I + 2/(1+|w|^2) ([w]x + [w]x^2)``."""
    W = ca.skew(w)
    return ca.SX.eye(3) + 2.0 / (1.0 + ca.dot(w, w)) * (W + ca.mtimes(W, W))


def cayley_np(w: np.ndarray) -> np.ndarray:
    """NumPy version of :func:`cayley`, shape (3, 3)."""
    w = np.asarray(w, dtype=float)
    W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    return np.eye(3) + 2.0 / (1.0 + w @ w) * (W + W @ W)


def cayley_vector(R: np.ndarray) -> np.ndarray:
    """Cayley vector ``w`` of a rotation (3, 3): the inverse of :func:`cayley_np`
    (``W = (R - I)(R + I)^-1``; a rotation by angle ``a`` has ``|w| = tan(a/2)``)."""
    W = (R - np.eye(3)) @ np.linalg.inv(R + np.eye(3))
    return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2.0


@register
class Registration(Effect):
    name = "registration"
    order = 0
    acts_on = MEASUREMENT
    declared = True
    groups = (
        ParamGroup("reg.w", xyz_labels("registration.w"), "1", scale=1e-3),
        ParamGroup("reg.t", xyz_labels("registration.t"), "m", scale=1e-3),
    )
    constants = (
        ConstGroup(
            "registration.R0",
            9,
            lambda r: np.eye(3).reshape(-1),
            "rotation the correction w is applied to (3x3, column-major)",
        ),
    )
    formula = "p_meas = R(w) R0 p_base + t (measurement frame)"
    simulation = "registration"

    def measurement(self, ctx: Any, p: Any) -> Any:
        R = ca.mtimes(cayley(ctx.p("reg.w")), ca.reshape(ctx.c("registration.R0"), 3, 3))
        return ca.mtimes(R, p) + ctx.p("reg.t")
