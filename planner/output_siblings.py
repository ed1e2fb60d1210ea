"""The hidden siblings of an output: their names, the clean-up of what an earlier run left, and the
lock that makes one process the writer of an output.

Beside an output ``NAME`` compplan makes only hidden siblings ``.NAME.compplan-<kind>``: the lock
file (``lock``), a set being built (``new-*``), a set being retired (``old-*``) and a file being
written (``tmp-*``).  A run that is killed (``SIGKILL``, a power cut) may leave ``new-*``,
``old-*`` or ``tmp-*`` siblings; the next writer of ``NAME`` removes them as soon as it holds
``NAME``'s lock (no live writer can own them then).  A sibling that cannot be removed (e.g. a
read-only folder) is left, and a one-line note names it and how to remove it: the library is
silent, the command line prints the notes (:func:`take_output_notes`) as warnings.

:mod:`planner.output` re-exports what callers use; this module holds no writing of outputs.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import secrets
import shlex
import shutil
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from models.errors import InputError

try:
    import fcntl
except ImportError:  # not POSIX: outputs are written whole but not locked
    fcntl = None  # type: ignore[assignment]

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
#: The kinds of sibling an interrupted writer may leave (removed by the next writer).
LEFTOVER_KINDS = (STAGING_KIND, RETIRED_KIND, TEMP_KIND)
#: Names longer than this are shortened (prefix + hash) in sibling names (NAME_MAX is 255).
SIBLING_NAME_MAX = 64
#: Random hex digits in a temporary sibling's name.
SIBLING_TOKEN_BYTES = 6

#: Attempts to lock a lock file that its previous holder removes between our open and flock.
LOCK_ATTEMPTS = 5

#: ``flock`` errors of a file system without locks (some network file systems): written unlocked.
_NO_LOCKING = (errno.ENOLCK, errno.ENOTSUP, errno.EOPNOTSUPP)


class OutputError(InputError, OSError):
    """An output cannot be written (disk full, file-size limit, permissions, another writer).

    One line naming the output and the cause; the previous output is unchanged.  Both an
    :class:`~models.errors.InputError` (the CLI prints it and exits 2) and an
    :class:`OSError` (callers that tolerate I/O failures, e.g. caches, still catch it).
    """


# ------------------------------------------------------------------------------ errors
def os_error_cause(exc: OSError) -> str:
    """``strerror (ENAME)`` of an OS error, e.g. ``No space left on device (ENOSPC)``."""
    if exc.errno is None:
        return str(exc)
    name = errno.errorcode.get(exc.errno, str(exc.errno))
    return f"{exc.strerror or os.strerror(exc.errno)} ({name})"


# ------------------------------------------------------------------------------ notes
#: One-line notes of this process about siblings left behind, oldest first (see :func:`take_output_notes`).
_NOTES: list[str] = []


def take_output_notes() -> list[str]:
    """The notes recorded since the last call (and forget them): one line per hidden sibling that
    could not be removed, naming it, the cause and the command that removes it."""
    notes = _NOTES[:]
    del _NOTES[: len(notes)]
    return notes


def removal_hint(path: Path) -> str:
    """The shell command that removes ``path`` even when it is read-only."""
    q = shlex.quote(os.fspath(path))
    return f"chmod -R u+w {q} && rm -rf {q}"


# ------------------------------------------------------------------------------ siblings
def real_path(path: str | Path) -> Path:
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
    real = real_path(target)
    return real.parent / f".{_stem(real.name)}{SIBLING_TAG}{kind}"


def lock_path(target: str | Path) -> Path:
    """The lock file of an output: ``.NAME.compplan-lock`` beside it."""
    return sibling_prefix(target, LOCK_KIND)


def new_sibling_name(target: Path, kind: str) -> Path:
    """A fresh name for a temporary sibling of ``target`` (``STAGING_KIND`` ...): pid and random digits."""
    return Path(f"{sibling_prefix(target, kind)}{os.getpid()}-{secrets.token_hex(SIBLING_TOKEN_BYTES)}")


def remove_path(path: Path) -> OSError | None:
    """Remove a file or a folder tree, as much of it as can be removed.

    Returns
    -------
    OSError or None
        The error that kept ``path`` (or part of it) in place; None when it is gone.
    """
    tree = path.is_dir() and not path.is_symlink()
    try:
        if tree:
            shutil.rmtree(path)
        else:
            path.unlink()
    except FileNotFoundError:
        return None
    except OSError as exc:
        if tree:
            shutil.rmtree(path, ignore_errors=True)  # what can go, goes
        return exc if os.path.lexists(path) else None
    return None


def clean_up(path: Path, owner: str, why: str) -> bool:
    """Remove the temporary sibling ``path``; when some of it stays, record a note
    ``"<owner>: cannot remove <path>, <why> (<cause>); remove it with: <command>"``.

    Parameters
    ----------
    path : Path
        The sibling.
    owner : str
        The output it belongs to, as messages name it (e.g. ``"output folder out/run"``).
    why : str
        What the sibling is, e.g. ``"the previous version of the folder"``.

    Returns
    -------
    bool
        Whether ``path`` is gone.
    """
    exc = remove_path(path)
    if exc is None:
        return True
    _NOTES.append(f"{owner}: cannot remove {path}, {why} ({os_error_cause(exc)}); remove it with: {removal_hint(path)}")
    return False


def _remove_leftovers(target: str | Path, what: str) -> None:
    """Remove the temporary siblings (:data:`LEFTOVER_KINDS`) an earlier, stopped writer of
    ``target`` left; each one that cannot be removed is named in a note.

    Only called by the holder of ``target``'s lock, so no live writer owns them.
    """
    real = real_path(target)
    prefixes = tuple(sibling_prefix(real, k).name for k in LEFTOVER_KINDS)
    try:
        names = sorted(os.listdir(real.parent))
    except OSError:
        return
    for name in names:
        if name.startswith(prefixes):
            clean_up(real.parent / name, f"{what} {target}", "left by an earlier run that was stopped")


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
    return real_path(target) in _HELD


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
        raise OutputError(f"{what} {target}: cannot create the lock file {path} ({os_error_cause(exc)})") from None
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
        raise OutputError(f"{what} {target}: cannot lock {path} ({os_error_cause(exc)})") from None
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
    real = real_path(target)
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
        raise OutputError(f"{what} {target}: cannot create the folder {path.parent} ({os_error_cause(exc)})") from None
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
    _remove_leftovers(target, what)
    return path


def release_output_lock(target: str | Path) -> None:
    """Release one :func:`acquire_output_lock` of ``target``; the last removes the lock file."""
    real = real_path(target)
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


__all__ = [
    "FILE_MODE",
    "FOLDER_MODE",
    "OutputError",
    "SIBLING_TAG",
    "acquire_output_lock",
    "clean_up",
    "holds_output_lock",
    "lock_path",
    "new_sibling_name",
    "os_error_cause",
    "output_lock",
    "real_path",
    "release_output_lock",
    "remove_path",
    "sibling_prefix",
    "take_output_notes",
]
