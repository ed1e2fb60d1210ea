"""Plausibility and consistency checks of a measurement table, and their messages.

The limits below catch unit mistakes (millimetres in a metre column, degrees in a
radian column ...); the message of a failed check names the file line, the column
as written and, for a plain column name, the unit suffix that would fix it.
"""

from __future__ import annotations

import math

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError

from .columns import (
    POSITION_COLUMNS,
    Q_COLUMNS,
    ROTATION_COLUMNS,
    SIGMA_ROT_COLUMNS,
    SIGMA_XYZ_COLUMNS,
    WRENCH_COLUMNS,
)
from .table import Measurements

#: A joint angle beyond this magnitude is implausible in radians (rad): two turns.
PLAUSIBLE_ANGLE_MAX_RAD = 4.0 * math.pi
#: A force beyond this is implausible (N); suggests a unit mistake.
PLAUSIBLE_FORCE_MAX_N = 1.0e5
#: A moment beyond this is implausible (N*m).
PLAUSIBLE_MOMENT_MAX_NM = 1.0e4
#: Plausible temperature range, deg C.
PLAUSIBLE_TEMPERATURE_C = (-50.0, 150.0)
#: A measurement standard deviation beyond this is implausible (m).
PLAUSIBLE_SIGMA_MAX_M = 0.01
#: An orientation-measurement standard deviation beyond this is implausible (rad, about 5.7 deg).
PLAUSIBLE_SIGMA_ROT_MAX_RAD = 0.1
#: A measured point farther than this from the nominal model's prediction is not the arm's error (m):
#: a real arm misses its nominal forward kinematics by millimetres (the UR5 of docs/real-data.md by
#: 2.6 mm), a compliant one under load by about 10 mm.  Beyond it the data are in another unit, in
#: another frame, or from another arm (a tracker-dif deviation; identification's nominal check).
PLAUSIBLE_NOMINAL_DEVIATION_M = 0.050

_UNIT_HINT = {"angle": "_deg", "length": "_mm", "force": "_kN", "moment": "_Nmm", "small_angle": "_urad"}


def _first_bad(values: np.ndarray, bad: np.ndarray) -> int:
    return int(np.argmax(bad))


class _Checks:
    """Magnitude and sign checks of one table's columns; messages quote the column as
    written (from ``colmap``) and, for a plain column name, the unit suffix to declare."""

    def __init__(
        self, m: Measurements, colmap: dict[str, tuple[int, str, float]] | None, plain: frozenset[str] | None
    ) -> None:
        self.m = m
        self.where = m.source
        self.colmap = colmap
        self.plain = plain

    def colname(self, base: str) -> str:
        return self.colmap[base][1] if self.colmap and base in self.colmap else base

    def factor(self, base: str) -> float:
        return self.colmap[base][2] if self.colmap and base in self.colmap else 1.0

    def is_plain(self, name: str, base: str) -> bool:
        return name == base or (self.plain is not None and name in self.plain)

    def check(self, base: str, values: np.ndarray, limit: float, qty: str) -> None:
        """Raise for the first value above ``limit`` in magnitude (SI units)."""
        bad = np.abs(values) > limit
        if bad.any():
            i = _first_bad(values, bad)
            hint = _UNIT_HINT.get(qty)
            name = self.colname(base)
            unit_msg = (
                f"; if the column is in other units, declare them by the suffix (e.g. '{name}{hint}')"
                if hint and self.is_plain(name, base)
                else ""
            )
            raise InputError(
                f"{self.where}: line {self.m.line[i]}, column '{name}': value "
                f"{values[i] / self.factor(base):g} is implausible (|value| above {limit:g} in SI "
                f"units){unit_msg}"
            )

    def positive(self, base: str, values: np.ndarray, unit: str) -> None:
        """Raise for the first standard deviation that is not > 0."""
        bad = ~(values > 0)
        if bad.any():
            i = _first_bad(values, bad)
            name = self.colname(base)
            shown = f"{values[i] / self.factor(base):g}" + (f" {unit}" if self.is_plain(name, base) else "")
            raise InputError(
                f"{self.where}: line {self.m.line[i]}, column '{name}': value {shown}; "
                "expected a standard deviation > 0"
            )


def _check_pose_and_load(ck: _Checks, m: Measurements) -> None:
    """Joint angles, forces and moments, position and orientation within their limits."""
    for j, c in enumerate(Q_COLUMNS):
        ck.check(c, m.q[:, j], PLAUSIBLE_ANGLE_MAX_RAD, "angle")
    for j, c in enumerate(WRENCH_COLUMNS):
        ck.check(
            c,
            m.wrench[:, j],
            PLAUSIBLE_FORCE_MAX_N if j < 3 else PLAUSIBLE_MOMENT_MAX_NM,
            "force" if j < 3 else "moment",
        )
    if m.p is not None:
        for j, c in enumerate(POSITION_COLUMNS):
            ck.check(c, m.p[:, j], PLAUSIBLE_POSITION_MAX_M, "length")
    if m.rotation is not None:
        for j, c in enumerate(ROTATION_COLUMNS):
            ck.check(c, m.rotation[:, j], 2 * math.pi, "angle")


def _check_sigma(ck: _Checks, m: Measurements, colmap: dict[str, tuple[int, str, float]] | None) -> None:
    """Position standard deviations (per axis, or the single one) > 0 and plausible."""
    if colmap is not None:
        per_axis = "sigma_x" in colmap
    else:
        per_axis = m.sigma_xyz is not None and not (
            m.sigma is not None and np.array_equal(m.sigma_xyz, np.repeat(m.sigma[:, None], 3, axis=1))
        )
    if per_axis:
        assert m.sigma_xyz is not None
        for j, c in enumerate(SIGMA_XYZ_COLUMNS):
            ck.positive(c, m.sigma_xyz[:, j], "m")
            ck.check(c, m.sigma_xyz[:, j], PLAUSIBLE_SIGMA_MAX_M, "length")
    elif m.sigma is not None:
        ck.positive("sigma", m.sigma, "m")
        ck.check("sigma", m.sigma, PLAUSIBLE_SIGMA_MAX_M, "length")


def _check_sigma_rot(ck: _Checks, m: Measurements, colmap: dict[str, tuple[int, str, float]] | None) -> None:
    """Orientation standard deviations: with a measured orientation, > 0 and plausible."""
    if m.sigma_rot is not None:
        if m.rotation is None:
            raise InputError(f"{ck.where}: orientation standard deviations without the measured orientation rx, ry, rz")
        single = colmap is not None and "sigma_r" in colmap
        for j, c in enumerate(SIGMA_ROT_COLUMNS):
            base = "sigma_r" if single else c
            ck.positive(base, m.sigma_rot[:, j], "rad")
            ck.check(base, m.sigma_rot[:, j], PLAUSIBLE_SIGMA_ROT_MAX_RAD, "small_angle")


def _check_temperature(ck: _Checks, m: Measurements) -> None:
    """Temperatures within :data:`PLAUSIBLE_TEMPERATURE_C`."""
    if m.temperature is not None:
        lo, hi = PLAUSIBLE_TEMPERATURE_C
        bad = (m.temperature < lo) | (m.temperature > hi)
        if bad.any():
            i = _first_bad(m.temperature, bad)
            raise InputError(
                f"{ck.where}: line {m.line[i]}, column '{ck.colname('temperature')}': value "
                f"{m.temperature[i]:g} deg C is outside the plausible range [{lo:g}, {hi:g}] "
                "(temperature is in deg C)"
            )


def _check_time_order(ck: _Checks, m: Measurements) -> None:
    """Times never running backwards."""
    if m.t is not None and m.n > 1:
        back = np.diff(m.t) < 0
        if back.any():
            i = int(np.argmax(back)) + 1
            raise InputError(
                f"{ck.where}: line {m.line[i]}, column '{ck.colname('t')}': time {m.t[i]:g} s is "
                f"earlier than the previous row ({m.t[i - 1]:g} s); rows must be in measurement order"
            )


def _check_duplicates(where: str, m: Measurements) -> None:
    """No duplicated rows: every value equal (a copy, not a repeated measurement)."""
    parts = [m.q, m.wrench]
    for extra in (m.p, m.rotation, m.sigma_xyz, m.sigma_rot):
        if extra is not None:
            parts.append(extra)
    for extra1 in (m.t, m.temperature, m.sigma):
        if extra1 is not None:
            parts.append(extra1[:, None])
    full = np.hstack(parts)
    if m.point is not None:
        _u, pid = np.unique(m.point, return_inverse=True)
        full = np.hstack([full, pid.reshape(-1, 1).astype(float)])
    _uniq, inv, counts = np.unique(full, axis=0, return_inverse=True, return_counts=True)
    inv = np.asarray(inv).reshape(-1)
    if (counts > 1).any():
        dup_rows = np.flatnonzero(counts[inv] > 1)
        a = dup_rows[0]
        b = next(r for r in dup_rows if r != a and inv[r] == inv[a])
        raise InputError(
            f"{where}: lines {m.line[a]} and {m.line[b]} are identical in every column "
            "(a duplicated row); remove the copy, or if it is a genuine repeated measurement "
            "its measured values cannot be bit-identical"
        )


def validate(
    m: Measurements, colmap: dict[str, tuple[int, str, float]] | None = None, *, _plain: frozenset[str] | None = None
) -> None:
    """Check magnitudes and consistency of a table (raises :class:`InputError`).

    ``colmap`` (quantity -> (column index, column as written, SI factor)) lets the
    messages quote the file's column and unit."""
    if m.n == 0:
        raise InputError(f"{m.source}: no measurement rows")
    ck = _Checks(m, colmap, _plain)
    _check_pose_and_load(ck, m)
    _check_sigma(ck, m, colmap)
    _check_sigma_rot(ck, m, colmap)
    _check_temperature(ck, m)
    _check_time_order(ck, m)
    _check_duplicates(m.source, m)
