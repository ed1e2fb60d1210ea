"""An arm model as a robot-file dictionary (the writing half of :mod:`models.arm_file`).

:func:`model_to_dict`: DH errors and stiffness folded into the ordinary joint fields, the rest in
the ``[identified]`` table (format :data:`MODEL_FORMAT`).  It reads an
:class:`~models.arm_model.ArmModel`'s attributes only, so that :meth:`ArmModel.robot` and the model
files share it without importing each other.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from . import effects as fx
from .effects import GROUP_SLICES
from .transforms import matrix_to_rotvec

if TYPE_CHECKING:  # pragma: no cover
    from .arm_model import ArmModel, CampaignFrame

#: Format version of the ``[identified]`` table written (2: the parameters' covariance, the
#: identified joint ranges and the campaigns; see ``docs/identification.md``).
MODEL_FORMAT = 2
#: Parameter groups folded into the ordinary joint fields of the robot file (DH errors, stiffness).
FOLDED_GROUPS = ("joint_offset.dtheta", "geometric.da", "geometric.dalpha", "geometric.dd", "stiffness.s")


def model_to_dict(model: ArmModel) -> dict[str, Any]:
    """Robot-file dictionary of an identified model.

    DH errors (``da, dalpha, dd, dtheta``) and stiffness go into the ordinary joint
    fields; the ``[identified]`` table holds the registration, measured point,
    effects with their parameters (SI), standard deviations, the nominal values the
    parameters refer to, and the constants of the effect formulas.
    """
    d = model.nominal.to_dict()
    d.pop("identified", None)
    _fold_joint_errors(model, d["joints"])
    b2m = model.base2meas()
    ident = {
        "format": MODEL_FORMAT,
        "registered": bool(model.registered),
        "base2meas": {
            "xyz": [float(v) for v in b2m[:3, 3]],
            "rotvec": [float(v) for v in matrix_to_rotvec(b2m[:3, :3])],
        },
        "measured_point": [float(v) for v in model.measured_point],
        "tcp_correction_m": [float(v) for v in model.tcp_correction_m],
        **({"torque_range_Nm": [float(v) for v in model.torque_range_Nm]} if model.torque_range_Nm is not None else {}),
        "effects": list(model.effects),
        "parameters": _effect_parameters(model),
        "std": {k: float(v) for k, v in model.std.items() if np.isfinite(v)},
        "held": dict(model.held),
        "constants": _constants(model),
        "nominal": _nominal(model),
    }
    _add_optional(model, ident)
    d["identified"] = ident
    return d


def _fold_joint_errors(model: ArmModel, joints: list[dict[str, Any]]) -> None:
    """Fold the DH errors and the stiffness factor into the robot file's joint fields (in place)."""
    r = model.nominal
    th = model.theta

    def g(name: str) -> np.ndarray:
        return th[GROUP_SLICES[name]]

    for i, j in enumerate(joints):
        j["a"] = float(r.a[i] + g("geometric.da")[i])
        j["alpha"] = float(r.alpha[i] + g("geometric.dalpha")[i])
        j["d"] = float(r.d[i] + g("geometric.dd")[i])
        j["theta_offset"] = float(r.theta_offset[i] + g("joint_offset.dtheta")[i])
        j["stiffness"] = float(r.stiffness[i] / (1.0 + g("stiffness.s")[i]))


def _effect_parameters(model: ArmModel) -> dict[str, Any]:
    """The ``parameters`` table: each effect's parameter groups not folded into the joints (SI)."""
    th = model.theta
    params: dict[str, Any] = {}
    for grp, eff, _names, _unit in fx.PARAMETER_GROUPS:
        if grp in FOLDED_GROUPS or grp.startswith("reg.") or grp == "tool.p":
            continue
        if eff not in model.effects and not (grp == "geometric.dbeta" and "geometric" in model.effects):
            continue
        params[grp] = [float(v) for v in th[GROUP_SLICES[grp]]]
    return params


def _constants(model: ArmModel) -> dict[str, Any]:
    """The ``constants`` table: the constants of the effect formulas."""
    return {
        "tau_scale_Nm": [float(v) for v in model.tau_scale],
        "gravity_on": bool(model.gravity_on),
        "beam_frames": [[float(v) for v in model.beams[i].reshape(-1)] for i in range(6)],
        "hardening_knots_Nm": [
            float(v)
            for v in (
                model.knots if model.knots is not None else np.outer(model.tau_scale, fx.HARDENING_KNOT_QUANTILES)
            ).reshape(-1)
        ],
        "time_ref_s": [float(model.time_ref[0]), float(model.time_ref[1])],
        "temperature_ref_C": float(model.temperature_ref),
        **(
            {
                "effect": {
                    k: [float(v) for v in np.asarray(a, dtype=float).reshape(-1)] for k, a in model.effect_const.items()
                }
            }
            if model.effect_const
            else {}
        ),
    }


def _nominal(model: ArmModel) -> dict[str, Any]:
    """The ``nominal`` table: the DH values and stiffness the parameters refer to."""
    r = model.nominal
    return {
        "a": r.a.tolist(),
        "alpha": r.alpha.tolist(),
        "d": r.d.tolist(),
        "theta_offset": r.theta_offset.tolist(),
        "stiffness": r.stiffness.tolist(),
    }


def _add_optional(model: ArmModel, ident: dict[str, Any]) -> None:
    """Add the fields written only when the model has them (noise, covariance, ranges, campaigns)."""
    if model.noise_sigma_m is not None:
        ident["noise_sigma_m"] = float(model.noise_sigma_m)
    if model.covariance is not None and model.covariance_names:
        C = np.asarray(model.covariance, dtype=float)
        ident["covariance"] = {
            "names": list(model.covariance_names),
            "matrix": [[float(v) for v in row] for row in 0.5 * (C + C.T)],
        }
    if model.residual_sigma_m is not None:
        ident["residual_sigma_m"] = float(model.residual_sigma_m)
    if model.sigma_scale != 1.0 or model.sigma_growth_rad_per_rad:
        ident["sigma_scale"] = float(model.sigma_scale)
        ident["sigma_growth_rad_per_rad"] = float(model.sigma_growth_rad_per_rad)
    if model.joint_range_rad is not None:
        ident["joint_range_rad"] = [[float(v) for v in row] for row in np.asarray(model.joint_range_rad)]
    if model.campaigns:
        ident["campaigns"] = [campaign_to_dict(c) for c in model.campaigns]


def campaign_to_dict(c: CampaignFrame) -> dict[str, Any]:
    out: dict[str, Any] = {
        "name": c.name,
        "base2meas": {
            "xyz": [float(v) for v in c.base2meas[:3, 3]],
            "rotvec": [float(v) for v in matrix_to_rotvec(c.base2meas[:3, :3])],
        },
        "rows": int(c.n_rows),
        "data": str(c.data),
    }
    if c.registration_cov is not None:
        out["registration_cov"] = [[float(v) for v in row] for row in np.asarray(c.registration_cov)]
    if c.registration_cross_cov is not None:
        out["registration_cross_cov"] = [[float(v) for v in row] for row in np.asarray(c.registration_cross_cov)]
    return out
