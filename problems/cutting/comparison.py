"""What compensating a constant stand-in for the cutting force would have left, under the model's own
physics: the commands are compensated for the stand-in, the arm is loaded with the predicted cut.

Both loads are the problem's load rows (:mod:`models.load`); the predicted one is the truth the
comparison is made against.  Frames: errors in the base frame, m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.load import Load
from models.transforms import rotation_angle

__all__ = ["StandInComparison", "compare_stand_in"]


@dataclass(frozen=True)
class StandInComparison:
    """TCP errors at the waypoints when the commands are compensated for a stand-in load.

    Attributes
    ----------
    error_m : ndarray, shape (N, 3)
        Reached minus target TCP position under the predicted load, base frame, m.
    error_rad : ndarray, shape (N,)
        TCP orientation error, rad.
    converged : bool
        Whether every equilibrium converged.
    """

    error_m: np.ndarray
    error_rad: np.ndarray
    converged: bool

    @property
    def error_norm_m(self) -> np.ndarray:
        """(N,) Euclidean TCP position error, m."""
        return np.linalg.norm(self.error_m, axis=1)


def stand_in_load(load: Load, cut_wrench_base: np.ndarray, stand_in: np.ndarray, frame: str) -> Load:
    """``load`` (which holds the predicted cut in its base-frame wrench) with the cut replaced by the
    constant ``stand_in`` wrench (shape (6,), N and N*m) in ``frame`` (``"base"`` or ``"tool"``)."""
    n = len(cut_wrench_base)
    base = np.broadcast_to(np.asarray(load.wrench_base, dtype=float), (n, 6)) - cut_wrench_base
    tool = np.broadcast_to(np.asarray(load.wrench_tool, dtype=float), (n, 6)).copy()
    s = np.asarray(stand_in, dtype=float).reshape(6)
    if frame == "base":
        base = base + s
    else:
        tool = tool + s
    return Load(base, tool, load.payload_mass_kg, load.payload_com_m, load.gravity)


def compare_stand_in(arm, q_target: np.ndarray, true_load: Load, stand_in: Load) -> StandInComparison:
    """The TCP errors left at the targets of ``q_target`` (N, 6) rad when the commands are exactly
    compensated for ``stand_in`` and the arm carries ``true_load`` (:class:`models.arm_model.ArmModel`)."""
    from problems.compensation import exact

    q = np.atleast_2d(np.asarray(q_target, dtype=float))
    n = len(q)
    target = arm.kinematics.tcp(q).reshape(-1, 4, 4)
    cmd = exact(arm, q, stand_in.rows(n))
    L = true_load.rows(n)
    eq = arm.equilibrium(cmd.q_command, L)
    p, R = arm.loaded_tcp(eq.q, L)
    return StandInComparison(p - target[:, :3, 3], rotation_angle(R, target[:, :3, :3]), bool(np.all(eq.converged)))
