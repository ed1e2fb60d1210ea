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

The compiler, the checked cache and the notes are :mod:`models.compiler`'s; this module holds the
batch evaluators.
"""

from __future__ import annotations

import ctypes
import os
import threading
from pathlib import Path

import casadi as ca
import numpy as np

# the compiler's names its callers import from here (models.compiler owns them)
from .compiler import CompileError as CompileError
from .compiler import cache_root as cache_root
from .compiler import clear_codegen_notes as clear_codegen_notes
from .compiler import codegen_notes as codegen_notes
from .compiler import compile_shared_library as compile_shared_library
from .compiler import compiler_disabled, no_compiled_code, one_line
from .compiler import note_virtual_machine as note_virtual_machine
from .errors import InputError

#: Batches smaller than this run on the calling thread: waking an OpenMP team
#: costs more than it saves, and idle spinning threads slow down IPOPT and NumPy.
PARALLEL_MIN_BATCH = 4096

# Idle OpenMP workers sleep instead of spinning: with GNU OpenMP's default spin-wait,
# idle workers compete with IPOPT/MUMPS and NumPy on small machines (a short batch call
# after an IPOPT solve was measured at ~10 ms instead of ~0.1 ms on 2 CPUs).  Must be set
# before libgomp starts; a user's explicit setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

#: Every batch evaluation on the calling thread (:func:`single_threaded`): set in a forked worker
#: process, whose OpenMP runtime (GNU libgomp is not fork-safe) must not start a team.
_SINGLE_THREAD = False


def single_threaded() -> None:
    """From now on, evaluate every batch function on the calling thread (no OpenMP team, no
    CasADi threads). For a process forked from one that has used OpenMP: GNU libgomp's thread pool
    does not survive a fork, and a team started in the child waits for threads that do not exist."""
    global _SINGLE_THREAD
    _SINGLE_THREAD = True


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
            no_compiled_code(disabled)
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
            no_compiled_code(f"cannot load compiled library {lib} ({one_line(str(exc))})")
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
        threads = self.threads if _SINGLE_THREAD is False else 1
        if self._fn(n, in_ptrs, st, out_ptrs, threads) != 0:
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
                fm = self.function.map(n, "thread", self.threads if _SINGLE_THREAD is False else 1)
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
