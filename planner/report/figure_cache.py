"""Rendered figures kept by content: a figure drawn again from the same data by the same code
is read back instead of rendered (a report's rendering is most of its cost).

The key of a figure hashes its job (the drawing function, by module and name, and its
arguments, pickled), whether the PDF is wanted, the source of the drawing code (every module
of :mod:`planner.report`, and :mod:`planner.numbers`), the versions of matplotlib and NumPy
and matplotlib's rc settings.  A figure whose key is found is the same bytes its
rendering would give (the rendering is reproducible: fixed metadata, no dates).

Entries live under ``$COMPPLAN_FIGURE_CACHE``, else ``$COMPPLAN_CACHE/figures`` (default
``~/.cache/compplan/figures``), one file
each: the PNG and PDF bytes behind a header with their lengths and the SHA-256 of both, checked
on reading (a damaged entry is rendered again and replaced).  The folder is kept under
:data:`FIGURE_CACHE_MAX_BYTES`, the least recently used entries removed first.  A cache that
cannot be read or written only costs the rendering: nothing fails because of it.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import struct
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from planner.report.rendering import FigureItem, Job

#: Most bytes kept in the figure cache (a report's figures take about 1 MB).
FIGURE_CACHE_MAX_BYTES = 64 * 2**20
#: The cache's sub-folder of ``$COMPPLAN_CACHE``.
FIGURE_CACHE_FOLDER = "figures"
#: The environment variable naming another folder for the figure cache (the tests use one of
#: their own, so they neither read nor fill the user's).
FIGURE_CACHE_ENV = "COMPPLAN_FIGURE_CACHE"
#: Entry format: magic, PNG length, PDF length (-1: none), SHA-256 of the PNG and PDF bytes.
_HEADER = struct.Struct("<8sqq32s")
_MAGIC = b"CPFIG001"
_CODE_HASH: list[bytes] = []


def _code_hash() -> bytes:
    """SHA-256 of the drawing code's source, the versions and the rc settings (once per process)."""
    if not _CODE_HASH:
        import matplotlib
        import numpy as np

        here = Path(__file__).resolve().parent
        h = hashlib.sha256(f"{matplotlib.__version__} {np.__version__}".encode())
        h.update(repr(sorted((k, repr(v)) for k, v in matplotlib.rcParams.items())).encode())
        for path in sorted(here.glob("*.py")) + [here.parent / "numbers.py"]:
            h.update(path.name.encode() + b"\0" + path.read_bytes())
        _CODE_HASH.append(h.digest())
    return _CODE_HASH[0]


def figure_key(jb: Job, pdf: bool) -> str | None:
    """The cache key of a figure job (None: its arguments cannot be pickled, not cached)."""
    try:
        blob = pickle.dumps(jb, protocol=5)
    except (pickle.PicklingError, TypeError, AttributeError):  # not picklable: not cached
        return None
    return hashlib.sha256(_code_hash() + (b"pdf" if pdf else b"png") + blob).hexdigest()[:32]


def _folder() -> Path:
    """``$COMPPLAN_FIGURE_CACHE`` when set, else the ``figures`` folder of ``$COMPPLAN_CACHE``."""
    own = os.environ.get(FIGURE_CACHE_ENV)
    if own:
        return Path(own)
    from models.codegen import cache_root

    return cache_root() / FIGURE_CACHE_FOLDER


def _read(path: Path) -> tuple[bytes, bytes | None] | None:
    """The PNG and PDF bytes of an entry, or None if it is missing, unreadable or damaged."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if len(data) < _HEADER.size:
        return None
    magic, n_png, n_pdf, digest = _HEADER.unpack_from(data)
    body = data[_HEADER.size :]
    if magic != _MAGIC or n_png < 0 or len(body) != n_png + max(n_pdf, 0) or hashlib.sha256(body).digest() != digest:
        return None
    return body[:n_png], (body[n_png:] if n_pdf >= 0 else None)


def take_cached(items: list[FigureItem], pdf: bool = True) -> dict[str, str]:
    """Fill the items whose figure is cached (their ``png``/``pdf`` set, ``job`` cleared); returns
    the keys of the others by figure name, for :func:`keep_rendered` after their rendering."""
    todo: dict[str, str] = {}
    folder = _folder()
    for it in items:
        if it.job is None:
            continue
        key = figure_key(it.job, pdf)
        if key is None:
            continue
        got = _read(folder / key)
        if got is None:
            todo[it.name] = key
            continue
        it.png, it.pdf = got
        it.job = None
        try:
            os.utime(folder / key)  # recently used: kept longest
        except OSError:
            pass
    return todo


def keep_rendered(items: list[FigureItem], keys: dict[str, str]) -> None:
    """Store the rendered figures of ``keys`` (from :func:`take_cached`); then trim the cache."""
    from planner.output import OutputError, atomic_write_bytes

    folder = _folder()
    stored = False
    for it in items:
        key = keys.get(it.name)
        if key is None or it.png is None:
            continue
        body = it.png + (it.pdf or b"")
        head = _HEADER.pack(_MAGIC, len(it.png), -1 if it.pdf is None else len(it.pdf), hashlib.sha256(body).digest())
        try:
            atomic_write_bytes(folder / key, head + body)
            stored = True
        except OutputError:
            return  # no cache here: the figures were rendered anyway
    if stored:
        _trim(folder)


def _trim(folder: Path) -> None:
    """Remove the least recently used entries until the folder holds at most FIGURE_CACHE_MAX_BYTES."""
    try:
        entries = [
            (e.stat().st_mtime, e.stat().st_size, e.path)
            for e in os.scandir(folder)
            if e.is_file() and not e.name.startswith(".")
        ]  # (not another writer's temporary file)
    except OSError:
        return
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= FIGURE_CACHE_MAX_BYTES:
            break
        try:
            os.unlink(path)
        except OSError:
            continue
        total -= size
