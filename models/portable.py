"""Batch evaluators shipped to another process (e.g. a Dask worker) that may have no C compiler.

:func:`portable_state` turns an evaluator of a CasADi Function into plain, picklable data: the
function serialised by CasADi and, for a compiled evaluator, the bytes of its shared library with
the identity of the CPU it was built for (``-march=native``).  :func:`evaluator_from_state`
rebuilds it: the shipped library where this machine's CPU identity matches the builder's, else
CasADi's virtual machine on the serialised function (the same results to rounding, slower).
"""

from __future__ import annotations

import hashlib
import os
from typing import Any

import casadi as ca

from .codegen import BatchFunction, VMBatchFunction
from .compiler import CACHE_LOCK, CompileError, host_id, private_folder


def portable_state(f: ca.Function, evaluator: BatchFunction | VMBatchFunction) -> dict[str, Any]:
    """What rebuilds ``evaluator`` (an evaluator of ``f``) in another process.

    Parameters
    ----------
    f : casadi.Function
        The function ``evaluator`` evaluates.
    evaluator : BatchFunction or VMBatchFunction

    Returns
    -------
    dict
        Plain data (bytes, str, int): picklable.
    """
    compiled = isinstance(evaluator, BatchFunction)
    return {
        "function": f.serialize(),
        "threads": int(evaluator.threads),
        "name": evaluator.name,
        "library": evaluator.library.read_bytes() if compiled else None,
        "host": host_id() if compiled else None,
    }


def evaluator_from_state(state: dict[str, Any], threads: int | None = None) -> BatchFunction | VMBatchFunction:
    """The evaluator described by :func:`portable_state`: the shipped compiled library when this
    machine's CPU identity matches the builder's (written once into this process's private
    temporary folder, named by its SHA-256), else CasADi's virtual machine.

    Parameters
    ----------
    state : dict
        From :func:`portable_state`.
    threads : int, optional
        Threads of the evaluation (default: the state's).
    """
    th = int(state["threads"] if threads is None else threads)
    f = ca.Function.deserialize(state["function"])
    lib = state.get("library")
    if lib is not None and state.get("host") == host_id():
        path = private_folder() / f"{state['name']}_shipped_{hashlib.sha256(lib).hexdigest()[:24]}.so"
        with CACHE_LOCK:
            if not path.exists():
                tmp = path.with_suffix(f".tmp{os.getpid()}")
                tmp.write_bytes(lib)
                os.replace(tmp, path)
        try:
            return BatchFunction.from_library(f, path, th)
        except CompileError:
            pass
    return VMBatchFunction(f, th)


__all__ = ["evaluator_from_state", "portable_state"]
