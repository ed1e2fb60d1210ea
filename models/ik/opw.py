"""IK family: ortho-parallel arms with a spherical wrist (OPW), closed form, 8 branches.

The chain (any robot file: DH table or URDF) is mapped onto the canonical OPW arm of
Brandstötter, Angerer & Hofbaur (2014) (parameters ``a1, a2, b, c1..c4``, a sign and an
offset per joint, a base and a flange transform) by :mod:`models.ik.opw_closed_form`, which also holds
the closed form.  Branch labels ``front|back``-``up|down``-``noflip|flip`` (see
``docs/conventions.md``, "IK branches").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..codegen import BatchFunction, VMBatchFunction, batch_function
from .opw_closed_form import OPW_BRANCH_LABELS, NotOPW, opw_guard_factors, opw_ik_function
from .opw_detect import opw_from_axes
from ..robot import Robot
from ..transforms import invert
from .base import IKSolution, IKSolver, IKStatus, IKStructureError, check_poses, into_limits, register_family, zero_axes

#: Threads of the batch evaluation of the closed form.
OPW_BATCH_THREADS = 2


@register_family
class OPWIK(IKSolver):
    """Closed-form IK of an ortho-parallel arm with a spherical wrist.

    Parameters
    ----------
    robot : Robot
        Its chain must have the OPW structure; otherwise :class:`IKStructureError` names
        the joints that break it.

    Attributes
    ----------
    geom : models.ik.opw_closed_form.OPWGeometry
        The canonical parameters, signs, offsets and end transforms.
    """

    family = "opw"
    order = 20
    description = "ortho-parallel with a spherical wrist (KUKA, ABB, Fanuc, ...; closed form, 8 branches)"
    labels = OPW_BRANCH_LABELS
    guard_names = ("shoulder", "elbow", "wrist")  # wrist centre from axis 1 (m), sin(bend), sin(theta5)
    guard_kinds = ("length", "sine", "sine")

    def __init__(self, robot: Robot) -> None:
        super().__init__(robot)
        w, p, M0 = zero_axes(robot)
        try:
            self.geom = opw_from_axes(w, p, M0)
        except NotOPW as exc:
            raise IKStructureError(f"robot '{robot.name}' is not an OPW arm: {exc}") from None
        self._flange2tcp = invert(np.asarray(robot.tcp2flange, dtype=float))
        self.function = opw_ik_function(self.geom)
        self._evaluator: BatchFunction | VMBatchFunction | None = None

    def branch_meaning(self) -> dict[str, str]:
        part = {
            "front": "wrist centre in front of axis 1",
            "back": "wrist centre behind axis 1 (over the top)",
            "up": "elbow above the shoulder-wrist line",
            "down": "elbow below it",
            "noflip": "theta5 > 0",
            "flip": "theta5 < 0 (wrist flipped)",
        }
        return {lab: ", ".join(part[x] for x in lab.split("-")) for lab in self.labels}

    def guard_factors(self, q: Any) -> Any:
        """Shoulder (m), elbow and wrist factors whose signs are the branch (see :mod:`models.ik.opw_closed_form`)."""
        return opw_guard_factors(self.geom, q)

    @property
    def evaluator(self) -> BatchFunction | VMBatchFunction:
        """Batch evaluator of the closed form (compiled C, or CasADi's virtual machine)."""
        if self._evaluator is None:
            self._evaluator = batch_function(self.function, OPW_BATCH_THREADS)
        return self._evaluator

    def solve(self, tcp2base: np.ndarray) -> IKSolution:
        """All 8 branches for target TCP pose(s) ((4, 4) or (N, 4, 4), base frame).

        Returns ``q`` (N, 8, 6) rad within the joint limits (nearest 0), NaN where none, and
        ``status`` (N, 8).
        """
        T = check_poses(tcp2base) @ self._flange2tcp
        n = T.shape[0]
        qc, st = self.evaluator(T.transpose(0, 2, 1).reshape(n, 16))
        q = qc.transpose(0, 2, 1).copy()
        status = st.astype(int)
        q, fits = into_limits(q, self.q_min, self.q_max)
        status = np.where((status == IKStatus.OK.code) & ~fits, IKStatus.JOINT_LIMIT.code, status)
        q[status != IKStatus.OK.code] = np.nan
        return IKSolution(q=q, status=status, labels=self.labels)
