"""Writing outputs whole or not at all, with the user's permissions, one writer at a time.

* **Whole or not at all.**  A single file (:func:`atomic_write_bytes`) is written to a
  hidden temporary sibling and moved into place with :func:`os.replace`.  A set of files
  (:class:`OutputSet`) is built in a hidden temporary sibling *folder*
  (``.<name>.compplan-new-*``) and moved into place in one step (``renameat2`` with
  ``RENAME_EXCHANGE`` on Linux, else two renames); the previous folder is removed after.
  A failure at any point (disk full ``ENOSPC``, file-size limit ``EFBIG``, an interrupt)
  removes the temporary folder and leaves the previous set exactly as it was: never a mix
  of old and new files, never an earlier run's file beside a new one.  A set either owns
  its whole folder (a run: plan, demo, place, map, pose, the identification report) or, with
  ``owns=``, some entries of an existing folder (the report of a run folder: the rest is
  carried over by hard links).  A file that belongs with a set but lives elsewhere (the model
  file of ``identify``) is written first and moved in after the set (:func:`pending_file`).
* **Killed runs.**  A run killed outright (``SIGKILL``, a power cut) cannot clean up: it
  leaves its hidden siblings (``new-*``, ``old-*``, ``tmp-*``) and never the output half
  written.  The next writer of the output removes them once it holds the output's lock; one
  it cannot remove is named in a note (:func:`take_output_notes`, printed by the command
  line as a warning) with the command that removes it.
* **What a folder holds.**  An output folder of compplan is recognised by its marker file
  (:data:`FOLDER_KIND_MARKERS`; :func:`output_folder_kind`).  A folder holding files compplan
  did not write is never replaced; one holding another command's output (a placement study
  where a plan is written) is replaced only when asked (``holds=``, ``force=`` of
  :func:`check_output_path`, the ``--force`` of the commands); one whose previous contents
  could not be removed (a read-only sub-folder) is refused before anything is written.
* **Permissions.**  Files are created with mode ``0o666`` and folders ``0o777`` less the
  process umask, as by any program (no temporary file's ``0600`` is left on an output).
* **One writer.**  An output is locked while it is written (``fcntl.flock`` on the hidden
  sibling ``.<name>.compplan-lock``, removed again by its holder); a second writer is
  refused at once with one line naming the holder's process.  The commands take the lock
  before their long work (:func:`planner.commands.common.check_output`) and keep it to the
  end; :meth:`OutputSet.publish` takes it too (re-entrant within one thread).

The siblings, their clean-up and the lock live in :mod:`planner.output_siblings`, the checks of
an output path and the kinds of output folder in :mod:`planner.output_checks`; this module
re-exports what callers use.

Errors are :class:`OutputError` (a :class:`~models.errors.InputError`, so the command
line prints one line and exits 2, and an :class:`OSError`).
"""

from __future__ import annotations

import contextlib
import csv
import ctypes
import errno
import io
import json
import os
import shutil
import sys
from pathlib import Path
from typing import Any
from collections.abc import Callable, Iterable, Iterator, Sequence

import numpy as np

from models import interrupts
from models.errors import InputError
from planner.output_checks import (
    FOLDER_KIND_MARKERS,
    OUTPUT_FOLDER_MARKERS,
    SUMMARY_COMMAND_KINDS,
    FolderKind,
    OutputKind,
    check_output_folder,
    check_output_path,
    output_folder_kind,
)
from planner.output_siblings import (
    FILE_MODE,
    FOLDER_MODE,
    RETIRED_KIND,
    SIBLING_TAG,
    STAGING_KIND,
    TEMP_KIND,
    OutputError,
    acquire_output_lock,
    clean_up,
    holds_output_lock,
    lock_path,
    new_sibling_name,
    os_error_cause,
    output_lock,
    real_path,
    release_output_lock,
    sibling_prefix,
    take_output_notes,
)

#: Columns of ``trajectory*.csv`` (SI): time, positions, velocities, accelerations, jerks.
TRAJECTORY_COLUMNS = (
    ["t"]
    + [f"q{i}" for i in range(1, 7)]
    + [f"qd{i}" for i in range(1, 7)]
    + [f"qdd{i}" for i in range(1, 7)]
    + [f"qddd{i}" for i in range(1, 7)]
)


#: Flush every output file to the disk before it is moved into place (a crash right after
#: the move then never leaves an empty file).
FSYNC_FILES = True

#: Linux ``renameat2`` arguments: ``AT_FDCWD`` and the flag that swaps two paths atomically.
_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


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


def json_bytes(obj: Any) -> bytes:
    """JSON text (non-finite floats become null) as bytes."""
    return (json.dumps(jsonable(obj), indent=2, allow_nan=False) + "\n").encode()


#: Rows of a CSV file formatted at a time when it is written in pieces (:func:`csv_chunks`).
CSV_CHUNK_ROWS = 50_000


def csv_chunks(
    header: Sequence[str], rows: Iterable[Sequence[float]] | np.ndarray, int_rows: np.ndarray | None = None
) -> Iterator[bytes]:
    """CSV text with a header row, in pieces of :data:`CSV_CHUNK_ROWS` rows (a 10^6-row trajectory
    is never one string in memory); floats written as the shortest text that reads back exactly
    (Python's ``repr``); ``int_rows`` (N, k), when given, are the last ``k`` columns, as integers."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(header)
    yield buf.getvalue().encode()
    A = np.asarray(rows, dtype=float)
    if A.ndim == 1:
        A = A.reshape(len(A), -1) if A.size else A.reshape(0, 0)
    I = None if int_rows is None else np.asarray(int_rows, dtype=np.int64).reshape(len(A), -1)
    for k in range(0, len(A), CSV_CHUNK_ROWS):
        body = [",".join(map(repr, r)) for r in A[k : k + CSV_CHUNK_ROWS].tolist()]
        if I is not None:
            body = [
                f"{a},{','.join(map(str, b))}" if a else ",".join(map(str, b))
                for a, b in zip(body, I[k : k + CSV_CHUNK_ROWS].tolist())
            ]
        yield "".join(f"{r}\n" for r in body).encode()


def csv_bytes(
    header: Sequence[str], rows: Iterable[Sequence[float]] | np.ndarray, int_rows: np.ndarray | None = None
) -> bytes:
    """CSV text with a header row (:func:`csv_chunks` joined)."""
    return b"".join(csv_chunks(header, rows, int_rows))


# ------------------------------------------------------------------------------ writing
def _write_new_file(path: Path, data: bytes | Iterable[bytes]) -> None:
    """Create ``path`` (which must not exist; mode ``FILE_MODE`` less the umask) holding ``data``
    (bytes, or the parts of a file written piece by piece).

    Every file of an output goes through here (tests replace it to simulate a full disk).
    """
    with open(path, "xb") as fh:
        if isinstance(data, (bytes, bytearray)):
            fh.write(data)
        else:
            for part in data:
                fh.write(part)
        if FSYNC_FILES:
            fh.flush()
            os.fsync(fh.fileno())


@contextlib.contextmanager
def pending_file(path: str | Path, data: bytes, what: str = "") -> Iterator[Path]:
    """``with pending_file(path, data): ...`` -- write ``data`` for ``path`` now, put it in place
    when the block ends without an error.

    The file is written to a hidden temporary sibling before the block runs (so a full disk or a
    file-size limit fails before anything is replaced) and moved into place with
    :func:`os.replace` after it; an error or an interrupt in the block removes it and leaves
    ``path`` as it was.  Used for a file that belongs with an output set published in the block
    (the model file of ``identify`` and its report folder): both are new, or both as they were.
    The file gets mode ``0o666`` less the umask; missing parent folders are created.

    Parameters
    ----------
    path : str or Path
        The file (a symbolic link is written through, not replaced).
    data : bytes
        Its contents.
    what : str
        How messages name it (e.g. ``"--out"``), before the path.

    Yields
    ------
    Path
        The temporary file.

    Raises
    ------
    OutputError
        The file cannot be written (names it and the cause); ``path`` is unchanged and no
        temporary file is left.
    """
    path = Path(path)
    name = f"{what} {path}".strip()
    real = real_path(path)
    try:
        real.parent.mkdir(FOLDER_MODE, parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{name}: cannot create the folder {path.parent} ({os_error_cause(exc)})") from None
    tmp = new_sibling_name(real, TEMP_KIND)
    unchanged = "the previous file, if any, is unchanged"
    done = False
    try:
        try:
            _write_new_file(tmp, data)
        except OSError as exc:
            raise OutputError(f"{name}: cannot write ({os_error_cause(exc)}); {unchanged}") from None
        yield tmp
        with interrupts.deferred():  # moved and recorded, or neither
            interrupts.raise_if_pending()  # a signal a library swallowed: not moved in
            try:
                os.replace(tmp, real)
            except OSError as exc:
                raise OutputError(f"{name}: cannot move it into place ({os_error_cause(exc)}); {unchanged}") from None
            done = True
            _PUBLISHED.append(path)
    finally:
        if not done:
            clean_up(tmp, name, "the unfinished new version of it")


#: The outputs moved into place in this process, in order (:func:`published_outputs`).
_PUBLISHED: list[Path] = []


def published_outputs() -> list[Path]:
    """The output folders and files moved into place so far in this process (oldest first): what a
    command interrupted after writing some of its outputs has changed (the command line says so)."""
    return list(_PUBLISHED)


def clear_published_outputs() -> None:
    """Forget the outputs recorded by :func:`published_outputs` (a new command starts)."""
    _PUBLISHED.clear()


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all (hidden temporary sibling + rename).

    The file gets mode ``0o666`` less the umask; missing parent folders are created.

    Raises
    ------
    OutputError
        The file cannot be written (names it and the cause); ``path`` is unchanged and no
        temporary file is left.
    """
    with pending_file(path, data):
        pass


def atomic_write_files(files: dict[Path, bytes]) -> None:
    """Write several single files whole or not at all (e.g. a KRL ``.src``/``.dat`` pair).

    Every file is first written to a hidden temporary sibling; only when all are written are
    they moved into place (:func:`os.replace`, which does not fail for want of space).  A
    failure while writing removes the temporaries and leaves every target unchanged.

    Raises
    ------
    OutputError
        Naming the file that could not be written and the cause.
    """
    staged: list[tuple[Path, Path, Path]] = []
    try:
        for path, data in files.items():
            real = real_path(Path(path))
            try:
                real.parent.mkdir(FOLDER_MODE, parents=True, exist_ok=True)
                tmp = new_sibling_name(real, TEMP_KIND)
                staged.append((tmp, real, Path(path)))
                _write_new_file(tmp, data)
            except OSError as exc:
                raise OutputError(
                    f"{path}: cannot write ({os_error_cause(exc)}); no file of the set was changed"
                ) from None
        with interrupts.deferred():  # the whole set moved and recorded, or none of it
            interrupts.raise_if_pending()  # a signal a library swallowed: not moved in
            for tmp, real, path in staged:
                os.replace(tmp, real)
                _PUBLISHED.append(path)
    finally:
        for tmp, _real_path, path in staged:
            if os.path.lexists(tmp):
                clean_up(tmp, str(path), "the unfinished new version of it")


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2(RENAME_EXCHANGE)``); False if unsupported."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), os.fspath(b))


def _move_into_place(staging: Path, target: Path) -> Path | None:
    """Put the folder ``staging`` at ``target`` in one step; returns where the old folder went.

    Raises
    ------
    OSError
        ``target`` is as it was (the fallback of two renames restores it on failure).
    """
    if not target.exists():
        os.rename(staging, target)
        return None
    if _exchange(staging, target):
        return staging
    retired = new_sibling_name(target, RETIRED_KIND)
    try:
        os.rename(target, retired)
        os.rename(staging, target)
    except BaseException:
        if not os.path.lexists(target) and os.path.lexists(retired):
            os.rename(retired, target)
        raise
    return retired


def _link_tree(src: Path, dst: Path) -> None:
    """Recreate ``src`` at ``dst``: files hard-linked (copied where links fail), folders made."""
    if src.is_symlink():
        os.symlink(os.readlink(src), dst)
    elif src.is_dir():
        dst.mkdir(FOLDER_MODE)
        for child in sorted(os.listdir(src)):
            _link_tree(src / child, dst / child)
    else:
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)


class OutputSet:
    """Collect output files in memory and publish them together, whole or not at all.

    >>> out = OutputSet("results")
    >>> out.add_json("summary.json", {...}); out.add_csv("path.csv", header, rows)
    >>> out.publish()      # nothing is written before this call

    Parameters
    ----------
    folder : str or Path
        The output folder.
    owns : iterable of str, optional
        Top-level entries of an existing folder that this set replaces (e.g. ``report.html``,
        ``figures``); every other entry is kept.  Default: the set is the whole folder, and
        nothing of an earlier run survives beside it.
    """

    def __init__(self, folder: str | Path, owns: Iterable[str] | None = None) -> None:
        self.folder = Path(folder)
        self.owns = None if owns is None else frozenset(owns)
        self.files: dict[str, bytes | Callable[[], Iterable[bytes]]] = {}

    def add_bytes(self, name: str, data: bytes | Callable[[], Iterable[bytes]]) -> None:
        """Add a file; ``name`` is relative to the folder (``figures/a.png`` makes ``figures/``).
        ``data`` is its bytes, or a callable yielding them piece by piece when the set is published
        (a large table is then never held in memory whole)."""
        parts = Path(name).parts
        if not parts or Path(name).is_absolute() or ".." in parts:
            raise InputError(f"output name {name!r}: expected a relative path inside the folder")
        self.files[name] = data

    def add_json(self, name: str, obj: Any) -> None:
        """Add a JSON file (see :func:`json_bytes`)."""
        self.add_bytes(name, json_bytes(obj))

    def add_csv(self, name: str, header: Sequence[str], rows: Any, int_rows: Any = None) -> None:
        """Add a CSV file (see :func:`csv_chunks`), written in pieces when the set is published."""
        A = np.asarray(rows, dtype=float)
        I = None if int_rows is None else np.asarray(int_rows)
        self.add_bytes(name, lambda: csv_chunks(header, A, I))

    def publish(self) -> list[Path]:
        """Write the set: built in a temporary sibling folder, then moved into place in one step.

        The folder is replaced whole (or, with ``owns``, every owned entry), so no earlier
        file survives.

        Returns
        -------
        list of Path
            The paths of the files written.

        Raises
        ------
        OutputError
            The folder cannot be written (disk full, file-size limit, permissions), is not
            an output folder, or another run is writing it; it is unchanged and no
            temporary folder is left.
        """
        kind: OutputKind = "folder" if self.owns is None else "update"
        check_output_path(self.folder, kind, "output folder", writes={Path(n).parts[0] for n in self.files})
        with output_lock(self.folder, "output folder"):
            target = real_path(self.folder)
            staging = new_sibling_name(target, STAGING_KIND)
            owner = f"output folder {self.folder}"
            doing = "create a temporary folder"
            try:
                staging.mkdir(FOLDER_MODE)
                for name, data in self.files.items():
                    doing = f"write {name}"
                    dest = staging / name
                    dest.parent.mkdir(FOLDER_MODE, parents=True, exist_ok=True)
                    _write_new_file(dest, data() if callable(data) else data)
                if self.owns is not None and target.is_dir():
                    owned = self.owns | {Path(n).parts[0] for n in self.files}
                    for entry in sorted(os.listdir(target)):
                        if entry not in owned:
                            doing = f"keep {entry}"
                            _link_tree(target / entry, staging / entry)
                doing = "move the new files into place"
                with interrupts.deferred():  # once moved, the set is recorded and the old one removed
                    interrupts.raise_if_pending()  # a signal a library swallowed: not moved in
                    retired = _move_into_place(staging, target)
                    _PUBLISHED.append(Path(self.folder))
                    if retired is not None:
                        clean_up(retired, owner, "its previous version (the new one is in place)")
            except OSError as exc:
                clean_up(staging, owner, "the unfinished new version of it")
                raise OutputError(f"{owner}: cannot {doing} ({os_error_cause(exc)}); nothing was changed") from None
            except BaseException:
                if not _PUBLISHED or _PUBLISHED[-1] != Path(self.folder):
                    clean_up(staging, owner, "the unfinished new version of it")
                raise
        return [self.folder / name for name in self.files]


__all__ = [
    "FILE_MODE",
    "FOLDER_KIND_MARKERS",
    "FOLDER_MODE",
    "FolderKind",
    "OUTPUT_FOLDER_MARKERS",
    "OutputError",
    "OutputKind",
    "OutputSet",
    "SIBLING_TAG",
    "STAGING_KIND",
    "SUMMARY_COMMAND_KINDS",
    "TRAJECTORY_COLUMNS",
    "acquire_output_lock",
    "atomic_write_bytes",
    "atomic_write_files",
    "check_output_folder",
    "check_output_path",
    "csv_bytes",
    "holds_output_lock",
    "json_bytes",
    "jsonable",
    "lock_path",
    "output_folder_kind",
    "output_lock",
    "pending_file",
    "published_outputs",
    "clear_published_outputs",
    "release_output_lock",
    "sibling_prefix",
    "take_output_notes",
]
