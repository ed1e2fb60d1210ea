"""The :class:`Measurements` table (a validated measurement table in SI units)."""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class Measurements:
    """A validated measurement table in SI units.

    Attributes
    ----------
    q : ndarray, shape (N, 6)
        Commanded joint angles, rad.
    wrench : ndarray, shape (N, 6)
        ``[fx, fy, fz, mx, my, mz]`` on the TCP, base frame, N and N*m.
    p : ndarray, shape (N, 3) or None
        Measured point, measurement frame, m (None for command-only files).
    t : ndarray, shape (N,) or None
        Time, s.  When the file gave date-times, seconds since :attr:`t_origin`
        (the first row's date-time, so ``t[0] == 0``).
    point : ndarray of str, shape (N,) or None
        Pose identifier.
    rotation : ndarray, shape (N, 3) or None
        Measured orientation as a rotation vector, rad (validated; not used by the fit).
    temperature : ndarray, shape (N,) or None
        deg C.
    sigma : ndarray, shape (N,) or None
        Standard deviation of the position measurement, m, one value per row that
        stands for every axis.  From the ``sigma`` column; when the file gives
        ``sigma_x, sigma_y, sigma_z`` instead, the per-row RMS over the three axes,
        ``sqrt((sx**2 + sy**2 + sz**2) / 3)`` (see :attr:`sigma_xyz` for the axes).
    line : ndarray of int, shape (N,)
        File line number of each row (1-based, header is line 1 of the table).
    source : str
        File name (for messages).
    units : dict
        Column actually read (as written in the file) -> SI factor applied.
    sigma_xyz : ndarray, shape (N, 3) or None
        Standard deviation of the position measurement per axis ``x, y, z`` of the
        measurement frame, m.  From ``sigma_x, sigma_y, sigma_z``, or ``sigma``
        broadcast to the three axes when only ``sigma`` is given.
    sigma_rot : ndarray, shape (N, 3) or None
        Standard deviation of the orientation measurement per component of the
        rotation vector ``rx, ry, rz``, rad.  From ``sigma_rx, sigma_ry, sigma_rz``,
        or ``sigma_r`` broadcast to the three; only with ``rotation``.
    notes : list of str
        What the reader decided by itself and the user should know (a detected CSV
        dialect, date-times read as times, a joint-name mapping), one line each,
        starting with the file name.  The library never prints them.
    columns : dict
        Quantity (``q1``, ``x``, ``sigma_x`` ...) -> the column that held it, as
        written in the file (``q1_deg``, ``shoulder_pan_joint``, ``x_mm`` ...).
    t_origin : datetime.datetime or None
        The first row's date-time when ``t`` was given as date-times (aware when the
        file gave a time zone, naive otherwise); ``None`` for numeric times.
    target : ndarray, shape (N, 3) or None
        The file's target position of the measured point, robot base frame, m: the
        acquisition software's nominal forward kinematics of the commanded joints
        (the ``x_t, y_t, z_t`` columns of the tracker-dif format; None otherwise).
        Identification compares it with the declared robot's nominal model.
    file_format : str
        The format the file was read as (``compplan``, ``tracker-dif`` ...).
    """

    q: np.ndarray
    wrench: np.ndarray
    p: np.ndarray | None = None
    t: np.ndarray | None = None
    point: np.ndarray | None = None
    rotation: np.ndarray | None = None
    temperature: np.ndarray | None = None
    sigma: np.ndarray | None = None
    line: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    source: str = "<memory>"
    units: dict[str, float] = field(default_factory=dict)
    sigma_xyz: np.ndarray | None = None
    sigma_rot: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    columns: dict[str, str] = field(default_factory=dict)
    t_origin: _dt.datetime | None = None
    target: np.ndarray | None = None
    file_format: str = "compplan"

    def __post_init__(self) -> None:
        n = len(self.q)
        if len(self.line) != n:
            self.line = np.arange(2, n + 2)
        # the single sigma and the per-axis sigmas describe the same thing: fill the missing one
        if self.sigma_xyz is None and self.sigma is not None:
            s = np.asarray(self.sigma, dtype=float).reshape(-1)
            self.sigma_xyz = np.repeat(s[:, None], 3, axis=1)
        elif self.sigma_xyz is not None:
            self.sigma_xyz = np.asarray(self.sigma_xyz, dtype=float).reshape(-1, 3)
            if self.sigma is None:
                self.sigma = sigma_rms(self.sigma_xyz)
        if self.sigma_rot is not None:
            self.sigma_rot = np.asarray(self.sigma_rot, dtype=float).reshape(-1, 3)

    @property
    def n(self) -> int:
        return len(self.q)

    def subset(self, idx: np.ndarray) -> Measurements:
        """Rows ``idx`` (integer indices or boolean mask) as a new table (notes, column
        names and the date-time origin carried along)."""

        def s(a: Any) -> Any:
            return None if a is None else a[idx]

        return Measurements(
            q=self.q[idx],
            wrench=self.wrench[idx],
            p=s(self.p),
            t=s(self.t),
            point=s(self.point),
            rotation=s(self.rotation),
            temperature=s(self.temperature),
            sigma=s(self.sigma),
            line=self.line[idx],
            source=self.source,
            units=dict(self.units),
            sigma_xyz=s(self.sigma_xyz),
            sigma_rot=s(self.sigma_rot),
            notes=list(self.notes),
            columns=dict(self.columns),
            t_origin=self.t_origin,
            target=s(self.target),
            file_format=self.file_format,
        )

    def pose_groups(self) -> np.ndarray:
        """Integer pose id per row, shape (N,): the ``point`` column if given, else
        rows with identical commanded joints (to 1e-9 rad) form one pose."""
        if self.point is not None:
            _u, inv = np.unique(self.point, return_inverse=True)
            return inv.astype(int)
        key = np.round(self.q, 9)
        _u, inv = np.unique(key, axis=0, return_inverse=True)
        return np.asarray(inv, dtype=int).reshape(-1)

    def load_varies(self) -> bool:
        """True when the wrench is not the same on every row."""
        return bool(np.ptp(self.wrench, axis=0).max() > 0.0) if self.n else False


def sigma_rms(sigma_xyz: np.ndarray) -> np.ndarray:
    """Per-row RMS of per-axis standard deviations.

    Parameters
    ----------
    sigma_xyz : ndarray, shape (N, 3)
        Standard deviations per axis, m.

    Returns
    -------
    ndarray, shape (N,)
        ``sqrt(mean(sigma_xyz**2, axis=1))``, m: the one standard deviation per axis
        with the same total variance.
    """
    s = np.asarray(sigma_xyz, dtype=float).reshape(-1, 3)
    return np.sqrt(np.mean(s**2, axis=1))
