"""Provenance of an output: which compplan, which command line, when, from which files.

Every summary a command writes (``summary.json`` of ``plan``/``demo``,
``pose.json``, ``compliance_map.json``, identify's ``report.json``) and every
report carries a ``provenance`` block::

    {"compplan_version": "0.1.0",
     "command_line": "compplan demo --out out/demo",   # None for a library call
     "argv": ["compplan", "demo", "--out", "out/demo"],
     "date_utc": "2026-11-23T04:42:21Z",              # ISO 8601, UTC
     "inputs": [{"role": "problem", "name": "paper_4_4",
                 "path": ".../problems/files/paper_4_4.toml",
                 "sha256": "...", "size_bytes": 1234}, ...]}

The command line reaches the library from the CLI: :func:`planner.cli.main`
runs the sub-command inside :func:`command_line_scope`, and the writers read it
with :func:`current_command_line`; outside a command (a library call) it is
None.  Built-in robots (``ar5``) and shipped problems (``paper_4_4``) are
hashed from the package's own files.  Nothing here prints.
"""

from __future__ import annotations

import contextlib
import contextvars
import datetime as _dt
import hashlib
import shlex
from importlib import resources
from pathlib import Path
from typing import Any
from collections.abc import Iterator, Sequence

#: Distribution name (``pip show compplan``).
DISTRIBUTION = "compplan"
#: Bytes read at a time when hashing a file.
_HASH_CHUNK = 1 << 20

_COMMAND_LINE: contextvars.ContextVar[tuple[str, ...] | None] = contextvars.ContextVar(
    "compplan_command_line", default=None
)


def version() -> str:
    """The installed compplan version (``importlib.metadata``), else ``"unknown"``."""
    from importlib import metadata

    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "unknown"


@contextlib.contextmanager
def command_line_scope(argv: Sequence[str]) -> Iterator[None]:
    """Within this block, outputs record ``argv`` as the command line that made them.

    Parameters
    ----------
    argv : sequence of str
        The full command line, program name first (``["compplan", "demo", ...]``).
    """
    token = _COMMAND_LINE.set(tuple(str(a) for a in argv))
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


def current_command_line() -> list[str] | None:
    """The command line of the running ``compplan`` command, or None (a library call)."""
    argv = _COMMAND_LINE.get()
    return list(argv) if argv is not None else None


def utc_now() -> str:
    """The current time, UTC, ISO 8601 to the second (``2026-11-23T04:42:21Z``)."""
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0)
    return now.isoformat().replace("+00:00", "Z")


def invocation() -> dict[str, Any]:
    """The command line (or None) and the date of *now*: what a result records when it is made."""
    argv = current_command_line()
    return {"command_line": shlex.join(argv) if argv else None, "argv": argv, "date_utc": utc_now()}


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(_HASH_CHUNK), b""):
            h.update(chunk)
    return h.hexdigest()


def _packaged(package: str, relative: str) -> Path | None:
    """The file of a package resource (None when it is not a plain file)."""
    try:
        res = resources.files(package).joinpath(relative)
        p = Path(str(res))
        return p if p.is_file() else None
    except (ModuleNotFoundError, TypeError, ValueError):
        return None


def builtin_robot_file(name: str) -> Path | None:
    """The packaged file of a built-in robot (``ar5`` -> ``models/robots/ar5.toml``), or None."""
    from models import BUILTIN_ROBOTS

    return _packaged("models", f"robots/{name}.toml") if name in BUILTIN_ROBOTS else None


def shipped_problem_file(name: str) -> Path | None:
    """The packaged file of a shipped problem (``paper_4_4``), or None."""
    return _packaged("problems", f"files/{name}.toml") if name and "/" not in name else None


def input_file(
    role: str, path: str | Path | None, name: str | None = None, sha256: str | None = None
) -> dict[str, Any]:
    """One entry of ``provenance.inputs``: role, name, absolute path, SHA-256 and size.

    Parameters
    ----------
    role : str
        What the file is to the run (``"problem"``, ``"robot model"``, ``"measurements"``...).
    path : str, Path or None
        The file; None when the input is not a file (then ``sha256`` is None and
        ``note`` says so).
    name : str, optional
        The name it was given by (a built-in robot, a shipped problem).
    sha256 : str, optional
        A hash recorded earlier (e.g. when the file was loaded); checked against the
        file, and ``note`` says when the file has changed since.
    """
    entry: dict[str, Any] = {"role": role, "name": name, "path": None, "sha256": None, "size_bytes": None}
    if path is None:
        entry["sha256"] = sha256
        entry["note"] = "not read from a file" if sha256 is None else "file no longer known; hash as loaded"
        return entry
    p = Path(path)
    try:
        entry["path"] = str(p.resolve())
        entry["sha256"] = sha256_file(p)
        entry["size_bytes"] = p.stat().st_size
    except OSError as exc:
        entry["sha256"] = sha256
        entry["note"] = (
            f"cannot read the file now ({exc.strerror}); hash as loaded"
            if sha256
            else f"cannot read the file ({exc.strerror})"
        )
        return entry
    if sha256 and sha256 != entry["sha256"]:
        entry["note"] = f"the file changed after it was loaded (hash then: {sha256})"
    return entry


def robot_input(spec: str | None, role: str = "robot model", sha256: str | None = None) -> dict[str, Any]:
    """The input entry of a robot or arm-model spec: a built-in name or a file path."""
    if spec is None:
        return input_file(role, None)
    f = builtin_robot_file(spec)
    if f is not None:
        return input_file(role, f, name=spec)
    p = Path(spec)
    return input_file(role, p if p.is_file() else None, name=p.name if p.is_file() else spec, sha256=sha256)


def problem_input(source: str) -> dict[str, Any]:
    """The input entry of a problem's ``source`` (a file path or ``shipped problem 'NAME'``)."""
    prefix = "shipped problem '"
    if source.startswith(prefix) and source.endswith("'"):
        name = source[len(prefix) : -1]
        return input_file("problem", shipped_problem_file(name), name=name)
    p = Path(source)
    return input_file("problem", p if p.is_file() else None, name=p.name)


def provenance(inputs: Sequence[dict[str, Any]] = (), made: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ``provenance`` block of a summary.

    Parameters
    ----------
    inputs : sequence of dict
        Entries made by :func:`input_file` (or :func:`robot_input`, :func:`problem_input`).
    made : dict, optional
        ``{"command_line", "argv", "date_utc"}`` recorded when the result was made
        (:func:`invocation`); default: now.
    """
    inv = dict(made) if made is not None else invocation()
    return {
        "compplan_version": version(),
        "command_line": inv.get("command_line"),
        "argv": inv.get("argv"),
        "date_utc": inv.get("date_utc"),
        "inputs": [dict(e) for e in inputs],
    }


def problem_provenance(problem: Any, made: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ``provenance`` block of a result made from one problem: its file, its arm model's
    (a built-in robot, a robot file or a model file), its program's (a program path) and its cell's mesh
    files (role ``cell mesh``), with their SHA-256.

    Parameters
    ----------
    problem : problems.problem.Problem
    made : dict, optional
        As for :func:`provenance`.
    """
    md = problem.model.describe()
    inputs = [problem_input(problem.source), robot_input(md.get("file") or problem.robot_spec, sha256=md.get("sha256"))]
    program = getattr(problem, "program", None)
    if program is not None:  # the CAM program the path was read from
        p = Path(program.file)
        inputs.append(input_file("program", p if p.is_file() else None, name=p.name))
    cell = getattr(problem, "cell", None)
    for f in cell.mesh_files() if cell is not None else ():  # the cell's mesh objects
        p = Path(f)
        inputs.append(input_file("cell mesh", p if p.is_file() else None, name=p.name))
    return provenance(inputs, made)


__all__ = [
    "builtin_robot_file",
    "command_line_scope",
    "input_file",
    "invocation",
    "problem_input",
    "problem_provenance",
    "provenance",
    "robot_input",
    "version",
]
