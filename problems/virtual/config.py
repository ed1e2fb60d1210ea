"""The simulation configuration: its top-level and campaign keys, defaults and limits, the checks of values.

The schema is in ``docs/identification.md``; every check raises :class:`SimConfigError`
with a message naming the source, the table, the key and the value.  Nothing here
realises a parameter: the checks are called by the modules that read each table.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from models.errors import InputError


#: Top-level keys of a configuration besides the declared model's tables (``[stiffness]``,
#: ``[registration]``: :func:`~problems.virtual.registry.top_level_tables`).  The keys of those and
#: of each ``[effects.NAME]`` table are declared with their realisation
#: (:mod:`~problems.virtual.effects`, :func:`~problems.virtual.registry.simulates`).
TOP_KEYS = {"seed", "campaign", "noise", "temperature", "effects", "units"}
#: Keys of the ``[campaign]`` table and their defaults.
DEFAULT_CAMPAIGN = {
    "poses": 100,
    "unloaded_rows": 1,
    "loaded_rows": 3,
    "force_magnitudes_N": [50.0, 100.0, 150.0],
    "moment_magnitudes_Nm": [0.0],
    "directions": "random",
    "dt_s": 20.0,
    "r_min_m": 0.25,
    "z_min_m": -0.2,
    "repeats": 0,
    "orientation": False,
}
#: Keys of the ``[noise]`` table and their defaults.
DEFAULT_NOISE = {"sigma_m": 2e-5, "sigma_column": False, "sigma_rad": 2e-5, "sigma_rot_column": False}

#: Largest number of rows a simulated campaign may have (poses x rows per pose).
SIM_MAX_ROWS = 1_000_000
#: Largest amplitude of one periodic joint-error term (rad): a transmission error, not an offset.
SIM_JOINT_ERROR_MAX_AMPLITUDE_RAD = 0.05
#: Largest harmonic (cycles per revolution of the joint) of a periodic joint-error term.
SIM_JOINT_ERROR_MAX_HARMONIC = 200.0


class SimConfigError(InputError):
    """A simulation configuration is malformed; the message names the key."""


def load_config(path: str | Path) -> dict[str, Any]:
    """Read a simulation configuration TOML file."""
    from models.robot import read_text_file

    p = Path(path)
    text = read_text_file(p, "simulation configuration file (TOML)", SimConfigError)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SimConfigError(f"{p}: not valid TOML: {exc}") from None


# ----------------------------------------------------------------------------------
# Checks of values (each names the source, the key and the value)
# ----------------------------------------------------------------------------------


def number(where: str, key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise SimConfigError(f"{where}: key '{key}' must be a finite number, got {v!r}")
    return float(v)


def vector(where: str, key: str, v: Any, n: int, broadcast: bool = True) -> np.ndarray:
    if broadcast and isinstance(v, (int, float)) and not isinstance(v, bool):
        return np.full(n, number(where, key, v))
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise SimConfigError(
            f"{where}: key '{key}' must be {'a number or ' if broadcast else ''}a list of {n} numbers, got {v!r}"
        )
    return np.array([number(where, f"{key}[{i}]", x) for i, x in enumerate(v)])


def at_least(where: str, key: str, v: float | np.ndarray, lo: float, strict: bool = False, what: str = "") -> None:
    """Refuse values below ``lo`` (or equal to it when ``strict``), naming the key and the value."""
    arr = np.atleast_1d(np.asarray(v, dtype=float))
    bad = np.flatnonzero(arr <= lo) if strict else np.flatnonzero(arr < lo)
    if bad.size:
        i = int(bad[0])
        k = key if arr.size == 1 and np.ndim(v) == 0 else f"{key}[{i}]"
        raise SimConfigError(
            f"{where}: key '{k}' must be {'>' if strict else '>='} {lo:g}"
            f"{' ' + what if what else ''}, got {float(arr[i]):g}"
        )


def integer(where: str, key: str, v: Any, lo: int) -> int:
    """An integer >= ``lo`` (a float such as 20.5 or a string is refused)."""
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise SimConfigError(f"{where}: key '{key}' must be an integer >= {lo}, got {v!r}")
    return int(v)


def boolean(where: str, key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise SimConfigError(f"{where}: key '{key}' must be true or false, got {v!r}")
    return v


def magnitudes(where: str, key: str, v: Any) -> np.ndarray:
    """A number or a non-empty list of finite numbers >= 0 (force or moment magnitudes)."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        out = np.array([number(where, key, v)])
    elif isinstance(v, list) and v:
        out = np.array([number(where, f"{key}[{i}]", x) for i, x in enumerate(v)])
    else:
        raise SimConfigError(f"{where}: key '{key}' must be a number or a non-empty list of numbers, got {v!r}")
    at_least(where, key, out if isinstance(v, list) else out[0], 0.0)
    return out


def table(where: str, cfg: Mapping[str, Any], key: str, allowed: set[str]) -> dict[str, Any]:
    t = cfg.get(key, {})
    if not isinstance(t, Mapping):
        raise SimConfigError(f"{where}: '{key}' must be a table")
    unknown = sorted(set(t) - allowed)
    if unknown:
        raise SimConfigError(f"{where}: [{key}]: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    return dict(t)


def joint_list(where: str, links: Any) -> list[int]:
    """``links``, checked to be a list of joint numbers 1..6 (``where``: the table, for messages)."""
    if not isinstance(links, list) or not all(isinstance(x, int) and 1 <= x <= 6 for x in links):
        raise SimConfigError(f"{where}: key 'links' must be a list of joint numbers 1..6, got {links!r}")
    return links
