"""Forward evaluation of the identification model over many rows.

* :class:`Evaluator` -- the model graph's CasADi functions (``models.effects``)
  mapped over rows with threads, cached per size;
* :func:`make_rows` and :func:`time_reference` -- the per-row inputs
  ``[q_c (6) rad, F (6) N and N*m base frame, tn (1), dT (1) K]``;
* :class:`FitProblem` -- the data and fixed inputs of one identification, and the
  constant-vector updates of the selection (hardening knots, gravity switch);
* the nominal model's evaluations used by diagnostics and compensation.

Everything is SI; positions are in the measurement frame unless named otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from models import effects as fx
from models.effects import GROUP_SLICES, N_PARAMS, ModelLayout, get_const, make_const, make_layout, set_const
from models.robot import Robot
from models.symbolic import KinematicModel

from ..measurements import Measurements

if TYPE_CHECKING:  # pragma: no cover
    from .lsq import ModelFit


def _np(x: ca.DM) -> np.ndarray:
    """A CasADi DM as a dense NumPy array (``DM.full``: about twice as fast as ``np.asarray``)."""
    return x.full() if isinstance(x, ca.DM) else np.asarray(x)


class Evaluator:
    """Evaluate the model over many rows (CasADi ``map`` with threads), cached per size.

    Parameters
    ----------
    convention : str
        DH convention of the robot (``"standard_dh"`` or ``"modified_dh"``).
    eligible : ndarray of bool, shape (N_PARAMS,), optional
        Parameters that exist for the robot (the Jacobian is taken w.r.t. them only).
    """

    THREADS = 2

    def __init__(
        self, convention: str, eligible: np.ndarray | None = None, orientation: bool = False, general: bool = False
    ) -> None:
        el = np.ones(N_PARAMS, dtype=bool) if eligible is None else np.asarray(eligible, dtype=bool)
        self.eligible_idx = np.flatnonzero(el)
        self.fns = fx.identification_functions(convention, tuple(bool(x) for x in el), orientation, general)
        self._maps: dict[tuple[str, int], ca.Function] = {}

    def _map(self, name: str, n: int) -> ca.Function:
        """Function ``name`` mapped over ``n`` rows (threads), cached."""
        key = (name, n)
        f = self._maps.get(key)
        if f is None:
            f = self.fns[name].map(n, "thread", self.THREADS)
            if len(self._maps) > 16:
                self._maps.clear()
            self._maps[key] = f
        return f

    def measure(self, rows: np.ndarray, theta: np.ndarray, const: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurement and deflected equilibrium.

        Parameters
        ----------
        rows : ndarray, shape (N, ROW_SIZE)
            Per-row inputs (:func:`make_rows`).
        theta : ndarray, shape (N_PARAMS,)
            Parameters, SI.
        const : ndarray
            Constant vector (``models.effects.make_const``).

        Returns
        -------
        p : ndarray, shape (N, 3)
            Measured point, measurement frame, m.
        q : ndarray, shape (N, 6)
            Equilibrium joints, rad.
        """
        n = len(rows)
        p, q = self._map("measure", n)(rows.T, theta, const)
        return _np(p).T, _np(q).T

    def jacobian(
        self, rows: np.ndarray, q_eq: np.ndarray, theta: np.ndarray, const: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurement (N, 3), m, and its Jacobian w.r.t. ``theta``.

        Returns
        -------
        p : ndarray, shape (N, 3)
        J : ndarray, shape (3N, N_PARAMS)
            Rows ``[x0, y0, z0, x1, ...]`` (m per SI unit of the parameter); columns of
            ineligible parameters are zero.
        """
        n = len(rows)
        p, J = self._map("measure_jac", n)(rows.T, q_eq.T, theta, const)
        ne = len(self.eligible_idx)
        Je = _np(J).reshape(3, n, ne).transpose(1, 0, 2).reshape(3 * n, ne)
        if ne == N_PARAMS:
            return _np(p).T, Je
        Jf = np.zeros((3 * n, N_PARAMS))
        Jf[:, self.eligible_idx] = Je
        return _np(p).T, Jf

    def call(self, name: str, *args: np.ndarray) -> list[np.ndarray]:
        """Evaluate a per-row function over rows; 2-D args are (N, k), 1-D are broadcast.

        Returns the outputs as CasADi-shaped arrays (k, N)."""
        n = max(a.shape[0] for a in args if a.ndim == 2)
        ins = [a.T if a.ndim == 2 else a for a in args]
        out = self._map(name, n)(*ins)
        out = out if isinstance(out, (list, tuple)) else [out]
        return [_np(o) for o in out]


_EVALUATORS: dict[tuple, Evaluator] = {}


def evaluator(
    convention: str, eligible: np.ndarray | None = None, orientation: bool = False, general: bool = False
) -> Evaluator:
    """Shared :class:`Evaluator` per convention, parameter eligibility, orientation rows and chain
    form (``general``: end transforms, a URDF chain)."""
    key = (convention, None if eligible is None else tuple(bool(x) for x in eligible), orientation, general)
    ev = _EVALUATORS.get(key)
    if ev is None:
        if len(_EVALUATORS) > 8:
            _EVALUATORS.clear()
        ev = _EVALUATORS[key] = Evaluator(convention, eligible, orientation, general)
    return ev


def evaluator_for(robot: Robot, const: np.ndarray | None = None) -> Evaluator:
    """The shared :class:`Evaluator` of a robot (its convention and eligible parameters) and,
    when given, a model's constant vector (the parameters in use, see ``make_layout``; orientation
    rows when its ``measured_frame.on`` is set)."""
    orient = const is not None and float(get_const(const, "measured_frame.on")[0]) > 0.5
    return evaluator(robot.convention, make_layout(robot, const).eligible, orient, robot.has_chain_transforms)


def time_reference(m: Measurements) -> tuple[float, float]:
    """``(t_start, t_span)`` of the campaign, s (row numbers when there is no ``t``).

    Drift is measured from the first measurement, where the instrument (and, for
    registered data, the registration) is taken as exact."""
    t = m.t if m.t is not None else np.arange(m.n, dtype=float)
    lo, hi = float(np.min(t)), float(np.max(t))
    return lo, max(hi - lo, 1e-9)


def make_rows(
    m: Measurements, time_ref: tuple[float, float] | None, temperature_ref: float, use_time: bool = True
) -> np.ndarray:
    """Per-row inputs of the CasADi functions, shape (N, ROW_SIZE).

    ``[q_c (6) rad, F (6) N and N*m (base frame), tn (1), dT (1) K]``: ``tn`` is the
    time since ``time_ref[0]`` over ``time_ref[1]`` (zero without a time reference),
    ``dT`` the temperature (else ``temperature_ref``, deg C) minus 20 deg C.
    """
    rows = np.zeros((m.n, fx.ROW_SIZE))
    rows[:, 0:6] = m.q
    rows[:, 6:12] = m.wrench
    if use_time and time_ref is not None:
        t = m.t if m.t is not None else np.arange(m.n, dtype=float)
        rows[:, 12] = (t - time_ref[0]) / time_ref[1]
    temp = m.temperature if m.temperature is not None else np.full(m.n, temperature_ref)
    rows[:, 13] = temp - fx.THERMAL_REFERENCE_C
    return rows


@dataclass
class FitProblem:
    """Data and fixed inputs of one identification.

    Attributes
    ----------
    m : Measurements
    layout : ModelLayout
    ev : Evaluator
    rows : ndarray, shape (N, ROW_SIZE)
    const : ndarray
        Constant vector of the model graph.
    weights : ndarray, shape (N,)
        ``1/sigma`` (1/m) or ones.
    folds : ndarray of int, shape (N,)
        Cross-validation fold per row.
    lower, upper : ndarray, shape (N_PARAMS,)
        Parameter bounds, SI.
    is_pos : ndarray of bool, shape (N,)
        Position rows (the others are orientation rows of 6-D data, :func:`with_orientation_rows`).
    """

    m: Measurements
    layout: ModelLayout
    ev: Evaluator
    rows: np.ndarray
    const: np.ndarray
    weights: np.ndarray
    folds: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    is_pos: np.ndarray | None = None

    @property
    def pos(self) -> np.ndarray:
        """Position rows (bool, (N,))."""
        return np.ones(self.m.n, dtype=bool) if self.is_pos is None else self.is_pos


def with_orientation_rows(m: Measurements) -> tuple[Measurements, np.ndarray]:
    """6-D data as rows of 3: the N position rows, then N orientation rows (same commands, loads,
    times and pose ids; measured value 0, the model's output there being the orientation error).

    Returns the table (2N rows; ``p`` of the orientation rows is zero) and ``is_pos`` (2N,)."""
    n = m.n

    def two(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else np.concatenate([a, a])

    mx = Measurements(
        q=two(m.q),
        wrench=two(m.wrench),
        p=np.vstack([m.p, np.zeros((n, 3))]),
        t=two(m.t),
        point=two(m.point),
        rotation=two(m.rotation),
        temperature=two(m.temperature),
        sigma=two(m.sigma),
        line=two(m.line),
        source=m.source,
        units=dict(m.units),
        sigma_xyz=two(m.sigma_xyz),
        sigma_rot=two(m.sigma_rot),
    )
    return mx, np.concatenate([np.ones(n, dtype=bool), np.zeros(n, dtype=bool)])


def row_weights(m: Measurements, is_pos: np.ndarray, rot_weight: float = 1.0) -> np.ndarray:
    """Weights (N, 3) of the rows of ``m`` (after :func:`with_orientation_rows`): ``1/sigma`` per axis
    of the position rows (1/m; ones without sigma) and of the orientation rows (1/rad; without
    ``sigma_rot``, ``rot_weight`` m/rad, which with unit position weights makes 1 rad count as
    ``rot_weight`` metres)."""
    w = np.ones((m.n, 3))
    sx = getattr(m, "sigma_xyz", None)
    if sx is not None:
        w[is_pos] = 1.0 / np.asarray(sx)[is_pos]
    elif m.sigma is not None:
        w[is_pos] = 1.0 / np.asarray(m.sigma)[is_pos][:, None]
    if (~is_pos).any():
        sr = getattr(m, "sigma_rot", None)
        w[~is_pos] = (1.0 / np.asarray(sr)[~is_pos]) if sr is not None else rot_weight
    return w


def _knots_from(tau: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Hardening knots (6, N_KNOTS), N*m: quantiles of the nonzero |tau| per joint.

    ``tau`` (N, 6) joint torques, N*m; ``ts`` (6,) torque scales, N*m (the knots of a
    joint with fewer than 10 nonzero torques are fixed fractions of its scale)."""
    tau = np.abs(tau)
    knots = np.outer(ts, fx.HARDENING_KNOT_QUANTILES)
    for j in range(6):
        nz = tau[:, j][tau[:, j] > 1e-9 * ts[j]]
        if len(nz) >= 10:
            knots[j] = np.quantile(nz, fx.HARDENING_KNOT_QUANTILES)
    return knots


def torque_scale(prob_robot: Robot, m: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint torque scale (90th percentile of |J^T F| over the data), N*m, (6,),
    and hardening knots (quantiles of the nonzero |J^T F|), N*m, (6, N_KNOTS)."""
    layout = make_layout(prob_robot)
    const = make_const(prob_robot, np.eye(3), np.ones(6), False)
    te, _tg, _q = evaluator_for(prob_robot).call(
        "torques", m.q, m.wrench, np.zeros((m.n, 1)), np.zeros(N_PARAMS) + layout.nominal, const
    )
    tau = np.abs(np.asarray(te).T)
    ts = np.maximum(np.percentile(tau, 90, axis=0), fx.TORQUE_SCALE_FLOOR_NM)
    return ts, _knots_from(tau, ts)


def update_knots(prob: FitProblem, fit: ModelFit) -> FitProblem:
    """Place the hardening knots on the joint torques the current model applies (external
    plus, when ``gravity`` is on, self-weight): only while hardening is not active."""
    rows = prob.rows
    te, tg, _q = prob.ev.call("torques", rows[:, 0:6], rows[:, 6:12], rows[:, 13:14], fit.theta, prob.const)
    tau = np.asarray(te).T + np.asarray(tg).T
    c = set_const(prob.const, "hardening.knots", _knots_from(tau, get_const(prob.const, "tau_scale")).reshape(-1))
    return replace(prob, const=c)


def gravity_problem(prob: FitProblem, on: bool) -> FitProblem:
    """The same problem with the self-weight torques switched on or off."""
    c = set_const(prob.const, "gravity.on", [1.0 if on else 0.0])
    return replace(prob, const=c)


def nominal_points(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Nominal TCP positions for joints ``q`` (N, 6) rad: base frame, m, (N, 3), without
    compiling anything."""
    layout = make_layout(robot)
    rows = np.zeros((len(q), fx.ROW_SIZE))
    rows[:, :6] = q
    const = make_const(robot, np.eye(3), np.ones(6), False)
    p, _q = evaluator_for(robot).measure(rows, layout.nominal, const)
    return p


def nominal_tcp(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Nominal-FK TCP frames of joints ``q`` (N, 6) rad: ``tcp2base``, (N, 4, 4), m, via
    ``Function.map`` (no compilation)."""
    km = KinematicModel(robot)
    n = len(q)
    T = np.asarray(km.fk_tcp.map(n, "thread", 2)(q.T))
    return T.reshape(4, n, 4).transpose(1, 0, 2)


def nominal_gravity_torque(robot: Robot, m: Measurements) -> np.ndarray | None:
    """Nominal gravity torques (N*m, (N, 6)) from the robot's masses, or a generic
    proxy (unit masses at the link mid-points) when the file gives none."""
    layout = make_layout(robot)
    theta = layout.nominal.copy()
    if not robot.has_masses:
        s = GROUP_SLICES["gravity.m"]
        theta[s] = 1.0
        h = np.zeros((6, 3))
        h[:, 0] = -robot.a / 2.0
        theta[GROUP_SLICES["gravity.h"]] = h.reshape(-1)
    const = make_const(robot, np.eye(3), np.ones(6), True)
    ev = evaluator_for(robot)
    _te, tg, _q = ev.call("torques", m.q, np.zeros((m.n, 6)), np.zeros((m.n, 1)), theta, const)
    return np.asarray(tg).T
