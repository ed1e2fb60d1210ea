"""Outputs: the user's umask, whole-or-nothing sets (disk full, file-size limit), no stale files,
one writer at a time, outputs never overwrite inputs, and output paths checked before long work.

Each failure class has one test; the command-line ones check the one-line ``compplan: error:``
message and exit status 2.
"""

from __future__ import annotations

import errno
import json
import os
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import planner.output as output
from models.errors import InputError
from planner.cli import EXIT_USER_ERROR, main
from planner.output import SIBLING_TAG, OutputError, OutputSet, acquire_output_lock, lock_path
from planner.report.writer import REPORT_OUTPUTS

REPO = Path(__file__).resolve().parents[1]
#: Grid points of the small compliance maps written here (fast; files of a few 10 kB).
MAP_POINTS = "21"
#: File-size limit of the RLIMIT_FSIZE test: above the small files of a 21 x 21 map, below its PNG.
FSIZE_LIMIT_BYTES = 100_000
#: Seconds to wait for the first of two concurrent runs to take its lock.
LOCK_APPEAR_S = 60.0
#: Polling interval while waiting for that lock (s).
LOCK_POLL_S = 0.02


def _main(capsys, *argv: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _one_line_error(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("compplan: error: "), err
    assert "Traceback" not in err
    return lines[0]


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (relative name -> bytes)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _siblings(folder: Path) -> list[str]:
    """Hidden temporary siblings and lock files compplan left beside ``folder``."""
    return sorted(n for n in os.listdir(folder.parent) if SIBLING_TAG in n)


def _python(script: str, *args: str, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run a Python snippet in a fresh interpreter (its own umask or rlimits)."""
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script), *args], cwd=cwd, capture_output=True, text=True, timeout=timeout
    )


def _map(capsys, out: Path, *extra: str) -> None:
    code, _, err = _main(capsys, "map", "--points", MAP_POINTS, "--out", str(out), *extra)
    assert code == 0, err


def _write_commands_csv(path: Path) -> Path:
    path.write_text("q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz\n0.1,-1.2,1.3,-1.5,-1.57,0.2,0,0,-50,0,0,0\n")
    return path


# ------------------------------------------------------------------------------ umask
#: The umasks of the umask test: the usual one and a group-writable one.
UMASKS = (0o022, 0o002)


@pytest.fixture(scope="module")
def umask_runs(tmp_path_factory) -> Path:
    """``map`` and ``predict`` under each of :data:`UMASKS`, in one fresh interpreter (a process
    has one umask at a time: set before each command), into ``umask_<octal>/``."""
    base = tmp_path_factory.mktemp("umask")
    for umask in UMASKS:
        (base / f"umask_{umask:o}").mkdir()
        _write_commands_csv(base / f"umask_{umask:o}" / "in.csv")
    r = _python(
        """
        import os, sys
        from planner.cli import main
        for umask in sys.argv[2:]:
            os.chdir(f"umask_{umask}")
            os.umask(int(umask, 8))
            assert main(["map", "--points", sys.argv[1], "--out", "map"]) == 0
            assert main(["predict", "--model", "ur5", "--input", "in.csv", "--out", "sub/pred.csv"]) == 0
            os.chdir("..")
        """,
        MAP_POINTS,
        *(f"{u:o}" for u in UMASKS),
        cwd=base,
    )
    assert r.returncode == 0, r.stderr
    return base


@pytest.mark.slow
@pytest.mark.parametrize("umask", UMASKS)
def test_files_and_folders_get_the_users_umask(umask_runs, umask):
    """A colleague or a web server can read what compplan wrote: no temporary file's 0600."""
    tmp_path = umask_runs / f"umask_{umask:o}"
    file_mode, folder_mode = 0o666 & ~umask, 0o777 & ~umask
    folders = [tmp_path / "map", tmp_path / "map" / "figures", tmp_path / "sub"]
    files = [p for p in (tmp_path / "map").rglob("*") if p.is_file()] + [tmp_path / "sub" / "pred.csv"]
    assert len(files) == 5
    for p in folders:
        assert stat.S_IMODE(p.stat().st_mode) == folder_mode, (p, oct(p.stat().st_mode))
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == file_mode, (p, oct(p.stat().st_mode))
    assert _siblings(tmp_path / "map") == []


# ------------------------------------------------------------------------------ disk full
@pytest.mark.slow
def test_disk_full_mid_write_keeps_the_previous_set(tmp_path, capsys, monkeypatch):
    """ENOSPC after some files: exit 2, one line, the previous set intact, no temporary folder."""
    out = tmp_path / "map"
    _map(capsys, out)
    before = _snapshot(out)
    written: list[Path] = []
    real_write = output._write_new_file

    def full_disk(path: Path, data: bytes) -> None:
        if len(written) == 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        real_write(path, data)
        written.append(path)

    monkeypatch.setattr(output, "_write_new_file", full_disk)
    code, stdout, err = _main(capsys, "map", "--points", "11", "--out", str(out))
    assert code == EXIT_USER_ERROR and "wrote" not in stdout
    line = _one_line_error(err)
    assert f"output folder {out}" in line and "No space left on device (ENOSPC)" in line
    assert "nothing was changed" in line and len(written) == 2
    assert _snapshot(out) == before and _siblings(out) == []


def test_disk_full_while_adding_a_report_keeps_the_run_and_its_earlier_report(tmp_path, monkeypatch):
    """The report of a run folder is published whole too: the run's files and the earlier report stay."""
    run = tmp_path / "run"
    s = OutputSet(run)
    s.add_json("summary.json", {"plan_status": "ok"})
    s.add_bytes("path.csv", b"x,y,z\n")
    s.publish()
    old = OutputSet(run, owns=REPORT_OUTPUTS)
    for name in ("report.html", "report.md", "figures/fig1.png", "figures/fig6.png", "compliance_map.csv"):
        old.add_bytes(name, b"old " + name.encode())
    old.publish()
    before = _snapshot(run)

    new = OutputSet(run, owns=REPORT_OUTPUTS)
    for name in ("figures/fig1.png", "report.md", "report.html"):
        new.add_bytes(name, b"new " + name.encode())
    calls = []

    def full_disk(path: Path, data: bytes) -> None:
        calls.append(path)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        path.write_bytes(data)

    monkeypatch.setattr(output, "_write_new_file", full_disk)
    with pytest.raises(OutputError, match=r"cannot write report.html \(No space left on device \(ENOSPC\)\)"):
        new.publish()
    assert _snapshot(run) == before and _siblings(run) == []
    monkeypatch.undo()
    new.publish()  # the new report replaces every report entry, the run's files stay
    assert _snapshot(run) == {
        "figures/fig1.png": b"new figures/fig1.png",
        "path.csv": b"x,y,z\n",
        "report.html": b"new report.html",
        "report.md": b"new report.md",
        "summary.json": before["summary.json"],
    }


# ------------------------------------------------------------------------------ file-size limit
@pytest.mark.slow
def test_file_size_limit_keeps_the_previous_set(tmp_path, capsys):
    """RLIMIT_FSIZE (SIGXFSZ ignored: write fails with EFBIG) part-way: the previous set intact."""
    out = tmp_path / "map"
    _map(capsys, out)
    before = _snapshot(out)
    sizes = sorted(len(v) for v in before.values())
    assert sizes[0] < FSIZE_LIMIT_BYTES < sizes[-1]  # some files fit, one does not
    r = _python(
        """
        import resource, signal, sys
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        limit = int(sys.argv[1])
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        from planner.cli import main
        sys.exit(main(["map", "--points", sys.argv[2], "--out", "map"]))
        """,
        str(FSIZE_LIMIT_BYTES),
        MAP_POINTS,
        cwd=tmp_path,
    )
    assert r.returncode == EXIT_USER_ERROR, r.stderr
    line = _one_line_error(r.stderr)
    assert "File too large (EFBIG)" in line and "nothing was changed" in line
    assert "wrote" not in r.stdout
    assert _snapshot(out) == before and _siblings(out) == []


# ------------------------------------------------------------------------------ stale files
@pytest.mark.slow
def test_a_new_run_leaves_no_file_of_an_earlier_run(tmp_path, capsys):
    """Report, figures, maps and trajectories of an earlier run never sit beside a new summary."""
    out = tmp_path / "run"
    old = OutputSet(out)
    old.add_json("summary.json", {"plan_status": "ok", "problem": {"name": "earlier"}})
    for name in (
        "report.html",
        "report.md",
        "figures/fig6_trajectory.png",
        "compliance_map.csv",
        "compliance_map.json",
        "trajectory_ruckig.csv",
        "trajectory.png",
        "pose.json",
    ):
        old.add_bytes(name, b"earlier run")
    old.publish()
    code, stdout, err = _main(capsys, "plan", "paper_4_4", "--out", str(out), "--no-report", "--no-figures")
    assert code == 0, err
    names = sorted(str(p.relative_to(out)) for p in out.rglob("*"))
    assert names == sorted(
        ["summary.json", "path.csv", "waypoints.csv", "branches.csv", "trajectory.csv", "trajectory_toppra.csv"]
    )
    assert json.loads((out / "summary.json").read_text())["problem"]["name"] == "paper_4_4"
    assert _siblings(out) == []
    # a map written over it (another command's output: --force) is again only a map
    _map(capsys, out, "--force")
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()) == [
        "compliance_map.csv",
        "compliance_map.json",
        "figures/fig1_compliance_map.pdf",
        "figures/fig1_compliance_map.png",
    ]


def test_leftovers_of_a_killed_writer_are_removed_and_do_not_block(tmp_path, capsys):
    """A temporary folder and a lock file left by a killed run: the next run cleans up and writes."""
    out = tmp_path / "map"
    lock_path(out).write_text("12345\n")  # not held by anyone
    left = Path(f"{output.sibling_prefix(out, output.STAGING_KIND)}12345-abc")
    (left / "figures").mkdir(parents=True)
    _map(capsys, out)
    assert (out / "compliance_map.csv").is_file() and _siblings(out) == []


def test_a_folder_of_other_files_is_refused(tmp_path, capsys, monkeypatch):
    """A run replaces its output folder whole: a folder compplan did not write is refused."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    code, _, err = _main(capsys, "map", "--out", str(mine))
    assert code == EXIT_USER_ERROR and "holds files compplan did not write (notes.txt)" in _one_line_error(err)
    assert (mine / "notes.txt").read_text() == "keep me"
    monkeypatch.chdir(mine)
    code, _, err = _main(capsys, "map", "--out", ".")
    assert code == EXIT_USER_ERROR and "is the current folder" in _one_line_error(err)


# ------------------------------------------------------------------------------ one writer
@pytest.mark.slow
def test_two_runs_into_one_out(tmp_path):
    """The second run is refused with one line while the first holds the folder; one 'wrote'."""
    cmd = [sys.executable, "-m", "planner", "demo", "--out", "run"]
    first = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lock = lock_path(tmp_path / "run")
        for _ in range(int(LOCK_APPEAR_S / LOCK_POLL_S)):  # wait for the first run's lock
            if lock.exists() or first.poll() is not None:
                break
            time.sleep(LOCK_POLL_S)
        assert lock.exists() and first.poll() is None, "the first run never took its lock"
        second = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=600)
        still_running = first.poll() is None
        out1, err1 = first.communicate(timeout=600)
    finally:
        if first.poll() is None:
            first.kill()
    assert still_running, "the first run ended before the second checked its --out"
    assert first.returncode == 0, err1
    assert second.returncode == EXIT_USER_ERROR
    line = _one_line_error(second.stderr)
    assert "--out run: another compplan run is writing it (pid" in line and str(first.pid) in line
    assert second.stdout == "" and (out1 + second.stdout).count("wrote run/:") == 1
    # the folder is the first run's, whole: summary and its report, nothing half-written
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["plan_status"] == "ok" and (tmp_path / "run" / "report.html").is_file()
    assert _siblings(tmp_path / "run") == []


@pytest.mark.slow
def test_a_locked_output_is_refused_in_process_and_released_after(tmp_path, capsys):
    out = tmp_path / "pred.csv"
    inp = _write_commands_csv(tmp_path / "in.csv")
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            textwrap.dedent("""
        import sys, time
        from planner.output import acquire_output_lock
        acquire_output_lock(sys.argv[1]); print("locked", flush=True); time.sleep(600)
        """),
            str(out),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        code, _, err = _main(capsys, "predict", "--model", "ur5", "--input", str(inp), "--out", str(out))
        assert code == EXIT_USER_ERROR and f"(pid {holder.pid}" in _one_line_error(err)
        assert not out.exists()
    finally:
        holder.kill()
        holder.wait()
    code, _, err = _main(capsys, "predict", "--model", "ur5", "--input", str(inp), "--out", str(out))
    assert code == 0, err
    assert out.read_text().startswith("x,y,z") and _siblings(out) == []
    # re-entrant within one thread: the command's lock and the library's publish nest
    acquire_output_lock(tmp_path / "run")
    try:
        with output.output_lock(tmp_path / "run"):
            pass
        assert output.holds_output_lock(tmp_path / "run")
    finally:
        output.release_output_lock(tmp_path / "run")
    assert not output.holds_output_lock(tmp_path / "run") and _siblings(out) == []


# ------------------------------------------------------------------------------ --out = an input
def _inputs(tmp_path: Path) -> dict[str, Path]:
    data = tmp_path / "data.csv"
    data.write_text("q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz,x,y,z\n")
    problem = tmp_path / "problems" / "task.toml"
    problem.parent.mkdir()
    problem.write_text((REPO / "problems" / "files" / "paper_4_4.toml").read_text())
    return {"data": data, "input": _write_commands_csv(tmp_path / "in.csv"), "problem": problem}


OUT_IS_INPUT = [
    (
        "identify --out DATA",
        lambda p: [
            "identify",
            "--robot",
            "ur5",
            "--data",
            p["data"],
            "--out",
            p["data"],
            "--report",
            p["data"].parent / "rep",
        ],
        "--out {data}: is also the input --data",
    ),
    (
        "identify --report holds DATA",
        lambda p: [
            "identify",
            "--robot",
            "ur5",
            "--data",
            p["data"],
            "--out",
            p["data"].parent / "m.toml",
            "--report",
            p["data"].parent,
        ],
        "--report {tmp}: contains the input --data",
    ),
    (
        "identify --out inside --report",
        lambda p: [
            "identify",
            "--robot",
            "ur5",
            "--data",
            p["data"],
            "--out",
            p["data"].parent / "rep" / "m.toml",
            "--report",
            p["data"].parent / "rep",
        ],
        "--report {tmp}/rep: contains the output --out",
    ),
    (
        "predict --out INPUT",
        lambda p: ["predict", "--model", "ur5", "--input", p["input"], "--out", p["input"]],
        "--out {input}: is also the input --input",
    ),
    (
        "compensate --out INPUT",
        lambda p: ["compensate", "--model", "ur5", "--input", p["input"], "--out", p["input"]],
        "--out {input}: is also the input --input",
    ),
    (
        "plan --out PROBLEM",
        lambda p: ["plan", p["problem"], "--out", p["problem"]],
        "--out {problem}: is also the input PROBLEM",
    ),
    (
        "plan --out the problem's folder",
        lambda p: ["plan", p["problem"], "--out", p["problem"].parent],
        "--out {problem_dir}: contains the input PROBLEM",
    ),
    (
        "demo --out the robot file",
        lambda p: ["demo", "--robot", p["problem"], "--out", p["problem"]],
        "--out {problem}: is also the input --robot",
    ),
    (
        "map --out the robot's folder",
        lambda p: ["map", "--robot", p["problem"], "--out", p["problem"].parent],
        "--out {problem_dir}: contains the input --robot",
    ),
    (
        "simulate --out --truth",
        lambda p: [
            "simulate",
            "--robot",
            "ur5",
            "--config",
            p["problem"],
            "--out",
            p["data"].parent / "d.csv",
            "--truth",
            p["data"].parent / "d.csv",
        ],
        "--out {tmp}/d.csv: is also the output --truth",
    ),
]


@pytest.mark.parametrize("case,argv,message", OUT_IS_INPUT, ids=[c[0] for c in OUT_IS_INPUT])
def test_out_naming_an_input_is_refused(tmp_path, capsys, case, argv, message):
    p = _inputs(tmp_path)
    before = _snapshot(tmp_path)
    code, stdout, err = _main(capsys, *map(str, argv(p)))
    assert code == EXIT_USER_ERROR and stdout == ""
    expected = message.format(tmp=tmp_path, problem_dir=p["problem"].parent, **p)
    assert expected in _one_line_error(err), (expected, err)
    assert _snapshot(tmp_path) == before and _siblings(p["data"]) == []


def test_predict_out_an_existing_folder_is_refused(tmp_path, capsys):
    inp = _write_commands_csv(tmp_path / "in.csv")
    (tmp_path / "results").mkdir()
    code, _, err = _main(capsys, "predict", "--model", "ur5", "--input", str(inp), "--out", str(tmp_path / "results"))
    assert code == EXIT_USER_ERROR
    assert f"--out {tmp_path / 'results'}: is an existing folder; give the path of the file" in _one_line_error(err)
    assert os.listdir(tmp_path / "results") == []


# ------------------------------------------------------------------------------ before long work
@pytest.fixture(scope="module")
def measurements(tmp_path_factory) -> Path:
    """A simulated campaign whose identification takes seconds."""
    d = tmp_path_factory.mktemp("meas")
    cfg = d / "sim.toml"
    cfg.write_text('seed = 3\nunits = "mm"\n[campaign]\nposes = 60\n[noise]\nsigma_m = 2e-5\n[effects.gravity]\n')
    assert main(["simulate", "--robot", "ur5", "--config", str(cfg), "--out", str(d / "data.csv")]) == 0
    return d / "data.csv"


@pytest.mark.parametrize("bad", ["out_is_folder", "report_is_file", "report_is_foreign"])
def test_identify_checks_its_outputs_before_the_fit(tmp_path, capsys, measurements, bad, monkeypatch):
    out, rep = tmp_path / "model.toml", tmp_path / "report"
    if bad == "out_is_folder":
        out.mkdir()
        expected = f"--out {out}: is an existing folder"
    elif bad == "report_is_file":
        rep.write_text("a file")
        expected = f"--report {rep}: exists and is not a folder"
    else:
        rep.mkdir()
        (rep / "mine.txt").write_text("x")
        expected = f"--report {rep}: holds files compplan did not write (mine.txt)"
    import problems.identify as ident

    def no_fit(*_a, **_k):  # the outputs must be refused before any fitting starts
        raise AssertionError("identify started the fit before checking its outputs")

    monkeypatch.setattr(ident, "identify", no_fit)
    monkeypatch.setattr(ident.engine, "identify", no_fit)
    code, _, err = _main(
        capsys,
        "identify",
        "--robot",
        "ur5",
        "--data",
        str(measurements),
        "--out",
        str(out),
        "--report",
        str(rep),
        "--no-progress",
    )
    assert code == EXIT_USER_ERROR and expected in _one_line_error(err)


def test_library_publish_refuses_and_raises_input_errors(tmp_path):
    """OutputSet itself checks its folder (library callers get the same one-line errors)."""
    (tmp_path / "f").write_text("x")
    s = OutputSet(tmp_path / "f")
    s.add_bytes("a.txt", b"a")
    with pytest.raises(InputError, match="exists and is not a folder"):
        s.publish()
    with pytest.raises(ValueError, match="relative path"):
        s.add_bytes("../escape.txt", b"x")
    # a set without a marker file can be published again over itself, not over other files
    s = OutputSet(tmp_path / "set")
    s.add_bytes("data/a.bin", b"1")
    s.publish()
    s.files = {"data/b.bin": b"2"}
    s.publish()
    assert _snapshot(tmp_path / "set") == {"data/b.bin": b"2"}
    (tmp_path / "set" / "mine.txt").write_text("x")
    with pytest.raises(OutputError, match=r"holds files compplan did not write \(data, mine.txt\)"):
        s.publish()


# ------------------------------------------------------------------------------ the report phase
@pytest.mark.parametrize(
    "failure",
    [
        OSError(errno.EFBIG, os.strerror(errno.EFBIG), "figures/fig1_compliance_map.png"),
        KeyboardInterrupt(),
    ],
    ids=["EFBIG", "Ctrl-C"],
)
def test_a_plan_failing_in_its_report_leaves_the_previous_run_whole(tmp_path, capsys, monkeypatch, failure):
    """Issue 24: the plan's files and its report are one output set; a failure or an interrupt while the
    report is built or written leaves the previous run, report, figures and map included, as it was."""
    out = tmp_path / "run"
    code, _, err = _main(capsys, "demo", "--points", "20", "--out", str(out))
    assert code == 0, err
    before = _snapshot(out)
    assert {"report.html", "summary.json", "compliance_map.csv"} <= set(before)
    real_write = output._write_new_file

    def fail_on_report(path: Path, data) -> None:
        if path.name == "report.html" or "figures" in path.parts:
            raise failure
        real_write(path, data)

    monkeypatch.setattr(output, "_write_new_file", fail_on_report)
    if isinstance(failure, KeyboardInterrupt):
        code, stdout, err = _main(capsys, "demo", "--points", "21", "--out", str(out))
        assert code == 130 and "interrupted" in err and "wrote" not in stdout
    else:
        code, stdout, err = _main(capsys, "demo", "--points", "21", "--out", str(out))
        assert code == EXIT_USER_ERROR and "wrote" not in stdout
        assert "File too large (EFBIG)" in _one_line_error(err)
    assert _snapshot(out) == before and _siblings(out) == []
