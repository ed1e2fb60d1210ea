"""Where an identified model holds: the predicted standard deviation of a prediction, and the
poses outside the identified ranges.

A model identified by :func:`problems.identify.identify` carries the covariance ``C`` of its
free parameters (SI, :attr:`models.arm.ArmModel.covariance`) and the standard deviation per
axis of its residual ``s`` (:attr:`models.arm.ArmModel.residual_sigma_m`).  At a pose the
predicted point ``p(theta)`` has the linearised covariance ``J C J^T`` (``J`` the Jacobian of
the point w.r.t. the free parameters, by CasADi's AD on the identification graph), and a
new measurement of it also carries the residual: per axis

    sigma_k^2 = (J C J^T)_kk + s^2.

In the measurement frame (``frame="measurement"``, what :func:`problems.identify.predict`
returns) every free parameter counts, the registration included; in the base frame
(``frame="base"``, where compensation and plans put the TCP) the Jacobian is taken at the TCP
(:func:`at_tcp`), the registration's parameters do not act (nor the measured point's, unless the
data were registered and the measured point is the TCP) and it is rotated into the base frame.

A parameter the identification data do not determine (:func:`undetermined`: its standard deviation
above :data:`UNDETERMINED_STD_RATIO` typical magnitudes) is not part of the sigma: it is held at
its identified value (the others' covariance conditioned on it, :func:`held_covariance`) and named,
with whether the evaluated load changes its effect (:func:`through_load`; loaded measurements
would determine it).

:func:`outside_ranges` names, per row, the joints commanded outside the range of the
identification data (:attr:`models.arm.ArmModel.joint_range_rad`): there the model
extrapolates and its sigma is the linearised one of an extrapolation.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from models import effects as fx
from models.arm import ArmModel

from ..measurements import Measurements
from .evaluation import evaluator_for, make_rows
from .identifiability import IDENT_MAX_STD_RATIO

#: Frames a sigma is given in.
FRAMES = ("measurement", "base")
#: The parameter group whose Jacobian columns are the joints' levers ``dp/dtheta_j`` (the point's motion per
#: radian of each joint's angle): what the sigma's growth beyond the identified ranges acts through.
LEVER_GROUP = "joint_offset.dtheta"
#: A joint counts as inside the identified range up to this far beyond it, rad (rounding).
JOINT_RANGE_TOL_RAD = 1e-9
#: A parameter whose standard deviation in the model's covariance exceeds this many typical
#: magnitudes (``ParamGroup.scale``) is not determined by the identification data (the
#: identification's own rule, ``IDENT_MAX_STD_RATIO``): the sigma holds it at its identified value
#: (conditions on it) and says it leaves it out.
UNDETERMINED_STD_RATIO = IDENT_MAX_STD_RATIO
#: A parameter "acts through the load" where the evaluated wrenches change its sensitivity (the
#: Jacobian column, at most :data:`LOAD_TEST_MAX_POSES` poses) by more than this fraction of its
#: sensitivity unloaded: loaded measurements tell it apart from what unloaded data see (e.g. a
#: joint stiffness from the self-weight it multiplies).
LOAD_EXCITED_FRACTION = 0.1
#: At most this many poses (evenly spaced) for the load test of the parameters left out.
LOAD_TEST_MAX_POSES = 200
#: Names per effect written out in the sigma's sentence of what it leaves out (the rest counted).
EXCLUDED_NAMED = 6


@dataclass(frozen=True)
class Undetermined:
    """A parameter of the model's covariance the identification data do not determine.

    Attributes
    ----------
    name : str
        Its label (``models.effects.PARAM_NAMES``), e.g. ``"stiffness.s[2]"``.
    effect : str
        The effect (or declared group) it belongs to, e.g. ``"joint_springs"``.
    std_ratio : float
        Its standard deviation in the model's covariance over its typical magnitude.
    through_load : bool
        It acts through the load at the evaluated poses (:data:`LOAD_EXCITED_RATIO`): loaded
        measurements would determine it.
    """

    name: str
    effect: str
    std_ratio: float
    through_load: bool = False

    def to_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "effect": self.effect,
            "std_ratio": float(self.std_ratio),
            "through_load": bool(self.through_load),
        }


def effect_of(name: str) -> str:
    """The effect (or declared group) a parameter label belongs to."""
    i = fx.PARAM_NAMES.index(name)
    for g, e, _names, _u in fx.PARAMETER_GROUPS:
        sl = fx.GROUP_SLICES[g]
        if sl.start <= i < sl.stop:
            return e
    return "?"


def undetermined(model: ArmModel) -> list[Undetermined]:
    """The parameters of the model's covariance whose standard deviation exceeds
    :data:`UNDETERMINED_STD_RATIO` typical magnitudes, in the covariance's order (none without
    covariance)."""
    if model.covariance is None or not model.covariance_names:
        return []
    scale = fx.make_layout(model.nominal).scale
    std = np.sqrt(np.maximum(np.diag(np.asarray(model.covariance, dtype=float)), 0.0))
    out = []
    for k, name in enumerate(model.covariance_names):
        ratio = std[k] / scale[fx.PARAM_NAMES.index(name)]
        if ratio > UNDETERMINED_STD_RATIO:
            out.append(Undetermined(name, effect_of(name), float(ratio)))
    return out


def held_covariance(C: np.ndarray, held: np.ndarray) -> np.ndarray:
    """The covariance of the parameters not in ``held`` (bool mask) given those held at their values:
    the Schur complement ``C_kk - C_kh C_hh^+ C_hk``, taken on the correlation matrix."""
    keep = ~held
    sd = np.sqrt(np.maximum(np.diag(C), 0.0))
    inv = np.where(sd > 0, 1.0 / np.where(sd > 0, sd, 1.0), 0.0)
    R = C * np.outer(inv, inv)
    Rkk, Rkh, Rhh = R[np.ix_(keep, keep)], R[np.ix_(keep, held)], R[np.ix_(held, held)]
    # least squares at machine precision: the held block is nearly singular where the data determine
    # only a combination of its parameters (stiffness times mass), and that combination must count
    Rc = Rkk - Rkh @ np.linalg.lstsq(Rhh, Rkh.T, rcond=None)[0]
    Rc = 0.5 * (Rc + Rc.T)
    return Rc * np.outer(sd[keep], sd[keep])


def excluded_text(excluded: list[Undetermined]) -> str:
    """One sentence: what the sigma leaves out and why (empty when nothing)."""
    if not excluded:
        return ""
    parts = []
    for eff in dict.fromkeys(u.effect for u in excluded):
        us = [u for u in excluded if u.effect == eff]
        names = ", ".join(u.name for u in us[:EXCLUDED_NAMED])
        more = f" and {len(us) - EXCLUDED_NAMED} more" if len(us) > EXCLUDED_NAMED else ""
        loaded = [u.name for u in us if u.through_load]
        why = (
            " (no loaded measurements: the load changes its effect; measure under load to determine it)"
            if loaded
            else ""
        )
        parts.append(f"{eff} {names}{more}{why}")
    return (
        f"sigma excludes {len(excluded)} parameter(s) the identification data do not determine (std > "
        f"{UNDETERMINED_STD_RATIO:g} typical magnitudes; held at their identified values): " + "; ".join(parts)
    )


@dataclass
class PredictedSigma:
    """The predicted standard deviation of N predicted points.

    Attributes
    ----------
    sigma_m : ndarray, shape (N, 3)
        Per axis (x, y, z of ``frame``), m: parameters and residual together.
    param_cov : ndarray, shape (N, 3, 3)
        The parameters' part ``J C J^T``, m^2.
    residual_sigma_m : float
        The residual's part per axis, m (0 when the model does not carry it).
    frame : str
        ``"measurement"`` or ``"base"``.
    available : bool
        False when the model has no covariance (a nominal model, or a format-1 model file):
        then ``sigma_m`` is NaN.
    excluded : list of Undetermined
        The parameters the identification data do not determine (:func:`undetermined`): held at
        their identified values, left out of ``sigma_m`` and ``param_cov``.
    """

    sigma_m: np.ndarray
    param_cov: np.ndarray
    residual_sigma_m: float
    frame: str
    available: bool
    excluded: list[Undetermined] = field(default_factory=list)

    def excluded_text(self) -> str:
        """What the sigma leaves out, one sentence (empty when nothing)."""
        return excluded_text(self.excluded)


def rows_of(model: ArmModel, q: np.ndarray, wrench: np.ndarray | None = None) -> np.ndarray:
    """Rows of the identification graph (:func:`problems.identify.evaluation.make_rows`) for commands
    ``q`` (N, 6), rad, under base-frame TCP wrenches ``wrench`` (N, 6) or (6,), N and N*m (zero when
    None), at the model's temperature and at the start of its time reference."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w = np.zeros((len(q), 6)) if wrench is None else np.broadcast_to(np.asarray(wrench, dtype=float), (len(q), 6))
    return make_rows(Measurements(q=q, wrench=np.array(w), p=None, source="commands"), None, model.temperature_ref)


def parameter_jacobian(
    model: ArmModel, q: np.ndarray, wrench: np.ndarray | None = None, names: list[str] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted measured point and its Jacobian w.r.t. named parameters (measurement frame).

    Parameters
    ----------
    model : ArmModel
    q : ndarray, shape (N, 6)
        Commands, rad.
    wrench : ndarray, shape (N, 6) or (6,), optional
        Base-frame TCP wrench ``[f (N); m (N*m)]``.
    names : list of str, optional
        Parameter names (``models.effects.PARAM_NAMES``); default the model's
        :attr:`~models.arm.ArmModel.covariance_names`.

    Returns
    -------
    p : ndarray, shape (N, 3)
        Predicted measured point, measurement frame, m.
    J : ndarray, shape (N, 3, k)
        ``dp/dtheta`` in m per SI unit of each parameter, columns in the order of ``names``.
    """
    names = list(model.covariance_names if names is None else names)
    idx = np.array([fx.PARAM_NAMES.index(n) for n in names], dtype=int)
    rows = rows_of(model, q, wrench)
    const = model.const
    ev = evaluator_for(model.nominal, const)
    _p, q_eq = ev.measure(rows, model.theta, const)
    p, J = ev.jacobian(rows, q_eq, model.theta, const)
    n = len(rows)
    return p, J.reshape(n, 3, -1)[:, :, idx]


def at_tcp(model: ArmModel) -> ArmModel:
    """The model with its measured point on the planning TCP (the robot file's tool translation plus
    :attr:`~models.arm.ArmModel.tcp_correction_m`, flange frame): where the base-frame sigma is taken."""
    theta = model.theta.copy()
    theta[fx.GROUP_SLICES["tool.p"]] = np.asarray(model.nominal.tcp2flange, dtype=float)[:3, 3] + np.asarray(
        model.tcp_correction_m, dtype=float
    )
    return replace(model, theta=theta)


def to_base_frame(model: ArmModel, J: np.ndarray, names: list[str]) -> np.ndarray:
    """A measurement-frame Jacobian (N, 3, k) rotated into the base frame, the registration's
    columns zero (they move the measurement frame, not the TCP), and the measured point's too unless
    the data were registered (then the measured point is the TCP; otherwise it is another point
    than the TCP, which the robot file declares)."""
    R = model.base2meas()[:3, :3]
    Jb = np.einsum("ji,njk->nik", R, J)
    reg = set(fx.REGISTRATION_NAMES) | (set() if model.registered else set(fx.PARAM_NAMES[fx.GROUP_SLICES["tool.p"]]))
    for k, name in enumerate(names):
        if name in reg:
            Jb[:, :, k] = 0.0
    return Jb


def predicted_sigma(
    model: ArmModel,
    q: np.ndarray,
    wrench: np.ndarray | None = None,
    frame: str = "measurement",
    include_residual: bool = True,
) -> PredictedSigma:
    """Predicted standard deviation per axis of the model's prediction at commands ``q`` (N, 6), rad.

    ``sigma^2 = diag(J C J^T) + s^2`` (module docstring); ``frame`` is ``"measurement"`` (the
    measured point, as :func:`problems.identify.predict`) or ``"base"`` (the TCP position of
    compensation and plans, registration excluded).  ``include_residual=False`` leaves out ``s``
    (the parameters' part alone, what a design can reduce).  The parameters the data do not
    determine are held and listed in ``excluded`` (module docstring).
    """
    if frame not in FRAMES:
        raise ValueError(f"frame {frame!r}: expected one of {FRAMES}")
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = len(q)
    s = float(model.residual_sigma_m or 0.0) if include_residual else 0.0
    if model.covariance is None or not model.covariance_names:
        return PredictedSigma(np.full((n, 3), np.nan), np.full((n, 3, 3), np.nan), s, frame, False)
    names = list(model.covariance_names)
    levers = list(fx.PARAM_NAMES[fx.GROUP_SLICES[LEVER_GROUP]])
    J = frame_jacobian(model, q, wrench, names + levers, frame)
    J, L = J[:, :, : len(names)], J[:, :, len(names) :]
    C = np.asarray(model.covariance, dtype=float)
    excluded = undetermined(model)
    if excluded:
        held = np.isin(names, [u.name for u in excluded])
        excluded = _through_load(model, q, wrench, names, frame, J, held, excluded)
        C = held_covariance(C, held)
        J = J[:, :, ~held]
    P = np.einsum("nik,kl,njl->nij", J, C, J)
    var = model.sigma_scale**2 * (np.maximum(np.diagonal(P, axis1=1, axis2=2), 0.0) + s**2)
    if model.sigma_growth_rad_per_rad and model.joint_range_rad is not None:
        var = var + model.sigma_growth_rad_per_rad**2 * growth_variance(beyond_range(model, q), L)
    return PredictedSigma(np.sqrt(var), P, s, frame, True, excluded)


def calibration_text(model: ArmModel) -> str:
    """Words for the sigma's calibration (:mod:`.sigma_calibration`): its scale and growth, or that it has none."""
    if model.sigma_scale == 1.0 and not model.sigma_growth_rad_per_rad:
        return "sigma linearised (no calibration on held-out rows in the model file)"
    return (
        f"sigma calibrated on held-out rows (x{model.sigma_scale:.3g}), growing beyond the identified ranges by "
        f"{model.sigma_growth_rad_per_rad * 1e3:.3g} mrad of joint error per rad"
    )


def growth_variance(beyond: np.ndarray, lever: np.ndarray) -> np.ndarray:
    """Per-axis variance of a unit growth rate: ``sum_j Delta_j^2 L_jk^2`` ((n, 3), m^2 per (rad/rad)^2)
    from the distances beyond the ranges ``beyond`` (n, 6), rad, and the levers ``lever`` (n, 3, 6), m/rad
    (:mod:`.sigma_calibration`)."""
    return np.einsum("nj,nkj->nk", beyond**2, lever**2)


def beyond_range(model: ArmModel, q: np.ndarray) -> np.ndarray:
    """Distance of each command beyond the identified joint ranges (N, 6), rad (0 inside)."""
    rng = np.asarray(model.joint_range_rad, dtype=float)
    return np.maximum(np.maximum(rng[:, 0] - q, q - rng[:, 1]), 0.0)


def frame_jacobian(
    model: ArmModel, q: np.ndarray, wrench: np.ndarray | None, names: list[str], frame: str
) -> np.ndarray:
    """The Jacobian (N, 3, k) of the predicted point in ``frame`` (:func:`predicted_sigma`)."""
    if frame == "base":
        return to_base_frame(model, parameter_jacobian(at_tcp(model), q, wrench, names)[1], names)
    return parameter_jacobian(model, q, wrench, names)[1]


def _through_load(
    model: ArmModel,
    q: np.ndarray,
    wrench: np.ndarray | None,
    names: list[str],
    frame: str,
    J: np.ndarray,
    held: np.ndarray,
    excluded: list[Undetermined],
) -> list[Undetermined]:
    """``excluded`` with ``through_load`` set where ``wrench`` changes a parameter's sensitivity
    (:func:`through_load`)."""
    if wrench is None or not np.any(np.asarray(wrench, dtype=float)):
        return excluded
    n = len(q)
    idx = np.unique(np.linspace(0, n - 1, min(n, LOAD_TEST_MAX_POSES)).round().astype(int))
    hn = [names[k] for k in np.flatnonzero(held)]
    J0 = frame_jacobian(model, q[idx], None, hn, frame)
    by_name = dict(zip(hn, through_load(J[idx][:, :, held], J0)))
    return [replace(u, through_load=bool(by_name[u.name])) for u in excluded]


def through_load(J_loaded: np.ndarray, J_unloaded: np.ndarray) -> np.ndarray:
    """Per column of two Jacobians (N, 3, k) at the same poses, loaded and unloaded: whether the load
    changes the column by more than :data:`LOAD_EXCITED_FRACTION` of its unloaded norm (bool (k,))."""
    diff = np.linalg.norm(J_loaded - J_unloaded, axis=(0, 1))
    return (diff > LOAD_EXCITED_FRACTION * np.linalg.norm(J_unloaded, axis=(0, 1))) & (diff > 0)


def outside_joints(model: ArmModel, q: np.ndarray) -> np.ndarray:
    """Which joints of each row of ``q`` (N, 6), rad, lie outside the identification data's range,
    bool (N, 6) (all False for a model that does not record its ranges)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    rng = model.joint_range_rad
    if rng is None:
        return np.zeros(q.shape, dtype=bool)
    return (q < rng[:, 0] - JOINT_RANGE_TOL_RAD) | (q > rng[:, 1] + JOINT_RANGE_TOL_RAD)


def outside_ranges(model: ArmModel, q: np.ndarray) -> list[str]:
    """Per row of ``q`` (N, 6), rad: the joints outside the identification data's range, e.g.
    ``"q1 -200.0 deg (identified -180.0..-45.0)"`` joined by ``"; "``, or ``""`` inside (and for
    a model that does not record its ranges)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    rng = model.joint_range_rad
    if rng is None:
        return [""] * len(q)
    out = []
    for row, mask in zip(q, outside_joints(model, q)):
        bad = np.flatnonzero(mask)
        out.append(
            "; ".join(
                f"q{j + 1} {np.degrees(row[j]):.1f} deg (identified {np.degrees(rng[j, 0]):.1f}.."
                f"{np.degrees(rng[j, 1]):.1f})"
                for j in bad
            )
        )
    return out


#: Poses of a path at which the plan's sigma is evaluated, at most (evenly spaced; the largest of
#: them is reported): the Jacobian costs about a millisecond per pose.
PATH_SIGMA_MAX_POSES = 2000
#: Waypoints outside the identified ranges named in a plan's warning (the rest counted).
PATH_OUTSIDE_NAMED = 5


@dataclass
class PathSigma:
    """The predicted sigma of the compensated TCP along a path, and where the model extrapolates.

    Attributes
    ----------
    available : bool
        False for a model without covariance (then ``reason`` says why and the numbers are NaN).
    reason : str
    waypoints : ndarray of int, shape (M,)
        The waypoints evaluated (every one up to :data:`PATH_SIGMA_MAX_POSES`, else evenly spaced).
    sigma_m : ndarray, shape (M, 3)
        Predicted standard deviation per axis of the base frame at those waypoints, m (the
        parameters' part and the residual's, :func:`predicted_sigma` with ``frame="base"``).
    outside : ndarray of bool, shape (N, 6)
        Joints outside the identification data's range at every waypoint of the path.
    outside_text : list of str
        :func:`outside_ranges` of the first :data:`PATH_OUTSIDE_NAMED` waypoints outside, with their index.
    excluded : list of Undetermined
        The parameters the identification data do not determine, left out of ``sigma_m``.
    """

    available: bool
    reason: str
    waypoints: np.ndarray
    sigma_m: np.ndarray
    outside: np.ndarray
    outside_text: list[tuple[int, str]]
    excluded: list[Undetermined] = field(default_factory=list)

    @property
    def n_outside(self) -> int:
        """Waypoints with a joint outside the identified ranges."""
        return int(self.outside.any(axis=1).sum())

    def text(self) -> str:
        """One line for the terminal and the report."""
        if not self.available:
            return f"predicted sigma of the compensated TCP: not available ({self.reason})"
        norm = np.linalg.norm(self.sigma_m, axis=1)
        k = int(np.argmax(norm))
        out = (
            f"; {self.n_outside} waypoint(s) outside the identified joint ranges (extrapolated)"
            if self.n_outside
            else "; every waypoint inside the identified joint ranges"
        )
        left = f"; {excluded_text(self.excluded)}" if self.excluded else ""
        return (
            f"predicted sigma of the compensated TCP (base frame, per axis): mean {self.sigma_m.mean() * 1e3:.4f} mm, "
            f"largest {self.sigma_m.max() * 1e3:.4f} mm (|sigma| {norm[k] * 1e3:.4f} mm at waypoint "
            f"{int(self.waypoints[k])}){out}{left}"
        )

    def warning(self) -> str | None:
        """The plan's warning naming the waypoints where the model extrapolates, or None."""
        if not self.n_outside:
            return None
        named = "; ".join(f"waypoint {k}: {t}" for k, t in self.outside_text)
        more = f" and {self.n_outside - len(self.outside_text)} more" if self.n_outside > len(self.outside_text) else ""
        return (
            f"the arm model extrapolates at {self.n_outside} waypoint(s), outside the joint ranges it was "
            f"identified on ({named}{more}): its prediction and sigma there are an extrapolation"
        )

    def load_warning(self) -> str | None:
        """The plan's warning when its load acts through parameters the data do not determine (joint
        stiffness identified without loads): the compensation of that load rests on values the
        identification could not check, and its error is not in the sigma.  None otherwise."""
        loaded = [u for u in self.excluded if u.through_load]
        if not loaded:
            return None
        names = ", ".join(u.name for u in loaded[:EXCLUDED_NAMED])
        more = f" and {len(loaded) - EXCLUDED_NAMED} more" if len(loaded) > EXCLUDED_NAMED else ""
        return (
            f"the compensation of this load rests on {len(loaded)} parameter(s) the identification data do not "
            f"determine ({names}{more}: no loaded measurements), held at their identified values; its error "
            "is not in the sigma: identify from measurements under load (compplan design proposes them)"
        )

    def to_dict(self) -> dict[str, object]:
        """``summary.json`` ``model_sigma`` (SI; NaN as None)."""
        ok = self.available and len(self.sigma_m)
        norm = np.linalg.norm(self.sigma_m, axis=1) if ok else np.zeros(0)
        return {
            "available": bool(self.available),
            "reason": self.reason,
            "frame": "base",
            "n_evaluated": int(len(self.waypoints)),
            "mean_m": float(self.sigma_m.mean()) if ok else None,
            "max_m": float(self.sigma_m.max()) if ok else None,
            "max_waypoint": int(self.waypoints[int(np.argmax(norm))]) if ok else None,
            "n_outside_range": self.n_outside,
            "outside_range": [{"waypoint": k, "joints": t} for k, t in self.outside_text],
            "excluded": [u.to_dict() for u in self.excluded],
            "text": self.text(),
        }


def path_sigma(model: ArmModel, q: np.ndarray, wrench: np.ndarray | None = None) -> PathSigma:
    """The predicted sigma of the compensated TCP along a path (commands ``q`` (N, 6), rad, under
    base-frame TCP wrenches ``wrench`` (N, 6)), and the waypoints outside the identified ranges."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = len(q)
    outside = outside_joints(model, q)
    bad = np.flatnonzero(outside.any(axis=1))[:PATH_OUTSIDE_NAMED]
    texts = outside_ranges(model, q[bad]) if len(bad) else []
    out_text = [(int(k), t) for k, t in zip(bad, texts)]
    idx = np.unique(np.linspace(0, n - 1, min(n, PATH_SIGMA_MAX_POSES)).round().astype(int)) if n else np.zeros(0, int)
    if model.covariance is None or not model.covariance_names:
        why = (
            "nominal model: no covariance"
            if not model.effects and model.is_nominal
            else "the model file has no parameter covariance (written before format 2); identify again"
        )
        return PathSigma(False, why, idx, np.full((len(idx), 3), np.nan), outside, out_text)
    w = None if wrench is None else np.broadcast_to(np.asarray(wrench, dtype=float), (n, 6))[idx]
    ps = predicted_sigma(model, q[idx], w, frame="base")
    return PathSigma(True, "", idx, ps.sigma_m, outside, out_text, ps.excluded)
