"""The C compiler behind :mod:`models.codegen`: compiling generated code into a shared library,
the checked library cache, and the one-line notes of every fallback.

:func:`compile_shared_library` compiles C source once with the system C compiler (``$CC``, else
``gcc`` / ``cc``; :data:`CFLAGS`) into a library cached under ``$COMPPLAN_CACHE`` (default
``~/.cache/compplan``, keyed by a hash of the source).  The cache is checked, never trusted: every
library carries a trailer with the SHA-256 of its bytes (:func:`check_library`), a corrupt entry is
rebuilt, and a cache folder that cannot be used is bypassed (the libraries are built into a private
temporary folder removed at exit, :func:`private_folder`).  ``$COMPPLAN_NO_COMPILER=1`` disables
compiled code (:func:`compiler_disabled`).  Every fallback is recorded as a one-line note
(:func:`codegen_notes`), which the command line prints once per run; the library is silent.
"""

from __future__ import annotations

import atexit
import hashlib
import os
import platform
import shlex
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path
from typing import NoReturn

import casadi as ca

#: Compiler flags for generated code.
CFLAGS = ("-O3", "-march=native", "-fPIC", "-shared", "-fopenmp", "-fno-math-errno")

#: Environment variable that, set to one of :data:`TRUE_WORDS`, disables compiled code.
NO_COMPILER_ENV = "COMPPLAN_NO_COMPILER"
#: Values of :data:`NO_COMPILER_ENV` that disable the compiler (case-insensitive).
TRUE_WORDS = frozenset({"1", "true", "yes", "on"})
#: Environment variable naming the cache folder.
CACHE_ENV = "COMPPLAN_CACHE"
#: The cache folder when :data:`CACHE_ENV` is unset, relative to the home folder.
DEFAULT_CACHE = Path(".cache") / "compplan"
#: Version of the cache entry format, part of the cache key (2: library + integrity trailer).
CACHE_FORMAT = 2
#: Start of the trailer appended to every cached library, followed by the SHA-256 of the library.
TRAILER_MAGIC = b"\0COMPPLAN-LIBRARY-SHA256\0"
#: Length of the trailer: magic and a SHA-256 digest.
TRAILER_LEN = len(TRAILER_MAGIC) + hashlib.sha256().digest_size
#: Longest compiler message kept in a note (characters).
NOTE_MESSAGE_MAX = 160
#: The end of every note about evaluating without compiled code.
VM_NOTE = "evaluating with CasADi's virtual machine, slower"


class CompileError(RuntimeError):
    """No compiled code: the C compiler is disabled, missing or failed, or its library cannot
    be loaded or stored; the message says which (and :func:`codegen_notes` records it)."""


# ------------------------------------------------------------------------------ notes
_NOTE_COMPILER = "compiler"
_NOTE_CACHE = "cache"
CACHE_LOCK = threading.RLock()
#: One-line notes of this process by topic (first note of a topic wins), in order.
_NOTES: dict[str, str] = {}
#: Compiler commands that failed in this process, with the reason; not tried again.
_FAILED_COMPILERS: dict[tuple[str, ...], str] = {}
#: Libraries whose trailer was verified: path -> (inode, size, mtime in ns).
_VERIFIED: dict[str, tuple[int, int, int]] = {}
#: Private folder of the libraries built while the cache is bypassed (removed at exit).
_PRIVATE_DIR: list[Path] = []
#: The note of a bypassed cache, recorded again whenever a bypassed library is reused.
_BYPASS_NOTE: list[str] = []


def codegen_notes() -> list[str]:
    """The one-line notes recorded in this process, oldest first (at most one per topic).

    A note says that compiled code is not used (no C compiler, ``$COMPPLAN_NO_COMPILER``,
    a library that cannot be loaded: evaluation by CasADi's virtual machine, slower) or
    that the compile cache was repaired or bypassed.  The library never prints them;
    the command line prints each once per run.

    Returns
    -------
    list of str
        Notes without a prefix or a trailing newline.
    """
    with CACHE_LOCK:
        return list(_NOTES.values())


def clear_codegen_notes() -> None:
    """Forget the recorded notes (the command line does this at the start of a run)."""
    with CACHE_LOCK:
        _NOTES.clear()


def _record(topic: str, message: str) -> None:
    with CACHE_LOCK:
        _NOTES.setdefault(topic, message)


def note_virtual_machine(reason: str) -> None:
    """Record that compiled code is not used because of ``reason`` (one line, no period).

    Parameters
    ----------
    reason : str
        E.g. ``"no C compiler (CC=/bin/false: exit status 1)"``; the note is
        ``"<reason>: evaluating with CasADi's virtual machine, slower"``.
    """
    _record(_NOTE_COMPILER, f"{reason}: {VM_NOTE}")


def no_compiled_code(reason: str) -> NoReturn:
    """Record ``reason`` as the virtual-machine note and raise :class:`CompileError`."""
    note_virtual_machine(reason)
    raise CompileError(reason)


def _os_reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def one_line(text: str) -> str:
    """The first non-empty line of a (compiler) message, shortened to :data:`NOTE_MESSAGE_MAX`."""
    line = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    return line if len(line) <= NOTE_MESSAGE_MAX else line[: NOTE_MESSAGE_MAX - 3] + "..."


# ------------------------------------------------------------------------------ compiler
def compiler_disabled() -> str | None:
    """Why compiled code is switched off in this process (``$COMPPLAN_NO_COMPILER``), or None."""
    value = os.environ.get(NO_COMPILER_ENV, "")
    if value.strip().lower() in TRUE_WORDS:
        return f"C compiler disabled ({NO_COMPILER_ENV}={value.strip()})"
    return None


def _compiler() -> tuple[list[str], str]:
    """The compiler command and its label for messages (``CC=...`` or the path found).

    Raises
    ------
    CompileError
        ``$CC`` names no program, none of ``gcc`` / ``cc`` is on ``PATH``, or the
        compiler already failed in this process.
    """
    cc_env = os.environ.get("CC", "").strip()
    if cc_env:
        try:
            cmd = shlex.split(cc_env)
        except ValueError:
            cmd = [cc_env]
        label = f"CC={cc_env}"
        exe = shutil.which(cmd[0]) if cmd else None
        if exe is None:
            no_compiled_code(f"no C compiler ({label}: not found)")
        cmd = [str(exe), *cmd[1:]]
    else:
        exe = shutil.which("gcc") or shutil.which("cc")
        if exe is None:
            no_compiled_code("no C compiler (CC unset, no gcc or cc on PATH)")
        cmd, label = [str(exe)], str(exe)
    with CACHE_LOCK:
        failed = _FAILED_COMPILERS.get(tuple(cmd))
    if failed is not None:
        no_compiled_code(failed)
    return cmd, label


def _build(src: str, cmd: list[str], label: str) -> bytes:
    """Compile ``src`` into a shared library; its bytes followed by the integrity trailer.

    Raises
    ------
    CompileError
        The compiler cannot be run or fails (then it is not tried again in this process).
    """
    reason = None
    try:
        with tempfile.TemporaryDirectory(prefix="compplan-cc-") as tmp:
            (Path(tmp) / "f.c").write_text(src)
            proc = subprocess.run([*cmd, *CFLAGS, "f.c", "-o", "f.so", "-lm"], cwd=tmp, capture_output=True, text=True)
            if proc.returncode == 0:
                data = (Path(tmp) / "f.so").read_bytes()
            else:
                reason = one_line(proc.stderr) or f"exit status {proc.returncode}"
    except OSError as exc:
        reason = _os_reason(exc)
    if reason is not None:
        reason = f"no usable C compiler ({label}: {reason})"
        with CACHE_LOCK:
            _FAILED_COMPILERS[tuple(cmd)] = reason
        no_compiled_code(reason)
    return data + TRAILER_MAGIC + hashlib.sha256(data).digest()


# ------------------------------------------------------------------------------ cache
def cache_root() -> Path:
    """The compile cache folder: ``$COMPPLAN_CACHE``, default ``~/.cache/compplan``."""
    root = os.environ.get(CACHE_ENV)
    return Path(root) if root else Path(os.path.expanduser("~")) / DEFAULT_CACHE


def _cache_problem(root: Path) -> str | None:
    """Why the cache folder cannot hold libraries (it is a file, cannot be created), or None."""
    try:
        if root.exists() and not root.is_dir():
            return "is not a folder"
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot be created ({_os_reason(exc)})"
    return None


#: :func:`check_library`'s answer for a library that is not there.
_MISSING = "missing"
#: Start of :func:`check_library`'s answer for a library that cannot be read (a cache problem).
_UNREADABLE = "unreadable"


def check_library(path: Path) -> str | None:
    """None if ``path`` is a complete library written by this module, else what is wrong
    (:data:`_MISSING` if there is none).  Checked before loading: ``dlopen`` of a truncated
    library kills the process (SIGBUS)."""
    try:
        st = path.stat()
    except FileNotFoundError:
        return _MISSING
    except OSError as exc:
        return f"{_UNREADABLE}: {_os_reason(exc)}"
    sig = (st.st_ino, st.st_size, st.st_mtime_ns)
    with CACHE_LOCK:
        if _VERIFIED.get(str(path)) == sig:
            return None
    try:
        data = path.read_bytes()
    except OSError as exc:
        return f"{_UNREADABLE}: {_os_reason(exc)}"
    digest_len = TRAILER_LEN - len(TRAILER_MAGIC)
    if len(data) <= TRAILER_LEN or data[-TRAILER_LEN:-digest_len] != TRAILER_MAGIC:
        return "truncated or not written by compplan"
    if hashlib.sha256(data[:-TRAILER_LEN]).digest() != data[-digest_len:]:
        return "checksum mismatch"
    with CACHE_LOCK:
        _VERIFIED[str(path)] = sig
    return None


def store_library(lib: Path, data: bytes) -> None:
    """Write ``data`` to ``lib`` atomically (concurrent builds of one library race safely)."""
    fd, staged = tempfile.mkstemp(dir=lib.parent, prefix=f".{lib.stem}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(staged, lib)
    except BaseException:
        try:
            os.unlink(staged)
        except OSError:
            pass
        raise


def private_folder() -> Path:
    """This process's folder for libraries built while the cache is bypassed."""
    with CACHE_LOCK:
        if not _PRIVATE_DIR:
            folder = Path(tempfile.mkdtemp(prefix="compplan-lib-"))
            atexit.register(shutil.rmtree, folder, True)
            _PRIVATE_DIR.append(folder)
        return _PRIVATE_DIR[0]


def host_id() -> str:
    """Identity of the CPU the code is compiled for (``-march=native``): part of the cache key,
    so a cache shared between different machines never loads code for another CPU."""
    model = platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith(("model name", "flags")):
                    model += line
    except OSError:
        model += platform.processor()
    return model


def compile_shared_library(src: str, prefix: str) -> Path:
    """Compile C source into a cached shared library and return its path.

    The cache key hashes the source, the flags, the CasADi version, the host CPU and the
    cache format.  A cached library is used only if its integrity trailer checks; a corrupt
    one is rebuilt.  Concurrent builds of the same library race safely (atomic rename).  If
    the cache folder is a file, cannot be created or is not writable, the library is built
    into a private temporary folder for this process.  Each repair or bypass records one
    note (:func:`codegen_notes`).

    Parameters
    ----------
    src : str
        Complete C source.
    prefix : str
        Start of the library's file name.

    Returns
    -------
    Path
        A verified library, safe to load.

    Raises
    ------
    CompileError
        The compiler is disabled (``$COMPPLAN_NO_COMPILER``), missing or failed, and no
        valid library is cached; a note is recorded.
    """
    disabled = compiler_disabled()
    if disabled is not None:
        no_compiled_code(disabled)
    key_src = src + " ".join(CFLAGS) + ca.__version__ + host_id() + f"format{CACHE_FORMAT}"
    name = f"{prefix}_{hashlib.sha256(key_src.encode()).hexdigest()[:20]}.so"
    root = cache_root()
    problem = _cache_problem(root)
    lib = root / name
    corrupt = None
    if problem is None:
        state = check_library(lib)
        if state is None:
            return lib
        if state.startswith(_UNREADABLE):
            problem = f"is not readable ({state.removeprefix(_UNREADABLE + ': ')})"
        elif state != _MISSING:
            corrupt = state
    with CACHE_LOCK:
        private = _PRIVATE_DIR[0] / name if _PRIVATE_DIR else None
    if private is not None and check_library(private) is None:
        with CACHE_LOCK:
            if _BYPASS_NOTE:
                _record(_NOTE_CACHE, _BYPASS_NOTE[0])
        return private
    cmd, label = _compiler()
    data = _build(src, cmd, label)
    if problem is None:
        try:
            store_library(lib, data)
        except OSError as exc:
            problem = f"is not writable ({_os_reason(exc)})"
        else:
            if corrupt is not None:
                _record(_NOTE_CACHE, f"cached library {lib} was corrupt ({corrupt}): rebuilt")
            return lib
    try:
        path = private_folder() / name
        store_library(path, data)
    except OSError as exc:
        no_compiled_code(f"compile cache {root} {problem} and no temporary folder ({_os_reason(exc)})")
    what = f"compile cache {root} {problem}"
    if corrupt is not None:
        what += f", its {name} corrupt ({corrupt})"
    message = f"{what}: compiled code kept in {path.parent} for this run only (set {CACHE_ENV})"
    with CACHE_LOCK:
        _BYPASS_NOTE[:] = [message]
    _record(_NOTE_CACHE, message)
    return path
