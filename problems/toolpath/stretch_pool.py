"""A program's stretches timed in parallel: the same function over every stretch, in forked worker
processes when there are many (each stretch between two stops is timed on its own, rest to rest, so
the stretches are independent; ``problems.toolpath.feed``).

The number of workers is ``$COMPPLAN_WORKERS`` when set (an integer >= 1; 1: in this process),
else the machine's CPU count capped at :data:`MAX_WORKERS`; fewer than
:data:`PARALLEL_MIN_STRETCHES` stretches, or a platform without ``fork``, are timed in this process.
The workers are forked, so they share the stretches' data and the arm model without pickling; they
ignore Ctrl-C (SIGINT), which the calling process receives and answers by terminating the pool,
and evaluate the compiled batch functions on their own thread (GNU OpenMP does not survive a fork:
a team started in a worker of a parent that had used one waited forever).
The results come back in the stretches' order, so the trajectory is the same as in one process.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from models.errors import InputError

__all__ = ["MAX_WORKERS", "PARALLEL_MIN_STRETCHES", "WORKERS_ENV", "map_stretches", "worker_count"]

#: The environment variable that sets the number of worker processes.
WORKERS_ENV = "COMPPLAN_WORKERS"
#: Most workers by default (beyond, the joining and the pickling of the results dominate).
MAX_WORKERS = 8
#: Fewer stretches than this are timed in this process (a pool costs ~0.1 s to start).
PARALLEL_MIN_STRETCHES = 64
#: Stretches handed to a worker at a time.
CHUNK = 8

#: The function and its shared data while a pool runs (set before the fork, read by the workers).
_SHARED: tuple[Callable[[Any, Any], Any], Any] | None = None


def worker_count(n_jobs: int) -> int:
    """The worker processes for ``n_jobs`` stretches (1: in this process).

    Raises
    ------
    InputError
        ``$COMPPLAN_WORKERS`` is set but not an integer >= 1.
    """
    raw = os.environ.get(WORKERS_ENV)
    if raw is not None and raw.strip():
        try:
            wanted = int(raw)
        except ValueError:
            wanted = 0
        if wanted < 1:
            raise InputError(f"${WORKERS_ENV} is {raw!r}; expected an integer >= 1 (1: no worker processes)")
    else:
        wanted = min(os.cpu_count() or 1, MAX_WORKERS)
    if n_jobs < PARALLEL_MIN_STRETCHES or "fork" not in multiprocessing.get_all_start_methods():
        return 1
    return max(1, min(wanted, n_jobs))


def _worker_init() -> None:
    """A worker: Ctrl-C is the calling process's to answer, SIGTERM (the pool's ``terminate``) ends
    it at once without a traceback (not the command's handler it was forked with), and no OpenMP
    team is started (GNU libgomp's threads do not survive the fork:
    :func:`models.codegen.single_threaded`)."""
    from models.codegen import single_threaded
    from models.interrupts import forked_worker_signals

    forked_worker_signals()
    single_threaded()


def _call(job: Any) -> Any:
    assert _SHARED is not None
    fn, shared = _SHARED
    return fn(shared, job)


def map_stretches(fn: Callable[[Any, Any], Any], shared: Any, jobs: Sequence[Any]) -> Iterator[Any]:
    """``fn(shared, job)`` for every job, in order: in this process or in a pool of forked workers
    (:func:`worker_count`). ``fn`` must be a module-level function."""
    global _SHARED
    workers = worker_count(len(jobs))
    if workers <= 1:
        for job in jobs:
            yield fn(shared, job)
        return
    _SHARED = (fn, shared)
    try:
        with multiprocessing.get_context("fork").Pool(workers, initializer=_worker_init) as pool:
            yield from pool.imap(_call, jobs, chunksize=CHUNK)
    finally:
        _SHARED = None
