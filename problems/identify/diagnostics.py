"""Diagnostics: what the residual still depends on (``docs/identification.md`` §6).

The final residual (measurement frame, weighted) is regressed, with the same
cross-validation folds as the selection, on time, load, load sign, joint torque,
gravity torque, temperature, workspace position and pose, and -- nonparametrically,
with cross-validated P-splines (:mod:`.error_map`) -- on each joint angle, both as an
error of that joint and per residual axis.  A
diagnostic is *significant* when its F-test passes at :data:`DIAG_ALPHA` over the
number of diagnostics and it explains more than :data:`DIAG_MIN_FRACTION` of the
residual variance out of fold; :func:`structure_left` picks the most specific one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy import stats

from models.robot import Robot

from ..measurements import Measurements
from .error_map import joint_smoother_cv, smoother_cv
from .evaluation import FitProblem, nominal_gravity_torque, nominal_points
from .results import Diagnostic

if TYPE_CHECKING:  # pragma: no cover
    from .lsq import ModelFit

#: Diagnostics: family-wise significance level and minimum cross-validated
#: explained fraction of the residual variance for "structure".
DIAG_ALPHA = 1e-3
DIAG_MIN_FRACTION = 0.05
#: Structure is reported as unexplained when a significant diagnostic explains at
#: least this fraction, or the residual RMS exceeds this multiple of a known noise floor.
UNEXPLAINED_MIN_FRACTION = 0.10
UNEXPLAINED_RMS_RATIO = 1.5


def _poly(x: np.ndarray, deg: int) -> np.ndarray:
    """Powers 1..deg of the standardised ``x`` (N,): (N, deg), dimensionless."""
    s = np.std(x)
    z = (x - np.mean(x)) / (s if s > 0 else 1.0)
    return np.column_stack([z**k for k in range(1, deg + 1)])


def _scalar_design(B: np.ndarray) -> np.ndarray:
    """Scalar basis (n, b) with a free 3-D coefficient each -> vector design (n, 3, 3b)."""
    n, b = B.shape
    X = np.zeros((n, 3, 3 * b))
    for k in range(3):
        X[:, k, k::3] = B
    return X


def _joint_design(Jp: np.ndarray, j: int, B: np.ndarray) -> np.ndarray:
    """Joint-error design: column j of the positional Jacobian times each basis function,
    (n, 3, b): the signature of an error of joint j that is a function of the basis."""
    return Jp[:, :, j][:, :, None] * B[:, None, :]


def regress_cv(R: np.ndarray, X: np.ndarray, folds: np.ndarray) -> tuple[float, float]:
    """CV explained fraction and F-test p-value of residual R (n, 3) on design X (n, 3, b).

    A constant 3-D offset is always part of the model (it is the reference).
    """
    n = len(R)
    X = np.concatenate([_scalar_design(np.ones((n, 1))), X], axis=2)
    b = X.shape[2]
    y = R.reshape(-1)
    A = X.reshape(3 * n, b)
    y0 = (R - R.mean(axis=0)).reshape(-1)
    rss0 = float(y0 @ y0)
    if rss0 <= 0 or b >= 3 * n - 3:
        return 0.0, 1.0
    coef = np.linalg.lstsq(A, y, rcond=None)[0]
    e = y - A @ coef
    rss1 = float(e @ e)
    f3 = np.repeat(folds, 3)
    cv = 0.0
    for k in np.unique(folds):
        tr, te = f3 != k, f3 == k
        c = np.linalg.lstsq(A[tr], y[tr], rcond=None)[0]
        cv += float(np.sum((y[te] - A[te] @ c) ** 2))
    rank = np.linalg.matrix_rank(A)
    df1, df2 = max(rank - 3, 1), 3 * n - rank
    if rss1 <= 0 or df2 <= 0:
        return 1.0 - cv / rss0, 0.0
    F = ((rss0 - rss1) / df1) / (rss1 / df2)
    return 1.0 - cv / rss0, float(stats.f.sf(F, df1, df2))


def diagnostic_variables(
    m: Measurements, Jp: np.ndarray, tau: np.ndarray, tau_g: np.ndarray | None, p_nominal: np.ndarray
) -> dict[str, tuple[np.ndarray, np.ndarray, str]]:
    """Explanatory variables: name -> (x for plots, design (n, 3, b), description).

    Parameters
    ----------
    Jp : ndarray, shape (n, 3, 6)
        Positional Jacobian of the measured point, measurement frame (m/rad).
    tau : ndarray, shape (n, 6)
        Joint torques of the applied wrench, N*m.
    tau_g : ndarray, shape (n, 6) or None
        Nominal gravity torques, N*m.
    p_nominal : ndarray, shape (n, 3)
        Nominal TCP positions, base frame, m.
    """
    out: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
    n = m.n
    t = m.t if m.t is not None else np.arange(n, dtype=float)
    if np.ptp(t) > 0:
        out["time"] = (
            t,
            _scalar_design(_poly(t, 4)),
            "time (s, or row number without a t column): polynomial of degree 4 per axis",
        )
    f = m.wrench[:, :3]
    fm = np.linalg.norm(f, axis=1)
    if fm.max() > 0:
        sc = fm.max()
        B = np.column_stack([f / sc, f * fm[:, None] / sc**2, f * (fm**2)[:, None] / sc**3])
        out["load_magnitude"] = (
            fm,
            _scalar_design(B),
            "applied force |f| (N): f, f|f|, f|f|^2 with free 3-D coefficients",
        )
        sg = np.sign(np.where(np.abs(f) > 1e-6 * sc, f, 0.0))
        ts = np.maximum(np.abs(tau).max(axis=0), 1e-12)
        sgt = np.sign(np.where(np.abs(tau) > 1e-3 * ts, tau, 0.0))
        X = np.concatenate([_scalar_design(sg)] + [_joint_design(Jp, j, sgt[:, j : j + 1]) for j in range(6)], axis=2)
        out["load_sign"] = (sg @ np.array([1.0, 2.0, 4.0]), X, "sign of each force component and of each joint torque")
        X = np.concatenate(
            [_joint_design(Jp, j, np.column_stack([tau[:, j] / ts[j], (tau[:, j] / ts[j]) ** 3])) for j in range(6)],
            axis=2,
        )
        out["joint_torque"] = (
            np.abs(tau).max(axis=1),
            X,
            "joint deflection as an odd cubic of each joint torque (J_j (a tau_j + b tau_j^3))",
        )
    if tau_g is not None:
        cols = [j for j in range(6) if np.ptp(tau_g[:, j]) > 1e-9]
        if cols:
            X = np.concatenate([_joint_design(Jp, j, _poly(tau_g[:, j], 2)) for j in cols], axis=2)
            big = cols[int(np.argmax([np.ptp(tau_g[:, j]) for j in cols]))]
            out["gravity_torque"] = (
                tau_g[:, big],
                X,
                "nominal gravity torque of each joint: J_j (a tau_g,j + b tau_g,j^2)",
            )
    if m.temperature is not None and np.ptp(m.temperature) > 0:
        out["temperature"] = (
            m.temperature,
            _scalar_design(_poly(m.temperature, 2)),
            "temperature (deg C): quadratic per axis",
        )
    P = p_nominal
    if np.ptp(P, axis=0).max() > 0:
        Z = (P - P.mean(axis=0)) / np.maximum(P.std(axis=0), 1e-9)
        quad = [Z[:, i] * Z[:, j] for i in range(3) for j in range(i, 3)]
        out["position"] = (
            np.linalg.norm(P[:, :2], axis=1),
            _scalar_design(np.column_stack([Z] + quad)),
            "nominal TCP position in the workspace: quadratic in x, y, z per axis",
        )
    return out


def _pose_anova(R: np.ndarray, groups: np.ndarray) -> tuple[float, float]:
    """Adjusted fraction of residual variance explained by per-pose means, and p-value."""
    ug, inv, counts = np.unique(groups, return_inverse=True, return_counts=True)
    if len(ug) < 2 or np.all(counts < 2):
        return 0.0, 1.0
    means = np.zeros((len(ug), 3))
    np.add.at(means, inv, R)
    means /= counts[:, None]
    within = float(np.sum((R - means[inv]) ** 2))
    total = float(np.sum((R - R.mean(axis=0)) ** 2))
    between = total - within
    n, g = len(R), len(ug)
    df1, df2 = 3 * (g - 1), 3 * (n - g)
    if df2 <= 0 or within <= 0 or total <= 0:
        return 0.0, 1.0
    F = (between / df1) / (within / df2)
    adj = 1.0 - (within / df2) / (total / (3 * (n - 1)))
    return adj, float(stats.f.sf(F, df1, df2))


def joint_angle_diagnostics(R: np.ndarray, Jw: np.ndarray, q: np.ndarray, folds: np.ndarray) -> list[Diagnostic]:
    """Nonparametric residual-versus-joint-angle diagnostics (significance not yet decided).

    Per joint j whose angle varies: ``q{j}``, the residual against an error of joint j that is
    any smooth function of its angle (``J_j(q) s(q_j)``, :func:`~.error_map.joint_smoother_cv`),
    and ``q{j}.x``, ``q{j}.y``, ``q{j}.z``, each residual axis against ``q_j`` alone
    (:func:`~.error_map.smoother_cv`): cross-validated P-splines with knots fine enough for
    :data:`~.error_map.MAP_MAX_CPR` cycles per revolution, so high harmonics and non-periodic
    smooth structure are both seen.

    Parameters
    ----------
    R : ndarray, shape (n, 3)
        Weighted residual, measurement frame.
    Jw : ndarray, shape (n, 3, 6)
        Positional Jacobian of the measured point with the same weights.
    q : ndarray, shape (n, 6)
        Commanded joint angles, rad.
    """
    out: list[Diagnostic] = []
    for j in range(6):
        x = q[:, j]
        if np.ptp(x) <= 1e-3:
            continue
        sj = joint_smoother_cv(R, Jw[:, :, j], x, folds)
        out.append(
            Diagnostic(
                f"q{j + 1}",
                sj.explained,
                sj.p_value,
                False,
                x,
                (
                    f"joint {j + 1} angle: an error of joint {j + 1} that is any smooth function of q{j + 1} "
                    f"(P-spline through the joint's Jacobian column, {sj.edf:.0f} effective dof)"
                ),
            )
        )
        for k, ax in enumerate("xyz"):
            sk = smoother_cv(R[:, k], x, folds)
            out.append(
                Diagnostic(
                    f"q{j + 1}.{ax}",
                    sk.explained,
                    sk.p_value,
                    False,
                    x,
                    (f"residual {ax} against q{j + 1} alone (P-spline, {sk.edf:.0f} effective dof)"),
                    y=R[:, k],
                    y_label=f"weighted residual {ax}",
                )
            )
    return out


def _share(fraction: float) -> float:
    """An explained fraction as a share of the residual variance: ``1 - CV RSS / RSS`` is negative
    when the cross-validated fit predicts held-out rows worse than their mean; that is no structure,
    a share of 0 (a share is never negative)."""
    return max(float(fraction), 0.0)


def run_diagnostics(
    R: np.ndarray,
    m: Measurements,
    variables: Mapping[str, tuple[np.ndarray, np.ndarray, str]],
    folds: np.ndarray,
    extra: Sequence[Diagnostic] = (),
) -> list[Diagnostic]:
    """Regress the residual on each variable; significance with a Bonferroni correction over
    every diagnostic (``extra``: ones already computed, e.g. :func:`joint_angle_diagnostics`).

    Returned sorted by explained fraction (largest first; never negative, :func:`_share`).
    """
    out: list[Diagnostic] = []
    n_tests = len(variables) + 1 + len(extra)
    for name, (x, X, desc) in variables.items():
        frac, p = regress_cv(R, X, folds)
        sig = (p < DIAG_ALPHA / n_tests) and frac > DIAG_MIN_FRACTION
        out.append(Diagnostic(name, _share(frac), p, sig, x, desc))
    for d in extra:
        d.significant = (d.p_value < DIAG_ALPHA / n_tests) and d.explained_fraction > DIAG_MIN_FRACTION
        d.explained_fraction = _share(d.explained_fraction)
        out.append(d)
    groups = m.pose_groups()
    frac, p = _pose_anova(R, groups)
    out.append(
        Diagnostic(
            "pose",
            _share(frac),
            p,
            (p < DIAG_ALPHA / n_tests) and frac > DIAG_MIN_FRACTION,
            groups.astype(float),
            "per-pose mean of the residual (one-way ANOVA, adjusted R^2): an error that "
            "depends on the pose and that the model does not describe",
        )
    )
    out.sort(key=lambda d: -d.explained_fraction)
    return out


def structure_left(diags: Sequence[Diagnostic]) -> Diagnostic | None:
    """The most specific significant diagnostic (a named variable before 'pose'), or None."""
    sig = [d for d in diags if d.significant]
    if not sig:
        return None
    named = [d for d in sig if d.variable != "pose"]
    return named[0] if named else sig[0]


def diagnose(prob: FitProblem, fit: ModelFit, robot: Robot) -> list[Diagnostic]:
    """Diagnostics of the residual of ``fit`` (inlier rows), sorted by explained fraction.

    The positional Jacobian of the measured point (measurement frame, m/rad) and the
    joint torques of the applied wrench (N*m) come from the fitted model; the gravity
    torques and workspace positions from the nominal ``robot``.
    """
    mask_all = fit.inliers
    mask = mask_all & prob.pos
    m = prob.m.subset(mask)
    n = m.n
    ev = prob.ev
    rows = prob.rows[mask]
    dT = rows[:, 13:14]
    _p, Jp = ev.call("point_jacobian", m.q, dT, fit.theta, prob.const)
    Jp = np.asarray(Jp).reshape(3, n, 6).transpose(1, 0, 2)
    te, _tg, _q = ev.call("torques", m.q, m.wrench, dT, fit.theta, prob.const)
    tau = np.asarray(te).T
    tau_g = nominal_gravity_torque(robot, m)
    p_nom = nominal_points(robot, m.q)
    variables = diagnostic_variables(m, Jp, tau, tau_g, p_nom)
    W = prob.weights[mask]
    R = (fit.pred[mask] - m.p) * W
    # the joint-error signature needs one weight per row: the axes' RMS (equal weights: exact)
    w_row = np.sqrt(np.mean(W**2, axis=1))
    Jw = Jp * w_row[:, None, None]
    extra = joint_angle_diagnostics(R, Jw, m.q, prob.folds[mask])
    rot = mask_all & ~prob.pos
    if rot.any():
        # orientation rows: each axis of the (weighted) orientation error against each joint angle
        Rr = (fit.pred[rot] - prob.m.p[rot]) * prob.weights[rot]
        qr = prob.m.q[rot]
        for j in range(6):
            if np.ptp(qr[:, j]) <= 1e-3:
                continue
            for k, ax in enumerate(("rx", "ry", "rz")):
                sk = smoother_cv(Rr[:, k], qr[:, j], prob.folds[rot])
                extra.append(
                    Diagnostic(
                        f"q{j + 1}.{ax}",
                        sk.explained,
                        sk.p_value,
                        False,
                        qr[:, j],
                        f"orientation residual {ax} against q{j + 1} alone (P-spline, {sk.edf:.0f} effective dof)",
                        y=Rr[:, k],
                        y_label=f"weighted orientation residual {ax}",
                    )
                )
    diags = run_diagnostics(R, m, variables, prob.folds[mask], extra)
    # joint-angle diagnostics are shown as the equivalent error of that joint: the residual
    # projected on the joint's column of the positional Jacobian, (J_j . r) / |J_j|^2 (rad)
    Ru = fit.pred[mask] - m.p
    for d in diags:
        if d.variable.startswith("q") and d.variable[1:].isdigit() and d.y is None:
            j = int(d.variable[1:]) - 1
            Jj = Jp[:, :, j]
            d.y = np.einsum("ni,ni->n", Jj, Ru) / np.maximum(np.einsum("ni,ni->n", Jj, Jj), 1e-12)
            d.y_label = f"equivalent joint-{j + 1} error (rad)"
    return diags
