"""Small numeric helpers for rotations and homogeneous transforms (NumPy).

Names follow the ``A2B`` habit: ``tcp2base`` maps TCP-frame coordinates to
base-frame coordinates (``x_base = tcp2base @ x_tcp``).
"""

from __future__ import annotations

import math

import numpy as np


def rot_x(a: float) -> np.ndarray:
    """Rotation about x by ``a`` rad, shape (3, 3)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Rotation about y by ``a`` rad, shape (3, 3)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    """Rotation about z by ``a`` rad, shape (3, 3)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    """Roll-pitch-yaw (rad) to rotation ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``, shape (3, 3)."""
    r, p, y = (float(v) for v in rpy)
    return rot_z(y) @ rot_y(p) @ rot_x(r)


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rpy_to_matrix`; returns (roll, pitch, yaw) rad, shape (3,)."""
    pitch = np.arcsin(-np.clip(R[2, 0], -1.0, 1.0))
    if abs(np.cos(pitch)) < 1e-12:
        roll = 0.0
        yaw = np.arctan2(-R[0, 1], R[1, 1])
    else:
        roll = np.arctan2(R[2, 1], R[2, 2])
        yaw = np.arctan2(R[1, 0], R[0, 0])
    return np.array([roll, pitch, yaw])


def transform(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Homogeneous transform from rotation (3, 3) and translation (3,), shape (4, 4)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of homogeneous transform(s), shape (..., 4, 4)."""
    R = T[..., :3, :3]
    p = T[..., :3, 3]
    Ti = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    Ti[..., :3, :3] = Rt
    Ti[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, p)
    Ti[..., 3, 3] = 1.0
    return Ti


def rotation_angle(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Angle (rad) of ``Ra^T Rb`` for stacks of rotations, shape (...)."""
    Rd = np.einsum("...ji,...jk->...ik", Ra, Rb)
    tr = np.trace(Rd, axis1=-2, axis2=-1)
    # Robust for small angles: use the skew part too.
    skew = np.stack(
        [Rd[..., 2, 1] - Rd[..., 1, 2], Rd[..., 0, 2] - Rd[..., 2, 0], Rd[..., 1, 0] - Rd[..., 0, 1]], axis=-1
    )
    return np.arctan2(0.5 * np.linalg.norm(skew, axis=-1), 0.5 * (tr - 1.0))


def tool_down_rotation(yaw: float = 0.0) -> np.ndarray:
    """Rotation of a tool whose z axis points along -z of the base, shape (3, 3).

    ``Rx(pi) @ Rz(yaw)``: x_tool turned by ``yaw`` about the tool axis.
    """
    return rot_x(np.pi) @ rot_z(yaw)


def wrap_angle(q: np.ndarray) -> np.ndarray:
    """Wrap angles (rad) to (-pi, pi]."""
    w = np.mod(np.asarray(q) + np.pi, 2.0 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def rotvec_to_matrix(v: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (axis * angle, rad), shape (3, 3)."""
    v = np.asarray(v, dtype=float)
    th = float(np.linalg.norm(v))
    if th < 1e-15:
        return np.eye(3)
    k = v / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix."""
    c = (np.trace(R) - 1.0) / 2.0
    th = math.acos(max(-1.0, min(1.0, c)))
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-12:
        return 0.5 * w
    if abs(math.pi - th) < 1e-6:
        # near pi: axis from the symmetric part
        M = (R + np.eye(3)) / 2.0
        k = np.sqrt(np.maximum(np.diag(M), 0.0))
        i = int(np.argmax(k))
        k = M[:, i] / max(k[i], 1e-12)
        k = k / np.linalg.norm(k)
        return th * k
    return th / (2.0 * math.sin(th)) * w


def rotations_about(w: np.ndarray, th: np.ndarray) -> np.ndarray:
    """Rotations about the unit axis ``w`` (3,) by angles ``th`` (N,) rad (Rodrigues), (N, 3, 3)."""
    w = np.asarray(w, dtype=float)
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    th = np.asarray(th, dtype=float).reshape(-1)
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def poe_fk(w: np.ndarray, p: np.ndarray, M0: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Forward kinematics by the product of exponentials ``exp([S1] q1) ... exp([S6] q6) M0``.

    Parameters
    ----------
    w, p : ndarray, shape (6, 3)
        Unit joint axes and a point on each axis, base frame (m), at q = 0; joint i turns
        positively about ``w_i``.
    M0 : ndarray, shape (4, 4)
        ``flange2base`` at q = 0.
    q : ndarray, shape (N, 6) or (6,)
        Joint angles, rad.

    Returns
    -------
    ndarray, shape (N, 4, 4), or (4, 4) for one q
        ``flange2base``.
    """
    w, p, M0 = (np.asarray(x, dtype=float) for x in (w, p, M0))
    qa = np.asarray(q, dtype=float)
    q2 = qa.reshape(-1, 6)
    n = q2.shape[0]
    T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for i in range(6):
        E = np.zeros((n, 4, 4))
        E[:, :3, :3] = rotations_about(w[i], q2[:, i])
        E[:, :3, 3] = p[i] - E[:, :3, :3] @ p[i]
        E[:, 3, 3] = 1.0
        T = T @ E
    T = T @ M0
    return T[0] if qa.ndim == 1 else T


def dh_chain_frames(
    convention: str,
    a: np.ndarray,
    alpha: np.ndarray,
    d: np.ndarray,
    theta_offset: np.ndarray,
    q: np.ndarray,
    frame02base: np.ndarray | None = None,
) -> np.ndarray:
    """DH frames 0..6 of a chain at ``q``, base frame: the one NumPy chain (twin of the model
    graph's :func:`models.effects.graph.chain`; frame 0 is ``frame02base``, default the base frame).

    ``standard_dh``: ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; ``modified_dh``:
    ``A_i = Rx(alpha_i) Tx(a_i) Rz(theta_i) Tz(d_i)`` (row i holds the previous link's a, alpha);
    ``theta_i = q_i + theta_offset_i``.

    Parameters
    ----------
    q : ndarray, shape (6,) or (N, 6)
        Joint angles, rad.

    Returns
    -------
    ndarray, shape (7, 4, 4) or (N, 7, 4, 4)
        ``frame_i2base`` for i = 0..6.
    """
    qa = np.asarray(q, dtype=float)
    q2 = np.atleast_2d(qa)
    n = q2.shape[0]
    th = q2 + np.asarray(theta_offset, dtype=float)
    ct, st = np.cos(th), np.sin(th)
    ca_, sa = np.cos(np.asarray(alpha, dtype=float)), np.sin(np.asarray(alpha, dtype=float))
    a, d = np.asarray(a, dtype=float), np.asarray(d, dtype=float)
    A = np.zeros((n, 6, 4, 4))
    A[..., 3, 3] = 1.0
    if convention == "standard_dh":
        A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca_, st * sa, a * ct
        A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca_, -ct * sa, a * st
        A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca_, d
    else:
        A[..., 0, 0], A[..., 0, 1], A[..., 0, 3] = ct, -st, a
        A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st * ca_, ct * ca_, -sa, -sa * d
        A[..., 2, 0], A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = st * sa, ct * sa, ca_, ca_ * d
    F = np.empty((n, 7, 4, 4))
    F[:, 0] = np.eye(4) if frame02base is None else np.asarray(frame02base, dtype=float)
    for i in range(6):
        F[:, i + 1] = F[:, i] @ A[:, i]
    return F[0] if qa.ndim == 1 else F
