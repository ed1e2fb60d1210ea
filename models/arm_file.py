"""Model files: an :class:`~models.arm.ArmModel` as a robot file with an ``[identified]`` table.

DH errors (``da, dalpha, dd, dtheta``) and stiffness are folded into the ordinary joint
fields, so the file is a valid robot file for any tool; the ``[identified]`` table holds
the registration, the measured point, the active effects with their parameters (SI,
by parameter group, see ``docs/identification.md``), standard deviations, the nominal
values the parameters refer to, and the constants of the effect formulas.  A plain
robot file (no ``[identified]`` table) reads as the nominal model.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from . import effects as fx
from .arm_dict import model_to_dict
from .arm_model import ArmModel, CampaignFrame
from .effects import GROUP_SLICES, LIBRARY, make_layout
from .robot import BUILTIN_ROBOTS, Robot, RobotFileError, load_robot, robot_from_dict
from .transforms import rotvec_to_matrix

#: Format versions read (a format-1 file has no covariance: no predicted sigma).
MODEL_FORMATS_READ = (1, 2)
#: A covariance read is symmetric when ``|C_ij - C_ji| <= tol sqrt(C_ii C_jj)``.
COVARIANCE_SYMMETRY_TOL = 1e-9
#: A variance whose standard deviation exceeds this many typical magnitudes of its parameter
#: (``ParamGroup.scale``) is refused at load: no identification writes it (the real UR5 grid's
#: least determined parameters reach about 1e6; a tampered 1e30 is far beyond).  Parameters with a
#: standard deviation above ``problems.identify.uncertainty.UNDETERMINED_STD_RATIO`` typical
#: magnitudes are read, and left out of the predicted sigma.
COVARIANCE_MAX_STD_RATIO = 1e8
#: A covariance read must be positive semi-definite: its correlations at most ``1 + tol`` and the
#: smallest eigenvalue of its correlation matrix at least ``-tol`` (rounding of the written floats).
COVARIANCE_PSD_TOL = 1e-6


def _matrix(where: str, key: str, v: Any, rows: int, cols: int) -> np.ndarray:
    if not isinstance(v, list) or len(v) != rows:
        raise RobotFileError(f"{where}: [identified] key '{key}' must be a list of {rows} rows of {cols} numbers")
    return np.array([_nums(where, f"{key}[{i}]", r, cols) for i, r in enumerate(v)], dtype=float).reshape(rows, cols)


def _covariance_from(where: str, ident: dict[str, Any], nominal: Robot) -> tuple[np.ndarray | None, list[str]]:
    """The ``[identified.covariance]`` table: names (known parameters, no repeats) and a plausible
    covariance of them (:func:`check_covariance`)."""
    cov = ident.get("covariance")
    if cov is None:
        return None, []
    names = cov["names"]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise RobotFileError(f"{where}: [identified.covariance] key 'names' must be a list of parameter names")
    unknown = [n for n in names if n not in fx.PARAM_NAMES]
    if unknown or len(set(names)) != len(names):
        raise RobotFileError(
            f"{where}: [identified.covariance] names {unknown or 'repeated'}: expected distinct parameter names "
            "(docs/identification.md)"
        )
    C = _covariance_matrix(where, cov["matrix"], len(names))
    scale = make_layout(nominal).scale[[fx.PARAM_NAMES.index(n) for n in names]]
    check_covariance(where, C, list(names), scale)
    return C, list(names)


def _covariance_matrix(where: str, v: Any, k: int) -> np.ndarray:
    """``covariance.matrix``: k rows of k numbers (finite or not: :func:`check_covariance` names the entry)."""
    ok = isinstance(v, list) and len(v) == k
    ok = ok and all(isinstance(r, list) and len(r) == k for r in v)
    ok = ok and all(isinstance(x, (int, float)) and not isinstance(x, bool) for r in v for x in r)
    if not ok:
        raise RobotFileError(
            f"{where}: [identified] key 'covariance.matrix' must be a list of {k} rows of {k} numbers "
            "(one row and column per name)"
        )
    return np.array(v, dtype=float).reshape(k, k)


def check_covariance(where: str, C: np.ndarray, names: list[str], scale: np.ndarray) -> None:
    """Refuse a covariance no identification writes, naming the file and the entry.

    Finite; a non-negative variance whose standard deviation is at most
    :data:`COVARIANCE_MAX_STD_RATIO` typical magnitudes of its parameter (``scale``,
    :class:`~models.effects.ParamGroup`); symmetric (:data:`COVARIANCE_SYMMETRY_TOL`); no
    correlation beyond 1 (:data:`COVARIANCE_PSD_TOL`); positive semi-definite (the smallest
    eigenvalue of the correlation matrix at least ``-COVARIANCE_PSD_TOL``, else the parameters of
    its eigenvector are named).  Raises :class:`RobotFileError`.
    """
    head = f"{where}: [identified.covariance] matrix"
    bad = np.argwhere(~np.isfinite(C))
    if len(bad):
        i, j = bad[0]
        raise RobotFileError(f"{head} entry ({names[i]}, {names[j]}) is {C[i, j]}: expected a finite number")
    d = np.diag(C)
    for i in np.flatnonzero(d < 0):
        raise RobotFileError(f"{head} variance of {names[i]} is {d[i]:.6g}: expected >= 0")
    ratio = np.sqrt(d) / scale
    for i in np.flatnonzero(ratio > COVARIANCE_MAX_STD_RATIO):
        raise RobotFileError(
            f"{head} variance of {names[i]} is {d[i]:.6g}: a standard deviation of {np.sqrt(d[i]):.3g}, "
            f"{ratio[i]:.3g} times its typical magnitude {scale[i]:.3g}; expected at most "
            f"{COVARIANCE_MAX_STD_RATIO:g} times (not a covariance an identification writes)"
        )
    sd = np.sqrt(d)
    outer = np.outer(sd, sd)
    asym = np.abs(C - C.T) > COVARIANCE_SYMMETRY_TOL * outer + 1e-300
    if asym.any():
        i, j = np.argwhere(asym)[0]
        raise RobotFileError(
            f"{head} is not symmetric: entry ({names[i]}, {names[j]}) is {C[i, j]:.6g} but "
            f"({names[j]}, {names[i]}) is {C[j, i]:.6g}"
        )
    over = np.abs(C) > outer * (1.0 + COVARIANCE_PSD_TOL) + 1e-300
    if over.any():
        i, j = np.argwhere(over)[0]
        raise RobotFileError(
            f"{head} entry ({names[i]}, {names[j]}) is {C[i, j]:.6g}: a correlation of "
            f"{C[i, j] / max(outer[i, j], 1e-300):.3g}, beyond 1 (not positive semi-definite)"
        )
    inv = np.where(sd > 0, 1.0 / np.where(sd > 0, sd, 1.0), 0.0)
    w, V = np.linalg.eigh(0.5 * (C + C.T) * np.outer(inv, inv))
    if len(w) and w[0] < -COVARIANCE_PSD_TOL:
        top = np.argsort(np.abs(V[:, 0]))[::-1][:3]
        raise RobotFileError(
            f"{head} is not positive semi-definite: the correlation matrix has eigenvalue {w[0]:.3g} "
            f"(along {', '.join(names[t] for t in top)}); expected >= {-COVARIANCE_PSD_TOL:g}"
        )


def _effect_constants(where: str, c: dict[str, Any]) -> dict[str, np.ndarray]:
    """``[identified.constants.effect]``: the data-dependent constant blocks of effects by key."""
    out = {}
    for key, vals in dict(c.get("effect", {})).items():
        if key not in fx.CONST_SLICES or key.split(".")[0] in ("dh", "tool", "gravity", "compliance0", "tau_scale"):
            raise RobotFileError(f"{where}: [identified.constants.effect] unknown constant block '{key}'")
        sl = fx.CONST_SLICES[key]
        out[key] = _nums(where, f"constants.effect.{key}", vals, sl.stop - sl.start)
    return out


def _where_it_holds(where: str, ident: dict[str, Any], nominal: Robot) -> dict[str, Any]:
    """The format-2 keys as :class:`ArmModel` fields: covariance and its names, the residual's sigma,
    the identified joint ranges and the campaigns (absent keys: a format-1 file, no sigma)."""
    cov, cov_names = _covariance_from(where, ident, nominal)
    return {
        "covariance": cov,
        "covariance_names": cov_names,
        "residual_sigma_m": (
            float(_nums(where, "residual_sigma_m", [ident["residual_sigma_m"]], 1)[0])
            if "residual_sigma_m" in ident
            else None
        ),
        "joint_range_rad": _joint_range(where, ident),
        **_sigma_calibration(where, ident),
        "campaigns": _campaigns_from(where, ident, cov, cov_names),
    }


def _sigma_calibration(where: str, ident: dict[str, Any]) -> dict[str, float]:
    """``sigma_scale`` (> 0) and ``sigma_growth_rad_per_rad`` (>= 0): both or neither (1 and 0)."""
    keys = ("sigma_scale", "sigma_growth_rad_per_rad")
    given = [k for k in keys if k in ident]
    if not given:
        return {}
    if len(given) == 1:
        raise RobotFileError(
            f"{where}: [identified] key '{given[0]}' needs '{(set(keys) - set(given)).pop()}' beside it"
        )
    scale = float(_nums(where, keys[0], [ident[keys[0]]], 1)[0])
    growth = float(_nums(where, keys[1], [ident[keys[1]]], 1)[0])
    if scale <= 0 or growth < 0:
        raise RobotFileError(
            f"{where}: [identified] sigma_scale = {scale:g}, sigma_growth_rad_per_rad = {growth:g}: expected a "
            "positive scale and a growth >= 0"
        )
    return {"sigma_scale": scale, "sigma_growth_rad_per_rad": growth}


def _joint_range(where: str, ident: dict[str, Any]) -> np.ndarray | None:
    """``joint_range_rad``: 6 rows ``[lo, hi]``, rad, lo <= hi (None when absent)."""
    if "joint_range_rad" not in ident:
        return None
    r = _matrix(where, "joint_range_rad", ident["joint_range_rad"], 6, 2)
    if (r[:, 0] > r[:, 1]).any():
        raise RobotFileError(f"{where}: [identified] key 'joint_range_rad' must hold [lo, hi] rows with lo <= hi")
    return r


def _cross_cov(where: str, key: str, v: Any, reg: np.ndarray | None, cov: np.ndarray | None, k: int) -> np.ndarray:
    """``registration_cross_cov``: 6 rows of k numbers, each a covariance its two variances allow."""
    if reg is None or cov is None:
        raise RobotFileError(f"{where}: [identified] key '{key}' needs 'registration_cov' and the model's covariance")
    X = _matrix(where, key, v, 6, k)
    bound = np.sqrt(np.outer(np.maximum(np.diag(reg), 0.0), np.maximum(np.diag(cov), 0.0)))
    bad = np.argwhere(np.abs(X) > (1.0 + COVARIANCE_PSD_TOL) * bound + 1e-300)
    if len(bad):
        a, b = bad[0]
        raise RobotFileError(
            f"{where}: [identified] key '{key}' entry [{a}][{b}] = {X[a, b]:g} exceeds the product of the two "
            f"standard deviations ({bound[a, b]:g}): not a covariance"
        )
    return X


def _campaigns_from(
    where: str, ident: dict[str, Any], cov: np.ndarray | None = None, cov_names: list[str] | None = None
) -> list[CampaignFrame]:
    out = []
    for k, c in enumerate(ident.get("campaigns", [])):
        key = f"campaigns[{k}]"
        if not isinstance(c, dict) or not isinstance(c.get("name"), str) or not c["name"]:
            raise RobotFileError(f"{where}: [identified] key '{key}' must be a table with a non-empty 'name'")
        T = np.eye(4)
        T[:3, :3] = rotvec_to_matrix(_nums(where, f"{key}.base2meas.rotvec", c["base2meas"]["rotvec"], 3))
        T[:3, 3] = _nums(where, f"{key}.base2meas.xyz", c["base2meas"]["xyz"], 3)
        rc = c.get("registration_cov")
        reg = None if rc is None else _matrix(where, f"{key}.registration_cov", rc, 6, 6)
        xc = c.get("registration_cross_cov")
        k = len(cov_names or [])
        cross = None if xc is None else _cross_cov(where, f"{key}.registration_cross_cov", xc, reg, cov, k)
        out.append(
            CampaignFrame(
                name=c["name"],
                base2meas=T,
                n_rows=int(c.get("rows", 0)),
                data=str(c.get("data", "")),
                registration_cov=reg,
                registration_cross_cov=cross,
            )
        )
    names = [c.name for c in out]
    if len(set(names)) != len(names):
        raise RobotFileError(f"{where}: [identified] campaigns {names}: names must be distinct")
    return out


def _nums(where: str, key: str, v: Any, n: int) -> np.ndarray:
    if (
        not isinstance(v, list)
        or len(v) != n
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
    ):
        raise RobotFileError(f"{where}: [identified] key '{key}' must be a list of {n} numbers")
    a = np.array(v, dtype=float)
    if not np.all(np.isfinite(a)):
        raise RobotFileError(f"{where}: [identified] key '{key}' must be finite")
    return a


def model_from_robot(robot: Robot, where: str = "model") -> ArmModel:
    """An :class:`ArmModel` from a robot (plain file = nominal model, no effects)."""
    ident = robot.identified
    if ident is None:
        return _nominal_model(robot)
    try:
        return _identified_model(robot, ident, where)
    except RobotFileError:
        raise
    except KeyError as exc:
        raise RobotFileError(f"{where}: [identified] table is missing key {exc}") from None
    except (TypeError, AttributeError, ValueError) as exc:
        raise RobotFileError(f"{where}: [identified] table is malformed ({exc})") from None


def _nominal_model(robot: Robot) -> ArmModel:
    """The nominal model of a plain robot file (no effects, registered)."""
    layout = make_layout(robot)
    return ArmModel(
        nominal=robot,
        theta=layout.nominal.copy(),
        R0=np.eye(3),
        tau_scale=np.ones(6),
        gravity_on=False,
        beams=fx.beam_frames(robot),
        registered=True,
    )


def _nominal_robot(robot: Robot, ident: dict[str, Any], where: str) -> Robot:
    """The nominal robot the ``[identified]`` parameters refer to (after checking the table's format)."""
    fmt = ident.get("format")
    if fmt not in MODEL_FORMATS_READ:
        raise RobotFileError(
            f"{where}: [identified] format {fmt!r} is not supported (expected one of {list(MODEL_FORMATS_READ)})"
        )
    nom = ident["nominal"]
    d = robot.to_dict()
    d.pop("identified", None)
    for key in ("a", "alpha", "d", "theta_offset", "stiffness"):
        vals = _nums(where, f"nominal.{key}", nom[key], 6)
        for i, j in enumerate(d["joints"]):
            j[key] = float(vals[i])
    return robot_from_dict(d, where)


def _identified_theta(
    robot: Robot, nominal: Robot, ident: dict[str, Any], where: str
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Parameter vector, base-to-measurement rotation (3, 3) and effects of an ``[identified]`` table."""
    theta = make_layout(nominal).nominal.copy()
    # folded parameters: identified - nominal
    theta[GROUP_SLICES["geometric.da"]] = robot.a - nominal.a
    theta[GROUP_SLICES["geometric.dalpha"]] = robot.alpha - nominal.alpha
    theta[GROUP_SLICES["geometric.dd"]] = robot.d - nominal.d
    theta[GROUP_SLICES["joint_offset.dtheta"]] = robot.theta_offset - nominal.theta_offset
    theta[GROUP_SLICES["stiffness.s"]] = nominal.stiffness / robot.stiffness - 1.0
    b2m = ident["base2meas"]
    R0 = rotvec_to_matrix(_nums(where, "base2meas.rotvec", b2m["rotvec"], 3))
    theta[GROUP_SLICES["reg.t"]] = _nums(where, "base2meas.xyz", b2m["xyz"], 3)
    theta[GROUP_SLICES["tool.p"]] = _nums(where, "measured_point", ident["measured_point"], 3)
    effects = list(ident.get("effects", []))
    for e in effects:
        if e not in LIBRARY:
            raise RobotFileError(f"{where}: [identified] effect '{e}' is not in the library")
    for grp, vals in dict(ident.get("parameters", {})).items():
        if grp not in GROUP_SLICES:
            raise RobotFileError(f"{where}: [identified.parameters] unknown group '{grp}'")
        s = GROUP_SLICES[grp]
        theta[s] = _nums(where, f"parameters.{grp}", vals, s.stop - s.start)
    return theta, R0, effects


def _identified_model(robot: Robot, ident: dict[str, Any], where: str) -> ArmModel:
    """The model of a robot file with an ``[identified]`` table (its errors raised as they come)."""
    nominal = _nominal_robot(robot, ident, where)
    theta, R0, effects = _identified_theta(robot, nominal, ident, where)
    c = ident["constants"]
    tau_s = _nums(where, "constants.tau_scale_Nm", c["tau_scale_Nm"], 6)
    beams = np.array([_nums(where, "constants.beam_frames", b, 9).reshape(3, 3) for b in c["beam_frames"]])
    if beams.shape != (6, 3, 3):
        raise RobotFileError(f"{where}: [identified] key 'constants.beam_frames' must hold 6 lists of 9")
    tr = _nums(where, "constants.time_ref_s", c["time_ref_s"], 2)
    knots = _nums(where, "constants.hardening_knots_Nm", c["hardening_knots_Nm"], 6 * fx.N_KNOTS).reshape(6, fx.N_KNOTS)
    return ArmModel(
        nominal=nominal,
        theta=theta,
        R0=R0,
        tau_scale=tau_s,
        gravity_on=bool(c.get("gravity_on", False)),
        beams=beams,
        knots=knots,
        time_ref=(float(tr[0]), float(tr[1])),
        temperature_ref=float(c.get("temperature_ref_C", fx.THERMAL_REFERENCE_C)),
        effects=effects,
        registered=bool(ident.get("registered", False)),
        std=dict(ident.get("std", {})),
        noise_sigma_m=ident.get("noise_sigma_m"),
        held=dict(ident.get("held", {})),
        tcp_correction_m=_nums(where, "tcp_correction_m", ident.get("tcp_correction_m", [0, 0, 0]), 3),
        torque_range_Nm=(
            _nums(where, "torque_range_Nm", ident["torque_range_Nm"], 6) if "torque_range_Nm" in ident else None
        ),
        effect_const=_effect_constants(where, c),
        **_where_it_holds(where, ident, nominal),
    )


def load_model(spec: str | Path) -> ArmModel:
    """Load an identified model file, or a plain robot file / built-in name (nominal).

    The model records where it came from (``source``) and, for a file, its SHA-256.
    """
    robot = load_robot(spec)
    model = model_from_robot(robot, str(spec))
    model.source = str(spec) if str(spec) in BUILTIN_ROBOTS else str(Path(spec).resolve())
    if str(spec) not in BUILTIN_ROBOTS:
        model.sha256 = hashlib.sha256(Path(spec).read_bytes()).hexdigest()
    return model


def model_toml(model: ArmModel) -> str:
    import tomli_w

    return tomli_w.dumps(model_to_dict(model))
