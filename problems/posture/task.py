"""The posture task and its results: the data, named constants and tolerances of the stage.

What is solved is described in :mod:`problems.posture`; this module holds what goes in
(:class:`PostureTask`, :class:`OrientationRule`, :class:`SolverSettings`), what comes out
(:class:`BranchResult`, :class:`PostureResult` and their statuses) and every named constant
(scales, singularity-guard margins, verification tolerances, warm-start and IPOPT
defaults).  All quantities are SI (m, rad, N, N*m) in the robot's base frame unless a name
says otherwise.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.effects import LOAD_SIZE
from models.errors import InputError
from models.load import load_rows
from models.status import Status
from problems.path import MAX_JOINT_STEP

# --------------------------------------------------------------------------------------
# Named constants
# --------------------------------------------------------------------------------------

#: Objective scale: m^2 -> mm^2 (conditioning only; reported costs are in m^2).
COST_SCALE = 1e6
#: Bounds of the objective weight that brings the warm start's objective to about one per
#: waypoint (conditioning only; see :meth:`problems.posture.transcription.PostureNLP.objective_weight`).
OBJECTIVE_WEIGHT_MIN = 1e-2
OBJECTIVE_WEIGHT_MAX = 1e4
#: Position constraints are posed in mm (m -> mm).
POSITION_SCALE = 1e3
#: Tool-axis constraints are posed in mrad (dimensionless -> 1e-3).
AXIS_SCALE = 1e3
#: Singularity guards (the IK family's guard factors, see
#: :func:`~problems.posture.verification.guard_bounds`): a sine factor (wrist, elbow) stays at
#: least this far from 0 (dimensionless; about 2.9 deg) ...
SINGULAR_SIN_MIN = 0.05
#: ... a length factor (the UR shoulder factor rho, the OPW wrist-centre distance from axis 1)
#: at least this far (m) ...
SINGULAR_RHO_MIN_M = 0.02
#: ... and a Jacobian-determinant factor (general 6R arms, dimensionless) at least this far.
SINGULAR_DET_MIN = 1e-3
#: A guard counts as active within this of its bound (m for a length factor, else dimensionless).
GUARD_ACTIVE_TOL = 1e-6
#: Contract: TCP position of the optimised posture on the waypoint to this (m).
POSITION_TOL_M = 1e-9
#: Contract: tool axis (free_tool_axis), orientation (fixed) and cone bound to this (rad).
ORIENTATION_TOL_RAD = 1e-9
#: Slack on the joint limits and joint-step bound when verifying (rad): IPOPT relaxes bounds
#: by ~1e-8 and the post-solve projection moves the joints by about as much.
JOINT_TOL_RAD = 1e-6
#: Gauss-Newton projection after IPOPT: at most this many steps, stop below POLISH_STEP_TOL (rad).
POLISH_MAX_ITER = 8
POLISH_STEP_TOL = 1e-14
#: The TCP counts as on the joint-6 axis (degenerate free rotation) within this (m) ...
DEGENERATE_OFFSET_TOL_M = 1e-9
#: ... and the tool axis as along the joint-6 axis within this angle (rad).
DEGENERATE_ANGLE_TOL_RAD = 1e-9
#: Default number of scanned rotations about the tool axis for the warm start.
DEFAULT_SCAN = 36
#: Extra tool axes of the position-only warm-start candidates: (tilt from the nominal
#: axis in deg, number of directions about it); together they cover the sphere.
POSITION_ONLY_AXES = ((45.0, 4), (90.0, 4), (135.0, 4), (180.0, 1))
#: Warm-start dynamic programme: at most this many cheapest candidates per waypoint
#: (all of them if the pruned graph is disconnected).
DP_MAX_STATES = 48
#: With more candidates than DP_MAX_STATES, transitions are first restricted to candidates
#: whose orientations differ by at most this angle (rad).
DP_NEIGHBOUR_ANGLE_RAD = math.radians(35.0)
#: Default smoothness weight (mm^2/rad^2).
DEFAULT_SMOOTHNESS = 1.0
#: IPOPT defaults.
DEFAULT_MAX_ITER = 200
DEFAULT_TOL = 1e-8
#: IPOPT options used unless a problem overrides them.
IPOPT_DEFAULTS: dict[str, Any] = {
    "mu_strategy": "adaptive",
    "bound_push": 1e-6,
    "bound_frac": 1e-6,
    "nlp_scaling_method": "none",
}  # the NLP is scaled by hand (mm, mrad)
#: IPOPT return statuses accepted as converged.
IPOPT_OK = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
#: Length of the stage parameter vector: p (3), R (9, column-major), F (6), branch signs (3).
N_THETA = 3 + 9 + LOAD_SIZE + 3


class OrientationRule(enum.Enum):
    """How the TCP orientation is constrained at every waypoint."""

    FIXED = "fixed"
    FREE_TOOL_AXIS = "free_tool_axis"
    CONE = "cone"
    POSITION_ONLY = "position_only"


#: Orientation constraints per waypoint of each rule.
N_ORIENTATION = {
    OrientationRule.FIXED: 3,
    OrientationRule.FREE_TOOL_AXIS: 2,
    OrientationRule.CONE: 1,
    OrientationRule.POSITION_ONLY: 0,
}


class BranchStatus(Status):
    """Outcome of one branch's posture optimisation."""

    OPTIMISED = "optimised"  # IPOPT converged, every constraint verified
    NO_FREEDOM = "no_freedom"  # fixed orientation: the IK posture is the only one
    DEGENERATE = "degenerate"  # free rotation turns joint 6 only: zero gradient
    ANALYTIC = "analytic"  # optimisation switched off by the caller
    SOLVER_FAILED = "solver_failed"  # IPOPT did not converge (its status in the reason)
    CONSTRAINT_VIOLATED = "constraint_violated"  # converged, but a constraint fails verification
    COLLISION = "collision"  # closer than the cell's clearance at a waypoint (planner/cell_check.py)

    @property
    def usable(self) -> bool:
        """True if the branch's posture may be executed."""
        return self in (BranchStatus.OPTIMISED, BranchStatus.NO_FREEDOM, BranchStatus.DEGENERATE, BranchStatus.ANALYTIC)


class PostureStatus(Status):
    """Outcome of the whole posture stage."""

    OK = "ok"
    UNREACHABLE = "unreachable"  # a waypoint has no IK solution on any branch
    NO_BRANCH = "no_branch"  # every waypoint reachable, but no branch along the whole path
    SOLVER_FAILED = "solver_failed"  # every feasible branch failed its NLP
    COLLISION = "collision"  # every branch the NLP gave collides with the cell (or itself)


class PostureError(InputError):
    """A posture task is malformed (shapes, values); the message names the field."""


@dataclass(frozen=True)
class SolverSettings:
    """NLP solver settings (a problem names its solver; only ``ipopt`` exists).

    Attributes
    ----------
    name : str
        ``"ipopt"``.
    max_iter : int
        IPOPT iteration limit.
    tol : float
        IPOPT convergence tolerance (scaled NLP error).
    codegen : bool
        Compile the stage functions to C (cached); else CasADi's virtual machine.
    ipopt_options : tuple of (str, value)
        Extra IPOPT options (override the defaults of :data:`IPOPT_DEFAULTS`).
    """

    name: str = "ipopt"
    max_iter: int = DEFAULT_MAX_ITER
    tol: float = DEFAULT_TOL
    codegen: bool = True
    ipopt_options: tuple[tuple[str, Any], ...] = ()


@dataclass
class PostureTask:
    """The data of one posture problem (SI units, base frame).

    Attributes
    ----------
    positions : ndarray, shape (N, 3)
        TCP waypoints, m.
    rotations : ndarray, shape (N, 3, 3)
        Nominal base->TCP rotations; their z column is the nominal tool axis.
    rule : OrientationRule
    wrench : ndarray, shape (N, 6) or (N, LOAD_SIZE)
        The load per waypoint: a base-frame wrench [f (N); m (N*m)] on the TCP, or load
        rows (:mod:`models.load`: base- and tool-frame wrenches, payload), as given.
    cone_half_angle : float
        Cone half-angle alpha, rad (rule ``cone`` only), in (0, pi/2).
    max_joint_step : float
        Largest joint step between neighbouring waypoints, rad.
    smoothness : float
        Weight of ``sum ||q_{k+1} - q_k||^2`` in mm^2/rad^2.
    scan : int
        Number of scanned rotations about the tool axis for the warm starts.
    """

    positions: np.ndarray
    rotations: np.ndarray
    rule: OrientationRule
    wrench: np.ndarray
    cone_half_angle: float = 0.0
    max_joint_step: float = MAX_JOINT_STEP
    smoothness: float = DEFAULT_SMOOTHNESS
    scan: int = DEFAULT_SCAN

    def __post_init__(self) -> None:
        """Validate the fields and normalise the arrays (broadcast, contiguous float).

        Raises
        ------
        PostureError
            Naming the malformed field (and the waypoint, where one is at fault).
        """
        self.positions = np.atleast_2d(np.asarray(self.positions, dtype=float))
        n = self.positions.shape[0]
        if self.positions.shape != (n, 3) or n < 1:
            raise PostureError(f"posture task: positions must have shape (N, 3), got {self.positions.shape}")
        R = np.asarray(self.rotations, dtype=float)
        if R.shape == (3, 3):
            R = np.broadcast_to(R, (n, 3, 3))
        if R.shape != (n, 3, 3):
            raise PostureError(f"posture task: rotations must have shape (3, 3) or ({n}, 3, 3), got {R.shape}")
        orth = np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max(axis=(1, 2))
        if np.any(orth > 1e-9) or np.any(np.linalg.det(R) < 0):
            k = int(np.argmax(orth))
            raise PostureError(f"posture task: rotation of waypoint {k} is not a proper rotation matrix")
        self.rotations = np.ascontiguousarray(R)
        W = np.asarray(self.wrench, dtype=float)
        if W.ndim == 1:
            W = np.broadcast_to(W, (n, W.shape[0]))
        if W.shape not in ((n, 6), (n, LOAD_SIZE)):
            raise PostureError(
                f"posture task: wrench must have shape (6,), ({n}, 6) or ({n}, {LOAD_SIZE}), got {W.shape}"
            )
        self.wrench = np.ascontiguousarray(W)
        for name, arr in (("positions", self.positions), ("wrench", self.wrench)):
            if not np.all(np.isfinite(arr)):
                k = int(np.argmax(~np.isfinite(arr).all(axis=1)))
                raise PostureError(f"posture task: {name} of waypoint {k} is not finite")
        if not isinstance(self.rule, OrientationRule):
            raise PostureError(f"posture task: rule must be an OrientationRule, got {self.rule!r}")
        if self.rule is OrientationRule.CONE and not (0.0 < self.cone_half_angle < math.pi / 2):
            raise PostureError(
                f"posture task: cone half-angle must be in (0, 90) deg, got {math.degrees(self.cone_half_angle):g} deg"
            )
        if not (self.max_joint_step > 0.0 and math.isfinite(self.max_joint_step)):
            raise PostureError(f"posture task: max_joint_step must be > 0 rad, got {self.max_joint_step!r}")
        if not (self.smoothness >= 0.0 and math.isfinite(self.smoothness)):
            raise PostureError(f"posture task: smoothness must be >= 0, got {self.smoothness!r}")
        if int(self.scan) < 1:
            raise PostureError(f"posture task: scan must be >= 1, got {self.scan!r}")

    @property
    def load(self) -> np.ndarray:
        """Load rows of every waypoint, (N, LOAD_SIZE) (see :mod:`models.load`)."""
        return load_rows(self.wrench, self.n)

    @property
    def n(self) -> int:
        """Number of waypoints N."""
        return int(self.positions.shape[0])

    @property
    def axes(self) -> np.ndarray:
        """Nominal tool axes, base frame, shape (N, 3)."""
        return self.rotations[:, :, 2]


@dataclass
class BranchResult:
    """One branch's posture along the path.

    Attributes
    ----------
    branch : int
        Index into the IK family's labels (label of the warm start's IK, :attr:`label`).
    status : BranchStatus
    reason : str
    q : ndarray, shape (N, 6)
        The branch's posture (optimised, or the analytic one when nothing is
        optimised or the solver failed), rad.  This is the *deflected* pose that
        puts the loaded TCP on the waypoint once compensated.
    q_analytic : ndarray, shape (N, 6), or None
        Analytic IK at the nominal rotations (None if the branch does not reach
        the whole path there).
    q_warm : ndarray, shape (N, 6)
        Warm start (the cheapest scanned candidate), rad.
    warm_offset : str
        Which scanned candidate the warm start is (e.g. ``"psi=90deg"``).
    cost, cost_analytic, cost_warm : float
        ``sum_k ||S C(q_k) F_k||^2`` (m^2) at ``q``, ``q_analytic`` (NaN if None)
        and ``q_warm``.
    error_m, error_analytic_m : ndarray, shape (N,)
        Linear load-induced TCP position error ``||S C F||`` per waypoint (m) at
        ``q`` and ``q_analytic`` (NaN if None).
    iterations : int
        IPOPT iterations (0 if not solved).
    solve_time_s : float
        Wall time of the IPOPT call (0 if not solved), s.
    solver_status : str
        IPOPT's return status ("" if not solved).
    residual_m, residual_rad : float
        Largest verified position (m) and orientation (rad) constraint residual.
    active_guards : dict str -> int
        Number of waypoints where a singularity guard is active at ``q`` (within
        :data:`GUARD_ACTIVE_TOL` of its bound), by factor ("shoulder", "wrist", "elbow"):
        there the load error would keep falling towards the singularity.
    """

    branch: int
    status: BranchStatus
    reason: str
    q: np.ndarray
    q_analytic: np.ndarray | None
    q_warm: np.ndarray
    warm_offset: str
    cost: float
    cost_analytic: float
    cost_warm: float
    error_m: np.ndarray
    error_analytic_m: np.ndarray
    iterations: int = 0
    solve_time_s: float = 0.0
    solver_status: str = ""
    residual_m: float = 0.0
    residual_rad: float = 0.0
    active_guards: dict[str, int] = field(default_factory=dict)
    #: The branch's IK label (e.g. ``"s+w-e+"`` or ``"front-up-noflip"``, see ``docs/conventions.md``).
    label: str = ""

    @property
    def rms_error_m(self) -> float:
        """RMS of the linear load-induced TCP error over the waypoints, m."""
        return float(np.sqrt(np.mean(self.error_m**2)))

    @property
    def rms_error_analytic_m(self) -> float:
        """RMS of the linear load-induced TCP error at the analytic posture, m (NaN if none)."""
        return float(np.sqrt(np.mean(self.error_analytic_m**2)))


@dataclass
class PostureResult:
    """Every branch's posture, the choice and the gains.

    Attributes
    ----------
    status : PostureStatus
    reason : str
    task : PostureTask
    branches : dict branch -> BranchResult
        Branches that reach the whole path (at some scanned candidate).
    rejected : dict branch -> str
        Why every other branch was rejected (naming the waypoint).
    chosen : int or None
        The usable branch of least cost (None unless status is OK).
    default : int or None
        The default branch: nearest the home configuration at its analytic posture.
    freedom : str
        ``"none"``, ``"degenerate"`` or ``"free"``; ``freedom_note`` says why.
    unreachable : list of int
        Waypoints with no IK solution on any branch at any scanned candidate.
    build_time_s : float
        Time to build (or load) the solver, s.
    labels : tuple of str
        The IK family's branch labels (index -> label).
    ik_family : str
        The IK family (``"ur"``, ``"opw"``, ``"general"``).
    """

    status: PostureStatus
    reason: str
    task: PostureTask
    branches: dict[int, BranchResult]
    rejected: dict[int, str]
    chosen: int | None
    default: int | None
    freedom: str
    freedom_note: str
    unreachable: list[int] = field(default_factory=list)
    build_time_s: float = 0.0
    labels: tuple[str, ...] = ()
    ik_family: str = ""

    @property
    def ok(self) -> bool:
        """True if a branch was chosen (status OK)."""
        return self.status is PostureStatus.OK

    @property
    def best(self) -> BranchResult:
        """The chosen branch's result (raises if there is none)."""
        if self.chosen is None:
            raise InputError(f"posture: no branch chosen ({self.status.value}: {self.reason})")
        return self.branches[self.chosen]

    def gains(self) -> dict[str, float]:
        """Gains of the chosen optimised posture, as ratios of RMS load-induced error (>1 is better).

        ``vs_default``: over the default branch at its analytic posture;
        ``vs_best_analytic``: over the best branch at its analytic posture (what the
        continuous freedom buys beyond the branch choice); ``*_cost`` the same as
        ratios of the summed squared error.
        """
        if self.chosen is None:
            return {}
        c = self.best.cost
        out: dict[str, float] = {}
        ana = [b.cost_analytic for b in self.branches.values() if np.isfinite(b.cost_analytic)]
        if self.default is not None and np.isfinite(self.branches[self.default].cost_analytic):
            r = self.branches[self.default].cost_analytic / c if c > 0 else math.inf
            out["vs_default_cost"] = r
            out["vs_default"] = math.sqrt(r)
        if ana:
            r = min(ana) / c if c > 0 else math.inf
            out["vs_best_analytic_cost"] = r
            out["vs_best_analytic"] = math.sqrt(r)
        return out
