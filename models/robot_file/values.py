"""The values of a robot file: the one table reader bound to :class:`RobotFileError`, and the
checks of angles (rad or ``_deg``, plausible in radians) and inertias."""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

import numpy as np

from models.description import RobotFileError
from models.tables import TableReader

#: The value kinds of a robot file (a dictionary built in Python may hold tuples for lists).
VALUES = TableReader(RobotFileError, lists=(list, tuple))
#: A finite number: ``finite(where, key, value)``.
finite = VALUES.number
#: A list of ``n`` finite numbers: ``vector(where, key, value, n)``.
vector = VALUES.vector

#: A DH twist, joint offset or tool angle in radians beyond this magnitude is implausible:
#: degrees given under the radian key (one turn).
PLAUSIBLE_ANGLE_MAX_RAD = 2.0 * math.pi * (1.0 + 1e-9)
#: A joint limit in radians beyond this magnitude is implausible (two turns).
PLAUSIBLE_LIMIT_MAX_RAD = 4.0 * math.pi * (1.0 + 1e-9)


def check_radians(
    where: str, key: str, value: float, limit: float = PLAUSIBLE_ANGLE_MAX_RAD, deg_key: str | None = None
) -> float:
    """Refuse a radian value that is almost certainly degrees (|value| > ``limit``); the
    message suggests ``deg_key`` (default ``key + "_deg"``)."""
    if abs(value) > limit:
        raise RobotFileError(
            f"{where}: key '{key}' = {value:g} rad is implausible (|value| > {limit:.4g} rad); "
            f"a key without '_deg' is in radians: degrees given? use '{deg_key or key + '_deg'}'"
        )
    return value


def angle(where: str, row: Mapping[str, Any], key: str) -> float:
    has_rad, has_deg = key in row, f"{key}_deg" in row
    if has_rad and has_deg:
        raise RobotFileError(f"{where}: give either '{key}' (rad) or '{key}_deg', not both")
    if has_deg:
        return math.radians(finite(where, f"{key}_deg", row[f"{key}_deg"]))
    if has_rad:
        limit = PLAUSIBLE_LIMIT_MAX_RAD if key in ("q_min", "q_max") else PLAUSIBLE_ANGLE_MAX_RAD
        return check_radians(where, key, finite(where, key, row[key]), limit)
    raise RobotFileError(f"{where}: missing key '{key}' (rad) or '{key}_deg'")


def as_written(row: Mapping[str, Any], key: str) -> tuple[str, str]:
    """The key of an angle as the file wrote it (``q_min`` or ``q_min_deg``) and its value text
    with the unit (``"-360 deg"``, ``"1 rad"``)."""
    if f"{key}_deg" in row:
        return f"{key}_deg", f"{float(row[f'{key}_deg']):g} deg"
    return key, f"{float(row[key]):g} rad"


#: Relative tolerance of the triangle inequality of principal moments (rounding in published tables).
INERTIA_TRIANGLE_RTOL = 1e-6


def inertia_matrix(where: str, v: np.ndarray) -> np.ndarray:
    """Symmetric 3x3 inertia from ``[ixx, iyy, izz, ixy, ixz, iyz]`` (kg*m^2), checked physical:
    positive semi-definite and principal moments obeying the triangle inequality."""
    ixx, iyy, izz, ixy, ixz, iyz = (float(x) for x in v)
    I = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    ev = np.linalg.eigvalsh(I)
    scale = max(float(np.max(np.abs(ev))), 1e-300)
    if ev[0] < -INERTIA_TRIANGLE_RTOL * scale or ev[2] > ev[0] + ev[1] + INERTIA_TRIANGLE_RTOL * scale:
        raise RobotFileError(
            f"{where}: key 'inertia' = {[float(x) for x in v]} kg*m^2 is not a physical inertia "
            f"(principal moments {[float(e) for e in ev]}: each must be >= 0 and at most "
            "the sum of the other two); order is [ixx, iyy, izz, ixy, ixz, iyz]"
        )
    return I
