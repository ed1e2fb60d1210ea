"""The workpiece frame: where a program's zero stands in the robot's base frame.

A CAM program (G-code or CL data) gives tool-tip points, and optionally tool axes, in its own
frame: the **program frame** (``P``), whose origin is the program zero (the work offset, G54…G59 on
a machine tool) and whose +Z points from the part towards the spindle. The problem places it in
the robot's base frame (``B``) by ``program2base`` (pytransform3d's naming: ``A2B`` maps coordinates
from A to B), ``p_B = R p_P + t``, given as ``xyz`` (m) and ``rpy`` (rad, ``R = Rz(yaw) Ry(pitch)
Rx(roll)``, :func:`models.transforms.rpy_to_matrix`).

The tool axis of a point is a unit vector from the tip towards the spindle (the CL convention);
a 3-axis program's is the program's +Z everywhere. The TCP's z axis is its opposite: the TCP
frame's z points out of the tool into the part, as for a tool-down pose (``docs/conventions.md``).
The rotation about the tool axis is free: the posture optimisation chooses it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.errors import InputError
from models.transforms import rpy_to_matrix, transform

__all__ = [
    "Workpiece",
]

#: A tool axis whose norm is further than this from 1 is an error (not a unit vector).
WORKPIECE_AXIS_TOL = 1e-6


@dataclass(frozen=True)
class Workpiece:
    """The program frame placed in the base frame.

    Attributes
    ----------
    xyz_m : np.ndarray
        Shape ``(3,)``, m: the program zero in the base frame.
    rpy_rad : np.ndarray
        Shape ``(3,)``, rad: roll, pitch, yaw of the program frame in the base frame.
    """

    xyz_m: np.ndarray
    rpy_rad: np.ndarray

    def __post_init__(self) -> None:
        for key, v in (("xyz", self.xyz_m), ("rpy", self.rpy_rad)):
            a = np.asarray(v, dtype=float)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise InputError(f"workpiece: {key} must be 3 finite numbers, got {v!r}")
            object.__setattr__(self, f"{key}_m" if key == "xyz" else f"{key}_rad", a)

    @property
    def program2base(self) -> np.ndarray:
        """Shape ``(4, 4)``: homogeneous transform from the program frame to the base frame."""
        return transform(rpy_to_matrix(self.rpy_rad), self.xyz_m)

    def tcp_targets(self, points_m: np.ndarray, tool_axis: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """TCP positions and TCP z axes in the base frame.

        Parameters
        ----------
        points_m : np.ndarray
            Shape ``(N, 3)``, m, program frame: tool-tip points.
        tool_axis : np.ndarray, optional
            Shape ``(N, 3)``, program frame: unit vectors from the tip towards the spindle
            (5-axis CL data); None: the program's +Z at every point (a 3-axis program).

        Returns
        -------
        positions : np.ndarray
            Shape ``(N, 3)``, m, base frame.
        z_axes : np.ndarray
            Shape ``(N, 3)``, base frame: the TCP's z axis, ``-R @ tool_axis``.

        Raises
        ------
        InputError
            Wrong shapes, non-finite values, or a tool axis that is not a unit vector.
        """
        P = np.asarray(points_m, dtype=float)
        if P.ndim != 2 or P.shape[1] != 3 or not np.all(np.isfinite(P)):
            raise InputError(f"workpiece: points must be finite, of shape (N, 3), got shape {P.shape}")
        if tool_axis is None:
            A = np.broadcast_to(np.array([0.0, 0.0, 1.0]), P.shape)
        else:
            A = np.asarray(tool_axis, dtype=float)
            if A.shape != P.shape or not np.all(np.isfinite(A)):
                raise InputError(f"workpiece: tool axes must be finite, of shape {P.shape}, got {A.shape}")
            norm = np.linalg.norm(A, axis=1)
            bad = np.flatnonzero(np.abs(norm - 1.0) > WORKPIECE_AXIS_TOL)
            if bad.size:
                k = int(bad[0])
                raise InputError(f"workpiece: tool axis {k} has norm {norm[k]:.9g}; expected a unit vector")
        R = rpy_to_matrix(self.rpy_rad)
        return P @ R.T + self.xyz_m, -(A @ R.T)
