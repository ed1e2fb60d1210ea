"""The section-4.4 pipeline: IK along the path, error before, closed-form and exact compensation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pathlib import Path

from models import AnalyticIK, KinematicModel, Robot
from models.symbolic import directional_stiffness
from models.errors import CompplanError, InfeasibleError
from models.ik import BRANCH_LABELS
from models.transforms import tool_down_rotation
from problems import paper
from problems.compensation import (CompensationResult, CompensationStatus, closed_form, exact,
                                   uncompensated)
from problems.path import BranchPath, branch_paths, default_branch, line_positions, poses

from planner.output import OutputSet

#: Columns of ``waypoints.csv`` (see docs/output-files.md).
WAYPOINT_COLUMNS = (["k", "s", "x", "y", "z"]
                    + [f"qt{i}" for i in range(1, 7)] + [f"qc{i}" for i in range(1, 7)]
                    + [f"qf{i}" for i in range(1, 7)]
                    + ["ebx", "eby", "ebz", "efx", "efy", "efz", "eex", "eey", "eez", "kx", "ky", "kz"])


def error_stats(res: CompensationResult) -> dict[str, float]:
    """Max and RMS of the Euclidean TCP position error, mm."""
    e = res.error_norm_m * 1e3
    return {"max_mm": float(e.max()), "rms_mm": float(np.sqrt(np.mean(e ** 2)))}


@dataclass
class DemoResult:
    robot: Robot
    positions: np.ndarray          # (N, 3) target TCP, m, base frame
    base2target: np.ndarray        # (N, 4, 4)
    wrench: np.ndarray             # (6,)
    branch: BranchPath
    branches: dict[int, BranchPath]
    rejected: dict[int, str]
    before: CompensationResult
    closed: CompensationResult
    exact: CompensationResult
    warnings: list[str] = field(default_factory=list)

    def waypoint_table(self) -> np.ndarray:
        """Rows of ``waypoints.csv`` (see :data:`WAYPOINT_COLUMNS`)."""
        n = len(self.positions)
        seg = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(self.positions, axis=0), axis=1))]
        s = seg / seg[-1] if seg[-1] > 0 else seg
        model = KinematicModel(self.robot)
        Cs = model.C(self.branch.q)
        k = np.stack([directional_stiffness(Cs, np.eye(3)[i]) for i in range(3)], axis=1)
        return np.hstack([np.arange(n)[:, None], s[:, None], self.positions, self.branch.q,
                          self.exact.q_command, self.closed.q_command, self.before.error_m,
                          self.closed.error_m, self.exact.error_m, k])

    def branch_table(self) -> tuple[list[str], np.ndarray]:
        """``branches.csv``: load-induced TCP error norm (m) per feasible branch at its analytic posture."""
        model = KinematicModel(self.robot)
        cols, data = ["k"], [np.arange(len(self.positions))]
        for b in sorted(self.branches):
            res = uncompensated(model, self.branches[b].q, self.wrench)
            cols.append(f"{self.branches[b].label}_analytic_m")
            data.append(res.error_norm_m)
        return cols, np.stack(data, axis=1)

    def summary(self) -> dict[str, Any]:
        return {
            "scenario": "paper section 4.4",
            "robot": self.robot.name,
            "tcp": "flange",
            "orientation": "tool z axis pointing down (base -z), R = Rx(pi)",
            "wrench": {"frame": "base", "point": "TCP", "F_N": self.wrench[:3], "M_Nm": self.wrench[3:]},
            "n_waypoints": int(len(self.positions)),
            "branch": self.branch.label,
            "error_before": error_stats(self.before),
            "error_after": {"closed_form": error_stats(self.closed), "exact": error_stats(self.exact)},
            "exact_residual_max_m": float(self.exact.error_norm_m.max()),
            "status": {"closed_form": self.closed.status.value, "exact": self.exact.status.value},
            "warnings": self.warnings + self.closed.warnings,
            "rejected_branches": {BRANCH_LABELS[b]: r for b, r in self.rejected.items()},
            "robot_file": self.robot.to_dict(),
        }


def run_demo(robot: Robot, n_points: int = paper.SECTION_4_4_POINTS,
             wrench: np.ndarray | None = None) -> DemoResult:
    """Run the paper's section-4.4 scenario on ``robot`` (TCP as in the robot file).

    Raises
    ------
    CompplanError
        If no branch reaches the whole path or the exact compensation fails.
    """
    F = paper.SECTION_4_4_WRENCH if wrench is None else np.asarray(wrench, float)
    model = KinematicModel(robot)
    ik = AnalyticIK(robot)
    P = line_positions(paper.SECTION_4_4_START_M, paper.SECTION_4_4_END_M, n_points)
    T = poses(P, tool_down_rotation())
    feasible, rejected = branch_paths(ik, T)
    b = default_branch(feasible, paper.HOME_Q, rejected)
    bp = feasible[b]
    before = uncompensated(model, bp.q, F)
    closed = closed_form(model, bp.q, F)
    ex = exact(model, bp.q, F)
    if ex.status is not CompensationStatus.OK:
        raise InfeasibleError(f"exact compensation failed: {ex.reason}")
    return DemoResult(robot, P, T, F, bp, feasible, rejected, before, closed, ex)


def write_outputs(res: DemoResult, folder: str | Path) -> dict[str, Any]:
    """Write summary.json, path.csv, waypoints.csv and branches.csv (all or nothing)."""
    summary = res.summary()
    out = OutputSet(folder)
    out.add_json("summary.json", summary)
    out.add_csv("path.csv", ["x", "y", "z", "q1", "q2", "q3", "q4", "q5", "q6"],
                np.hstack([res.positions, res.exact.q_command]))
    out.add_csv("waypoints.csv", WAYPOINT_COLUMNS, res.waypoint_table())
    cols, rows = res.branch_table()
    out.add_csv("branches.csv", cols, rows)
    out.publish()
    return summary
