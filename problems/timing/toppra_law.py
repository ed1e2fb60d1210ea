"""Scalar time law ``s(t)`` built from TOPP-RA's gridpoint path velocities.

Used by :mod:`problems.timing.toppra_method`; see there for the two kinds
(``"smoothed"`` and ``"spline"``). ``s`` is the dimensionless path parameter
of :mod:`problems.timing.path`, ``t`` the time in s.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ToppraLaw"]


class ToppraLaw:
    """Scalar time law ``s(t)`` built from TOPP-RA's gridpoint velocities.

    Parameters
    ----------
    grid : np.ndarray
        Shape ``(K,)``, gridpoints in s, from 0 to 1.
    sd : np.ndarray
        Shape ``(K,)``, 1/s, path velocity at the gridpoints (``sd[0] =
        sd[-1] = 0``), with ``sd[i] + sd[i + 1] > 0`` on every interval.
    kind : str
        ``"smoothed"``: the constant-path-acceleration law between gridpoints
        (exact meaning of TOPP-RA's solution), filtered by a causal moving
        average of width ``window`` s. It is C2, ends with zero velocity *and*
        acceleration, has jerk bounded by (acceleration jump) / window and
        stays within the range of the unfiltered velocities and accelerations
        over the window; the motion lasts ``window`` s longer.
        ``"spline"``: cubic spline through the ``(t_i, s_i)`` pairs with zero
        end velocity (toppra's ``ParametrizeSpline`` convention), which rings
        between gridpoints.
    window : float
        Moving-average width (s), > 0, used by ``"smoothed"`` only.

    Attributes
    ----------
    tgrid : np.ndarray
        Shape ``(K,)``, s, time of each gridpoint in the raw law.
    duration : float
        End of the motion (s).
    breaks : np.ndarray
        Times (s) where the law's acceleration has kinks (added to the check
        grid).
    lag : float
        s: the law at ``t`` depends on the raw law on ``[t - lag, t]``.
    """

    def __init__(self, grid: np.ndarray, sd: np.ndarray, kind: str, window: float) -> None:
        from scipy.interpolate import CubicSpline, PPoly  # on first use: a problem file is read without SciPy

        ds = np.diff(grid)
        vmean = 0.5 * (sd[1:] + sd[:-1])
        self.tgrid = np.concatenate(([0.0], np.cumsum(ds / vmean)))  # (K,) s
        t_end = float(self.tgrid[-1])
        self.kind = kind
        if kind == "spline":
            self._spline = CubicSpline(self.tgrid, grid, bc_type=((1, 0.0), (1, 0.0)))
            self.duration = t_end
            self.breaks = self.tgrid
            self.lag = 0.0
            return
        self.window = float(window)
        self.lag = self.window
        acc = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)  # (K-1,) 1/s^2
        x = np.concatenate(([-self.window], self.tgrid, [t_end + self.window]))
        c = np.zeros((3, x.size - 1))
        c[0, 1:-1] = 0.5 * acc
        c[1, 1:-1] = sd[:-1]
        c[2, 1:-1] = grid[:-1]
        c[2, -1] = 1.0
        self._law = PPoly(c, x)  # raw law, at rest outside [0, t_end]
        self._integral = self._law.antiderivative()
        self.duration = t_end + self.window
        self.breaks = np.concatenate((self.tgrid, self.tgrid + self.window))

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Evaluate the law.

        Parameters
        ----------
        t : np.ndarray
            Shape ``(M,)``, s, in ``[0, duration]``.

        Returns
        -------
        s, sd, sdd, sddd : np.ndarray
            Shape ``(M,)``: -, 1/s, 1/s^2, 1/s^3.
        """
        if self.kind == "spline":
            sp = self._spline
            return sp(t), sp(t, 1), sp(t, 2), sp(t, 3)
        w = self.window
        lo = t - w
        law = self._law
        s = (self._integral(t) - self._integral(lo)) / w
        sd = (law(t) - law(lo)) / w
        sdd = (law(t, 1) - law(lo, 1)) / w
        sddd = (law(t, 2) - law(lo, 2)) / w
        return s, sd, sdd, sddd
