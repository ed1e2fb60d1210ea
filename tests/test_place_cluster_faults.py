"""Faults of a placement sweep on a Dask cluster (``docs/placement.md``, "Cluster failures").

* Workers that all die mid-sweep end it, within ``cluster.WORKER_WAIT_S`` (made small here),
  with status ``no workers`` and one line naming the address, the chunks scored and what to do;
  the remaining tasks are cancelled.  Until the last one dies, the survivors carry the sweep.
  ``compplan place`` on the scheduler left without workers is that one line, exit 2.
* A Ctrl-C (SIGINT to the process group, as a terminal sends it) under ``--scheduler local:2``
  is ``compplan: interrupted``, exit 130: no worker traceback, no worker process left.

Every process and cluster started here is stopped before the test ends.
"""

from __future__ import annotations

import functools
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")  # a dependency of distributed

import problems.placement.cluster as cluster_mod  # noqa: E402 - after the importorskip above
from models import interrupts  # noqa: E402 - after the importorskip above
from problems.placement.grid import parse_grid_text  # noqa: E402 - after the importorskip above
from problems.placement.kernel import PlacementKernel  # noqa: E402 - after the importorskip above
from problems.placement.sweep import SweepStatus, run_sweep  # noqa: E402 - after the importorskip above
from problems.problem import load_problem  # noqa: E402 - after the importorskip above

ROOT = Path(__file__).resolve().parents[1]
#: The bound on a cluster without a live worker in these tests, s (the product's is 30 s).
WORKER_WAIT_PATCHED_S = 1
#: Seconds after which a sweep that has not ended is reported as hung (a guard: the test fails
#: instead of waiting forever, which is the bug under test).
HANG_S = 120
#: Seconds to wait for worker processes to start, to import compplan, or to be gone.
PROCESS_WAIT_S = 60
#: 50 chunks of 20 placements (7,200 poses each, tens of ms on a worker): work remains when the
#: workers die.
DEATH_GRID, DEATH_CHUNK = "x_m=-0.4:0.4:5,y_m=-0.6:0.6:5,yaw_deg=0:270:4,z_m=0:0.4:10", 20
#: The first worker is killed when the first chunk is in, the second when this many are.
SECOND_KILL_AT = 5
#: 16,236 placements (about 16 s on two workers): the sweep is running when the Ctrl-C comes.
INTERRUPT_GRID = "x_m=-0.6:1.0:33,y_m=-1.0:1.0:41,yaw_deg=0:330:12"


@functools.cache
def _kernel() -> PlacementKernel:
    return PlacementKernel(load_problem("placement_milling"))


def _placements(text: str):
    return parse_grid_text(text, base=load_problem("placement_milling").placement).placements()


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))


def _gone(pid: int) -> bool:
    """The process has exited (a zombie waiting for its reaper counts as gone)."""
    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def _wait_all_gone(pids: list[int]) -> list[int]:
    """Those of ``pids`` still running after PROCESS_WAIT_S (polled; empty as soon as all exit)."""
    deadline = time.monotonic() + PROCESS_WAIT_S
    while time.monotonic() < deadline and not all(_gone(p) for p in pids):
        time.sleep(0.1)
    return [p for p in pids if not _gone(p)]


@pytest.fixture
def scheduler_without_nannies():
    """An in-process scheduler and two ``dask worker --no-nanny`` processes (a worker killed
    stays dead): ``(address, {worker address: pid})``."""
    sched = distributed.LocalCluster(
        n_workers=0,
        processes=True,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": cluster_mod.LOCAL_HTTP_ADDRESS},
        silence_logs=logging.ERROR,
    )
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", sched.scheduler_address]
            + ["--nthreads", "1", "--no-nanny", "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=_env(),
        )
        for _ in range(2)
    ]
    try:
        with distributed.Client(sched.scheduler_address, timeout=PROCESS_WAIT_S) as watcher:
            watcher.wait_for_workers(2, timeout=PROCESS_WAIT_S)
            pids = watcher.run(os.getpid)
        assert sorted(pids.values()) == sorted(p.pid for p in procs)
        yield sched, pids
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait()
        sched.close()


@pytest.mark.slow
def test_workers_that_all_die_end_the_sweep_with_one_line(scheduler_without_nannies, monkeypatch, tmp_path, capsys):
    sched, pids = scheduler_without_nannies
    address = sched.scheduler_address
    monkeypatch.setattr(cluster_mod, "WORKER_WAIT_S", WORKER_WAIT_PATCHED_S)
    order = sorted(pids.values())
    killed: list[tuple[int, int]] = []  # (pid, chunks in when killed)

    def kill(n_done: int) -> None:
        if len(killed) < 2 and n_done >= (1, SECOND_KILL_AT)[len(killed)]:
            os.kill(order[len(killed)], signal.SIGKILL)
            killed.append((order[len(killed)], n_done))

    pls = _placements(DEATH_GRID)
    outcome: list = []
    sweep = threading.Thread(
        target=lambda: outcome.append(run_sweep(_kernel(), pls, address, chunk_placements=DEATH_CHUNK, on_chunk=kill)),
        daemon=True,  # a sweep that hangs (the bug under test) is left behind, and the test fails
    )
    sweep.start()
    sweep.join(HANG_S)
    assert outcome, f"the sweep on a cluster without workers did not end within {HANG_S} s"
    (res,) = outcome
    # the survivor carried the sweep after the first death; the second one ended it
    assert [n for _, n in killed] == [1, SECOND_KILL_AT]
    done = res.extra["chunks_done"]
    assert SECOND_KILL_AT <= done < res.n_chunks
    assert res.status is SweepStatus.NO_WORKERS and not res.scored and len(res.scores) == 0
    assert res.extra["workers_at_start"] == 2
    assert "\n" not in res.reason
    for part in (address, "no Dask worker alive", f"after {done} of {res.n_chunks} chunks", "dask worker", "local:N"):
        assert part in res.reason, (part, res.reason)
    # the remaining tasks were cancelled and released: the scheduler holds none of them
    deadline = time.monotonic() + PROCESS_WAIT_S
    while sched.scheduler.tasks and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not sched.scheduler.tasks, list(sched.scheduler.tasks)[:3]

    # the command line, on the scheduler now without workers: one line, exit 2, nothing written
    from planner.cli import main as cli_main

    out = tmp_path / "place"
    capsys.readouterr()
    argv = ["place", "placement_milling", "--grid", "x_m=0", "--top", "0", "--no-report", "--out", str(out)]
    assert cli_main(argv + ["--scheduler", address]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("compplan: error: place: --scheduler " + address), err
    assert "no Dask worker joined" in err[0] and "dask worker" in err[0] and "local:N" in err[0]
    assert not out.exists()


#: The child: the command line with Python's own SIGINT handler, whatever this process ignores
#: (pytest started in the background ignores SIGINT, and a child would inherit that).
_CLI_CHILD = (
    "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "from planner.cli import main; sys.exit(main(sys.argv[1:]))"
)


def _sigint_blocked(pid: int) -> bool:
    """SIGINT is blocked in the main thread of process ``pid``."""
    (mask,) = [ln.split()[1] for ln in Path(f"/proc/{pid}/status").read_text().splitlines() if ln.startswith("SigBlk:")]
    return bool(int(mask, 16) >> (signal.SIGINT - 1) & 1)


def _running_workers(pid: int, n: int) -> list[int]:
    """The pids of the ``n`` Dask worker processes of process ``pid`` once each has imported
    compplan's kernel (CasADi mapped: the sweep is about to start or running); RuntimeError if
    ``pid`` exits or PROCESS_WAIT_S passes first."""
    deadline = time.monotonic() + PROCESS_WAIT_S
    parent = psutil.Process(pid)
    while time.monotonic() < deadline and parent.is_running() and not _gone(pid):
        ready = []
        for child in parent.children():
            try:
                worker = "spawn_main" in " ".join(child.cmdline())
                if worker and "casadi" in Path(f"/proc/{child.pid}/maps").read_text():
                    ready.append(child.pid)
            except (psutil.Error, OSError):
                continue
        if len(ready) == n:
            return ready
        time.sleep(0.1)
    raise RuntimeError(f"no {n} Dask workers running compplan under process {pid}")


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc; signals a process group")
def test_ctrl_c_under_a_local_cluster_is_one_line_and_leaves_no_worker(tmp_path):
    out = tmp_path / "place"
    argv = ["place", "placement_milling", "--grid", INTERRUPT_GRID, "--top", "0", "--no-report", "--out", str(out)]
    proc = subprocess.Popen(
        [sys.executable, "-c", _CLI_CHILD, *argv, "--scheduler", "local:2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=_env(),
        cwd=str(ROOT),
        start_new_session=True,  # its own process group, which receives the Ctrl-C
    )
    try:
        workers = _running_workers(proc.pid, 2)
        # a Ctrl-C cannot reach the workers: SIGINT is blocked in them (how soon a worker left to
        # handle it prints its traceback races with the client's close of the cluster)
        assert all(_sigint_blocked(w) for w in workers)
        os.killpg(proc.pid, signal.SIGINT)
        _, err_bytes = proc.communicate(timeout=HANG_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    err = err_bytes.decode()
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-2000:]
    assert err.strip().splitlines() == ["compplan: interrupted"], err[-2000:]
    assert not _wait_all_gone(workers)
    assert not out.exists()


def test_a_ctrl_c_while_closing_is_held_until_the_close_is_done():
    """The close of a cluster is not cut short by a second Ctrl-C: the signal is raised after."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # pytest may run ignoring it
    try:
        reached: list[str] = []
        with pytest.raises(KeyboardInterrupt):
            with interrupts.deferred():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)  # a signal is handled between bytecodes: give it some
                reached.append("closed")
        assert reached == ["closed"]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        with interrupts.deferred():  # without a Ctrl-C, nothing is raised
            reached.append("again")
        assert reached == ["closed", "again"]
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="POSIX signal masks")
def test_threads_started_for_a_local_cluster_block_sigint():
    """The LocalCluster's threads (and the worker processes they spawn) inherit a mask that
    blocks SIGINT; this thread's mask is restored after."""
    before = signal.pthread_sigmask(signal.SIG_BLOCK, set())
    seen: list[set[signal.Signals]] = []
    with cluster_mod._sigint_blocked_in_new_threads():
        t = threading.Thread(target=lambda: seen.append(signal.pthread_sigmask(signal.SIG_BLOCK, set())))
        t.start()
        t.join()
    assert signal.SIGINT in seen[0]
    assert signal.pthread_sigmask(signal.SIG_BLOCK, set()) == before
