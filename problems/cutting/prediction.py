"""What the cut does along a program: the predicted cutting wrench at every waypoint, with the
engagement, the force's peak and the stock before and after.

Made by :func:`problems.cutting.program_cut.predict_cut`; the problem's load adds
:attr:`CutPrediction.wrench_base` to its base-frame wrench (:attr:`problems.problem.Problem.load`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any

import numpy as np

__all__ = ["CutPrediction", "Milling"]


class Milling(Enum):
    """How the cutter meets the material at a sample."""

    AIR = "air"  # no edge in material (or a rapid)
    SLOT = "slot"  # engaged on both sides of the feed (entry near 0 and exit near pi)
    UP = "up"  # conventional: the engagement starts at phi = 0
    DOWN = "down"  # climb: the engagement ends at phi = pi
    PARTIAL = "partial"  # engaged, touching neither side (e.g. a boss)
    PLUNGE = "plunge"  # a vertical move into material: the peripheral model gives no force


#: Integer codes of :class:`Milling` in :attr:`CutPrediction.milling`.
MILLING_CODES: tuple[Milling, ...] = tuple(Milling)


@dataclass(frozen=True)
class CutPrediction:
    """The predicted cut along a program's waypoints (``N`` waypoints).

    Attributes
    ----------
    wrench_program : ndarray, shape (N, 6)
        ``[f (N); m (N*m)]``: the mean over a spindle revolution of the wrench the cut puts on the
        tool, program frame, moment about the tool tip (the TCP), as the cutter arrives at each
        waypoint along the move ending there (waypoint 0: zero).
    program2base : ndarray, shape (3, 3)
        The program frame's rotation in the base frame.
    peak_force_N : ndarray, shape (N,)
        Largest instantaneous force magnitude over the revolution, N.
    axial_depth_m, radial_width_m : ndarray, shape (N,)
        Engagement: the highest engaged edge above the tip, and the width of cut across the feed, m.
    entry_rad, exit_rad : ndarray, shape (N,)
        Immersion angles where the lowest engaged slice enters and leaves the material, rad (NaN in
        the air).
    milling : ndarray, shape (N,), int
        Index into :data:`MILLING_CODES`.
    feed_per_tooth_m : ndarray, shape (N,)
        The programmed feed per tooth (horizontal), m (0 on rapids).
    spindle_rad_s : ndarray, shape (N,)
        Spindle speed, rad/s.
    removed_m3 : float
        Volume the program removes, m^3.
    stock_volume_m3 : float
        The stock's volume before the program, m^3.
    heights_before, heights_after : ndarray, shape (ny, nx)
        The stock's top (program frame z, m; NaN where there is no material) on a grid for figures.
    grid_extent_m : tuple of float
        ``(x_min, x_max, y_min, y_max)`` of that grid, program frame, m.
    warnings : tuple of str
        What the user should know (plunges the model gives no force for, grazing cuts...).
    material : Any
        The cutting coefficients used (:class:`models.cutting.material.CuttingCoefficients`).
    mill : Any
        The end mill (:class:`models.cutting.cutter.EndMill`).
    stand_in : ndarray or None
        Shape (6,): the constant wrench the report compares against (``[cut] stand_in``), in its
        frame ``stand_in_frame``; None when not given.
    stand_in_frame : str
    """

    wrench_program: np.ndarray
    program2base: np.ndarray
    peak_force_N: np.ndarray
    axial_depth_m: np.ndarray
    radial_width_m: np.ndarray
    entry_rad: np.ndarray
    exit_rad: np.ndarray
    milling: np.ndarray
    feed_per_tooth_m: np.ndarray
    spindle_rad_s: np.ndarray
    removed_m3: float
    stock_volume_m3: float
    heights_before: np.ndarray
    heights_after: np.ndarray
    grid_extent_m: tuple[float, float, float, float]
    warnings: tuple[str, ...] = ()
    material: Any = None
    mill: Any = None
    stand_in: np.ndarray | None = None
    stand_in_frame: str = "tool"
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(len(self.wrench_program))

    @property
    def wrench_base(self) -> np.ndarray:
        """The cutting wrench at every waypoint in the base frame, shape (N, 6), N and N*m, about the
        TCP (the tool tip)."""
        R = np.asarray(self.program2base, dtype=float)
        W = np.asarray(self.wrench_program, dtype=float)
        return np.hstack([W[:, :3] @ R.T, W[:, 3:] @ R.T])

    def rotated(self, R_new2old_base: np.ndarray) -> CutPrediction:
        """The same cut seen from a base frame turned by ``R`` (``p_new = R p_old``): the program frame
        turns with it (a placement)."""
        return replace(self, program2base=np.asarray(R_new2old_base, dtype=float) @ self.program2base)

    def cutting(self) -> np.ndarray:
        """Waypoints where an edge is in material, shape (N,), bool."""
        return np.asarray(self.milling) != MILLING_CODES.index(Milling.AIR)
