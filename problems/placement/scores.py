"""Scores of base placements: the status of each placement and the numbers that rank them.

Per placement and IK branch (a branch is *feasible* when the kernel found a flip-free
sequence of scanned orientations inside the joint limits and outside every singularity
guard, see :mod:`problems.placement.kernel`):

* ``branch_rms_m``, ``branch_max_m``: RMS and largest load-induced TCP position error along
  the path, m (the arm model's ``load_error``, the posture NLP's objective, at the analytic
  postures of the chosen orientations);
* ``branch_joint_margin_rad``: the smallest distance of any joint to its limit along the
  path, rad;
* ``branch_singular_margin``: the smallest ratio of a singularity guard factor to its guard
  bound along the path (1 = at the guard the posture NLP keeps; 2 = twice as far).

Per placement, the *best branch* is the feasible branch with the smallest RMS error, and the
placement's scores are that branch's.  An infeasible placement has a
:class:`PlacementStatus` saying why and, for ``UNREACHABLE``, the first waypoint concerned.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from models.status import CodedStatus


class PlacementStatus(CodedStatus):
    """Why a placement is (in)feasible; ``code`` is the integer of :attr:`ChunkScores.status`."""

    OK = "ok", 0
    #: some waypoint has no IK solution outside the singularity guards on any branch at any
    #: scanned orientation (or no single branch reaches every waypoint)
    UNREACHABLE = "unreachable", 1
    #: every branch reaching all waypoints must flip (a joint step above ``max_joint_step``)
    FLIP = "flip", 2
    #: every flip-free branch leaves a joint's limits along the path, or the first waypoint out of
    #: reach has solutions that only the joint limits exclude
    JOINT_LIMIT = "joint_limit", 3
    #: the base footprint overlaps a cell object, or every branch that is otherwise feasible (flip-
    #: free, inside the joint limits) comes closer than the cell's clearance to an object or to
    #: itself at every sequence of scanned orientations (only with a ``[cell]``)
    COLLISION = "collision", 4


#: One line per status, for reports and summaries.
STATUS_REASONS = {
    PlacementStatus.OK: "feasible",
    PlacementStatus.UNREACHABLE: "a waypoint is out of reach (or inside a singularity guard) on every branch",
    PlacementStatus.FLIP: "every branch reaching the whole path flips (joint step above max_joint_step)",
    PlacementStatus.JOINT_LIMIT: "the joint limits exclude every branch (along the path, or at a waypoint whose "
    "solutions all lie outside them)",
    PlacementStatus.COLLISION: "the base stands on an object, or every otherwise feasible branch comes closer than "
    "the clearance to an object or to itself",
}


@dataclass
class ChunkScores:
    """Scores of P placements with B branches (see the module docstring).

    Attributes
    ----------
    status : ndarray of int8, shape (P,)
        :attr:`PlacementStatus.code` per placement (``PlacementStatus.from_code`` gives the enum).
    best_branch : ndarray of int8, shape (P,)
        -1 where infeasible.
    feasible_branches : ndarray of int8, shape (P,)
    blocked_waypoint : ndarray of int32, shape (P,)
        First waypoint out of reach on every branch (-1: none).
    rms_error_m, max_error_m, joint_margin_rad, singular_margin : ndarray, shape (P,)
        The best branch's (NaN where infeasible).
    branch_rms_m, branch_max_m, branch_joint_margin_rad, branch_singular_margin : ndarray, shape (P, B)
        Per branch (NaN where the branch is infeasible).
    """

    status: np.ndarray
    best_branch: np.ndarray
    feasible_branches: np.ndarray
    blocked_waypoint: np.ndarray
    rms_error_m: np.ndarray
    max_error_m: np.ndarray
    joint_margin_rad: np.ndarray
    singular_margin: np.ndarray
    branch_rms_m: np.ndarray
    branch_max_m: np.ndarray
    branch_joint_margin_rad: np.ndarray
    branch_singular_margin: np.ndarray

    @classmethod
    def empty(cls, P: int, B: int) -> ChunkScores:
        nan1, nan2 = (lambda: np.full(P, np.nan)), (lambda: np.full((P, B), np.nan))
        return cls(
            status=np.zeros(P, np.int8),
            best_branch=np.full(P, -1, np.int8),
            feasible_branches=np.zeros(P, np.int8),
            blocked_waypoint=np.full(P, -1, np.int32),
            rms_error_m=nan1(),
            max_error_m=nan1(),
            joint_margin_rad=nan1(),
            singular_margin=nan1(),
            branch_rms_m=nan2(),
            branch_max_m=nan2(),
            branch_joint_margin_rad=nan2(),
            branch_singular_margin=nan2(),
        )

    def __len__(self) -> int:
        return int(len(self.status))

    def finish(
        self,
        flip: np.ndarray,
        limit: np.ndarray,
        gap_limit: np.ndarray | None = None,
        collision: np.ndarray | None = None,
    ) -> None:
        """Pick the best branch of each placement and set its status.

        ``flip``, ``limit`` (P, B): branches that reach every waypoint but flip, or leave the
        joint limits; ``gap_limit`` (P,): the first waypoint out of reach has an IK solution that
        only the joint limits exclude (the placement is then ``JOINT_LIMIT``, not ``UNREACHABLE``);
        ``collision`` (P, B): branches that would be feasible but violate the cell's clearance on
        every sequence (the placement is then ``COLLISION`` when no branch is feasible; it takes
        precedence over ``FLIP`` and ``JOINT_LIMIT``)."""
        feas = np.isfinite(self.branch_rms_m)
        self.feasible_branches[:] = feas.sum(axis=1)
        anyf = feas.any(axis=1)
        best = np.argmin(np.where(feas, self.branch_rms_m, np.inf), axis=1)
        rows = np.flatnonzero(anyf)
        b = best[rows]
        self.best_branch[rows] = b
        for dst, src in (
            (self.rms_error_m, self.branch_rms_m),
            (self.max_error_m, self.branch_max_m),
            (self.joint_margin_rad, self.branch_joint_margin_rad),
            (self.singular_margin, self.branch_singular_margin),
        ):
            dst[rows] = src[rows, b]
        st = np.full(len(self.status), PlacementStatus.OK.code, dtype=np.int8)
        unreach = self.blocked_waypoint >= 0
        st[~anyf & limit.any(axis=1)] = PlacementStatus.JOINT_LIMIT.code
        st[~anyf & ~limit.any(axis=1) & flip.any(axis=1)] = PlacementStatus.FLIP.code
        st[~anyf & unreach] = PlacementStatus.UNREACHABLE.code
        # reach on no single branch although every waypoint is reached on some branch
        st[~anyf & ~unreach & ~flip.any(axis=1) & ~limit.any(axis=1)] = PlacementStatus.UNREACHABLE.code
        if gap_limit is not None:
            st[~anyf & unreach & gap_limit] = PlacementStatus.JOINT_LIMIT.code
        if collision is not None:
            st[~anyf & ~unreach & collision.any(axis=1)] = PlacementStatus.COLLISION.code
        self.status[:] = st

    def set_rows(self, rows: np.ndarray, other: ChunkScores) -> None:
        """Copy ``other``'s rows (in order) into rows ``rows`` of these scores."""
        for f in fields(self):
            getattr(self, f.name)[rows] = getattr(other, f.name)

    @property
    def feasible(self) -> np.ndarray:
        """(P,) bool."""
        return self.status == PlacementStatus.OK.code

    def status_of(self, i: int) -> PlacementStatus:
        """The :class:`PlacementStatus` of placement ``i``."""
        return PlacementStatus.from_code(self.status[i])

    @classmethod
    def concatenate(cls, parts: list[ChunkScores]) -> ChunkScores:
        """The scores of several chunks, in order."""
        return cls(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls)})

    def equal(self, other: ChunkScores) -> bool:
        """Bit-for-bit equality of every array (NaN equal to NaN)."""
        return all(np.array_equal(getattr(self, f.name), getattr(other, f.name), equal_nan=True) for f in fields(self))

    def max_difference(self, other: ChunkScores) -> float:
        """Largest absolute difference over every float array (NaN positions must match, else inf)."""
        worst = 0.0
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if a.shape != b.shape:
                return float("inf")
            if a.dtype.kind != "f":
                if not np.array_equal(a, b):
                    return float("inf")
                continue
            if not np.array_equal(np.isnan(a), np.isnan(b)):
                return float("inf")
            m = ~np.isnan(a)
            if m.any():
                worst = max(worst, float(np.abs(a[m] - b[m]).max()))
        return worst


#: Resolution of the errors when ranking, m: placements whose errors agree to it (e.g. yaws that
#: joint 1 absorbs exactly) are ordered by their margins instead of by round-off.
RANK_RESOLUTION_M = 1e-7


#: Resolution of the singularity-margin ratio when ranking (dimensionless): placements whose
#: margins agree to it (the same posture turned by a yaw) are ordered by their joint margins.
RANK_RESOLUTION_SINGULAR = 1e-9


def ranking(scores: ChunkScores) -> np.ndarray:
    """Indices of the feasible placements, best first: smallest RMS error, then smallest largest
    error (both at :data:`RANK_RESOLUTION_M`), then the larger singularity margin (at
    :data:`RANK_RESOLUTION_SINGULAR`), then the larger joint-limit margin, then the lower index."""
    idx = np.flatnonzero(scores.feasible)
    rms = np.round(scores.rms_error_m[idx] / RANK_RESOLUTION_M)
    mx = np.round(scores.max_error_m[idx] / RANK_RESOLUTION_M)
    sing = np.round(scores.singular_margin[idx] / RANK_RESOLUTION_SINGULAR)
    order = np.lexsort((idx, -scores.joint_margin_rad[idx], -sing, mx, rms))
    return idx[order]


__all__ = [
    "ChunkScores",
    "PlacementStatus",
    "RANK_RESOLUTION_M",
    "RANK_RESOLUTION_SINGULAR",
    "STATUS_REASONS",
    "ranking",
]
