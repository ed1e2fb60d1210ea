"""What every IK family shares: statuses, the solution object, the solver interface, the registry.

An IK family is a module of :mod:`models.ik` with one :class:`IKSolver` subclass decorated
with :func:`register_family` (or such a module in a folder of ``$COMPPLAN_IK_PATH``).
:func:`ik_solver` tries the families in increasing ``order`` (:attr:`IKSolver.order`) and
returns the first whose structure check accepts the robot's chain, so the family is
detected from the chain itself (joint axes and offsets), never from a name.

Every family gives, per target pose, a fixed list of *branches* with stable labels
(``labels``): branch ``b`` of one pose and branch ``b`` of the next are the same formula,
so a path can be followed on one branch.  Its ``guard_factors`` are smooth functions of the
joint angles whose signs identify the branch and which cross zero at the singularities that
separate branches; the posture NLP keeps ``sign * factor >= guard_bounds`` to stay on its
branch (``docs/conventions.md``, "IK branches").
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..errors import InputError, PluginError
from ..robot import Robot
from ..status import CodedStatus
from ..transforms import dh_chain_frames


class IKStatus(CodedStatus):
    """Why a branch has (or has no) solution; ``code`` is the integer of :attr:`IKSolution.status`."""

    OK = "ok", 0
    SHOULDER_UNREACHABLE = "shoulder_unreachable", 1  # wrist centre inside the lateral-offset cylinder
    WRIST_UNREACHABLE = "wrist_unreachable", 2  # |cos(theta5)| > 1
    WRIST_SINGULAR = "wrist_singular", 3  # sin(theta5) ~ 0: theta6 undetermined (joints 4, 6 aligned)
    ELBOW_UNREACHABLE = "elbow_unreachable", 4  # target beyond the reach of links 2-3
    JOINT_LIMIT = "joint_limit", 5  # a solution exists but no 2*pi shift puts it in the limits
    SHOULDER_SINGULAR = "shoulder_singular", 6  # wrist centre on the joint-1 axis: theta1 undetermined
    UNREACHABLE = "unreachable", 7  # general arms: this branch has no solution for the pose
    SINGULAR = "singular", 8  # general arms: the solution is at a singular Jacobian


IK_REASONS = {
    IKStatus.OK: "ok",
    IKStatus.SHOULDER_UNREACHABLE: "unreachable: wrist centre closer to the base axis than the lateral offset",
    IKStatus.WRIST_UNREACHABLE: "unreachable: no theta5 (|cos theta5| > 1)",
    IKStatus.WRIST_SINGULAR: "singular: wrist (axes 4 and 6 aligned), theta4 and theta6 not separable",
    IKStatus.ELBOW_UNREACHABLE: "unreachable: beyond the reach of the upper arm and forearm",
    IKStatus.JOINT_LIMIT: "outside the joint limits",
    IKStatus.SHOULDER_SINGULAR: "singular: wrist centre on the joint-1 axis (shoulder singularity)",
    IKStatus.UNREACHABLE: "unreachable: no solution on this branch",
    IKStatus.SINGULAR: "singular: the Jacobian is singular at the solution",
}


class IKStructureError(InputError):
    """No IK family applies to the robot's chain (the message says why for each)."""


@dataclass
class IKSolution:
    """All branches of an IK family for N target poses.

    Attributes
    ----------
    q : ndarray, shape (N, B, 6)
        Joint angles (rad); NaN where the branch has no solution.
    status : ndarray of int, shape (N, B)
        :attr:`IKStatus.code` per branch (:meth:`status_of` gives the enum).
    labels : tuple of str, length B
        The family's branch labels.
    """

    q: np.ndarray
    status: np.ndarray
    labels: tuple[str, ...] = field(default=())

    @property
    def valid(self) -> np.ndarray:
        """(N, B) bool: branch has a solution within the limits."""
        return self.status == IKStatus.OK.code

    def status_of(self, i: int, branch: int) -> IKStatus:
        """The :class:`IKStatus` of pose ``i``, branch ``branch``."""
        return IKStatus.from_code(self.status[i, branch])

    def reason(self, i: int, branch: int) -> str:
        """Human-readable reason for pose ``i``, branch ``branch``."""
        return IK_REASONS[self.status_of(i, branch)]

    def summary(self, i: int) -> str:
        """One line per pose: the worst reason if no branch is valid."""
        if self.valid[i].any():
            return f"{int(self.valid[i].sum())} branch(es)"
        codes = sorted({int(c) for c in self.status[i]})
        return "; ".join(IK_REASONS[IKStatus.from_code(c)] for c in codes)


def into_limits(
    q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray, seed: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Shift each angle by 2*pi*k into [q_min, q_max], nearest to ``seed`` (default 0).

    Returns the shifted angles (same shape as ``q``) and, per row of the last axis, whether
    all of its joints fit (rows with NaN count as fitting: they are masked elsewhere).
    """
    ref = np.zeros_like(q) if seed is None else np.broadcast_to(seed, q.shape)
    two_pi = 2.0 * np.pi
    with np.errstate(invalid="ignore"):
        k = np.round((ref - q) / two_pi)
        cand = q + two_pi * k
        lo = cand < q_min
        cand = np.where(lo, cand + two_pi * np.ceil((q_min - cand) / two_pi), cand)
        hi = cand > q_max
        cand = np.where(hi, cand - two_pi * np.ceil((cand - q_max) / two_pi), cand)
        ok = (cand >= q_min - 1e-12) & (cand <= q_max + 1e-12)
    return cand, ok.all(axis=-1) | np.isnan(q).any(axis=-1)


#: Cost of leaving a reference slot unmatched (rad; above any real joint distance).
UNMATCHED_COST = 1e3


def match_branches(sol: IKSolution, reference: np.ndarray) -> IKSolution:
    """``sol`` with each pose's branches permuted onto the slots of the nearest ``reference``
    branches (N, B, 6), rad (wrapped joint distance; linear assignment; NaN never matches)."""
    from scipy.optimize import linear_sum_assignment

    q, st = sol.q.copy(), sol.status.copy()
    ref = np.broadcast_to(np.asarray(reference, dtype=float), q.shape)
    for i in range(q.shape[0]):
        d = np.linalg.norm((q[i][:, None, :] - ref[i][None, :, :] + np.pi) % (2 * np.pi) - np.pi, axis=2)
        d = np.where(np.isfinite(d), d, UNMATCHED_COST)
        rows, cols = linear_sum_assignment(d)
        q[i, cols], st[i, cols] = sol.q[i, rows], sol.status[i, rows]
    return IKSolution(q=q, status=st, labels=sol.labels)


def check_poses(tcp2base: np.ndarray) -> np.ndarray:
    """Target poses as (N, 4, 4), refusing wrong shapes and non-finite entries."""
    T = np.asarray(tcp2base, dtype=float)
    if T.shape[-2:] != (4, 4):
        raise InputError(f"target poses: expected shape (4, 4) or (N, 4, 4), got {T.shape}")
    T = T.reshape(-1, 4, 4)
    if not np.all(np.isfinite(T)):
        bad = int(np.where(~np.isfinite(T).all(axis=(1, 2)))[0][0])
        raise InputError(f"target pose {bad} is not finite: {T[bad].tolist()}; expected finite entries")
    return T


class IKSolver(abc.ABC):
    """All-branch inverse kinematics of one robot (one family).

    Attributes
    ----------
    family : str
        ``"ur"``, ``"opw"``, ``"general"``, or a plug-in family's name (``$COMPPLAN_IK_PATH``).
    labels : tuple of str
        Branch labels (stable along a path).
    guard_names : tuple of str
        Names of the guard factors (messages).
    guard_kinds : tuple of str
        What each factor is: ``"length"`` (m), ``"sine"`` (1) or ``"det"`` (dimensionless
        Jacobian determinant); the posture NLP's margins are set per kind.
    complete : bool
        Whether every branch is found for certain (False for a numeric search).
    """

    family: ClassVar[str] = ""
    #: Priority: :func:`ik_solver` tries the families in increasing ``order``, ties in
    #: registration order (built-in modules, then plug-in modules by folder and name).  The
    #: built-ins: ``ur`` 10, ``opw`` 20 (closed forms), ``general`` :data:`FALLBACK_ORDER` (it
    #: accepts any 6R chain, so it is tried last).  A family that does not set it gets
    #: :data:`DEFAULT_ORDER`: after the closed forms, before the fallback; one that specialises a
    #: built-in for some arms (e.g. a subclass of the UR family) sets an order below that family's.
    order: ClassVar[float] = 50
    #: One line: which arms the family serves.
    description: ClassVar[str] = ""
    labels: tuple[str, ...] = ()
    guard_names: tuple[str, ...] = ()
    guard_kinds: tuple[str, ...] = ()
    complete: bool = True
    #: Whether a label means the same formula branch in every call (closed forms); otherwise
    #: labels follow continuity within one call and :meth:`solve_like` matches them to a reference.
    labels_stable: bool = True

    #: The family's batch CasADi function (closed forms: poses -> every branch), or None
    #: (numeric families); closed forms evaluate it through :attr:`evaluator`.
    function: Any = None

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.q_min, self.q_max = robot.q_min, robot.q_max

    def use_evaluator(self, evaluator: Any) -> None:
        """Evaluate :attr:`function` with ``evaluator`` from now on: a batch evaluator of it built
        elsewhere, e.g. the compiled library another process shipped
        (:func:`models.portable.evaluator_from_state`), so this process needs no compiler.

        Raises
        ------
        PluginError
            The family has no batch function (a numeric family).
        """
        if self.function is None:
            # callers ship an evaluator only for families with a function; a plug-in family may not have one
            raise PluginError(f"IK family {self.family!r} has no batch function to evaluate")
        self._evaluator = evaluator

    @property
    def n_branches(self) -> int:
        return len(self.labels)

    @abc.abstractmethod
    def solve(self, tcp2base: np.ndarray) -> IKSolution:
        """All branches for target TCP pose(s) ``tcp2base`` ((4, 4) or (N, 4, 4), base frame).

        Returns angles within the joint limits (nearest to 0), NaN and a status where none.
        """

    @abc.abstractmethod
    def guard_factors(self, q: Any) -> Any:
        """The branch's guard factors at ``q``: CasADi (6,) -> (G,), or ndarray (..., 6) -> (..., G)."""

    def branch_meaning(self) -> dict[str, str]:
        """What each label means physically (for reports and docs)."""
        return {lab: lab for lab in self.labels}

    def solve_like(self, tcp2base: np.ndarray, reference: np.ndarray) -> IKSolution:
        """:meth:`solve`, with each pose's branches in the slots of the nearest ``reference``
        solutions (N, B, 6), rad: a continuation from neighbouring poses (e.g. the same waypoint
        at a slightly turned tool).  Families with stable labels ignore ``reference``."""
        sol = self.solve(tcp2base)
        return sol if self.labels_stable else match_branches(sol, reference)

    def nearest(
        self, tcp2base: np.ndarray, seed: np.ndarray, branch: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, IKSolution]:
        """The solution nearest a seed configuration.

        Parameters
        ----------
        tcp2base : ndarray, shape (N, 4, 4) or (4, 4)
        seed : ndarray, shape (N, 6) or (6,)
            Each joint of every branch is shifted by 2*pi*k (within limits) to lie
            nearest the seed; the branch with the smallest Euclidean distance wins.
        branch : int, optional
            Restrict to one branch index.

        Returns
        -------
        q : ndarray, shape (N, 6)
            NaN rows where no branch is valid.
        chosen : ndarray of int, shape (N,)
            Branch index, -1 where none.
        sol : IKSolution
            All branches (shifted to the seed).
        """
        sol = self.solve(tcp2base)
        n, nb = sol.q.shape[:2]
        seed = np.broadcast_to(np.asarray(seed, dtype=float).reshape(-1, 6), (n, 6))
        qs, ok = into_limits(sol.q, self.q_min, self.q_max, seed[:, None, :])
        valid = sol.valid & ok
        dist = np.linalg.norm(qs - seed[:, None, :], axis=-1)
        dist = np.where(valid, dist, np.inf)
        if branch is not None:
            mask = np.zeros(nb, bool)
            mask[branch] = True
            dist = np.where(mask, dist, np.inf)
        chosen = np.argmin(dist, axis=1)
        none = ~np.isfinite(dist[np.arange(n), chosen])
        q = qs[np.arange(n), chosen].copy()
        q[none] = np.nan
        chosen = np.where(none, -1, chosen)
        return q, chosen, IKSolution(q=np.where(valid[..., None], qs, np.nan), status=sol.status, labels=sol.labels)


_FAMILIES: list[type[IKSolver]] = []
#: ``order`` of a family that does not set it (after the closed forms, before the fallback).
DEFAULT_ORDER: float = IKSolver.order
#: ``order`` of the general 6R family, which accepts any 6R chain: the last one tried.
FALLBACK_ORDER: float = 90


def register_family(cls: type[IKSolver]) -> type[IKSolver]:
    """Class decorator: add an IK family to the registry.

    :func:`ik_solver` tries the registered families in increasing :attr:`IKSolver.order`, ties
    in registration order; a family with an order above :data:`FALLBACK_ORDER` would never be
    tried (the general family accepts every 6R chain) and is refused.

    Raises
    ------
    PluginError
        (a ``TypeError``) No ``family`` name, a name registered twice, or an ``order`` that is
        not a number at most :data:`FALLBACK_ORDER`.
    """
    if not cls.family:
        raise PluginError(f"{cls.__name__}: an IK family needs a 'family' name (a non-empty class attribute)")
    if isinstance(cls.order, bool) or not isinstance(cls.order, (int, float)) or not cls.order <= FALLBACK_ORDER:
        raise PluginError(
            f"IK family '{cls.family}': order {cls.order!r}; expected a number <= {FALLBACK_ORDER:g} "
            "(the general family, tried last, accepts every 6R chain)"
        )
    if any(c.family == cls.family for c in _FAMILIES):
        raise PluginError(f"IK family '{cls.family}' registered twice; expected one class per family name")
    _FAMILIES.append(cls)
    _FAMILIES.sort(key=lambda c: c.order)
    return cls


def families() -> list[type[IKSolver]]:
    """The registered IK families, in the order they are tried."""
    return list(_FAMILIES)


def ik_solver(robot: Robot, family: str | None = None) -> IKSolver:
    """The IK solver of ``robot``: the first family whose structure check accepts its chain.

    Parameters
    ----------
    robot : Robot
    family : str, optional
        Force one family (``"ur"``, ``"opw"``, ``"general"``, or a plug-in's name).

    Raises
    ------
    IKStructureError
        No family applies (or the forced one does not), with each family's reason.
    """
    reasons = []
    for cls in _FAMILIES:
        if family is not None and cls.family != family:
            continue
        try:
            return cls(robot)
        except IKStructureError as exc:
            reasons.append(f"{cls.family}: {exc}")
    if family is not None and not reasons:
        raise IKStructureError(f"unknown IK family {family!r}; families: {[c.family for c in _FAMILIES]}")
    raise IKStructureError(f"robot '{robot.name}': no IK family applies: " + " | ".join(reasons))


def dh_frames(robot: Robot, q: np.ndarray) -> np.ndarray:
    """DH frames 0..6 of the robot's nominal chain at ``q`` (6,), base frame, shape (7, 4, 4)."""
    return dh_chain_frames(robot.convention, robot.a, robot.alpha, robot.d, robot.theta_offset, q, robot.frame02base)


def zero_axes(robot: Robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The chain at q = 0 in product-of-exponentials form (nominal geometry).

    Returns
    -------
    w : ndarray, shape (6, 3)
        Unit joint axes, base frame (joint i turns positively about w_i).
    p : ndarray, shape (6, 3)
        A point on each axis, base frame, m.
    flange2base : ndarray, shape (4, 4)
        The flange at q = 0.
    """
    F = dh_frames(robot, np.zeros(6))
    axis_frames = F[:6] if robot.convention == "standard_dh" else F[1:7]
    return (
        axis_frames[:, :3, 2].copy(),
        axis_frames[:, :3, 3].copy(),
        F[6] @ np.asarray(robot.flange2frame6, dtype=float),
    )
