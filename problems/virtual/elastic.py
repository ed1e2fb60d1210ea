"""Elastic-joint simulation of a timed trajectory: the arm as it moves, not only where it settles.

The link side is a rigid multibody driven through one torsional spring-damper per joint::

    M(q) qdd + c(q, qd) + g(q) - J(q)^T W = K (theta - q) + D (thetad - qd)

``q`` the link angles, ``theta`` the motor angles (link side, after the gear), ``K`` the joint
stiffnesses (N*m/rad, ``robot.stiffness``), ``D`` the joint damping (N*m*s/rad), ``W = [f; m]`` the
process wrench **acting on the arm** at the TCP (base frame, moment about the TCP), ``g(q)`` the
holding torques of the links and the payload against ``robot.gravity``.  At rest this is the static
model of the virtual robot (:meth:`problems.virtual.physics.PhysicsPart.equilibrium`) and of the arm
model: ``q = theta + K^-1 (tau_g + J^T W)``, a joint yields in the direction of the torque applied
to it.

The motor side follows the command ``theta_cmd(t)``:

* ``motor="exact"`` (default): ``theta = theta_cmd(t)``, ``thetad = thetad_cmd(t)`` exactly (a
  prescribed motor position, an infinitely stiff position loop);
* ``motor="pid"``: a motor of reflected inertia ``B`` under a PID position loop,
  ``B thetadd = Kp e + Kd ed + Ki int(e) - K (theta - q) - D (thetad - qd)``, ``e = theta_cmd - theta``,
  gains placing the poles of motor and link as one rigid body, inertia ``J = B + M_ii(q_0)``
  (``M_ii`` at the start pose), at ``-omega`` (triple): ``Kp = 3 J omega^2``, ``Kd = 3 J omega``,
  ``Ki = J omega^3`` (designed on ``B`` alone the loop is far too soft for the link behind the
  spring and rings for seconds); the integral holds the spring torque, so the motor settles on
  the command and the rest pose is the same as with ``"exact"``.  No torque feed-forward.

The rigid-body dynamics are :mod:`problems.virtual.rigid_body`, written independently of the
CasADi model (:mod:`models.dynamics`): NumPy kinematics of
:mod:`problems.virtual.geometry`, a NumPy recursive Newton-Euler (moments about the joint points,
propagated from the tip) for ``c + g - J^T W``, and the mass matrix summed from body Jacobians
(``M = sum m Jv^T Jv + Jw^T I Jw``), so the two are cross-checks of each other and of pinocchio
(``tests/test_elastic_sim.py``).  SI units; frames: base frame unless stated.
"""

from __future__ import annotations

import csv
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from models.errors import InputError
from models.robot import Robot
from models.status import Status

from .rigid_body import EQUILIBRIUM_MAX_ITER, ElasticArm, as_vector, static_command

__all__ = [
    "ElasticArm",
    "ElasticStatus",
    "read_trajectory_csv",
    "simulate_elastic",
    "static_command",
    "tracking_error",
]

#: Integrator: Radau IIA (order 5). The joint springs make the system stiff (link modes from
#: ~15 Hz to > 1 kHz on the wrist without payload); Radau is A- and L-stable, so it is not limited by
#: the fastest mode, and unlike BDF of order > 2 it stays accurate for lightly damped oscillations
#: (BDF's stability region misses part of the imaginary axis); LSODA's explicit phase would crawl
#: at the wrist's frequencies.
SIM_METHOD = "Radau"
#: Relative tolerance of the integrator (on q, qd, and the motor states).  Measured on a 2 s UR5
#: move with 5 kg: 1e-8 puts the TCP within 1.2e-10 m of a 1e-10 / 1e-12 rad run (1e-7: 1.4e-9 m,
#: 1e-9: 2e-11 m at 2x / 0.5x the cost of 1e-8).
SIM_RTOL = 1e-8
#: Absolute tolerance on the angles (rad): well below the deflections (1e-5 .. 1e-3 rad), ~1e-10 m
#: at the TCP of a 1 m arm.
SIM_ATOL_ANGLE_RAD = 1e-10
#: Absolute tolerance on the rates (rad/s).
SIM_ATOL_RATE_RAD_S = 1e-8
#: Absolute tolerance on the PID integral state (rad*s).
SIM_ATOL_INTEGRAL_RAD_S = 1e-12
#: Default damping ratio of each joint: ``D_i = 2 zeta sqrt(K_i M_ii(q_0))``, ``M_ii`` the inertia
#: joint ``i`` sees with the other joints locked, at the start pose (an assumption: gear damping
#: ratios of a few per cent are typical; nothing of the robot files states it).
DEFAULT_DAMPING_RATIO = 0.05
#: Default time the last command is held after the trajectory ends, s.
DEFAULT_SETTLE_S = 0.5
#: Default reflected motor inertia (link side, kg*m^2) of ``motor="pid"``: an order of magnitude
#: (rotor ~6e-5 / 1.5e-5 kg*m^2 times a gear ratio of ~100, squared), not a datasheet value.
DEFAULT_MOTOR_INERTIA = (0.6, 0.6, 0.6, 0.15, 0.15, 0.15)
#: Default position-loop bandwidth of ``motor="pid"``, rad/s (triple pole of motor + link as one
#: rigid body; 40 Hz tracks the UR5 test move within 0.1 um of the exact motor, 10-20 Hz lag more).
DEFAULT_MOTOR_BANDWIDTH_RAD_S = 2 * np.pi * 40.0
#: Fewest output samples of the settle phase.
SETTLE_MIN_SAMPLES = 50
#: Interpolations of the command between its samples: ``"spline"`` a C2 cubic spline through the
#: samples (end rates clamped to ``theta_dot_cmd`` when given, else not-a-knot); ``"hermite"`` the
#: C1 cubic Hermite with ``theta_dot_cmd`` at every sample.  The Hermite's jumps of acceleration at
#: every sample excite the stiff wrist modes: on a 2 s UR5 move sampled at 8 ms it costs 4-5x the
#: evaluations of the spline for the same TCP path (1e-9 m apart), hence the default.
INTERPOLATIONS = ("spline", "hermite")


class ElasticStatus(Status):
    """Outcome of :func:`simulate_elastic`."""

    OK = "ok"
    NO_EQUILIBRIUM = "no_equilibrium"  #: the start's static equilibrium did not converge
    SOLVER_FAILED = "solver_failed"  #: solve_ivp stopped early (its message in ``reason``)


@dataclass
class ElasticResult:
    """A simulated elastic-joint motion.

    Attributes
    ----------
    status : ElasticStatus
    reason : str
        What happened, in words (``""`` when ``ok``).
    t : ndarray, shape (K,)
        Output times, s: the command's samples, then the settle phase.
    q, qd : ndarray, shape (K, 6)
        Link angles (rad) and rates (rad/s).
    theta : ndarray, shape (K, 6)
        Motor angles, link side, rad (the command itself for ``motor="exact"``).
    p_tcp : ndarray, shape (K, 3)
        TCP position of the elastic arm, base frame, m.
    t_command_end : float
        Time of the command's last sample, s; after it the command is held.
    stiffness, damping : ndarray, shape (6,)
        K (N*m/rad) and D (N*m*s/rad) used.
    motor : str
    nfev, njev, nlu : int
        Right-hand-side evaluations (a vectorised call counts once), Jacobians, LU decompositions.
    message : str
        The solver's own message(s), one per phase.
    cpu_s : float
        Process CPU time of the integration, s.
    """

    status: ElasticStatus
    reason: str
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    q: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    qd: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    theta: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    p_tcp: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    t_command_end: float = 0.0
    stiffness: np.ndarray = field(default_factory=lambda: np.zeros(6))
    damping: np.ndarray = field(default_factory=lambda: np.zeros(6))
    motor: str = "exact"
    nfev: int = 0
    njev: int = 0
    nlu: int = 0
    message: str = ""
    cpu_s: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status is ElasticStatus.OK


@dataclass
class TrackingError:
    """TCP position error of a simulated motion against the planned link-side trajectory.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Times, s (those of the :class:`ElasticResult`).
    error : ndarray, shape (K,)
        ``|p_tcp(q(t)) - p_tcp(q_planned(t))|``, m.
    max_motion, rms_motion : float
        Over ``t <= t_command_end``, m.
    max_rest, rms_rest : float
        Over the settle phase ``t > t_command_end``, m (NaN without one).
    final : float
        At the last sample, m.
    """

    t: np.ndarray
    error: np.ndarray
    max_motion: float
    rms_motion: float
    max_rest: float
    rms_rest: float
    final: float


def _command(t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray | None, interpolation: str):
    """Piecewise cubic of the command (see :data:`INTERPOLATIONS`)."""
    if interpolation == "hermite":
        if theta_dot is None:
            raise InputError("interpolation='hermite' needs theta_dot_cmd")
        return CubicHermiteSpline(t, theta, theta_dot, axis=0)
    bc = "not-a-knot" if theta_dot is None else ((1, theta_dot[0]), (1, theta_dot[-1]))
    return CubicSpline(t, theta, axis=0, bc_type=bc)


def _check_command(t, theta_cmd, theta_dot_cmd):
    t = np.asarray(t, dtype=float).reshape(-1)
    th = np.asarray(theta_cmd, dtype=float)
    if th.ndim != 2 or th.shape != (t.size, 6) or t.size < 2:
        raise InputError(f"theta_cmd must have shape (K, 6) with K = len(t) >= 2, got {th.shape} for {t.size} times")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(th)) and np.all(np.diff(t) > 0)):
        raise InputError("t must increase strictly and t, theta_cmd be finite")
    thd = None
    if theta_dot_cmd is not None:
        thd = np.asarray(theta_dot_cmd, dtype=float)
        if thd.shape != th.shape or not np.all(np.isfinite(thd)):
            raise InputError(f"theta_dot_cmd must have shape {th.shape} and be finite, got {thd.shape}")
    return t, th, thd


class _Rhs:
    """Right-hand side of the ODE, vectorised over columns of the state (solve_ivp's layout).

    State: ``[q, qd]`` (12,) for the exact motor, ``[q, qd, theta, thetad, int(e)]`` (30,) for
    the PID motor."""

    def __init__(
        self,
        arm: ElasticArm,
        K: np.ndarray,
        D: np.ndarray,
        cmd,
        hold: np.ndarray | None,
        motor: str,
        B: np.ndarray,
        gains: tuple[np.ndarray, np.ndarray, np.ndarray],
    ) -> None:
        self.arm, self.K, self.D, self.cmd, self.hold, self.motor = arm, K, D, cmd, hold, motor
        self.B, (self.kp, self.kd, self.ki) = B, gains

    def command(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        if self.hold is not None:
            return self.hold, np.zeros(6)
        return self.cmd(t), self.cmd(t, 1)

    def __call__(self, t: float, x: np.ndarray) -> np.ndarray:
        x2 = x.reshape(x.shape[0], -1).T  # (N, n_state)
        q, qd = x2[:, 0:6], x2[:, 6:12]
        th_c, thd_c = self.command(t)
        if self.motor == "exact":
            th, thd = np.broadcast_to(th_c, q.shape), np.broadcast_to(thd_c, q.shape)
        else:
            th, thd = x2[:, 12:18], x2[:, 18:24]
        spring = self.K * (th - q) + self.D * (thd - qd)
        kin = self.arm.kinematics(q)
        bias = self.arm.inverse_dynamics(q, qd, np.zeros_like(q), kin)
        qdd = np.linalg.solve(self.arm.mass_matrix(q, kin), (spring - bias)[..., None])[..., 0]
        parts = [qd, qdd]
        if self.motor != "exact":
            e = th_c - th
            u = self.kp * e + self.kd * (thd_c - thd) + self.ki * x2[:, 24:30]
            parts += [thd, (u - spring) / self.B, e]
        out = np.concatenate(parts, axis=1).T
        return out.reshape(x.shape)


def _damping(arm: ElasticArm, q0: np.ndarray, K: np.ndarray, damping: np.ndarray | None, ratio: float) -> np.ndarray:
    """``damping`` (6,) N*m*s/rad as given, or ``2 ratio sqrt(K_i M_ii(q0))``."""
    if damping is not None:
        D = as_vector(damping, 6, "damping")
        if np.any(D < 0):
            raise InputError(f"damping must be >= 0 N*m*s/rad, got {D}")
        return D
    return 2.0 * float(ratio) * np.sqrt(K * np.diagonal(arm.mass_matrix(q0[None])[0]))


def _output_times(t: np.ndarray, settle_s: float) -> np.ndarray:
    """Output times of the settle phase (after ``t[-1]``, ending at ``t[-1] + settle_s``): the
    command's median step, at least :data:`SETTLE_MIN_SAMPLES` samples."""
    step = min(float(np.median(np.diff(t))), settle_s / SETTLE_MIN_SAMPLES)
    n = max(int(np.ceil(settle_s / step - 1e-9)), 1)
    return t[-1] + settle_s * np.arange(1, n + 1) / n


def _integrate(rhs: _Rhs, span: tuple[float, float], x0: np.ndarray, t_eval: np.ndarray):
    atol = np.r_[np.full(6, SIM_ATOL_ANGLE_RAD), np.full(6, SIM_ATOL_RATE_RAD_S)]
    if rhs.motor != "exact":
        atol = np.r_[
            atol, np.full(6, SIM_ATOL_ANGLE_RAD), np.full(6, SIM_ATOL_RATE_RAD_S), np.full(6, SIM_ATOL_INTEGRAL_RAD_S)
        ]
    return solve_ivp(rhs, span, x0, method=SIM_METHOD, t_eval=t_eval, rtol=SIM_RTOL, atol=atol, vectorized=True)


def _check_options(interpolation: str, motor: str, settle_s: float) -> None:
    """Raise :class:`InputError` for an unknown interpolation or motor, or a negative settle time."""
    if interpolation not in INTERPOLATIONS:
        raise InputError(f"interpolation must be one of {INTERPOLATIONS}, got {interpolation!r}")
    if motor not in ("exact", "pid"):
        raise InputError(f"motor must be 'exact' or 'pid', got {motor!r}")
    if not (np.isfinite(settle_s) and settle_s >= 0):
        raise InputError(f"settle_s must be >= 0 s, got {settle_s}")


def _checked_stiffness(robot: Robot, stiffness: np.ndarray | None) -> np.ndarray:
    """Joint stiffness (6,), N*m/rad: the given one, else the robot's; each > 0."""
    K = as_vector(robot.stiffness if stiffness is None else stiffness, 6, "stiffness")
    if np.any(K <= 0):
        raise InputError(f"stiffness must be > 0 N*m/rad, got {K}")
    return K


def _motor_start(
    arm: ElasticArm,
    q_start: np.ndarray,
    th0: np.ndarray,
    K: np.ndarray,
    motor: str,
    motor_inertia: np.ndarray,
    motor_bandwidth: float,
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """Motor inertia B (6,), kg*m^2, the PID gains and the initial state (link, and motor with ``pid``)."""
    B = as_vector(motor_inertia, 6, "motor_inertia")
    J = B + np.diagonal(arm.mass_matrix(q_start[None])[0])  # motor and link as one rigid body
    w = float(motor_bandwidth)
    gains = (3 * J * w**2, 3 * J * w, J * w**3)
    x0 = np.r_[q_start, np.zeros(6)]
    if motor == "pid":
        x0 = np.r_[x0, th0, np.zeros(6), K * (th0 - q_start) / gains[2]]
    return B, gains, x0


def simulate_elastic(
    robot: Robot,
    t: np.ndarray,
    theta_cmd: np.ndarray,
    theta_dot_cmd: np.ndarray | None = None,
    *,
    payload: np.ndarray | None = None,
    wrench: np.ndarray | None = None,
    stiffness: np.ndarray | None = None,
    damping: np.ndarray | None = None,
    damping_ratio: float = DEFAULT_DAMPING_RATIO,
    q0: np.ndarray | None = None,
    motor: str = "exact",
    motor_inertia: np.ndarray = DEFAULT_MOTOR_INERTIA,
    motor_bandwidth: float = DEFAULT_MOTOR_BANDWIDTH_RAD_S,
    settle_s: float = DEFAULT_SETTLE_S,
    interpolation: str = "spline",
) -> ElasticResult:
    """Simulate the elastic-joint arm driven by a motor-side command.

    Parameters
    ----------
    robot : Robot
        Kinematics, link inertials, gravity, stiffness (``robot.stiffness`` unless ``stiffness``).
    t : ndarray, shape (K,)
        Command sample times, s, strictly increasing (K >= 2).
    theta_cmd : ndarray, shape (K, 6)
        Motor-side command, link-side angles, rad; ``theta_dot_cmd`` (K, 6) rad/s its rates
        (optional).  Interpolated piecewise cubic (``interpolation``, :data:`INTERPOLATIONS`) and
        held at its last value (rate 0) for ``settle_s`` after ``t[-1]``.
    payload : ndarray, shape (10,), optional
        See :class:`ElasticArm`.
    wrench : ndarray, shape (6,), optional
        Constant process wrench on the arm at the TCP, base frame, ``[f N; m N*m]``.
    stiffness, damping : ndarray, shape (6,), optional
        K (N*m/rad) and D (N*m*s/rad); default ``robot.stiffness`` and
        ``2 damping_ratio sqrt(K_i M_ii(q0))`` (:data:`DEFAULT_DAMPING_RATIO`).
    q0 : ndarray, shape (6,), optional
        Link angles at ``t[0]`` (rad), at rest; default the static equilibrium of ``theta_cmd[0]``.
    motor : {"exact", "pid"}
        Prescribed motor position, or a motor of inertia ``motor_inertia`` (6,) kg*m^2 under a
        PID loop of bandwidth ``motor_bandwidth`` rad/s (see the module docstring).
    settle_s : float
        Hold time after the command, s.

    Returns
    -------
    ElasticResult
        ``status`` ``ok``, ``no_equilibrium`` (the start's equilibrium failed; nothing simulated)
        or ``solver_failed`` (the samples up to the failure).

    Raises
    ------
    InputError
        Malformed inputs (shapes, non-finite values, unknown ``motor``).
    """
    t, th, thd = _check_command(t, theta_cmd, theta_dot_cmd)
    _check_options(interpolation, motor, settle_s)
    arm = ElasticArm(robot, payload, wrench)
    K = _checked_stiffness(robot, stiffness)
    if q0 is None:
        q_start, converged = arm.equilibrium(th[0], K)
        if not converged:
            return ElasticResult(
                ElasticStatus.NO_EQUILIBRIUM,
                "static equilibrium of theta_cmd[0] did not converge "
                f"in {EQUILIBRIUM_MAX_ITER} iterations (joints too soft for the load?)",
            )
    else:
        q_start = as_vector(q0, 6, "q0")
    D = _damping(arm, q_start, K, damping, damping_ratio)
    B, gains, x0 = _motor_start(arm, q_start, th[0], K, motor, motor_inertia, motor_bandwidth)
    cmd = _command(t, th, thd, interpolation)
    phases = [(_Rhs(arm, K, D, cmd, None, motor, B, gains), (t[0], t[-1]), t)]
    if settle_s > 0:
        phases.append(
            (_Rhs(arm, K, D, cmd, th[-1], motor, B, gains), (t[-1], t[-1] + settle_s), _output_times(t, settle_s))
        )
    return _run_phases(arm, phases, x0, K, D, motor, t[-1])


def _run_phases(
    arm: ElasticArm, phases: list, x0: np.ndarray, K: np.ndarray, D: np.ndarray, motor: str, t_end: float
) -> ElasticResult:
    """Integrate the phases one after the other (the held command's rate may jump at ``t_end``);
    each phase's output times end at its span's end and the first phase's start at its start."""
    ts, xs, msgs = [], [], []
    nfev = njev = nlu = 0
    status, reason = ElasticStatus.OK, ""
    cpu0 = time.process_time()
    for rhs, span, t_eval in phases:
        sol = _integrate(rhs, span, x0, t_eval)
        nfev, njev, nlu = nfev + sol.nfev, njev + sol.njev, nlu + sol.nlu
        msgs.append(str(sol.message))
        ts.append(sol.t)
        xs.append(sol.y.T)
        if sol.status != 0 or sol.t.size == 0 or sol.t[-1] != span[1]:
            status = ElasticStatus.SOLVER_FAILED
            reason = f"{SIM_METHOD} stopped in [{span[0]:.6g}, {span[1]:.6g}] s: {sol.message}"
            break
        x0 = sol.y[:, -1]
    cpu = time.process_time() - cpu0
    t_all = np.concatenate(ts)
    x = np.concatenate(xs, axis=0).reshape(-1, x0.size)
    q, qd = x[:, 0:6], x[:, 6:12]
    if motor == "pid":
        theta = x[:, 12:18]
    else:
        cmd, hold = phases[0][0].cmd, phases[0][0].cmd(t_end)
        theta = np.where((t_all > t_end)[:, None], hold, cmd(np.minimum(t_all, t_end)).reshape(-1, 6))
    return ElasticResult(
        status,
        reason,
        t=t_all,
        q=q,
        qd=qd,
        theta=theta,
        p_tcp=arm.tcp_position(q),
        t_command_end=float(t_end),
        stiffness=K,
        damping=D,
        motor=motor,
        nfev=nfev,
        njev=njev,
        nlu=nlu,
        message=" | ".join(msgs),
        cpu_s=cpu,
    )


# --------------------------------------------------------------------------------------
# Evaluation and input
# --------------------------------------------------------------------------------------


def tracking_error(
    result: ElasticResult,
    robot: Robot,
    q_planned_t: np.ndarray,
    q_planned: np.ndarray,
    q_planned_dot: np.ndarray | None = None,
) -> TrackingError:
    """TCP position error of a simulated motion against the planned link-side trajectory.

    Parameters
    ----------
    result : ElasticResult
    robot : Robot
        The robot simulated (its kinematics and tool give the TCP).
    q_planned_t : ndarray, shape (P,)
        Times of the plan, s.
    q_planned : ndarray, shape (P, 6)
        Planned link angles, rad; interpolated at ``result.t`` as the command is (a C2 cubic
        spline, or the cubic Hermite with ``q_planned_dot`` (P, 6) rad/s) and held after its end.

    Returns
    -------
    TrackingError
        ``|p_tcp(q(t)) - p_tcp(q_planned(t))|`` (m) along ``result.t`` with its max and RMS during
        the motion (``t <= result.t_command_end``) and at rest (after it).
    """
    tp, qp, qpd = _check_command(q_planned_t, q_planned, q_planned_dot)
    plan = _command(tp, qp, qpd, "hermite" if qpd is not None else "spline")
    tt = np.clip(result.t, tp[0], tp[-1])
    p_plan = ElasticArm(robot).tcp_position(plan(tt).reshape(-1, 6))
    err = np.linalg.norm(result.p_tcp - p_plan, axis=1)
    moving = result.t <= result.t_command_end

    def stats(e: np.ndarray) -> tuple[float, float]:
        return (float(e.max()), float(np.sqrt(np.mean(e**2)))) if e.size else (float("nan"), float("nan"))

    (mx_m, rms_m), (mx_r, rms_r) = stats(err[moving]), stats(err[~moving])
    return TrackingError(
        t=result.t,
        error=err,
        max_motion=mx_m,
        rms_motion=rms_m,
        max_rest=mx_r,
        rms_rest=rms_r,
        final=float(err[-1]) if err.size else float("nan"),
    )


def read_trajectory_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The command of a ``trajectory*.csv`` written by ``compplan plan`` (``docs/cli.md``).

    Parameters
    ----------
    path : str or Path
        CSV with a header row; columns found by name, any order: ``t`` (s), ``q1..q6`` (rad),
        optionally ``qd1..qd6`` (rad/s); other columns are ignored, ``#`` lines skipped.

    Returns
    -------
    t : ndarray, shape (K,)
    q : ndarray, shape (K, 6)
    qd : ndarray, shape (K, 6) or None

    Raises
    ------
    InputError
        Unreadable file, missing columns, non-numeric or non-finite values, fewer than 2 rows.
    """
    p = Path(path)
    try:
        with p.open(newline="", encoding="utf-8") as f:
            rows = [r for r in csv.reader(f) if r and not r[0].lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{p}: not a readable CSV file ({exc})") from None
    if len(rows) < 3:
        raise InputError(f"{p}: expected a header row and at least 2 samples")
    head = [h.strip() for h in rows[0]]
    need = ["t"] + [f"q{i}" for i in range(1, 7)]
    missing = [c for c in need if c not in head]
    if missing:
        raise InputError(f"{p}: missing column(s) {', '.join(missing)}")
    rate = [f"qd{i}" for i in range(1, 7)]
    cols = need + (rate if all(c in head for c in rate) else [])
    idx = [head.index(c) for c in cols]
    try:
        a = np.array([[float(r[i]) for i in idx] for r in rows[1:]])
    except (ValueError, IndexError):
        raise InputError(f"{p}: every row must hold {len(head)} numbers") from None
    if not np.all(np.isfinite(a)):
        raise InputError(f"{p}: non-finite values")
    return a[:, 0], a[:, 1:7], (a[:, 7:13] if a.shape[1] == 13 else None)
