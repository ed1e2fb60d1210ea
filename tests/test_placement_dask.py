"""The placement sweep on Dask (``pip install "compplan[dask]"``): bit-for-bit equal to the serial
sweep, robust to a worker killed mid-run, and clear errors for bad scheduler specs, an
unreachable scheduler and a missing Dask.

Every cluster is started here (or by ``run_sweep`` itself) and closed before the test ends, so no
worker process outlives the module.
"""

from __future__ import annotations

import functools
import logging
import os
import signal
import socket
import sys
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

import problems.placement.cluster as cluster_mod  # noqa: E402 - after the importorskip above
from models.errors import InputError  # noqa: E402 - after the importorskip above
from problems.placement.grid import parse_grid_text  # noqa: E402 - after the importorskip above
from problems.placement.kernel import PlacementKernel  # noqa: E402 - after the importorskip above
from problems.placement.sweep import SweepStatus, parse_scheduler, run_sweep  # noqa: E402 - after the importorskip above
from problems.problem import load_problem  # noqa: E402 - after the importorskip above

#: Placements per chunk of the headline comparison (50 placements -> 10 chunks).
HEADLINE_CHUNK = 5
#: Chunks of the worker-kill run: enough that work remains when the first result arrives.
KILL_MIN_CHUNKS = 20
#: The client's connection timeout (a closed port) and the wait for a worker (a scheduler
#: without workers) in these tests, s.
CONNECT_TIMEOUT_PATCHED_S = 2
#: Seconds to wait for a killed worker's nanny to bring up a replacement.
RESTART_WAIT_S = 60


@functools.cache
def _problem():
    return load_problem("placement_milling")


@functools.cache
def _kernel() -> PlacementKernel:
    return PlacementKernel(_problem())


def _placements(text: str) -> np.ndarray:
    return parse_grid_text(text, base=_problem().placement).placements()


HEADLINE_GRID = "x_m=-0.4:0.4:5,y_m=-0.6:0.6:5,yaw_deg=0:90:2"  # 50 placements
KILL_GRID = "x_m=-0.4:0.4:9,y_m=-0.6:0.6:5,yaw_deg=0:90:2"  # 90 placements


@pytest.mark.slow
def test_local_cluster_equals_serial_bit_for_bit():
    pls = _placements(HEADLINE_GRID)
    kern = _kernel()
    serial = run_sweep(kern, pls, "serial", chunk_placements=HEADLINE_CHUNK)
    done: list[int] = []
    seen: list[tuple[str, int, int]] = []
    dask = run_sweep(
        kern, pls, "local:2", chunk_placements=HEADLINE_CHUNK, on_chunk=done.append, progress=lambda *a: seen.append(a)
    )
    assert serial.ok and dask.ok and dask.status is SweepStatus.OK
    assert dask.n_chunks == serial.n_chunks == int(np.ceil(len(pls) / HEADLINE_CHUNK)) > 2
    assert dask.scheduler == "local:2" and dask.workers == 2 and dask.extra["workers_at_start"] == 2
    assert dask.scores.equal(serial.scores)  # the headline claim: bit for bit
    assert 0 < int(dask.scores.feasible.sum()) < len(pls)  # not a trivial all-equal result
    np.testing.assert_array_equal(dask.placements, pls)
    assert dask.poses == serial.poses == len(pls) * kern.poses_per_placement
    assert dask.compiled == kern.compiled
    # every chunk reported once, in completion order; progress reaches the total
    assert done == list(range(1, dask.n_chunks + 1))
    assert seen[-1][1] == seen[-1][2] == dask.poses and len(seen) == dask.n_chunks


@pytest.fixture
def own_cluster():
    """A LocalCluster of two single-threaded worker processes (each under a nanny)."""
    c = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
    )
    try:
        yield c
    finally:
        c.close()


@pytest.mark.slow
def test_a_worker_killed_mid_run_does_not_change_the_scores(own_cluster):
    pls = _placements(KILL_GRID)
    kern = _kernel()
    per = len(pls) // KILL_MIN_CHUNKS - 1
    serial = run_sweep(kern, pls, "serial", chunk_placements=per)
    assert serial.n_chunks >= KILL_MIN_CHUNKS
    with distributed.Client(own_cluster.scheduler_address, timeout=30) as watcher:
        watcher.wait_for_workers(2, timeout=RESTART_WAIT_S)
        pids = watcher.run(os.getpid)  # worker address -> worker pid
        assert len(pids) == 2 and os.getpid() not in pids.values()
        killed: list[tuple[int, int]] = []

        def kill_once(n_done: int) -> None:
            if not killed:
                pid = sorted(pids.values())[0]
                os.kill(pid, signal.SIGKILL)
                killed.append((pid, n_done))

        res = run_sweep(kern, pls, own_cluster.scheduler_address, chunk_placements=per, on_chunk=kill_once)
        assert killed and killed[0][1] == 1
        assert killed[0][1] < res.n_chunks  # work remained after the kill
        assert res.n_chunks == serial.n_chunks
        assert res.scores.equal(serial.scores)
        # the kill did happen: the worker process is gone and its nanny started another one
        watcher.wait_for_workers(2, timeout=RESTART_WAIT_S)
        deadline = time.monotonic() + RESTART_WAIT_S
        while time.monotonic() < deadline:
            now = watcher.run(os.getpid)
            if len(now) == 2 and killed[0][0] not in now.values():
                break
            time.sleep(0.2)
        assert killed[0][0] not in watcher.run(os.getpid).values()


@pytest.mark.parametrize(
    "spec", ["local:0", "local:x", "local:257", "foo", "tcp://nohost", "tcp://host:", "tcp://:8786", "local:"]
)
def test_bad_scheduler_specs_name_the_value(spec):
    with pytest.raises(InputError) as ei:
        parse_scheduler(spec)
    assert repr(spec) in str(ei.value) and "--scheduler" in str(ei.value)


def test_good_scheduler_specs_are_normalised():
    assert parse_scheduler(None) == parse_scheduler("serial") == "serial"
    assert parse_scheduler("local:02") == "local:2"
    assert parse_scheduler(" tcp://10.0.0.5:8786 ") == "tcp://10.0.0.5:8786"


def test_run_sweep_refuses_a_bad_spec_before_any_work():
    with pytest.raises(InputError, match="local:0"):
        run_sweep(_kernel(), _placements("x_m=0"), "local:0")


@pytest.mark.slow
def test_no_scheduler_at_the_address_is_an_input_error(monkeypatch):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there now
    monkeypatch.setattr(cluster_mod, "CONNECT_TIMEOUT_S", CONNECT_TIMEOUT_PATCHED_S)
    spec = f"tcp://127.0.0.1:{port}"
    with pytest.raises(InputError) as ei:
        run_sweep(_kernel(), _placements("x_m=0"), spec)
    assert spec in str(ei.value) and "cannot connect" in str(ei.value)


def test_missing_dask_says_how_to_install_it(monkeypatch):
    for name in list(sys.modules):
        if name == "distributed" or name.startswith("distributed."):
            monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(InputError) as ei:
        cluster_mod.require_dask()
    assert 'pip install "compplan[dask]"' in str(ei.value)
    with pytest.raises(InputError, match=r'pip install "compplan\[dask\]"'):
        run_sweep(_kernel(), _placements("x_m=0"), "local:2")
    # the serial sweep needs no Dask
    assert run_sweep(_kernel(), _placements("x_m=0"), "serial").n_chunks == 1


@pytest.mark.slow
def test_local_cluster_workers_keep_glibcs_dynamic_mmap_threshold():
    """Our LocalCluster's workers run without the nanny's MALLOC_TRIM_THRESHOLD_ (it made every
    chunk fault its large arrays in afresh) and keep the nanny's other settings (one BLAS/OpenMP
    thread per worker)."""
    with cluster_mod.dask_client("local:1") as client:
        env = client.run(lambda: {k: os.environ.get(k) for k in ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS")})
    (got,) = env.values()
    assert got["MALLOC_TRIM_THRESHOLD_"] is None
    assert got["OMP_NUM_THREADS"] == "1"


@pytest.mark.slow
def test_a_scheduler_without_workers_ends_the_sweep_with_no_workers(monkeypatch):
    """No worker joins within cluster.WORKER_WAIT_S: status ``no workers`` and one line naming the
    address and what to do, no scores (tests/test_place_cluster_faults.py: workers that die)."""
    monkeypatch.setattr(cluster_mod, "WORKER_WAIT_S", CONNECT_TIMEOUT_PATCHED_S)
    with distributed.LocalCluster(
        n_workers=0, processes=True, dashboard_address=None, silence_logs=logging.ERROR
    ) as empty:
        res = run_sweep(_kernel(), _placements("x_m=0"), empty.scheduler_address)
    assert res.status is SweepStatus.NO_WORKERS and not res.scored and len(res.scores) == 0
    assert res.extra["workers_at_start"] == 0 and res.extra["chunks_done"] == 0
    assert "\n" not in res.reason and empty.scheduler_address in res.reason
    assert "no Dask worker joined" in res.reason and "dask worker" in res.reason


@pytest.mark.slow
def test_workers_with_another_compplan_are_refused(monkeypatch):
    """The client compares its compplan version with every worker's before sending work."""
    monkeypatch.setattr(cluster_mod, "_installed_version", lambda: "0.0.0-not-this-one")
    with pytest.raises(InputError) as ei:
        run_sweep(_kernel(), _placements("x_m=0"), "local:1")
    assert "another compplan" in str(ei.value) and "0.0.0-not-this-one" in str(ei.value)


@pytest.mark.slow
def test_place_command_on_a_local_cluster_writes_the_serial_scores(tmp_path, capsys):
    """``compplan place --scheduler local:2`` writes the serial run's scores.csv byte for byte and
    says where it ran."""
    from planner.cli import main as cli_main

    base = ["place", "placement_milling", "--grid", HEADLINE_GRID, "--top", "0", "--no-report", "--chunk", "7"]
    assert cli_main(base + ["--out", str(tmp_path / "serial")]) == 0
    assert cli_main(base + ["--out", str(tmp_path / "dask"), "--scheduler", "local:2"]) == 0
    out = capsys.readouterr().out
    assert "scheduler local:2" in out and "on 2 worker(s)" in out
    a = (tmp_path / "serial" / "scores.csv").read_bytes()
    assert a == (tmp_path / "dask" / "scores.csv").read_bytes() and a.count(b"\n") == 51
    import json

    s = json.loads((tmp_path / "dask" / "summary.json").read_text())
    assert s["sweep"]["scheduler"] == "local:2" and s["sweep"]["workers"] == 2 and s["sweep"]["chunks"] == 8


def _free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _wait_listening(port: int, proc) -> None:
    """Until something listens on ``port`` (at most RESTART_WAIT_S); RuntimeError if ``proc`` exits
    or the time runs out first."""
    deadline = time.monotonic() + RESTART_WAIT_S
    while proc.poll() is None and time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            time.sleep(0.2)
    raise RuntimeError(f"no Dask scheduler listens on port {port}")


@pytest.mark.slow
def test_a_scheduler_lost_mid_run_ends_the_sweep_with_cluster_failed(tmp_path, capfd):
    """A remote scheduler (``dask scheduler``, its own process) killed after the first chunk: the
    sweep ends with status ``cluster failed`` and one line naming the address, and nothing of
    Dask's logging reaches stderr (the library is silent)."""
    import subprocess

    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.getcwd(), os.environ.get("PYTHONPATH", "")]))
    sched = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--no-dashboard",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    worker = None
    try:
        _wait_listening(port, sched)
        worker = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
        )
        with distributed.Client(address, timeout=30) as c:
            c.wait_for_workers(1, timeout=RESTART_WAIT_S)
        capfd.readouterr()

        def kill_scheduler(n_done: int) -> None:
            if sched.poll() is None:
                sched.kill()
                sched.wait()

        records: list[logging.LogRecord] = []
        collect = logging.Handler(logging.DEBUG)
        collect.emit = records.append  # type: ignore[method-assign]
        loggers = [logging.getLogger(n) for n in ("distributed", "distributed.client", "distributed.core")]
        for lg in loggers:
            lg.addHandler(collect)
        try:
            res = run_sweep(_kernel(), _placements(KILL_GRID), address, chunk_placements=2, on_chunk=kill_scheduler)
        finally:
            for lg in loggers:
                lg.removeHandler(collect)
        assert res.status is SweepStatus.CLUSTER_FAILED and not res.scored and len(res.scores) == 0
        assert address in res.reason and "went away" in res.reason
        assert "\n" not in res.reason
        assert not [r for r in records if r.levelno >= logging.WARNING], [r.getMessage() for r in records][:3]
        err = capfd.readouterr().err
        assert "Traceback" not in err and "CommClosedError" not in err, err
    finally:
        for p in (worker, sched):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
