"""The material an end mill removes moving in a straight line: its swept envelope over z-map columns.

Program frame (m), tool axis +Z (3-axis).  The cutter is taken as a solid of revolution: below its
corner the :meth:`models.cutting.cutter.EndMill.bottom_height_at` profile ``f(d)``, above it a
cylinder of radius ``R`` up to ``length_m`` above the tip (the flutes and the body both remove;
material above the tip + ``length_m`` is left).  Moving the tip ``p(t) = p0 + t (p1 - p0)``,
``t in [0, 1]``, over a vertical line at horizontal ``c``:

* the line is within reach where ``d(t) = |c - p_xy(t)| <= R``: ``d^2`` is quadratic in ``t``, so
  the reach is one interval ``[t1, t2]`` (closest approach, closed form);
* the swept solid on the line is then one interval ``[low, high]``: ``high = max z(t) + length`` (at
  ``t1`` or ``t2``, ``z`` being linear) and ``low = min_t z(t) + f(d(t))``.  ``f`` is convex and
  non-decreasing, ``d(t)`` convex, ``z(t)`` linear, so ``g(t) = z(t) + f(d(t))`` is **convex** on
  ``[t1, t2]``:
    - flat (``f = 0``): ``low = min(z(t1), z(t2))``, exact;
    - ball: the lowest point of the capsule of radius ``R`` about the centres' segment, exact (the
      lowest point of a convex set on a line lies on its boundary: an end sphere or the cylinder
      where the foot of the perpendicular is inside the segment — a quadratic in z);
    - bull-nose: golden-section search of the convex ``g`` (``GOLDEN_ITERATIONS`` steps: the
      bracket shrinks to ``0.618^48 ~ 1e-10`` of the segment; height error far below a micrometre).

A column ``[b, top]`` loses its overlap with ``[low, high]``.  If the swept interval lies strictly
inside the column (the body above ``length_m`` — the holder — would be buried), a z-map cannot hold
the roof left above it: the column is cut down to ``low`` and the cut reports ``holder_hit``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.cutting.cutter import CutterShape, EndMill
from models.errors import InputError

from .stock import ZMap

__all__ = [
    "CANDIDATE_ULPS",
    "GOLDEN_ITERATIONS",
    "CutResult",
    "cut_segment",
    "lowest_by_search",
    "reach_interval",
    "sweep_envelope",
]

#: Golden-section steps of the bull-nose's lowest-surface search.
GOLDEN_ITERATIONS = 48
#: Horizontal motion below this (m) counts as none (the reach is then a whole segment or nothing).
HORIZONTAL_TOL_M = 1e-12
_INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0
#: A column whose top is not above the cutter's lowest tip cannot be cut by the move (the swept
#: solid's lowest point is that tip) and is not examined; up to this many units in the last place of
#: the heights below it, it still is (the computed lowest point may round below the tip; a flat end
#: mill's horizontal move computes it exactly, and there no allowance is made).
CANDIDATE_ULPS = 64


@dataclass(frozen=True)
class CutResult:
    """What one straight move removed.

    Attributes
    ----------
    removed_m3 : float
        Volume of stock removed, m^3 (> 0 on a rapid means a crash into the stock).
    holder_hit : bool
        Some column had material above the cutter's length (the holder would hit it).
    """

    removed_m3: float
    holder_hit: bool


def _points(p0_m, p1_m) -> tuple[np.ndarray, np.ndarray]:
    p0, p1 = np.asarray(p0_m, dtype=float), np.asarray(p1_m, dtype=float)
    if p0.shape != (3,) or p1.shape != (3,) or not (np.all(np.isfinite(p0)) and np.all(np.isfinite(p1))):
        raise InputError(f"a cutter move's tip positions must be 3 finite numbers each, got {p0_m!r} and {p1_m!r}")
    return p0, p1


def reach_interval(R: float, p0: np.ndarray, v: np.ndarray, x: np.ndarray, y: np.ndarray):
    """Where the cutter's axis, moving from ``p0`` by ``v`` (m), is within ``R`` (m) of the vertical
    lines at ``x, y`` (m): ``(t1, t2, ok)``, the interval clipped to [0, 1] and whether it exists."""
    wx, wy = x - p0[0], y - p0[1]
    A = v[0] ** 2 + v[1] ** 2
    C = wx * wx + wy * wy
    if A <= HORIZONTAL_TOL_M**2:
        ok = C <= R * R
        return np.zeros_like(C), np.ones_like(C), ok
    B = wx * v[0] + wy * v[1]
    disc = B * B - A * (C - R * R)
    s = np.sqrt(np.maximum(disc, 0.0))
    t1, t2 = np.maximum((B - s) / A, 0.0), np.minimum((B + s) / A, 1.0)
    return t1, t2, (disc >= 0.0) & (t1 <= t2)


def _ball_low(R: float, p0: np.ndarray, v: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Lowest point over (x, y) of the capsule of radius R about the ball centres' segment (inf off it)."""
    low = np.full(np.broadcast(x, y).shape, np.inf)
    for q in (p0, p0 + v):
        d2 = (x - q[0]) ** 2 + (y - q[1]) ** 2
        low = np.minimum(low, np.where(d2 <= R * R, q[2] + R - np.sqrt(np.maximum(R * R - d2, 0.0)), np.inf))
    L = float(np.linalg.norm(v))
    nn = (v[0] ** 2 + v[1] ** 2) / (L * L) if L > 0.0 else 0.0
    if nn < 1e-12:
        return low  # vertical (or no) move: the end spheres bound it
    u = v / L
    # w(z) = (x - Ax, y - Ay, z - Az), A = p0 + R z^; m = w(0) x u, n = z^ x u = (-uy, ux, 0)
    wx, wy, wz = x - p0[0], y - p0[1], -(p0[2] + R)
    mx, my, mz = wy * u[2] - wz * u[1], wz * u[0] - wx * u[2], wx * u[1] - wy * u[0]
    mn = -mx * u[1] + my * u[0]
    disc = mn * mn - nn * (mx * mx + my * my + mz * mz - R * R)
    z = (-mn - np.sqrt(np.maximum(disc, 0.0))) / nn
    t = (wx * u[0] + wy * u[1] + (wz + z) * u[2]) / L
    return np.minimum(low, np.where((disc >= 0.0) & (t >= 0.0) & (t <= 1.0), z, np.inf))


def lowest_by_search(mill: EndMill, p0: np.ndarray, v: np.ndarray, x, y, t1, t2) -> np.ndarray:
    """min over t in [t1, t2] of z(t) + f(d(t)) by golden section (g convex: see the module).

    Parameters
    ----------
    mill : EndMill
    p0, v : ndarray, shape (3,)
        Start tip position and move vector, m.
    x, y, t1, t2 : ndarray
        Column coordinates (m) and reach interval, one shape.
    """

    def g(t):
        d = np.hypot(x - (p0[0] + t * v[0]), y - (p0[1] + t * v[1]))
        return p0[2] + t * v[2] + mill.bottom_height_at(np.minimum(d, mill.radius_m))

    a, b = np.array(t1, dtype=float), np.array(t2, dtype=float)
    c, d = b - _INV_PHI * (b - a), a + _INV_PHI * (b - a)
    gc, gd = g(c), g(d)
    for _ in range(GOLDEN_ITERATIONS):
        left = gc <= gd
        b, a = np.where(left, d, b), np.where(left, a, c)
        d_new, c_new = np.where(left, c, a + _INV_PHI * (b - a)), np.where(left, b - _INV_PHI * (b - a), d)
        g_new = g(np.where(left, c_new, d_new))
        gd, gc = np.where(left, gc, g_new), np.where(left, g_new, gd)
        c, d = c_new, d_new
    return np.minimum(np.minimum(gc, gd), np.minimum(g(np.array(t1, dtype=float)), g(np.array(t2, dtype=float))))


def sweep_envelope(mill: EndMill, p0_m, p1_m, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The swept solid's interval on vertical lines: ``(low, high)``, m, NaN where out of reach.

    Parameters
    ----------
    mill : EndMill
    p0_m, p1_m : array_like, shape (3,)
        Tip at the move's start and end, program frame, m.
    x_m, y_m : ndarray
        The lines' X and Y, m, broadcastable to one shape.
    """
    p0, p1 = _points(p0_m, p1_m)
    x, y = np.broadcast_arrays(np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float))
    return _envelope(mill, p0, p1 - p0, x, y)


def _envelope(mill: EndMill, p0: np.ndarray, v: np.ndarray, x: np.ndarray, y: np.ndarray):
    """:func:`sweep_envelope` of checked points: tip ``p0`` moving by ``v``; ``x, y`` one shape, float."""
    t1, t2, ok = reach_interval(mill.radius_m, p0, v, x, y)
    z1, z2 = p0[2] + t1 * v[2], p0[2] + t2 * v[2]
    high = np.maximum(z1, z2) + mill.length_m
    if mill.shape is CutterShape.FLAT:
        low = np.minimum(z1, z2)
    elif mill.shape is CutterShape.BALL:
        low = _ball_low(mill.radius_m, p0, v, x, y)
    else:
        low = np.full(x.shape, np.nan)
        if ok.any():
            low[ok] = lowest_by_search(mill, p0, v, x[ok], y[ok], t1[ok], t2[ok])
    return np.where(ok, low, np.nan), np.where(ok, high, np.nan)


def cut_segment(zmap: ZMap, mill: EndMill, p0_m, p1_m) -> CutResult:
    """Remove from ``zmap`` (in place) what ``mill`` sweeps moving its tip from ``p0_m`` to ``p1_m``.

    Any direction (horizontal, ramp, plunge, retract).  Over the columns of the move's bounding box
    grown by the cutter's radius, only those whose top is above the cutter's lowest point (see
    :data:`CANDIDATE_ULPS`) can lose material: the envelope is computed on those alone.

    Returns
    -------
    CutResult
        Removed volume (m^3) and whether the holder would be buried.
    """
    p0, p1 = _points(p0_m, p1_m)
    R, res = mill.radius_m, zmap.resolution_m
    nx, ny = zmap.shape
    i0 = max(int(np.floor((min(p0[0], p1[0]) - R - zmap.x0_m) / res)), 0)
    i1 = min(int(np.ceil((max(p0[0], p1[0]) + R - zmap.x0_m) / res)), nx)
    j0 = max(int(np.floor((min(p0[1], p1[1]) - R - zmap.y0_m) / res)), 0)
    j1 = min(int(np.ceil((max(p0[1], p1[1]) + R - zmap.y0_m) / res)), ny)
    if i1 <= i0 or j1 <= j0:
        return CutResult(0.0, False)
    # candidates: flat indices into the grid of the columns whose top is above the lowest tip
    zlo = min(p0[2], p1[2])
    if not (mill.shape is CutterShape.FLAT and p0[2] == p1[2]):
        zlo -= CANDIDATE_ULPS * math.ulp(abs(zlo) + mill.length_m)
    local = np.flatnonzero(zmap.top_m[i0:i1, j0:j1] > zlo)  # NaN (empty): False
    if local.size == 0:
        return CutResult(0.0, False)
    ii, jj = np.divmod(local, j1 - j0)
    x = zmap.x0_m + (ii + (i0 + 0.5)) * res
    y = zmap.y0_m + (jj + (j0 + 0.5)) * res
    low, high = _envelope(mill, p0, p1 - p0, x, y)
    cells = ii * ny
    cells += jj + (i0 * ny + j0)
    top, bot = np.take(zmap.top_m, cells), np.take(zmap.bottom_m, cells)
    hit = (low < top) & (high > bot)  # NaN (no reach) compares False
    if not hit.any():
        return CutResult(0.0, False)
    cells, low, high, top, bot = cells[hit], low[hit], high[hit], top[hit], bot[hit]
    roof = (high < top) & (low > bot)
    new_top = np.where(low > bot, np.minimum(top, low), top)
    new_bot = np.where((low <= bot) & (high < top), high, bot)
    gone = (low <= bot) & (high >= top)
    new_top[gone] = np.nan
    new_bot[gone] = np.nan
    removed = float(np.nansum(top - bot) - np.nansum(new_top - new_bot)) * res * res
    np.put(zmap.top_m, cells, new_top)
    np.put(zmap.bottom_m, cells, new_bot)
    return CutResult(removed, bool(roof.any()))
