"""Symbolic CasADi model of a 6R arm: FK, geometric Jacobian, compliance.

:class:`KinematicModel` is the working data built from a :class:`~models.robot.Robot`
description or an arm model (defined beside :class:`~models.arm_model.ArmModel`, which it builds
from a description and which builds it).  Every quantity is a named :class:`casadi.Function`; batch helpers
evaluate them over many poses in one call (compiled C from :mod:`models.codegen`, or,
without a C compiler, ``Function.map`` with threads on CasADi's virtual machine), so
NumPy arrays are converted once per batch, not once per pose.

Frames and signs (see ``docs/conventions.md``):

* ``frame_i2base`` (i = 1..6): DH frame *i* in the base frame; frame 6 is the flange.
* ``tcp2base = flange2base @ tcp2flange``.
* Jacobian ``J`` (6, 6): geometric, at the TCP point, base frame, rows
  ``[v_x, v_y, v_z, w_x, w_y, w_z]`` (linear velocity first), ``twist = J qdot``.
* A wrench ``F = [f; m]`` (N, N*m), base frame, acts on the TCP; joint torques
  ``tau = J^T F``; joint deflection ``dq = K^-1 tau`` (a joint yields in the
  direction of the torque applied to it); TCP deflection ``D = J dq = C F`` with
  ``C = J K^-1 J^T`` (eq. 15 of the paper), ``D = [dp (m); dphi (rad)]``.
"""

from __future__ import annotations


import numpy as np

from .arm_model import KinematicModel


__all__ = [
    "KinematicModel",
    "cartesian_stiffness",
    "directional_stiffness",
]


def directional_stiffness(C: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Translational stiffness along unit direction(s) ``u``: ``1 / (u^T C_tt u)`` (N/m).

    Parameters
    ----------
    C : ndarray, shape (..., 6, 6)
        Compliance matrices.
    u : ndarray, shape (3,) or (..., 3)
        Direction in the base frame (normalised here).
    """
    u = np.asarray(u, dtype=float)
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    ctt = C[..., :3, :3]
    return 1.0 / np.einsum("...i,...ij,...j->...", u, ctt, u)


def cartesian_stiffness(C: np.ndarray, max_cond: float = 1e12) -> np.ndarray:
    """Cartesian stiffness ``K_x = C^-1`` (paper eq. 20) where it exists.

    Raises
    ------
    np.linalg.LinAlgError
        If C is singular (condition number above ``max_cond``): at a singular
        pose the arm is infinitely compliant in some direction and K_x does not exist.
    """
    cond = np.linalg.cond(C)
    if np.any(~np.isfinite(cond)) or np.any(cond > max_cond):
        raise np.linalg.LinAlgError(
            f"compliance is singular (condition number {np.max(cond):.3g} > {max_cond:.1g}): "
            "the Cartesian stiffness does not exist at this pose"
        )
    return np.linalg.inv(C)
