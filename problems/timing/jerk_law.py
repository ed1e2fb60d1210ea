"""The time law of the jerk-optimal method's profile (:mod:`problems.timing.jerk_optimal`), exactly as
its NLP models it: :class:`JerkLaw` maps times to the path parameter and its derivatives.

Units: s for times, 1/s, 1/s^2 and 1/s^3 for the path parameter's derivatives.
"""

from __future__ import annotations

import numpy as np

__all__ = ["JerkLaw"]

#: Gauss-Legendre nodes and weights on [0, 1] for the interval times of the law.
_GL_X, _GL_W = (0.5 * (np.polynomial.legendre.leggauss(6)[0] + 1.0), 0.5 * np.polynomial.legendre.leggauss(6)[1])
#: Newton iterations that invert t(s) inside an interval.
_NEWTON_STEPS = 6


class JerkLaw:
    """The time law of the optimised profile, exactly as the NLP models it.

    Inside, the path acceleration is linear in ``s`` on each interval, so
    ``x(s)^2 = x_k^2 + 2 u_k sigma + c_k sigma^2`` (``sigma = s - s_k``, ``c_k = du/ds`` chosen so
    that ``x`` reaches ``x_{k+1}`` exactly), ``sdd = u_k + c_k sigma``,
    ``sddd = x(s) c_k``, and ``t(s) = integral ds / x`` (Gauss-Legendre, inverted by Newton's
    method when sampling).  The end intervals are constant-jerk cubics in time from and to rest
    (``s = J t^3 / 6`` over ``h = 3 ds / x``, ``J = 2 x / h^2``).

    Parameters
    ----------
    s, x, u : ndarray, shape (K + 1,)
        Gridpoints (-), path velocity (1/s) and acceleration (1/s^2) there.
    scale : float
        Uniform slow-down >= 1 (time stretched by it).
    """

    def __init__(self, s: np.ndarray, x: np.ndarray, u: np.ndarray, scale: float = 1.0) -> None:
        self.s, self.x, self.u, self.scale = s, x, u, float(scale)
        ds = np.diff(s)
        # du/ds per interval from the end velocities, so that s and ds/dt are exactly continuous
        # whatever the solver's tolerance (d2s/dt2 then jumps by that tolerance at gridpoints)
        self.ds, self.du = ds, (x[1:] ** 2 - x[:-1] ** 2 - 2.0 * u[:-1] * ds) / ds**2
        h = np.empty(ds.size)
        h[0], h[-1] = 3.0 * ds[0] / x[1], 3.0 * ds[-1] / x[-2]
        inner = slice(1, ds.size - 1)
        sig = ds[inner, None] * _GL_X[None, :]
        h[inner] = ds[inner] * (_GL_W[None, :] / self._x(np.arange(1, ds.size - 1)[:, None], sig)).sum(axis=1)
        self.h = h
        self.t = np.concatenate(([0.0], np.cumsum(h)))
        self.duration = float(self.t[-1]) * self.scale
        self.breaks = self.t[1:-1] * self.scale

    def _x(self, k: np.ndarray, sig: np.ndarray) -> np.ndarray:
        """Path velocity at ``sigma`` into interval ``k`` (inner intervals), 1/s."""
        b = self.x[k] ** 2 + 2.0 * self.u[k] * sig + self.du[k] * sig**2
        return np.sqrt(np.maximum(b, 1e-300))

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``s, sd, sdd, sddd`` at times ``t`` (s), each shape (M,)."""
        k_s = self.scale
        tau_all = np.asarray(t, dtype=float) / k_s
        K = self.ds.size
        i = np.clip(np.searchsorted(self.t, tau_all, side="right") - 1, 0, K - 1)
        tau = tau_all - self.t[i]
        s, sd, sdd, sddd = (np.empty_like(tau) for _ in range(4))
        first, last = i == 0, i == K - 1
        if first.any():
            J = 2.0 * self.x[1] / self.h[0] ** 2
            tt = tau[first]
            s[first], sd[first], sdd[first], sddd[first] = J * tt**3 / 6, J * tt**2 / 2, J * tt, J
        if last.any():
            J = 2.0 * self.x[K - 1] / self.h[K - 1] ** 2
            tt = self.h[K - 1] - tau[last]
            s[last], sd[last], sdd[last], sddd[last] = 1.0 - J * tt**3 / 6, J * tt**2 / 2, -J * tt, J
        mid = ~(first | last)
        if mid.any():
            s[mid], sd[mid], sdd[mid], sddd[mid] = self._inner(i[mid], tau[mid])
        return s, sd / k_s, sdd / k_s**2, sddd / k_s**3

    def _inner(self, k: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, ...]:
        """The law inside inner intervals ``k`` at times ``tau`` after their start."""
        ds = self.ds[k]
        sig = np.clip(tau * 0.5 * (self.x[k] + self.x[k + 1]), 0.0, ds)
        for _ in range(_NEWTON_STEPS):
            t_sig = sig * (_GL_W[None, :] / self._x(k[:, None], sig[:, None] * _GL_X[None, :])).sum(axis=1)
            sig = np.clip(sig - (t_sig - tau) * self._x(k, sig), 0.0, ds)
        xs = self._x(k, sig)
        us = self.u[k] + self.du[k] * sig
        return self.s[k] + sig, xs, us, xs * self.du[k]
