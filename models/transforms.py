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
    skew = np.stack([Rd[..., 2, 1] - Rd[..., 1, 2], Rd[..., 0, 2] - Rd[..., 2, 0],
                     Rd[..., 1, 0] - Rd[..., 0, 1]], axis=-1)
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
