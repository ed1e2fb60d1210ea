"""A foreign or tampered ``summary.json`` (and the CSV files it points to): ``compplan report``,
``export`` and ``track`` refuse it with one line naming the key, exit 2, and write nothing.

The cases are generated from the declaration (:data:`planner.summary_schema.SUMMARY`): every
declared key of a real run (the demo's, ``paper_folder``) is given every value its kind refuses
(another type, NaN, infinity, a negative duration, ``"lots"`` for a number, a list for a number,
...), every key a command needs is removed, and a declared block the run lacks (program, dynamic
compensation, payload) is added from the declaration's example first, so a key declared later is
tested without an edit here.  The refusal comes before any drawing (each command costs
milliseconds).  What the report and the export read is recorded and must be declared, so a key
read without a declaration fails here.
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import shutil
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from planner.cli import main
from planner.export import EXPORT_FORMATS
from planner.summary_schema import COMMANDS, SUMMARY, SummaryError, read_summary
from models.tables.kinds import (
    Either,
    External,
    ListOf,
    MapOf,
    Row,
    Spec,
    Table,
    Vector,
    dotted,
    template_text,
    templates,
)

TEMPLATES = list(templates(SUMMARY))
#: The commands each tampered value is run through, in turn (report always; the export in each
#: format and track by rotation: the check does not depend on the format).
OTHERS = [("export", f) for f in EXPORT_FORMATS] + [("track", None)]


# ------------------------------------------------------------------------------------ helpers
@pytest.fixture(scope="module", autouse=True)
def one_parser() -> Iterator[None]:
    """``planner.cli.main`` with its argument parser built once for the module (building it is
    three quarters of a refused command's time; the thousands of commands here run the same
    parser, each in ``main`` with its error handling)."""
    import functools

    import planner.cli as cli

    with pytest.MonkeyPatch.context() as m:
        m.setattr(cli, "build_parser", functools.cache(cli.build_parser))
        yield


@pytest.fixture(scope="module")
def run_copy(paper_folder, tmp_path_factory) -> Path:
    """A private copy of the demo run (its summary.json is rewritten by each case)."""
    folder = tmp_path_factory.mktemp("tampered") / "run"
    shutil.copytree(paper_folder, folder)
    return folder


@pytest.fixture(scope="module")
def original(run_copy) -> dict[str, Any]:
    return json.loads((run_copy / "summary.json").read_text(encoding="utf-8"))


@pytest.fixture
def run(run_copy, original) -> Iterator[Path]:
    """The private run; its summary.json as the run wrote it again afterwards."""
    yield run_copy
    _write(run_copy, original)
    for name in ("report.html", "report.md", "figures", "compliance_map.csv"):
        p = run_copy / name
        shutil.rmtree(p) if p.is_dir() else p.unlink(missing_ok=True)


def _is_shape(step: Any) -> bool:
    return isinstance(step, str) and step.startswith("#")


def _present(holder: Any, key: Any) -> bool:
    return key < len(holder) if isinstance(holder, list) else key in holder


def _fits(value: Any, spec: Spec) -> bool:
    """A value the next step can descend into (or choose a shape of)."""
    if isinstance(spec, (Table, MapOf)):
        return isinstance(value, dict)
    if isinstance(spec, ListOf):
        return isinstance(value, list)
    return value is not None


def _locate(doc: dict[str, Any], steps: tuple) -> tuple[Any, Any, Spec, str]:
    """``(container, key, spec, dotted path)`` of a template's key in ``doc``, adding from the
    declaration's examples what the run lacks on the way (an absent block, an entry of an empty
    table or list, the other shape of an :class:`Either`); a table's first entry stands for
    ``<name>``, a list's first item for ``[0]``."""
    spec: Spec = SUMMARY
    cur: Any = doc
    holder: Any = None
    key: Any = None
    names: list[Any] = []
    for n, step in enumerate(steps):
        if _is_shape(step):
            assert isinstance(spec, Either)
            shape = (spec.first, spec.second)[int(step[1:])]
            if spec.pick(holder[key]) != int(step[1:]):
                holder[key] = shape.example()
            spec, cur = shape, holder[key]
            continue
        if isinstance(spec, Table):
            sub, k = spec.fields[step], step
        elif isinstance(spec, MapOf):
            sub = spec.item
            if not cur:
                cur["x"] = sub.example()
            k = next(iter(cur))
        else:
            assert isinstance(spec, ListOf)
            sub, k = spec.item, 0
            if not cur:
                cur.append(sub.example())
        holder, key, spec = cur, k, sub
        names.append(k)
        if n < len(steps) - 1 and not (_present(holder, key) and _fits(holder[key], spec)):
            holder[key] = spec.example()
        cur = holder[key] if _present(holder, key) else None
    return holder, key, spec, dotted(names)


def _write(folder: Path, doc: Any) -> None:
    (folder / "summary.json").write_text(json.dumps(doc), encoding="utf-8")  # NaN, Infinity as such


def _cli(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, err.getvalue()


def _argv(folder: Path, command: str, fmt: str | None, out: Path) -> list[str]:
    if command == "report":
        return ["report", str(folder), "--no-map", "--jobs", "1"]
    if command == "export":
        return ["export", str(folder), "--format", str(fmt), "--out", str(out / f"prog_{fmt}")]
    return ["track", str(folder), "--out", str(out / "track.csv")]


def _refused(folder: Path, command: str, fmt: str | None, out: Path, key: str, why: str) -> None:
    code, err = _cli(_argv(folder, command, fmt, out))
    label = f"{command}{' ' + fmt if fmt else ''}, {why}"
    assert code == 2, f"{label}: exit {code}\n{err}"
    assert err.startswith("compplan: error:") and err.count("\n") == 1, f"{label}: {err}"
    assert key in err and "Traceback" not in err, f"{label}: the message does not name {key}: {err}"
    assert not (folder / "report.html").exists() and not (folder / "figures").exists(), label
    assert not any(out.iterdir()), f"{label}: wrote {sorted(p.name for p in out.iterdir())}"


# -------------------------------------------------------------------------------- the cases
IDS = [template_text(s) for s, _ in TEMPLATES]


@pytest.mark.parametrize("index", range(len(TEMPLATES)), ids=IDS)
def test_every_declared_key_refuses_every_bad_value(index, run, original, tmp_path):
    """Each value the key's kind refuses: report, and in turn the export in every format and track,
    exit 2 naming the key; nothing is written."""
    steps, _ = TEMPLATES[index]
    doc = copy.deepcopy(original)
    holder, key, spec, path = _locate(doc, steps)
    _write(run, doc)
    read_summary(run, "report")  # the run with the blocks added is accepted
    bad_values = spec.bad_values()
    assert bad_values, path
    for n, bad in enumerate(bad_values):
        holder[key] = bad
        _write(run, doc)
        why = f"{path} = {bad!r}"
        _refused(run, "report", None, tmp_path, path, why)
        command, fmt = OTHERS[(index + n) % len(OTHERS)]
        _refused(run, command, fmt, tmp_path, path, why)


NEEDED = [i for i, (_, spec) in enumerate(TEMPLATES) if spec.need]


@pytest.mark.parametrize("index", NEEDED, ids=[IDS[i] for i in NEEDED])
def test_a_needed_key_missing_or_null_is_refused_by_the_commands_that_need_it(index, run, original, tmp_path):
    """A key a command needs, removed (and null where null is otherwise allowed): that command
    refuses naming it; the others read the summary."""
    steps, spec = TEMPLATES[index]
    for variant in ("missing", "null") if spec.nullable else ("missing",):
        doc = copy.deepcopy(original)
        holder, key, _, path = _locate(doc, steps)
        if variant == "missing":
            del holder[key]
        else:
            holder[key] = None
        _write(run, doc)
        for command in COMMANDS:
            if command in spec.need:
                fmt = EXPORT_FORMATS[index % len(EXPORT_FORMATS)] if command == "export" else None
                _refused(run, command, fmt, tmp_path, path, f"{path} {variant}")
            else:
                read_summary(run, command)


@pytest.mark.parametrize("index", range(len(TEMPLATES)), ids=IDS)
def test_an_optional_key_may_be_missing(index, run, original):
    """Every declared key a command does not need may be absent (a summary written before it)."""
    steps, _ = TEMPLATES[index]
    doc = copy.deepcopy(original)
    holder, key, spec, _ = _locate(doc, steps)
    holder.pop(key) if isinstance(holder, list) else holder.pop(key, None)
    _write(run, doc)
    for command in COMMANDS:
        if command not in spec.need:
            read_summary(run, command)


@pytest.mark.parametrize("fmt", EXPORT_FORMATS)
def test_every_format_refuses_a_tampered_summary(fmt, run, original, tmp_path):
    """The export in each format, for a tampered value of each kind (duration, vector, status
    word, file name, robot file)."""
    cases = [
        ("timing.toppra.dt", -0.008),
        ("limits.velocity", "lots"),
        ("limits.q_max", [1.0, 1.0, 1.0, 1.0, math.nan, 1.0]),
        ("plan_status", "fine"),
        ("timing.jerk_optimal.file", "../../etc/passwd"),
        ("robot_file", ["ar5"]),
    ]
    for key, bad in cases:
        doc = copy.deepcopy(original)
        *parents, last = key.split(".")
        target = doc
        for p in parents:
            target = target[p]
        target[last] = bad
        _write(run, doc)
        _refused(run, "export", fmt, tmp_path, key, f"{key} = {bad!r}")


@pytest.mark.parametrize(
    "text,needle",
    [
        ("{", "not valid JSON"),
        ("[1, 2]", "top level is [1, 2]; expected an object"),
        ('"lots"', 'top level is "lots"'),
        ('{"command": "place"}', "placement study's summary"),
        ('{"command": "identify"}', "command = \"identify\"; expected one of 'plan', 'demo'"),
    ],
)
def test_a_foreign_file_is_refused(text, needle, run, original, tmp_path):
    (run / "summary.json").write_text(text, encoding="utf-8")
    for command, fmt in [("report", None), *OTHERS]:
        _refused(run, command, fmt, tmp_path, needle, text)


def test_joint_limits_out_of_order_are_refused(run, original, tmp_path):
    doc = copy.deepcopy(original)
    doc["limits"]["q_min"][2] = doc["limits"]["q_max"][2] + 0.1
    _write(run, doc)
    for command, fmt in [("report", None), ("export", "krl"), ("track", None)]:
        _refused(run, command, fmt, tmp_path, "limits.q_min[2]", "q_min above q_max")


# -------------------------------------------------------------------- the files it points to
def _rewrite_cell(path: Path, line: int, column: str, value: str) -> None:
    rows = [r.split(",") for r in path.read_text(encoding="utf-8").splitlines()]
    rows[line - 1][rows[0].index(column)] = value
    path.write_text("\n".join(",".join(r) for r in rows) + "\n", encoding="utf-8")


@pytest.mark.parametrize(
    "file,line,column,value,needle",
    [
        ("trajectory.csv", 5, "qd3", "nan", "line 5, column qd3: nan; expected a finite number"),
        ("trajectory.csv", 5, "q1", "inf", "line 5, column q1: inf; expected a finite number"),
        ("trajectory.csv", 7, "q2", "lots", "line 7, column q2: 'lots' is not a number"),
        ("trajectory.csv", 2, "t", "-0.5", "line 2, column t: -0.5; expected a time >= 0 s"),
        ("trajectory.csv", 9, "t", "0.001", "line 9, column t: 0.001; expected a time after the previous"),
        ("trajectory_toppra.csv", 4, "t", "nan", "line 4, column t: nan; expected a finite number"),
        ("waypoints.csv", 3, "k", "1.5", "line 3, column k: 1.5; expected a whole number >= 0"),
        ("waypoints.csv", 4, "qc2", "nan", "line 4, column qc2: nan; expected a finite number"),
        ("waypoints.csv", 6, "y", "1e309", "line 6, column y: inf; expected a finite number"),
        ("branches.csv", 5, "s-w-e-_optimised_m", "-inf", "line 5, column s-w-e-_optimised_m: -inf; expected a"),
        ("branches.csv", 6, "s-w-e-_analytic_m", "1e300", "line 6, column s-w-e-_analytic_m: 1e+300; expected a"),
        ("branches.csv", 3, "k", "-1", "line 3, column k: -1.0; expected a whole number >= 0"),
    ],
)
def test_a_bad_cell_of_a_run_file_is_refused(file, line, column, value, needle, run, tmp_path):
    folder = tmp_path / "run"
    shutil.copytree(run, folder)
    _rewrite_cell(folder / file, line, column, value)
    out = tmp_path / "out"
    out.mkdir()
    _refused(folder, "report", None, out, f"{file}: {needle}", f"{file} line {line} {column} = {value}")


def test_a_duration_that_is_not_the_file_s_is_refused(run, original, tmp_path):
    doc = copy.deepcopy(original)
    doc["duration_s"]["toppra"] = 2 * doc["duration_s"]["toppra"]
    _write(run, doc)
    _refused(run, "report", None, tmp_path, "duration_s.toppra", "duration twice the file's")


def test_a_trajectory_file_named_but_absent_is_stated(run, original, tmp_path):
    from planner.record import read_record as load_run

    folder = tmp_path / "run"
    shutil.copytree(run, folder)
    (folder / original["timing"]["toppra"]["file"]).unlink()
    run = load_run(folder)
    assert "timing.toppra.file" in run.absent["trajectory toppra"] and "toppra" not in run.trajectories


# ------------------------------------------------------------------- nothing read undeclared
class _Recorded(dict):
    """A summary that records the key paths read from it (not those iterated over)."""

    def __init__(self, data: Mapping[str, Any], path: tuple, log: set) -> None:
        super().__init__({k: _recorded(v, (*path, k), log) for k, v in data.items()})
        self._path, self._log = path, log

    def _read(self, key: Any) -> None:
        self._log.add((*self._path, key))

    def __getitem__(self, key: Any) -> Any:
        self._read(key)
        return super().__getitem__(key)

    def get(self, key: Any, default: Any = None) -> Any:
        self._read(key)
        return super().get(key, default)

    def __contains__(self, key: Any) -> bool:
        self._read(key)
        return super().__contains__(key)


def _recorded(v: Any, path: tuple, log: set) -> Any:
    if isinstance(v, dict):
        return _Recorded(v, path, log)
    if isinstance(v, list):
        return [_recorded(x, (*path, i), log) for i, x in enumerate(v)]
    return v


def _declared(path: tuple) -> bool:
    """Whether ``path`` (keys and list indices) is a declared key of :data:`SUMMARY` (or inside one
    checked by its own reader)."""

    def walk(spec: Spec, rest: tuple) -> bool:
        if not rest:
            return True
        if isinstance(spec, Either):
            return walk(spec.first, rest) or walk(spec.second, rest)
        if isinstance(spec, Table):
            return rest[0] in spec.fields and walk(spec.fields[rest[0]], rest[1:])
        if isinstance(spec, MapOf):
            return walk(spec.item, rest[1:])
        if isinstance(spec, ListOf):
            return isinstance(rest[0], int) and walk(spec.item, rest[1:])
        return isinstance(spec, External) or (isinstance(spec, (Vector, Row)) and len(rest) == 1)

    return walk(SUMMARY, tuple(path))


def _with_every_block(doc: dict[str, Any]) -> dict[str, Any]:
    """``doc`` with the declared tables it lacks (under tables it has) added from the declaration's
    examples, so that what reads them is recorded."""
    doc = copy.deepcopy(doc)
    for steps, spec in TEMPLATES:
        if not isinstance(spec, Table) or not all(isinstance(s, str) and s[0] not in "#<" for s in steps):
            continue
        parent: Any = doc
        for s in steps[:-1]:
            parent = parent.get(s) if isinstance(parent, dict) else None
        if isinstance(parent, dict) and parent.get(steps[-1]) is None:
            parent[steps[-1]] = spec.example()
    return doc


def test_every_key_the_report_and_the_export_read_is_declared(run, original, tmp_path, monkeypatch):
    """Build the report's tables, figures (not drawn) and pages, and the export's data, from a summary
    that records what is read (with every declared block present): every key read is declared."""
    import planner.export.sources as export_module
    import planner.record.read as run_module
    from planner.report.figures import build_figures
    from planner.report.rendering import render_html, render_markdown
    from planner.report.tables import summary_tables

    folder = tmp_path / "run"
    shutil.copytree(run, folder)
    _write(folder, _with_every_block(original))
    log: set = set()
    real_read = run_module.read_summary
    monkeypatch.setattr(run_module, "read_summary", lambda f, c: _recorded(real_read(f, c), (), log))
    run = run_module.read_record(folder)
    tables = summary_tables(run.summary, run.absent)
    items = build_figures(run, map_options=False)
    render_markdown(run, tables, items), render_html(run, tables, items)
    report_reads = len(log)

    class _Json:  # the export's json.loads, recording
        JSONDecodeError = json.JSONDecodeError

        @staticmethod
        def loads(text: str, **kw: Any) -> Any:
            return _recorded(json.loads(text, **kw), (), log)

    monkeypatch.setattr(export_module, "json", _Json)
    export_module.data_from_run(folder)
    assert report_reads > 50 and len(log) > report_reads, "nothing recorded: the readers changed"
    undeclared = sorted(template_text(p) for p in log if not _declared(p))
    assert not undeclared, f"read from summary.json but not declared in planner/summary_schema.py: {undeclared}"


def test_the_declaration_accepts_the_run_and_its_examples(original, run):
    """The real run reads for every command, and so does the run with every block's example."""
    for doc in (original, _with_every_block(original)):
        _write(run, doc)
        for command in COMMANDS:
            read_summary(run, command)
    with pytest.raises(SummaryError, match="no such folder"):
        read_summary(run / "nope", "export")
    assert np.isfinite(original["duration_s"]["toppra"])
