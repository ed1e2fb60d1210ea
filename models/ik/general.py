"""IK family: any other 6R arm, through EAIK's subproblem decomposition or a numeric multi-start.

Tried last.  Branch labels ``b1, b2, ...`` follow continuity along the poses of one call
(EAIK returns its solutions in no fixed order); :meth:`solve_like` matches them to a
reference, which is how the posture warm starts keep one label per branch across scanned
orientations.  :mod:`models.ik.general_solver` builds an EAIK robot from the chain's joint axes; when
EAIK knows a closed-form decomposition of the geometry every branch is found for certain;
otherwise a deterministic numeric multi-start finds the branches it can and says it may have
missed one (``complete`` is False, ``note`` says why).  The guard is the sign of the
Jacobian's determinant (the branches of a general arm have no simpler invariant), and the
posture result is re-checked against the branch after solving.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .general_numeric import general_guard_factors
from .general_solver import GeneralIK, GeneralIKStatus
from ..robot import Robot
from ..transforms import invert
from .base import FALLBACK_ORDER, IKSolution, IKSolver, IKStatus, check_poses, into_limits, register_family, zero_axes

#: The helper's status codes -> IKStatus.
_CODES = {
    GeneralIKStatus.OK.code: IKStatus.OK,
    GeneralIKStatus.UNREACHABLE.code: IKStatus.UNREACHABLE,
    GeneralIKStatus.SINGULAR.code: IKStatus.SINGULAR,
}


@register_family
class GeneralSixR(IKSolver):
    """All branches of a 6R arm that is neither UR-type nor OPW."""

    family = "general"
    order = FALLBACK_ORDER  # accepts any 6R chain: tried last
    description = "any other 6R (EAIK subproblem decomposition, else numeric multi-start)"
    guard_names = ("det J",)
    guard_kinds = ("det",)
    labels_stable = False

    def __init__(self, robot: Robot) -> None:
        super().__init__(robot)
        self._w, self._p, self._M0 = zero_axes(robot)
        self.backend = GeneralIK(self._w, self._p, self._M0)
        self.labels = tuple(self.backend.labels)
        self.complete = self.backend.kind == "eaik"
        self._flange2tcp = invert(np.asarray(robot.tcp2flange, dtype=float))
        self.note = ""

    def guard_factors(self, q: Any) -> Any:
        """``det J`` of the flange Jacobian over a length scale cubed (dimensionless)."""
        return general_guard_factors(self._w, self._p, self._M0, q)

    def solve(self, tcp2base: np.ndarray) -> IKSolution:
        """Every branch found for target TCP pose(s) ((4, 4) or (N, 4, 4), base frame)."""
        res = self.backend.solve(check_poses(tcp2base) @ self._flange2tcp)
        status = np.vectorize(lambda c: _CODES.get(int(c), IKStatus.UNREACHABLE).code)(res.status)
        q, fits = into_limits(np.asarray(res.q, dtype=float), self.q_min, self.q_max)
        status = np.where((status == IKStatus.OK.code) & ~fits, IKStatus.JOINT_LIMIT.code, status)
        q[status != IKStatus.OK.code] = np.nan
        self.complete = bool(res.complete)
        self.note = res.note
        return IKSolution(q=q, status=status.astype(int), labels=self.labels)
