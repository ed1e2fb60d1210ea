"""The workpiece frame (problems/toolpath/workpiece.py): program points and tool axes to base-frame
TCP targets, checked against an independent rotation (scipy) and hand-worked cases."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from models.errors import InputError
from problems.toolpath.workpiece import Workpiece

#: Agreement of two implementations of the same rotation (m, and for unit vectors).
FRAME_TOL = 1e-12


def test_a_three_axis_program_points_the_tcp_z_down_the_program_z():
    wp = Workpiece(np.array([0.6, -0.1, 0.05]), np.zeros(3))
    pos, z = wp.tcp_targets(np.array([[0.0, 0.0, 0.0], [0.010, 0.020, -0.003]]))
    np.testing.assert_allclose(pos, [[0.6, -0.1, 0.05], [0.61, -0.08, 0.047]], atol=FRAME_TOL)
    np.testing.assert_allclose(z, [[0, 0, -1], [0, 0, -1]], atol=FRAME_TOL)


def test_placement_and_tool_axes_agree_with_scipy(rng):
    rpy = np.array([0.3, -0.2, 1.1])
    wp = Workpiece(np.array([0.5, 0.2, 0.1]), rpy)
    P = rng.uniform(-0.1, 0.1, (50, 3))
    A = rng.normal(size=(50, 3))
    A /= np.linalg.norm(A, axis=1, keepdims=True)
    pos, z = wp.tcp_targets(P, A)
    R = Rotation.from_euler("ZYX", rpy[::-1]).as_matrix()  # Rz(yaw) Ry(pitch) Rx(roll)
    np.testing.assert_allclose(pos, (R @ P.T).T + [0.5, 0.2, 0.1], atol=FRAME_TOL)
    np.testing.assert_allclose(z, -(R @ A.T).T, atol=FRAME_TOL)
    T = wp.program2base
    np.testing.assert_allclose(T[:3, :3], R, atol=FRAME_TOL)
    np.testing.assert_allclose((T @ np.c_[P, np.ones(50)].T).T[:, :3], pos, atol=FRAME_TOL)


@pytest.mark.parametrize(
    "kwargs, points, axes, message",
    [
        ({"xyz_m": [0, 0], "rpy_rad": [0, 0, 0]}, None, None, "xyz must be 3 finite numbers"),
        ({"xyz_m": [0, 0, 0], "rpy_rad": [0, np.nan, 0]}, None, None, "rpy must be 3 finite numbers"),
        ({"xyz_m": [0, 0, 0], "rpy_rad": [0, 0, 0]}, np.zeros((2, 2)), None, r"shape \(N, 3\)"),
        ({"xyz_m": [0, 0, 0], "rpy_rad": [0, 0, 0]}, np.zeros((2, 3)), np.zeros((2, 3)), "tool axis 0 has norm 0"),
    ],
)
def test_bad_frames_points_and_axes_are_named(kwargs, points, axes, message):
    with pytest.raises(InputError, match=message):
        wp = Workpiece(np.asarray(kwargs["xyz_m"], float), np.asarray(kwargs["rpy_rad"], float))
        wp.tcp_targets(points, axes)
