"""NumPy kinematics of the true arm, vectorised over rows (per-row DH parameters allowed).

Link transforms in standard or modified DH with an optional Hayati ``beta``, the frames
and joint axes of the chain, joint torques of a force at a point, and rotation vectors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _link(
    theta: np.ndarray, d: np.ndarray, a: np.ndarray, alpha: np.ndarray, beta: np.ndarray, convention: str
) -> np.ndarray:
    n = theta.shape[0]
    ct, st = np.cos(theta), np.sin(theta)
    ca_, sa = np.cos(alpha), np.sin(alpha)
    A = np.zeros((n, 4, 4))
    if convention == "standard_dh":
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = ct, -st * ca_, st * sa, a * ct
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st, ct * ca_, -ct * sa, a * st
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca_, d
    else:
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 3] = ct, -st, a
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st * ca_, ct * ca_, -sa, -sa * d
        A[:, 2, 0], A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = st * sa, ct * sa, ca_, ca_ * d
    A[:, 3, 3] = 1.0
    if np.any(beta != 0):
        cb, sb = np.cos(beta), np.sin(beta)
        Ry = np.zeros((n, 4, 4))
        Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2], Ry[:, 3, 3] = cb, sb, 1, -sb, cb, 1
        A = A @ Ry
    return A


@dataclass
class ArmGeometry:
    """Per-row DH parameters, shape (N, 6) each, and DH frame 0 in the base frame (4x4)."""

    a: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    toff: np.ndarray
    beta: np.ndarray
    frame02base: np.ndarray | None = None


def link_frames(q: np.ndarray, g: ArmGeometry, convention: str) -> np.ndarray:
    """Frames frame_i2base (i = 1..6), shape (N, 6, 4, 4)."""
    n = q.shape[0]
    out = np.zeros((n, 6, 4, 4))
    T = np.broadcast_to(np.eye(4) if g.frame02base is None else g.frame02base, (n, 4, 4)).copy()
    for i in range(6):
        T = T @ _link(q[:, i] + g.toff[:, i], g.d[:, i], g.a[:, i], g.alpha[:, i], g.beta[:, i], convention)
        out[:, i] = T
    return out


def joint_axes(
    frames: np.ndarray, convention: str, frame02base: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Joint axes z_i and points p_i, shape (N, 6, 3) each (``frame02base``: DH frame 0, default
    the base frame)."""
    n = frames.shape[0]
    if convention == "standard_dh":
        F0 = np.eye(4) if frame02base is None else np.asarray(frame02base, dtype=float)
        z = np.concatenate([np.broadcast_to(F0[:3, 2], (n, 1, 3)), frames[:, :5, :3, 2]], axis=1)
        p = np.concatenate([np.broadcast_to(F0[:3, 3], (n, 1, 3)), frames[:, :5, :3, 3]], axis=1)
    else:
        z, p = frames[:, :, :3, 2], frames[:, :, :3, 3]
    return z, p


def tau_point(
    z: np.ndarray, p: np.ndarray, point: np.ndarray, f: np.ndarray, m: np.ndarray, first: int = 0
) -> np.ndarray:
    """Joint torques of force f at ``point`` and moment m: z_i . ((point - p_i) x f + m)."""
    lever = point[:, None, :] - p
    tau = np.einsum("nij,nij->ni", z, np.cross(lever, f[:, None, :]) + m[:, None, :])
    tau[:, :first] = 0.0
    return tau


def rotvecs(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis x angle, rad, angle in [0, pi]) of rotations (N, 3, 3) -> (N, 3)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, dtype=float).reshape(-1, 3, 3)).as_rotvec()
