"""The simulation configuration: its top-level and campaign keys, defaults and limits, the checks of values.

The schema is in ``docs/identification.md``; every check raises :class:`SimConfigError`
with a message naming the source, the table, the key and the value.  Nothing here
realises a parameter: the checks are called by the modules that read each table.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from models.errors import InputError
from models.tables import TableReader, is_number


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
    from models.tables.text_file import read_text_file

    p = Path(path)
    text = read_text_file(p, "simulation configuration file (TOML)", SimConfigError)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SimConfigError(f"{p}: not valid TOML: {exc}") from None


# ----------------------------------------------------------------------------------
# Checks of values (each names the source, the key and the value)
# ----------------------------------------------------------------------------------


#: The value kinds of a simulation configuration (a number is "a finite number" in one message).
VALUES = TableReader(
    SimConfigError,
    lists=(list, tuple),
    not_number="must be a finite number, got {v!r}",
    not_finite="must be a finite number, got {v!r}",
)
#: A finite number: ``number(where, key, v)``.
number = VALUES.number
#: Numbers below a bound refused: ``at_least(where, key, v, lo, strict=False, what="")``.
at_least = VALUES.at_least
#: An integer ``>= lo`` (a float such as 20.5 or a string is refused): ``integer(where, key, v, lo)``.
integer = VALUES.integer
#: true or false: ``flag(where, key, v)``.
flag = VALUES.flag


def vector(where: str, key: str, v: Any, n: int, broadcast: bool = True) -> np.ndarray:
    """A list of ``n`` finite numbers, shape (n,); ``broadcast``: one number stands for all."""
    return VALUES.vector(where, key, v, n, scalar=broadcast)


def magnitudes(where: str, key: str, v: Any) -> np.ndarray:
    """A number or a non-empty list of finite numbers >= 0 (force or moment magnitudes)."""
    if is_number(v):
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
    VALUES.unknown_keys(f"{where}: [{key}]", t, sorted(allowed))
    return dict(t)


def joint_list(where: str, links: Any, key: str = "links") -> list[int]:
    """``links``, checked to be a list of joint numbers 1..6 (``where``: the table, ``key``: its
    key, for messages)."""
    if not isinstance(links, list) or not all(isinstance(x, int) and 1 <= x <= 6 for x in links):
        raise SimConfigError(f"{where}: key '{key}' must be a list of joint numbers 1..6, got {links!r}")
    return links
