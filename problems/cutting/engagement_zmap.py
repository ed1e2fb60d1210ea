"""Where the cutting edges of an end mill are in the stock: engagement masks from a z-map.

For a sample of a straight move (tip at ``p_s``, move direction ``u``), the feed frame has
``x^ = `` the horizontal part of ``u`` normalised, ``z^ = +Z`` (program frame, 3-axis) and
``y^ = z^ x x^`` for a clockwise spindle (M3) or ``-z^ x x^`` for a counter-clockwise one (M4: the
mirrored feed frame of ``docs/cutting.md``).  The edge point of slice ``k`` and angle bin ``j`` is::

    q = p_s + rho(z_k) (sin phi_j x^ + cos phi_j y^) + z_k z^

and ``mask[s, k, j]`` is True when ``q`` lies in material of the z-map **before the move is cut**,
for ``phi_j`` in ``[0, pi]`` only (the half ahead of the feed).

Lookup: the column whose cell holds ``q`` (nearest cell centre), i.e. the z-map's own model of the
stock (the union of the columns' prisms, the same one its volumes are computed on).  Bilinear
interpolation of the interval ends would invent sloped material across every wall a previous pass
left (a step of the full depth between two neighbouring columns), so edges near a wall would be
half-engaged; with the nearest cell the engaged angles are exact up to ``resolution / rho``.

Why the masks of a move may all be made before the move is removed (exactness): an earlier position
of the same move is ``p_s - a x^ - b z^`` with ``a > 0`` (behind, horizontally; ``a`` is 0 only for a
plunge, handled apart).

* Flank (``rho = R``): the earlier cutter is inside the vertical cylinder of radius ``R`` about its
  axis, and ``|R e + a x^|^2 = R^2 + 2 a R (e . x^) + a^2 > R^2`` for ``e . x^ = sin phi >= 0``: the
  front edge point is outside that cylinder, so the move cannot have removed it before.
* Corner (``rho(z) < R``, ball or bull-nose): if the move is horizontal or descends (``b >= 0``),
  the earlier cutter at the height of ``q`` is at most as wide as ``rho(z)`` (``rho`` grows with
  height, and ``q`` is no higher above the earlier tip) while ``q`` is at least ``rho(z)`` from its
  axis: outside again.  A **rising** move breaks this for the corner's lower front: there the edge
  point is tested against the solid swept from the move's start to the sample
  (:func:`problems.cutting.removal.sweep_envelope`) and dropped if it lies in it (below its surface
  by more than ``SWEEP_TOL_M``), which keeps the masks exact.

A plunge (no horizontal motion) has no feed direction: its mask is empty and it is marked ``plunge``
(the peripheral force model has no bottom-edge force; the caller reports it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.cutting.cutter import EndMill
from models.cutting.engagement import ANGLE_BINS, SLICE_HEIGHT_M, EngagementBatch
from models.errors import InputError

from .removal import sweep_envelope
from .stock import ZMap

__all__ = [
    "EDGE_ANGLE_TOL_RAD",
    "PLUNGE_TOL",
    "SWEEP_TOL_M",
    "SampleEngagement",
    "concatenate_engagements",
    "segment_engagement",
]

#: A move whose horizontal part is below this share of its length is a plunge.
PLUNGE_TOL = 1e-9
#: An edge point below the surface of the solid already swept by a rising move by more than this (m)
#: was removed by the move itself.
SWEEP_TOL_M = 1e-7
#: Entry within this of 0 (exit within it of pi) counts as starting (ending) at the edge, rad.
EDGE_ANGLE_TOL_RAD = math.radians(5.0)
#: Most edge points handled at once (bounds the temporaries of one call).
_POINTS_PER_BLOCK = 2_000_000

KINDS = ("air", "up", "down", "slot", "plunge")


@dataclass(frozen=True)
class SampleEngagement:
    """The engagement of ``S`` samples and what it means for the cut.

    Attributes
    ----------
    segment : ndarray, int, shape (S,)
        The move of each sample (index of the waypoint the move ends at).
    t : ndarray, shape (S,)
        Where on its move, 0 (start) to 1 (end).
    position_m : ndarray, shape (S, 3)
        Tool tip, program frame, m.
    batch : EngagementBatch
        The masks, shape (S, K, J).
    plunge : ndarray, bool, shape (S,)
        No horizontal motion: no mask (empty) and no peripheral force.
    axial_depth_m : ndarray, shape (S,)
        Top of the highest engaged slice above the tip, m (0 in air).
    radial_width_m : ndarray, shape (S,)
        Width of cut across the feed at the lowest engaged flank slice, ``rho (cos phi_st - cos phi_ex)``, m.
    entry_rad, exit_rad : ndarray, shape (S,)
        First and last engaged angle (bin edges) of that slice, rad (NaN in air).
    kind : ndarray, str, shape (S,)
        ``air``, ``up`` (entry at 0: conventional), ``down`` (exit at pi: climb), ``slot`` (both) or
        ``plunge``; an engagement touching neither edge is ``up`` or ``down`` by the side of its middle.
    """

    segment: np.ndarray
    t: np.ndarray
    position_m: np.ndarray
    batch: EngagementBatch
    plunge: np.ndarray
    axial_depth_m: np.ndarray
    radial_width_m: np.ndarray
    entry_rad: np.ndarray
    exit_rad: np.ndarray
    kind: np.ndarray

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])


def _n_slices(mill: EndMill, dz_m: float) -> int:
    if not (math.isfinite(dz_m) and dz_m > 0.0):
        raise InputError(f"engagement slice height must be > 0 m, got {dz_m!r}")
    return max(int(math.ceil(mill.flute_length_m / dz_m - 1e-9)), 1)


def _front_mask(zmap, mill, p0, v, ps, xh, yh, dz_m, K, J) -> np.ndarray:
    """The (S, K, J) mask of non-plunge samples ``ps`` (S, 3) of the move p0 -> p0 + v."""
    S = ps.shape[0]
    mask = np.zeros((S, K, J), dtype=bool)
    w = 2.0 * math.pi / J
    jf = int(np.count_nonzero((np.arange(J) + 0.5) * w <= math.pi))
    phi = (np.arange(jf) + 0.5) * w
    R, res = mill.radius_m, zmap.resolution_m
    # the slices that can reach material: up to the highest top near the move
    nx, ny = zmap.shape
    lo = np.floor((np.minimum(p0, p0 + v)[:2] - R - (zmap.x0_m, zmap.y0_m)) / res).astype(int)
    hi = np.ceil((np.maximum(p0, p0 + v)[:2] + R - (zmap.x0_m, zmap.y0_m)) / res).astype(int)
    sub = zmap.top_m[max(lo[0], 0) : min(hi[0], nx), max(lo[1], 0) : min(hi[1], ny)]
    top = np.fmax.reduce(sub, axis=None) if sub.size else np.nan
    if not np.isfinite(top):
        return mask
    k_act = int(np.clip(math.ceil((top - ps[:, 2].min()) / dz_m), 0, K))
    if k_act == 0:
        return mask
    zk = (np.arange(k_act) + 0.5) * dz_m
    rho = mill.radius_at(zk)
    ex = np.sin(phi)[None, :] * xh[:2, None] + np.cos(phi)[None, :] * yh[:2, None]  # (2, jf)
    corner = (v[2] > 0.0) and mill.corner_radius_m > 0.0
    per = max(_POINTS_PER_BLOCK // (k_act * jf), 1)
    for s0 in range(0, S, per):
        p = ps[s0 : s0 + per]
        X = p[:, 0, None, None] + rho[None, :, None] * ex[0][None, None, :]
        Y = p[:, 1, None, None] + rho[None, :, None] * ex[1][None, None, :]
        Z = p[:, 2, None, None] + zk[None, :, None]
        m = zmap.contains(X, Y, Z)
        if corner:
            kc = int(np.count_nonzero(zk < mill.corner_radius_m))
            for i in range(p.shape[0]):
                low, high = sweep_envelope(mill, p0, p[i], X[i, :kc], Y[i, :kc])
                m[i, :kc] &= ~((low < Z[i, :kc] - SWEEP_TOL_M) & (Z[i, :kc] <= high))
        mask[s0 : s0 + per, :k_act, :jf] = m
    return mask


def _describe(mask: np.ndarray, mill: EndMill, dz_m: float):
    """Per sample: radial width, entry, exit (lowest engaged flank slice) and kind."""
    S, K, J = mask.shape
    w = 2.0 * math.pi / J
    any_k = mask.any(axis=2)
    flank = (np.arange(K) + 0.5) * dz_m >= mill.corner_radius_m
    on_flank = any_k & flank[None, :]
    k_low = np.where(on_flank.any(axis=1), np.argmax(on_flank, axis=1), np.argmax(any_k, axis=1))
    engaged = any_k.any(axis=1)
    rows = mask[np.arange(S), k_low]  # (S, J)
    j_first = np.argmax(rows, axis=1)
    j_last = J - 1 - np.argmax(rows[:, ::-1], axis=1)
    entry = np.where(engaged, j_first * w, np.nan)
    exit_ = np.where(engaged, (j_last + 1) * w, np.nan)
    rho = mill.radius_at((k_low + 0.5) * dz_m)
    width = np.where(engaged, rho * (np.cos(np.nan_to_num(entry)) - np.cos(np.nan_to_num(exit_))), 0.0)
    at_start, at_end = entry <= EDGE_ANGLE_TOL_RAD, exit_ >= math.pi - EDGE_ANGLE_TOL_RAD
    kind = np.where(
        at_start & at_end,
        "slot",
        np.where(at_end, "down", np.where(at_start, "up", np.where((entry + exit_) / 2 > math.pi / 2, "down", "up"))),
    )
    return width, entry, exit_, np.where(engaged, kind, "air").astype("<U6")


def segment_engagement(
    zmap: ZMap,
    mill: EndMill,
    p0_m,
    p1_m,
    t: np.ndarray,
    spindle_cw: bool = True,
    dz_m: float = SLICE_HEIGHT_M,
    n_angles: int = ANGLE_BINS,
    segment_index: int = 0,
) -> SampleEngagement:
    """The engagement of samples of the straight move ``p0_m -> p1_m`` against ``zmap`` as it is
    (call before cutting the move; see the module for why that is exact).

    Parameters
    ----------
    zmap : ZMap
        The stock before the move, program frame.
    mill : EndMill
    p0_m, p1_m : array_like, shape (3,)
        Tip at the move's start and end, m.
    t : ndarray, shape (S,)
        Where the samples are on the move, in [0, 1].
    spindle_cw : bool
        M3 (True) or M4 (False: the mirrored feed frame).
    dz_m : float
        Slice height, m; K = ceil(flute length / dz).
    n_angles : int
        Angle bins J of a revolution.
    segment_index : int
        Recorded in the result's ``segment``.
    """
    p0, p1 = np.asarray(p0_m, dtype=float), np.asarray(p1_m, dtype=float)
    t = np.asarray(t, dtype=float).reshape(-1)
    if np.any((t < 0.0) | (t > 1.0)):
        raise InputError(f"sample positions on a move must be in [0, 1], got {t.min()!r}..{t.max()!r}")
    if isinstance(n_angles, bool) or not isinstance(n_angles, int) or n_angles < 4:
        raise InputError(f"angle bins must be an integer >= 4, got {n_angles!r}")
    K, J, S = _n_slices(mill, dz_m), n_angles, t.size
    v = p1 - p0
    ps = p0[None, :] + t[:, None] * v[None, :]
    vh = math.hypot(v[0], v[1])
    plunge = vh <= PLUNGE_TOL * max(float(np.linalg.norm(v)), 1e-300)
    if plunge:
        mask = np.zeros((S, K, J), dtype=bool)
    else:
        xh = np.array([v[0] / vh, v[1] / vh, 0.0])
        yh = np.array([-xh[1], xh[0], 0.0]) * (1.0 if spindle_cw else -1.0)
        mask = _front_mask(zmap, mill, p0, v, ps, xh, yh, dz_m, K, J)
    batch = EngagementBatch(mask, dz_m)
    width, entry, exit_, kind = _describe(mask, mill, dz_m)
    if plunge:
        kind = np.full(S, "plunge", dtype="<U6")
    return SampleEngagement(
        segment=np.full(S, segment_index, dtype=np.int64),
        t=t,
        position_m=ps,
        batch=batch,
        plunge=np.full(S, plunge),
        axial_depth_m=batch.axial_depth_m(),
        radial_width_m=width,
        entry_rad=entry,
        exit_rad=exit_,
        kind=kind,
    )


def concatenate_engagements(parts: list[SampleEngagement]) -> SampleEngagement:
    """One :class:`SampleEngagement` of the samples of ``parts`` in order (one dz and shape)."""
    if not parts:
        raise InputError("no engagements to concatenate")
    cat = np.concatenate
    return SampleEngagement(
        segment=cat([p.segment for p in parts]),
        t=cat([p.t for p in parts]),
        position_m=cat([p.position_m for p in parts]),
        batch=EngagementBatch(cat([p.batch.mask for p in parts]), parts[0].batch.dz_m),
        plunge=cat([p.plunge for p in parts]),
        axial_depth_m=cat([p.axial_depth_m for p in parts]),
        radial_width_m=cat([p.radial_width_m for p in parts]),
        entry_rad=cat([p.entry_rad for p in parts]),
        exit_rad=cat([p.exit_rad for p in parts]),
        kind=cat([p.kind for p in parts]),
    )
