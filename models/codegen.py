"""Compile a CasADi Function to C once and evaluate it over batches from NumPy.

CasADi's own ``map`` converts every argument to a ``DM`` and runs the SX
virtual machine; for kinematics over millions of poses that costs far more than
the arithmetic.  Here the function's generated C code is wrapped in a small
OpenMP loop, compiled once with the system C compiler into a shared library
cached under ``$COMPPLAN_CACHE`` (default ``~/.cache/compplan``, keyed by a hash
of the source), and called through :mod:`ctypes` on NumPy buffers directly.

Without a usable C compiler everything still runs, slower, on CasADi's virtual
machine: :func:`batch_function` returns a :class:`VMBatchFunction` (same call
convention as :class:`BatchFunction`) and :func:`compile_shared_library` raises
:class:`CompileError`, which its callers catch to use the SX functions.  No
compiler is used when

* ``$COMPPLAN_NO_COMPILER`` is set to ``1`` (``true``, ``yes``, ``on``): no compiled
  code at all, not even from the cache (tests and CI);
* ``$CC`` (or, if unset, ``gcc`` / ``cc`` on ``PATH``) is missing or fails: libraries
  already in the cache are still used, the others are evaluated by the virtual machine.

The cache is checked, never trusted: every library carries a trailer with the
SHA-256 of its bytes, checked before it is loaded (a truncated library would
crash the process in ``dlopen``).  A corrupt entry is rebuilt; a cache folder that
is a file, cannot be created or is not writable is bypassed (the libraries are
built into a private temporary folder removed at exit).

The library is silent: each such fallback is recorded as a one-line note
(:func:`codegen_notes`), which the command line prints once per run.
"""

from __future__ import annotations

import atexit
import ctypes
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
import numpy as np

from .errors import InputError

#: Batches smaller than this run on the calling thread: waking an OpenMP team
#: costs more than it saves, and idle spinning threads slow down IPOPT and NumPy.
PARALLEL_MIN_BATCH = 4096

# Idle OpenMP workers sleep instead of spinning: with GNU OpenMP's default spin-wait,
# idle workers compete with IPOPT/MUMPS and NumPy on small machines (a short batch call
# after an IPOPT solve was measured at ~10 ms instead of ~0.1 ms on 2 CPUs).  Must be set
# before libgomp starts; a user's explicit setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

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
#: Threads of a virtual-machine batch (``Function.map(..., "thread", N)``) by default.
VM_THREADS = 2
#: Mapped functions kept per :class:`VMBatchFunction` (one per batch size).
VM_MAP_CACHE_SIZE = 64

_WRAPPER = r"""
#include <stdlib.h>
#include <omp.h>
int compplan_batch(long long n, const double** ins, const long long* in_stride,
                   double** outs, int n_threads) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  if (%(name)s_work(&sz_arg, &sz_res, &sz_iw, &sz_w)) return 1;
  int fail = 0;
  #pragma omp parallel num_threads(n_threads) reduction(|:fail) if(n >= %(min_batch)d)
  {
    const casadi_real** arg = malloc(sizeof(casadi_real*) * (sz_arg > %(n_in)d ? sz_arg : %(n_in)d));
    casadi_real** res = malloc(sizeof(casadi_real*) * (sz_res > %(n_out)d ? sz_res : %(n_out)d));
    casadi_int* iw = malloc(sizeof(casadi_int) * (sz_iw > 0 ? sz_iw : 1));
    casadi_real* w = malloc(sizeof(casadi_real) * (sz_w > 0 ? sz_w : 1));
    long long i; int k;
    #pragma omp for schedule(static)
    for (i = 0; i < n; ++i) {
      for (k = 0; k < %(n_in)d; ++k) arg[k] = ins[k] + i * in_stride[k];
      for (k = 0; k < %(n_out)d; ++k) res[k] = outs[k] + i * %(out_nnz)s[k];
      if (%(name)s(arg, res, iw, w, 0)) fail = 1;
    }
    free(arg); free(res); free(iw); free(w);
  }
  return fail;
}
"""


class CompileError(RuntimeError):
    """No compiled code: the C compiler is disabled, missing or failed, or its library cannot
    be loaded or stored; the message says which (and :func:`codegen_notes` records it)."""


# ------------------------------------------------------------------------------ notes
_NOTE_COMPILER = "compiler"
_NOTE_CACHE = "cache"
_LOCK = threading.RLock()
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
    with _LOCK:
        return list(_NOTES.values())


def clear_codegen_notes() -> None:
    """Forget the recorded notes (the command line does this at the start of a run)."""
    with _LOCK:
        _NOTES.clear()


def _record(topic: str, message: str) -> None:
    with _LOCK:
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


def _fail(reason: str) -> NoReturn:
    """Record ``reason`` as the virtual-machine note and raise :class:`CompileError`."""
    note_virtual_machine(reason)
    raise CompileError(reason)


def _os_reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _one_line(text: str) -> str:
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
            _fail(f"no C compiler ({label}: not found)")
        cmd = [str(exe), *cmd[1:]]
    else:
        exe = shutil.which("gcc") or shutil.which("cc")
        if exe is None:
            _fail("no C compiler (CC unset, no gcc or cc on PATH)")
        cmd, label = [str(exe)], str(exe)
    with _LOCK:
        failed = _FAILED_COMPILERS.get(tuple(cmd))
    if failed is not None:
        _fail(failed)
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
                reason = _one_line(proc.stderr) or f"exit status {proc.returncode}"
    except OSError as exc:
        reason = _os_reason(exc)
    if reason is not None:
        reason = f"no usable C compiler ({label}: {reason})"
        with _LOCK:
            _FAILED_COMPILERS[tuple(cmd)] = reason
        _fail(reason)
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


#: :func:`_check_library`'s answer for a library that is not there.
_MISSING = "missing"
#: Start of :func:`_check_library`'s answer for a library that cannot be read (a cache problem).
_UNREADABLE = "unreadable"


def _check_library(path: Path) -> str | None:
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
    with _LOCK:
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
    with _LOCK:
        _VERIFIED[str(path)] = sig
    return None


def _store(lib: Path, data: bytes) -> None:
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


def _private_folder() -> Path:
    """This process's folder for libraries built while the cache is bypassed."""
    with _LOCK:
        if not _PRIVATE_DIR:
            folder = Path(tempfile.mkdtemp(prefix="compplan-lib-"))
            atexit.register(shutil.rmtree, folder, True)
            _PRIVATE_DIR.append(folder)
        return _PRIVATE_DIR[0]


def _host_id() -> str:
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
        _fail(disabled)
    key_src = src + " ".join(CFLAGS) + ca.__version__ + _host_id() + f"format{CACHE_FORMAT}"
    name = f"{prefix}_{hashlib.sha256(key_src.encode()).hexdigest()[:20]}.so"
    root = cache_root()
    problem = _cache_problem(root)
    lib = root / name
    corrupt = None
    if problem is None:
        state = _check_library(lib)
        if state is None:
            return lib
        if state.startswith(_UNREADABLE):
            problem = f"is not readable ({state.removeprefix(_UNREADABLE + ': ')})"
        elif state != _MISSING:
            corrupt = state
    with _LOCK:
        private = _PRIVATE_DIR[0] / name if _PRIVATE_DIR else None
    if private is not None and _check_library(private) is None:
        with _LOCK:
            if _BYPASS_NOTE:
                _record(_NOTE_CACHE, _BYPASS_NOTE[0])
        return private
    cmd, label = _compiler()
    data = _build(src, cmd, label)
    if problem is None:
        try:
            _store(lib, data)
        except OSError as exc:
            problem = f"is not writable ({_os_reason(exc)})"
        else:
            if corrupt is not None:
                _record(_NOTE_CACHE, f"cached library {lib} was corrupt ({corrupt}): rebuilt")
            return lib
    try:
        path = _private_folder() / name
        _store(path, data)
    except OSError as exc:
        _fail(f"compile cache {root} {problem} and no temporary folder ({_os_reason(exc)})")
    what = f"compile cache {root} {problem}"
    if corrupt is not None:
        what += f", its {name} corrupt ({corrupt})"
    message = f"{what}: compiled code kept in {path.parent} for this run only (set {CACHE_ENV})"
    with _LOCK:
        _BYPASS_NOTE[:] = [message]
    _record(_NOTE_CACHE, message)
    return path


# ------------------------------------------------------------------------------ batches
def _dense(f: ca.Function) -> ca.Function:
    ins = [ca.SX.sym(f.name_in(k), f.size_in(k)) for k in range(f.n_in())]
    outs = f.call(ins)
    return ca.Function(
        f.name(),
        ins,
        [ca.densify(o) for o in outs],
        [f.name_in(k) for k in range(f.n_in())],
        [f.name_out(k) for k in range(f.n_out())],
    )


def _batch_rows(
    name: str, in_sizes: list[tuple[int, int]], args: tuple[np.ndarray, ...]
) -> tuple[int, list[np.ndarray], list[bool]]:
    """Check and flatten batch inputs.

    Returns
    -------
    n : int
        Batch size.
    arrays : list of ndarray
        Contiguous, shape (N, rows*cols) per batched input, (rows*cols,) per broadcast one.
    batched : list of bool
        Whether each input has one row per pose (False: broadcast).
    """
    if len(args) != len(in_sizes):
        raise InputError(f"{name}: expected {len(in_sizes)} inputs, got {len(args)}")
    n = 1
    arrays, batched = [], []
    for k, a in enumerate(args):
        r, c = in_sizes[k]
        arr = np.asarray(a, dtype=float)
        if arr.ndim == 1:
            if arr.size != r * c:
                raise InputError(f"{name}: input {k} has {arr.size} values, expected {r * c}")
            arr = np.ascontiguousarray(arr)
            batched.append(False)
        else:
            arr = np.ascontiguousarray(arr.reshape(arr.shape[0], int(np.prod(arr.shape[1:]))))
            if arr.shape[1] != r * c:
                raise InputError(f"{name}: input {k} has {arr.shape[1]} columns, expected {r * c}")
            if arr.shape[0] != 1:
                if n not in (1, arr.shape[0]):
                    raise InputError(
                        f"{name}: input {k} has {arr.shape[0]} rows, expected 1 or {n} (the other inputs' rows)"
                    )
                n = arr.shape[0]
            batched.append(True)
        arrays.append(arr)
    if n != 1:  # a one-row input against a larger batch is broadcast (never read past its row)
        for k, arr in enumerate(arrays):
            if batched[k] and arr.shape[0] == 1:
                arrays[k], batched[k] = arr.reshape(-1), False
    return n, arrays, batched


def _batch_outputs(outs: list[np.ndarray], out_sizes: list[tuple[int, int]]) -> list[np.ndarray]:
    """(N, rows*cols) column-major rows -> (N, rows, cols), or (N, rows) for column vectors."""
    n = outs[0].shape[0] if outs else 0
    return [o if c == 1 else o.reshape(n, c, r).transpose(0, 2, 1) for o, (r, c) in zip(outs, out_sizes)]


class BatchFunction:
    """A compiled batch evaluator of a CasADi Function.

    Call with one array per input, shape (N, rows*cols) or (rows*cols,) to
    broadcast (column-major flattening for matrices); returns one array per output,
    shape (N, rows, cols), or (N, rows) for column vectors.

    Raises
    ------
    CompileError
        From the constructor: no compiled code (see :func:`compile_shared_library`).
    """

    #: This evaluator runs compiled C.
    compiled = True

    def __init__(self, f: ca.Function, threads: int = 2) -> None:
        disabled = compiler_disabled()
        if disabled is not None:  # before generating code that will not be compiled
            _fail(disabled)
        fd = _dense(f)
        self._describe(fd, threads)
        cg = ca.CodeGenerator(
            f"{self.name}_cg.c", {"with_header": False, "casadi_real": "double", "casadi_int": "long long int"}
        )
        cg.add(fd)
        src = cg.dump()
        nnz = ", ".join(str(r * c) for r, c in self.out_sizes)
        src += f"\nstatic const long long {self.name}_out_nnz[{self.n_out}] = {{{nnz}}};\n"
        src += _WRAPPER % {
            "name": self.name,
            "n_in": self.n_in,
            "n_out": self.n_out,
            "out_nnz": f"{self.name}_out_nnz",
            "min_batch": PARALLEL_MIN_BATCH,
        }
        self._load(compile_shared_library(src, self.name))

    @classmethod
    def from_library(cls, f: ca.Function, lib: Path, threads: int = 2) -> BatchFunction:
        """The evaluator of ``f`` running a library compiled from it before (e.g. by another
        process, :mod:`models.portable`), without generating or compiling code.

        Raises
        ------
        CompileError
            The library cannot be loaded.
        """
        ev = cls.__new__(cls)
        ev._describe(_dense(f), threads)
        ev._load(Path(lib))
        return ev

    def _describe(self, fd: ca.Function, threads: int) -> None:
        """Name, input and output sizes of the dense function ``fd``; threads of the evaluation."""
        self.name = fd.name()
        self.n_in, self.n_out = fd.n_in(), fd.n_out()
        self.in_sizes = [fd.size_in(k) for k in range(self.n_in)]
        self.out_sizes = [fd.size_out(k) for k in range(self.n_out)]
        self.threads = threads

    def _load(self, lib: Path) -> None:
        """Load the compiled library ``lib`` (its ``compplan_batch`` entry point)."""
        try:
            self._lib = ctypes.CDLL(str(lib))
            fn = self._lib.compplan_batch
        except (OSError, AttributeError) as exc:
            _fail(f"cannot load compiled library {lib} ({_one_line(str(exc))})")
        #: The shared library this evaluator runs.
        self.library = Path(lib)
        fn.restype = ctypes.c_int
        fn.argtypes = [
            ctypes.c_longlong,
            ctypes.POINTER(ctypes.c_void_p),
            ctypes.POINTER(ctypes.c_longlong),
            ctypes.POINTER(ctypes.c_void_p),
            ctypes.c_int,
        ]
        self._fn = fn

    def __call__(self, *args: np.ndarray) -> list[np.ndarray]:
        n, bufs, batched = _batch_rows(self.name, self.in_sizes, args)
        strides = [r * c if b else 0 for (r, c), b in zip(self.in_sizes, batched)]
        outs = [np.empty((n, r * c)) for r, c in self.out_sizes]
        in_ptrs = (ctypes.c_void_p * self.n_in)(*[b.ctypes.data for b in bufs])
        out_ptrs = (ctypes.c_void_p * self.n_out)(*[o.ctypes.data for o in outs])
        st = (ctypes.c_longlong * self.n_in)(*strides)
        if self._fn(n, in_ptrs, st, out_ptrs, self.threads) != 0:
            raise FloatingPointError(f"{self.name}: evaluation failed")
        return _batch_outputs(outs, self.out_sizes)


class VMBatchFunction:
    """The batch evaluator of a CasADi Function on CasADi's virtual machine (no compiler).

    Same call convention and output layout as :class:`BatchFunction` (which it replaces
    when there is no compiled code): ``Function.map(N, "thread", threads)`` over the batch.

    Parameters
    ----------
    f : casadi.Function
    threads : int
        Threads of the mapped evaluation.
    """

    #: This evaluator runs on CasADi's virtual machine.
    compiled = False

    def __init__(self, f: ca.Function, threads: int = VM_THREADS) -> None:
        self.function = f
        self.name = f.name()
        self.n_in, self.n_out = f.n_in(), f.n_out()
        self.in_sizes = [f.size_in(k) for k in range(self.n_in)]
        self.out_sizes = [f.size_out(k) for k in range(self.n_out)]
        self.threads = threads
        self._maps: dict[int, ca.Function] = {}
        self._maps_lock = threading.Lock()

    def _mapped(self, n: int) -> ca.Function:
        with self._maps_lock:
            fm = self._maps.get(n)
            if fm is None:
                fm = self.function.map(n, "thread", self.threads)
                if len(self._maps) >= VM_MAP_CACHE_SIZE:
                    self._maps.clear()
                self._maps[n] = fm
            return fm

    def __call__(self, *args: np.ndarray) -> list[np.ndarray]:
        n, arrays, batched = _batch_rows(self.name, self.in_sizes, args)
        if n == 0:
            return _batch_outputs([np.empty((0, r * c)) for r, c in self.out_sizes], self.out_sizes)
        cols = []
        for arr, b, (r, c) in zip(arrays, batched, self.in_sizes):
            # Pose k's matrix (column-major row k) becomes columns k*c .. k*c + c-1: (r, c*N).
            cols.append(arr.reshape(n * c, r).T if b else arr.reshape(c, r).T)
        res = self._mapped(n).call(cols)
        outs = []
        for x, (r, c) in zip(res, self.out_sizes):
            arr = np.asarray(x, dtype=float).reshape(r, n, c)  # (r, c*N) -> pose-major rows
            outs.append(np.ascontiguousarray(arr.transpose(1, 2, 0)).reshape(n, c * r))
        return _batch_outputs(outs, self.out_sizes)


def compile_batch(f: ca.Function, threads: int = 2) -> BatchFunction:
    """Compile ``f`` for batch evaluation (cached on disk); raises CompileError."""
    return BatchFunction(f, threads)


def batch_function(f: ca.Function, threads: int = 2) -> BatchFunction | VMBatchFunction:
    """The batch evaluator of ``f``: compiled if possible, else CasADi's virtual machine.

    Parameters
    ----------
    f : casadi.Function
    threads : int
        Threads of the evaluation.

    Returns
    -------
    BatchFunction or VMBatchFunction
        Both take the same arguments and return the same layout; ``.compiled`` says which.
        Without compiled code a note is recorded (:func:`codegen_notes`).
    """
    try:
        return BatchFunction(f, threads)
    except CompileError:
        return VMBatchFunction(f, threads)
