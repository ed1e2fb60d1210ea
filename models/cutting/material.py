"""A work material's mechanistic cutting coefficients (linear edge-force model) and the shipped table.

The six coefficients of Altintas' linear edge-force model (*Manufacturing Automation*, 2nd ed., 2012,
ch. 2; :mod:`.force`): the cutting (shearing) coefficients ``Ktc, Krc, Kac`` (N/m^2, force per chip
area) and the edge (ploughing) coefficients ``Kte, Kre, Kae`` (N/m, force per edge length), in the
tangential, radial and axial directions.  They belong to a pair of material and tool (geometry,
coating, wear): a table row is only a starting value for another tool.

The shipped table ``models/tables/cutting_materials.toml`` holds published sets, each with its source
and the tool it was measured with (:func:`material`, :func:`material_names`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from ..errors import InputError

__all__ = [
    "unit_mistake",
    "MIN_CUTTING_N_M2",
    "MIN_EDGE_N_M",
    "CuttingCoefficients",
    "material",
    "material_names",
]

#: Below this the cutting coefficients (the largest |Ktc, Krc, Kac|, N/m^2) are taken for N/mm^2
#: given as SI.  Metals have Ktc about 3e8 (aluminium) to 5e9 N/m^2 (hardened steel, nickel
#: alloys); given in N/mm^2 by mistake they read 300 to 5000.  1e6 N/m^2 (1 N/mm^2) leaves two
#: decades on both sides (plastics and wood cut at 1e7 N/m^2 and more).
MIN_CUTTING_N_M2 = 1e6
#: Below this (and not zero) the edge coefficients (the largest |Kte, Kre, Kae|, N/m) are taken for
#: N/mm given as SI.  Published edge coefficients of metals are about 5 to 200 N/mm (5e3 to 2e5 N/m);
#: given in N/mm by mistake they read 5 to 200.  All three may be zero (no edge force).
MIN_EDGE_N_M = 500.0

#: Below these a single coefficient typed under its SI key was given in N/mm^2 (cutting) or N/mm
#: (edge) (:func:`unit_mistake`): one key at a time, so lower than the set's floors above (a small
#: radial or axial coefficient of a set may lie below those).
KEY_FLOOR = {"cutting": 1e5, "edge": 10.0}
#: Published unit to SI: N/mm^2 -> N/m^2, N/mm -> N/m.
KEY_FACTOR = {"cutting": 1e6, "edge": 1e3}


def unit_mistake(key: str, value: float) -> str | None:
    """What is wrong with coefficient ``key`` (``"Ktc"`` ... ``"Kae"``) = ``value`` typed in SI, if
    it looks like the published unit (N/mm^2, N/mm): the message, with the SI value; else None."""
    kind = "cutting" if key in _NAMES[:3] else "edge"
    if not 0.0 < abs(value) < KEY_FLOOR[kind]:
        return None
    unit, other = ("N/m²", "N/mm²") if kind == "cutting" else ("N/m", "N/mm")
    return f"= {value:g} is far too small for {unit}: it looks like {other} (in {unit}: {value * KEY_FACTOR[kind]:g})"


#: The shipped table (``models/tables``).
TABLE_FILE = "cutting_materials.toml"
_NAMES = ("Ktc", "Krc", "Kac", "Kte", "Kre", "Kae")
#: Keys of a table row, in the published units (converted to SI when read) with their factor to SI.
TABLE_KEYS = {
    "Ktc_N_mm2": 1e6,
    "Krc_N_mm2": 1e6,
    "Kac_N_mm2": 1e6,
    "Kte_N_mm": 1e3,
    "Kre_N_mm": 1e3,
    "Kae_N_mm": 1e3,
}


@dataclass(frozen=True)
class CuttingCoefficients:
    """The six coefficients of the linear edge-force model (SI).

    Attributes
    ----------
    Ktc, Krc, Kac : float
        Tangential, radial, axial cutting coefficients, N/m^2 (``Ktc > 0``).
    Kte, Kre, Kae : float
        Tangential, radial, axial edge coefficients, N/m.
    name : str
        The material (and tool) they belong to.
    source : str
        Where they come from.

    Raises
    ------
    InputError
        A value not finite, ``Ktc <= 0``, or magnitudes of N/mm^2 or N/mm given as SI (the message
        gives the SI value).
    """

    Ktc: float
    Krc: float
    Kac: float
    Kte: float
    Kre: float
    Kae: float
    name: str = ""
    source: str = ""

    def __post_init__(self) -> None:
        what = f" of '{self.name}'" if self.name else ""
        values = self.as_vector()
        for key, value in zip(_NAMES, values):
            if not math.isfinite(value):
                raise InputError(f"cutting coefficient {key}{what} must be finite, got {value!r}")
        if not self.Ktc > 0.0:
            raise InputError(f"cutting coefficient Ktc{what} must be > 0 N/m^2, got {self.Ktc!r}")
        cut = np.abs(values[:3]).max()
        if cut < MIN_CUTTING_N_M2:
            raise InputError(
                f"cutting coefficients{what} (Ktc, Krc, Kac) = {tuple(values[:3].tolist())} look like N/mm^2, "
                f"expected N/m^2 (>= {MIN_CUTTING_N_M2:g}): in SI they would be {tuple((values[:3] * 1e6).tolist())}"
            )
        edge = np.abs(values[3:]).max()
        if 0.0 < edge < MIN_EDGE_N_M:
            raise InputError(
                f"edge coefficients{what} (Kte, Kre, Kae) = {tuple(values[3:].tolist())} look like N/mm, "
                f"expected N/m (largest >= {MIN_EDGE_N_M:g}, or all 0): in SI they would be "
                f"{tuple((values[3:] * 1e3).tolist())}"
            )

    def as_vector(self) -> np.ndarray:
        """``[Ktc, Krc, Kac, Kte, Kre, Kae]``, shape (6,), N/m^2 and N/m."""
        return np.array([self.Ktc, self.Krc, self.Kac, self.Kte, self.Kre, self.Kae], dtype=float)


def _row(key: str, row: object) -> CuttingCoefficients:
    where = f"{TABLE_FILE} [{key}]"
    if not isinstance(row, dict):
        raise InputError(f"{where} must be a table, got {type(row).__name__}")
    unknown = set(row) - set(TABLE_KEYS) - {"name", "source", "tool"}
    if unknown:
        raise InputError(f"{where}: unknown keys {sorted(unknown)}, expected {sorted(TABLE_KEYS)}, name, source, tool")
    values = []
    for k, factor in TABLE_KEYS.items():
        v = row.get(k)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise InputError(f"{where}.{k} must be a number, got {v!r}")
        values.append(float(v) * factor)
    for k in ("source", "tool"):
        if not isinstance(row.get(k), str) or not row[k].strip():
            raise InputError(f"{where}.{k} must be a non-empty string")
    source = f"{row['source']} Tool: {row['tool']}"
    return CuttingCoefficients(*values, name=str(row.get("name", key)), source=source)


@lru_cache(maxsize=1)
def _table() -> dict[str, CuttingCoefficients]:
    text = resources.files("models").joinpath("tables", TABLE_FILE).read_text(encoding="utf-8")
    data = tomllib.loads(text)
    return {key.lower(): _row(key, row) for key, row in data.items()}


def material_names() -> list[str]:
    """The keys of the shipped table's rows, sorted."""
    return sorted(_table())


def material(name: str) -> CuttingCoefficients:
    """A shipped row by key (case-insensitive).

    Raises
    ------
    InputError
        An unknown name (the message lists the known ones).
    """
    table = _table()
    try:
        return table[str(name).strip().lower()]
    except KeyError:
        raise InputError(f"unknown cutting material {name!r}, expected one of {', '.join(sorted(table))}") from None
