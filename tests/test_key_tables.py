"""Tables declared key by key (``models/tables/keys.py``): the allowed keys and the reader follow from one
declaration; the problem file's ``[payload]``, ``[cost]`` and ``[solver]`` are declared so."""

from __future__ import annotations

import numpy as np
import pytest

from models.errors import InputError
from models.tables import TableReader
from models.tables.keys import ABSENT, Key, KeyTable
from problems.problem_file import ProblemFileError
from problems.problem_file.sections import COST_KEYS, PAYLOAD_KEYS, SOLVER_KEYS, parse_payload, parse_solver

READER = TableReader(InputError)
TABLE = KeyTable(
    "t",
    (
        Key("n", lambda w, k, v: READER.integer(w, k, v, 1), required=lambda w, k: READER.fail(w, k, "is required")),
        Key("x", READER.number, default=2.5, unit="m"),
        Key("flag", READER.flag),
    ),
)


def test_names_defaults_and_absent_keys():
    assert TABLE.names == ("n", "x", "flag")
    assert TABLE.read("f.toml", {"n": 3}) == {"n": 3, "x": 2.5, "flag": None}
    assert TABLE.read("f.toml", {"n": 3, "x": 1, "flag": True}) == {"n": 3, "x": 1.0, "flag": True}
    assert repr(ABSENT) == "ABSENT"


def test_errors_name_the_key_path_in_declaration_order():
    with pytest.raises(InputError, match=r"^f.toml: key 't.n' is required$"):
        TABLE.read("f.toml", {"x": "far"})
    with pytest.raises(InputError, match=r"key 't.x' must be a number, got 'far'"):
        TABLE.read("f.toml", {"n": 1, "x": "far", "flag": 3})
    with pytest.raises(InputError, match=r"key 't.flag'"):
        TABLE.read("f.toml", {"n": 1, "flag": 3})


def test_problem_tables_are_declared_once():
    assert PAYLOAD_KEYS.names == ("mass_kg", "com_m", "gravity_m_s2")
    assert COST_KEYS.names == ("smoothness",)
    assert SOLVER_KEYS.names == ("name", "max_iter", "tol", "codegen")
    s = parse_solver("p.toml", {"solver": {"max_iter": 7}})
    assert (s.name, s.max_iter, s.codegen) == ("ipopt", 7, True)
    with pytest.raises(ProblemFileError, match=r"\[solver\]: unknown key\(s\) \['maxiter'\]; allowed: \['name', "):
        parse_solver("p.toml", {"solver": {"maxiter": 7}})
    p = parse_payload("p.toml", {"payload": {"mass_kg": 2.0}})
    assert p.mass_kg == 2.0 and np.array_equal(p.com_m, np.zeros(3)) and p.gravity is None
    assert parse_payload("p.toml", {}).mass_kg == 0.0
    with pytest.raises(ProblemFileError, match=r"key 'payload.mass_kg' is required in a \[payload\] table \(kg\)"):
        parse_payload("p.toml", {"payload": {"com_m": [0, 0, 0.1]}})
