"""Geometric paths and branch-consistent IK along them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.errors import InputError, UnreachableError
from models.ik import IKSolver, IKStatus

#: Largest joint step (rad) allowed between neighbouring waypoints before the
#: path is declared to flip (a configuration change between two samples).
MAX_JOINT_STEP = 0.5


def line_positions(p_start: np.ndarray, p_end: np.ndarray, n: int) -> np.ndarray:
    """``n`` equally spaced points on the segment, both ends included; (n, 3), m."""
    if n < 2:
        raise InputError(f"path: need at least 2 points, got {n}")
    s = np.linspace(0.0, 1.0, n)[:, None]
    return (1.0 - s) * np.asarray(p_start, float) + s * np.asarray(p_end, float)


def poses(positions: np.ndarray, tcp2base_rotation: np.ndarray) -> np.ndarray:
    """Stack positions (N, 3) m with one rotation (3, 3) or N rotations (N, 3, 3) into (N, 4, 4)."""
    p = np.asarray(positions, float)
    T = np.zeros((len(p), 4, 4))
    T[:, :3, :3] = tcp2base_rotation
    T[:, :3, 3] = p
    T[:, 3, 3] = 1.0
    return T


@dataclass
class BranchPath:
    """IK along a path on one branch.

    Attributes
    ----------
    branch : int
        Branch index into the IK family's labels.
    q : ndarray, shape (N, 6), rad
        Continuous joint path (each joint unwrapped to follow its predecessor).
    max_step : float
        Largest joint step between neighbouring waypoints, rad.
    label : str
        The branch's label (``docs/conventions.md``, "IK branches").
    """

    branch: int
    q: np.ndarray
    max_step: float
    label: str = ""


def branch_paths(
    ik: IKSolver, tcp2base: np.ndarray, max_step: float = MAX_JOINT_STEP
) -> tuple[dict[int, BranchPath], dict[int, str]]:
    """IK of every waypoint on every branch, unwrapped into continuous joint paths.

    Returns
    -------
    feasible : dict branch -> BranchPath
        Branches with a solution at every waypoint and no step above ``max_step``.
    rejected : dict branch -> str
        Why each other branch was rejected (naming the waypoint).
    """
    sol = ik.solve(tcp2base)
    feasible: dict[int, BranchPath] = {}
    rejected: dict[int, str] = {}
    for b in range(ik.n_branches):
        bad = np.where(sol.status[:, b] != IKStatus.OK.code)[0]
        if bad.size:
            k = int(bad[0])
            rejected[b] = f"waypoint {k}: {sol.reason(k, b)}"
            continue
        q = np.unwrap(sol.q[:, b, :], axis=0)
        # Keep the unwrapped path inside the limits if a common 2*pi shift allows it.
        shift = 2 * np.pi * np.round((np.clip(q[0], ik.q_min, ik.q_max) - q[0]) / (2 * np.pi))
        q = q + shift
        if np.any(q < ik.q_min - 1e-12) or np.any(q > ik.q_max + 1e-12):
            j = int(np.argmax(np.any((q < ik.q_min) | (q > ik.q_max), axis=0)))
            rejected[b] = f"joint {j + 1} leaves its limits along the path"
            continue
        steps = np.abs(np.diff(q, axis=0)).max(axis=1) if len(q) > 1 else np.zeros(1)
        if steps.max() > max_step:
            k = int(np.argmax(steps))
            rejected[b] = f"flip between waypoints {k} and {k + 1}: joint step {steps[k]:.3g} rad > {max_step:g} rad"
            continue
        feasible[b] = BranchPath(b, q, float(steps.max()), ik.labels[b])
    return feasible, rejected


def default_branch(
    feasible: dict[int, BranchPath],
    q_home: np.ndarray,
    rejected: dict[int, str] | None = None,
    labels: tuple[str, ...] = (),
) -> int:
    """The feasible branch whose first waypoint is nearest the home configuration.

    Raises
    ------
    UnreachableError
        No branch is feasible; the message gives each branch's reason.
    """
    if not feasible:
        why = "; ".join(f"{labels[b] if b < len(labels) else b}: {r}" for b, r in sorted((rejected or {}).items()))
        raise UnreachableError("no IK branch is feasible along the whole path" + (f" ({why})" if why else ""))
    home = np.asarray(q_home, float)

    def dist(bp: BranchPath) -> float:
        d = (bp.q[0] - home + np.pi) % (2 * np.pi) - np.pi
        return float(np.linalg.norm(d))

    return min(feasible, key=lambda b: dist(feasible[b]))
