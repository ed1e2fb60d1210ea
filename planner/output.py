"""Writing outputs whole or not at all.

Every file is first written to a temporary file in the destination folder and
then moved into place with :func:`os.replace` (atomic on one file system), so a
failure never leaves a truncated file behind.  :class:`OutputSet` stages a group
of files and publishes them only after all were produced.
"""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from models.errors import InputError


#: Columns of ``trajectory*.csv`` (SI): time, positions, velocities, accelerations, jerks.
TRAJECTORY_COLUMNS = (["t"] + [f"q{i}" for i in range(1, 7)] + [f"qd{i}" for i in range(1, 7)]
                      + [f"qdd{i}" for i in range(1, 7)] + [f"qddd{i}" for i in range(1, 7)])


def jsonable(obj: Any) -> Any:
    """``obj`` as the JSON values :func:`json_bytes` writes (and ``json.loads`` reads back):
    plain dicts with str keys, lists, floats (non-finite ones None), ints, bools, str."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if np.isfinite(v) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    return obj


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def json_bytes(obj: Any) -> bytes:
    """JSON text (non-finite floats become null) as bytes."""
    return (json.dumps(jsonable(obj), indent=2, allow_nan=False) + "\n").encode()


def csv_bytes(header: Sequence[str], rows: Iterable[Sequence[float]] | np.ndarray) -> bytes:
    """CSV text with a header row; floats written with 17 significant digits."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in np.asarray(rows, dtype=float):
        w.writerow([repr(float(v)) for v in row])
    return buf.getvalue().encode()


class OutputSet:
    """Collect output files in memory and publish them together.

    >>> out = OutputSet("results")
    >>> out.add_json("summary.json", {...}); out.add_csv("path.csv", header, rows)
    >>> out.publish()      # nothing is written before this call
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.files: dict[str, bytes] = {}

    def add_bytes(self, name: str, data: bytes) -> None:
        self.files[name] = data

    def add_json(self, name: str, obj: Any) -> None:
        self.files[name] = json_bytes(obj)

    def add_csv(self, name: str, header: Sequence[str], rows: Any) -> None:
        self.files[name] = csv_bytes(header, rows)

    def publish(self, stale: Iterable[str] = ()) -> list[Path]:
        """Write every file (each atomically); returns the paths written.

        Parameters
        ----------
        stale : iterable of str
            Output names this kind of run may produce: those present in the folder
            but not produced this time are removed, so a reused folder never mixes
            an earlier run's files with this one's.

        Raises
        ------
        InputError
            The folder cannot be created or written (names the folder and the cause).
        """
        check_output_folder(self.folder, create=True)
        written = []
        try:
            for name, data in self.files.items():
                p = self.folder / name
                atomic_write_bytes(p, data)
                written.append(p)
            for name in stale:
                p = self.folder / name
                if name not in self.files and p.is_file():
                    p.unlink()
        except OSError as exc:
            raise InputError(f"output folder {self.folder}: cannot write ({exc})") from None
        return written


def check_output_folder(folder: str | Path, create: bool = False) -> Path:
    """Check that ``folder`` is, or can be created as, a writable directory.

    Call it before long computations so a bad ``--out`` fails at once; nothing is
    created unless ``create`` (so a run that fails later leaves no trace).

    Raises
    ------
    InputError
        Naming the folder and what is wrong with it.
    """
    p = Path(folder)
    if p.exists() and not p.is_dir():
        raise InputError(f"--out {p}: exists and is not a folder; give a folder path")
    parent = p
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(f"--out {p}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"--out {p}: {parent} is not writable")
    if create:
        try:
            p.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"--out {p}: cannot create the folder ({exc.strerror or exc})") from None
    return p
