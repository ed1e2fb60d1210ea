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
from functools import lru_cache

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
    "n_slices",
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


def n_slices(mill: EndMill, dz_m: float) -> int:
    """Slices K of a mask: ``ceil(flute length / dz)`` (at least 1)."""
    if not (math.isfinite(dz_m) and dz_m > 0.0):
        raise InputError(f"engagement slice height must be > 0 m, got {dz_m!r}")
    return max(int(math.ceil(mill.flute_length_m / dz_m - 1e-9)), 1)


@dataclass(frozen=True)
class _Grid:
    """The mask's fixed geometry for one cutter, slice height and bin count (shared by all moves)."""

    jf: int  # angle bins whose centre is at most pi
    sin_phi: np.ndarray  # (jf,)
    cos_phi: np.ndarray  # (jf,)
    zk: np.ndarray  # (K,) slice midpoints above the tip, m
    rho: np.ndarray  # (K,) edge radius there, m
    flank: np.ndarray  # (K,) bool: on the flank (rho = R)


@lru_cache(maxsize=16)
def _grid(mill: EndMill, dz_m: float, K: int, J: int) -> _Grid:
    w = 2.0 * math.pi / J
    jf = int(np.count_nonzero((np.arange(J) + 0.5) * w <= math.pi))
    phi = (np.arange(jf) + 0.5) * w
    zk = (np.arange(K) + 0.5) * dz_m
    arrays = (np.sin(phi), np.cos(phi), zk, mill.radius_at(zk), zk >= mill.corner_radius_m)
    for x in arrays:
        x.setflags(write=False)
    return _Grid(jf, *arrays)


def _active_slices(zmap: ZMap, mill: EndMill, p0: np.ndarray, p1: np.ndarray, z_tip: float, dz_m: float, K: int) -> int:
    """Slices that can reach material: up to the highest top within the cutter's reach over the move
    (its bounding box grown by the radius, one cell more each side) above the lowest sample tip
    ``z_tip``; 0 in air.  The slices above are empty: no edge point there is below a column's top."""
    R, res = mill.radius_m, zmap.resolution_m
    nx, ny = zmap.shape
    i0 = max(math.floor((min(p0[0], p1[0]) - R - zmap.x0_m) / res) - 1, 0)
    i1 = min(math.ceil((max(p0[0], p1[0]) + R - zmap.x0_m) / res) + 1, nx)
    j0 = max(math.floor((min(p0[1], p1[1]) - R - zmap.y0_m) / res) - 1, 0)
    j1 = min(math.ceil((max(p0[1], p1[1]) + R - zmap.y0_m) / res) + 1, ny)
    if i1 <= i0 or j1 <= j0:
        return 0
    top = np.fmax.reduce(zmap.top_m[i0:i1, j0:j1], axis=None)
    if not top > z_tip:  # air (or no material near): no slice is engaged
        return 0
    return int(min(math.ceil((top - z_tip) / dz_m), K))


def _front_mask(zmap, mill, p0, v, ps, xh, yh, dz_m, K, J) -> np.ndarray:
    """The compact mask ``(S, k_act, jf)`` of non-plunge samples ``ps`` (S, 3) of the move
    p0 -> p0 + v: the first ``k_act`` slices (those above are empty) and the ``jf`` bins whose centre
    is at most pi (the others are never engaged)."""
    S = ps.shape[0]
    g = _grid(mill, float(dz_m), K, J)
    k_act = _active_slices(zmap, mill, p0, p0 + v, float(ps[:, 2].min()), dz_m, K)
    if k_act == 0:
        return np.zeros((S, 0, g.jf), dtype=bool)
    zk, rho = g.zk[:k_act], g.rho[:k_act]
    # corner slices (rho < R) first; on the flank every slice's edge points share one column per angle
    kc = k_act - int(np.count_nonzero(g.flank[:k_act]))
    ex = (g.sin_phi * xh[0] + g.cos_phi * yh[0], g.sin_phi * xh[1] + g.cos_phi * yh[1])
    mask = np.empty((S, k_act, g.jf), dtype=bool)
    per = max(_POINTS_PER_BLOCK // (k_act * g.jf), 1)
    for s0 in range(0, S, per):
        p = ps[s0 : s0 + per]
        if kc < k_act:
            R = mill.radius_m
            bot, top = zmap.column_interval(p[:, 0, None] + R * ex[0], p[:, 1, None] + R * ex[1])
            Z = (p[:, 2, None] + zk[kc:])[:, :, None]
            mask[s0 : s0 + per, kc:] = (bot[:, None, :] <= Z) & (Z <= top[:, None, :])
        if kc:
            mask[s0 : s0 + per, :kc] = _corner_mask(zmap, mill, p0, v, p, ex, zk[:kc], rho[:kc])
    if mask.any():
        _drop_slivers(mask, _inner_mask(zmap, ps, ex, zk, rho, g.flank[:k_act], SLIVER_CELLS * zmap.resolution_m))
    return mask


#: A run of engaged edge points (one slice, neighbouring angle bins) is material only if it reaches
#: this many z-map cells inside the cutter's circle somewhere along it: a wall a previous pass left
#: exactly where the edge runs now (a contour's next level, a finishing pass retracing it) shows on
#: the edge wherever the cell holding an edge point has its centre just outside the earlier cut, and
#: reaches less than a cell in; below the z-map's resolution, it is dropped.  A real engagement keeps
#: its whole extent (the test is per run, not per point: no bias on the width of cut).
SLIVER_CELLS = 1.0


def _inner_mask(zmap, ps, ex, zk, rho, flank, inset_m: float) -> np.ndarray:
    """Material at the edge points moved ``inset_m`` towards the axis, (S, k, jf) (on the flank one
    column per angle, as for the mask)."""
    r = np.maximum(rho - inset_m, 0.0)
    out = np.empty((ps.shape[0], len(zk), len(ex[0])), dtype=bool)
    if flank.any():
        rf = float(r[flank][0])
        bot, top = zmap.column_interval(ps[:, 0, None] + rf * ex[0], ps[:, 1, None] + rf * ex[1])
        Z = (ps[:, 2, None] + zk[flank])[:, :, None]
        out[:, flank] = (bot[:, None, :] <= Z) & (Z <= top[:, None, :])
    c = ~flank
    if c.any():
        X = ps[:, 0, None, None] + r[c][None, :, None] * ex[0][None, None, :]
        Y = ps[:, 1, None, None] + r[c][None, :, None] * ex[1][None, None, :]
        out[:, c] = zmap.contains(X, Y, ps[:, 2, None, None] + zk[c][None, :, None])
    return out


def _drop_slivers(mask: np.ndarray, inner: np.ndarray) -> None:
    """Clear, in place, every engaged run of ``mask`` (S, k, jf: consecutive bins of one slice) that
    has no point in ``inner`` (the same shape)."""
    S, K, jf = mask.shape
    if not (S and K and jf):
        return
    start = mask & ~np.concatenate([np.zeros((S, K, 1), dtype=bool), mask[:, :, :-1]], axis=2)
    rid = np.cumsum(start, axis=2, dtype=np.int32)  # run number within its slice (1, 2, ...)
    base = (np.arange(S * K, dtype=np.int64) * (jf + 1)).reshape(S, K, 1)
    idx = base + np.where(mask, rid, 0)
    keep = np.zeros(S * K * (jf + 1), dtype=bool)
    keep[idx[mask & inner]] = True
    mask &= keep[idx]


def _corner_mask(zmap, mill, p0, v, p, ex, zk, rho) -> np.ndarray:
    """The corner slices' part (S, kc, jf) of the mask: each slice its own radius; on a rising move the
    points the move itself swept before the sample are dropped (see the module)."""
    X = p[:, 0, None, None] + rho[None, :, None] * ex[0][None, None, :]
    Y = p[:, 1, None, None] + rho[None, :, None] * ex[1][None, None, :]
    Z = p[:, 2, None, None] + zk[None, :, None]
    m = zmap.contains(X, Y, Z)
    if v[2] > 0.0:
        for i in range(p.shape[0]):
            low, high = sweep_envelope(mill, p0, p[i], X[i], Y[i])
            m[i] &= ~((low < Z[i] - SWEEP_TOL_M) & (Z[i] <= high))
    return m


_AIR_KIND = np.asarray(KINDS[:4], dtype="<U6")


def _describe(mask: np.ndarray, g: _Grid, dz_m: float, J: int):
    """Per sample of a compact mask ``(S, k, jf)`` (slices from the tip, bins from phi = 0; ``J`` bins
    a revolution; ``g`` the grid of all slices): radial width, entry, exit (lowest engaged flank
    slice), kind and axial depth."""
    S, K, jf = mask.shape
    any_k = mask.any(axis=2) if K else np.zeros((S, 0), dtype=bool)
    engaged = any_k.any(axis=1)
    if not engaged.any():
        return np.zeros(S), np.full(S, np.nan), np.full(S, np.nan), np.full(S, "air", dtype="<U6"), np.zeros(S)
    depth = np.where(engaged, K - np.argmax(any_k[:, ::-1], axis=1), 0) * dz_m
    w = 2.0 * math.pi / J
    on_flank = any_k & g.flank[None, :K]
    k_low = np.where(on_flank.any(axis=1), np.argmax(on_flank, axis=1), np.argmax(any_k, axis=1))
    rows = mask[np.arange(S), k_low]  # (S, jf)
    entry = np.argmax(rows, axis=1) * w
    exit_ = (jf - np.argmax(rows[:, ::-1], axis=1)) * w
    width = np.where(engaged, g.rho[k_low] * (np.cos(entry) - np.cos(exit_)), 0.0)
    at_start, at_end = entry <= EDGE_ANGLE_TOL_RAD, exit_ >= math.pi - EDGE_ANGLE_TOL_RAD
    side = np.where(at_start, 1, 1 + ((entry + exit_) / 2 > math.pi / 2))  # touching neither edge: by the middle
    code = np.where(at_start & at_end, 3, np.where(at_end, 2, side))
    kind = _AIR_KIND[np.where(engaged, code, 0)]
    return width, np.where(engaged, entry, np.nan), np.where(engaged, exit_, np.nan), kind, depth


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
    out: np.ndarray | None = None,
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
    out : ndarray or None
        A zeroed bool array ``(S, K, J)`` to write the mask into (it becomes the result's mask; only
        its engaged slices and front bins are written); None: a new one.
    """
    p0, p1 = np.asarray(p0_m, dtype=float), np.asarray(p1_m, dtype=float)
    t = np.asarray(t, dtype=float).reshape(-1)
    if np.any((t < 0.0) | (t > 1.0)):
        raise InputError(f"sample positions on a move must be in [0, 1], got {t.min()!r}..{t.max()!r}")
    if isinstance(n_angles, bool) or not isinstance(n_angles, int) or n_angles < 4:
        raise InputError(f"angle bins must be an integer >= 4, got {n_angles!r}")
    K, J, S = n_slices(mill, dz_m), n_angles, t.size
    v = p1 - p0
    ps = p0[None, :] + t[:, None] * v[None, :]
    vh = math.hypot(v[0], v[1])
    plunge = vh <= PLUNGE_TOL * max(float(np.linalg.norm(v)), 1e-300)
    if out is None:
        mask = np.zeros((S, K, J), dtype=bool)
    elif out.shape != (S, K, J) or out.dtype != bool:
        raise InputError(
            f"engagement output mask must be a bool array of shape {(S, K, J)}, got {out.dtype} {out.shape}"
        )
    else:
        mask = out
    if plunge:
        compact = np.zeros((S, 0, (J + 1) // 2), dtype=bool)
    else:
        xh = np.array([v[0] / vh, v[1] / vh, 0.0])
        yh = np.array([-xh[1], xh[0], 0.0]) * (1.0 if spindle_cw else -1.0)
        compact = _front_mask(zmap, mill, p0, v, ps, xh, yh, dz_m, K, J)
        mask[:, : compact.shape[1], : compact.shape[2]] = compact
    width, entry, exit_, kind, depth = _describe(compact, _grid(mill, float(dz_m), K, J), dz_m, J)
    if plunge:
        kind = np.full(S, "plunge", dtype="<U6")
    return SampleEngagement(
        segment=np.full(S, segment_index, dtype=np.int64),
        t=t,
        position_m=ps,
        batch=EngagementBatch(mask, dz_m),
        plunge=np.full(S, plunge),
        axial_depth_m=depth,
        radial_width_m=width,
        entry_rad=entry,
        exit_rad=exit_,
        kind=kind,
    )


def concatenate_engagements(parts: list[SampleEngagement], mask: np.ndarray | None = None) -> SampleEngagement:
    """One :class:`SampleEngagement` of the samples of ``parts`` in order (one dz and shape).

    ``mask``: the parts' masks already laid out in order in one ``(S, K, J)`` array (written there by
    :func:`segment_engagement` with ``out=``), used as it is instead of a copy.
    """
    if not parts:
        raise InputError("no engagements to concatenate")
    cat = np.concatenate
    n = sum(p.n_samples for p in parts)
    if mask is None:
        mask = cat([p.batch.mask for p in parts])
    elif mask.shape != (n, *parts[0].batch.mask.shape[1:]):
        raise InputError(f"the joined mask must have shape {(n, *parts[0].batch.mask.shape[1:])}, got {mask.shape}")
    return SampleEngagement(
        segment=cat([p.segment for p in parts]),
        t=cat([p.t for p in parts]),
        position_m=cat([p.position_m for p in parts]),
        batch=EngagementBatch(mask, parts[0].batch.dz_m),
        plunge=cat([p.plunge for p in parts]),
        axial_depth_m=cat([p.axial_depth_m for p in parts]),
        radial_width_m=cat([p.radial_width_m for p in parts]),
        entry_rad=cat([p.entry_rad for p in parts]),
        exit_rad=cat([p.exit_rad for p in parts]),
        kind=cat([p.kind for p in parts]),
    )
