"""Stiffness-optimal IK branch and posture along a path: one NLP per branch (CasADi + IPOPT).

The problem
-----------
For every IK branch that reaches the whole path, with variables ``q_k`` (rad,
shape (6,)) at the waypoints ``k = 0..N-1``::

    minimise    sum_k  s ||S C(q_k) F_k||^2   +   lam sum_k ||q_{k+1} - q_k||^2
    subject to  p_tcp(q_k) = p_k                       TCP position on the waypoint
                orientation rule at q_k                 (see below)
                q_min <= q_k <= q_max                   joint limits
                |q_{k+1,i} - q_{k,i}| <= dq_max         bounded joint step (no flips)
                sigma_i f_i(q_k) >= m_i, i = 1..3       singularity guards (below)

* ``C(q) = J K^-1 J^T`` is the compliance (:mod:`models.symbolic`), ``F_k`` the
  wrench at waypoint k (base frame, on the TCP, N and N*m).
* ``S = [I3 0]`` (3x6) selects the translational part of the TCP deflection
  ``D = C F = [dp (m); dphi (rad)]``, so ``||S C F||`` is the load-induced TCP
  position error in m and the first term is the sum of its squares (m^2).
  ``s = COST_SCALE = 1e6`` expresses it in mm^2 for IPOPT's conditioning; every
  cost this module *reports* is in m^2 (SI).
* ``lam`` (``smoothness``, mm^2/rad^2) is a small smoothness weight; it
  regularises directions the load does not see and keeps the path smooth.
* The singularity guards: on a UR-type arm ``det J = a2 a3 sin(theta3)
  sin(theta5) rho`` (:func:`singular_factors`), and the signs of the three
  factors (shoulder ``rho``, wrist ``sin theta5``, elbow ``sin theta3``) *are* the
  IK branch.  Each factor keeps the sign it has at the warm start, with a margin
  (``SINGULAR_RHO_MIN_M``, ``SINGULAR_SIN_MIN``), so the optimum stays on its
  branch and away from singular poses (where ``C`` loses rank and the error
  would vanish only on paper).

Orientation rules (``z(q)`` is the TCP z axis = the tool axis, ``R_k`` the nominal
base->TCP rotation of waypoint k, ``a_k = R_k e_z`` its tool axis):

``fixed``
    ``R(q_k) = R_k``: six equations for six joints; the posture is the IK
    solution of the branch and the NLP has nothing to choose (status
    ``NO_FREEDOM``; only the branch is chosen).
``free_tool_axis``
    ``z(q_k) = a_k`` (two equations ``x_k . z = y_k . z = 0`` with ``x_k, y_k``
    the other columns of ``R_k``; ``a_k . z > 0`` is verified): free rotation
    about the tool axis, a 5-DOF task.  Degenerate when the TCP lies on the
    joint-6 axis and the tool axis is along it: the free rotation then turns
    joint 6 only and leaves ``C(q)`` unchanged (the gradient is exactly zero),
    which is detected and reported (status ``DEGENERATE``).
``cone``
    ``a_k . z(q_k) >= cos(alpha)``: tool axis inside the cone of half-angle
    ``alpha`` around ``a_k``; the rotation about the tool axis is free.
``position_only``
    No orientation constraint (a probe or reflector whose orientation does not
    matter).

Warm starts and branch labels
-----------------------------
The *analytic posture* of a branch is the analytic IK at the nominal rotations
``R_k``.  Where a rotation is free, candidate orientations are scanned at every
waypoint (rotations about the tool axis by ``2 pi j / scan``; plus tilts on the
cone's rim for ``cone`` and tool axes covering the sphere for ``position_only``)
and the cheapest sequence under the NLP's own objective (node cost plus
smoothness, joint steps above ``dq_max`` excluded) is found by dynamic
programming over the waypoints (:func:`warm_starts`).  The branch keeps the IK
label of its warm start (:data:`models.ik.BRANCH_LABELS`); the guards make the
label hold at the optimum.

Implementation
--------------
The per-waypoint stage functions (cost, constraints, their gradient, Jacobian
and Lagrangian Hessian) are CasADi SX functions compiled to C once per robot,
tool and rule (cached on disk under ``$COMPPLAN_CACHE``, default
``~/.cache/compplan``, keyed by a hash of the source), independent of ``N``.  The
NLP is assembled in MX by mapping them over the waypoints, with the sparse
derivative functions assembled by hand and passed to ``nlpsol`` (options
``grad_f``, ``jac_g``, ``hess_lag``), so one solver per (robot, rule, N) serves
every branch (only the warm start and parameters change).  After IPOPT, each
waypoint is projected onto its equality constraints by a few Gauss-Newton steps
and every constraint is verified with the forward kinematics of
:class:`models.symbolic.KinematicModel`.

The module prints nothing; IPOPT is quiet unless ``verbose=True``.
"""

from __future__ import annotations

import enum
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from models.codegen import CompileError, compile_shared_library
from models.errors import InputError
from models.ik import BRANCH_LABELS, AnalyticIK, IK_REASONS, IKStatus
from models.arm import ArmModel
from models.effects import LOAD_SIZE
from models.load import load_rows
from models.robot import Robot
from models.symbolic import KinematicModel
from models.transforms import rotation_angle
from problems.path import MAX_JOINT_STEP, BranchPath, branch_paths, default_branch, poses

# --------------------------------------------------------------------------------------
# Named constants
# --------------------------------------------------------------------------------------

#: Objective scale: m^2 -> mm^2 (conditioning only; reported costs are in m^2).
COST_SCALE = 1e6
#: Position constraints are posed in mm (m -> mm).
POSITION_SCALE = 1e3
#: Tool-axis constraints are posed in mrad (dimensionless -> 1e-3).
AXIS_SCALE = 1e3
#: Singularity guards (see :func:`singular_factors`): the wrist and elbow sines stay
#: at least this far from 0 (dimensionless; about 2.9 deg) ...
SINGULAR_SIN_MIN = 0.05
#: ... and the shoulder factor rho at least this far from 0 (m).
SINGULAR_RHO_MIN_M = 0.02
#: Singularity guards per waypoint (shoulder, wrist, elbow).
N_GUARDS = 3
GUARD_NAMES = ("shoulder", "wrist", "elbow")
#: A guard counts as active within this of its bound (m for the shoulder, else dimensionless).
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
IPOPT_DEFAULTS: dict[str, Any] = {"mu_strategy": "adaptive", "bound_push": 1e-6, "bound_frac": 1e-6,
                                  "nlp_scaling_method": "none"}  # the NLP is scaled by hand (mm, mrad)
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
N_ORIENTATION = {OrientationRule.FIXED: 3, OrientationRule.FREE_TOOL_AXIS: 2,
                 OrientationRule.CONE: 1, OrientationRule.POSITION_ONLY: 0}


class BranchStatus(enum.Enum):
    """Outcome of one branch's posture optimisation."""

    OPTIMISED = "optimised"                  # IPOPT converged, every constraint verified
    NO_FREEDOM = "no_freedom"                # fixed orientation: the IK posture is the only one
    DEGENERATE = "degenerate"                # free rotation turns joint 6 only: zero gradient
    ANALYTIC = "analytic"                    # optimisation switched off by the caller
    SOLVER_FAILED = "solver_failed"          # IPOPT did not converge (its status in the reason)
    CONSTRAINT_VIOLATED = "constraint_violated"  # converged, but a constraint fails verification

    @property
    def usable(self) -> bool:
        """True if the branch's posture may be executed."""
        return self in (BranchStatus.OPTIMISED, BranchStatus.NO_FREEDOM, BranchStatus.DEGENERATE,
                        BranchStatus.ANALYTIC)


class PostureStatus(enum.Enum):
    """Outcome of the whole posture stage."""

    OK = "ok"
    UNREACHABLE = "unreachable"        # a waypoint has no IK solution on any branch
    NO_BRANCH = "no_branch"            # every waypoint reachable, but no branch along the whole path
    SOLVER_FAILED = "solver_failed"    # every feasible branch failed its NLP


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
            raise PostureError(f"posture task: wrench must have shape (6,), ({n}, 6) or ({n}, {LOAD_SIZE}), "
                               f"got {W.shape}")
        self.wrench = np.ascontiguousarray(W)
        for name, arr in (("positions", self.positions), ("wrench", self.wrench)):
            if not np.all(np.isfinite(arr)):
                k = int(np.argmax(~np.isfinite(arr).all(axis=1)))
                raise PostureError(f"posture task: {name} of waypoint {k} is not finite")
        if not isinstance(self.rule, OrientationRule):
            raise PostureError(f"posture task: rule must be an OrientationRule, got {self.rule!r}")
        if self.rule is OrientationRule.CONE and not (0.0 < self.cone_half_angle < math.pi / 2):
            raise PostureError(f"posture task: cone half-angle must be in (0, 90) deg, "
                               f"got {math.degrees(self.cone_half_angle):g} deg")
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
        Index into :data:`models.ik.BRANCH_LABELS` (label of the warm start's IK).
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

    @property
    def label(self) -> str:
        return BRANCH_LABELS[self.branch]

    @property
    def rms_error_m(self) -> float:
        """RMS of the linear load-induced TCP error over the waypoints, m."""
        return float(np.sqrt(np.mean(self.error_m ** 2)))

    @property
    def rms_error_analytic_m(self) -> float:
        return float(np.sqrt(np.mean(self.error_analytic_m ** 2)))


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

    @property
    def ok(self) -> bool:
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


# --------------------------------------------------------------------------------------
# Degenerate case
# --------------------------------------------------------------------------------------

def analyse_freedom(robot: Robot, rule: OrientationRule) -> tuple[str, str]:
    """What the NLP can choose beyond the branch.

    Returns
    -------
    kind : {"none", "degenerate", "free"}
    note : str
        One sentence for the summary.
    """
    if rule is OrientationRule.FIXED:
        return "none", ("fixed orientation: six equations for six joints, the posture is the IK "
                        "solution of each branch; only the branch is chosen")
    T = robot.flange2tcp
    off = float(np.hypot(T[0, 3], T[1, 3]))
    # Angle between the tool axis and the joint-6 axis, either sense (a tool axis
    # anti-parallel to joint 6 is just as degenerate).
    tilt = float(np.arccos(np.clip(abs(T[2, 2]), 0.0, 1.0)))
    on_axis = off <= DEGENERATE_OFFSET_TOL_M and tilt <= DEGENERATE_ANGLE_TOL_RAD
    if rule is OrientationRule.FREE_TOOL_AXIS and on_axis:
        return "degenerate", ("degenerate: the TCP lies on the joint-6 axis and the tool axis is "
                              "along it, so rotation about the tool axis only turns joint 6 and "
                              "leaves C(q) unchanged (zero gradient); only the branch is chosen")
    if on_axis and rule in (OrientationRule.CONE, OrientationRule.POSITION_ONLY):
        return "free", (f"{rule.value}: the tool axis direction is optimised; rotation about it "
                        "only turns joint 6 (TCP on the joint-6 axis) and is left to the smoothness term")
    return "free", f"{rule.value}: the posture is optimised along the free directions"


# --------------------------------------------------------------------------------------
# Stage functions (per waypoint) and their compilation
# --------------------------------------------------------------------------------------

def _n_stage_constraints(rule: OrientationRule) -> int:
    return 3 + N_ORIENTATION[rule] + N_GUARDS


def singular_factors(ik: AnalyticIK, q: Any) -> Any:
    """The three singularity factors of a UR-type arm.

    ``det J = a2 a3 * sin(theta3) * sin(theta5) * rho`` with
    ``rho = a2 cos(theta2) + a3 cos(theta2 + theta3) + d5 sin(theta2 + theta3 + theta4)``
    (m) and ``theta = q + theta_offset``, in the standard-DH reading the analytic
    IK uses.  Their signs are the IK branch (shoulder: rho, wrist: sin theta5,
    elbow: sin theta3), so keeping them away from zero keeps the branch.

    Parameters
    ----------
    ik : AnalyticIK
    q : casadi SX/MX (6,) or ndarray (6,) or (N, 6), rad

    Returns
    -------
    ``[rho (m), sin(theta5), sin(theta3)]``: CasADi (3,) or ndarray (3,) / (N, 3).
    """
    a, d, off = ik.a, ik.d, ik.offset
    if isinstance(q, (ca.SX, ca.MX)):
        th = [q[i] + off[i] for i in range(6)]
        rho = a[1] * ca.cos(th[1]) + a[2] * ca.cos(th[1] + th[2]) + d[4] * ca.sin(th[1] + th[2] + th[3])
        return ca.vertcat(rho, ca.sin(th[4]), ca.sin(th[2]))
    th = np.asarray(q, dtype=float) + off
    rho = (a[1] * np.cos(th[..., 1]) + a[2] * np.cos(th[..., 1] + th[..., 2])
           + d[4] * np.sin(th[..., 1] + th[..., 2] + th[..., 3]))
    return np.stack([rho, np.sin(th[..., 4]), np.sin(th[..., 2])], axis=-1)


def guard_bounds() -> np.ndarray:
    """Lower bounds of ``sigma_i * factor_i`` (shoulder m, wrist, elbow), shape (3,)."""
    return np.array([SINGULAR_RHO_MIN_M, SINGULAR_SIN_MIN, SINGULAR_SIN_MIN])


def _stage_sx(arm: ArmModel | Robot, rule: OrientationRule) -> dict[str, ca.Function]:
    """The per-waypoint SX functions.

    ``theta = [p (3, m); R (9, column-major); L (LOAD_SIZE); sigma (3)]`` with ``L`` the
    load vector of the waypoint and ``sigma`` the signs of the branch's singularity
    factors.  The cost is the arm model's first-order load-induced TCP position error
    (``load_error``), squared.  Constraint vector ``g``: position (mm), rule-specific
    orientation (scaled by AXIS_SCALE), then the three singularity guards ``sigma_i * factor_i``.
    """
    arm = arm if isinstance(arm, ArmModel) else ArmModel.from_robot(arm)
    ik = AnalyticIK(arm.nominal)
    q = ca.SX.sym("q", 6)
    th = ca.SX.sym("theta", N_THETA)
    p, R, L, sig = th[0:3], ca.reshape(th[3:12], 3, 3), th[12:12 + LOAD_SIZE], th[12 + LOAD_SIZE:N_THETA]
    fn = arm.kinematics.fn
    T = fn["fk_tcp"](q)
    d = fn["load_error"](q, L)[:3]                # first-order TCP position error (m)
    cost = COST_SCALE * ca.sumsqr(d)
    z = T[:3, 2]
    g = [POSITION_SCALE * (T[:3, 3] - p)]
    if rule is OrientationRule.FIXED:
        Rd = ca.mtimes(R.T, T[:3, :3])
        g.append(0.5 * AXIS_SCALE * ca.vertcat(Rd[2, 1] - Rd[1, 2], Rd[0, 2] - Rd[2, 0], Rd[1, 0] - Rd[0, 1]))
    elif rule is OrientationRule.FREE_TOOL_AXIS:
        g.append(AXIS_SCALE * ca.vertcat(ca.dot(R[:, 0], z), ca.dot(R[:, 1], z)))
    elif rule is OrientationRule.CONE:
        g.append(AXIS_SCALE * ca.dot(R[:, 2], z))
    g.append(sig * singular_factors(ik, q))
    g = ca.vertcat(*g)
    sigma = ca.SX.sym("sigma")
    lam = ca.SX.sym("lam", g.shape[0])
    lag = sigma * cost + ca.dot(lam, g)
    H = ca.hessian(lag, q)[0]
    H = 0.5 * (H + H.T)
    tag = rule.value
    return {
        "f": ca.Function(f"posture_{tag}_f", [q, th], [cost, g], ["q", "theta"], ["cost", "g"]),
        "grad": ca.Function(f"posture_{tag}_grad", [q, th], [cost, ca.gradient(cost, q)],
                            ["q", "theta"], ["cost", "grad"]),
        "jac": ca.Function(f"posture_{tag}_jac", [q, th], [g, ca.densify(ca.jacobian(g, q))],
                           ["q", "theta"], ["g", "jac"]),
        "hess": ca.Function(f"posture_{tag}_hess", [q, th, sigma, lam], [ca.densify(H)],
                            ["q", "theta", "sigma", "lam"], ["hess"]),
    }


class StageCompileError(RuntimeError):
    """No C compiler, or it failed (then the CasADi virtual machine is used)."""


def _compile_stage(funcs: dict[str, ca.Function]) -> dict[str, ca.Function]:
    """Compile the stage functions into one shared library (cached) and load them."""
    cg = ca.CodeGenerator("posture_stage.c", {"with_header": False, "casadi_real": "double",
                                              "casadi_int": "long long int"})
    for f in funcs.values():
        cg.add(f)
    src = cg.dump()
    try:
        lib = compile_shared_library(src, "posture")
    except CompileError as exc:
        raise StageCompileError(str(exc)) from None
    return {k: ca.external(f.name(), str(lib)) for k, f in funcs.items()}


# --------------------------------------------------------------------------------------
# The NLP (one per robot, rule, N; reused across branches)
# --------------------------------------------------------------------------------------

def _blockdiag_sparsity(n: int, rows: int, cols: int) -> ca.Sparsity:
    r, c = [], []
    for k in range(n):
        for j in range(cols):
            for i in range(rows):
                r.append(k * rows + i)
                c.append(k * cols + j)
    return ca.Sparsity.triplet(n * rows, n * cols, r, c)


def _difference_matrix(n: int) -> ca.DM:
    """(6(N-1), 6N) sparse matrix D with ``D vec(X) = vec(X[:, 1:] - X[:, :-1])``."""
    r, c, v = [], [], []
    for k in range(n - 1):
        for i in range(6):
            row = 6 * k + i
            r += [row, row]
            c += [6 * k + i, 6 * (k + 1) + i]
            v += [-1.0, 1.0]
    return ca.DM.triplet(r, c, ca.DM(v), 6 * (n - 1), 6 * n)


class PostureNLP:
    """The posture NLP for one robot, rule and number of waypoints.

    Parameters
    ----------
    robot : Robot
    rule : OrientationRule
    n : int
        Number of waypoints.
    settings : SolverSettings
    verbose : bool
        IPOPT output on (print level 5).

    Attributes
    ----------
    compiled : bool
        Whether the stage functions run as compiled C.
    build_time_s : float
    """

    def __init__(self, arm: ArmModel | Robot, rule: OrientationRule, n: int,
                 settings: SolverSettings = SolverSettings(), verbose: bool = False) -> None:
        if settings.name != "ipopt":
            raise InputError(f"solver: unknown NLP solver {settings.name!r}; available: ['ipopt']")
        t0 = time.perf_counter()
        arm = arm if isinstance(arm, ArmModel) else ArmModel.from_robot(arm)
        self.arm, self.robot, self.rule, self.n, self.settings = arm, arm.nominal, rule, n, settings
        sx = _stage_sx(arm, rule)
        self.compiled = False
        funcs = sx
        if settings.codegen:
            try:
                funcs = _compile_stage(sx)
                self.compiled = True
            except StageCompileError:
                funcs = sx
        self.stage = funcs
        self.m = _n_stage_constraints(rule)
        self._build(funcs, verbose)
        self.build_time_s = time.perf_counter() - t0

    def _build(self, funcs: dict[str, ca.Function], verbose: bool) -> None:
        n, m = self.n, self.m
        X = ca.MX.sym("X", 6, n)
        Th = ca.MX.sym("Theta", N_THETA, n)
        lam_s = ca.MX.sym("lam_s")
        x = ca.vec(X)
        p = ca.vertcat(ca.vec(Th), lam_s)
        Dm = _difference_matrix(n)
        LtL = ca.mtimes(Dm.T, Dm) if n > 1 else ca.DM(6 * n, 6 * n)

        c_all, g_all = funcs["f"].map(n)(X, Th)
        dX = ca.mtimes(Dm, x) if n > 1 else ca.MX(0, 1)
        f = ca.sum2(c_all) + lam_s * ca.sumsqr(dX)
        g = ca.vertcat(ca.vec(g_all), dX)

        c_g, grad = funcs["grad"].map(n)(X, Th)
        grad_f = ca.Function("grad_f", [x, p], [ca.sum2(c_g) + lam_s * ca.sumsqr(dX),
                                                 ca.vec(grad) + 2.0 * lam_s * ca.mtimes(LtL, x)],
                             ["x", "p"], ["f", "grad_f_x"])

        g_j, jac = funcs["jac"].map(n)(X, Th)
        jac_stage = ca.MX(_blockdiag_sparsity(n, m, 6), ca.vec(jac))
        jac_full = ca.vertcat(jac_stage, ca.MX(Dm)) if n > 1 else jac_stage
        jac_g = ca.Function("jac_g", [x, p], [ca.vertcat(ca.vec(g_j), dX), jac_full],
                            ["x", "p"], ["g", "jac_g_x"])

        lam_f = ca.MX.sym("lam_f")
        lam_g = ca.MX.sym("lam_g", m * n + 6 * (n - 1))
        Lg = ca.reshape(lam_g[: m * n], m, n)
        H = funcs["hess"].map(n)(X, Th, ca.repmat(lam_f, 1, n), Lg)
        H_stage = ca.MX(_blockdiag_sparsity(n, 6, 6), ca.vec(H))
        H_full = H_stage + 2.0 * lam_f * lam_s * ca.MX(ca.DM(LtL)) if n > 1 else H_stage
        hess = ca.Function("hess_lag", [x, p, lam_f, lam_g], [ca.triu(H_full)],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])

        s = self.settings
        opts: dict[str, Any] = {
            "grad_f": grad_f, "jac_g": jac_g, "hess_lag": hess,
            "calc_lam_p": False, "no_nlp_grad": True, "print_time": False,
            "ipopt": {**IPOPT_DEFAULTS, "print_level": 5 if verbose else 0, "sb": "yes",
                      "max_iter": int(s.max_iter), "tol": float(s.tol), **dict(s.ipopt_options)},
        }
        self.solver = ca.nlpsol("posture", "ipopt", {"x": x, "p": p, "f": f, "g": g}, opts)
        self._jac_map = funcs["jac"].map(n)

    # ---------------------------------------------------------------- parameters
    def theta(self, task: PostureTask, sign: np.ndarray) -> np.ndarray:
        """Stage parameters, shape (N_THETA, N)."""
        n = task.n
        th = np.empty((N_THETA, n))
        th[0:3] = task.positions.T
        th[3:12] = task.rotations.transpose(0, 2, 1).reshape(n, 9).T   # column-major R
        th[12:12 + LOAD_SIZE] = task.load.T
        th[12 + LOAD_SIZE:N_THETA] = np.asarray(sign, dtype=float).reshape(3, 1)
        return th

    def bounds_g(self, task: PostureTask) -> tuple[np.ndarray, np.ndarray]:
        n, m = self.n, self.m
        lo = np.zeros((m, n))
        hi = np.zeros((m, n))
        if self.rule is OrientationRule.CONE:
            lo[3] = AXIS_SCALE * math.cos(task.cone_half_angle)
            hi[3] = np.inf
        lo[m - N_GUARDS:] = guard_bounds()[:, None]
        hi[m - N_GUARDS:] = np.inf
        step = np.full(6 * (n - 1), task.max_joint_step)
        return np.r_[lo.reshape(-1, order="F"), -step], np.r_[hi.reshape(-1, order="F"), step]

    def solve(self, task: PostureTask, q0: np.ndarray, sign: np.ndarray,
              q_min: np.ndarray, q_max: np.ndarray) -> tuple[np.ndarray, str, int, float]:
        """Run IPOPT from ``q0`` (N, 6). Returns (q (N, 6), status, iterations, wall time s)."""
        th = self.theta(task, sign)
        lbg, ubg = self.bounds_g(task)
        p = np.r_[th.reshape(-1, order="F"), task.smoothness]
        t0 = time.perf_counter()
        res = self.solver(x0=q0.reshape(-1), p=p, lbx=np.tile(q_min, self.n), ubx=np.tile(q_max, self.n),
                          lbg=lbg, ubg=ubg)
        dt = time.perf_counter() - t0
        st = self.solver.stats()
        q = np.asarray(res["x"]).reshape(self.n, 6)
        return q, str(st.get("return_status", "unknown")), int(st.get("iter_count", 0)), dt

    # ---------------------------------------------------------------- polishing
    def polish(self, task: PostureTask, q: np.ndarray, sign: np.ndarray) -> np.ndarray:
        """Project every waypoint onto its equality constraints (Gauss-Newton, min-norm steps).

        The cone inequality joins the projection only where it is violated.
        """
        th = self.theta(task, sign)
        q = q.copy()
        n_eq = 3 + (0 if self.rule is OrientationRule.CONE else N_ORIENTATION[self.rule])
        cos_a = math.cos(task.cone_half_angle)
        for _ in range(POLISH_MAX_ITER):
            g, jac = self._jac_map(q.T, th)
            g = np.asarray(g).T                                              # (N, m)
            # jac is (m, 6N): columns 6k..6k+5 hold waypoint k's m x 6 Jacobian.
            jac = np.asarray(jac).reshape(self.m, self.n, 6).transpose(1, 0, 2)  # (N, m, 6)
            worst = 0.0
            for k in range(self.n):
                r = g[k, :n_eq]
                A = jac[k, :n_eq]
                if self.rule is OrientationRule.CONE and g[k, 3] < AXIS_SCALE * cos_a:
                    r = np.r_[r, g[k, 3] - AXIS_SCALE * cos_a]
                    A = np.vstack([A, jac[k, 3]])
                dq = -np.linalg.lstsq(A, r, rcond=None)[0]
                q[k] += dq
                worst = max(worst, float(np.abs(dq).max()))
            if worst < POLISH_STEP_TOL:
                break
        return q


_SOLVERS: dict[tuple, PostureNLP] = {}
_SOLVERS_LOCK = threading.Lock()


def _model_key(arm: ArmModel) -> tuple:
    r = arm.nominal
    return (r.convention, tuple(r.a), tuple(r.alpha), tuple(r.d), tuple(r.theta_offset), tuple(r.stiffness),
            tuple(r.flange2tcp.reshape(-1)), arm.active_effects, arm.theta.tobytes(), arm.const.tobytes(),
            float(arm.temperature_ref))


def get_nlp(arm: ArmModel | Robot, rule: OrientationRule, n: int, settings: SolverSettings = SolverSettings(),
            verbose: bool = False) -> PostureNLP:
    """The cached :class:`PostureNLP` for (model, rule, n, settings, verbose)."""
    arm = arm if isinstance(arm, ArmModel) else ArmModel.from_robot(arm)
    robot = arm
    key = (_model_key(arm), rule, n, settings, verbose)
    with _SOLVERS_LOCK:
        nlp = _SOLVERS.get(key)
        if nlp is None:
            if len(_SOLVERS) > 32:
                _SOLVERS.clear()
            nlp = PostureNLP(robot, rule, n, settings, verbose)
            _SOLVERS[key] = nlp
    return nlp


# --------------------------------------------------------------------------------------
# Warm starts
# --------------------------------------------------------------------------------------

def _axis_angle(u: np.ndarray, angle: float) -> np.ndarray:
    u = u / np.linalg.norm(u)
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def candidates(task: PostureTask) -> list[tuple[str, np.ndarray]]:
    """Constant orientation offsets scanned for warm starts: (name, rotations (N, 3, 3)).

    The first candidate is always the nominal orientation.
    """
    R = task.rotations
    out = [("nominal", R)]
    if task.rule is OrientationRule.FIXED:
        return out
    tilts: list[tuple[str, float, float]] = [("", 0.0, 0.0)]
    if task.rule is OrientationRule.CONE:
        tilts += [(f"tilt={math.degrees(task.cone_half_angle):g}deg@{int(phi)}deg",
                   task.cone_half_angle, math.radians(phi)) for phi in (0, 90, 180, 270)]
    elif task.rule is OrientationRule.POSITION_ONLY:
        tilts += [(f"tilt={t:g}deg@{360.0 * i / nd:g}deg", math.radians(t), 2.0 * math.pi * i / nd)
                  for t, nd in POSITION_ONLY_AXES for i in range(nd)]
    n_scan = int(task.scan)
    for tname, tilt, phi in tilts:
        if tilt > 0.0:
            # Tilt about a tool-frame direction perpendicular to the tool axis (per waypoint).
            u = math.cos(phi) * R[:, :, 0] + math.sin(phi) * R[:, :, 1]
            Rt = np.stack([_axis_angle(u[k], tilt) @ R[k] for k in range(len(R))])
        else:
            Rt = R
        for j in range(n_scan):
            psi = 2.0 * math.pi * j / n_scan
            if tilt == 0.0 and j == 0:
                continue
            c, s = math.cos(psi), math.sin(psi)
            Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            name = ", ".join(x for x in (tname, f"psi={math.degrees(psi):g}deg") if x)
            out.append((name, Rt @ Rz))
    return out


@dataclass
class WarmStarts:
    """Analytic postures and warm starts of every branch (see :func:`warm_starts`)."""

    analytic: dict[int, BranchPath]
    warm: dict[int, tuple[BranchPath, str, float]]
    rejected: dict[int, str]
    unreachable: list[int]


def linear_error(model: KinematicModel, q: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """First-order load-induced TCP position error per row (the NLP's objective), m:
    q (N, 6), load (N, 6) / (6,) base wrench or (N, LOAD_SIZE) load rows -> (N,).

    For the nominal model and a base-frame wrench this is ``||S C(q_k) F_k||``."""
    q = np.atleast_2d(q)
    D = model.batch(model.fn["load_error"], q, load_rows(wrench, len(q)))[0]
    return np.linalg.norm(D[:, :3], axis=1)


def _wrap(d: np.ndarray) -> np.ndarray:
    return (d + np.pi) % (2.0 * np.pi) - np.pi


def _into_limits(q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray) -> np.ndarray | None:
    """Shift each joint of a continuous path (N, 6) by a common 2*pi*k into the limits, or None."""
    out = q.copy()
    for j in range(6):
        lo, hi = q[:, j].min(), q[:, j].max()
        k_lo = math.ceil((q_min[j] - lo) / (2.0 * math.pi) - 1e-12)
        k_hi = math.floor((q_max[j] - hi) / (2.0 * math.pi) + 1e-12)
        if k_lo > k_hi:
            return None
        k = min(max(0, k_lo), k_hi)          # the shift nearest zero that fits
        out[:, j] += 2.0 * math.pi * k
    return out


def warm_starts(ik: AnalyticIK, model: KinematicModel, task: PostureTask) -> WarmStarts:
    """Analytic IK at the nominal rotations, and a warm start per branch.

    The warm start of a branch is the cheapest sequence of scanned candidates
    (:func:`candidates`, one per waypoint) under the NLP's own objective, found by
    dynamic programming over the waypoints: node cost ``s ||S C F||^2`` (mm^2),
    transition cost ``lam ||dq||^2`` (wrapped joint differences), transitions with
    a joint step above ``max_joint_step`` and nodes inside a singularity guard
    excluded.  With a fixed orientation it is the analytic posture itself.
    """
    n = task.n
    feas_nom, rej_nom = branch_paths(ik, poses(task.positions, task.rotations), task.max_joint_step)
    cands = candidates(task)
    S = len(cands)
    T_all = np.concatenate([poses(task.positions, R) for _, R in cands])      # (S*N, 4, 4)
    sol = ik.solve(T_all)
    Q = sol.q.reshape(S, n, 8, 6)
    ok = sol.status.reshape(S, n, 8) == IKStatus.OK
    unreachable = [int(k) for k in np.where(~ok.any(axis=(0, 2)))[0]]
    warm: dict[int, tuple[BranchPath, str, float]] = {}
    rejected: dict[int, str] = {}
    if task.rule is OrientationRule.FIXED or S == 1:
        for b, bp in feas_nom.items():
            err = linear_error(model, bp.q, task.load)
            warm[b] = (bp, "nominal", float(np.sum(err ** 2)))
        return WarmStarts(feas_nom, warm, dict(rej_nom), unreachable)

    # Guards: a node must lie on the branch's side of every singularity, with margin.
    fac = singular_factors(ik, np.nan_to_num(Q))                              # (S, N, 8, 3)
    ok &= (np.abs(fac) >= guard_bounds()).all(axis=-1)
    idx = np.argwhere(ok)                                                     # (M, 3): s, k, b
    cost = np.full((S, n, 8), np.inf)
    if len(idx):
        qv = Q[idx[:, 0], idx[:, 1], idx[:, 2]]
        err = linear_error(model, qv, task.load[idx[:, 1]])
        cost[idx[:, 0], idx[:, 1], idx[:, 2]] = COST_SCALE * err ** 2
    lam = task.smoothness
    Qb = np.ascontiguousarray(np.nan_to_num(Q).transpose(2, 0, 1, 3))         # (8, S, N, 6)
    sparse: dict[int, np.ndarray] = {}
    if S > DP_MAX_STATES:
        reach_all = np.isfinite(cost).any(axis=0).all(axis=0)                 # (8,)
        bs = np.flatnonzero(reach_all)
        if bs.size:
            # float32 halves the memory traffic of the programme; the sequence it picks is
            # re-evaluated in float64 below
            qk = np.ascontiguousarray(Qb[bs].transpose(0, 2, 1, 3), dtype=np.float32)  # (B, N, S, 6)
            seqs = _dp_sparse(cost.transpose(2, 0, 1)[bs].astype(np.float32), qk, lam,
                              task.max_joint_step, _neighbours([R for _, R in cands]))
            sparse = {int(b): sq for b, sq in zip(bs, seqs) if sq is not None}
    for b in range(8):
        node = cost[:, :, b]                                                  # (S, N)
        if not np.isfinite(node).any(axis=0).all():
            k = int(np.argmin(np.isfinite(node).any(axis=0)))
            st = sol.status.reshape(S, n, 8)[0, k, b]
            why = IK_REASONS[IKStatus(int(st))] if st != IKStatus.OK else "inside a singularity guard"
            rejected[b] = f"waypoint {k}: {why} (at the nominal orientation and every scanned one)"
            continue
        qb = Qb[b]                                                            # (S, N, 6)
        seq = sparse.get(b)
        if seq is None:                         # dense programme, pruned first
            limit = DP_MAX_STATES
            seq = _dp(node, qb, lam, task.max_joint_step, limit)
            while seq is None:                  # pruned graph disconnected: keep more states
                limit *= 2
                seq = _dp(node, qb, lam, task.max_joint_step, limit)
        if isinstance(seq, int):
            rejected[b] = (f"flip between waypoints {seq} and {seq + 1}: no scanned "
                           f"orientation keeps every joint step <= {task.max_joint_step:g} rad")
            continue
        q = np.empty((n, 6))
        q[0] = qb[seq[0], 0]
        for k in range(n - 1):
            q[k + 1] = q[k] + _wrap(qb[seq[k + 1], k + 1] - qb[seq[k], k])
        q = _into_limits(q, ik.q_min, ik.q_max)
        if q is None:
            rejected[b] = "a joint leaves its limits along the path at every scanned orientation"
            continue
        steps = np.abs(np.diff(q, axis=0)).max() if n > 1 else 0.0
        names = sorted({cands[s][0] for s in seq})
        label = names[0] if len(names) == 1 else f"per-waypoint scan over {S} orientations"
        warm[b] = (BranchPath(b, q, float(steps)), label,
                   float(np.sum(node[seq, np.arange(n)])) / COST_SCALE)
    for b, r in rej_nom.items():
        if b not in warm and b not in rejected:
            rejected[b] = r
    return WarmStarts(feas_nom, warm, rejected, unreachable)


def _neighbours(rotations: list[np.ndarray]) -> np.ndarray:
    """(S, M) indices of the candidates within DP_NEIGHBOUR_ANGLE_RAD of each candidate
    (padded with -1), from their rotations at the first waypoint."""
    R = np.stack([r[0] for r in rotations])                                  # (S, 3, 3)
    tr = np.einsum("aji,bji->ab", R, R)                                       # trace(Ra^T Rb)
    ang = np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))
    close = ang <= DP_NEIGHBOUR_ANGLE_RAD
    m = int(close.sum(axis=1).max())
    out = -np.ones((len(R), m), dtype=int)
    for i, row in enumerate(close):
        idx = np.flatnonzero(row)
        out[i, :len(idx)] = idx
    return out


def _dp_sparse(node: np.ndarray, qb: np.ndarray, lam: float, max_step: float,
               nbr: np.ndarray) -> list[np.ndarray | None]:
    """Cheapest candidate sequences of several branches at once, with transitions only
    between neighbouring candidates (:func:`_neighbours`).

    Parameters
    ----------
    node : ndarray (B, S, N)
        Node costs per branch (inf where invalid).
    qb : ndarray (B, N, S, 6)
        The candidates' joint angles per branch (waypoint-major for contiguous slices).
    nbr : ndarray (S, M)
        Neighbour indices, -1 padded.

    Returns
    -------
    list (B,) of sequences (N,), or None where that graph is blocked (the caller then
    runs the dense :func:`_dp`).
    """
    B, S, n = node.shape
    valid = nbr >= 0
    idx = np.where(valid, nbr, 0)
    rows = np.arange(S)
    V = node[:, :, 0].copy()                                                  # (B, S)
    blocked = np.zeros(B, dtype=bool)
    backs = []
    for k in range(n - 1):
        d = qb[:, k + 1][:, :, None, :] - qb[:, k][:, idx]                    # (B, S_to, M, 6)
        d -= np.float32(2.0 * np.pi) * np.round(d * np.float32(0.5 / np.pi))
        trans = np.float32(lam) * np.einsum("bsmj,bsmj->bsm", d, d)
        trans[(np.abs(d).max(axis=-1) > max_step) | ~valid] = np.inf
        tot = V[:, idx] + trans
        j = np.argmin(tot, axis=2)                                            # (B, S)
        V = np.take_along_axis(tot, j[:, :, None], axis=2)[:, :, 0] + node[:, :, k + 1]
        backs.append(idx[rows, j])                                            # (B, S)
        blocked |= ~np.isfinite(V).any(axis=1)
    out: list[np.ndarray | None] = []
    for i in range(B):
        if blocked[i]:
            out.append(None)
            continue
        seq = np.zeros(n, dtype=int)
        seq[-1] = int(np.argmin(V[i]))
        for k in range(n - 1, 0, -1):
            seq[k - 1] = backs[k - 1][i, seq[k]]
        out.append(seq)
    return out


def _dp(node: np.ndarray, qb: np.ndarray, lam: float, max_step: float,
        max_states: int) -> np.ndarray | int | None:
    """Cheapest candidate sequence (Viterbi) over the waypoints.

    Parameters
    ----------
    node : ndarray (S, N)
        Node costs (inf where a candidate is not valid).
    qb : ndarray (S, N, 6)
        The candidates' joint angles.
    max_states : int
        Keep at most this many cheapest candidates per waypoint.

    Returns
    -------
    ndarray of int (N,) : the sequence; int k : blocked between waypoints k and k+1
    with every candidate kept; None : blocked with pruned states (retry with more).
    """
    S, n = node.shape
    states = []
    for k in range(n):
        idx = np.flatnonzero(np.isfinite(node[:, k]))
        if len(idx) > max_states:
            idx = idx[np.argsort(node[idx, k])[:max_states]]
        states.append(idx)
    V = node[states[0], 0]
    backs = []
    for k in range(n - 1):
        a, b = states[k], states[k + 1]
        d = qb[b, k + 1][None, :, :] - qb[a, k][:, None, :]                   # (A, B, 6)
        d -= 2.0 * np.pi * np.round(d / (2.0 * np.pi))
        trans = lam * np.einsum("abj,abj->ab", d, d)
        trans[np.abs(d).max(axis=-1) > max_step] = np.inf
        tot = V[:, None] + trans
        back = np.argmin(tot, axis=0)
        V = tot[back, np.arange(len(b))] + node[b, k + 1]
        backs.append(back)
        if not np.isfinite(V).any():
            pruned = any(len(states[j]) < np.isfinite(node[:, j]).sum() for j in range(k + 2))
            return None if pruned else k
    pos = int(np.argmin(V))
    seq = np.zeros(n, dtype=int)
    seq[-1] = states[-1][pos]
    for k in range(n - 1, 0, -1):
        pos = int(backs[k - 1][pos])
        seq[k - 1] = states[k - 1][pos]
    return seq


# --------------------------------------------------------------------------------------
# Verification
# --------------------------------------------------------------------------------------

def verify(model: KinematicModel, task: PostureTask, q: np.ndarray, q_min: np.ndarray,
           q_max: np.ndarray, ik: AnalyticIK | None = None,
           signs: np.ndarray | None = None) -> tuple[list[str], float, float]:
    """Check every constraint of the task at ``q`` (N, 6).

    With ``ik`` and ``signs`` (the branch's singularity-factor signs) the singularity
    guards are checked as well.

    Returns
    -------
    problems : list of str
        One line per violated constraint (empty if all hold).
    residual_m, residual_rad : float
        Largest position residual (m) and orientation residual (rad).
    """
    out: list[str] = []
    T = model.tcp(q) if q.shape[0] > 1 else model.tcp(q[0])[None]
    e = np.linalg.norm(T[:, :3, 3] - task.positions, axis=1)
    k = int(np.argmax(e))
    if e[k] > POSITION_TOL_M:
        out.append(f"waypoint {k}: TCP {e[k]:.3g} m from the waypoint > {POSITION_TOL_M:g} m")
    z = T[:, :3, 2]
    a = task.axes
    ang = np.arctan2(np.linalg.norm(np.cross(z, a), axis=1), np.einsum("ij,ij->i", z, a))
    res_rad = 0.0
    if task.rule is OrientationRule.FIXED:
        r = rotation_angle(T[:, :3, :3], task.rotations)
        res_rad = float(r.max())
        if res_rad > ORIENTATION_TOL_RAD:
            k = int(np.argmax(r))
            out.append(f"waypoint {k}: orientation off by {r[k]:.3g} rad > {ORIENTATION_TOL_RAD:g} rad")
    elif task.rule is OrientationRule.FREE_TOOL_AXIS:
        res_rad = float(ang.max())
        if res_rad > ORIENTATION_TOL_RAD:
            k = int(np.argmax(ang))
            out.append(f"waypoint {k}: tool axis off by {ang[k]:.3g} rad > {ORIENTATION_TOL_RAD:g} rad")
    elif task.rule is OrientationRule.CONE:
        over = ang - task.cone_half_angle
        res_rad = float(max(over.max(), 0.0))
        if res_rad > ORIENTATION_TOL_RAD:
            k = int(np.argmax(over))
            out.append(f"waypoint {k}: tool axis {math.degrees(ang[k]):.6g} deg from the nominal axis "
                       f"> cone half-angle {math.degrees(task.cone_half_angle):g} deg")
    lo = q < q_min - JOINT_TOL_RAD
    hi = q > q_max + JOINT_TOL_RAD
    if lo.any() or hi.any():
        k, j = (int(v) for v in np.argwhere(lo | hi)[0])
        out.append(f"waypoint {k}: joint {j + 1} = {q[k, j]:.6g} rad outside [{q_min[j]:.6g}, {q_max[j]:.6g}]")
    if ik is not None and signs is not None:
        g = singular_factors(ik, q) * signs - guard_bounds()
        if np.any(g < -JOINT_TOL_RAD):
            k, i = (int(v) for v in np.unravel_index(np.argmin(g), g.shape))
            name = ("shoulder factor rho", "wrist sin(theta5)", "elbow sin(theta3)")[i]
            out.append(f"waypoint {k}: {name} crosses its singularity guard (margin {g[k, i]:.3g})")
    if len(q) > 1:
        steps = np.abs(np.diff(q, axis=0))
        if steps.max() > task.max_joint_step + JOINT_TOL_RAD:
            k, j = (int(v) for v in np.unravel_index(np.argmax(steps), steps.shape))
            out.append(f"waypoints {k}-{k + 1}: joint {j + 1} steps {steps[k, j]:.4g} rad "
                       f"> {task.max_joint_step:g} rad")
    return out, float(e.max()), res_rad


# --------------------------------------------------------------------------------------
# The whole stage
# --------------------------------------------------------------------------------------

def _onto_model_geometry(arm: ArmModel, ik: AnalyticIK, ws: WarmStarts) -> WarmStarts:
    """Move the analytic postures and warm starts onto the model's geometry.

    The closed-form IK solves the *nominal* chain; an identified model's chain differs
    (DH errors, offsets, thermal).  Each path is moved by damped Newton to the joints whose
    TCP under the model's geometry is the pose the nominal chain had (the IK target).
    """
    from problems.compensation import rigid_pose_solve
    nominal = KinematicModel(ik.robot)

    def move(bp: BranchPath) -> BranchPath:
        q = rigid_pose_solve(arm, bp.q, nominal.tcp(bp.q).reshape(-1, 4, 4))
        steps = float(np.abs(np.diff(q, axis=0)).max()) if len(q) > 1 else 0.0
        return BranchPath(bp.branch, q, steps)

    analytic = {b: move(bp) for b, bp in ws.analytic.items()}
    warm = {b: (analytic[b] if b in analytic and bp.q is ws.analytic[b].q else move(bp), name, cost)
            for b, (bp, name, cost) in ws.warm.items()}
    return WarmStarts(analytic, warm, ws.rejected, ws.unreachable)


def branch_signs(ik: AnalyticIK, q: np.ndarray) -> np.ndarray:
    """Signs (3,) of the singularity factors (shoulder, wrist, elbow) along a branch path (N, 6)."""
    f = singular_factors(ik, np.atleast_2d(q))
    return np.where(np.median(f, axis=0) >= 0.0, 1.0, -1.0)


def optimise_postures(robot: ArmModel | Robot, task: PostureTask, home_q: np.ndarray,
                      settings: SolverSettings = SolverSettings(), verbose: bool = False,
                      model: KinematicModel | None = None, ik: AnalyticIK | None = None,
                      optimise: bool = True) -> PostureResult:
    """Solve the posture NLP on every feasible branch and choose the best.

    Parameters
    ----------
    robot : Robot
        With its tool (``flange2tcp``); must be UR-type for the analytic warm starts.
    task : PostureTask
    home_q : ndarray, shape (6,)
        Home configuration (rad): the default branch is the one nearest to it.
    settings : SolverSettings
    verbose : bool
        IPOPT output on.
    model, ik : optional
        Reuse already built objects for ``robot``.
    optimise : bool
        False: analytic postures only (every branch as if it had no freedom).

    Returns
    -------
    PostureResult
        Never raises for infeasible tasks: the status and reason say what failed.
    """
    arm = robot if isinstance(robot, ArmModel) else ArmModel.from_robot(robot)
    robot = arm.nominal
    model = model or arm.kinematics
    ik = ik or AnalyticIK(robot)
    q_min, q_max = robot.q_min, robot.q_max
    freedom, note = analyse_freedom(robot, task.rule)
    ws = warm_starts(ik, model, task)
    if not arm.geometry_is_nominal:
        ws = _onto_model_geometry(arm, ik, ws)
    default = default_branch(ws.analytic, home_q) if ws.analytic else (
        default_branch({b: v[0] for b, v in ws.warm.items()}, home_q) if ws.warm else None)
    if not ws.warm:
        if ws.unreachable:
            k = ws.unreachable[0]
            p = task.positions[k]
            sol = ik.solve(poses(task.positions[k:k + 1], task.rotations[k]))
            why = "; ".join(sorted({IK_REASONS[IKStatus(int(c))] for c in sol.status[0]}))
            reason = (f"no IK branch reaches waypoint {k} at ({p[0]:.4g}, {p[1]:.4g}, {p[2]:.4g}) m "
                      f"({why})")
            if len(ws.unreachable) > 1:
                reason += f"; {len(ws.unreachable)} unreachable waypoints in all"
            status = PostureStatus.UNREACHABLE
        else:
            reason = "no IK branch reaches the whole path: " + "; ".join(
                f"{BRANCH_LABELS[b]}: {r}" for b, r in sorted(ws.rejected.items()))
            status = PostureStatus.NO_BRANCH
        return PostureResult(status, reason, task, {}, ws.rejected, None, default, freedom, note,
                             ws.unreachable)

    nlp: PostureNLP | None = None
    build = 0.0
    if optimise and freedom == "free":
        t0 = time.perf_counter()
        nlp = get_nlp(arm, task.rule, task.n, settings, verbose)
        build = time.perf_counter() - t0

    results: dict[int, BranchResult] = {}
    for b in sorted(ws.warm):
        bp_warm, wname, wcost = ws.warm[b]
        qa = ws.analytic[b].q if b in ws.analytic else None
        err_a = linear_error(model, qa, task.load) if qa is not None else np.full(task.n, np.nan)
        cost_a = float(np.sum(err_a ** 2)) if qa is not None else math.nan
        base = qa if qa is not None else bp_warm.q
        if nlp is None:
            if freedom == "none":
                st, why = BranchStatus.NO_FREEDOM, note
            elif freedom == "degenerate":
                st, why = BranchStatus.DEGENERATE, note
            else:
                st, why = BranchStatus.ANALYTIC, "optimisation switched off: analytic posture"
            q = base
            err = linear_error(model, q, task.load)
            results[b] = BranchResult(b, st, why, q, qa, bp_warm.q, wname if qa is None else "nominal",
                                      float(np.sum(err ** 2)), cost_a, wcost, err, err_a)
            continue
        sign = branch_signs(ik, bp_warm.q)
        q_opt, ip_status, iters, dt = nlp.solve(task, bp_warm.q, sign, q_min, q_max)
        q_pol = nlp.polish(task, q_opt, sign) if np.all(np.isfinite(q_opt)) else q_opt
        problems, res_m, res_rad = verify(model, task, q_pol, q_min, q_max, ik, sign)
        kept = "analytic posture" if qa is not None else "warm start"
        if ip_status not in IPOPT_OK:
            st, why = BranchStatus.SOLVER_FAILED, (f"IPOPT: {ip_status} after {iters} iterations; "
                                                   f"the {kept} is kept")
        elif problems:
            st, why = BranchStatus.CONSTRAINT_VIOLATED, f"{problems[0]}; the {kept} is kept"
        else:
            st, why = BranchStatus.OPTIMISED, f"IPOPT: {ip_status} in {iters} iterations"
        q = q_pol if st is BranchStatus.OPTIMISED else base
        err = linear_error(model, q, task.load)
        margin = singular_factors(ik, q) * sign - guard_bounds()
        active = {GUARD_NAMES[i]: int(np.sum(margin[:, i] <= GUARD_ACTIVE_TOL)) for i in range(N_GUARDS)}
        results[b] = BranchResult(b, st, why, q, qa, bp_warm.q, wname, float(np.sum(err ** 2)), cost_a,
                                  wcost, err, err_a, iters, dt, ip_status, res_m, res_rad,
                                  {k: v for k, v in active.items() if v})

    usable = {b: r for b, r in results.items() if r.status.usable}
    if not usable:
        reason = "the NLP failed on every feasible branch: " + "; ".join(
            f"{r.label}: {r.reason}" for r in results.values())
        return PostureResult(PostureStatus.SOLVER_FAILED, reason, task, results, ws.rejected, None,
                             default, freedom, note, ws.unreachable, build)
    chosen = min(usable, key=lambda b: usable[b].cost)
    n_fail = len(results) - len(usable)
    reason = (f"branch {BRANCH_LABELS[chosen]} chosen among {len(usable)} usable branch(es)"
              + (f"; {n_fail} failed" if n_fail else ""))
    return PostureResult(PostureStatus.OK, reason, task, results, ws.rejected, chosen, default, freedom,
                         note, ws.unreachable, build)


def optimal_pose(robot: ArmModel | Robot, position: np.ndarray, rotation: np.ndarray, rule: OrientationRule,
                 wrench: np.ndarray, cone_half_angle: float = 0.0, home_q: np.ndarray | None = None,
                 settings: SolverSettings = SolverSettings(), scan: int = DEFAULT_SCAN,
                 verbose: bool = False) -> PostureResult:
    """Single-pose query: the stiffness-optimal posture for one target and wrench.

    Parameters
    ----------
    position : ndarray, shape (3,)
        TCP target, m, base frame.
    rotation : ndarray, shape (3, 3)
        Nominal base->TCP rotation (the tool axis is its z column).
    rule : OrientationRule
    wrench : ndarray, shape (6,)
        [N, N*m] on the TCP, base frame.
    home_q : ndarray, shape (6,), optional
        For the default branch (zeros if not given).

    Returns
    -------
    PostureResult
        With N = 1 (no joint-step constraint).
    """
    task = PostureTask(np.asarray(position, float).reshape(1, 3), np.asarray(rotation, float), rule,
                       np.asarray(wrench, float), cone_half_angle=cone_half_angle, scan=scan)
    return optimise_postures(robot, task, np.zeros(6) if home_q is None else np.asarray(home_q, float),
                             settings, verbose)
