"""Outputs survive failure (issue 24): a run of ``plan``, ``place`` or ``identify`` that is
interrupted (Ctrl-C), fails (file-size limit ``EFBIG``) or is killed (``SIGKILL``) at any phase
leaves the previous output byte for byte as it was, and no hidden sibling beside it once the
command has ended (a killed run's siblings are removed by the next run).  A folder holding
another command's output is replaced only with ``--force``; one whose previous contents could
not be removed is refused before any work; a sibling that cannot be removed is named in a warning.

Each class is one test parametrized over the phases of each command (computing, building the
report, writing each kind of file, the swap).  The failing runs reuse what the previous run
computed (its plan, study or identification and its report figures, recorded once per module),
so that a phase after the computation costs only the writing.
"""

from __future__ import annotations

import ctypes
import errno
import importlib
import os
import resource
import shutil
import signal
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import planner.output as output
import planner.output_siblings as siblings
from planner.cli import EXIT_USER_ERROR, main
from models.errors import InputError
from planner.output import SIBLING_TAG, FolderKind, OutputSet

#: Exit status of an interrupted command (``compplan: interrupted``).
EXIT_INTERRUPTED = 130
#: The plan of these tests: the smallest shipped problem (9 waypoints) at its analytic postures,
#: with an export and the report (RAPID: its servoj URScript, over max_motions, would need a stream_host).
PLAN_ARGV = ("plan", "drilling_cone", "--no-optimise", "--export", "rapid")
#: The placement study: two placements, the problem as written planned in full, no posture NLP.
PLACE_ARGV = (
    "place",
    "placement_milling",
    "--grid",
    "x_m=0:0.2:2,y_m=0:0:1,yaw_deg=0:0:1",
    "--top",
    "0",
    "--no-optimise",
)
#: The simulated campaign the identification reads (small: the fit takes under a second).
CAMPAIGN = 'seed = 3\nunits = "mm"\n[campaign]\nposes = 30\n[noise]\nsigma_m = 2e-5\n[effects.gravity]\n'
#: File-size limit of the RLIMIT_FSIZE run: above the plan's small files, below its trajectory and report.
FSIZE_LIMIT_BYTES = 500_000
#: Seconds a subprocess may take (a bound against a hang, not a timing assertion).
SUBPROCESS_TIMEOUT_S = 600
#: Linux ``prctl`` option and capabilities: a root test process drops the override of file
#: permissions so that read-only folders are read-only to it too.
PR_CAPBSET_DROP = 24
CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH = 1, 2

#: How each failure is raised.
FAILURES: dict[str, Callable[[], BaseException]] = {
    "Ctrl-C": KeyboardInterrupt,
    "EFBIG": lambda: OSError(errno.EFBIG, os.strerror(errno.EFBIG)),
}


# ------------------------------------------------------------------------------ helpers
def _run(capsys, *argv: Any) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (or the file itself): relative name -> bytes."""
    if folder.is_file():
        return {folder.name: folder.read_bytes()}
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _siblings(folder: Path) -> list[str]:
    """The hidden siblings (temporary sets and files, locks) beside ``folder``."""
    return sorted(n for n in os.listdir(folder.parent) if SIBLING_TAG in n)


def _error_line(err: str) -> str:
    """The one error line of a failed command (its warnings, e.g. about an export, aside)."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("compplan: warning: ")]
    assert len(lines) == 1 and lines[0].startswith("compplan: error: "), err
    return lines[0]


def _record(calls: dict[str, Any], where: str) -> Callable[..., Any]:
    """A wrapper of the function ``module:name`` that keeps its last result in ``calls[where]``."""
    module, name = where.split(":")
    real = getattr(importlib.import_module(module), name)

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        calls[where] = real(*args, **kwargs)
        return calls[where]

    return wrapper


def _previous_run(factory, name: str, argv: tuple[str, ...], recorded: tuple[str, ...]) -> tuple[Path, dict]:
    """Run ``compplan ARGV --out <new folder>/run`` once, recording the results of ``recorded``."""
    out = factory.mktemp(name) / "run"
    calls: dict[str, Any] = {}
    with pytest.MonkeyPatch.context() as mp:
        for where in recorded:
            module, attr = where.split(":")
            mp.setattr(importlib.import_module(module), attr, _record(calls, where))
        assert main([*argv, "--out", str(out)]) == 0
    assert set(calls) == set(recorded)
    return out, calls


def _reuse(monkeypatch, calls: dict[str, Any]) -> None:
    """Make the recorded functions return what they returned in the previous run."""
    for where, value in calls.items():
        module, name = where.split(":")
        monkeypatch.setattr(importlib.import_module(module), name, lambda *_a, _v=value, **_k: _v)


def _inject(monkeypatch, phase: tuple, failure: Callable[[], BaseException]) -> None:
    """Raise ``failure()`` at ``phase``: ``("call", "module:function")`` when the function is
    called; ``("write", test)`` part-way through the first file ``test(path)`` accepts (half of it
    on the disk); ``("swap",)`` when the new folder is to be moved into place."""
    if phase[0] == "call":
        module, name = phase[1].split(":")

        def fail(*_a: Any, **_k: Any) -> Any:
            raise failure()

        monkeypatch.setattr(importlib.import_module(module), name, fail)
    elif phase[0] == "write":
        real = output._write_new_file

        def fail_in(path: Path, data: Any) -> None:
            if not phase[1](path):
                return real(path, data)
            whole = data if isinstance(data, bytes) else b"".join(data)
            real(path, whole[: len(whole) // 2])
            raise failure()

        monkeypatch.setattr(output, "_write_new_file", fail_in)
    else:

        def fail_swap(*_a: Any) -> Any:
            raise failure()

        monkeypatch.setattr(output, "_move_into_place", fail_swap)


def _named(name: str) -> Callable[[Path], bool]:
    return lambda p: p.name == name


def _check_failed_run(capsys, failure: str, argv: list[Any], outputs: list[Path]) -> None:
    """Run ``argv``, which fails with ``failure``: the outputs as they were, no sibling left."""
    before = {p: _snapshot(p) for p in outputs}
    code, stdout, err = _run(capsys, *argv)
    assert "wrote" not in stdout
    if failure == "Ctrl-C":
        assert code == EXIT_INTERRUPTED and "compplan: interrupted" in err, err
    else:
        assert code == EXIT_USER_ERROR and "File too large" in _error_line(err)
    for p in outputs:
        assert _snapshot(p) == before[p], p
        assert _siblings(p) == [], _siblings(p)


# ------------------------------------------------------------------------------ plan
#: What the failing runs of ``plan`` reuse from the previous run.
PLAN_RECORDED = ("planner.plan:plan", "planner.report.writer:report_files")
#: The phases of ``plan``: computing (posture, compensation, timing), building the exports and the
#: report, writing the summary (the first file), the export and the report, and the swap.
PLAN_PHASES: dict[str, tuple] = {
    "posture": ("call", "planner.plan:optimise_postures"),
    "compensation": ("call", "planner.plan:_compensate"),
    "timing": ("call", "planner.plan:_time"),
    "building the exports": ("call", "planner.commands.plan:plan_exports"),
    "building the report": ("call", "planner.report.writer:report_files"),
    "writing summary.json": ("write", _named("summary.json")),
    "writing the export": ("write", lambda p: p.suffix == ".mod"),
    "writing report.html": ("write", _named("report.html")),
    "the swap": ("swap",),
}
#: Phases that come before anything the previous run recorded (run for real).
PLAN_COMPUTING = ("posture", "compensation", "timing")


@pytest.fixture(scope="module")
def plan_previous(tmp_path_factory) -> tuple[Path, dict]:
    """A plan's folder (report and export included) and what its run computed."""
    return _previous_run(tmp_path_factory, "plan_previous", PLAN_ARGV, PLAN_RECORDED)


@pytest.mark.parametrize("failure", FAILURES)
@pytest.mark.parametrize("phase", PLAN_PHASES)
def test_a_failing_plan_leaves_the_previous_plan_whole(tmp_path, capsys, monkeypatch, plan_previous, phase, failure):
    previous, calls = plan_previous
    out = tmp_path / "run"
    shutil.copytree(previous, out)
    if phase not in PLAN_COMPUTING:
        _reuse(monkeypatch, {k: v for k, v in calls.items() if ("call", k) != PLAN_PHASES[phase]})
    _inject(monkeypatch, PLAN_PHASES[phase], FAILURES[failure])
    _check_failed_run(capsys, failure, [*PLAN_ARGV, "--out", out], [out])


# ------------------------------------------------------------------------------ place
PLACE_RECORDED = ("planner.placement:study", "planner.report.placement:figures")
#: The phases of ``place``: the sweep, the full plans, the report, writing, the swap.
PLACE_PHASES: dict[str, tuple] = {
    "sweep": ("call", "planner.placement:run_sweep"),
    "full plans": ("call", "planner.placement:plan"),
    "building the report": ("call", "planner.report.placement:figures"),
    "writing summary.json": ("write", _named("summary.json")),
    "writing scores.csv": ("write", _named("scores.csv")),
    "writing report.html": ("write", _named("report.html")),
    "the swap": ("swap",),
}
PLACE_COMPUTING = ("sweep", "full plans")


@pytest.fixture(scope="module")
def place_previous(tmp_path_factory) -> tuple[Path, dict]:
    """A placement study's folder (report included) and what its run computed."""
    return _previous_run(tmp_path_factory, "place_previous", PLACE_ARGV, PLACE_RECORDED)


@pytest.mark.parametrize("failure", FAILURES)
@pytest.mark.parametrize("phase", PLACE_PHASES)
def test_a_failing_placement_study_leaves_the_previous_study_whole(
    tmp_path, capsys, monkeypatch, place_previous, phase, failure
):
    previous, calls = place_previous
    out = tmp_path / "run"
    shutil.copytree(previous, out)
    if phase not in PLACE_COMPUTING:
        _reuse(monkeypatch, {k: v for k, v in calls.items() if ("call", k) != PLACE_PHASES[phase]})
    _inject(monkeypatch, PLACE_PHASES[phase], FAILURES[failure])
    _check_failed_run(capsys, failure, [*PLACE_ARGV, "--out", out], [out])


# ------------------------------------------------------------------------------ identify
#: The report's figures are recorded as empty (their drawing, seconds, is tested with the report).
IDENTIFY_RECORDED = ("problems.identify.campaigns:identify_campaigns",)
IDENTIFY_FIGURES = "planner.identify_report.writer:render_figures"
#: The phases of ``identify``: the fit, building the report, writing the model file (written
#: first, moved in last), the report's files, the swap of the report folder.
IDENTIFY_PHASES: dict[str, tuple] = {
    "fit": ("call", "problems.identify.campaigns:identify_campaigns"),
    "building the report": ("call", "planner.identify_report.writer:report_html"),
    "writing the model file": ("write", lambda p: p.name.startswith(".model.toml" + SIBLING_TAG)),
    "writing report.json": ("write", _named("report.json")),
    "writing report.html": ("write", _named("report.html")),
    "the swap": ("swap",),
}


def _identify_argv(folder: Path, data: Path) -> list[Any]:
    return ["identify", "--robot", "ur5", "--data", data, "--out", folder / "model.toml", "--report", folder / "report"]


@pytest.fixture(scope="module")
def identify_previous(tmp_path_factory) -> tuple[Path, Path, dict]:
    """A model file and its report folder (``<folder>/model.toml``, ``<folder>/report``), the
    measurements they were identified from, and the identification."""
    folder = tmp_path_factory.mktemp("identify_previous")
    (folder / "sim.toml").write_text(CAMPAIGN)
    data = folder / "data.csv"
    assert main(["simulate", "--robot", "ur5", "--config", str(folder / "sim.toml"), "--out", str(data)]) == 0
    calls: dict[str, Any] = {}
    with pytest.MonkeyPatch.context() as mp:
        module, name = IDENTIFY_RECORDED[0].split(":")
        mp.setattr(importlib.import_module(module), name, _record(calls, IDENTIFY_RECORDED[0]))
        mp.setattr(importlib.import_module("planner.identify_report.writer"), "render_figures", lambda *_a: {})
        argv = [*map(str, _identify_argv(folder, data)), "--no-progress", "--candidates", "none"]
        assert main(argv) == 0
    return folder, data, calls


@pytest.mark.parametrize("failure", FAILURES)
@pytest.mark.parametrize("phase", IDENTIFY_PHASES)
def test_a_failing_identification_leaves_the_previous_model_and_report_whole(
    tmp_path, capsys, monkeypatch, identify_previous, phase, failure
):
    previous, data, calls = identify_previous
    shutil.copytree(previous / "report", tmp_path / "report")
    shutil.copy2(previous / "model.toml", tmp_path / "model.toml")
    monkeypatch.setattr(importlib.import_module("planner.identify_report.writer"), "render_figures", lambda *_a: {})
    if phase != "fit":
        _reuse(monkeypatch, calls)
    _inject(monkeypatch, IDENTIFY_PHASES[phase], FAILURES[failure])
    argv = [*_identify_argv(tmp_path, data), "--no-progress"]
    _check_failed_run(capsys, failure, argv, [tmp_path / "model.toml", tmp_path / "report"])


def test_identify_writes_its_model_and_report_together(tmp_path, capsys, monkeypatch, identify_previous):
    """The model file goes in only with its report: both new after a run that ends well."""
    previous, data, calls = identify_previous
    shutil.copytree(previous / "report", tmp_path / "report")
    (tmp_path / "model.toml").write_text("# an earlier model\n")
    (tmp_path / "report" / "report.md").write_text("an earlier report\n")
    monkeypatch.setattr(importlib.import_module("planner.identify_report.writer"), "render_figures", lambda *_a: {})
    _reuse(monkeypatch, calls)
    code, _, err = _run(capsys, *_identify_argv(tmp_path, data), "--no-progress")
    assert code == 0, err
    assert _snapshot(tmp_path / "model.toml") == _snapshot(previous / "model.toml")
    assert (tmp_path / "report" / "report.md").read_text() != "an earlier report\n"
    assert _siblings(tmp_path / "report") == []


# ------------------------------------------------------------------------------ killed, file-size limit
KILL_SCRIPT = """
import sys, time
import planner.output as output
from planner.cli import main

real = output._write_new_file


def stall(path, data):
    if path.name == "report.html":  # half the report on the disk, then wait to be killed
        whole = data if isinstance(data, bytes) else b"".join(data)
        real(path, whole[: len(whole) // 2])
        print("writing report.html", flush=True)
        time.sleep(600)
    real(path, data)


output._write_new_file = stall
sys.exit(main(sys.argv[1:]))
"""


def test_a_plan_killed_while_writing_its_report_leaves_the_previous_plan(tmp_path, capsys, monkeypatch, plan_previous):
    """SIGKILL while the report is written (the new set half built beside the previous one): the
    previous plan is whole; the next run removes what the killed one left and writes."""
    previous, calls = plan_previous
    out = tmp_path / "run"
    shutil.copytree(previous, out)
    before = _snapshot(out)
    argv = [*PLAN_ARGV, "--out", str(out)]
    child = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(KILL_SCRIPT), *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        for line in child.stdout:  # the plan prints nothing before its files are written
            if line.startswith(b"writing report.html"):
                break
        else:
            pytest.fail(f"the plan ended before writing its report: {child.communicate()[1].decode()}")
        staged = [n for n in _siblings(out) if n.startswith(f".run{SIBLING_TAG}new-")]
        assert len(staged) == 1 and (tmp_path / staged[0] / "report.html").is_file(), _siblings(out)
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        _, err = child.communicate(timeout=SUBPROCESS_TIMEOUT_S)
    assert child.returncode == -signal.SIGKILL, err
    assert _snapshot(out) == before
    assert _siblings(out) == sorted([staged[0], f".run{SIBLING_TAG}lock"])
    _reuse(monkeypatch, calls)
    code, _, err = _run(capsys, *argv)
    assert code == 0, err
    assert "cannot remove" not in err  # the killed run's siblings were removed
    assert _siblings(out) == [] and (out / "report.html").stat().st_size == len(before["report.html"])


def _limit_file_size() -> None:
    """``preexec_fn``: files of at most :data:`FSIZE_LIMIT_BYTES` (Python ignores SIGXFSZ: writes fail with EFBIG)."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (FSIZE_LIMIT_BYTES, FSIZE_LIMIT_BYTES))


def test_a_plan_at_the_file_size_limit_leaves_the_previous_plan(tmp_path, plan_previous):
    """RLIMIT_FSIZE (the system's EFBIG, in a real process): exit 2, one line, the previous plan whole."""
    previous, _calls = plan_previous
    out = tmp_path / "run"
    shutil.copytree(previous, out)
    before = _snapshot(out)
    sizes = sorted(len(v) for v in before.values())
    assert sizes[0] < FSIZE_LIMIT_BYTES < sizes[-1]  # some files fit, some do not
    r = subprocess.run(
        [sys.executable, "-m", "planner", *PLAN_ARGV, "--out", str(out)],
        preexec_fn=_limit_file_size,
        capture_output=True,
        text=True,
        timeout=SUBPROCESS_TIMEOUT_S,
    )
    assert r.returncode == EXIT_USER_ERROR, r.stderr
    line = _error_line(r.stderr)
    assert f"output folder {out}: cannot write" in line and "File too large (EFBIG)" in line
    assert "nothing was changed" in line and "wrote" not in r.stdout
    assert _snapshot(out) == before and _siblings(out) == []


# ------------------------------------------------------------------------------ siblings that stay
def _read_only_for_root() -> None:
    """``preexec_fn``: a root process loses the override of file permissions (no-op for others)."""
    if os.geteuid() != 0:
        return
    prctl = ctypes.CDLL(None, use_errno=True).prctl
    for cap in (CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH):
        if prctl(PR_CAPBSET_DROP, cap, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


def _fake_output(folder: Path, marker: str, content: bytes = b"{}") -> Path:
    """An output folder of compplan with the given marker file and a ``figures/`` sub-folder."""
    s = OutputSet(folder)
    s.add_bytes(marker, content)
    s.add_bytes("figures/fig.png", b"png")
    s.publish()
    return folder


READ_ONLY_SCRIPT = """
import sys
from planner.cli import main
for out in sys.argv[1:]:
    print("exit", main(["map", "--points", "5", "--out", out]), flush=True)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="capabilities and permissions as on Linux")
def test_read_only_outputs_and_leftovers_are_named(tmp_path):
    """A read-only previous output is refused before any work (it could not be removed once
    replaced); a read-only leftover of a killed run is named in a warning with the command that
    removes it, and the run writes."""
    ro = _fake_output(tmp_path / "ro", "compliance_map.json")
    left = Path(f"{siblings.sibling_prefix(tmp_path / 'fresh', siblings.STAGING_KIND)}1-abc")
    (left / "figures").mkdir(parents=True)
    (left / "figures" / "fig.png").write_bytes(b"png")
    before = _snapshot(ro)
    for folder in (ro / "figures", left / "figures"):
        folder.chmod(0o555)
    try:
        try:
            r = subprocess.run(
                [sys.executable, "-c", textwrap.dedent(READ_ONLY_SCRIPT), "ro", "fresh"],
                cwd=tmp_path,
                preexec_fn=_read_only_for_root,
                capture_output=True,
                text=True,
                timeout=SUBPROCESS_TIMEOUT_S,
            )
        except subprocess.SubprocessError as exc:  # no capability to drop (a restricted container)
            pytest.skip(f"cannot drop the permission override: {exc}")
        assert r.stdout.count("exit") == 2, r.stderr
        codes = [int(ln.split()[1]) for ln in r.stdout.splitlines() if ln.startswith("exit")]
        assert codes == [EXIT_USER_ERROR, 0], r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 2, r.stderr
        assert lines[0] == (
            "compplan: error: --out ro: ro/figures is read-only, and the previous output is removed when it is "
            "replaced; make it writable (chmod -R u+w ro) or give another --out"
        )
        assert _snapshot(ro) == before and _siblings(ro) == [left.name]
        hint = f"chmod -R u+w {left} && rm -rf {left}"
        assert lines[1] == (
            f"compplan: warning: --out fresh: cannot remove {left}, left by an earlier run that was stopped "
            f"(Permission denied (EACCES)); remove it with: {hint}"
        )
        assert (tmp_path / "fresh" / "compliance_map.json").is_file()
        subprocess.run(hint, shell=True, check=True, preexec_fn=_read_only_for_root)
        assert not left.exists()
    finally:
        for folder in (ro / "figures", left / "figures"):
            if folder.exists():
                folder.chmod(0o755)


def test_a_previous_version_that_cannot_be_removed_is_named(tmp_path, capsys, monkeypatch, plan_previous):
    """The new set is in place; its previous version, which could not be removed, is named."""
    previous, calls = plan_previous
    out = tmp_path / "run"
    shutil.copytree(previous, out)
    _reuse(monkeypatch, calls)
    real = siblings.remove_path

    def stays(path: Path) -> OSError | None:
        if SIBLING_TAG in path.name:
            return OSError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return real(path)

    monkeypatch.setattr(siblings, "remove_path", stays)
    code, stdout, err = _run(capsys, *PLAN_ARGV, "--out", out)
    assert code == 0 and "wrote" in stdout, err
    kept = [n for n in _siblings(out) if SIBLING_TAG + "new-" in n or SIBLING_TAG + "old-" in n]
    assert len(kept) == 1 and _snapshot(tmp_path / kept[0]) == _snapshot(previous)
    warning = [ln for ln in err.splitlines() if "its previous version" in ln]
    assert warning == [
        f"compplan: warning: output folder {out}: cannot remove {tmp_path / kept[0]}, its previous version (the "
        f"new one is in place) (Permission denied (EACCES)); remove it with: "
        f"chmod -R u+w {tmp_path / kept[0]} && rm -rf {tmp_path / kept[0]}"
    ]


# ------------------------------------------------------------------------------ --force
#: Placeholders of the argument lists below: the output folder, a run folder (export's input).
OUT, RUN = "{out}", "{run}"
#: Every command that writes an output folder: what it writes, its arguments and the option
#: naming the folder.
WRITERS: dict[str, tuple[FolderKind, tuple[str, ...], str]] = {
    "plan": (FolderKind.PLAN, ("plan", "drilling_cone", "--out", OUT), "--out"),
    "demo": (FolderKind.PLAN, ("demo", "--out", OUT), "--out"),
    "pose": (FolderKind.POSE, ("pose", "drilling_cone", "--out", OUT), "--out"),
    "map": (FolderKind.MAP, ("map", "--out", OUT), "--out"),
    "place": (FolderKind.PLACEMENT, ("place", "placement_milling", "--out", OUT), "--out"),
    "identify": (
        FolderKind.IDENTIFICATION,
        ("identify", "--robot", "ur5", "--data", "data.csv", "--out", "model.toml", "--report", OUT),
        "--report",
    ),
    "export": (FolderKind.EXPORT, ("export", RUN, "--format", "rosbag2", "--out", OUT), "--out"),
    "design": (
        FolderKind.DESIGN,
        ("design", "--model", "model.toml", "--pool", "pool.csv", "--n", "5", "--out", "c.csv", "--report", OUT),
        "--report",
    ),
}
#: A folder of each kind with a marker: its marker file and contents.
MARKED: dict[FolderKind, tuple[str, bytes]] = {
    FolderKind.PLAN: ("summary.json", b'{"command": "plan"}'),
    FolderKind.PLACEMENT: ("summary.json", b'{"command": "place"}'),
    FolderKind.IDENTIFICATION: ("report.json", b"{}"),
    FolderKind.DESIGN: ("report.json", b'{"command": "design"}'),
    FolderKind.MAP: ("compliance_map.json", b"{}"),
    FolderKind.POSE: ("pose.json", b"{}"),
}
FORCE_CASES = [(c, k) for c, (own, _, _) in WRITERS.items() for k in MARKED if k is not own]


class _CheckPassed(InputError):
    """Raised where a command locks its output: the output's checks have passed."""


@pytest.mark.parametrize("command,kind", FORCE_CASES, ids=[f"{c}-over-{k.name.lower()}" for c, k in FORCE_CASES])
def test_another_commands_output_is_replaced_only_with_force(
    tmp_path, capsys, monkeypatch, plan_previous, command, kind
):
    """Every writing command refuses, with one line and before any work, a folder holding another
    command's output; with ``--force`` it goes on (to the lock of its output)."""
    own, argv, option = WRITERS[command]
    out = _fake_output(tmp_path / "out", *MARKED[kind])
    assert output.output_folder_kind(out) is kind
    before = _snapshot(out)
    args = [str(out) if a == OUT else str(plan_previous[0]) if a == RUN else a for a in argv]
    code, stdout, err = _run(capsys, *args)
    assert code == EXIT_USER_ERROR and stdout == ""
    assert _error_line(err) == (
        f"compplan: error: {option} {out}: holds {kind.phrase} ({kind.command}), which {own.phrase} would "
        f"replace whole; use --force to replace it, or another {option}"
    )
    assert _snapshot(out) == before and _siblings(out) == []

    def passed(*_a: Any, **_k: Any) -> None:
        raise _CheckPassed("the output checks passed")

    monkeypatch.setattr(importlib.import_module("planner.commands.common"), "acquire_output_lock", passed)
    code, _, err = _run(capsys, *args, "--force")
    assert code == EXIT_USER_ERROR and "the output checks passed" in _error_line(err)


def test_an_export_folder_is_replaced_by_the_next_export_and_forced_over_a_plan(tmp_path, capsys, plan_previous):
    """A rosbag2 folder (no marker file) is the export's own: written again without --force; a plan's
    folder is replaced by an export only with it."""
    run = plan_previous[0]
    for _ in range(2):
        code, _, err = _run(capsys, "export", run, "--format", "rosbag2", "--out", tmp_path / "bag")
        assert code == 0, err
    shutil.copytree(run, tmp_path / "other")
    code, _, err = _run(capsys, "export", run, "--format", "rosbag2", "--out", tmp_path / "other")
    assert code == EXIT_USER_ERROR and "holds a plan" in _error_line(err)
    code, _, err = _run(capsys, "export", run, "--format", "rosbag2", "--out", tmp_path / "other", "--force")
    assert code == 0, err
    bag_files = sorted(n.replace("bag", "other") for n in os.listdir(tmp_path / "bag"))  # the .db3 is named after it
    assert sorted(os.listdir(tmp_path / "other")) == bag_files
    assert output.output_folder_kind(tmp_path / "other") is None and _siblings(tmp_path / "other") == []


@pytest.mark.parametrize("command", WRITERS)
def test_a_command_replaces_its_own_output_without_force(tmp_path, capsys, monkeypatch, plan_previous, command):
    """A folder holding the command's own kind of output passes the checks without ``--force``,
    also when it is named after the shipped problem the command reads (``plan drilling_cone --out
    drilling_cone``: the folder is not the input)."""
    own, argv, _option = WRITERS[command]
    monkeypatch.chdir(tmp_path)
    name = next((a for a in argv if a in ("drilling_cone", "placement_milling")), "out")
    if own is FolderKind.EXPORT:
        shutil.copytree(plan_previous[0], tmp_path / "run")
        assert main(["export", "run", "--format", "rosbag2", "--out", name]) == 0
    else:
        _fake_output(tmp_path / name, *MARKED[own])
    assert output.output_folder_kind(name) is (None if own is FolderKind.EXPORT else own)

    def passed(*_a: Any, **_k: Any) -> None:
        raise _CheckPassed("the output checks passed")

    monkeypatch.setattr(importlib.import_module("planner.commands.common"), "acquire_output_lock", passed)
    args = [name if a == OUT else "run" if a == RUN else a for a in argv]
    code, _, err = _run(capsys, *args)
    assert code == EXIT_USER_ERROR and "the output checks passed" in _error_line(err)
