"""The load on the TCP: a base-frame wrench, a tool-frame wrench and a payload, added up.

All three act on the TCP and are evaluated at the pose the (deflected) arm takes:

* ``wrench_base`` ``[f (N); m (N*m)]`` in the base frame: constant in space;
* ``wrench_tool`` ``[f; m]`` in the TCP frame: turns with the tool (process forces);
* a payload of mass ``m`` (kg) with centre of mass ``c`` (m, TCP frame): its weight
  ``f = m g`` (``g`` the gravity vector, base frame, m/s^2) acts at ``R c`` from the TCP,
  so ``M = (R c) x f``.

Row layout of :meth:`Load.rows` (the ``L`` input of the arm model's functions,
:data:`models.effects.LOAD_SIZE` = 19)::

    [f_base (3), m_base (3), f_tool (3), m_tool (3), mass (1), com_tcp (3), gravity (3)]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .constants import STANDARD_GRAVITY
from .errors import InputError
from .effects.graph import LOAD_SIZE


def _rows6(x: np.ndarray | None, n: int, name: str) -> np.ndarray:
    if x is None:
        return np.zeros((n, 6))
    a = np.asarray(x, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.shape[1] != 6 or a.shape[0] not in (1, n):
        raise InputError(f"{name}: expected shape (6,) or ({n}, 6), got {a.shape}")
    return np.broadcast_to(a, (n, 6)).copy()


@dataclass(frozen=True)
class Load:
    """The load on the TCP (SI units).

    Attributes
    ----------
    wrench_base : ndarray, shape (6,) or (N, 6)
        ``[f (N); m (N*m)]``, base frame, acting on the TCP.
    wrench_tool : ndarray, shape (6,) or (N, 6)
        ``[f (N); m (N*m)]``, TCP frame, acting on the TCP.
    payload_mass_kg : float
    payload_com_m : ndarray, shape (3,)
        Payload centre of mass, TCP frame, m.
    gravity : ndarray, shape (3,)
        Gravity acceleration acting on the payload, base frame, m/s^2.
    """

    wrench_base: np.ndarray = field(default_factory=lambda: np.zeros(6))
    wrench_tool: np.ndarray = field(default_factory=lambda: np.zeros(6))
    payload_mass_kg: float = 0.0
    payload_com_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -STANDARD_GRAVITY]))

    @classmethod
    def base(cls, wrench: np.ndarray) -> Load:
        """A base-frame wrench only (shape (6,) or (N, 6))."""
        return cls(wrench_base=np.asarray(wrench, dtype=float))

    @property
    def has_payload(self) -> bool:
        return self.payload_mass_kg != 0.0

    @property
    def turns_with_tool(self) -> bool:
        """Whether the wrench on the TCP depends on the tool orientation."""
        return bool(np.any(np.asarray(self.wrench_tool) != 0) or self.has_payload)

    def rows(self, n: int) -> np.ndarray:
        """The load vector of each of ``n`` waypoints, shape (n, LOAD_SIZE)."""
        out = np.zeros((n, LOAD_SIZE))
        out[:, 0:6] = _rows6(self.wrench_base, n, "wrench_base")
        out[:, 6:12] = _rows6(self.wrench_tool, n, "wrench_tool")
        out[:, 12] = float(self.payload_mass_kg)
        out[:, 13:16] = np.asarray(self.payload_com_m, dtype=float).reshape(3)
        out[:, 16:19] = np.asarray(self.gravity, dtype=float).reshape(3)
        return out

    def wrench_at(self, R_tcp: np.ndarray) -> np.ndarray:
        """Wrench on the TCP, base frame, for TCP rotations ``R_tcp`` (N, 3, 3): (N, 6).

        NumPy twin of :func:`models.effects.graph.load_wrench` (used for reporting).
        """
        R = np.atleast_3d(np.asarray(R_tcp, dtype=float))
        if R.ndim == 2:
            R = R[None]
        n = len(R)
        L = self.rows(n)
        fw = L[:, 12:13] * L[:, 16:19]
        f = L[:, 0:3] + np.einsum("nij,nj->ni", R, L[:, 6:9]) + fw
        r = np.einsum("nij,nj->ni", R, L[:, 13:16])
        m = L[:, 3:6] + np.einsum("nij,nj->ni", R, L[:, 9:12]) + np.cross(r, fw)
        return np.hstack([f, m])


def load_rows(load: Load | np.ndarray, n: int) -> np.ndarray:
    """Load vectors (n, LOAD_SIZE) from a :class:`Load`, load rows, or a base-frame wrench
    of shape (6,) or (n, 6)."""
    if isinstance(load, Load):
        return load.rows(n)
    a = np.asarray(load, dtype=float)
    if a.shape[-1] == 6:
        return Load.base(a).rows(n)
    if a.shape[-1] == LOAD_SIZE:
        return np.broadcast_to(np.atleast_2d(a), (n, LOAD_SIZE)).copy()
    raise InputError(
        f"load: expected a Load, a wrench (6 or (N, 6)) or load rows (N, {LOAD_SIZE}); got shape {a.shape}"
    )
