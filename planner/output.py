"""Writing outputs whole or not at all, with the user's permissions, one writer at a time.

* **Whole or not at all.**  A single file (:func:`atomic_write_bytes`) is written to a
  hidden temporary sibling and moved into place with :func:`os.replace`.  A set of files
  (:class:`OutputSet`) is built in a hidden temporary sibling *folder*
  (``.<name>.compplan-new-*``) and moved into place in one step (``renameat2`` with
  ``RENAME_EXCHANGE`` on Linux, else two renames); the previous folder is removed after.
  A failure at any point (disk full ``ENOSPC``, file-size limit ``EFBIG``, an interrupt)
  removes the temporary folder and leaves the previous set exactly as it was: never a mix
  of old and new files, never an earlier run's file beside a new one.  A set either owns
  its whole folder (a run: plan, demo, map, pose, the identification report) or, with
  ``owns=``, some entries of an existing folder (the report of a run folder: the rest is
  carried over by hard links).
* **Permissions.**  Files are created with mode ``0o666`` and folders ``0o777`` less the
  process umask, as by any program (no temporary file's ``0600`` is left on an output).
* **One writer.**  An output is locked while it is written (``fcntl.flock`` on the hidden
  sibling ``.<name>.compplan-lock``, removed again by its holder); a second writer is
  refused at once with one line naming the holder's process.  The commands take the lock
  before their long work (:func:`planner.commands.common.check_output`) and keep it to the
  end; :meth:`OutputSet.publish` takes it too (re-entrant within one thread).

Errors are :class:`OutputError` (a :class:`~models.errors.InputError`, so the command
line prints one line and exits 2, and an :class:`OSError`).
"""

from __future__ import annotations

import contextlib
import csv
import ctypes
import errno
import hashlib
import io
import json
import os
import secrets
import shutil
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal
from collections.abc import Callable, Iterable, Iterator, Sequence

import numpy as np

from models.errors import InputError

try:
    import fcntl
except ImportError:  # not POSIX: outputs are written whole but not locked
    fcntl = None  # type: ignore[assignment]

#: Columns of ``trajectory*.csv`` (SI): time, positions, velocities, accelerations, jerks.
TRAJECTORY_COLUMNS = (
    ["t"]
    + [f"q{i}" for i in range(1, 7)]
    + [f"qd{i}" for i in range(1, 7)]
    + [f"qdd{i}" for i in range(1, 7)]
    + [f"qddd{i}" for i in range(1, 7)]
)

#: Mode of a created file and of a created folder before the process umask is applied.
FILE_MODE = 0o666
FOLDER_MODE = 0o777

#: Every hidden sibling compplan makes beside an output ``NAME`` is ``.NAME`` + this tag + a
#: kind: the lock file, a set being built, a set being retired, a file being written.
SIBLING_TAG = ".compplan-"
LOCK_KIND = "lock"
STAGING_KIND = "new-"
RETIRED_KIND = "old-"
TEMP_KIND = "tmp-"
#: Names longer than this are shortened (prefix + hash) in sibling names (NAME_MAX is 255).
SIBLING_NAME_MAX = 64
#: Random hex digits in a temporary sibling's name.
SIBLING_TOKEN_BYTES = 6

#: A file of one of these names marks an existing folder as an output folder of compplan
#: (plan/demo, identification report, map, pose), which a new run may replace whole.
OUTPUT_FOLDER_MARKERS = ("summary.json", "report.json", "compliance_map.json", "pose.json")
#: Entries of a foreign folder named in the refusal message.
FOREIGN_SHOWN = 3

#: Attempts to lock a lock file that its previous holder removes between our open and flock.
LOCK_ATTEMPTS = 5

#: Flush every output file to the disk before it is moved into place (a crash right after
#: the move then never leaves an empty file).
FSYNC_FILES = True

#: ``flock`` errors of a file system without locks (some network file systems): written unlocked.
_NO_LOCKING = (errno.ENOLCK, errno.ENOTSUP, errno.EOPNOTSUPP)

#: Linux ``renameat2`` arguments: ``AT_FDCWD`` and the flag that swaps two paths atomically.
_AT_FDCWD = -100
_RENAME_EXCHANGE = 2

OutputKind = Literal["file", "folder", "update"]


class OutputError(InputError, OSError):
    """An output cannot be written (disk full, file-size limit, permissions, another writer).

    One line naming the output and the cause; the previous output is unchanged.  Both an
    :class:`~models.errors.InputError` (the CLI prints it and exits 2) and an
    :class:`OSError` (callers that tolerate I/O failures, e.g. caches, still catch it).
    """


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


# ------------------------------------------------------------------------------ errors
def _cause(exc: OSError) -> str:
    """``strerror (ENAME)`` of an OS error, e.g. ``No space left on device (ENOSPC)``."""
    if exc.errno is None:
        return str(exc)
    name = errno.errorcode.get(exc.errno, str(exc.errno))
    return f"{exc.strerror or os.strerror(exc.errno)} ({name})"


# ------------------------------------------------------------------------------ siblings
def _real(path: str | Path) -> Path:
    """The absolute path with symbolic links resolved (also for parts that do not exist yet)."""
    return Path(os.path.realpath(os.fspath(path)))


def _stem(name: str) -> str:
    """``name`` as used in sibling names: long names shortened to a prefix and a hash."""
    if len(name) <= SIBLING_NAME_MAX:
        return name
    digest = hashlib.sha256(name.encode("utf-8", "surrogateescape")).hexdigest()[:12]
    return f"{name[: SIBLING_NAME_MAX - 13]}-{digest}"


def sibling_prefix(target: str | Path, kind: str) -> Path:
    """Path (prefix) of a hidden sibling of ``target`` of the given kind (``LOCK_KIND`` ...)."""
    real = _real(target)
    return real.parent / f".{_stem(real.name)}{SIBLING_TAG}{kind}"


def lock_path(target: str | Path) -> Path:
    """The lock file of an output: ``.NAME.compplan-lock`` beside it."""
    return sibling_prefix(target, LOCK_KIND)


def _new_sibling_name(target: Path, kind: str) -> Path:
    return Path(f"{sibling_prefix(target, kind)}{os.getpid()}-{secrets.token_hex(SIBLING_TOKEN_BYTES)}")


def _remove(path: Path) -> None:
    """Remove a file or a folder tree; errors ignored (best effort clean-up)."""
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink()
    except OSError:
        pass


def _remove_leftovers(target: Path) -> None:
    """Remove temporary siblings that an earlier, killed writer of ``target`` left.

    Only called by the holder of ``target``'s lock, so no live writer owns them.
    """
    real = _real(target)
    prefixes = tuple(sibling_prefix(real, k).name for k in (STAGING_KIND, RETIRED_KIND, TEMP_KIND))
    try:
        names = os.listdir(real.parent)
    except OSError:
        return
    for name in names:
        if name.startswith(prefixes):
            _remove(real.parent / name)


# ------------------------------------------------------------------------------ locks
@dataclass
class _HeldLock:
    """A lock this process holds on one output."""

    fd: int
    path: Path
    thread: int
    count: int = 1
    created: list[Path] = field(default_factory=list)


_HELD: dict[Path, _HeldLock] = {}
_HELD_GUARD = threading.Lock()


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; returns the folders created, outermost first."""
    missing = []
    p = folder
    while not p.exists():
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    created = []
    for d in reversed(missing):
        try:
            d.mkdir(FOLDER_MODE)
            created.append(d)
        except FileExistsError:
            pass
    return created


def _remove_if_empty(folders: list[Path]) -> None:
    """Remove the folders made for a lock, innermost first, while they are empty."""
    for d in reversed(folders):
        try:
            d.rmdir()
        except OSError:
            break


def _holder(fd: int) -> str:
    """``pid N`` as the holder wrote it into the lock file, or ``''``."""
    try:
        text = os.pread(fd, 64, 0).decode(errors="replace").strip()
    except OSError:
        return ""
    return f"pid {text}" if text.isdigit() else ""


def holds_output_lock(target: str | Path) -> bool:
    """Whether this process holds the lock of ``target``."""
    return _real(target) in _HELD


def _lock_attempt(path: Path, created: list[Path], target: str | Path, what: str) -> tuple[int | None, bool]:
    """One attempt at the lock file ``path``: ``(fd, True)`` when locked, ``(None, True)`` on a
    file system without locks, ``(None, False)`` when the file was removed under us (try again).

    Raises
    ------
    OutputError
        Another run holds the lock, or the lock file cannot be created or locked.
    """
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, FILE_MODE)
    except OSError as exc:
        _remove_if_empty(created)
        raise OutputError(f"{what} {target}: cannot create the lock file {path} ({_cause(exc)})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _holder(fd)
        os.close(fd)
        _remove_if_empty(created)
        raise OutputError(
            f"{what} {target}: another compplan run is writing it "
            f"({holder + ', ' if holder else ''}lock {path}); wait for it to finish "
            "or choose another path"
        ) from None
    except OSError as exc:
        os.close(fd)
        if exc.errno in _NO_LOCKING:
            with contextlib.suppress(OSError):
                path.unlink()
            _remove_if_empty(created)
            return None, True
        _remove_if_empty(created)
        raise OutputError(f"{what} {target}: cannot lock {path} ({_cause(exc)})") from None
    # The previous holder removes the file on release: ours may be an unlinked one.
    try:
        same = os.path.samestat(os.fstat(fd), os.stat(path))
    except FileNotFoundError:
        same = False
    if same:
        return fd, True
    os.close(fd)
    return None, False


def acquire_output_lock(target: str | Path, what: str = "output") -> Path:
    """Lock ``target`` (a file or folder to be written) for this process, without waiting.

    Re-entrant within one thread (a count); release with :func:`release_output_lock` as
    often.  Missing parent folders are created for the lock file and removed again on
    release if nothing was written into them.

    Parameters
    ----------
    target : str or Path
        The output file or folder.
    what : str
        How messages name it, e.g. ``"--out"`` or ``"output folder"``.

    Returns
    -------
    Path
        The lock file.

    Raises
    ------
    OutputError
        Another process (or another thread of this one) is writing ``target``, or the
        lock file cannot be created.
    """
    real = _real(target)
    with _HELD_GUARD:
        held = _HELD.get(real)
        if held is not None:
            if held.thread != threading.get_ident():
                raise OutputError(f"{what} {target}: another thread of this process is writing it")
            held.count += 1
            return held.path
    path = lock_path(real)
    if fcntl is None:
        return path
    try:
        created = _make_parents(path.parent)
    except OSError as exc:
        raise OutputError(f"{what} {target}: cannot create the folder {path.parent} ({_cause(exc)})") from None
    for _ in range(LOCK_ATTEMPTS):
        fd, locked = _lock_attempt(path, created, target, what)
        if locked and fd is None:  # a file system without locks: write unlocked
            return path
        if locked:
            break
    else:
        _remove_if_empty(created)
        raise OutputError(f"{what} {target}: cannot lock {path} (removed repeatedly by other runs)")
    with contextlib.suppress(OSError):
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    with _HELD_GUARD:
        _HELD[real] = _HeldLock(fd, path, threading.get_ident(), created=created)
    _remove_leftovers(real)
    return path


def release_output_lock(target: str | Path) -> None:
    """Release one :func:`acquire_output_lock` of ``target``; the last removes the lock file."""
    real = _real(target)
    with _HELD_GUARD:
        held = _HELD.get(real)
        if held is None:
            return
        held.count -= 1
        if held.count > 0:
            return
        del _HELD[real]
    try:
        if os.path.samestat(os.fstat(held.fd), os.stat(held.path)):
            held.path.unlink()  # while still locked: no one can hold this inode
    except OSError:
        pass
    os.close(held.fd)
    _remove_if_empty(held.created)


@contextlib.contextmanager
def output_lock(target: str | Path, what: str = "output") -> Iterator[Path]:
    """``with output_lock(path):`` -- :func:`acquire_output_lock` ... :func:`release_output_lock`."""
    path = acquire_output_lock(target, what)
    try:
        yield path
    finally:
        release_output_lock(target)


# ------------------------------------------------------------------------------ checks
def check_output_path(
    path: str | Path, kind: OutputKind = "folder", what: str = "--out", writes: Iterable[str] = ()
) -> Path:
    """Check that ``path`` can be written as an output of the given kind; nothing is created.

    Call it before long computations so that a bad output path fails at once.

    Parameters
    ----------
    path : str or Path
        The output.
    kind : {"file", "folder", "update"}
        ``"file"``: one file (not an existing folder).  ``"folder"``: a folder a run
        replaces whole: new, empty, or an output folder of compplan (it holds one of
        :data:`OUTPUT_FOLDER_MARKERS`, or only entries named in ``writes``).  ``"update"``:
        an existing folder some of whose entries are replaced (the report of a run folder).
    what : str
        How messages name the output (``"--out"``, ``"--report"``, ...).
    writes : iterable of str
        Top-level names the output set writes (a folder holding only these is one it wrote).

    Returns
    -------
    Path

    Raises
    ------
    OutputError
        One line naming the path and what is wrong with it.
    """
    p = Path(path)
    real = _real(p)
    if real.parent == real:
        raise OutputError(f"{what} {p}: is the root folder; give a folder below it")
    if kind == "file":
        if p.is_dir():
            raise OutputError(f"{what} {p}: is an existing folder; give the path of the file to write")
        if p.exists() and not p.is_file():
            raise OutputError(f"{what} {p}: exists and is not a regular file")
    else:
        if p.exists() and not p.is_dir():
            raise OutputError(f"{what} {p}: exists and is not a folder; give a folder path")
        cwd = _real(os.getcwd())
        if cwd == real or real in cwd.parents:
            raise OutputError(
                f"{what} {p}: is the current folder or contains it, and it is replaced whole "
                "when written; run from outside it (e.g. its parent)"
            )
        if kind == "folder" and p.is_dir():
            try:
                entries = sorted(os.listdir(p))
            except OSError as exc:
                raise OutputError(f"{what} {p}: cannot read the folder ({_cause(exc)})") from None
            ours = set(writes)
            if entries and not any(m in entries for m in OUTPUT_FOLDER_MARKERS) and not set(entries) <= ours:
                shown = ", ".join(entries[:FOREIGN_SHOWN]) + (", ..." if len(entries) > FOREIGN_SHOWN else "")
                raise OutputError(
                    f"{what} {p}: holds files compplan did not write ({shown}), and an output "
                    "folder is replaced whole; give a new or empty folder"
                )
    parent = real.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(f"{what} {p}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {p}: {parent} is not writable")
    return p


def check_output_folder(folder: str | Path, create: bool = False) -> Path:
    """Check that ``folder`` can be written as a whole output folder (see :func:`check_output_path`).

    Kept for callers of earlier versions; nothing is created unless ``create``.

    Raises
    ------
    OutputError
        Naming the folder and what is wrong with it.
    """
    p = check_output_path(folder, "folder", "--out")
    if create:
        try:
            p.mkdir(FOLDER_MODE, parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"--out {p}: cannot create the folder ({_cause(exc)})") from None
    return p


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


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all (hidden temporary sibling + rename).

    The file gets mode ``0o666`` less the umask; missing parent folders are created.

    Raises
    ------
    OutputError
        The file cannot be written (names it and the cause); ``path`` is unchanged and no
        temporary file is left.
    """
    path = Path(path)
    real = _real(path)  # a symbolic link is written through, not replaced
    try:
        real.parent.mkdir(FOLDER_MODE, parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create the folder {path.parent} ({_cause(exc)})") from None
    tmp = _new_sibling_name(real, TEMP_KIND)
    try:
        _write_new_file(tmp, data)
        os.replace(tmp, real)
    except OSError as exc:
        _remove(tmp)
        raise OutputError(f"{path}: cannot write ({_cause(exc)}); the previous file, if any, is unchanged") from None
    except BaseException:
        _remove(tmp)
        raise


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
    staged: list[tuple[Path, Path]] = []
    try:
        for path, data in files.items():
            real = _real(Path(path))
            try:
                real.parent.mkdir(FOLDER_MODE, parents=True, exist_ok=True)
                tmp = _new_sibling_name(real, TEMP_KIND)
                staged.append((tmp, real))
                _write_new_file(tmp, data)
            except OSError as exc:
                raise OutputError(f"{path}: cannot write ({_cause(exc)}); no file of the set was changed") from None
        for tmp, real in staged:
            os.replace(tmp, real)
    finally:
        for tmp, _real_path in staged:
            _remove(tmp)


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
    retired = _new_sibling_name(target, RETIRED_KIND)
    os.rename(target, retired)
    try:
        os.rename(staging, target)
    except BaseException:
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
            target = _real(self.folder)
            staging = _new_sibling_name(target, STAGING_KIND)
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
                retired = _move_into_place(staging, target)
            except OSError as exc:
                _remove(staging)
                raise OutputError(
                    f"output folder {self.folder}: cannot {doing} ({_cause(exc)}); nothing was changed"
                ) from None
            except BaseException:
                _remove(staging)
                raise
            if retired is not None:
                _remove(retired)
        return [self.folder / name for name in self.files]


__all__ = [
    "FILE_MODE",
    "FOLDER_MODE",
    "OUTPUT_FOLDER_MARKERS",
    "OutputError",
    "OutputSet",
    "TRAJECTORY_COLUMNS",
    "acquire_output_lock",
    "atomic_write_bytes",
    "check_output_folder",
    "check_output_path",
    "csv_bytes",
    "holds_output_lock",
    "json_bytes",
    "jsonable",
    "lock_path",
    "output_lock",
    "release_output_lock",
]
