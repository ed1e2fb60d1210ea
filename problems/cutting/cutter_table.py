"""A cutter file: a TOML file with one ``[cutter]`` table (``compplan cutting fit --cutter``).

Its keys and their checks are those of a problem file's ``[robot.tool.cutter]``
(:func:`problems.problem_file.cutter_section.parse_cutter_table`, the one home of the end mill's
schema); here the stick-out ``length`` is optional (it defaults to the flute length).
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
