"""The Jacobians of a campaign design (:mod:`.design`): its parameter vector and every row in it.

The design's parameter vector (:class:`DesignLayout`: the model's free parameters, the new
campaign's registration block, one block per earlier campaign but the last), a Jacobian placed in
it (:func:`place_columns`), the evaluation poses' (:func:`eval_jacobian`) and the earlier
campaigns' (:func:`earlier_rows`) Jacobians, the column scales (:func:`column_scale`) and the
selection's problem with the potential terms of the model-robust design
(:func:`selection_problem`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from models import effects as fx
from models.arm import ArmModel

from ..measurements import Measurements
from .uncertainty import beyond_range, parameter_jacobian, to_base_frame

#: Prior standard deviation of each potential term, rad (a gear's periodic error), at least: beyond the
#: model's identified range a knot's prior is the calibrated growth of its sigma there
#: (:func:`potential_prior`).
DESIGN_POTENTIAL_SIGMA_RAD = 1e-4
#: Knots per joint of the potential terms when the evaluation poses lie beyond the model's identified
#: ranges and its sigma grows there (:func:`auto_knots`).
DESIGN_TRANSFER_KNOTS = 8


def auto_knots(model: ArmModel, eval_q: np.ndarray, requested: int | None) -> int:
    """The potential terms' knots per joint: ``requested`` when given, else :data:`DESIGN_TRANSFER_KNOTS`
    when some evaluation pose (``eval_q`` (N, 6), rad) lies beyond the model's identified joint ranges and
    its sigma grows there (``sigma_growth_rad_per_rad`` > 0), else 0 (the model's parameters alone)."""
    if requested is not None:
        return max(0, int(requested))
    if not model.sigma_growth_rad_per_rad or model.joint_range_rad is None:
        return 0
    return DESIGN_TRANSFER_KNOTS if beyond_range(model, np.atleast_2d(eval_q)).any() else 0


def potential_prior(model: ArmModel, centres: np.ndarray) -> np.ndarray:
    """Prior standard deviation of each potential term (6, K), rad: :data:`DESIGN_POTENTIAL_SIGMA_RAD`, or
    beyond the identified range the model's calibrated growth there (``g`` times the knot's distance
    beyond the range, :mod:`.sigma_calibration`), whichever is larger."""
    tau = np.full(centres.shape, DESIGN_POTENTIAL_SIGMA_RAD)
    if model.sigma_growth_rad_per_rad and model.joint_range_rad is not None:
        tau = np.maximum(tau, model.sigma_growth_rad_per_rad * beyond_range(model, centres.T).T)
    return tau


@dataclass
class DesignLayout:
    """The design's parameter vector: the model's free parameters, then the new campaign's
    registration block, then one registration block per earlier campaign but the one whose registration
    is the model's own (:func:`own_campaign`)."""

    names: list[str]
    k: int
    reg_idx: np.ndarray  # positions of the registration columns within the first k
    new_reg: np.ndarray | None  # columns of the new campaign's registration block (or None: shared)
    earlier_reg: list[np.ndarray | None]  # per earlier file: its own block (None: the model's)

    @property
    def size(self) -> int:
        return len(self.names)


def own_campaign(model: ArmModel, n_earlier: int) -> int:
    """Index of the earlier campaign whose registration is the model's own: when the model's campaigns
    match the earlier files one for one (a several-campaign fit), its reference campaign (the one with
    the model's registration), else the last."""
    if len(model.campaigns) == n_earlier and n_earlier > 1:
        own = model.base2meas()
        for e, c in enumerate(model.campaigns):
            if np.allclose(c.base2meas, own, rtol=0.0, atol=1e-12):
                return e
    return n_earlier - 1


def design_layout(names: list[str], n_earlier: int, new_registration: bool, own: int | None = None) -> DesignLayout:
    """The layout of :class:`DesignLayout`; ``own``: the earlier campaign with the model's registration
    (default: the last)."""
    own = n_earlier - 1 if own is None else own
    k = len(names)
    reg = np.array([i for i, n in enumerate(names) if n in fx.REGISTRATION_NAMES], dtype=int)
    out = list(names)
    new_reg = None
    if new_registration and len(reg):
        new_reg = np.arange(len(out), len(out) + len(reg))
        out += [f"{names[i]} (new campaign)" for i in reg]
    earlier_reg: list[np.ndarray | None] = []
    for e in range(n_earlier):
        if e == own or not len(reg):
            earlier_reg.append(None)
        else:
            earlier_reg.append(np.arange(len(out), len(out) + len(reg)))
            out += [f"{names[i]} (earlier campaign {e + 1})" for i in reg]
    return DesignLayout(out, k, reg, new_reg, earlier_reg)


def place_columns(J: np.ndarray, lay: DesignLayout, reg_block: np.ndarray | None) -> np.ndarray:
    """A Jacobian over the model's k free parameters (N, 3, k) in the design's layout, its
    registration columns moved into ``reg_block`` (None: kept in place)."""
    out = np.zeros(J.shape[:2] + (lay.size,))
    out[:, :, : lay.k] = J
    if reg_block is not None and len(lay.reg_idx):
        out[:, :, reg_block] = J[:, :, lay.reg_idx]
        out[:, :, lay.reg_idx] = 0.0
    return out


def _model_for_earlier(model: ArmModel, e: int, n_earlier: int) -> ArmModel:
    """The model with earlier campaign ``e``'s registration when the model's campaigns match the
    earlier files one for one (a several-campaign fit), else the model itself."""
    if len(model.campaigns) == n_earlier and n_earlier > 1:
        return model.for_campaign(model.campaigns[e].name)
    return model


def eval_jacobian(
    model: ArmModel, q: np.ndarray, wrench: np.ndarray | None, names: list[str], lay: DesignLayout, frame: str
) -> np.ndarray:
    _p, J = parameter_jacobian(model, q, wrench, names)
    if frame == "base":
        return place_columns(to_base_frame(model, J, names), lay, None)
    return place_columns(J, lay, lay.new_reg)


def _with_potential(
    J: np.ndarray,
    model: ArmModel,
    q: np.ndarray,
    wrench: np.ndarray | None,
    knots: int,
    frame: str,
    q_range: np.ndarray,
) -> np.ndarray:
    """``J`` (N, 3, p) with the potential terms' columns appended (N, 3, p + 6 K), scaled by their prior
    standard deviations (:func:`potential_prior`):
    joint ``j``'s angular error as hat functions of ``q_j`` on ``K = knots`` evenly spaced knots over
    ``q_range[j]`` (rad, (6, 2): the evaluation poses' range; zero outside it), acting through
    ``dp/ddtheta_j`` (the joint's angle offset; in the base frame rotated as
    :func:`~.uncertainty.to_base_frame`)."""
    if knots <= 0:
        return J
    names = [f"dtheta[{j}]" for j in range(1, 7)]
    _p, Jt = parameter_jacobian(model, q, wrench, names)
    if frame == "base":
        Jt = to_base_frame(model, Jt, names)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    lo, hi = q_range[:, 0], q_range[:, 1]
    width = np.maximum(hi - lo, 1e-9) / max(knots - 1, 1)
    centres = lo[:, None] + width[:, None] * np.arange(knots)  # (6, K)
    u = np.abs(q[:, :, None] - centres[None]) / width[None, :, None]  # (N, 6, K)
    inside = ((q >= lo - 1e-12) & (q <= hi + 1e-12))[:, :, None]
    basis = np.where(inside, np.maximum(1.0 - u, 0.0), 0.0) if knots > 1 else inside.astype(float)
    basis = basis * potential_prior(model, centres)[None]
    K = (Jt[:, :, :, None] * basis[:, None, :, :]).reshape(len(q), 3, -1)
    return np.concatenate([J, K], axis=2)


def earlier_rows(
    model: ArmModel, earlier: Sequence[Measurements], names: list[str], lay: DesignLayout, s: float
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The earlier campaigns' Jacobians placed in the design's layout (each with its own registration
    block but the last), unscaled, and their row weights ``1/sigma`` (the file's, else ``s``)."""
    J_rows: list[np.ndarray] = []
    w_rows: list[np.ndarray] = []
    for e, m in enumerate(earlier):
        me = _model_for_earlier(model, e, len(earlier))
        _pe, Jx = parameter_jacobian(me, m.q, m.wrench, names)
        J_rows.append(place_columns(Jx, lay, lay.earlier_reg[e]))
        se = np.asarray(m.sigma, dtype=float) if m.sigma is not None else np.full(m.n, s)
        w_rows.append(1.0 / se)
    return J_rows, w_rows


def column_scale(rows: list[np.ndarray]) -> np.ndarray:
    """Column scales: unit RMS over the rows (N, 3, k) that carry each column (1 for none)."""
    ss = sum(np.einsum("nik,nik->k", R, R) for R in rows)
    cnt = sum(len(R) * 3 * np.any(R != 0, axis=(0, 1)) for R in rows)
    return np.where(ss > 0, np.sqrt(ss / np.maximum(cnt, 1)), 1.0)


def selection_problem(
    model: ArmModel,
    pool: Measurements,
    Jc: np.ndarray,
    Jev: np.ndarray,
    eq: np.ndarray,
    ew: np.ndarray | None,
    eval_frame: str,
    earlier: Sequence[Measurements],
    Je_rows: list[np.ndarray],
    w_rows: list[np.ndarray],
    scale: np.ndarray,
    I0p: np.ndarray,
    potential_knots: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The selection's pool and evaluation Jacobians and prior information: the model's own (scaled)
    with, when ``potential_knots`` > 0, the potential terms appended (scaled by their prior sigma
    :func:`potential_prior`: prior information 1 each, and what the earlier data say of them)."""
    H = max(0, int(potential_knots))
    n_prim = len(I0p)
    q_range = np.column_stack([eq.min(axis=0), eq.max(axis=0)])
    Jca = _with_potential(Jc, model, pool.q, pool.wrench, H, "measurement", q_range)
    Jeva = _with_potential(Jev, model, eq, ew, H, eval_frame, q_range)
    I0 = np.zeros((Jca.shape[2], Jca.shape[2]))
    I0[:n_prim, :n_prim] = I0p
    if H:
        I0[n_prim:, n_prim:] += np.eye(Jca.shape[2] - n_prim)
        for e, (Jx, w, m) in enumerate(zip(Je_rows, w_rows, earlier)):
            me = _model_for_earlier(model, e, len(earlier))
            K = _with_potential(np.zeros(Jx.shape[:2] + (0,)), me, m.q, m.wrench, H, "measurement", q_range)
            Jw = np.concatenate([Jx / scale, K], axis=2) * w[:, None, None]
            I0[:n_prim, n_prim:] += np.einsum("nik,nil->kl", Jw[:, :, :n_prim], Jw[:, :, n_prim:])
            I0[n_prim:, :n_prim] = I0[:n_prim, n_prim:].T
            I0[n_prim:, n_prim:] += np.einsum("nik,nil->kl", Jw[:, :, n_prim:], Jw[:, :, n_prim:])
    return Jca, Jeva, I0
