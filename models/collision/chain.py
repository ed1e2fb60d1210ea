"""Capsule positions from the one kinematic chain of the arm, in NumPy and in CasADi.

* :func:`chain_frames`: DH frames 0..6 at N configurations, the one NumPy chain
  (:func:`models.transforms.dh_chain_frames`); :func:`capsule_segments`: every capsule's ends from them.
* :func:`chain_frames_sx`: the same frames as CasADi expressions, the model graph's chain
  (:func:`models.effects.graph.chain`, the one CasADi chain) of the nominal DH table;
  :func:`capsule_points_sx`: every capsule's ends from them (the posture NLP's clearance constraints,
  the placement kernel's compiled capsule function).

Units: m, rad.  Frames: the base frame (or frame x given ``base2x``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..robot import Robot
from ..transforms import dh_chain_frames

if TYPE_CHECKING:
    from .capsules import CapsuleModel

__all__ = ["capsule_points_sx", "capsule_segments", "chain_frames", "chain_frames_sx"]


def chain_frames(robot: Robot, q: np.ndarray) -> np.ndarray:
    """DH frames 0..6 of the robot's nominal chain at N configurations, base frame
    (:func:`models.transforms.dh_chain_frames`, the one NumPy chain).

    Parameters
    ----------
    robot : Robot
    q : ndarray, shape (N, 6) or (6,)
        Joint angles, rad.

    Returns
    -------
    ndarray, shape (N, 7, 4, 4)
        ``frame_i2base`` for i = 0..6 (frame 0 is ``frame02base``).
    """
    r = robot
    return dh_chain_frames(r.convention, r.a, r.alpha, r.d, r.theta_offset, np.atleast_2d(q), r.frame02base)


def chain_frames_sx(robot: Robot, q: Any) -> list[Any]:
    """DH frames 0..6 (4 x 4 CasADi SX, base frame) of the robot's nominal chain at symbolic ``q``
    (6): the model graph's chain (:func:`models.effects.graph.chain`, the one CasADi chain) of the
    nominal DH table, frame 0 ``frame02base``."""
    import casadi as ca

    from ..effects.graph import chain

    f0 = ca.SX(np.asarray(robot.frame02base, dtype=float))
    return [f0, *chain(q, robot.nominal_dh(f0), robot.convention)]


def capsule_points_sx(model: CapsuleModel, frames: list[Any], base2x: Any = None) -> list[tuple[Any, Any]]:
    """Every capsule's segment ends (3 x 1 SX each) from symbolic DH frames 0..6
    (:func:`chain_frames_sx`), in the base frame, or in frame x with ``base2x`` (4 x 4 SX).

    Returns
    -------
    list of (SX, SX), length M
        End a and end b of each capsule.
    """
    import casadi as ca

    def point(frame: int, local: np.ndarray) -> Any:
        loc = ca.DM(np.asarray(local, dtype=float))
        if base2x is None:
            if frame < 0:
                return ca.SX(np.asarray(local, dtype=float))
            T = frames[frame]
        else:
            T = base2x if frame < 0 else ca.mtimes(base2x, frames[frame])
        return ca.mtimes(T[:3, :3], loc) + T[:3, 3]

    return [
        (point(int(model.frame_a[c]), model.local_a[c]), point(int(model.frame_b[c]), model.local_b[c]))
        for c in range(model.n_capsules)
    ]


def capsule_segments(model: CapsuleModel, frames: np.ndarray) -> np.ndarray:
    """End points of every capsule's segment at N configurations, base frame.

    Parameters
    ----------
    model : CapsuleModel
    frames : ndarray, shape (N, 7, 4, 4)
        DH frames 0..6 (:func:`chain_frames`).

    Returns
    -------
    ndarray, shape (N, M, 2, 3)
        ``[..., 0, :]`` end a, ``[..., 1, :]`` end b, m.
    """
    n = frames.shape[0]
    ext = np.concatenate([np.broadcast_to(np.eye(4), (n, 1, 4, 4)), frames], axis=1)  # index 0: base
    out = np.empty((n, model.n_capsules, 2, 3))
    for end, (fr, loc) in enumerate(((model.frame_a, model.local_a), (model.frame_b, model.local_b))):
        T = ext[:, fr + 1]  # (N, M, 4, 4)
        out[:, :, end] = np.einsum("nmij,mj->nmi", T[..., :3, :3], loc) + T[..., :3, 3]
    return out
