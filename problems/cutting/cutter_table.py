"""An end mill read from a TOML table: ``[cutter]`` of a cutter file, ``[robot.tool.cutter]`` of a problem file.

Keys (lengths in metres, the helix angle in degrees)::

    shape         = "flat" | "ball" | "bull_nose"
    diameter      = 0.010        # D, m
    corner_radius = 0.0          # r, m: flat 0 (default), ball D/2 (default), bull_nose required
    flutes        = 4            # number of cutting edges
    helix_deg     = 30.0         # helix angle at the flank, deg
    flute_length  = 0.030        # length of the cutting edges from the tip, m
    length        = 0.045        # stick-out from the tip to the holder, m (optional where allowed)

Every message names the file and the dotted key (``cutter.diameter`` or ``robot.tool.cutter.diameter``),
the value found and what was expected.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from models.cutting.cutter import CutterShape, EndMill
from models.errors import InputError
from models.tables import TableReader

__all__ = ["CUTTER_KEYS", "MAX_PLAUSIBLE_DIAMETER_M", "parse_cutter_table", "read_cutter_file"]

#: The keys a cutter table may hold, in the order messages list them.
CUTTER_KEYS = ("shape", "diameter", "corner_radius", "flutes", "helix_deg", "flute_length", "length")
#: Largest end-mill diameter taken as metres; a larger one was almost surely given in millimetres.
MAX_PLAUSIBLE_DIAMETER_M = 0.2
#: Largest flute length / stick-out taken as metres (same reason).
MAX_PLAUSIBLE_LENGTH_M = 1.0
#: Most flutes of an end mill.
MAX_FLUTES = 64


def parse_cutter_table(
    where: str,
    table: Any,
    prefix: str = "cutter",
    *,
    length_required: bool = True,
    error: type[InputError] = InputError,
) -> EndMill:
    """The end mill a cutter table describes.

    Parameters
    ----------
    where : str
        The file, as messages name it.
    table : mapping
        The table as parsed from TOML (str keys).
    prefix : str
        The table's dotted name in messages (``"cutter"``, ``"robot.tool.cutter"``).
    length_required : bool
        Whether ``length`` (the stick-out) must be given; when not, it defaults to the flute length
        (enough for a force computation, not for a collision check).
    error : type of InputError
        The error class raised (a problem file passes its own).

    Returns
    -------
    EndMill

    Raises
    ------
    InputError
        (or ``error``) A key missing, unknown or out of range; the message names ``where``, the key,
        the value and what was expected.
    """
    values = TableReader(error)
    if not isinstance(table, Mapping):
        raise error(f"{where}: '{prefix}' must be a table of {', '.join(CUTTER_KEYS)}, got {table!r}")
    values.unknown_keys(f"{where}: table '{prefix}'", table, CUTTER_KEYS)

    def key(name: str) -> str:
        return f"{prefix}.{name}"

    def need(name: str) -> Any:
        if name not in table:
            raise error(f"{where}: key '{key(name)}' is missing ({_EXPECTED[name]})")
        return table[name]

    shape_text = values.text(where, key("shape"), need("shape"))
    shapes = [s.value for s in CutterShape]
    if shape_text not in shapes:
        raise values.fail(where, key("shape"), f"must be one of {', '.join(shapes)}, got {shape_text!r}")
    shape = CutterShape(shape_text)
    diameter = _length(values, where, key("diameter"), need("diameter"), MAX_PLAUSIBLE_DIAMETER_M)
    corner = _corner_radius(values, where, key("corner_radius"), table.get("corner_radius"), shape, diameter)
    flutes = values.integer(where, key("flutes"), need("flutes"), 1, MAX_FLUTES)
    helix_deg = values.number(where, key("helix_deg"), need("helix_deg"))
    if not 0.0 <= helix_deg < 75.0:
        raise values.fail(where, key("helix_deg"), f"must be in [0, 75) degrees, got {helix_deg:g}")
    flute_length = _length(values, where, key("flute_length"), need("flute_length"), MAX_PLAUSIBLE_LENGTH_M)
    if "length" in table or length_required:
        length = _length(values, where, key("length"), need("length"), MAX_PLAUSIBLE_LENGTH_M)
    else:
        length = flute_length
    try:
        return EndMill(shape, diameter, corner, flutes, math.radians(helix_deg), flute_length, length)
    except InputError as exc:  # the end mill's own cross-checks (flute length >= corner radius ...)
        raise error(f"{where}: table '{prefix}': {exc}") from None


#: What each required key holds, for the message of a missing key.
_EXPECTED = {
    "shape": "flat, ball or bull_nose",
    "diameter": "the cutter diameter in metres",
    "flutes": "the number of cutting edges",
    "helix_deg": "the helix angle in degrees, 0 for straight flutes",
    "flute_length": "the length of the cutting edges from the tip, in metres",
    "length": "the stick-out from the tip to the holder, in metres",
}


def _length(values: TableReader, where: str, key: str, v: Any, most: float) -> float:
    """A length in metres: > 0 and at most ``most`` (a larger value was given in millimetres)."""
    f = values.positive(where, key, v)
    if f > most:
        raise values.fail(where, key, f"must be in metres (millimetres given?): got {f:g}, expected at most {most:g} m")
    return f


def _corner_radius(values: TableReader, where: str, key: str, v: Any, shape: CutterShape, diameter: float) -> float:
    """The corner radius: given, or the shape's own (flat 0, ball D/2); a bull-nose needs one."""
    if v is None:
        if shape is CutterShape.BULL_NOSE:
            raise _missing_corner(values, where, key)
        return 0.0 if shape is CutterShape.FLAT else diameter / 2.0
    r = values.number(where, key, v)
    if r < 0.0 or r > diameter / 2.0:
        raise values.fail(where, key, f"must be in [0, D/2 = {diameter / 2.0:g}] m, got {r:g}")
    return r


def _missing_corner(values: TableReader, where: str, key: str) -> InputError:
    """The error of a bull-nose cutter table without its corner radius."""
    return values.error(f"{where}: key '{key}' is missing (a bull_nose end mill's corner radius in metres)")


def read_cutter_file(path: str | Path) -> EndMill:
    """The end mill of a cutter file: a TOML file with a ``[cutter]`` table (``length`` optional).

    Raises
    ------
    InputError
        The file cannot be read or parsed, has no ``[cutter]`` table, or the table is wrong (the
        message names the file and the key).
    """
    where = str(path)
    try:
        doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{where}: no such file (expected a TOML file with a [cutter] table)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{where}: cannot read it as UTF-8 text ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{where}: not valid TOML ({exc})") from None
    if "cutter" not in doc:
        raise InputError(f"{where}: no [cutter] table (keys {', '.join(CUTTER_KEYS)}; docs/cutting.md)")
    other = sorted(set(doc) - {"cutter"})
    if other:
        raise InputError(f"{where}: unknown table(s) or key(s) {other}; a cutter file holds one [cutter] table")
    return parse_cutter_table(where, doc["cutter"], "cutter", length_required=False)
