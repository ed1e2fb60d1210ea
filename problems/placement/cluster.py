"""Running a placement sweep's chunks on Dask (``pip install "compplan[dask]"``).

``local:N`` starts a ``dask.distributed.LocalCluster`` of N single-threaded worker processes
(each under a nanny that restarts it if it dies; a Ctrl-C reaches the client only, which closes
the cluster: :func:`_sigint_blocked_in_new_threads`); ``tcp://HOST:PORT`` connects to an
existing cluster.  The kernel is submitted once as a task whose argument is the pickled kernel
(it carries its compiled library, :func:`models.portable.portable_state`), and every chunk is a
task depending on it.  If a worker is lost mid-run, the scheduler re-runs its chunks (and, if
needed, the kernel task) on the remaining or restarted workers; only a chunk whose workers die
more than ``distributed.scheduler.allowed-failures`` times (default 3) fails the sweep.  A
cluster with no live worker for :data:`WORKER_WAIT_S` (none joined, or all died and none came
back) fails it too: the sweep ends with a status and a one-line reason, never waits forever.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import multiprocessing.resource_tracker
import os
import signal
import time
import uuid
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Callable, Iterator

import numpy as np

from models import interrupts
from models.errors import CompplanError, InputError
from problems.placement.kernel import PlacementKernel
from problems.placement.scores import ChunkScores
from problems.placement.sweep_status import PROGRESS_STAGE, SweepStatus

#: What to install when Dask is missing.
DASK_INSTALL = 'pip install "compplan[dask]"'
#: Seconds to wait for a remote scheduler.
CONNECT_TIMEOUT_S = 20
#: Seconds to wait for a LocalCluster's workers.
LOCAL_START_TIMEOUT_S = 120
#: Seconds a sweep waits while the cluster has no live worker (none joined yet, or all died)
#: before it ends with status ``no workers``: a nanny restarts a dead worker in a few seconds, so
#: only a cluster whose workers are gone for good waits this long.
WORKER_WAIT_S = 30
#: Seconds between the sweep's checks that the cluster still has a worker, while no chunk
#: completes (one request to the scheduler each).
LIVENESS_POLL_S = 1.0
#: Seconds between looks for completed chunks (the most a result waits to be collected).
RESULT_POLL_S = 0.05
#: Seconds to close the client, and to stop a LocalCluster (a worker still alive then exits with
#: this process: its nanny watches it).
CLOSE_TIMEOUT_S = 10
#: The HTTP server of a LocalCluster's scheduler (health routes; the dashboard is off) listens on
#: a free local port: Dask's default 8787 may be taken (another cluster), and it then warns on stderr.
LOCAL_HTTP_ADDRESS = "127.0.0.1:0"
#: Re-runs of a chunk whose task raised (worker loss is retried by the scheduler itself).
CHUNK_RETRIES = 2
#: Environment variables Dask's nanny sets by default that a LocalCluster of ours does not:
#: ``MALLOC_TRIM_THRESHOLD_`` turns off glibc's dynamic mmap threshold, so every large array a
#: chunk allocates is mapped and faulted in afresh (measured: a worker then scores 25 % slower
#: than the serial sweep, its system time tripled; without it the two are equal).
LOCAL_ENV_DROPPED = ("MALLOC_TRIM_THRESHOLD_",)


class ClusterError(CompplanError):
    """A sweep on a cluster did not complete (no live worker, a chunk kept killing its workers, or
    the cluster went away): what ``compplan place`` raises for such a sweep's status."""


def require_dask() -> Any:
    """``distributed``, or an InputError saying how to install it."""
    try:
        import distributed
    except ImportError:
        raise InputError(
            f"--scheduler needs Dask, which is not installed: {DASK_INSTALL} "
            "(without it, run the sweep serially: omit --scheduler)"
        ) from None
    return distributed


@contextmanager
def dask_client(spec: str) -> Iterator[Any]:
    """A ``distributed.Client`` for ``local:N`` (a LocalCluster it starts and stops) or a
    scheduler address.  Both are closed on the way out, also on an error or a Ctrl-C, within
    :data:`CLOSE_TIMEOUT_S` each.

    Raises
    ------
    InputError
        No Dask scheduler answers at the address within :data:`CONNECT_TIMEOUT_S`.
    """
    distributed = require_dask()
    if spec.startswith("local:"):
        n = int(spec.split(":", 1)[1])
        with _local_cluster(n) as cluster:
            client = None
            try:
                client = distributed.Client(cluster, timeout=LOCAL_START_TIMEOUT_S)
                client.wait_for_workers(n, timeout=LOCAL_START_TIMEOUT_S)
                yield client
            finally:
                _close(client)
    else:
        try:
            client = distributed.Client(spec, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise InputError(
                f"--scheduler {spec}: cannot connect to a Dask scheduler there "
                f"({type(exc).__name__}: {_first_line(exc) if str(exc) else 'timed out'}); "
                "start one (dask scheduler) or run on this machine with --scheduler local:N"
            ) from None
        try:
            yield client
        finally:
            _close(client)


@contextmanager
def _local_cluster(n: int) -> Iterator[Any]:
    """A LocalCluster of ``n`` single-threaded worker processes that a Ctrl-C does not reach
    (:func:`_sigint_blocked_in_new_threads`), stopped on the way out."""
    import dask

    distributed = require_dask()
    # A None value unsets the nanny's variable (distributed.nanny._get_env_variables); a value
    # an earlier nanny of this process wrote into os.environ before spawning would still be
    # inherited, so it is lifted while this cluster (and any worker it restarts) lives.
    lifted = {k: os.environ.pop(k) for k in LOCAL_ENV_DROPPED if k in os.environ}
    cluster = None
    try:
        with (
            dask.config.set({f"distributed.nanny.pre-spawn-environ.{k}": None for k in LOCAL_ENV_DROPPED}),
            _sigint_blocked_in_new_threads(),
        ):
            cluster = distributed.LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                scheduler_kwargs={"dashboard_address": LOCAL_HTTP_ADDRESS},
                silence_logs=logging.ERROR,
            )
        yield cluster
    finally:
        try:
            _close(cluster)
        finally:
            os.environ.update(lifted)


@contextmanager
def _sigint_blocked_in_new_threads() -> Iterator[None]:
    """SIGINT blocked in this thread, so in the threads started inside (the LocalCluster's event
    loop and the nannies' process watchers, which spawn the worker processes, also those that
    replace a dead worker later) and in the worker processes (a signal mask survives fork and
    exec; Python does not unblock it).

    A Ctrl-C at a terminal sends SIGINT to the whole foreground process group: without this,
    each worker process would end on a ``KeyboardInterrupt`` and print its traceback on the shared
    stderr.  With it, only this process is interrupted, and it stops the cluster.  A Ctrl-C while
    the cluster starts is delivered when this thread unblocks it.  Multiprocessing's resource
    tracker is started first: starting it unblocks SIGINT in the thread that does."""
    if not hasattr(signal, "pthread_sigmask"):  # not POSIX
        yield
        return
    multiprocessing.resource_tracker.ensure_running()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _close(thing: Any) -> None:
    """Close a client or a cluster (None: nothing), within :data:`CLOSE_TIMEOUT_S`.

    A failure to close is not the sweep's outcome (workers still alive then are killed with their
    cluster, or exit with this process), so it is dropped.  A Ctrl-C while closing (a second one,
    typically) is held until the close is done, then raised: interrupted half-way, the close would
    be finished by Dask at the interpreter's exit, which waits for the workers far longer."""
    if thing is None:
        return
    with interrupts.deferred():
        try:
            thing.close(timeout=CLOSE_TIMEOUT_S)
        except Exception:  # closing is best effort, see above
            pass


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else "no message"


@contextmanager
def _quiet(prefix: str = "distributed") -> Iterator[None]:
    """Dask's own log records (e.g. the tracebacks of a lost connection) are not printed while a
    sweep runs, nor while its cluster is closed: the library is silent, and the sweep's outcome is
    its result (a status and a one-line reason).
    Dask's configuration gives some of its loggers levels of their own (``distributed.client``),
    so each is raised, and restored afterwards."""
    names = [prefix] + [n for n in list(logging.root.manager.loggerDict) if n.startswith(prefix + ".")]
    saved = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for n, level in saved.items():
            logging.getLogger(n).setLevel(level)


def _kernel(k: PlacementKernel) -> PlacementKernel:
    """The kernel task: its argument arrives unpickled on the worker (library loaded there)."""
    return k


def _installed_version() -> str:
    """The compplan version installed in this process's environment (``unknown`` if none is)."""
    from importlib import metadata

    try:
        return metadata.version("compplan")
    except metadata.PackageNotFoundError:
        return "unknown"


def _warm_import() -> str:
    """Import the kernel's modules on a worker (once per worker process, before timing) and say
    which compplan the worker has."""
    import problems.placement.kernel  # noqa: F401 - imported for its cost, paid before timing

    return _installed_version()


def check_workers(client: Any, spec: str) -> int:
    """Import the kernel on every worker; the number of workers (0: none joined within
    :data:`WORKER_WAIT_S`).

    Raises
    ------
    InputError
        A worker cannot import compplan, or runs another version of it than this process.
    """
    if not client.scheduler_info().get("workers"):
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        except (TimeoutError, OSError):
            return 0
    try:
        versions = client.run(_warm_import)
    except Exception as exc:
        raise InputError(
            f"--scheduler {spec}: the Dask workers cannot import compplan "
            f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
            "install the same compplan on every worker"
        ) from None
    here = _installed_version()
    other = sorted({f"{v} on {w}" for w, v in versions.items() if v != here})
    if other:
        raise InputError(
            f"--scheduler {spec}: the workers run another compplan than this process ({here}): "
            f"{', '.join(other[:3])}{' ...' if len(other) > 3 else ''}; install {here} on every worker"
        )
    return len(versions)


def _no_workers_reason(spec: str, done: int | None, n_chunks: int) -> str:
    """One line: no worker alive (``done`` None: none joined; else the chunks scored before),
    and what to do."""
    if done is None:
        what = f"no Dask worker joined the scheduler within {WORKER_WAIT_S:g} s"
    else:
        what = (
            f"no Dask worker alive for {WORKER_WAIT_S:g} s: the workers died after {done} of "
            f"{n_chunks} chunks were scored"
        )
    todo = (
        "a worker that keeps dying may be out of memory: try a smaller --chunk"
        if spec.startswith("local:")
        else f"start workers with: dask worker {spec} --nthreads 1, or run on this machine with --scheduler local:N"
    )
    return f"--scheduler {spec}: {what}; {todo}"


@dataclass
class DaskRun:
    """What a sweep on Dask gave.

    Attributes
    ----------
    status : SweepStatus
        ``OK`` (every chunk scored), ``NO_WORKERS`` or ``CLUSTER_FAILED``.
    reason : str
        One line; empty when ``OK``.
    parts : list of ChunkScores
        Every chunk's scores in chunk order when ``OK``; else empty.
    elapsed_s : float
        From the first submission (the kernel's) to the last result, s; the workers' one-time
        import of the package is done before.
    workers : int
        Workers that ran at least one chunk.
    workers_at_start : int
    chunks_done : int
        Chunks scored (all when ``OK``).
    """

    status: SweepStatus
    reason: str
    parts: list[ChunkScores] = field(default_factory=list)
    elapsed_s: float = 0.0
    workers: int = 0
    workers_at_start: int = 0
    chunks_done: int = 0

    @property
    def ok(self) -> bool:
        return self.status is SweepStatus.OK


def _evaluate(k: PlacementKernel, chunk: np.ndarray) -> ChunkScores:
    return k.evaluate(chunk)


def run_on_dask(
    kernel: PlacementKernel,
    chunks: list[np.ndarray],
    spec: str,
    progress: Callable[[str, int, int], None] | None,
    on_chunk: Callable[[int], None] | None,
) -> DaskRun:
    """Score the chunks on a Dask cluster.

    Returns
    -------
    DaskRun
        ``NO_WORKERS`` when the cluster has no live worker for :data:`WORKER_WAIT_S` (none
        joined, or all died and none came back): the remaining chunks are cancelled;
        ``CLUSTER_FAILED`` when a chunk's workers died more than
        ``distributed.scheduler.allowed-failures`` times, or the scheduler went away.

    Raises
    ------
    InputError
        No scheduler at the address; workers without compplan or with another version.
    """
    token = uuid.uuid4().hex[:12]
    with _quiet(), dask_client(spec) as client:
        at_start = check_workers(client, spec)
        if not at_start:
            return DaskRun(SweepStatus.NO_WORKERS, _no_workers_reason(spec, None, len(chunks)))
        t0 = time.perf_counter()
        kf = client.submit(_kernel, kernel, key=f"placement-kernel-{token}", pure=False)
        futs = [
            client.submit(_evaluate, kf, c, key=f"placement-chunk-{token}-{i}", pure=False, retries=CHUNK_RETRIES)
            for i, c in enumerate(chunks)
        ]
        run = _collect(client, futs, chunks, spec, kernel.poses_per_placement, progress, on_chunk)
        run.elapsed_s, run.workers_at_start = time.perf_counter() - t0, at_start
        if run.ok:
            who: set[str] = set()
            try:
                for ws in client.who_has(futs).values():
                    who.update(ws)
            except Exception:  # who ran the chunks is a figure, not the outcome
                pass
            run.workers = max(1, len(who)) if who else at_start
        elif run.status is SweepStatus.NO_WORKERS:
            try:
                client.cancel(futs + [kf])
            except Exception:  # the client is closed next in any case
                pass
        for f in futs + [kf]:
            f.release()
    return run


def _collect(
    client: Any,
    futs: list[Any],
    chunks: list[np.ndarray],
    spec: str,
    ppp: int,
    progress: Callable[[str, int, int], None] | None,
    on_chunk: Callable[[int], None] | None,
) -> DaskRun:
    """The chunks' results as they complete; while none arrives, the scheduler is asked every
    :data:`LIVENESS_POLL_S` whether a worker is alive, and after :data:`WORKER_WAIT_S` without
    one the run ends (``NO_WORKERS``)."""
    distributed = require_dask()
    index = {f.key: i for i, f in enumerate(futs)}
    parts: list[ChunkScores | None] = [None] * len(chunks)
    total = sum(len(c) for c in chunks) * ppp
    done = done_poses = 0
    ac = distributed.as_completed(futs, loop=client.loop)
    alive_at = checked_at = time.monotonic()
    try:
        while not ac.is_empty():
            got = _fetch(ac, ac.next_batch(block=False))
            for fut, part in got:
                i = index[fut.key]
                parts[i] = part
                done += 1
                done_poses += len(chunks[i]) * ppp
                if progress is not None:
                    progress(PROGRESS_STAGE, done_poses, total)
                if on_chunk is not None:
                    on_chunk(done)
            now = time.monotonic()
            if got:
                alive_at = checked_at = now
                continue
            if now - checked_at >= LIVENESS_POLL_S:
                checked_at = now
                if client.nthreads():
                    alive_at = now
                elif now - alive_at >= WORKER_WAIT_S:
                    reason = _no_workers_reason(spec, done, len(chunks))
                    return DaskRun(SweepStatus.NO_WORKERS, reason, chunks_done=done)
            time.sleep(RESULT_POLL_S)
    except distributed.KilledWorker as exc:
        reason = f"Dask sweep failed: a chunk's workers died repeatedly ({_first_line(exc)})"
        return DaskRun(SweepStatus.CLUSTER_FAILED, reason, chunks_done=done)
    except (OSError, concurrent.futures.CancelledError, asyncio.CancelledError) as exc:
        reason = (
            f"Dask sweep failed: the cluster at {spec} went away during the sweep "
            f"({type(exc).__name__}: {_first_line(exc)})"
        )
        return DaskRun(SweepStatus.CLUSTER_FAILED, reason, chunks_done=done)
    return DaskRun(SweepStatus.OK, "", [p for p in parts if p is not None], chunks_done=done)


def _fetch(ac: Any, batch: list[Any]) -> list[tuple[Any, ChunkScores]]:
    """The results of a batch of completed chunks.  A result that does not arrive within
    :data:`LIVENESS_POLL_S` was lost with its worker (the scheduler computes it again, if a worker
    is left): it and the rest of the batch go back to ``ac`` (``as_completed``), which hands them
    out again once complete, and the caller checks that a worker is alive."""
    got = []
    for n, fut in enumerate(batch):
        try:
            got.append((fut, fut.result(timeout=LIVENESS_POLL_S)))
        except TimeoutError:  # before the OSError of a lost cluster: TimeoutError is one
            ac.update(batch[n:])
            break
    return got


__all__ = [
    "ClusterError",
    "LOCAL_ENV_DROPPED",
    "WORKER_WAIT_S",
    "dask_client",
    "require_dask",
    "run_on_dask",
]
