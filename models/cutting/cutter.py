"""An end mill's geometry: flat, ball or bull-nose, as the cutting-force model and the stock see it.

One description serves the cut (force, material removal) and the cell (the cutter's collision
capsule, :class:`models.collision.tool.Cutter`, is built from it by :meth:`EndMill.capsule`).

Frame: the **cutter frame** has its origin at the tool tip (the lowest point of the cutter, the TCP
of a program path) and ``z`` along the tool axis from the tip towards the spindle.  A point of a
cutting edge at height ``z`` above the tip lies at radius :meth:`EndMill.radius_at` from the axis.

Geometry (Altintas, *Manufacturing Automation*, 2nd ed., 2012, section 2.5, the generalised end
mill reduced to its three common forms): diameter ``D = 2 R``, corner radius ``r`` (flat ``r = 0``,
ball ``r = R``, bull-nose ``0 < r < R``).  Below ``z = r`` the edge lies on the corner's torus::

    rho(z) = (R - r) + sqrt(r^2 - (r - z)^2),   sin kappa(z) = sqrt(r^2 - (r - z)^2) / r

and above it on the cylinder (``rho = R``, ``kappa = pi/2``).  ``kappa`` is the axial immersion
angle: between the tool axis and the normal of the cutting edge's surface (0 at a ball's tip, pi/2 on
the flank).  The flutes are helices of constant lead: an edge point at height ``z`` lags the point at
the tip by ``psi(z) = z tan(beta) / R`` (``beta`` the helix angle at the flank).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from ..errors import InputError

__all__ = ["CutterShape", "EndMill"]


class CutterShape(Enum):
    """The end mill's form."""

    FLAT = "flat"
    BALL = "ball"
    BULL_NOSE = "bull_nose"


@dataclass(frozen=True)
class EndMill:
    """An end mill (SI units).

    Attributes
    ----------
    shape : CutterShape
    diameter_m : float
        D, m.
    corner_radius_m : float
        r, m: 0 for a flat end mill, D/2 for a ball, between for a bull-nose.
    flutes : int
        Number of cutting edges N (evenly spaced).
    helix_rad : float
        Helix angle beta at the flank, rad (0: straight flutes).
    flute_length_m : float
        Length of the cutting edges from the tip, m.
    length_m : float
        Stick-out: from the tip to the holder, m (the collision capsule's length).

    Raises
    ------
    InputError
        A value out of its range (the message names the quantity, the value and the range).
    """

    shape: CutterShape
    diameter_m: float
    corner_radius_m: float
    flutes: int
    helix_rad: float
    flute_length_m: float
    length_m: float

    def __post_init__(self) -> None:
        R = self.diameter_m / 2.0
        if not (math.isfinite(self.diameter_m) and self.diameter_m > 0.0):
            raise InputError(f"cutter diameter must be > 0 m, got {self.diameter_m!r}")
        if self.shape is CutterShape.FLAT and self.corner_radius_m != 0.0:
            raise InputError(f"a flat end mill has corner radius 0, got {self.corner_radius_m!r} m")
        if self.shape is CutterShape.BALL and not math.isclose(self.corner_radius_m, R, rel_tol=1e-9):
            raise InputError(f"a ball end mill's corner radius is D/2 = {R:g} m, got {self.corner_radius_m!r} m")
        if self.shape is CutterShape.BULL_NOSE and not 0.0 < self.corner_radius_m < R:
            raise InputError(
                f"a bull-nose end mill's corner radius must be in (0, D/2 = {R:g}) m, got {self.corner_radius_m!r} m"
            )
        if isinstance(self.flutes, bool) or not isinstance(self.flutes, int) or not 1 <= self.flutes <= 64:
            raise InputError(f"cutter flutes must be an integer in 1..64, got {self.flutes!r}")
        if not (math.isfinite(self.helix_rad) and 0.0 <= self.helix_rad < math.radians(75.0)):
            raise InputError(f"cutter helix angle must be in [0, 75) deg, got {math.degrees(self.helix_rad)!r} deg")
        if not (math.isfinite(self.flute_length_m) and self.flute_length_m >= self.corner_radius_m > -1.0):
            raise InputError(
                f"cutter flute length must be >= the corner radius ({self.corner_radius_m:g} m), "
                f"got {self.flute_length_m!r} m"
            )
        if not self.flute_length_m > 0.0:
            raise InputError(f"cutter flute length must be > 0 m, got {self.flute_length_m!r}")
        if not (math.isfinite(self.length_m) and self.length_m >= self.flute_length_m):
            raise InputError(
                f"cutter length (stick-out) must be >= its flute length ({self.flute_length_m:g} m), "
                f"got {self.length_m!r} m"
            )

    @property
    def radius_m(self) -> float:
        """R = D/2, m."""
        return self.diameter_m / 2.0

    def radius_at(self, z_m: np.ndarray | float) -> np.ndarray:
        """rho(z): the cutting edge's distance from the axis at height ``z`` above the tip, m.

        Parameters
        ----------
        z_m : array_like
            Heights above the tip, m (clipped to [0, flute length]).

        Returns
        -------
        ndarray
            Same shape as ``z_m``, m.
        """
        z = np.clip(np.asarray(z_m, dtype=float), 0.0, self.flute_length_m)
        R, r = self.radius_m, self.corner_radius_m
        if r == 0.0:
            return np.full_like(z, R)
        inside = z < r
        s = np.sqrt(np.maximum(r * r - (r - np.minimum(z, r)) ** 2, 0.0))
        return np.where(inside, (R - r) + s, R)

    def sin_kappa(self, z_m: np.ndarray | float) -> np.ndarray:
        """sin(kappa(z)): kappa the axial immersion angle (tool axis to the edge surface's normal)."""
        z = np.clip(np.asarray(z_m, dtype=float), 0.0, self.flute_length_m)
        r = self.corner_radius_m
        if r == 0.0:
            return np.ones_like(z)
        s = np.sqrt(np.maximum(r * r - (r - np.minimum(z, r)) ** 2, 0.0)) / r
        return np.where(z < r, s, 1.0)

    def lag_rad(self, z_m: np.ndarray | float) -> np.ndarray:
        """psi(z) = z tan(beta) / R: how far the edge at height z lags the tip's, rad."""
        return np.asarray(z_m, dtype=float) * math.tan(self.helix_rad) / self.radius_m

    def bottom_height_at(self, d_m: np.ndarray | float) -> np.ndarray:
        """The cutter's lowest surface at distance ``d`` from its axis, height above the tip, m
        (inf beyond the diameter): what a stationary cutter leaves in the stock below it."""
        d = np.abs(np.asarray(d_m, dtype=float))
        R, r = self.radius_m, self.corner_radius_m
        flat = R - r
        out = np.full_like(d, np.inf)
        core = d <= flat
        out[core] = 0.0
        ring = (~core) & (d <= R)
        if r > 0.0:
            out[ring] = r - np.sqrt(np.maximum(r * r - (d[ring] - flat) ** 2, 0.0))
        return out

    def to_dict(self) -> dict[str, float | int | str]:
        """The end mill in the problem-file schema (``[robot.tool.cutter]``: m, degrees)."""
        return {
            "shape": self.shape.value,
            "diameter": self.diameter_m,
            "corner_radius": self.corner_radius_m,
            "flutes": self.flutes,
            "helix_deg": math.degrees(self.helix_rad),
            "flute_length": self.flute_length_m,
            "length": self.length_m,
        }

    def capsule(self):
        """The cutter's collision capsule (:class:`models.collision.tool.Cutter`): radius D/2,
        length the stick-out."""
        from ..collision.tool import Cutter  # loads coal only when a cell is checked

        return Cutter(self.radius_m, self.length_m, self)
