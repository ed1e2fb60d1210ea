"""The cutting force of an engaged end mill: the mechanistic (linear edge-force) model.

Source: Y. Altintas, *Manufacturing Automation*, 2nd ed., Cambridge University Press, 2012, ch. 2
(the mechanics of milling: sections 2.3-2.5, the flat end mill's average forces and the general /
ball-end mill's differential forces).

Model
-----
The cutter is cut into axial slices of height ``dz`` (the engagement mask's, :mod:`.engagement`).  An
edge element at height ``z`` above the tip and immersion angle ``phi`` (the mask's angle bin centre)
removes a chip of thickness ``h = c sin(phi) sin(kappa)`` (``c`` the feed per tooth, m; ``kappa`` the
axial immersion angle of :class:`.cutter.EndMill`) and width ``db = dz / sin(kappa)``; it cuts only
where its mask cell is true and ``h > 0`` (cells beyond ``phi = pi`` never cut).  Its tangential,
radial and axial forces are::

    dFt = Ktc h db + Kte dS,   dFr = Krc h db + Kre dS,   dFa = Kac h db + Kae dS

``h db = c sin(phi) dz`` for every edge shape.  **Edge length** ``dS``: the length of the edge's
meridian (its trace in the axial plane through the point), ``r dkappa`` on a corner of radius ``r``
and ``dz`` on the flank.  On the flank this is Altintas' flat-end-mill model (edge force ``Kte dz``
per slice), the model with which published coefficients are identified (mean slot forces of flat end
mills, linear in the feed); on a ball it is Altintas' ball-end ``dS`` without its helical term
``rho dpsi`` (book: ``dS = sqrt(drho^2 + dz^2 + (rho dpsi)^2)``), which would make the flank's edge
force ``Kte dz / cos(beta)``, 15 % more at a 30 deg helix than the coefficients were identified with,
and would jump there at the ball's equator.  With this choice a cell's force does not depend on the
helix; the helix only shifts it in time.

Each slice's forces are the exact integrals over its height (closed form on the flank, Gauss-Legendre
in ``kappa`` on a corner, where ``sin(kappa)`` varies like ``sqrt(z)`` near a ball's tip), moments
included; only the angle is sampled at the bin centres (a midpoint sum, about ``1e-5`` relative on 1
deg bins).

The forces ON THE TOOL in the sample's **feed frame** (origin at the tool tip, ``x`` the feed, ``z``
the tool axis towards the spindle, ``y = z x x``; for a clockwise spindle the edge point is
``(rho sin phi, rho cos phi, z)``, ``docs/cutting.md``)::

    [dFx]   [-sin k sin phi   -cos phi   -cos k sin phi] [dFr]
    [dFy] = [-sin k cos phi    sin phi   -cos k cos phi] [dFt]
    [dFz]   [ cos k               0      -sin k        ] [dFa]

so on the flank ``dFz = -dFa``: a positive ``Kac`` pulls the tool down towards the work.  The moment
about the tool tip is ``r x dF`` (``r`` the edge point); its ``z`` part is ``rho dFt``, the resisting
torque of the cut, positive about ``+z`` (the spindle turns the other way, clockwise seen from
``+z``).  A wrench is ``[Fx, Fy, Fz, Mx, My, Mz]`` (N, N m).  For a counter-clockwise spindle the mask
is made in the mirrored frame and the caller mirrors the result (``Fy, Mx, Mz`` change sign).

At rotation ``theta`` flute ``n`` of ``N`` is at ``phi = theta + 2 pi n / N - psi(z)`` at height
``z`` (``psi`` the helix lag, :meth:`.cutter.EndMill.lag_rad`); its cell is the angle bin holding
that angle.  Averaged over a revolution every flute passes every bin once, so the **mean wrench** is
``N / J sum_{k, j} mask[k, j] w(k, j)`` (``J`` angle bins, ``w`` the cell's wrench): it does not depend
on the helix and is linear in the six coefficients, ``mean = D @ [Ktc, Krc, Kac, Kte, Kre, Kae]``
(:func:`mean_force_design`).  The **instantaneous wrench** (:func:`instantaneous_wrench`) sums, per
rotation, the cells under each flute's edge (each slice's angle snapped to its bin, +-half a bin);
the **peak force** of :func:`cut_wrench` is its largest ``|F|`` over :data:`ROTATION_STEPS_PER_TOOTH`
rotations of one tooth period (the pattern repeats every ``2 pi / N``).  Both are matrix products of
the flattened ``(K, J)`` mask with per-cell weights, over chunks of samples and the engaged slices.

Limits: no force of the bottom (end) cutting edges of a flat mill (plunging, ramping); no run-out
(all flutes cut the same chip); no tool or workpiece deflection fed back into the chip; no size
effect (coefficients constant in ``h``, no minimum chip thickness); no process damping or dynamics;
the mask's resolution (angle bins, slices) is the model's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import InputError
from .cutter import EndMill
from .engagement import EngagementBatch
from .material import CuttingCoefficients

__all__ = [
    "MAX_FEED_PER_TOOTH_M",
    "ROTATION_STEPS_PER_TOOTH",
    "CutWrench",
    "cut_wrench",
    "instantaneous_wrench",
    "mean_force_design",
]

#: Rotation positions per tooth period at which the instantaneous force is evaluated for its peak
#: (the force pattern repeats every tooth period 2 pi / N).
ROTATION_STEPS_PER_TOOTH = 36
#: A feed per tooth above this (m) is taken for a unit mistake (mm given as m): high-feed mills run
#: at most about 2-3 mm per tooth.
MAX_FEED_PER_TOOTH_M = 5e-3
#: Memory bound of one chunk of samples' float mask (bytes).
CHUNK_BYTES = 32 * 2**20
#: Gauss-Legendre points per slice on a corner (torus or ball) for the slice's integrals.
CORNER_GAUSS_POINTS = 6
#: Memory bound of the instantaneous wrench's weight matrix (bytes; rotations are taken in blocks).
WEIGHT_BYTES = 64 * 2**20


@dataclass(frozen=True)
class CutWrench:
    """The cutting load of ``S`` samples (forces on the tool, feed frame, moments about the tool tip).

    Attributes
    ----------
    mean : ndarray, shape (S, 6)
        Mean wrench over a spindle revolution ``[Fx, Fy, Fz, Mx, My, Mz]``, N and N m.
    peak_force_N : ndarray, shape (S,)
        Largest ``|F(theta)|`` over the revolution, N (nan when not computed).
    """

    mean: np.ndarray
    peak_force_N: np.ndarray

    @property
    def torque_Nm(self) -> np.ndarray:
        """Mean cutting torque about the tool axis the spindle supplies, N m, shape (S,) (``Mz``)."""
        return self.mean[:, 5]

    def power_W(self, spindle_rad_s: np.ndarray | float) -> np.ndarray:
        """Mean cutting power ``torque * |spindle speed|``, W, shape (S,) (speed in rad/s)."""
        return self.torque_Nm * np.abs(np.asarray(spindle_rad_s, dtype=float))


def _feed(feed_per_tooth_m: np.ndarray | float, n: int) -> np.ndarray:
    """The feed per tooth of each of ``n`` samples, m, shape (n,), checked."""
    c = np.asarray(feed_per_tooth_m, dtype=float)
    if c.ndim == 0:
        c = np.full(n, float(c))
    elif c.shape != (n,):
        raise InputError(f"feed per tooth must have shape ({n},) (one per sample) or be a number, got {c.shape}")
    bad = ~(np.isfinite(c) & (c >= 0.0) & (c <= MAX_FEED_PER_TOOTH_M))
    if bad.any():
        i = int(np.argmax(bad))
        hint = " (mm given as m?)" if np.isfinite(c[i]) and c[i] > MAX_FEED_PER_TOOTH_M else ""
        limit = MAX_FEED_PER_TOOTH_M
        raise InputError(f"feed per tooth of sample {i} must be in [0, {limit:g}] m, got {c[i]!r} m{hint}")
    return c


def _half_bins(n_angles: int) -> int:
    """Angle bins whose centre is at most pi (the only ones where ``h = c sin(phi) sin(kappa) > 0``)."""
    return (n_angles + 1) // 2


def _slice_integrals(mill: EndMill, z0: np.ndarray, z1: np.ndarray) -> np.ndarray:
    """Integrals over each slice ``[z0, z1]`` of the edge, shape (3, 6, K): arms ``1, rho, z`` (m^0,
    m, m) times the weights ``dz, sin(kappa) dz, cos(kappa) dz`` (the chip's, per unit
    ``c sin(phi)``) and ``dS, sin(kappa) dS, cos(kappa) dS`` (the edge's; ``dS = r dkappa`` on the
    corner, ``dz`` on the flank), m.  Closed form on the flank, Gauss-Legendre in ``kappa`` on the
    corner (smooth there: exact to rounding)."""
    R, r = mill.radius_m, mill.corner_radius_m
    za = np.maximum(z0, r)
    length = np.maximum(z1 - za, 0.0)
    zb = za + length
    flank = np.array([length, length, 0.0 * length, length, length, 0.0 * length])
    out = np.stack([flank, R * flank, 0.5 * (zb * zb - za * za) * (flank > 0.0)])
    if r == 0.0:
        return out
    k0, k1 = (np.arccos(np.clip((r - np.minimum(z, r)) / r, -1.0, 1.0)) for z in (z0, z1))
    x, w = np.polynomial.legendre.leggauss(CORNER_GAUSS_POINTS)
    kap = 0.5 * (k0 + k1)[:, None] + 0.5 * (k1 - k0)[:, None] * x[None, :]
    wk = 0.5 * (k1 - k0)[:, None] * w[None, :]
    sk, ck = np.sin(kap), np.cos(kap)
    arms = (np.ones_like(kap), (R - r) + r * sk, r * (1.0 - ck))
    per = (r * sk, r * sk * sk, r * sk * ck, r + 0.0 * sk, r * sk, r * ck)
    out = out + np.array([[(arm * p * wk).sum(axis=1) for p in per] for arm in arms])
    return out


@lru_cache(maxsize=16)
def _cell_design(mill: EndMill, n_slices: int, dz_m: float, n_angles: int) -> np.ndarray:
    """Wrench of each cell per unit coefficient, shape (K, Jh, 6, 6): rows ``[F, M]``, columns the six
    coefficients; the three cutting columns per unit feed per tooth (m)."""
    jh = _half_bins(n_angles)
    phi = (np.arange(jh) + 0.5) * (2.0 * math.pi / n_angles)
    z0 = np.arange(n_slices) * dz_m
    z1 = np.maximum(np.minimum(z0 + dz_m, mill.flute_length_m), z0)
    ints = _slice_integrals(mill, z0, z1)[:, :, :, None]  # (arm, weight, K, 1)
    sp, cp = np.sin(phi)[None, :], np.cos(phi)[None, :]
    zero = np.zeros((n_slices, jh))
    chip = np.maximum(sp, 0.0)  # h db = c sin(phi) dz

    def forces(arm: int) -> np.ndarray:
        """Forces on the tool per unit coefficient (K, Jh, 6, 3), weighted by the arm."""
        cols = []
        for (p, s, c), scale in ((ints[arm, :3], chip), (ints[arm, 3:], np.ones_like(chip))):
            f_t = np.stack([-cp * p, sp * p, zero], axis=-1)
            f_r = np.stack([-sp * s, -cp * s, c + zero], axis=-1)
            f_a = np.stack([-sp * c, -cp * c, -s + zero], axis=-1)
            cols += [f * scale[..., None] for f in (f_t, f_r, f_a)]
        return np.stack(cols, axis=2)

    e_rho = np.stack(np.broadcast_arrays(sp, cp, zero), axis=-1)[:, :, None, :]
    e_z = np.array([0.0, 0.0, 1.0])
    moment = np.cross(e_rho, forces(1)) + np.cross(e_z, forces(2))
    g = np.concatenate([forces(0), moment], axis=-1).transpose(0, 1, 3, 2).copy()
    g.setflags(write=False)
    return g


@lru_cache(maxsize=16)
def _mean_basis(mill: EndMill, n_slices: int, dz_m: float, n_angles: int) -> tuple[np.ndarray, np.ndarray]:
    """The cell wrenches factored as ``G[k, j] = sum_b A[k, b] B[j, b]`` over the angle functions
    ``B = [1, sin, cos, sin^2, sin cos](phi_j)`` (every entry of a cell's wrench is one of their
    combinations): ``B`` (Jh, 5) and ``A`` (K, 5, 36), so that a sample's sum over the mask costs five
    products per cell instead of 36."""
    g = _cell_design(mill, n_slices, dz_m, n_angles)
    jh = g.shape[1]
    phi = (np.arange(jh) + 0.5) * (2.0 * math.pi / n_angles)
    s, c = np.sin(phi), np.cos(phi)
    basis = np.stack([np.ones_like(phi), s, c, s * s, s * c], axis=1)
    flat = g.transpose(1, 0, 2, 3).reshape(jh, -1)
    coef = np.linalg.lstsq(basis, flat, rcond=None)[0]  # exact: the wrench lies in the span
    coef = coef.reshape(5, n_slices, 36).transpose(1, 0, 2).copy()
    return basis, coef


def _chunks(batch: EngagementBatch, bytes_per_value: int):
    """Yield ``(s0, s1, k0, k1)``: sample chunks and the range of slices engaged in each."""
    jh = _half_bins(batch.n_angles)
    per_sample = max(batch.n_slices * jh * bytes_per_value, 1)
    step = max(1, CHUNK_BYTES // per_sample)
    for s0 in range(0, batch.n_samples, step):
        s1 = min(s0 + step, batch.n_samples)
        active = np.flatnonzero(batch.mask[s0:s1, :, :jh].any(axis=(0, 2)))
        if active.size:
            yield s0, s1, int(active[0]), int(active[-1]) + 1


def mean_force_design(mill: EndMill, batch: EngagementBatch, feed_per_tooth_m: np.ndarray | float) -> np.ndarray:
    """The linear map from the cutting coefficients to the mean wrench over a spindle revolution.

    Parameters
    ----------
    mill : EndMill
    batch : EngagementBatch
        The engagement of ``S`` samples (mask ``(S, K, J)``).
    feed_per_tooth_m : array_like, shape (S,) or scalar
        Feed per tooth ``c``, m.

    Returns
    -------
    ndarray, shape (S, 6, 6)
        ``D`` with ``mean wrench = D @ [Ktc, Krc, Kac, Kte, Kre, Kae]`` (coefficients in N/m^2 and
        N/m): rows ``[Fx, Fy, Fz, Mx, My, Mz]`` on the tool in the feed frame, moments about the tool
        tip (N, N m).  Zero for a sample in air.
    """
    c = _feed(feed_per_tooth_m, batch.n_samples)
    basis, coef = _mean_basis(mill, batch.n_slices, float(batch.dz_m), batch.n_angles)
    jh = basis.shape[0]
    out = np.zeros((batch.n_samples, 6, 6))
    scale = mill.flutes / batch.n_angles
    for s0, s1, k0, k1 in _chunks(batch, 8):
        n, nk = s1 - s0, k1 - k0
        x = batch.mask[s0:s1, k0:k1, :jh].reshape(n * nk, jh).astype(np.float64)
        sums = (x @ basis).reshape(n, nk * 5)
        d = (sums @ coef[k0:k1].reshape(nk * 5, 36)).reshape(n, 6, 6) * scale
        d[:, :, :3] *= c[s0:s1, None, None]
        out[s0:s1] = d
    return out


def _rotation_weights(
    mill: EndMill,
    coeffs: CuttingCoefficients,
    batch: EngagementBatch,
    theta: np.ndarray,
    rows: int,
    slices: slice,
) -> np.ndarray:
    """Weights ``(K', Jh, T, rows, 2)`` of the slices ``slices``: the wrench rows at rotation
    ``theta[t]`` of a true cell, its cutting part per unit feed ``[..., 0]`` and its edge part
    ``[..., 1]``."""
    g = _cell_design(mill, batch.n_slices, float(batch.dz_m), batch.n_angles)[slices]
    n_slices, jh = g.shape[:2]
    k = coeffs.as_vector()
    gc = g[:, :, :rows, :3] @ k[:3]
    ge = g[:, :, :rows, 3:] @ k[3:]
    lag = mill.lag_rad(batch.slice_heights_m()[slices])
    w = np.zeros((n_slices, jh, theta.size, rows, 2))
    width = 2.0 * math.pi / batch.n_angles
    ks, ts = np.meshgrid(np.arange(n_slices), np.arange(theta.size), indexing="ij")
    for n in range(mill.flutes):
        ang = theta[None, :] + 2.0 * math.pi * n / mill.flutes - lag[:, None]
        j = np.floor(np.mod(ang, 2.0 * math.pi) / width).astype(int) % batch.n_angles
        on = j < jh
        kk, jj, tt = ks[on], j[on], ts[on]
        w[kk, jj, tt, :, 0] += gc[kk, jj]
        w[kk, jj, tt, :, 1] += ge[kk, jj]
    return w


def instantaneous_wrench(
    mill: EndMill,
    coeffs: CuttingCoefficients,
    batch: EngagementBatch,
    feed_per_tooth_m: np.ndarray | float,
    rotation_rad: np.ndarray,
    rows: int = 6,
    dtype: type = np.float64,
) -> np.ndarray:
    """The wrench at given spindle rotations (all flutes, with the helix lag).

    Parameters
    ----------
    mill, coeffs, batch, feed_per_tooth_m
        As :func:`cut_wrench`.
    rotation_rad : array_like, shape (T,)
        Rotation ``theta`` of flute 0's tip edge from ``+y`` (the direction of ``phi``), rad.
    rows : int
        3: forces only; 6: the wrench.
    dtype : numpy float type
        Precision of the product (float32: about 1e-6 relative, twice as fast).

    Returns
    -------
    ndarray, shape (S, T, rows)
        ``[Fx, Fy, Fz(, Mx, My, Mz)]`` on the tool, feed frame, about the tool tip (N, N m).
    """
    if rows not in (3, 6):
        raise InputError(f"instantaneous wrench rows must be 3 (forces) or 6 (wrench), got {rows!r}")
    c = _feed(feed_per_tooth_m, batch.n_samples)
    theta = np.atleast_1d(np.asarray(rotation_rad, dtype=float))
    out = np.zeros((batch.n_samples, theta.size, rows))
    jh = _half_bins(batch.n_angles)
    active = np.flatnonzero(batch.mask[:, :, :jh].any(axis=(0, 2)))
    if active.size == 0:
        return out
    lo, hi = int(active[0]), int(active[-1]) + 1
    block = max(1, min(theta.size, WEIGHT_BYTES // ((hi - lo) * jh * rows * 2 * 8)))
    for t0 in range(0, theta.size, block):
        th = theta[t0 : t0 + block]
        w = _rotation_weights(mill, coeffs, batch, th, rows, slice(lo, hi)).astype(dtype)
        for s0, s1, k0, k1 in _chunks(batch, np.dtype(dtype).itemsize):
            x = batch.mask[s0:s1, k0:k1, :jh].reshape(s1 - s0, -1).astype(dtype)
            y = (x @ w[k0 - lo : k1 - lo].reshape(-1, th.size * rows * 2)).reshape(s1 - s0, th.size, rows, 2)
            out[s0:s1, t0 : t0 + th.size] = y[..., 0] * c[s0:s1, None, None] + y[..., 1]
    return out


def cut_wrench(
    mill: EndMill,
    coeffs: CuttingCoefficients,
    batch: EngagementBatch,
    feed_per_tooth_m: np.ndarray | float,
    peak: bool = True,
) -> CutWrench:
    """The mean wrench and the peak force of each sample.

    Parameters
    ----------
    mill : EndMill
    coeffs : CuttingCoefficients
    batch : EngagementBatch
        Mask ``(S, K, J)``.
    feed_per_tooth_m : array_like, shape (S,) or scalar
        Feed per tooth, m.
    peak : bool
        Whether to evaluate the peak force (:data:`ROTATION_STEPS_PER_TOOTH` rotations of one tooth
        period, single precision); nan otherwise.

    Returns
    -------
    CutWrench
    """
    mean = mean_force_design(mill, batch, feed_per_tooth_m) @ coeffs.as_vector()
    if not peak:
        return CutWrench(mean, np.full(batch.n_samples, np.nan))
    theta = np.arange(ROTATION_STEPS_PER_TOOTH) * (2.0 * math.pi / (mill.flutes * ROTATION_STEPS_PER_TOOTH))
    f = instantaneous_wrench(mill, coeffs, batch, feed_per_tooth_m, theta, rows=3, dtype=np.float32)
    return CutWrench(mean, np.linalg.norm(f, axis=2).max(axis=1))
