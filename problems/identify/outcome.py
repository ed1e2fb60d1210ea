"""Step 6 of an identification: its result.

:func:`build_result` computes the covariance of the free parameters, builds the identified
:class:`~models.arm.ArmModel`, its parameter table, the diagnostics of the final residual and the
verdict (ok / unexplained structure / not converged / implausible / does not generalise), and
summarises the joint error maps.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from models import effects as fx
from models.effects import GROUP_SLICES, N_PARAMS, PARAM_NAMES, ModelLayout, get_const
from models.effects.joint_error_map import MAP_CONST_KEYS
from models.plausibility import implausible_geometry

from ..measurements import Measurements
from .diagnostics import UNEXPLAINED_MIN_FRACTION, UNEXPLAINED_RMS_RATIO, diagnose, structure_left
from .fit_setup import FitSetup
from .evaluation import FitProblem
from .identifiability import Known, priority_order
from .lsq import ModelFit, rms, weighted_jacobian, weighted_residual
from .map_candidate import MAP_CHANNEL_GROUPS
from .map_summary import ErrorMapSummary, summarise_maps
from .orientation import orientation_gain
from .results import (
    Diagnostic,
    IdentificationResult,
    IdentifiedModel,
    IdentifyStatus,
    ParameterEstimate,
    ParameterStatus,
)
from .selection import SelectionRun, SelectionState
from .sigma_calibration import calibrate_sigma
from .selection_scores import Score


#: Parameter groups of the registration and the measured point (and frame).
REGISTRATION_GROUPS = ("reg.t", "reg.w", "tool.p", "tool.r")
#: An identification whose cross-validated (held-out) RMS after exceeds this multiple of the nominal
#: model's is refused as a model to use: status ``does_not_generalise`` (it fits noise, not the arm).
#: A 20 % margin: at the noise floor the two differ by chance by a few per cent.
CV_WORSE_RATIO = 1.2


def _covariance(
    prob: FitProblem, fit: ModelFit, free: Sequence[int], full: list[np.ndarray] | None = None
) -> tuple[np.ndarray, float]:
    """Standard deviations (N_PARAMS,), SI (NaN where not free), from ``s^2 (J^T J)^-1``,
    and the condition number of the column-normalised Jacobian; the whole covariance
    (N_PARAMS, N_PARAMS), SI, zero where not free, is appended to ``full`` when given."""
    r_w = weighted_residual(prob, fit.pred, fit.inliers)
    n_res, k_f = r_w.size, len(free)
    s2 = float(r_w @ r_w) / max(n_res - k_f, 1)
    Js = weighted_jacobian(prob, fit.J, fit.inliers, np.asarray(free, dtype=int))
    std = np.full(N_PARAMS, np.nan)
    cond = float("nan")
    if k_f:
        G = Js.T @ Js
        try:
            cov = np.linalg.inv(G) * s2
            std[free] = np.sqrt(np.maximum(np.diag(cov), 0.0)) * prob.layout.scale[free]
            if full is not None:
                C = np.zeros((N_PARAMS, N_PARAMS))
                sc = prob.layout.scale[free]
                C[np.ix_(free, free)] = cov * np.outer(sc, sc)
                full.append(C)
        except np.linalg.LinAlgError:
            pass
        Jn = Js / np.maximum(np.linalg.norm(Js, axis=0), 1e-300)
        sv = np.linalg.svd(Jn, compute_uv=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    return std, cond


def _effect_of(i: int) -> str:
    """Effect (or declared group) of parameter index ``i``."""
    for g, e, _names, _u in fx.PARAMETER_GROUPS:
        s = GROUP_SLICES[g]
        if s.start <= i < s.stop:
            return e
    return "?"


def _parameter_table(
    layout: ModelLayout, fit: ModelFit, order: Sequence[int], std: np.ndarray, active: Sequence[str], registered: bool
) -> list[ParameterEstimate]:
    """Every parameter of the model (priority order), with value, std, unit and status."""
    out = []
    order_set = set(order)
    for i in order:
        name = PARAM_NAMES[i]
        if i in fit.held:
            out.append(
                ParameterEstimate(
                    name, _effect_of(i), float(fit.theta[i]), None, layout.units[i], ParameterStatus.HELD, fit.held[i]
                )
            )
        else:
            out.append(
                ParameterEstimate(
                    name,
                    _effect_of(i),
                    float(fit.theta[i]),
                    float(std[i]) if np.isfinite(std[i]) else None,
                    layout.units[i],
                    ParameterStatus.FREE,
                )
            )
    known = Known.of(registered)
    if known.registration or known.measured_point:
        for i in layout.indices(REGISTRATION_GROUPS):
            if i not in order_set:
                out.insert(
                    0,
                    ParameterEstimate(
                        PARAM_NAMES[i],
                        _effect_of(i),
                        float(fit.theta[i]),
                        None,
                        layout.units[i],
                        ParameterStatus.HELD,
                        "data declared registered" if known else f"declared known ({known.describe()})",
                    ),
                )
    return out


def _build_model(
    run: SelectionRun,
    st: SelectionState,
    s: FitSetup,
    std: np.ndarray,
    free: Sequence[int],
    order: Sequence[int],
    sigma_noise: float | None,
) -> IdentifiedModel:
    """The identified :class:`~models.arm.ArmModel`."""
    fit, robot = st.fit, run.robot
    rows = st.prob.rows[fit.inliers]
    te, tg, _q = st.prob.ev.call("torques", rows[:, 0:6], rows[:, 6:12], rows[:, 13:14], fit.theta, st.prob.const)
    torque_range = np.max(np.abs(np.asarray(te).T + np.asarray(tg).T), axis=0)
    return IdentifiedModel(
        nominal=robot,
        theta=fit.theta.copy(),
        R0=s.R0,
        tau_scale=s.tau_s,
        gravity_on=bool(get_const(st.prob.const, "gravity.on")[0] > 0.5),
        beams=fx.beam_frames(robot),
        knots=get_const(st.prob.const, "hardening.knots").reshape(6, fx.N_KNOTS).copy(),
        time_ref=s.t_ref,
        temperature_ref=s.temp_ref,
        effects=list(st.active),
        registered=bool(run.registered),
        std={PARAM_NAMES[i]: float(std[i]) for i in free},
        noise_sigma_m=sigma_noise,
        held={PARAM_NAMES[i]: r for i, r in fit.held.items() if i in order},
        tcp_correction_m=(
            fit.theta[GROUP_SLICES["tool.p"]] - robot.tcp2flange[:3, 3] if bool(run.registered) else np.zeros(3)
        ),
        torque_range_Nm=torque_range,
        effect_const=(
            {k: get_const(st.prob.const, k).copy() for k in MAP_CONST_KEYS} if "joint_error_map" in st.active else {}
        ),
    )


def _verdict(
    diags: Sequence[Diagnostic], score_f: Score, sigma_noise: float | None, stop_reason: str, converged: bool
) -> tuple[IdentifyStatus, str, dict[str, Any]]:
    """Status, reason and the ``unexplained`` record of the final residual."""
    top = structure_left(diags)
    above_floor = sigma_noise is not None and score_f.cv_rms_m > UNEXPLAINED_RMS_RATIO * sigma_noise
    # strong: any significant diagnostic (the unspecific per-pose one too) explains the threshold
    strong = any(d.significant and d.explained_fraction >= UNEXPLAINED_MIN_FRACTION for d in diags)
    if strong or above_floor or top is not None:
        if top is None:
            top = diags[0]
        weak = not (strong or above_floor)
        unexplained = {
            "present": True,
            "diagnostic": f"residual vs {top.variable}",
            "variable": top.variable,
            "explained_fraction": top.explained_fraction,
            "p_value": top.p_value,
            "description": top.description,
            "weak": weak,
            "rms_over_noise": (score_f.cv_rms_m / sigma_noise) if sigma_noise else None,
            "message": (
                f"{'weak ' if weak else ''}structure remains that no library effect explains: the residual "
                f"depends on {top.variable} (cross-validated regression explains "
                f"{100 * top.explained_fraction:.0f} % of its variance, p = {top.p_value:.2g})"
                + (f"; held-out RMS is {score_f.cv_rms_m / sigma_noise:.2f} x the noise floor" if sigma_noise else "")
            ),
        }
        status = IdentifyStatus.OK if weak else IdentifyStatus.UNEXPLAINED
        reason = stop_reason + "; " + unexplained["message"] if weak else unexplained["message"]
    else:
        unexplained = {
            "present": False,
            "diagnostic": None,
            "variable": None,
            "weak": False,
            "explained_fraction": (diags[0].explained_fraction if diags else None),
            "message": (
                "no diagnostic shows structure the model leaves unexplained (cross-validated "
                "nonparametric fits of the residual on each joint angle, per axis and through "
                "each joint, and on time, load, temperature, position and pose)"
            ),
        }
        status = IdentifyStatus.OK
        reason = stop_reason
    if not converged:
        status = IdentifyStatus.NOT_CONVERGED
        reason = "the final least-squares fit did not converge"
    return status, reason, unexplained


def build_result(
    run: SelectionRun,
    st: SelectionState,
    s: FitSetup,
    score_b: Score,
    sat_info: dict[str, Any],
    noise_src: str,
    notes: list[str],
) -> IdentificationResult:
    """Step 6: covariance, model, parameter table, diagnostics and verdict."""
    prob, fit, m = st.prob, st.fit, st.prob.m
    score_f, free_f = run.score(prob, fit, st.active)
    order_f = priority_order(prob.layout, st.active, run.registered)
    cov: list[np.ndarray] = []
    std, cond = _covariance(prob, fit, free_f, cov)
    R_un = fit.residual(prob)
    model = _build_model(run, st, s, std, free_f, order_f, run.sigma_noise)
    if cov:
        free_idx = np.asarray(free_f, dtype=int)
        model.covariance = cov[0][np.ix_(free_idx, free_idx)].copy()
        model.covariance_names = [PARAM_NAMES[i] for i in free_idx]
    r_in = R_un[fit.inliers & prob.pos]
    if r_in.size:
        model.residual_sigma_m = float(np.sqrt(np.sum(r_in**2) / max(r_in.size - len(free_f), 1)))
    q_used = prob.m.q[fit.inliers]
    model.joint_range_rad = np.column_stack([q_used.min(axis=0), q_used.max(axis=0)]) if len(q_used) else None
    calibration = calibrate_sigma(prob, fit, free_f) if cov else None
    if calibration is not None:
        model.sigma_scale, model.sigma_growth_rad_per_rad = calibration.scale, calibration.growth_rad_per_rad
        notes = [*notes, calibration.text()]
    params = _parameter_table(prob.layout, fit, order_f, std, st.active, run.registered)
    diags = diagnose(prob, fit, run.robot)  # diagnostics on the final residual (inliers)
    status, reason, unexplained = _verdict(diags, score_f, run.sigma_noise, st.stop_reason, fit.converged)
    implausible = implausible_geometry(run.robot, fit.theta, [i for i in fit.held])
    if implausible is not None and status is not IdentifyStatus.NOT_CONVERGED:
        status, reason = IdentifyStatus.IMPLAUSIBLE, implausible
    elif status is not IdentifyStatus.NOT_CONVERGED and score_f.cv_rms_m > CV_WORSE_RATIO * score_b.cv_rms_m:
        status = IdentifyStatus.DOES_NOT_GENERALISE
        reason = (
            f"the identified model predicts held-out poses worse than the nominal one (cross-validated RMS "
            f"{score_b.cv_rms_m * 1e3:.4g} -> {score_f.cv_rms_m * 1e3:.4g} mm per axis): {s.n_poses} poses are "
            f"too few for {len(free_f)} free parameters; do not use this model, measure more poses spread "
            "over the workspace"
        )
    pos = prob.pos
    R_un_all = R_un
    R_un = R_un_all[pos]
    excluded = _excluded_rows(m, fit, R_un_all, pos)
    ident, orient = _identifiability_record(run, s, prob, fit, free_f, order_f, cond, sat_info)
    ident["sigma_calibration"] = calibration.to_dict() if calibration is not None else None
    res_b_all = s.fit_b.residual(prob)
    res_b = res_b_all[pos]
    inl = fit.inliers[pos]
    return IdentificationResult(
        status=status,
        reason=reason,
        model=model,
        effects_added=st.effects_added,
        history=st.history,
        parameters=params,
        rms_before_m=rms(res_b[inl]),
        rms_after_m=rms(R_un[inl]),
        cv_rms_before_m=score_b.cv_rms_m,
        cv_rms_after_m=score_f.cv_rms_m,
        noise_sigma_m=run.sigma_noise,
        noise_source=noise_src,
        excluded=excluded,
        unexplained=unexplained,
        diagnostics=diags,
        identifiability=ident,
        residual_before=res_b,
        residual_after=R_un,
        inliers=inl,
        data=m.subset(pos),
        notes=notes,
        error_maps=_error_maps(st, cov[0] if cov else None),
        orientation=orient,
    )


def _error_maps(st: SelectionState, cov: np.ndarray | None) -> list[ErrorMapSummary]:
    """Summaries of the identified joint error maps (empty without ``joint_error_map``)."""
    if "joint_error_map" not in st.active:
        return []
    prob, fit = st.prob, st.fit
    mask = fit.inliers
    n = int(mask.sum())
    J3 = fit.J[np.repeat(mask, 3)]
    lever = np.zeros((n, 6, len(MAP_CHANNEL_GROUPS)))
    for k, group in enumerate(MAP_CHANNEL_GROUPS):
        for j in range(6):
            lever[:, j, k] = np.linalg.norm(J3[:, GROUP_SLICES[group].start + j].reshape(n, 3), axis=1)
    return summarise_maps(
        fit.theta,
        cov,
        get_const(prob.const, "error_map.freq"),
        get_const(prob.const, "error_map.range"),
        lever,
        prob.m.q[mask],
    )


def _excluded_rows(m: Measurements, fit: ModelFit, R_un_all: np.ndarray, pos: np.ndarray) -> list[dict[str, Any]]:
    """The rows the robust fit excluded: row, file line, residual (mm) and kind (position or orientation)."""
    return [
        {
            "row": int(i),
            "line": int(m.line[i]),
            "residual_mm": float(np.linalg.norm(R_un_all[i]) * 1e3),
            "residual_xyz_mm": (R_un_all[i] * 1e3).tolist(),
            "kind": "position" if pos[i] else "orientation",
        }
        for i in np.flatnonzero(~fit.inliers)
    ]


def _identifiability_record(
    run: SelectionRun,
    s: FitSetup,
    prob: FitProblem,
    fit: ModelFit,
    free_f: Sequence[int],
    order_f: Sequence[int],
    cond: float,
    sat_info: dict[str, Any],
) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The ``identifiability`` record of the result (rank, condition number, rows, the saturated
    model, the held parameters, the known parts) and, with orientation rows, the ``orientation``
    record it also holds."""
    pos = prob.pos
    ident = {
        "rank": len(free_f),
        "condition_number": cond,
        "n_rows": int(pos.sum()),
        "n_inliers": int(fit.inliers[pos].sum()),
        "n_poses": int(s.n_poses),
        "saturated_model": sat_info,
        "held": [
            {"name": PARAM_NAMES[i], "effect": _effect_of(i), "reason": r} for i, r in fit.held.items() if i in order_f
        ],
        "known": Known.of(run.registered).describe(),
    }
    orient: dict[str, Any] | None = None
    if (~pos).any():
        res_b_all = s.fit_b.residual(prob)
        R_un_all = fit.residual(prob)
        rot = ~pos & fit.inliers
        orient = {
            "rms_before_rad": rms(res_b_all[~pos][fit.inliers[~pos]]),
            "rms_after_rad": rms(R_un_all[rot]),
            "n_rows": int((~pos).sum()),
            "identifiable_thanks_to_orientation": orientation_gain(prob, fit, order_f),
        }
        ident["orientation"] = orient
    return ident, orient
