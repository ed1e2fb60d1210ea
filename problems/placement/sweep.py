"""A placement sweep: the grid cut into chunks, each scored by the kernel, serially or on Dask.

The chunks are the same in every mode (:func:`chunk_bounds`: consecutive placements, a fixed
number per chunk) and every chunk runs the same :meth:`PlacementKernel.evaluate
<problems.placement.kernel.PlacementKernel.evaluate>` with one thread, so a sweep on a Dask
cluster gives the serial sweep's scores bit for bit (same chunking, same compiled code;
``tests/test_placement_dask.py`` checks it).
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Callable

import numpy as np

from models.errors import InputError
from problems.placement.kernel import PlacementKernel
from problems.placement.scores import ChunkScores, PlacementStatus
from problems.placement.sweep_status import PROGRESS_STAGE, Progress, SweepStatus

#: Fewest TCP poses per chunk (one Dask task) by default: Dask's per-task overhead (a few ms,
#: ``benchmarks/bench_placement.py``) stays a few per cent of a chunk's cost (about 5 us per pose),
#: and a sweep of a few thousand placements still spreads over a few workers.
CHUNK_POSES = 32_768
#: Most chunks of a default chunking: a large sweep gets larger chunks, so the per-task overhead
#: and the scheduler's serial handling of tasks stay small against the work (docs/placement.md).
DEFAULT_MAX_CHUNKS = 1000
#: Most TCP poses per chunk by default: a chunk's memory (about 2.5 kB per pose at its peak,
#: about 650 MiB here) bounds it.
CHUNK_MAX_POSES = 262_144
#: Fewest and most placements in one chunk.
CHUNK_MIN_PLACEMENTS, CHUNK_MAX_PLACEMENTS = 1, 100_000


@dataclass
class SweepResult:
    """Scores of every placement of a sweep.

    Attributes
    ----------
    status : SweepStatus
    reason : str
        One line; empty when ``OK``.
    placements : ndarray, shape (P, 5)
        ``[x, y, z, yaw, tilt]`` (m, rad), grid order.
    scores : ChunkScores
        One row per placement; none when the sweep did not complete (not :attr:`scored`).
    poses : int
        TCP poses evaluated (placements x waypoints x scanned orientations), each on every branch.
    chunk_placements : int
        Placements per chunk.
    n_chunks : int
    scheduler : str
        ``serial``, ``local:N`` or the scheduler address.
    workers : int
        Workers that ran chunks (1 for serial).
    elapsed_s : float
        Wall time of scoring (cluster start-up excluded), s.
    compiled : bool
        The model's functions ran compiled C (else CasADi's virtual machine).
    extra : dict
        On a cluster: ``workers_at_start``, ``chunks_done`` (chunks scored before it failed, or
        all).
    """

    status: SweepStatus
    reason: str
    placements: np.ndarray
    scores: ChunkScores
    poses: int
    chunk_placements: int
    n_chunks: int
    scheduler: str
    workers: int
    elapsed_s: float
    compiled: bool
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status is SweepStatus.OK

    @property
    def scored(self) -> bool:
        """Every placement was scored (``OK`` or ``NO_FEASIBLE``); else the cluster failed."""
        return self.status in (SweepStatus.OK, SweepStatus.NO_FEASIBLE)

    @property
    def poses_per_second(self) -> float:
        return self.poses / self.elapsed_s if self.elapsed_s > 0 else float("nan")


def default_chunk_poses(total_poses: int) -> int:
    """Poses per chunk of a default chunking of ``total_poses``: :data:`CHUNK_POSES`, or more for a
    sweep that would need more than :data:`DEFAULT_MAX_CHUNKS` chunks, at most
    :data:`CHUNK_MAX_POSES`."""
    return int(min(max(CHUNK_POSES, math.ceil(total_poses / DEFAULT_MAX_CHUNKS)), CHUNK_MAX_POSES))


def chunk_placements_for(kernel: PlacementKernel, n_placements: int = 0, target_poses: int | None = None) -> int:
    """Placements per chunk: about ``target_poses`` poses per chunk (default
    :func:`default_chunk_poses` of a sweep of ``n_placements``)."""
    ppp = max(1, kernel.poses_per_placement)
    target = default_chunk_poses(n_placements * ppp) if target_poses is None else int(target_poses)
    n = max(1, target // ppp)
    return int(min(max(n, CHUNK_MIN_PLACEMENTS), CHUNK_MAX_PLACEMENTS))


def chunk_bounds(n_placements: int, per_chunk: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of consecutive chunks of ``per_chunk`` placements."""
    return [(a, min(a + per_chunk, n_placements)) for a in range(0, n_placements, per_chunk)]


def parse_scheduler(spec: str | None) -> str:
    """Check a ``--scheduler`` value: ``serial`` (or None), ``local:N`` (N workers, 1 to 256)
    or a Dask scheduler address ``tcp://HOST:PORT``.  Returns the normalised spec.

    Raises
    ------
    InputError
        Naming the value and what was expected.
    """
    if spec is None or spec == "serial":
        return "serial"
    s = str(spec).strip()
    if s.startswith("local:"):
        n = s[len("local:") :]
        if not re.fullmatch(r"[0-9]{1,4}", n) or not 1 <= int(n) <= 256:
            raise InputError(f"--scheduler {spec!r}: local:N needs a whole number of workers N in [1, 256]")
        return f"local:{int(n)}"
    if s.startswith(("tcp://", "tls://", "ucx://")):
        host, _, port = s.split("://", 1)[1].rpartition(":")
        if not host or not re.fullmatch(r"[0-9]{1,5}", port) or not 1 <= int(port) <= 65535:
            raise InputError(f"--scheduler {spec!r}: an address must be tcp://HOST:PORT with PORT in [1, 65535]")
        return s
    raise InputError(
        f"--scheduler {spec!r}: expected 'serial', 'local:N' (a LocalCluster of N workers) "
        "or a Dask scheduler address tcp://HOST:PORT"
    )


def _no_feasible_reason(scores: ChunkScores) -> str:
    """One line: why no placement is feasible, with the count of each status."""
    counts = ", ".join(
        f"{s.value.replace('_', ' ')} {int((scores.status == s.code).sum())}"
        for s in PlacementStatus
        if not s.ok and (scores.status == s.code).any()
    )
    return (
        f"none of the {len(scores)} placements reaches the whole path on one branch without a flip, "
        f"inside the joint limits and outside the singularity guards ({counts}); move or widen the grid"
    )


def run_sweep(
    kernel: PlacementKernel,
    placements: np.ndarray,
    scheduler: str | None = None,
    chunk_placements: int | None = None,
    progress: Progress | None = None,
    on_chunk: Callable[[int], None] | None = None,
) -> SweepResult:
    """Score every placement.

    Parameters
    ----------
    kernel : PlacementKernel
    placements : ndarray, shape (P, 5)
        ``[x, y, z, yaw, tilt]`` (m, rad).
    scheduler : str, optional
        ``serial`` (default), ``local:N`` or ``tcp://HOST:PORT`` (see :func:`parse_scheduler`).
    chunk_placements : int, optional
        Placements per chunk (default :func:`chunk_placements_for` of the sweep's size).
    progress : callable, optional
        ``progress(PROGRESS_STAGE, poses_done, poses_total)`` after each chunk.
    on_chunk : callable, optional
        Called with the number of chunks done after each chunk (tests use it to kill a worker).

    Returns
    -------
    SweepResult
        Status ``NO_WORKERS`` or ``CLUSTER_FAILED`` (and no scores) when the cluster could not
        score every chunk: it never waits forever for workers (``cluster.WORKER_WAIT_S``).

    Raises
    ------
    InputError
        A bad scheduler spec, Dask missing for a cluster, no connection to the scheduler, or
        workers without compplan or with another version.
    """
    spec = parse_scheduler(scheduler)
    pl = np.atleast_2d(np.asarray(placements, dtype=float))
    per = int(chunk_placements) if chunk_placements else chunk_placements_for(kernel, len(pl))
    if not CHUNK_MIN_PLACEMENTS <= per <= CHUNK_MAX_PLACEMENTS:
        raise InputError(f"chunk of {per} placements: expected {CHUNK_MIN_PLACEMENTS} to {CHUNK_MAX_PLACEMENTS}")
    per = min(per, max(1, len(pl)))
    bounds = chunk_bounds(len(pl), per)
    chunks = [pl[a:b] for a, b in bounds]
    ppp = kernel.poses_per_placement
    total = len(pl) * ppp
    extra: dict[str, Any] = {}
    failed: tuple[SweepStatus, str] | None = None
    if spec == "serial":
        t0 = time.perf_counter()
        parts, done = [], 0
        for i, c in enumerate(chunks):
            parts.append(kernel.evaluate(c))
            done += len(c) * ppp
            if progress is not None:
                progress(PROGRESS_STAGE, done, total)
            if on_chunk is not None:
                on_chunk(i + 1)
        elapsed, workers = time.perf_counter() - t0, 1
    else:
        from problems.placement.cluster import run_on_dask

        run = run_on_dask(kernel, chunks, spec, progress, on_chunk)
        parts, elapsed, workers = run.parts, run.elapsed_s, run.workers
        extra = {"workers_at_start": run.workers_at_start, "chunks_done": run.chunks_done}
        if not run.ok:
            failed = (run.status, run.reason)
    if failed is not None:  # the cluster failed: no scores
        scores, (status, reason) = ChunkScores.empty(0, kernel.n_branches), failed
    else:
        scores = ChunkScores.concatenate(parts) if parts else ChunkScores.empty(0, kernel.n_branches)
        n_ok = int(scores.feasible.sum())
        status, reason = (SweepStatus.OK, "") if n_ok else (SweepStatus.NO_FEASIBLE, _no_feasible_reason(scores))
    return SweepResult(
        status, reason, pl, scores, total, per, len(chunks), spec, workers, elapsed, kernel.compiled, extra
    )


__all__ = [
    "CHUNK_MAX_POSES",
    "CHUNK_POSES",
    "DEFAULT_MAX_CHUNKS",
    "PROGRESS_STAGE",
    "SweepResult",
    "SweepStatus",
    "chunk_bounds",
    "chunk_placements_for",
    "default_chunk_poses",
    "parse_scheduler",
    "run_sweep",
]
