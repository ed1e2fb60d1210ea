"""The outcome of a placement sweep and its progress stage, shared by the serial sweep
(:mod:`problems.placement.sweep`) and its Dask side (:mod:`problems.placement.cluster`)."""

from __future__ import annotations

from collections.abc import Callable

from models.status import Status

__all__ = ["PROGRESS_STAGE", "Progress", "SweepStatus"]

#: Progress stage name (``progress(stage, done, total)``, poses).
PROGRESS_STAGE = "placement sweep"

Progress = Callable[[str, int, int], None]


class SweepStatus(Status):
    """Outcome of a sweep."""

    OK = "ok"
    #: every chunk was scored, but no placement is feasible
    NO_FEASIBLE = "no feasible placement"
    #: the cluster had no live worker for ``cluster.WORKER_WAIT_S`` (none joined, or all died and
    #: none came back); the remaining chunks were cancelled
    NO_WORKERS = "no workers"
    #: a chunk's workers died more than ``distributed.scheduler.allowed-failures`` times, or the
    #: scheduler went away
    CLUSTER_FAILED = "cluster failed"
