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


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
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
    return (json.dumps(_jsonable(obj), indent=2, allow_nan=False) + "\n").encode()


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

    def publish(self) -> list[Path]:
        """Write every file (each atomically); returns the paths written."""
        self.folder.mkdir(parents=True, exist_ok=True)
        written = []
        for name, data in self.files.items():
            p = self.folder / name
            atomic_write_bytes(p, data)
            written.append(p)
        return written
