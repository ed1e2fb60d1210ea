"""What a format sends its controller (:class:`ControllerMotion`, under an :class:`Interpolation`),
a quantity's worst value against its limit (:class:`Peak`), and the tolerances of the checks
(:mod:`planner.export.limits`, :mod:`planner.export.quintic`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

__all__ = [
    "EXACT_MAX",
    "EXPORT_FD_TOL",
    "EXPORT_LIMIT_TOL",
    "EXPORT_POSITION_TOL",
    "EXPORT_TIME_TOL",
    "RATES",
    "SCREEN_SAMPLES",
    "SEGMENT_CHUNK",
    "ControllerMotion",
    "Interpolation",
    "Peak",
]

#: Relative slack of the limit check before export (the timing's own LIMIT_RATIO_TOL).
EXPORT_LIMIT_TOL: float = 1e-9
#: Slack on the position limits (rad) and on the sample period's uniformity (s).
EXPORT_POSITION_TOL: float = 1e-9
EXPORT_TIME_TOL: float = 1e-9
#: Relative slack of every check of a differenced or interpolated quantity (finite differences of
#: the positions, the controller's interpolation between points): a difference quotient over one
#: period is a weighted mean of the analytic derivative over it, so it is within the limit the
#: derivative keeps, up to the methods' own check tolerance and rounding (0.1 %: a jump of a sample
#: is orders of magnitude above it).
EXPORT_FD_TOL: float = 1e-3
#: Segments of a quintic spline checked at a time (bounds the temporary arrays of 10^6 samples).
SEGMENT_CHUNK = 20_000
#: Sub-samples per segment that screen a quintic's positions and velocities; a segment and joint
#: the screen cannot clear (its sampled peak plus the bound (h/n)^2 max|f''| / 8 of what lies
#: between the sub-samples reaches the limit) is solved exactly (the roots of the derivative).
SCREEN_SAMPLES = 8
#: Most segment-joint pairs solved exactly; beyond, the screen's upper bound is the value (a
#: trajectory that far over its limits is refused either way).
EXACT_MAX = 20_000

#: The rate limits: quantity, unit, order of the derivative (a time scale k divides it by k^order).
RATES = (("velocity", "rad/s", 1), ("acceleration", "rad/s^2", 2), ("jerk", "rad/s^3", 3))
_UNIT = {"position": "rad", **{name: u for name, u, _n in RATES}}


class Interpolation(Enum):
    """What the controller does between the points it is sent."""

    #: Setpoints, one per period, followed as they come (URScript ``servoj``): checked at them.
    SETPOINTS = "setpoints"
    #: The quintic through each pair of points of position, velocity and acceleration
    #: (ROS 2 joint_trajectory_controller, interpolation ``splines``): checked on the spline.
    QUINTIC = "quintic"
    #: A move from rest to rest on a trapezoidal speed profile reaching each point at its time
    #: (URScript ``movej`` with ``t`` and no blend).
    REST_TO_REST = "rest_to_rest"
    #: Not documented by the vendor: every motion through the points at their times reaches at
    #: least their divided differences; what lies between is the controller's (a warning).
    THROUGH_POINTS = "through_points"


@dataclass(frozen=True)
class ControllerMotion:
    """What a format sends to its controller, as written, in the model's joint convention.

    Attributes
    ----------
    interpolation : Interpolation
    label : str
        What it is, for messages: ``"the servoj setpoints every 0.002 s"``.
    t : ndarray, shape (M,), or None
        The times the controller reaches the points, s, as written (after rounding); None when
        the format gives none (KUKA ``PTP`` with axis percentages).
    q : ndarray, shape (M, 6)
        The positions as written (rounded, mapped back to the model's convention), rad.
    qd, qdd : ndarray, shape (M, 6), or None
        The velocities (rad/s) and accelerations (rad/s^2) written with the points, if any.
    eps : float
        Half a unit of the last printed digit of ``q``, rad.
    unchecked : str
        What cannot be checked because the vendor does not document it (a warning), or empty.
    advice : str
        What to change when a limit is exceeded (the end of the refusal), or empty.
    approach : tuple of float, or None
        ``(speed, acceleration)`` of the move to the first point at the leading axis (rad/s,
        rad/s^2), which may be any joint; None if not given in joint units.
    """

    interpolation: Interpolation
    label: str
    t: np.ndarray | None
    q: np.ndarray
    qd: np.ndarray | None = None
    qdd: np.ndarray | None = None
    eps: float = 0.0
    unchecked: str = ""
    advice: str = ""
    approach: tuple[float, float] | None = None


@dataclass(frozen=True)
class Peak:
    """The worst value of one quantity of a motion against its limit.

    ``score`` > 1 is over the limit with its slack (``allowed``); ``value`` is signed (infinite
    for a trapezoid's jerk), ``limit`` the robot's (``q_max`` or ``q_min`` for positions).
    """

    quantity: str
    joint: int
    value: float
    limit: float
    score: float
    time: float
    how: str

    @property
    def over(self) -> bool:
        return self.score > 1.0

    @property
    def ratio(self) -> float:
        """``|value| / limit`` of a rate (the factor over its limit)."""
        return abs(self.value) / self.limit

    def sentence(self) -> str:
        """``joint 2 jerk 111.6 rad/s^3 <how> at t = 0.3 s is 1.116x its limit (100 rad/s^3)``."""
        unit = _UNIT[self.quantity]
        if self.quantity == "position":
            side = "above q_max" if self.value >= self.limit else "below q_min"
            return (
                f"joint {self.joint + 1} position {self.value:.9g} rad {self.how} at t = {self.time:.6g} s is {side} "
                f"({self.limit:.9g} rad)"
            )
        if not math.isfinite(self.value):
            return (
                f"joint {self.joint + 1} {self.quantity} is unbounded {self.how} from t = {self.time:.6g} s "
                f"(limit {self.limit:.6g} {unit})"
            )
        return (
            f"joint {self.joint + 1} {self.quantity} {abs(self.value):.6g} {unit} {self.how} at t = {self.time:.6g} s "
            f"is {self.ratio:.4g}x its limit ({self.limit:.6g} {unit})"
        )
