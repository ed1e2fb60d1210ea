"""Transcription of the posture problem into an NLP: the per-waypoint stage functions,
their compilation to C, and :class:`PostureNLP` (one IPOPT solver per model, rule and N).

The stage functions (cost, constraints, their gradient, Jacobian and Lagrangian Hessian)
are CasADi SX functions of one waypoint's joints ``q`` (6,) rad and parameters ``theta``
(:data:`~problems.posture.task.N_THETA`,); they are compiled to C once per model, tool and
rule (cached on disk under ``$COMPPLAN_CACHE``, keyed by a hash of the source) and are
independent of ``N``; without a usable C compiler (or with ``$COMPPLAN_NO_COMPILER=1``) the
SX functions themselves run on CasADi's virtual machine, slower, with the same results to
rounding (:attr:`PostureNLP.compiled` says which; :func:`models.codegen.codegen_notes`
records why).  The NLP is assembled in MX by mapping them over the waypoints, with
the sparse derivative functions assembled by hand and passed to ``nlpsol`` (options
``grad_f``, ``jac_g``, ``hess_lag``), so one solver per (model, rule, N) serves every
branch: only the warm start and the parameters change.  With a cell, the clearance rows are
posed pair by pair where each pair comes near (:mod:`problems.posture.clearance_rows`), and the
solver is cached by that set too (:meth:`PostureNLP.with_posed` adds entries).
"""

from __future__ import annotations

import hashlib
import math
import threading
import time
from typing import Any

import casadi as ca
import numpy as np

from models import interrupts
from models.arm import ArmModel
from models.codegen import CompileError, compile_shared_library, note_virtual_machine
from models.effects import LOAD_SIZE
from models.errors import InputError
from models.ik import IKSolver
from models.robot import Robot
from problems.posture.task import (
    AXIS_SCALE,
    COST_SCALE,
    IPOPT_DEFAULTS,
    N_ORIENTATION,
    N_THETA,
    OBJECTIVE_WEIGHT_MAX,
    OBJECTIVE_WEIGHT_MIN,
    POLISH_MAX_ITER,
    POLISH_STEP_TOL,
    POSITION_SCALE,
    OrientationRule,
    PostureTask,
    SolverSettings,
)
from problems.posture.clearance import ClearanceSpec
from problems.posture.clearance_rows import ClearanceRows
from problems.posture.verification import guard_bounds

# --------------------------------------------------------------------------------------
# Stage functions (per waypoint) and their compilation
# --------------------------------------------------------------------------------------


def _n_stage_constraints(rule: OrientationRule, n_guards: int) -> int:
    """Constraints per waypoint: position (3), the rule's orientation, the IK family's guards."""
    return 3 + N_ORIENTATION[rule] + n_guards


def _stage_sx(arm: ArmModel | Robot, rule: OrientationRule, ik: IKSolver | None = None) -> dict[str, ca.Function]:
    """The per-waypoint SX functions.

    ``theta = [p (3, m); R (9, column-major); L (LOAD_SIZE); sigma (3)]`` with ``L`` the
    load vector of the waypoint and ``sigma`` the signs of the branch's singularity
    factors.  The cost is the arm model's first-order load-induced TCP position error
    (``load_error``), squared.  Constraint vector ``g``: position (mm), rule-specific
    orientation (scaled by AXIS_SCALE), then the three singularity guards ``sigma_i * factor_i``.

    Parameters
    ----------
    arm : ArmModel or Robot
        The arm model (a :class:`Robot` is wrapped in its nominal model); its
        ``kinematics.fn["fk_tcp"]`` and ``kinematics.fn["load_error"]`` are evaluated.
    rule : OrientationRule

    Returns
    -------
    dict str -> casadi.Function
        ``"f"``: (q, theta) -> (cost (mm^2), g (n_g,)); ``"grad"``: (q, theta) -> (cost,
        d cost / dq (6,)); ``"jac"``: (q, theta) -> (g, dg/dq (n_g, 6) dense); ``"hess"``:
        (q, theta, sigma, lam (n_g,)) -> Hessian (6, 6) of ``sigma cost + lam . g``, dense
        and symmetric.  ``n_g = 3 + N_ORIENTATION[rule] + G`` constraints (G: the IK family's guard factors).
    """
    arm = arm if isinstance(arm, ArmModel) else ArmModel.from_robot(arm)
    ik = ik or arm.ik
    n_guards = len(ik.guard_kinds)
    q = ca.SX.sym("q", 6)
    th = ca.SX.sym("theta", N_THETA)
    p, R, L, sig = th[0:3], ca.reshape(th[3:12], 3, 3), th[12 : 12 + LOAD_SIZE], th[12 + LOAD_SIZE : N_THETA]
    fn = arm.kinematics.fn
    T = fn["fk_tcp"](q)
    d = fn["load_error"](q, L)[:3]  # first-order TCP position error (m)
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
    g.append(sig[:n_guards] * ik.guard_factors(q))
    g = ca.vertcat(*g)
    sigma = ca.SX.sym("sigma")
    lam = ca.SX.sym("lam", g.shape[0])
    lag = sigma * cost + ca.dot(lam, g)
    H = ca.hessian(lag, q)[0]
    H = 0.5 * (H + H.T)
    tag = rule.value
    return {
        "f": ca.Function(f"posture_{tag}_f", [q, th], [cost, g], ["q", "theta"], ["cost", "g"]),
        "grad": ca.Function(
            f"posture_{tag}_grad", [q, th], [cost, ca.gradient(cost, q)], ["q", "theta"], ["cost", "grad"]
        ),
        "jac": ca.Function(
            f"posture_{tag}_jac", [q, th], [g, ca.densify(ca.jacobian(g, q))], ["q", "theta"], ["g", "jac"]
        ),
        "hess": ca.Function(
            f"posture_{tag}_hess", [q, th, sigma, lam], [ca.densify(H)], ["q", "theta", "sigma", "lam"], ["hess"]
        ),
    }


class StageCompileError(RuntimeError):
    """No C compiler, or it failed (then the CasADi virtual machine is used)."""


def _compile_stage(funcs: dict[str, ca.Function]) -> dict[str, ca.Function]:
    """Compile the stage functions into one shared library (cached) and load them.

    Raises
    ------
    StageCompileError
        No C compiler, compilation failed, or the library cannot be loaded (a note is
        recorded, see :func:`models.codegen.codegen_notes`).
    """
    cg = ca.CodeGenerator(
        "posture_stage.c", {"with_header": False, "casadi_real": "double", "casadi_int": "long long int"}
    )
    for f in funcs.values():
        cg.add(f)
    src = cg.dump()
    try:
        lib = compile_shared_library(src, "posture")
    except CompileError as exc:
        raise StageCompileError(str(exc)) from None
    try:
        return {k: ca.external(f.name(), str(lib)) for k, f in funcs.items()}
    except RuntimeError as exc:
        first = next((ln.strip() for ln in str(exc).splitlines() if ln.strip()), type(exc).__name__)
        reason = f"cannot load compiled library {lib} ({first})"
        note_virtual_machine(reason)
        raise StageCompileError(reason) from None


# --------------------------------------------------------------------------------------
# The NLP (one per robot, rule, N; reused across branches)
# --------------------------------------------------------------------------------------


def _blockdiag_sparsity(n: int, rows: int, cols: int) -> ca.Sparsity:
    """Sparsity (n rows, n cols) of ``n`` dense (rows, cols) blocks on the diagonal."""
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
    """The posture NLP for one arm model, rule and number of waypoints.

    Variables: the joints of every waypoint, ``vec(X)`` with ``X`` (6, N) rad.  Parameters:
    the stage parameters (:meth:`theta`) and the smoothness weight (mm^2/rad^2).

    Parameters
    ----------
    arm : ArmModel or Robot
        The arm model whose ``load_error`` is the objective (a :class:`Robot` is wrapped
        in its nominal model).
    rule : OrientationRule
    n : int
        Number of waypoints.
    settings : SolverSettings
    verbose : bool
        IPOPT output on (print level 5).
    clearance : ClearanceSpec, optional
        The cell's clearance constraints (:mod:`problems.posture.clearance`), after the stage
        constraints: one row per pair and waypoint where it is posed
        (:class:`~problems.posture.clearance_rows.ClearanceRows`); none without a cell.
    posed : ndarray of bool, shape (P, N), optional
        Where each pair is posed (:func:`problems.posture.clearance_active.posed_at`); default
        every pair at every waypoint.

    Attributes
    ----------
    compiled : bool
        Whether the stage functions run as compiled C.
    stage : dict str -> casadi.Function
        The stage functions in use (see :func:`_stage_sx`).
    m : int
        Constraints per waypoint.
    solver : casadi.Function
        The IPOPT ``nlpsol``.
    build_time_s : float
        Time to build the solver (incl. compiling or loading the stage functions), s.
    posed : ndarray of bool, shape (P, N), or None
        Where each clearance pair is posed (None without a cell); ``clear`` its rows
        (:class:`~problems.posture.clearance_rows.ClearanceRows`, None when nothing is posed).
    """

    def __init__(
        self,
        arm: ArmModel | Robot,
        rule: OrientationRule,
        n: int,
        settings: SolverSettings = SolverSettings(),
        verbose: bool = False,
        clearance: ClearanceSpec | None = None,
        posed: np.ndarray | None = None,
    ) -> None:
        if settings.name != "ipopt":
            raise InputError(f"solver: unknown NLP solver {settings.name!r}; available: ['ipopt']")
        t0 = time.perf_counter()
        arm = arm if isinstance(arm, ArmModel) else ArmModel.from_robot(arm)
        self.arm, self.robot, self.rule, self.n, self.settings = arm, arm.nominal, rule, n, settings
        self.ik = arm.ik
        sx = _stage_sx(arm, rule, self.ik)
        self.compiled = False
        funcs = sx
        if settings.codegen:
            try:
                funcs = _compile_stage(sx)
                self.compiled = True
            except StageCompileError:
                funcs = sx
        self.stage = funcs
        self.m = _n_stage_constraints(rule, len(self.ik.guard_kinds))
        self.clearance = clearance if clearance is not None and clearance.pairs else None
        if self.clearance is not None and posed is None:
            posed = np.ones((len(self.clearance.pairs), n), dtype=bool)
        # each pair's functions run on CasADi's virtual machine, mapped over the waypoints where it
        # is posed (problems/posture/clearance_rows.py); none posed: no clearance rows
        self.posed = np.asarray(posed, dtype=bool) if self.clearance is not None else None
        self.clear = ClearanceRows(self.clearance, self.posed) if self.posed is not None and self.posed.any() else None
        self.mc = self.clear.count if self.clear is not None else 0
        self.verbose = verbose
        self._build(funcs, verbose)
        self.build_time_s = time.perf_counter() - t0

    def _build(self, funcs: dict[str, ca.Function], verbose: bool) -> None:
        """Assemble the NLP and its hand-made sparse derivatives in MX, and make the solver."""
        n, m = self.n, self.m
        X = ca.MX.sym("X", 6, n)
        Th = ca.MX.sym("Theta", N_THETA, n)
        lam_s = ca.MX.sym("lam_s")
        w_obj = ca.MX.sym("w_obj")  # objective weight (conditioning, see solve)
        x = ca.vec(X)
        p = ca.vertcat(ca.vec(Th), lam_s, w_obj)
        Dm = _difference_matrix(n)
        LtL = ca.mtimes(Dm.T, Dm) if n > 1 else ca.DM(6 * n, 6 * n)

        c_all, g_all = funcs["f"].map(n)(X, Th)
        dX = ca.mtimes(Dm, x) if n > 1 else ca.MX(0, 1)
        f = w_obj * (ca.sum2(c_all) + lam_s * ca.sumsqr(dX))
        mc, clear = self.mc, self.clear
        gc = clear.g(X) if clear is not None else ca.MX(0, 1)
        g = ca.vertcat(ca.vec(g_all), gc, dX)

        c_g, grad = funcs["grad"].map(n)(X, Th)
        grad_f = ca.Function(
            "grad_f",
            [x, p],
            [w_obj * (ca.sum2(c_g) + lam_s * ca.sumsqr(dX)), w_obj * (ca.vec(grad) + 2.0 * lam_s * ca.mtimes(LtL, x))],
            ["x", "p"],
            ["f", "grad_f_x"],
        )

        g_j, jac = funcs["jac"].map(n)(X, Th)
        blocks = [ca.MX(_blockdiag_sparsity(n, m, 6), ca.vec(jac))]
        g_rows = [ca.vec(g_j)]
        if clear is not None:
            g_c, jac_c = clear.jac(X)
            blocks.append(jac_c)
            g_rows.append(g_c)
        if n > 1:
            blocks.append(ca.MX(Dm))
        jac_g = ca.Function(
            "jac_g", [x, p], [ca.vertcat(*g_rows, dX), ca.vertcat(*blocks)], ["x", "p"], ["g", "jac_g_x"]
        )

        lam_f = ca.MX.sym("lam_f")
        lam_g = ca.MX.sym("lam_g", m * n + mc + 6 * (n - 1))
        Lg = ca.reshape(lam_g[: m * n], m, n)
        H = funcs["hess"].map(n)(X, Th, ca.repmat(lam_f * w_obj, 1, n), Lg)
        H_c = clear.hess(X, lam_g[m * n : m * n + mc]) if clear is not None else None
        if H_c is not None:
            H = H + H_c
        H_stage = ca.MX(_blockdiag_sparsity(n, 6, 6), ca.vec(H))
        H_full = H_stage + 2.0 * lam_f * w_obj * lam_s * ca.MX(ca.DM(LtL)) if n > 1 else H_stage
        hess = ca.Function(
            "hess_lag", [x, p, lam_f, lam_g], [ca.triu(H_full)], ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]
        )

        s = self.settings
        opts: dict[str, Any] = {
            "grad_f": grad_f,
            "jac_g": jac_g,
            "hess_lag": hess,
            "calc_lam_p": False,
            "no_nlp_grad": True,
            "print_time": False,
            "ipopt": {
                **IPOPT_DEFAULTS,
                "print_level": 5 if verbose else 0,
                "sb": "yes",
                "max_iter": int(s.max_iter),
                "tol": float(s.tol),
                **dict(s.ipopt_options),
            },
        }
        self.solver = ca.nlpsol("posture", "ipopt", {"x": x, "p": p, "f": f, "g": g}, opts)
        self._jac_map = funcs["jac"].map(n)
        self._f_map = funcs["f"].map(n)

    # ---------------------------------------------------------------- parameters
    def theta(self, task: PostureTask, sign: np.ndarray) -> np.ndarray:
        """Stage parameters, shape (N_THETA, N).

        Columns: position (m), base->TCP rotation (column-major), load row (see
        :mod:`models.load`) and the branch's guard-factor signs ``sign`` (G,), zero-padded to 3.
        """
        n = task.n
        th = np.empty((N_THETA, n))
        th[0:3] = task.positions.T
        th[3:12] = task.rotations.transpose(0, 2, 1).reshape(n, 9).T  # column-major R
        th[12 : 12 + LOAD_SIZE] = task.load.T
        sig = np.zeros(N_THETA - 12 - LOAD_SIZE)
        sig[: len(sign)] = np.asarray(sign, dtype=float)
        th[12 + LOAD_SIZE : N_THETA] = sig[:, None]
        return th

    def bounds_g(self, task: PostureTask) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the constraint vector, each shape (m N + 6 (N-1),).

        Per waypoint (scaled as in :func:`_stage_sx`): equalities (position, orientation),
        the cone bound ``>= cos(alpha)``, the guards ``>= guard_bounds(ik)``; then the joint
        steps within ``+-max_joint_step`` (rad).
        """
        n, m = self.n, self.m
        lo = np.zeros((m, n))
        hi = np.zeros((m, n))
        if self.rule is OrientationRule.CONE:
            lo[3] = AXIS_SCALE * math.cos(task.cone_half_angle)
            hi[3] = np.inf
        ng = len(self.ik.guard_kinds)
        lo[m - ng :] = guard_bounds(self.ik)[:, None]
        hi[m - ng :] = np.inf
        step = np.full(6 * (n - 1), task.max_joint_step)
        clo, chi = np.zeros(self.mc), np.full(self.mc, np.inf)
        return np.r_[lo.reshape(-1, order="F"), clo, -step], np.r_[hi.reshape(-1, order="F"), chi, step]

    def solve(
        self, task: PostureTask, q0: np.ndarray, sign: np.ndarray, q_min: np.ndarray, q_max: np.ndarray
    ) -> tuple[np.ndarray, str, int, float]:
        """Run IPOPT from ``q0`` (N, 6) rad with joint limits ``q_min``, ``q_max`` (6,) rad.

        Returns
        -------
        q : ndarray, shape (N, 6)
            IPOPT's solution, rad.
        status : str
            IPOPT's return status.
        iterations : int
        wall_time_s : float
        """
        th = self.theta(task, sign)
        lbg, ubg = self.bounds_g(task)
        p = np.r_[th.reshape(-1, order="F"), task.smoothness, self.objective_weight(task, q0, th)]
        t0 = time.perf_counter()
        with interrupts.native_call():  # IPOPT swallows Ctrl-C: raised again after the call
            res = self.solver(
                x0=q0.reshape(-1), p=p, lbx=np.tile(q_min, self.n), ubx=np.tile(q_max, self.n), lbg=lbg, ubg=ubg
            )
        dt = time.perf_counter() - t0
        st = self.solver.stats()
        q = np.asarray(res["x"]).reshape(self.n, 6)
        return q, str(st.get("return_status", "unknown")), int(st.get("iter_count", 0)), dt

    def with_posed(self, more: np.ndarray) -> PostureNLP:
        """The NLP of the same model, rule and N with the clearance entries ``more`` (P, N) bool
        posed too (:func:`get_nlp`, cached)."""
        assert self.clearance is not None and self.posed is not None
        return get_nlp(self.arm, self.rule, self.n, self.settings, self.verbose, self.clearance, self.posed | more)

    def objective_weight(self, task: PostureTask, q0: np.ndarray, th: np.ndarray) -> float:
        """Weight that brings the objective at the warm start to about one per waypoint.

        IPOPT's convergence test is absolute: a stiff industrial arm whose load-induced error
        is a few micrometres (costs of 1e-2 mm^2) would otherwise need tens of iterations to
        meet it, where a cobot's (1 mm^2) needs five.  The weight multiplies the whole
        objective, so the optimum is unchanged; it is clipped to
        [OBJECTIVE_WEIGHT_MIN, OBJECTIVE_WEIGHT_MAX], and it is 1 when the load error at the
        warm start is zero (no load: only the smoothness term, nothing to rescale for).
        """
        c, _ = self._f_map(q0.T, th)
        cost = float(np.sum(np.asarray(c)))
        if cost <= 0.0:
            return 1.0
        f0 = cost + task.smoothness * float(np.sum(np.diff(q0, axis=0) ** 2))
        return float(min(max(self.n / f0, OBJECTIVE_WEIGHT_MIN), OBJECTIVE_WEIGHT_MAX))

    # ---------------------------------------------------------------- polishing
    def polish(self, task: PostureTask, q: np.ndarray, sign: np.ndarray) -> np.ndarray:
        """Project every waypoint onto its equality constraints (Gauss-Newton, min-norm steps).

        The cone inequality joins the projection only where it is violated.

        Parameters
        ----------
        q : ndarray, shape (N, 6)
            Joints, rad (not modified).
        sign : ndarray, shape (G,)
            The branch's guard-factor signs.

        Returns
        -------
        ndarray, shape (N, 6)
            The projected joints, rad.
        """
        th = self.theta(task, sign)
        q = q.copy()
        n_eq = 3 + (0 if self.rule is OrientationRule.CONE else N_ORIENTATION[self.rule])
        cos_a = math.cos(task.cone_half_angle)
        for _ in range(POLISH_MAX_ITER):
            g, jac = self._jac_map(q.T, th)
            g = np.asarray(g).T  # (N, m)
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


#: Solvers built so far, by (model key, rule, N, settings, verbose); cleared beyond 32.
_SOLVERS: dict[tuple, PostureNLP] = {}
_SOLVERS_LOCK = threading.Lock()


def _model_key(arm: ArmModel) -> tuple:
    """Hashable key of everything in the arm model the stage functions depend on."""
    r = arm.nominal
    return (
        r.convention,
        tuple(r.a),
        tuple(r.alpha),
        tuple(r.d),
        tuple(r.theta_offset),
        tuple(r.stiffness),
        tuple(r.tcp2flange.reshape(-1)),
        arm.active_effects,
        arm.theta.tobytes(),
        arm.const.tobytes(),
        float(arm.temperature_ref),
    )


def get_nlp(
    arm: ArmModel | Robot,
    rule: OrientationRule,
    n: int,
    settings: SolverSettings = SolverSettings(),
    verbose: bool = False,
    clearance: ClearanceSpec | None = None,
    posed: np.ndarray | None = None,
) -> PostureNLP:
    """The cached :class:`PostureNLP` for (model, rule, n, settings, verbose, clearance, posed).

    ``posed`` (P, N) bool: where each pair of ``clearance`` is posed (default: everywhere).
    """
    arm = arm if isinstance(arm, ArmModel) else ArmModel.from_robot(arm)
    ckey = None
    if clearance is not None and clearance.pairs:
        mask = np.ones((len(clearance.pairs), n), dtype=bool) if posed is None else np.asarray(posed, dtype=bool)
        ckey = (clearance.key, hashlib.sha256(np.packbits(mask).tobytes() + str(mask.shape).encode()).hexdigest())
    key = (_model_key(arm), rule, n, settings, verbose, ckey)
    with _SOLVERS_LOCK:
        nlp = _SOLVERS.get(key)
        if nlp is None:
            if len(_SOLVERS) > 32:
                _SOLVERS.clear()
            nlp = PostureNLP(arm, rule, n, settings, verbose, clearance, posed)
            _SOLVERS[key] = nlp
    return nlp
