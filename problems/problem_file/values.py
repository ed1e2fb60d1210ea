"""The values of a problem file: the error type, the generic validators and the plausibility limits.

Every section parser of a problem file (the modules of :mod:`problems.problem_file`) checks its
values with the helpers here (the one reader of tables, :class:`models.tables.TableReader`, bound
to :class:`ProblemFileError`), so every message reads the same: ``"<file>: key '<key>' ..."``, naming the file,
the key (dotted, e.g. ``path.points``) and, for tables of rows, the row; the value found; and
what was expected.

Holds :class:`ProblemFileError`; the checks of one value (numbers, positive numbers, bounded
integers, vectors, rows, an angle given in rad or ``_deg``, a roll-pitch-yaw triple); the check of
a table against the keys it may hold (``TABLE_KEYS``; ``[timing]`` also takes one
``[timing.<method>]`` table per registered timing method); and the plausibility limits that catch
a value in the wrong unit (millimetres for metres, degrees under a radian key).
"""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError
from models.tables import TableReader, is_number
from problems.timing import available_methods

#: The keys each table of a problem file may hold (checked by :func:`table`); a table declared key by
#: key (:class:`models.tables.keys.KeyTable`: ``[payload]``, ``[cost]``, ``[solver]`` in
#: :mod:`problems.problem_file.sections`) passes its own ``names``.
TABLE_KEYS: dict[str, tuple[str, ...]] = {
    "robot": ("model", "tool"),
    "robot.tool": ("xyz", "rpy", "rpy_deg", "body", "cutter"),  # body, cutter: cell_section.py
    "path": ("kind", "start", "end", "points", "positions", "rpy", "rpy_deg", "file", "tolerance_mm"),
    "workpiece": ("xyz", "rpy", "rpy_deg"),
    "orientation": ("rule", "rpy", "rpy_deg", "axis", "half_angle", "half_angle_deg", "scan"),
    "wrench": ("frame", "force", "moment", "per_waypoint"),
    "limits": (
        "velocity",
        "acceleration",
        "jerk",
        "velocity_scale",
        "acceleration_scale",
        "jerk_scale",
        "max_joint_step",
        "max_joint_step_deg",
    ),
    "branch": ("home", "home_deg"),
    "timing": ("methods", "dt", "toppra_gridpoints", "toppra_max_iterations", "ruckig_max_iterations", "dynamic"),
}


class ProblemFileError(InputError):
    """A problem file is malformed; the message names the file, key, value and expectation."""


#: The value kinds of a problem file (every message: "<file>: key '<key>' ...").
VALUES = TableReader(ProblemFileError)
#: The error ``"<file>: key '<key>' <msg>"``: ``err(where, key, msg)`` (to raise).
err = VALUES.fail
#: A finite number: ``number(where, key, v)``.
number = VALUES.number
#: A finite number > 0: ``positive(where, key, v)``.
positive = VALUES.positive
#: An integer in ``[lo, hi]``: ``integer(where, key, v, lo, hi=None)``.
integer = VALUES.integer
#: A list of ``n`` finite numbers: ``vector(where, key, v, n)``.
vector = VALUES.vector
#: true or false: ``flag(where, key, v)``.
flag = VALUES.flag
#: A non-empty list of rows of ``width`` numbers: ``rows(where, key, v, width)``.
rows = VALUES.rows


def vector_or_scalar(where: str, key: str, v: Any, n: int) -> np.ndarray:
    """One number for all ``n``, or a list of ``n`` numbers (the message asks for the list)."""
    if is_number(v):
        return np.full(n, number(where, key, v))
    return vector(where, key, v, n)


def table(where: str, data: Mapping[str, Any], key: str, allowed: tuple[str, ...] | None = None) -> Mapping[str, Any]:
    """The table ``key`` (dotted) of ``data`` (empty when absent), its unknown keys refused: those not in
    ``allowed`` (default: ``TABLE_KEYS[key]``; ``[timing]`` also takes a table per timing method)."""
    parts = key.split(".")
    cur: Any = data
    for p in parts:
        cur = cur.get(p, {}) if isinstance(cur, Mapping) else None
        if not isinstance(cur, Mapping):
            raise err(where, key, f"must be a table, got {cur!r}")
    if allowed is None:
        allowed = TABLE_KEYS[key] + (available_methods() if key == "timing" else ())  # [timing.<method>]
    VALUES.unknown_keys(f"{where}: [{key}]", cur, allowed)
    return cur


def angle_pair(where: str, tab: Mapping[str, Any], key: str, prefix: str) -> tuple[Any, bool] | None:
    """The raw value of ``key`` (rad) or ``key_deg``, and whether it is in degrees."""
    has_rad, has_deg = key in tab, f"{key}_deg" in tab
    if has_rad and has_deg:
        raise ProblemFileError(f"{where}: give either '{prefix}{key}' (rad) or '{prefix}{key}_deg', not both")
    if has_deg:
        return tab[f"{key}_deg"], True
    if has_rad:
        return tab[key], False
    return None


def rpy_angles(where: str, tab: Mapping[str, Any], prefix: str) -> np.ndarray | None:
    got = angle_pair(where, tab, "rpy", prefix)
    if got is None:
        return None
    raw, deg = got
    v = vector(where, f"{prefix}rpy{'_deg' if deg else ''}", raw, 3)
    if not deg:
        check_radians(where, f"{prefix}rpy", v, PLAUSIBLE_RPY_MAX_RAD, f"{prefix}rpy_deg")
    return np.radians(v) if deg else v


def check_positions(where: str, key: str, P: np.ndarray) -> None:
    r = np.linalg.norm(P, axis=1)
    if np.any(r > PLAUSIBLE_POSITION_MAX_M):
        k = int(np.argmax(r))
        raise ProblemFileError(
            f"{where}: key '{key}' row {k}: position {P[k].tolist()} is {r[k]:.4g} m from the base "
            f"(> {PLAUSIBLE_POSITION_MAX_M:g} m); positions are in metres (millimetres given?)"
        )


#: An orientation angle (rpy) in radians beyond this magnitude is implausible: degrees given
#: under the radian key (one turn).
PLAUSIBLE_RPY_MAX_RAD = 2.0 * math.pi * (1.0 + 1e-9)
#: A joint angle (``branch.home``) or joint step in radians beyond this magnitude is
#: implausible (two turns for a joint angle, one turn for a step).
PLAUSIBLE_JOINT_MAX_RAD = 4.0 * math.pi * (1.0 + 1e-9)
PLAUSIBLE_JOINT_STEP_MAX_RAD = 2.0 * math.pi * (1.0 + 1e-9)


def check_radians(where: str, key: str, values: np.ndarray, limit: float, deg_key: str) -> None:
    """Refuse radian values that are almost certainly degrees (|value| > ``limit``), naming the
    key, the value and the ``_deg`` key to use instead."""
    v = np.atleast_1d(np.asarray(values, dtype=float))
    bad = np.flatnonzero(np.abs(v) > limit)
    if bad.size:
        i = int(bad[0])
        raise err(
            where,
            key,
            f"= {v.tolist() if v.size > 1 else float(v[0])} rad is implausible "
            f"(|{float(v[i]):g}| > {limit:.4g} rad): a key without '_deg' is in radians; "
            f"degrees given? use '{deg_key}'",
        )
