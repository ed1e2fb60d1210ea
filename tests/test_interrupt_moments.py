"""Interrupts at random moments of every long command (issue 34).

Each long command (``plan`` of an NLP-heavy shipped problem and of a G-code program, ``demo``,
``identify``, ``design``, ``place``, ``map``, ``report``, ``predict``, ``export``) is run once in
full, as the user runs it (``python -m planner`` in a process of its own, stderr not a terminal),
to learn its duration T and to leave a previous output; then it is run again and stopped by a
signal at a random moment in (:data:`FIRST_MOMENT_S`, :data:`LAST_MOMENT_FRACTION` x T): SIGINT to
its process group (Ctrl-C at a terminal) or SIGTERM to the process (``kill``, a job scheduler).
An interrupted command must

* exit 130 within :data:`INTERRUPT_LATENCY_S` of the signal (the issue asks for a second: the
  margin is for a loaded 2-core CI machine; ``benchmarks/interrupt_campaign.py`` measures many
  moments and prints the maxima);
* end its stderr with exactly one line ``compplan: interrupted`` (``terminated`` for SIGTERM), or
  ``compplan: interrupted after writing X (complete)``, with no traceback and no CasADi
  ``KeyboardInterruptException`` warning;
* leave every previous output byte for byte as it was, but the ones it says it wrote (which are
  then whole: the full run's files), no hidden ``.compplan-`` sibling and no process of its own.

A command that finished before the signal exits 0 with its new outputs whole.  The moments come
from a seeded generator: the seed is ``$COMPPLAN_TEST_SEED`` if set, else a fresh one, so each run
explores new moments; every assertion message prints the seed and the moment, and
``COMPPLAN_TEST_SEED=<seed> python -m pytest tests/test_interrupt_moments.py`` repeats them.

The helpers (:class:`Case`, :func:`prepare_inputs`, :func:`run_full`, :func:`run_interrupted`,
:func:`defects`) are shared with ``benchmarks/interrupt_campaign.py``, which runs many moments per
command and prints a table.
"""

from __future__ import annotations

import hashlib
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

# a small G-code part: straight moves, corners, a dwell, and its problem (a template of its file name)
from tests.test_program_path import PROBLEM as PROGRAM_PROBLEM
from tests.test_program_path import PROGRAM

#: Seconds from the signal to the exit of the command that an interrupt may take (the issue asks
#: for one second; the margin is for a loaded 2-core CI machine).
INTERRUPT_LATENCY_S = 2.5
#: Exit status of an interrupted command.
EXIT_INTERRUPTED = 130
#: The earliest moment of a signal (s after the start of the process): the interpreter and the
#: command line's first imports come before its handlers are installed.
FIRST_MOMENT_S = 0.2
#: The latest moment of a signal, as a fraction of the full run's duration.
LAST_MOMENT_FRACTION = 0.95
#: The environment variable that fixes the seed of the moments.
SEED_VARIABLE = "COMPPLAN_TEST_SEED"
#: Seconds a command may take (a bound against a hang, not a timing assertion).
SUBPROCESS_TIMEOUT_S = 600
#: Seconds after the command's exit within which its worker processes must be gone.
CHILD_GRACE_S = 1.0
#: What marks a hidden sibling of an output while it is written (planner.output's SIBLING_TAG).
SIBLING_MARK = ".compplan-"
#: The last line of an interrupted command's stderr.
LAST_LINE = re.compile(r"compplan: (interrupted|terminated)( after writing (?P<written>.+) \(complete\))?")
#: Lines an interrupted command must not print.
FORBIDDEN = ("Traceback", "KeyboardInterruptException", "Exception ignored")

#: The simulated campaign ``identify`` reads (small: the fit takes seconds).
CAMPAIGN = 'seed = 3\nunits = "mm"\n[campaign]\nposes = 30\n[noise]\nsigma_m = 2e-5\n[effects.gravity]\n'


@dataclass(frozen=True)
class Case:
    """A long command: its arguments (relative to the work folder) and the outputs it writes."""

    name: str
    argv: tuple[str, ...]
    outputs: tuple[str, ...]
    #: (source, copy): inputs the command changes, copied afresh from the prepared ones first.
    copies: tuple[tuple[str, str], ...] = ()
    #: Also stopped with SIGTERM in the test suite (every case is stopped with SIGINT).
    sigterm: bool = False


CASES: tuple[Case, ...] = (
    Case("plan", ("plan", "ur5_tool_thrust", "--out", "plan"), ("plan",), sigterm=True),
    Case("plan-program", ("plan", "part.toml", "--out", "program"), ("program",), sigterm=True),
    Case("demo", ("demo", "--out", "demo"), ("demo",)),
    Case(
        "identify",
        ("identify", "--robot", "ur5", "--data", "data.csv", "--out", "model.toml", "--report", "identify"),
        ("model.toml", "identify"),
        sigterm=True,
    ),
    Case(
        "design",
        ("design", "--model", "input_model.toml", "--problem", "ur5_tool_thrust", "--n", "12")
        + ("--out", "campaign.csv", "--report", "design", "--no-progress"),
        ("campaign.csv", "design"),
    ),
    Case(
        "place",
        ("place", "placement_milling", "--grid", "x_m=0:0.2:2,y_m=0:0:1,yaw_deg=0:0:1", "--top", "0", "--out", "place"),
        ("place",),
        sigterm=True,
    ),
    Case("map", ("map", "--out", "map"), ("map",)),
    Case("report", ("report", "reported"), ("reported",), copies=(("run", "reported"),), sigterm=True),
    Case(
        "predict", ("predict", "--model", "input_model.toml", "--input", "data.csv", "--out", "pred.csv"), ("pred.csv",)
    ),
    Case("export", ("export", "run", "--format", "rapid", "--out", "run.mod"), ("run.mod",)),
)


def command(case: Case) -> list[str]:
    """The process's command line: this checkout's command line, as the user runs it."""
    return [sys.executable, "-m", "planner", *case.argv]


def _environment() -> dict[str, str]:
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH", "")) if p)
    return env


def prepare_inputs(folder: Path) -> None:
    """The inputs of :data:`CASES` in ``folder``: a simulated campaign, a model identified from it,
    a plan run (for ``report`` and ``export``) and a G-code problem."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "campaign.toml").write_text(CAMPAIGN)
    (folder / "part.ngc").write_text(PROGRAM)
    (folder / "part.toml").write_text(PROGRAM_PROBLEM.format(file="part.ngc"))
    steps = (
        ("simulate", "--robot", "ur5", "--config", "campaign.toml", "--out", "data.csv"),
        ("identify", "--robot", "ur5", "--data", "data.csv", "--out", "input_model.toml", "--report", "input_id"),
        ("plan", "drilling_cone", "--no-optimise", "--no-report", "--out", "run"),
    )
    for argv in steps:
        done = subprocess.run(
            [sys.executable, "-m", "planner", *argv],
            cwd=folder,
            env=_environment(),
            capture_output=True,
            text=True,
            timeout=SUBPROCESS_TIMEOUT_S,
        )
        assert done.returncode == 0, f"{' '.join(argv)}: {done.stderr[-2000:]}"


# ------------------------------------------------------------------------------ outputs
def tree(path: Path) -> dict[str, str]:
    """Every file of an output (a file or a folder): relative name -> SHA-256 of its bytes."""
    if path.is_file():
        return {".": hashlib.sha256(path.read_bytes()).hexdigest()}
    return {
        str(p.relative_to(path)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(path.rglob("*"))
        if p.is_file()
    }


def siblings(folder: Path) -> list[str]:
    """Hidden siblings of outputs left in ``folder`` (and one level down)."""
    return sorted(
        str(p.relative_to(folder)) for p in [*folder.iterdir(), *folder.glob("*/*")] if SIBLING_MARK in p.name
    )


# ------------------------------------------------------------------------------ runs
@dataclass
class Outcome:
    """What a run of a command did."""

    code: int
    stderr: str
    duration_s: float
    #: Seconds from the signal to the exit (None: no signal was sent, the command had ended).
    latency_s: float | None = None
    #: Processes of its process group still alive after its exit.
    leftovers: list[str] = field(default_factory=list)


def _reset_copies(case: Case, folder: Path) -> None:
    for source, copy in case.copies:
        if not (folder / copy).exists():
            shutil.copytree(folder / source, folder / copy)


def _group_processes(pgid: int) -> list[str]:
    import psutil

    found = []
    for proc in psutil.process_iter(["pid", "name", "status"]):
        try:
            if os.getpgid(proc.pid) == pgid and proc.info["status"] != psutil.STATUS_ZOMBIE:
                found.append(f"{proc.info['pid']} {proc.info['name']}")
        except (ProcessLookupError, psutil.Error):
            continue
    return found


def _leftovers(pgid: int) -> list[str]:
    deadline = time.monotonic() + CHILD_GRACE_S
    while True:
        found = _group_processes(pgid)
        if not found or time.monotonic() > deadline:
            return found
        time.sleep(0.05)


def run(case: Case, folder: Path, sig: int | None = None, at_s: float = 0.0, group: bool = False) -> Outcome:
    """Run ``case`` in ``folder``; with ``sig``, send it ``at_s`` seconds after the start (to the
    process group with ``group``: Ctrl-C at a terminal) unless the command has ended."""
    _reset_copies(case, folder)
    start = time.monotonic()
    proc = subprocess.Popen(
        command(case),
        cwd=folder,
        env=_environment(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group: what is left of it is found by the group
    )
    sent = None
    if sig is not None:
        try:
            proc.wait(timeout=at_s)
        except subprocess.TimeoutExpired:
            if group:
                os.killpg(proc.pid, sig)
            else:
                proc.send_signal(sig)
            sent = time.monotonic()
    try:
        _, err = proc.communicate(timeout=SUBPROCESS_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
    end = time.monotonic()
    return Outcome(proc.returncode, err, end - start, None if sent is None else end - sent, _leftovers(proc.pid))


def run_full(case: Case, folder: Path) -> tuple[Outcome, dict[str, dict[str, str]]]:
    """Run ``case`` to its end: its outcome and its outputs' files."""
    outcome = run(case, folder)
    assert outcome.code == 0, f"{case.name}: the full run failed:\n{outcome.stderr[-3000:]}"
    outputs = {o: tree(folder / o) for o in case.outputs}
    assert all(outputs.values()), f"{case.name}: the full run wrote no {[o for o, t in outputs.items() if not t]}"
    return outcome, outputs


def moments(seed: int, duration_s: float, n: int) -> list[float]:
    """``n`` moments in (FIRST_MOMENT_S, LAST_MOMENT_FRACTION x duration_s), from ``seed``."""
    rng = random.Random(seed)
    last = max(FIRST_MOMENT_S, LAST_MOMENT_FRACTION * duration_s)
    return [rng.uniform(FIRST_MOMENT_S, last) for _ in range(n)]


def defects(
    case: Case,
    folder: Path,
    sig: int,
    outcome: Outcome,
    before: dict[str, dict[str, str]],
    full: dict[str, dict[str, str]],
) -> list[str]:
    """What an interrupted run of ``case`` did wrong (empty: handled).  ``before``: its outputs'
    files before the run; ``full``: a full run's (the names of a whole output)."""
    found: list[str] = []
    lines = outcome.stderr.strip().splitlines()
    after = {o: tree(folder / o) for o in case.outputs}
    for word in FORBIDDEN:
        if word in outcome.stderr:
            found.append(f"stderr holds {word!r}")
    if outcome.latency_s is not None and outcome.latency_s > INTERRUPT_LATENCY_S:
        found.append(f"latency {outcome.latency_s:.2f} s > {INTERRUPT_LATENCY_S} s")
    if outcome.leftovers:
        found.append(f"processes left: {outcome.leftovers}")
    left = siblings(folder)
    if left:
        found.append(f"hidden siblings left: {left}")
    if outcome.code == 0:  # it had finished: the new outputs, whole
        for o in case.outputs:
            if sorted(after[o]) != sorted(full[o]):
                found.append(f"exit 0 but {o} is not whole: {sorted(set(full[o]) ^ set(after[o]))[:5]}")
        return found
    if outcome.code != EXIT_INTERRUPTED:
        found.append(f"exit {outcome.code}, not {EXIT_INTERRUPTED}")
    word = "terminated" if sig == signal.SIGTERM else "interrupted"
    stops = [x for x in lines if LAST_LINE.fullmatch(x)]
    last = LAST_LINE.fullmatch(lines[-1]) if lines else None
    if last is None or len(stops) != 1 or last.group(1) != word:
        found.append(f"stderr does not end in one 'compplan: {word}' line: {lines[-3:]}")
    said = last.group("written") if last is not None and last.group("written") else ""
    written = {(folder / w).resolve() for w in said.split(", ") if w}
    for o in case.outputs:
        if (folder / o).resolve() in written:
            if sorted(after[o]) != sorted(full[o]):
                found.append(f"says it wrote {o}, which is not whole")
        elif after[o] != before[o]:
            changed = sorted(k for k in set(before[o]) | set(after[o]) if before[o].get(k) != after[o].get(k))
            found.append(f"previous {o} changed: {changed[:5]}")
    return found


# ------------------------------------------------------------------------------ the tests
def _seed() -> int:
    return int(os.environ.get(SEED_VARIABLE) or random.SystemRandom().randrange(1 << 31))


#: The seed of this session's moments (printed in every assertion message).
SEED = _seed()


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    pytest.importorskip("psutil")
    folder = tmp_path_factory.mktemp("interrupt_moments")
    prepare_inputs(folder)
    return folder


@pytest.fixture(scope="module")
def full_runs(work) -> dict[str, tuple[Outcome, dict[str, dict[str, str]]]]:
    """Each case's full run (once): its duration and its outputs (the previous ones of the tests)."""
    return {}


def _stops() -> list:
    params = []
    for case in CASES:
        params.append(pytest.param(case, signal.SIGINT, id=f"{case.name}-SIGINT"))
        if case.sigterm:
            params.append(pytest.param(case, signal.SIGTERM, id=f"{case.name}-SIGTERM"))
    return params


@pytest.mark.slow
@pytest.mark.parametrize("case, sig", _stops())
def test_interrupt_at_a_random_moment(work, full_runs, case, sig):
    """Stopped at a random moment, the command exits 130 at once with one line, leaving the
    previous output whole (or, finished, its new one); SIGINT goes to the process group, as
    Ctrl-C does at a terminal, SIGTERM to the process, as ``kill`` does."""
    if case.name not in full_runs:
        full_runs[case.name] = run_full(case, work)
    full, outputs = full_runs[case.name]
    seed = SEED + CASES.index(case) + 1000 * (sig == signal.SIGTERM)
    (at_s,) = moments(seed, full.duration_s, 1)
    before = {o: tree(work / o) for o in case.outputs}
    outcome = run(case, work, sig, at_s, group=sig == signal.SIGINT)
    found = defects(case, work, sig, outcome, before, outputs)
    where = (
        f"{case.name}: {signal.Signals(sig).name} at {at_s:.2f} s of a {full.duration_s:.1f} s run "
        f"({SEED_VARIABLE}={SEED}; exit {outcome.code}, latency {outcome.latency_s} s)"
    )
    assert not found, where + ": " + "; ".join(found) + "\n" + outcome.stderr[-3000:]
    if outcome.code == 0:  # the outputs it wrote are the previous ones of the next test
        full_runs[case.name] = (full, {o: tree(work / o) for o in case.outputs})


def test_moments_are_reproducible_and_in_range():
    """The same seed, the same moments, all inside (FIRST_MOMENT_S, LAST_MOMENT_FRACTION x T)."""
    a, b = moments(7, 4.0, 20), moments(7, 4.0, 20)
    assert a == b and all(FIRST_MOMENT_S <= x <= LAST_MOMENT_FRACTION * 4.0 for x in a)
    assert moments(8, 4.0, 20) != a


def test_defects_names_each_broken_rule(tmp_path):
    """The checker is honest: a traceback, a second line, a wrong word, a changed previous output,
    an exit other than 130, a slow exit and a hidden sibling are each reported."""
    case = Case("x", ("x",), ("out",))
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "a.txt").write_text("old")
    before = {"out": tree(tmp_path / "out")}
    good = Outcome(EXIT_INTERRUPTED, "compplan: [    0.3 s] posture\ncompplan: interrupted\n", 1.0, 0.1)
    assert defects(case, tmp_path, signal.SIGINT, good, before, before) == []
    assert defects(case, tmp_path, signal.SIGTERM, good, before, before)  # the wrong word
    bad = Outcome(3, "Traceback (most recent call last):\ncompplan: interrupted\ncompplan: interrupted\n", 9.0, 9.0)
    found = " ".join(defects(case, tmp_path, signal.SIGINT, bad, before, before))
    assert "Traceback" in found and "exit 3" in found and "latency" in found and "one 'compplan" in found
    (tmp_path / "out" / "a.txt").write_text("new")
    (tmp_path / ".out.compplan-123").mkdir()
    found = " ".join(defects(case, tmp_path, signal.SIGINT, good, before, before))
    assert "previous out changed" in found and "hidden siblings" in found
