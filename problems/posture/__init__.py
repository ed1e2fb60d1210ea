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
* The singularity guards are the IK family's guard factors
  (:meth:`models.ik.IKSolver.guard_factors`), whose signs *are* the branch: on a
  UR-type arm the three factors of ``det J = a2 a3 sin(theta3) sin(theta5) rho``
  (shoulder ``rho``, wrist ``sin theta5``, elbow ``sin theta3``); on an OPW arm the
  wrist centre's signed distance from axis 1 (front/back), the sine of the elbow bend
  (up/down) and ``sin theta5`` (flip); on any other 6R arm the sign of ``det J`` (with
  the branch re-checked after solving).  Each factor keeps the sign it has at the warm
  start, with a margin per kind (``SINGULAR_RHO_MIN_M`` for lengths,
  ``SINGULAR_SIN_MIN`` for sines, ``SINGULAR_DET_MIN``), so the optimum stays on its
  branch and away from singular poses (where ``C`` loses rank and the error would
  vanish only on paper).

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
label of its warm start (the IK family's ``labels``); the guards make the
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

The cost evaluates the arm model (:class:`models.arm.ArmModel`): its
``kinematics.fn["load_error"]`` is the first-order load-induced TCP error, which for the
nominal model and a base-frame wrench is ``C(q) F`` above.

Modules
-------
:mod:`~problems.posture.task`
    The task data, named constants and tolerances, and the result types.
:mod:`~problems.posture.transcription`
    The stage functions, their compilation and :class:`PostureNLP` (:func:`get_nlp`).
:mod:`~problems.posture.warm_start`
    Candidates, warm starts, the dynamic programmes, moving paths onto the model geometry.
:mod:`~problems.posture.verification`
    Singularity factors and guards, and :func:`verify`.
:mod:`~problems.posture.solve`
    :func:`optimise_postures`, :func:`optimal_pose`, :func:`analyse_freedom`, :func:`branch_signs`.

The package prints nothing; IPOPT is quiet unless ``verbose=True``.
"""

from __future__ import annotations

from problems.posture.task import (
    AXIS_SCALE,
    COST_SCALE,
    DEFAULT_MAX_ITER,
    DEFAULT_SCAN,
    DEFAULT_SMOOTHNESS,
    DEFAULT_TOL,
    DEGENERATE_ANGLE_TOL_RAD,
    DEGENERATE_OFFSET_TOL_M,
    DP_MAX_STATES,
    DP_NEIGHBOUR_ANGLE_RAD,
    GUARD_ACTIVE_TOL,
    IPOPT_DEFAULTS,
    IPOPT_OK,
    JOINT_TOL_RAD,
    N_ORIENTATION,
    N_THETA,
    ORIENTATION_TOL_RAD,
    POLISH_MAX_ITER,
    POLISH_STEP_TOL,
    POSITION_ONLY_AXES,
    POSITION_SCALE,
    POSITION_TOL_M,
    SINGULAR_DET_MIN,
    SINGULAR_RHO_MIN_M,
    SINGULAR_SIN_MIN,
    BranchResult,
    BranchStatus,
    OrientationRule,
    PostureError,
    PostureResult,
    PostureStatus,
    PostureTask,
    SolverSettings,
)
from problems.posture.verification import guard_bounds, singular_factors, verify
from problems.posture.transcription import PostureNLP, get_nlp
from problems.posture.warm_start import WarmStarts, candidates, linear_error, warm_starts
from problems.posture.solve import analyse_freedom, branch_signs, optimal_pose, optimise_postures

__all__ = [
    "AXIS_SCALE",
    "COST_SCALE",
    "DEFAULT_MAX_ITER",
    "DEFAULT_SCAN",
    "DEFAULT_SMOOTHNESS",
    "DEFAULT_TOL",
    "DEGENERATE_ANGLE_TOL_RAD",
    "DEGENERATE_OFFSET_TOL_M",
    "DP_MAX_STATES",
    "DP_NEIGHBOUR_ANGLE_RAD",
    "GUARD_ACTIVE_TOL",
    "IPOPT_DEFAULTS",
    "IPOPT_OK",
    "JOINT_TOL_RAD",
    "N_ORIENTATION",
    "N_THETA",
    "ORIENTATION_TOL_RAD",
    "POLISH_MAX_ITER",
    "POLISH_STEP_TOL",
    "POSITION_ONLY_AXES",
    "POSITION_SCALE",
    "POSITION_TOL_M",
    "SINGULAR_DET_MIN",
    "SINGULAR_RHO_MIN_M",
    "SINGULAR_SIN_MIN",
    "BranchResult",
    "BranchStatus",
    "OrientationRule",
    "PostureError",
    "PostureResult",
    "PostureStatus",
    "PostureTask",
    "SolverSettings",
    "guard_bounds",
    "singular_factors",
    "verify",
    "PostureNLP",
    "get_nlp",
    "WarmStarts",
    "candidates",
    "linear_error",
    "warm_starts",
    "analyse_freedom",
    "branch_signs",
    "optimal_pose",
    "optimise_postures",
]
