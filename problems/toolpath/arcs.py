"""Arc geometry of G2/G3: the centre (I/J/K or R form), the swept angle, and chords within a tolerance.

Facts from LinuxCNC's RS-274/NGC interpreter (``src/emc/rs274ngc/interp_arc.cc``, ``arc_data_ijk``
and ``arc_data_r``; constants in ``interp_internal.hh``):

* I/J/K form: the centre is the start plus the offsets (incremental, G91.1, the default) or the
  offsets themselves (G90.1). The arc is refused when the start or end radius is below
  ``RADIUS_TOLERANCE`` (a zero-radius arc), or when the two radii differ by more than 100 times
  ``CENTER_ARC_RADIUS_TOLERANCE``, or by more than ``CENTER_ARC_RADIUS_TOLERANCE`` *and* by more
  than ``SPIRAL_RELATIVE_TOLERANCE`` of the larger radius.  Within that, the arc is a spiral whose
  radius changes linearly with the angle, so that its end is the programmed end.
* R form: the centre lies on the perpendicular bisector of start-end; a positive R gives the arc
  of at most half a turn, a negative R the one of at least half a turn.  Start equal to end is
  refused; a chord longer than 2|R| by more than ``RADIUS_TOLERANCE`` is refused, a smaller excess
  is taken as a half circle.
* P (a whole number >= 1, default 1) is the number of turns; G2 turns clockwise, G3
  counter-clockwise, seen from the positive end of the plane's normal (G17: +Z, G18: +Y, G19: +X).
  The plane's coordinates are (X, Y) with offsets (I, J) for G17, (Z, X) with (K, I) for G18 and
  (Y, Z) with (J, K) for G19, so each is right-handed about its normal.
* A start equal to the end (I/J/K form) is a full circle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

__all__ = [
    "CENTER_ARC_RADIUS_TOLERANCE_INCH_M",
    "CENTER_ARC_RADIUS_TOLERANCE_MM_M",
    "INCH_M",
    "RADIUS_TOLERANCE_INCH_M",
    "RADIUS_TOLERANCE_MM_M",
    "ArcGeometry",
    "Plane",
    "arc_points",
    "centre_ijk",
    "centre_r",
]

#: One inch in m (exact by definition).
INCH_M = 0.0254
_INCH = INCH_M
#: LinuxCNC's default CENTER_ARC_RADIUS_TOLERANCE_MM, 2·0.01·√2 mm, in m (used in G21).
CENTER_ARC_RADIUS_TOLERANCE_MM_M = 2 * 0.01 * math.sqrt(2.0) * 1e-3
#: LinuxCNC's default CENTER_ARC_RADIUS_TOLERANCE_INCH, 2·0.001·√2 in, in m (used in G20).
CENTER_ARC_RADIUS_TOLERANCE_INCH_M = 2 * 0.001 * math.sqrt(2.0) * _INCH
#: LinuxCNC's RADIUS_TOLERANCE_INCH, 0.00005 in, in m (used in G20).
RADIUS_TOLERANCE_INCH_M = 0.00005 * _INCH
#: LinuxCNC's RADIUS_TOLERANCE_MM (= RADIUS_TOLERANCE_INCH · 25.4 mm), in m (used in G21).
RADIUS_TOLERANCE_MM_M = 0.00005 * _INCH
#: LinuxCNC's SPIRAL_RELATIVE_TOLERANCE: relative start/end radius difference accepted.
SPIRAL_RELATIVE_TOLERANCE = 0.001
#: Start and end closer than this (m) in the plane make an arc a full circle: LinuxCNC's CART_FUZZ
#: (1e-8 in machine units, ``libposemath/posemath_types.h``, used by ``pmCircleInit``) for a mm machine.
FULL_CIRCLE_FUZZ_M = 1e-11
#: Largest angle one chord spans (rad), whatever the tolerance: at least 4 chords a turn.
MAX_CHORD_ANGLE_RAD = 0.5 * math.pi


class Plane(Enum):
    """The arc plane: G17 (XY), G18 (ZX), G19 (YZ)."""

    XY = 17
    ZX = 18
    YZ = 19

    @property
    def axes(self) -> tuple[int, int, int]:
        """Indices (first, second, normal) of the plane's coordinates in (X, Y, Z)."""
        return {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}[self.value]

    @property
    def offsets(self) -> tuple[str, str]:
        """The centre-offset letters (first, second)."""
        return {17: ("I", "J"), 18: ("K", "I"), 19: ("J", "K")}[self.value]


@dataclass(frozen=True, slots=True)
class ArcGeometry:
    """An arc in its plane's coordinates (m, rad).

    Attributes
    ----------
    centre : tuple of float
        (first, second) plane coordinates of the centre, m.
    r0, r1 : float
        Start and end radius, m (equal up to the spiral tolerance).
    theta0 : float
        Angle of the start about the centre, rad, from the first plane axis towards the second.
    sweep : float
        Signed swept angle, rad: positive counter-clockwise (G3), negative clockwise (G2);
        ``|sweep| = 2π`` for a full circle, more with P > 1.
    """

    centre: tuple[float, float]
    r0: float
    r1: float
    theta0: float
    sweep: float


def _sweep(a0, b0, a1, b1, ca, cb, ccw: bool, turns: int) -> tuple[float, float]:
    t0 = math.atan2(b0 - cb, a0 - ca)
    t1 = math.atan2(b1 - cb, a1 - ca)
    if math.hypot(a1 - a0, b1 - b0) <= FULL_CIRCLE_FUZZ_M:
        d = 2.0 * math.pi
    else:
        d = (t1 - t0) % (2.0 * math.pi) if ccw else (t0 - t1) % (2.0 * math.pi)
    d += 2.0 * math.pi * (turns - 1)
    return t0, d if ccw else -d


def centre_ijk(
    start: tuple[float, float],
    end: tuple[float, float],
    centre: tuple[float, float],
    ccw: bool,
    turns: int,
    spiral_tol_m: float,
    radius_tol_m: float,
) -> ArcGeometry | str:
    """The arc given its absolute centre (I/J/K form); a string saying what is wrong if refused."""
    (a0, b0), (a1, b1), (ca, cb) = start, end, centre
    r0 = math.hypot(a0 - ca, b0 - cb)
    r1 = math.hypot(a1 - ca, b1 - cb)
    if r0 < radius_tol_m or r1 < radius_tol_m:
        return f"zero-radius arc (start radius {r0 * 1e3:.6g} mm, end radius {r1 * 1e3:.6g} mm)"
    err = abs(r0 - r1)
    rel = err / max(r0, r1)
    if err > 100.0 * spiral_tol_m or (rel > SPIRAL_RELATIVE_TOLERANCE and err > spiral_tol_m):
        return (
            f"the radius to the end ({r1 * 1e3:.6g} mm) differs from the radius to the start "
            f"({r0 * 1e3:.6g} mm) by {err * 1e3:.4g} mm ({100 * rel:.3g} %); LinuxCNC accepts up to "
            f"{spiral_tol_m * 1e3:.4g} mm, or up to {100 * spiral_tol_m * 1e3:.4g} mm within "
            f"{100 * SPIRAL_RELATIVE_TOLERANCE:g} % of the radius"
        )
    t0, d = _sweep(a0, b0, a1, b1, ca, cb, ccw, turns)
    return ArcGeometry((ca, cb), r0, r1, t0, d)


def centre_r(
    start: tuple[float, float], end: tuple[float, float], radius: float, ccw: bool, turns: int, radius_tol_m: float
) -> ArcGeometry | str:
    """The arc given its signed radius (R form); a string saying what is wrong if refused."""
    (a0, b0), (a1, b1) = start, end
    if a0 == a1 and b0 == b1:
        return "the R form cannot make a full circle (start equals end); use I/J/K for a full circle"
    if radius == 0.0:
        return "R is zero; give the arc's radius"
    rabs = abs(radius)
    ma, mb = 0.5 * (a0 + a1), 0.5 * (b0 + b1)
    half = math.hypot(a1 - ma, b1 - mb)
    if half - rabs > radius_tol_m:
        return (
            f"radius {rabs * 1e3:.6g} mm is too small to reach the end point "
            f"({2 * half * 1e3:.6g} mm away); correct R or the end point"
        )
    half = min(half, rabs)
    right = (not ccw and radius > 0) or (ccw and radius < 0)  # centre right of start->end
    theta = math.atan2(b1 - b0, a1 - a0) + (-0.5 * math.pi if right else 0.5 * math.pi)
    offset = math.sqrt(max(rabs * rabs - half * half, 0.0))
    ca, cb = ma + offset * math.cos(theta), mb + offset * math.sin(theta)
    t0, d = _sweep(a0, b0, a1, b1, ca, cb, ccw, turns)
    return ArcGeometry((ca, cb), rabs, rabs, t0, d)


def chord_count(radius_m: float, sweep_rad: float, tol_m: float) -> int:
    """Number of chords so that each chord's sagitta ``r (1 - cos(Δθ/2))`` is at most ``tol_m``."""
    if tol_m >= radius_m:
        step = MAX_CHORD_ANGLE_RAD
    else:
        step = min(2.0 * math.acos(1.0 - tol_m / radius_m), MAX_CHORD_ANGLE_RAD)
    return max(1, math.ceil(abs(sweep_rad) / step - 1e-12))


def arc_points(geo: ArcGeometry, plane: Plane, start: np.ndarray, end: np.ndarray, tol_m: float) -> np.ndarray:
    """Chord end points of an arc (helical when the normal coordinate changes), start excluded.

    Parameters
    ----------
    geo : ArcGeometry
        The arc.
    plane : Plane
        Its plane.
    start, end : np.ndarray
        Shape ``(3,)``, m, program frame: the arc's start and (programmed) end.
    tol_m : float
        Largest sagitta, m.

    Returns
    -------
    np.ndarray
        Shape ``(n, 3)``, m: the chord ends, the last one exactly ``end``. The radius and the
        normal coordinate change linearly with the angle (a spiral/helix), so a chord's largest
        distance from the curve, at its middle, is at most ``tol_m``.
    """
    n = chord_count(max(geo.r0, geo.r1), geo.sweep, tol_m)
    ia, ib, inn = plane.axes
    s = np.arange(1, n + 1) / n
    th = geo.theta0 + s * geo.sweep
    r = geo.r0 + s * (geo.r1 - geo.r0)
    pts = np.empty((n, 3))
    pts[:, ia] = geo.centre[0] + r * np.cos(th)
    pts[:, ib] = geo.centre[1] + r * np.sin(th)
    pts[:, inn] = start[inn] + s * (end[inn] - start[inn])
    pts[-1] = end
    return pts
