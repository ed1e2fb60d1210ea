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

import tomllib
from collections.abc import Mapping
from pathlib import Path

from models.cutting.cutter import EndMill
from models.errors import InputError
from problems.problem_file.cutter_section import END_MILL_KEYS, parse_cutter_table

__all__ = ["read_cutter_file"]


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
        raise InputError(f"{where}: no [cutter] table (keys {', '.join(END_MILL_KEYS)}; docs/cutting.md)")
    other = sorted(set(doc) - {"cutter"})
    if other:
        raise InputError(f"{where}: unknown table(s) or key(s) {other}; a cutter file holds one [cutter] table")
    if not isinstance(doc["cutter"], Mapping):
        raise InputError(f"{where}: [cutter] must be a table, got {doc['cutter']!r}")
    return parse_cutter_table(where, doc["cutter"], "cutter", length_required=False)
