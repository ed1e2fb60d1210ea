"""Where an end mill's cutting edges are in material: the engagement mask of a batch of samples.

Frames and angles (``docs/cutting.md``): the **feed frame** of a sample has its origin at the tool
tip, ``x`` along the horizontal feed, ``z`` along the tool axis towards the spindle, ``y = z x x``.
For a clockwise spindle (M3) the immersion angle ``phi`` is measured clockwise (seen from ``+z``)
from ``+y``: the edge point at height ``z`` is ``(rho(z) sin phi, rho(z) cos phi, z)``.  For a
counter-clockwise spindle (M4) the mask is made in the mirrored feed frame (``y -> -y``) and the
force is mirrored back by its user.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["ANGLE_BINS", "SLICE_HEIGHT_M", "EngagementBatch"]

#: Angle bins of a revolution in a mask (1 degree each).
ANGLE_BINS = 360
#: Height of an axial slice of the cutter in a mask, m (0.1 mm).
SLICE_HEIGHT_M = 1e-4


@dataclass(frozen=True)
class EngagementBatch:
    """The engagement of ``S`` samples.

    Attributes
    ----------
    mask : ndarray, bool, shape (S, K, J)
        ``mask[s, k, j]``: at sample ``s`` the cutting edge point at height ``(k + 0.5) dz_m`` above
        the tip and immersion angle ``(j + 0.5) 2 pi / J`` is in material not yet removed.  Only
        angles in ``[0, pi]`` (the half ahead of the feed) may be set.
    dz_m : float
        Slice height, m.
    """

    mask: np.ndarray
    dz_m: float

    def __post_init__(self) -> None:
        m = np.asarray(self.mask)
        if m.ndim != 3 or m.dtype != bool:
            raise InputError(f"engagement mask must be a bool array (S, K, J), got {m.dtype} {m.shape}")
        if not (math.isfinite(self.dz_m) and self.dz_m > 0.0):
            raise InputError(f"engagement slice height must be > 0 m, got {self.dz_m!r}")

    @property
    def n_samples(self) -> int:
        return int(self.mask.shape[0])

    @property
    def n_slices(self) -> int:
        return int(self.mask.shape[1])

    @property
    def n_angles(self) -> int:
        return int(self.mask.shape[2])

    def slice_heights_m(self) -> np.ndarray:
        """Midpoint height of each slice above the tip, m, shape (K,)."""
        return (np.arange(self.n_slices) + 0.5) * self.dz_m

    def angles_rad(self) -> np.ndarray:
        """Centre of each angle bin, rad, shape (J,)."""
        return (np.arange(self.n_angles) + 0.5) * (2.0 * math.pi / self.n_angles)

    def axial_depth_m(self) -> np.ndarray:
        """Height of the highest engaged slice's top above the tip, m, shape (S,) (0: air)."""
        any_k = self.mask.any(axis=2)
        top = np.where(any_k, np.arange(1, self.n_slices + 1)[None, :], 0).max(axis=1, initial=0)
        return top * self.dz_m

    def in_air(self) -> np.ndarray:
        """Whether no edge is in material, shape (S,)."""
        return ~self.mask.any(axis=(1, 2))
