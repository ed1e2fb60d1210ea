"""A problem moved to a base placement: the same task, written in the placed robot's base frame.

The problem's path, nominal orientations and base-frame wrench (and a predicted cut's wrench) are in the cell frame (the
problem as written is the placement at the origin).  :func:`problem_at` maps them with the
placement's ``cell2base`` (:mod:`problems.placement.grid`): positions and rotations as
coordinates, a base-frame force and moment as free vectors (fixed in the cell), the payload's
gravity and the arm's own gravity (its self-weight) as free vectors.  A tool-frame wrench and
the payload's centre of mass (tool frame) are unchanged.  Limits, solver, timing and the home
posture are the problem's own.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from models.transforms import matrix_to_rpy, rpy_to_matrix
from problems.placement.grid import cell2base, placement_label
from problems.problem import Problem


def problem_at(problem: Problem, placement: np.ndarray) -> Problem:
    """``problem`` with its robot placed at ``placement`` ``[x, y, z, yaw, tilt]`` (m, rad).

    Parameters
    ----------
    problem : Problem
        Written in the cell frame.
    placement : ndarray, shape (5,)

    Returns
    -------
    Problem
        In the placed base frame; planned like any problem.
    """
    T = cell2base(np.asarray(placement, dtype=float).reshape(1, 5))[0]
    R, t = T[:3, :3], T[:3, 3]
    P = problem.positions @ R.T + t
    Rot = np.einsum("ij,njk->nik", R, problem.rotations)
    line = None if problem.line is None else (R @ problem.line[0] + t, R @ problem.line[1] + t)
    W = problem.wrench.copy()
    if problem.wrench_frame == "base":
        W[:, :3] = W[:, :3] @ R.T
        W[:, 3:] = W[:, 3:] @ R.T
    g_payload = problem.robot.gravity if problem.gravity is None else problem.gravity
    arm = replace(
        problem.model,
        nominal=replace(problem.model.nominal, gravity=R @ np.asarray(problem.model.nominal.gravity, dtype=float)),
    )
    robot = arm.nominal  # one description: the problem's robot is its model's
    rpy = matrix_to_rpy(R @ rpy_to_matrix(problem.nominal_rpy))
    label = placement_label(np.asarray(placement, dtype=float))
    return replace(
        problem,
        description=f"{problem.description} (base placed at {label})",
        positions=P,
        rotations=Rot,
        line=line,
        wrench=W,
        gravity=R @ np.asarray(g_payload, dtype=float),
        robot=robot,
        arm=arm,
        nominal_rpy=rpy,
        cell=None if problem.cell is None else problem.cell.moved(T),  # the objects seen from the placed base
        cut=None if problem.cut is None else problem.cut.rotated(R),  # the cut's wrench is fixed in the cell
    )


__all__ = ["problem_at"]
