"""Applying an identified model: predict, compensate, check and validate.

* :func:`predict` -- the measured point in the measurement frame, every identified
  effect applied (comparable with a held-out measurement file);
* :func:`compensate` -- commands that put the TCP on base-frame targets under the
  load, by the product's one exact-compensation engine
  (:func:`problems.compensation.exact`);
* :func:`compensate_targets` -- the targets of ``compplan compensate`` from a command
  file, in one of three frames (:class:`~problems.identify.results.TargetsFrame`):
  the nominal-FK TCP of the commands, base-frame TCP positions, or measurement-frame
  positions of the measured point;
* :func:`compensation_check` -- simulate, compensate, re-measure on a virtual robot;
* :func:`validate_on` -- RMS on a held-out measurement file.

Frames: ``target2base`` poses map target-frame coordinates to base-frame coordinates
(4x4, m); ``model.base2meas()`` maps base-frame coordinates to measurement-frame
coordinates.  Everything is SI.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from models.arm import ArmModel
from models.effects import GROUP_SLICES, LOAD_SIZE, PARAM_NAMES, make_const, make_layout
from models.load import load_rows

from ..compensation import CompensationStatus
from ..compensation import exact as exact_compensation
from ..measurements import POSITION_COLUMNS, Measurements
from .evaluation import evaluator_for, make_rows, nominal_tcp
from .identifiability import aliases_registration
from .lsq import rms
from .transfer import where_it_holds
from .position_error import frame_words, position_errors
from .results import CompensationOutcome, DataError, IdentifiedModel, TargetsError, TargetsFrame

#: Compensation fails for a row if the model-predicted residual exceeds this (m).
COMPENSATION_RESIDUAL_TOL = 1e-6
#: The compensation check on a virtual robot avoids poses whose nominal Jacobian
#: condition number exceeds this (targets at the edge of the reach may be
#: unreachable for the true arm).
COMPENSATION_CHECK_MAX_COND = 80.0
#: A position target (base frame, or mapped from the measurement frame) farther than this
#: from the nominal position of the row's commands is refused, m: the commands seed the
#: solve and pick the branch, so they must command a pose near the target (a larger gap
#: means targets in another frame or unit than declared).
TARGET_SEED_MAX_M = 0.05
#: Tolerance of the joint-limit checks of :func:`compensate` and :func:`compensate_targets`
#: (rad): a command this far beyond ``q_min``/``q_max`` is outside the limits.
JOINT_LIMIT_TOL_RAD = 1e-12


# ----------------------------------------------------------------------------------
# Predict and compensate
# ----------------------------------------------------------------------------------


def predict(model: IdentifiedModel, m: Measurements) -> np.ndarray:
    """Predicted measurement of the measured point, measurement frame, m, (N, 3).

    Registration, measured point and every identified effect are applied; drift
    only when the input has a ``t`` column (same clock as the identification data;
    otherwise the state at the campaign's first row), temperature from the input or
    the identification data's mean.
    """
    ev = evaluator_for(model.nominal, model.const)
    rows = make_rows(m, model.time_ref if m.t is not None else None, model.temperature_ref)
    p, _q = ev.measure(rows, model.theta, model.const)
    return p


def _at_temperature(model: ArmModel, temperature: np.ndarray | None) -> list[tuple[np.ndarray, ArmModel]]:
    """Row groups that share a temperature (deg C, (N,)), each with the model evaluated at
    it (thermal); one group of no rows when there is no temperature."""
    if temperature is None or "thermal" not in model.active_effects:
        return [(np.arange(0), model)] if temperature is None else [(np.arange(len(temperature)), model)]
    temp = np.asarray(temperature, dtype=float)
    out = []
    for t in np.unique(temp):
        out.append((np.flatnonzero(temp == t), replace(model, temperature_ref=float(t))))
    return out


def compensate(
    model: ArmModel,
    q_in: np.ndarray,
    wrench: np.ndarray,
    temperature: np.ndarray | None = None,
    target2base: np.ndarray | None = None,
) -> CompensationOutcome:
    """Commands that put the real TCP on its targets under ``wrench``.

    The targets are the nominal-FK TCP of ``q_in`` (the robot file's chain: what the
    user commanded), or the poses ``target2base`` when given.  The engine is the
    product's one exact compensation (:func:`problems.compensation.exact`) on the
    identified arm model; the equilibrium reached from the commands is solved
    independently and its TCP compared with the target.

    Parameters
    ----------
    model : ArmModel
    q_in : ndarray, shape (N, 6)
        Commands, rad: the nominal targets, and the start of the pose solve.
    wrench : ndarray, shape (6,) or (N, 6), or load rows (N, LOAD_SIZE)
        Base-frame wrench on the TCP ``[f (N); m (N*m)]``, or load vectors
        (:mod:`models.load`).
    temperature : ndarray, shape (N,), optional
        deg C (thermal models are evaluated per temperature).
    target2base : ndarray, shape (N, 4, 4), optional
        Target TCP poses, base frame (TCP-frame coordinates -> base-frame coordinates), m.

    Returns
    -------
    CompensationOutcome
        Status ``FAILED`` (naming the rows) when a row is not compensated to
        :data:`COMPENSATION_RESIDUAL_TOL` or its compensated command is outside the robot's
        joint limits (the reason names the row, the joint, the value and the limit).
    """
    q_in = np.atleast_2d(np.asarray(q_in, dtype=float))
    n = len(q_in)
    L = load_rows(np.asarray(wrench, dtype=float), n)
    target = nominal_tcp(model.nominal, q_in) if target2base is None else np.asarray(target2base, float)
    q_c = np.zeros_like(q_in)
    q_eq = np.zeros_like(q_in)
    res = np.zeros(n)
    rres = np.zeros(n)
    groups = _at_temperature(model, temperature)
    if len(groups[0][0]) == 0:
        groups = [(np.arange(n), model)]
    for idx, arm in groups:
        out = exact_compensation(arm, q_in[idx], L[idx], tol_m=COMPENSATION_RESIDUAL_TOL, target2base=target[idx])
        q_c[idx], q_eq[idx] = out.q_command, out.q_deflected
        res[idx], rres[idx] = out.error_norm_m, out.error_rad
    failure = _failure(model, q_c, res)
    if failure is not None:
        message, rows = failure
        return CompensationOutcome(q_c, q_eq, target, res, rres, CompensationStatus.FAILED, message, failed_rows=rows)
    return CompensationOutcome(
        q_c, q_eq, target, res, rres, CompensationStatus.OK, f"max model-predicted residual {res.max():.3g} m"
    )


def _failure(model: ArmModel, q_c: np.ndarray, res: np.ndarray) -> tuple[str, np.ndarray] | None:
    """Why the compensation failed and its failed rows: commands outside the joint limits, else residuals
    above :data:`COMPENSATION_RESIDUAL_TOL` (None: every row compensated)."""
    bad_rows = np.flatnonzero(~(np.isfinite(res) & (res <= COMPENSATION_RESIDUAL_TOL)))
    limit_msg, limit_rows = _outside_limits(model, q_c)
    if len(limit_rows):
        return (
            f"{len(limit_rows)} row(s) need a compensated command outside the joint limits ({limit_msg})",
            np.union1d(bad_rows, limit_rows),
        )
    if len(bad_rows):
        worst = int(bad_rows[np.argmax(np.where(np.isfinite(res[bad_rows]), res[bad_rows], np.inf))])
        return (
            f"{len(bad_rows)} row(s) not compensated to {COMPENSATION_RESIDUAL_TOL:g} m "
            f"(rows {', '.join(str(int(i)) for i in bad_rows[:10])}"
            f"{' ...' if len(bad_rows) > 10 else ''}; worst row {worst}: "
            f"{res[worst]:.3g} m): target at the edge of the identified model's reach "
            "or near a singularity",
            bad_rows,
        )
    return None


def _outside_limits(model: ArmModel, q: np.ndarray) -> tuple[str, np.ndarray]:
    """Rows (0-based) of ``q`` (N, 6), rad, outside the robot's joint limits, and a text naming
    the first: row, joint, value and the limit in the robot file's key and unit."""
    robot = model.nominal
    lo = q < robot.q_min - JOINT_LIMIT_TOL_RAD
    hi = q > robot.q_max + JOINT_LIMIT_TOL_RAD
    rows = np.flatnonzero(np.any(lo | hi, axis=1))
    if not len(rows):
        return "", rows
    i = int(rows[0])
    j = int(np.argmax(lo[i] | hi[i]))
    key = "q_min" if lo[i, j] else "q_max"
    joint = robot.joints[j]
    return (f"row {i}: joint {j + 1} = {q[i, j]:.6g} rad, beyond {joint.limit_text(key)} of robot '{robot.name}'"), rows


def check_command_limits(model: ArmModel, m: Measurements) -> None:
    """Refuse input commands outside the robot's joint limits, naming the file line, the column
    (as written, e.g. ``q1_deg``), the value in that column's unit and the limit in the robot
    file's key and unit (with its value in the column's unit when they differ)."""
    robot = model.nominal
    lo = m.q < robot.q_min - JOINT_LIMIT_TOL_RAD
    hi = m.q > robot.q_max + JOINT_LIMIT_TOL_RAD
    bad = np.flatnonzero(np.any(lo | hi, axis=1))
    if not len(bad):
        return
    i = int(bad[0])
    j = int(np.argmax(lo[i] | hi[i]))
    key = "q_min" if lo[i, j] else "q_max"
    col = _column(m, f"q{j + 1}")
    factor = m.units.get(col, 1.0)
    unit = "deg" if col.endswith("_deg") else "rad"
    limit = getattr(robot.joints[j], key)
    limit_text = robot.joints[j].limit_text(key)
    in_col = f" ({limit / factor:.6g} {unit})" if (unit == "deg") != (key in robot.joints[j].deg_keys) else ""
    raise TargetsError(
        f"{m.source}: line {int(m.line[i])}, column '{col}': command {m.q[i, j] / factor:.6g} {unit} "
        f"is {'below' if key == 'q_min' else 'above'} the joint-{j + 1} limit {limit_text}{in_col} of "
        f"robot '{robot.name}' ({len(bad)} row(s) outside the limits); the commands must be within "
        "the robot's joint limits"
    )


# ----------------------------------------------------------------------------------
# Targets of ``compplan compensate``
# ----------------------------------------------------------------------------------


def _column(m: Measurements, base: str) -> str:
    """The column of the file that holds quantity ``base`` (e.g. ``x_mm`` for ``x``)."""
    for col in m.units:
        if col == base or col.startswith(base + "_"):
            return col
    return base


def _target_positions(m: Measurements, frame: TargetsFrame) -> np.ndarray:
    """The ``x, y, z`` columns of a command file, (N, 3), m; :class:`TargetsError` without them."""
    if m.p is None:
        what = (
            "TCP target positions in the robot base frame"
            if frame is TargetsFrame.BASE
            else "target positions of the measured point in the measurement frame"
        )
        raise TargetsError(
            f"{m.source}: missing column(s) {', '.join(POSITION_COLUMNS)}: targets frame "
            f"'{frame.value}' needs the {what} (units by suffix, e.g. x_mm; "
            "docs/measurement-file.md)"
        )
    return np.asarray(m.p, dtype=float)


def _check_seeds(m: Measurements, target: np.ndarray, seed: np.ndarray, frame: TargetsFrame, what: str) -> None:
    """Refuse targets (N, 3) farther than :data:`TARGET_SEED_MAX_M` from the nominal position
    ``seed`` (N, 3) of the row's commands (base frame, m), naming the file line and the values."""
    gap = np.linalg.norm(target - seed, axis=1)
    bad = np.flatnonzero(~(gap <= TARGET_SEED_MAX_M))
    if not len(bad):
        return
    i = int(bad[np.argmax(gap[bad])]) if np.isfinite(gap[bad]).all() else int(bad[0])
    cols = [_column(m, c) for c in POSITION_COLUMNS]
    vals = ", ".join(f"{m.p[i, k] / m.units.get(cols[k], 1.0):g}" for k in range(3))
    raise TargetsError(
        f"{m.source}: line {int(m.line[i])}, columns {', '.join(cols)}: target ({vals}) is "
        f"{gap[i] * 1e3:.1f} mm from the {what} of the row's q1..q6 (more than "
        f"{TARGET_SEED_MAX_M * 1e3:g} mm; {len(bad)} row(s)): q1..q6 seed the solve and pick the "
        f"branch and must command a pose near the target; are the targets in the '{frame.value}' "
        "frame and in the declared unit?"
    )


def measured_point_model(model: ArmModel) -> ArmModel:
    """The model with its TCP on the measured point.

    The tool keeps the robot file's orientation (so target orientations taken from the
    nominal TCP apply unchanged) and its translation becomes
    :attr:`~models.arm.ArmModel.measured_point` (flange frame, m); the planning TCP
    correction is dropped (the measured point is the identified point itself).
    """
    T = np.array(model.nominal.tcp2flange, dtype=float)
    T[:3, 3] = model.measured_point
    return replace(model.with_tool(T), tcp_correction_m=np.zeros(3))


def _measured_point_loads(model: ArmModel, wrench: np.ndarray) -> np.ndarray:
    """Load rows (N, LOAD_SIZE) that apply the base-frame wrench (N, 6) [N; N*m] at the robot
    file's TCP to the arm whose TCP is the measured point (:func:`measured_point_model`).

    The force keeps acting at the file's TCP (as in the identification): its moment about
    the measured point gains ``(R a) x f``, with ``a`` the file's TCP relative to the
    measured point in the new TCP frame and ``R`` that frame's (deflected) rotation.  That
    term is exactly the payload slot of the load vector with a unit mass, centre of mass
    ``a`` and "gravity" ``f``.
    """
    F = np.atleast_2d(np.asarray(wrench, dtype=float))
    T = np.asarray(model.nominal.tcp2flange, dtype=float)
    a = T[:3, :3].T @ (T[:3, 3] - model.measured_point)
    L = np.zeros((len(F), LOAD_SIZE))
    L[:, 3:6] = F[:, 3:6]
    L[:, 12] = 1.0
    L[:, 13:16] = a
    L[:, 16:19] = F[:, 0:3]
    return L


def unobservable_in_base(model: ArmModel) -> list[str]:
    """Parameters the base frame cannot see for this model, in parameter order.

    With unregistered data the joint-1 offset and base height alias with the registration
    and the flange-side DH errors with the measured point: they are held at zero (their
    ``held`` reason names ``registration.`` or ``measured_point``, see
    :func:`~.identifiability.aliases_registration`) and the model is exact in the measurement frame only.
    Empty for registered data.
    """
    if model.registered:
        return []
    names = [n for n, why in model.held.items() if aliases_registration(why)]
    return sorted(names, key=lambda n: PARAM_NAMES.index(n) if n in PARAM_NAMES else len(PARAM_NAMES))


def alias_effect_m(
    model: ArmModel, names: list[str], q: np.ndarray, wrench: np.ndarray, temperature: np.ndarray | None = None
) -> dict[str, float]:
    """Largest TCP displacement (base frame, m) over the rows that one typical magnitude
    (``make_layout(robot).scale``) of each parameter in ``names`` would cause.

    From the identification model's measurement Jacobian with the measured point on the
    planning TCP and the measurement frame on the base frame (no registration, no drift).

    Parameters
    ----------
    q : ndarray, shape (N, 6)
        Commands, rad.
    wrench : ndarray, shape (N, 6)
        Base-frame wrench on the TCP, N and N*m.
    temperature : ndarray, shape (N,), optional
        deg C.
    """
    robot = model.nominal
    layout = make_layout(robot, model.const)
    theta = model.theta.copy()
    theta[GROUP_SLICES["reg.w"]] = 0.0
    theta[GROUP_SLICES["reg.t"]] = 0.0
    theta[GROUP_SLICES["tool.p"]] = np.asarray(robot.tcp2flange)[:3, 3] + np.asarray(model.tcp_correction_m)
    const = make_const(
        robot, np.eye(3), model.tau_scale, model.gravity_on, model.beams, model.knots, model.effect_const
    )
    m = Measurements(q=np.atleast_2d(q), wrench=np.atleast_2d(wrench), temperature=temperature)
    rows = make_rows(m, None, model.temperature_ref)
    ev = evaluator_for(robot, const)
    _p, q_eq = ev.measure(rows, theta, const)
    _p, J = ev.jacobian(rows, q_eq, theta, const)
    out: dict[str, float] = {}
    for name in names:
        i = PARAM_NAMES.index(name)
        d = J[:, i].reshape(-1, 3) * layout.scale[i]
        out[name] = float(np.linalg.norm(d, axis=1).max()) if len(d) else 0.0
    return out


def _typical(scale: float, unit: str) -> str:
    """A typical magnitude as text (``1 mm``, ``1 mrad``)."""
    if unit == "m":
        return f"{scale * 1e3:g} mm"
    if unit == "rad":
        return f"{scale * 1e3:g} mrad"
    return f"{scale:g} {unit}"


def base_frame_warning(
    model: ArmModel, q: np.ndarray, wrench: np.ndarray, temperature: np.ndarray | None = None
) -> str | None:
    """The caveat of base-frame targets for a model identified from unregistered data
    (:func:`unobservable_in_base`), with the size of each parameter's effect; None when
    there is none."""
    names = unobservable_in_base(model)
    if not names:
        return None
    layout = make_layout(model.nominal)
    size = alias_effect_m(model, names, q, wrench, temperature)
    parts = []
    for n in names:
        i = PARAM_NAMES.index(n)
        typical = _typical(float(layout.scale[i]), layout.units[i])
        mm = size[n] * 1e3 if size[n] > 1e-12 else 0.0
        # a DH angle error turns every frame after it, the tool included, by the same angle
        turn = f" and turns the tool by {typical}" if layout.units[i] == "rad" else ""
        parts.append(f"{n}: {typical} moves the TCP by up to {mm:.3g} mm{turn}")
    return (
        f"the model was identified from unregistered data: {', '.join(names)} cannot be told apart from "
        "the registration or the measured point, are held at their nominal values (zero for DH errors) "
        "and cannot be compensated in the base "
        f"frame (over these rows, {'; '.join(parts)}); the compensation is exact in the measurement frame "
        "(use --targets-frame measurement)"
    )


def compensate_targets(
    model: ArmModel, m: Measurements, frame: TargetsFrame | str = TargetsFrame.NOMINAL
) -> CompensationOutcome:
    """Compensated commands for the targets of a command file.

    Parameters
    ----------
    model : ArmModel
    m : Measurements
        ``q1..q6`` (rad: the commands, which seed the solve, pick the branch and give
        the target orientation as their nominal-FK TCP rotation), ``fx..mz`` (base
        frame), optional ``temperature`` and, for ``base`` and ``measurement``, the
        target positions ``x, y, z`` (m).
    frame : TargetsFrame or str
        ``nominal``: the nominal-FK TCP poses of the commands; ``base``: TCP positions
        in the robot base frame; ``measurement``: positions of the measured point in the
        measurement frame, mapped to the base frame by the inverse of
        ``model.base2meas()``, reached by the model whose tool is the measured point
        (:func:`measured_point_model`) -- exact in the measurement frame even for
        unregistered data.

    Returns
    -------
    CompensationOutcome
        ``WARNING`` (reason and ``warnings``) for base-frame targets of a model
        identified from unregistered data whose held parameters alias with the
        registration (:func:`base_frame_warning`); ``FAILED`` as :func:`compensate`.

    Raises
    ------
    TargetsError
        ``x, y, z`` missing for ``base``/``measurement``, a target too far from the
        nominal position of its row's commands (:data:`TARGET_SEED_MAX_M`), or a command
        outside the robot's joint limits (naming the line, column, value and limit).
    """
    frame = TargetsFrame(frame)
    check_command_limits(model, m)
    if frame is TargetsFrame.NOMINAL:
        out = compensate(model, m.q, m.wrench, m.temperature)
    else:
        p = _target_positions(m, frame)
        target = nominal_tcp(model.nominal, m.q)
        if frame is TargetsFrame.BASE:
            _check_seeds(m, p, target[:, :3, 3].copy(), frame, "nominal TCP")
            target[:, :3, 3] = p
            out = compensate(model, m.q, m.wrench, m.temperature, target2base=target)
        else:
            b2m = model.base2meas()
            p_base = (p - b2m[:3, 3]) @ b2m[:3, :3]  # R^T (p - t), row-wise
            point_in_tcp = np.linalg.solve(
                np.asarray(model.nominal.tcp2flange, dtype=float), np.append(model.measured_point, 1.0)
            )[:3]
            seed = target[:, :3, :3] @ point_in_tcp + target[:, :3, 3]  # (N, 3) base frame
            _check_seeds(m, p_base, seed, frame, "measured point of the nominal arm (mapped to the base frame)")
            target[:, :3, 3] = p_base
            out = compensate(
                measured_point_model(model),
                m.q,
                _measured_point_loads(model, m.wrench),
                m.temperature,
                target2base=target,
            )
    out.targets_frame = frame
    if frame is not TargetsFrame.MEASUREMENT:
        warn = base_frame_warning(model, m.q, m.wrench, m.temperature)
        if warn is not None:
            out.warnings.append(warn)
            if out.status is CompensationStatus.OK:
                out.status, out.reason = CompensationStatus.WARNING, warn
    return out


# ----------------------------------------------------------------------------------
# Checks
# ----------------------------------------------------------------------------------


def compensation_check(
    vr: Any, model: IdentifiedModel, n_poses: int = 40, force_N: float | None = None, seed: int = 99
) -> dict[str, Any]:
    """Simulate -> compensate -> re-measure on a virtual robot.

    New poses and loads (not those of the campaign) are drawn; the target is the
    nominal-FK TCP of each command; errors are the virtual robot's true TCP minus the
    target (base frame) before (command as is) and after compensation, and the same for
    the measured point in the measurement frame against its target mapped by the
    identified registration.  Figures in mm.
    """
    rng = np.random.default_rng(seed)
    q = vr.sample_poses(n_poses, rng, max_cond=COMPENSATION_CHECK_MAX_COND)
    camp = dict(vr.config.get("campaign", {}))
    mags = np.atleast_1d(camp.get("force_magnitudes_N", [100.0])) if force_N is None else [force_N]
    F = np.zeros((n_poses, 6))
    u = rng.normal(size=(n_poses, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    F[:, :3] = u * rng.choice(np.asarray(mags, dtype=float), n_poses)[:, None]
    F[::4] = 0.0
    temp = np.full(n_poses, model.temperature_ref)
    target = nominal_tcp(model.nominal, q)
    before = vr.tcp_error(q, F, target, temp)
    out = compensate(model, q, F, temp)
    after = vr.tcp_error(out.q_command, F, target, temp)
    # the same in the measurement frame: the measured point against its nominal target mapped
    # by the identified registration (what a tracker can check; free of the base-frame aliasing
    # of unregistered data)
    b2m = model.base2meas()
    p_t = (
        target[:, :3, :3] @ (np.linalg.solve(model.nominal.tcp2flange, np.append(model.measured_point, 1.0))[:3])
        + target[:, :3, 3]
    )
    p_t = p_t @ b2m[:3, :3].T + b2m[:3, 3]
    t0 = np.full(n_poses, model.time_ref[0])  # drift is zero at the campaign's first row
    before_m = vr.measure(q, F, t0, temp) - p_t
    after_m = vr.measure(out.q_command, F, t0, temp) - p_t

    def rms3(e: np.ndarray) -> float:
        """RMS of the 3-D norms of (N, 3) errors."""
        return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))

    rb, ra, rbm, ram = rms3(before), rms3(after), rms3(before_m), rms3(after_m)
    return {
        "n_poses": n_poses,
        "rms_before_mm": rb * 1e3,
        "rms_after_mm": ra * 1e3,
        "max_before_mm": float(np.linalg.norm(before, axis=1).max() * 1e3),
        "max_after_mm": float(np.linalg.norm(after, axis=1).max() * 1e3),
        "fraction_left": ra / rb if rb > 0 else 0.0,
        "meas_frame_rms_before_mm": rbm * 1e3,
        "meas_frame_rms_after_mm": ram * 1e3,
        "meas_frame_fraction_left": ram / rbm if rbm > 0 else 0.0,
        "status": out.status.value,
        "reason": out.reason,
        "metric": (
            "RMS of the 3-D TCP position error in the true base frame of the virtual robot; "
            "meas_frame_*: the measured point in the measurement frame against its nominal target "
            "mapped by the identified registration"
        ),
    }


def validate_on(model: IdentifiedModel, m: Measurements) -> dict[str, Any]:
    """Held-out validation on a separate measurement file (a given split).

    Returns per-axis RMS (mm) of ``predict(model) - measured`` and, for reference,
    of the nominal robot with the identified registration and measured point; and the
    Euclidean errors as calibration results are quoted (:mod:`.position_error`): ``euclidean``
    and ``euclidean_nominal`` (``mean_mm``, ``rms_mm``, ``max_mm``, ``max_line``, ``frame``).
    """
    if m.p is None:
        raise DataError(f"{m.source}: the validation file has no measured positions (x, y, z)")
    r = predict(model, m) - m.p
    nominal = IdentifiedModel(
        nominal=model.nominal,
        theta=make_layout(model.nominal).nominal.copy(),
        R0=model.R0,
        tau_scale=model.tau_scale,
        gravity_on=False,
        beams=model.beams,
        knots=model.knots,
        time_ref=model.time_ref,
        temperature_ref=model.temperature_ref,
    )
    for g in ("reg.w", "reg.t", "tool.p"):
        nominal.theta[GROUP_SLICES[g]] = model.theta[GROUP_SLICES[g]]
    r0 = predict(nominal, m) - m.p
    frame = frame_words(model)
    return {
        "file": m.source,
        "n_rows": m.n,
        "rms_mm": rms(r) * 1e3,
        "rms_nominal_mm": rms(r0) * 1e3,
        "max_mm": float(np.linalg.norm(r, axis=1).max() * 1e3),
        "frame": frame,
        "euclidean": position_errors(r, np.zeros_like(r), frame, m.line).to_mm_dict(),
        "euclidean_nominal": position_errors(r0, np.zeros_like(r0), frame, m.line).to_mm_dict(),
        "where_it_holds": where_it_holds(model, m.q, m.wrench, r),
    }
