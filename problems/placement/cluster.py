"""Running a placement sweep's chunks on Dask (``pip install "compplan[dask]"``).

``local:N`` starts a ``dask.distributed.LocalCluster`` of N single-threaded worker processes
(each under a nanny that restarts it if it dies); ``tcp://HOST:PORT`` connects to an existing
cluster.  The kernel is submitted once as a task whose argument is the pickled kernel (it
carries its compiled library, :func:`models.portable.portable_state`), and every chunk is a
task depending on it.  If a worker is lost mid-run, the scheduler re-runs its chunks (and, if
needed, the kernel task) on the remaining or restarted workers; only a chunk whose workers die
more than ``distributed.scheduler.allowed-failures`` times (default 3) fails the sweep.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import os
import time
import uuid
from contextlib import contextmanager
from typing import Any
from collections.abc import Callable, Iterator

import numpy as np

from models.errors import CompplanError, InputError
from problems.placement.kernel import PlacementKernel
from problems.placement.scores import ChunkScores

#: What to install when Dask is missing.
DASK_INSTALL = 'pip install "compplan[dask]"'
#: Seconds to wait for a remote scheduler.
CONNECT_TIMEOUT_S = 20
#: Seconds to wait for a LocalCluster's workers.
LOCAL_START_TIMEOUT_S = 120
#: Re-runs of a chunk whose task raised (worker loss is retried by the scheduler itself).
CHUNK_RETRIES = 2
#: Environment variables Dask's nanny sets by default that a LocalCluster of ours does not:
#: ``MALLOC_TRIM_THRESHOLD_`` turns off glibc's dynamic mmap threshold, so every large array a
#: chunk allocates is mapped and faulted in afresh (measured: a worker then scores 25 % slower
#: than the serial sweep, its system time tripled; without it the two are equal).
LOCAL_ENV_DROPPED = ("MALLOC_TRIM_THRESHOLD_",)


class ClusterError(CompplanError):
    """The cluster failed the sweep (a chunk kept killing its workers, or the cluster went away)."""


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
    scheduler address."""
    distributed = require_dask()
    if spec.startswith("local:"):
        import dask

        n = int(spec.split(":", 1)[1])
        # A None value unsets the nanny's variable (distributed.nanny._get_env_variables); a value
        # an earlier nanny of this process wrote into os.environ before spawning would still be
        # inherited, so it is lifted while this cluster (and any worker it restarts) lives.
        lifted = {k: os.environ.pop(k) for k in LOCAL_ENV_DROPPED if k in os.environ}
        try:
            with dask.config.set({f"distributed.nanny.pre-spawn-environ.{k}": None for k in LOCAL_ENV_DROPPED}):
                cluster = distributed.LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            client = distributed.Client(cluster, timeout=LOCAL_START_TIMEOUT_S)
            try:
                client.wait_for_workers(n, timeout=LOCAL_START_TIMEOUT_S)
                yield client
            finally:
                client.close()
                cluster.close()
        finally:
            os.environ.update(lifted)
    else:
        try:
            client = distributed.Client(spec, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise InputError(
                f"--scheduler {spec}: cannot connect to a Dask scheduler there "
                f"({type(exc).__name__}: {_first_line(exc) if str(exc) else 'timed out'})"
            ) from None
        try:
            yield client
        finally:
            client.close()


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else "no message"


@contextmanager
def _quiet(prefix: str = "distributed") -> Iterator[None]:
    """Dask's own log records (e.g. the tracebacks of a lost connection) are not printed while a
    sweep runs: the library is silent, and the sweep's outcome is its result or one exception.
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
    """Import the kernel on every worker; the number of workers.

    Raises
    ------
    InputError
        A worker cannot import compplan, or runs another version of it than this process.
    """
    if not client.scheduler_info().get("workers"):
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except (TimeoutError, OSError):
            raise InputError(
                f"--scheduler {spec}: the scheduler has no workers (none joined within "
                f"{CONNECT_TIMEOUT_S} s); start workers with: dask worker {spec}"
            ) from None
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


def _evaluate(k: PlacementKernel, chunk: np.ndarray) -> ChunkScores:
    return k.evaluate(chunk)


def run_on_dask(
    kernel: PlacementKernel,
    chunks: list[np.ndarray],
    spec: str,
    progress: Callable[[str, int, int], None] | None,
    on_chunk: Callable[[int], None] | None,
) -> tuple[list[ChunkScores], float, int, dict[str, Any]]:
    """Score the chunks on a Dask cluster.

    Returns
    -------
    parts : list of ChunkScores
        In chunk order.
    elapsed_s : float
        From the first submission (the kernel's) to the last result, s; the workers' one-time
        import of the package is done before.
    workers : int
        Workers that ran at least one chunk.
    extra : dict
        ``workers_at_start``.
    """
    from problems.placement.sweep import PROGRESS_STAGE

    distributed = require_dask()
    ppp = kernel.poses_per_placement
    total = sum(len(c) for c in chunks) * ppp
    token = uuid.uuid4().hex[:12]
    with _quiet(), dask_client(spec) as client:
        at_start = check_workers(client, spec)
        t0 = time.perf_counter()
        kf = client.submit(_kernel, kernel, key=f"placement-kernel-{token}", pure=False)
        futs = [
            client.submit(_evaluate, kf, c, key=f"placement-chunk-{token}-{i}", pure=False, retries=CHUNK_RETRIES)
            for i, c in enumerate(chunks)
        ]
        index = {f.key: i for i, f in enumerate(futs)}
        parts: list[ChunkScores | None] = [None] * len(chunks)
        who: set[str] = set()
        done_poses = 0
        try:
            for n_done, fut in enumerate(distributed.as_completed(futs, loop=client.loop), start=1):
                i = index[fut.key]
                parts[i] = fut.result()
                done_poses += len(chunks[i]) * ppp
                if progress is not None:
                    progress(PROGRESS_STAGE, done_poses, total)
                if on_chunk is not None:
                    on_chunk(n_done)
        except distributed.KilledWorker as exc:
            raise ClusterError(f"Dask sweep failed: a chunk's workers died repeatedly ({exc})") from None
        except (OSError, concurrent.futures.CancelledError, asyncio.CancelledError) as exc:
            raise ClusterError(
                f"Dask sweep failed: the cluster at {spec} went away during the sweep "
                f"({type(exc).__name__}: {_first_line(exc)})"
            ) from None
        elapsed = time.perf_counter() - t0
        try:
            for ws in client.who_has(futs).values():
                who.update(ws)
        except Exception:
            pass
        for f in futs + [kf]:
            f.release()
    return (
        [p for p in parts if p is not None],
        elapsed,
        max(1, len(who)) if who else at_start,
        {"workers_at_start": at_start},
    )


__all__ = [
    "CHUNK_RETRIES",
    "ClusterError",
    "DASK_INSTALL",
    "LOCAL_ENV_DROPPED",
    "check_workers",
    "dask_client",
    "require_dask",
    "run_on_dask",
]
