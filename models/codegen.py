"""Compile a CasADi Function to C once and evaluate it over batches from NumPy.

CasADi's own ``map`` converts every argument to a ``DM`` and runs the SX
virtual machine; for kinematics over millions of poses that costs far more than
the arithmetic.  Here the function's generated C code is wrapped in a small
OpenMP loop, compiled once with the system C compiler into a shared library
cached under ``$COMPPLAN_CACHE`` (default ``~/.cache/compplan``, keyed by a hash
of the source), and called through :mod:`ctypes` on NumPy buffers directly.

If no C compiler is available, :func:`compile_batch` raises
:class:`CompileError`; :class:`models.symbolic.KinematicModel` then falls back
to ``Function.map``.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

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
    """The C compiler is missing or failed; the message says which."""


def _cache_dir() -> Path:
    root = os.environ.get("COMPPLAN_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "compplan")
    p = Path(root)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CompileError(f"cache folder {p} is not usable ({exc}); set COMPPLAN_CACHE") from None
    return p


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

    The cache key hashes the source, the flags, the CasADi version and the host
    CPU.  Concurrent builds of the same library race safely (atomic rename).

    Raises
    ------
    CompileError
        No compiler, a compiler failure, or an unusable cache folder.
    """
    key = hashlib.sha256((src + " ".join(CFLAGS) + ca.__version__ + _host_id()).encode()).hexdigest()[:20]
    lib = _cache_dir() / f"{prefix}_{key}.so"
    if lib.exists():
        return lib
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        raise CompileError("no C compiler found (set CC or install gcc)")
    try:
        with tempfile.TemporaryDirectory() as tmp:
            c_file = Path(tmp) / "f.c"
            c_file.write_text(src)
            tmp_lib = Path(tmp) / "f.so"
            proc = subprocess.run([cc, *CFLAGS, str(c_file), "-o", str(tmp_lib), "-lm"],
                                  capture_output=True, text=True)
            if proc.returncode != 0:
                raise CompileError(f"{cc} failed: {proc.stderr.strip()[:500]}")
            fd, staged = tempfile.mkstemp(dir=lib.parent, suffix=".so")
            os.close(fd)
            shutil.copyfile(tmp_lib, staged)
            os.replace(staged, lib)
    except OSError as exc:
        raise CompileError(f"cannot build {lib.name} in {lib.parent}: {exc}") from None
    return lib


def _dense(f: ca.Function) -> ca.Function:
    ins = [ca.SX.sym(f.name_in(k), f.size_in(k)) for k in range(f.n_in())]
    outs = f.call(ins)
    return ca.Function(f.name(), ins, [ca.densify(o) for o in outs],
                       [f.name_in(k) for k in range(f.n_in())],
                       [f.name_out(k) for k in range(f.n_out())])


class BatchFunction:
    """A compiled batch evaluator of a CasADi Function.

    Call with one array per input, shape (N, rows*cols) or (rows*cols,) to
    broadcast (column-major flattening for matrices); returns one array per output,
    shape (N, rows, cols), or (N, rows) for column vectors.
    """

    def __init__(self, f: ca.Function, threads: int = 2) -> None:
        fd = _dense(f)
        self.name = fd.name()
        self.n_in, self.n_out = fd.n_in(), fd.n_out()
        self.in_sizes = [fd.size_in(k) for k in range(self.n_in)]
        self.out_sizes = [fd.size_out(k) for k in range(self.n_out)]
        self.threads = threads
        cg = ca.CodeGenerator(f"{self.name}_cg.c", {"with_header": False, "casadi_real": "double",
                                                     "casadi_int": "long long int"})
        cg.add(fd)
        src = cg.dump()
        nnz = ", ".join(str(r * c) for r, c in self.out_sizes)
        src += f"\nstatic const long long {self.name}_out_nnz[{self.n_out}] = {{{nnz}}};\n"
        src += _WRAPPER % {"name": self.name, "n_in": self.n_in, "n_out": self.n_out,
                           "out_nnz": f"{self.name}_out_nnz", "min_batch": PARALLEL_MIN_BATCH}
        lib = compile_shared_library(src, self.name)
        self._lib = ctypes.CDLL(str(lib))
        fn = self._lib.compplan_batch
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_longlong, ctypes.POINTER(ctypes.c_void_p),
                       ctypes.POINTER(ctypes.c_longlong), ctypes.POINTER(ctypes.c_void_p), ctypes.c_int]
        self._fn = fn

    def __call__(self, *args: np.ndarray) -> list[np.ndarray]:
        if len(args) != self.n_in:
            raise ValueError(f"{self.name}: expected {self.n_in} inputs, got {len(args)}")
        n = 1
        bufs = []
        strides = []
        for k, a in enumerate(args):
            r, c = self.in_sizes[k]
            arr = np.asarray(a, dtype=float)
            if arr.ndim == 1:
                if arr.size != r * c:
                    raise ValueError(f"{self.name}: input {k} must have {r * c} values, got {arr.size}")
                arr = np.ascontiguousarray(arr)
                strides.append(0)
            else:
                arr = np.ascontiguousarray(arr.reshape(arr.shape[0], -1))
                if arr.shape[1] != r * c:
                    raise ValueError(f"{self.name}: input {k} must have {r * c} columns, got {arr.shape[1]}")
                if n not in (1, arr.shape[0]):
                    raise ValueError(f"{self.name}: inputs have {n} and {arr.shape[0]} rows")
                n = arr.shape[0]
                strides.append(r * c)
            bufs.append(arr)
        outs = [np.empty((n, r * c)) for r, c in self.out_sizes]
        in_ptrs = (ctypes.c_void_p * self.n_in)(*[b.ctypes.data for b in bufs])
        out_ptrs = (ctypes.c_void_p * self.n_out)(*[o.ctypes.data for o in outs])
        st = (ctypes.c_longlong * self.n_in)(*strides)
        if self._fn(n, in_ptrs, st, out_ptrs, self.threads) != 0:
            raise FloatingPointError(f"{self.name}: evaluation failed")
        result = []
        for o, (r, c) in zip(outs, self.out_sizes):
            result.append(o if c == 1 else o.reshape(n, c, r).transpose(0, 2, 1))
        return result


def compile_batch(f: ca.Function, threads: int = 2) -> BatchFunction:
    """Compile ``f`` for batch evaluation (cached on disk); raises CompileError."""
    return BatchFunction(f, threads)
