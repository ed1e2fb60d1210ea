"""Every command works without a C compiler, and a broken compile cache never breaks a run.

Without compiled code the batch evaluators, the IK and the posture NLP run on CasADi's
virtual machine: same results to rounding, one note line from the command line
(``compplan: note: ...``), the library silent.  The compile cache (``$COMPPLAN_CACHE``)
that is a file, is not writable or holds a truncated or garbage library is bypassed or
rebuilt, again with one note line and exit status 0.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from models import AnalyticIK, KinematicModel, load_robot
from models import codegen, compiler
from models.codegen import batch_function
from models.compiler import (
    NO_COMPILER_ENV,
    CompileError,
    clear_codegen_notes,
    codegen_notes,
    compile_shared_library,
)

from .conftest import OUT, PAPER_RUN_ARGV, ROBOTS

#: Results with and without compiled code agree to this, relative to max(1, |value|).
SAME_RESULT_RTOL = 1e-9
#: ... except the time-parametrised trajectories: TOPP-RA's piecewise solution turns path
#: differences of 1e-15 rad (compiled C against the virtual machine) into ~1e-9 in accelerations.
TRAJECTORY_RTOL = 1e-7
#: FK, Jacobian (m, rad) of compiled C and the virtual machine agree to this.
KINEMATICS_ATOL = 1e-12
#: Compliances (m/N ... rad/(N m)) agree to this relative to their largest element.
COMPLIANCE_RTOL = 1e-12
#: IK joint angles (rad) agree to this.
IK_ATOL = 1e-9
#: Poses per robot in the compiled-vs-VM comparisons.
N_POSES = 500
#: Seconds a command may take in these tests (the VM is slower than compiled code).
COMMAND_TIMEOUT_S = 600
#: The prefix of the command line's note lines.
NOTE_PREFIX = "compplan: note: "
#: Summary keys holding wall-clock times (differ run to run), left out of comparisons.
TIME_KEY_PART = "time"
#: Summary keys describing the run (command line, date, input files), left out of comparisons.
RUN_KEYS = frozenset({"provenance"})
#: Output files compared number by number.
COMPARED_CSV = ("path.csv", "waypoints.csv", "branches.csv", "trajectory.csv", "trajectory_toppra.csv")
#: Grid of the small compliance map used to exercise the compile cache (compiles FK, C and IK).
MAP_ARGS = ("map", "--points", "5")
#: A tiny C library for the in-process cache tests.
PROBE_SRC = "int compplan_probe(void) { return 42; }\n"
PROBE_VALUE = 42


# ------------------------------------------------------------------------------ helpers
@pytest.fixture(autouse=True)
def _fresh_notes():
    clear_codegen_notes()
    yield
    clear_codegen_notes()


def _env(**changes: str | None) -> dict[str, str]:
    """This process's environment without the no-compiler switch, with ``changes`` applied
    (None removes a variable)."""
    env = {k: v for k, v in os.environ.items() if k != NO_COMPILER_ENV}
    for k, v in changes.items():
        if v is None:
            env.pop(k, None)
        else:
            env[k] = v
    return env


def _compplan(args: tuple[str, ...] | list[str], env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "planner", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=COMMAND_TIMEOUT_S,
    )


def _notes(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith(NOTE_PREFIX)]


def _assert_clean(proc: subprocess.CompletedProcess, n_notes: int, *words: str) -> str:
    """Exit 0, no traceback, exactly ``n_notes`` note lines containing ``words``; the note."""
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, proc.stderr
    notes = _notes(proc.stderr)
    assert len(notes) == n_notes, proc.stderr
    for w in words:
        assert w in (notes[0] if notes else ""), proc.stderr
    return notes[0] if notes else ""


def _have_compiler() -> bool:
    """A C compiler is configured here (``$CC``, else ``gcc`` or ``cc`` on ``PATH``)."""
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    return bool(cc) and shutil.which(cc.split()[0]) is not None


needs_compiler = pytest.mark.skipif(not _have_compiler(), reason="no C compiler on this machine")


def _close(a: float, b: float, rtol: float = SAME_RESULT_RTOL) -> bool:
    return abs(a - b) <= rtol * max(1.0, abs(a), abs(b))


def _compare_json(a, b, where: str = "summary") -> None:
    if isinstance(a, dict):
        assert set(a) == set(b), (where, set(a) ^ set(b))
        for k in a:
            if TIME_KEY_PART not in k and k not in RUN_KEYS:
                _compare_json(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _compare_json(x, y, f"{where}[{i}]")
    elif isinstance(a, float) or (isinstance(a, int) and not isinstance(a, bool) and isinstance(b, float)):
        assert _close(float(a), float(b)) or (math.isnan(a) and math.isnan(b)), (where, a, b)
    else:
        assert a == b, (where, a, b)


def _compare_outputs(ref: Path, out: Path) -> None:
    """summary.json and the CSV files of two runs agree to :data:`SAME_RESULT_RTOL`."""
    _compare_json(json.loads((ref / "summary.json").read_text()), json.loads((out / "summary.json").read_text()))
    for name in COMPARED_CSV:
        if not (ref / name).exists():
            assert not (out / name).exists(), name
            continue
        ra, rb = (
            [row for row in csv.reader((d / name).open()) if row and not row[0].startswith("#")] for d in (ref, out)
        )
        assert ra[0] == rb[0] and len(ra) == len(rb), name
        rtol = TRAJECTORY_RTOL if name.startswith("trajectory") else SAME_RESULT_RTOL
        for i, (x, y) in enumerate(zip(ra[1:], rb[1:])):
            for u, v in zip(x, y):
                try:
                    fu, fv = float(u), float(v)
                except ValueError:
                    assert u == v, (name, i, u, v)
                    continue
                assert _close(fu, fv, rtol) or (math.isnan(fu) and math.isnan(fv)), (name, i, u, v)


# ------------------------------------------------------------------------------ commands
#: (command, how the compiler is disabled).  ``env``: $COMPPLAN_NO_COMPILER=1 (the cache is
#: not even read); ``cc``: CC=/bin/false with an empty cache; ``path``: CC unset, no gcc on PATH.
COMMANDS = {
    "demo": ("demo", "--no-report"),
    "plan": ("plan", "machining_offaxis", "--no-report"),
}
#: The compiled runs the commands are compared with, run in this process once per session
#: (``demo`` plans ``paper_4_4``: the same summary and files but for the run's provenance, times
#: and its two quick figures, which are not compared).
REFERENCE_ARGV = {
    "demo": PAPER_RUN_ARGV,
    "plan": ("plan", "machining_offaxis", "--out", OUT, "--no-report"),
}


@pytest.fixture(scope="module")
def reference(shared_cli) -> dict[str, Path]:
    """Each command's output with the compiler (the usual cache)."""
    if not _have_compiler():
        pytest.skip("no C compiler: nothing to compare the virtual machine with")
    if os.environ.get(NO_COMPILER_ENV):
        pytest.skip(f"{NO_COMPILER_ENV} is set for the tests: no compiled run to compare with")
    out = {}
    for name, argv in REFERENCE_ARGV.items():
        run = shared_cli.run(*argv)
        assert "virtual machine" not in run.err, run.err
        out[name] = run.folder
    return out


@pytest.mark.slow
@pytest.mark.parametrize("command, how", [("demo", "env"), ("plan", "cc"), ("demo", "path")])
def test_command_without_compiler(command, how, reference, tmp_path):
    if how == "env":
        env, words = _env(**{NO_COMPILER_ENV: "1"}), (f"{NO_COMPILER_ENV}=1",)
    elif how == "cc":
        env, words = _env(CC="/bin/false", COMPPLAN_CACHE=str(tmp_path / "cache")), ("CC=/bin/false",)
    else:
        empty = tmp_path / "bin"
        empty.mkdir()
        env = _env(CC=None, PATH=str(empty), COMPPLAN_CACHE=str(tmp_path / "cache"))
        words = ("no gcc or cc on PATH",)
    proc = _compplan([*COMMANDS[command], "--out", str(tmp_path / "out")], env, tmp_path)
    _assert_clean(proc, 1, "virtual machine", *words)
    _compare_outputs(reference[command], tmp_path / "out")


# ------------------------------------------------------------------------------ kinematics
@pytest.mark.parametrize("name", ROBOTS)
@needs_compiler
def test_batches_compiled_equal_virtual_machine(name, monkeypatch):
    robot = load_robot(name)
    rng = np.random.default_rng(sum(map(ord, name)))
    q = rng.uniform(-np.pi, np.pi, (N_POSES, 6))
    F = np.array([3.0, -2.0, 10.0, 0.5, -0.2, 0.1])
    results = {}
    for mode in ("vm", "compiled"):
        if mode == "vm":
            monkeypatch.setenv(NO_COMPILER_ENV, "1")
        else:
            monkeypatch.delenv(NO_COMPILER_ENV, raising=False)
        km, ik = KinematicModel(robot), AnalyticIK(robot)
        T = km.tcp(q)
        p, R, J, C = km.batch(km.kinetostatics, q)
        D = km.batch(km.deflection, q, F)[0]  # a wrench broadcast to every pose
        sol = ik.solve(T)
        assert km.evaluator(km.fk_tcp).compiled is (mode == "compiled")
        assert ik.evaluator.compiled is (mode == "compiled")
        results[mode] = (T, p, R, J, C, D, sol)
    vm, cc = results["vm"], results["compiled"]
    for a, b in zip(vm[:4], cc[:4]):
        assert a.shape == b.shape
        assert np.allclose(a, b, rtol=0.0, atol=KINEMATICS_ATOL)
    for a, b in zip(vm[4:6], cc[4:6]):
        assert a.shape == b.shape
        assert np.allclose(a, b, rtol=0.0, atol=COMPLIANCE_RTOL * np.abs(b).max())
    sv, sc = vm[6], cc[6]
    assert sv.q.shape == sc.q.shape == (N_POSES, 8, 6)
    assert np.array_equal(sv.status, sc.status)
    assert np.array_equal(np.isnan(sv.q), np.isnan(sc.q))
    assert np.allclose(sv.q[sv.valid], sc.q[sc.valid], rtol=0.0, atol=IK_ATOL)
    # the virtual machine was noted once, by the library, silently
    assert [n for n in codegen_notes() if "virtual machine" in n] == [
        f"C compiler disabled ({NO_COMPILER_ENV}=1): {compiler.VM_NOTE}"
    ]


def test_virtual_machine_batch_layout():
    """The VM evaluator takes and returns what the compiled one does: column-major matrix
    rows, broadcast 1-D inputs, (N, rows, cols) outputs, and empty batches."""
    import casadi as ca

    x = ca.SX.sym("x", 2)
    M = ca.SX.sym("M", 2, 3)
    f = ca.Function("layout_probe", [x, M], [ca.mtimes(M.T, x), M * x[0]], ["x", "M"], ["y", "N"])
    ev = codegen.VMBatchFunction(f)
    rng = np.random.default_rng(3)
    xs = rng.normal(size=(5, 2))
    Ms = rng.normal(size=(5, 2, 3))
    y, N = ev(xs, Ms.transpose(0, 2, 1).reshape(5, 6))
    assert y.shape == (5, 3) and N.shape == (5, 2, 3)
    assert np.allclose(y, np.einsum("kij,ki->kj", Ms, xs))
    assert np.allclose(N, Ms * xs[:, :1, None])
    y1, _ = ev(xs, Ms[0].reshape(-1, order="F"))  # one matrix for every pose
    assert np.allclose(y1, xs @ Ms[0])
    y0, N0 = ev(np.empty((0, 2)), np.empty((0, 6)))
    assert y0.shape == (0, 3) and N0.shape == (0, 2, 3)


# ------------------------------------------------------------------------------ no compiler, in process
def test_no_compiler_reasons(monkeypatch, tmp_path):
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv(NO_COMPILER_ENV, "1")
    with pytest.raises(CompileError, match=NO_COMPILER_ENV):
        compile_shared_library(PROBE_SRC, "probe_disabled")
    monkeypatch.delenv(NO_COMPILER_ENV)
    clear_codegen_notes()
    monkeypatch.setenv("CC", "/bin/false")
    with pytest.raises(CompileError, match="CC=/bin/false"):
        compile_shared_library(PROBE_SRC, "probe_false")
    assert codegen_notes() == [f"no usable C compiler (CC=/bin/false: exit status 1): {compiler.VM_NOTE}"]
    clear_codegen_notes()
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.raises(CompileError, match="not found"):
        compile_shared_library(PROBE_SRC, "probe_missing")
    clear_codegen_notes()
    monkeypatch.delenv("CC")
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(CompileError, match="no gcc or cc on PATH"):
        compile_shared_library(PROBE_SRC, "probe_path")
    assert len(codegen_notes()) == 1
    # batch_function falls back silently to the virtual machine
    ev = batch_function(KinematicModel(load_robot("ur5")).fk_tcp)
    assert ev.compiled is False


# ------------------------------------------------------------------------------ cache, in process
def _probe(lib: Path) -> int:
    """Load a probe library in a fresh process (a process keeps the first copy it loaded)."""
    code = f"import ctypes; print(ctypes.CDLL({str(lib)!r}).compplan_probe())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return int(out.stdout)


@needs_compiler
@pytest.mark.parametrize("damage", ["truncated", "garbage"])
def test_corrupt_library_is_rebuilt(damage, monkeypatch, tmp_path):
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path))
    monkeypatch.delenv(NO_COMPILER_ENV, raising=False)
    src = PROBE_SRC + f"/* {damage} */\n"
    lib = compile_shared_library(src, "probe")
    assert lib.parent == tmp_path and codegen_notes() == []
    good = lib.read_bytes()
    bad = good[: len(good) // 2] if damage == "truncated" else os.urandom(len(good))
    lib.write_bytes(bad)
    assert compile_shared_library(src, "probe") == lib
    (note,) = codegen_notes()
    assert note.startswith(f"cached library {lib} was corrupt") and note.endswith("rebuilt")
    assert lib.read_bytes() != bad and _probe(lib) == PROBE_VALUE


@needs_compiler
def test_cache_that_is_a_file_is_bypassed(monkeypatch, tmp_path):
    cache = tmp_path / "cache"
    cache.write_text("not a folder")
    monkeypatch.setenv("COMPPLAN_CACHE", str(cache))
    monkeypatch.delenv(NO_COMPILER_ENV, raising=False)
    src = PROBE_SRC + "/* file */\n"
    lib = compile_shared_library(src, "probe")
    assert lib.parent != cache and _probe(lib) == PROBE_VALUE
    (note,) = codegen_notes()
    assert f"compile cache {cache} is not a folder" in note and "for this run only" in note
    clear_codegen_notes()
    assert compile_shared_library(src, "probe") == lib  # reused, noted again for the new run
    assert len(codegen_notes()) == 1
    assert cache.read_text() == "not a folder"


@needs_compiler
def test_unwritable_cache_is_bypassed(monkeypatch, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    monkeypatch.setenv("COMPPLAN_CACHE", str(cache))
    monkeypatch.delenv(NO_COMPILER_ENV, raising=False)
    store = compiler.store_library

    def refuse_cache(lib: Path, data: bytes) -> None:  # root ignores permission bits: refuse here
        if lib.parent == cache:
            raise PermissionError(13, "Permission denied")
        store(lib, data)

    monkeypatch.setattr(compiler, "store_library", refuse_cache)
    lib = compile_shared_library(PROBE_SRC + "/* unwritable */\n", "probe")
    assert lib.parent != cache and _probe(lib) == PROBE_VALUE
    (note,) = codegen_notes()
    assert f"compile cache {cache} is not writable (Permission denied)" in note
    assert list(cache.iterdir()) == []


@needs_compiler
def test_disabled_compiler_ignores_a_valid_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("COMPPLAN_CACHE", str(tmp_path))
    monkeypatch.delenv(NO_COMPILER_ENV, raising=False)
    src = PROBE_SRC + "/* valid */\n"
    lib = compile_shared_library(src, "probe")
    monkeypatch.setenv("CC", "/bin/false")  # a broken compiler: the cache still serves
    assert compile_shared_library(src, "probe") == lib and codegen_notes() == []
    monkeypatch.setenv(NO_COMPILER_ENV, "1")  # disabled: no compiled code at all
    with pytest.raises(CompileError):
        compile_shared_library(src, "probe")


# ------------------------------------------------------------------------------ cache, command line
@pytest.mark.slow
@needs_compiler
def test_command_with_cache_that_is_a_file(tmp_path):
    cache = tmp_path / "cache"
    cache.write_text("")
    proc = _compplan([*MAP_ARGS, "--out", str(tmp_path / "map")], _env(COMPPLAN_CACHE=str(cache)), tmp_path)
    _assert_clean(proc, 1, "is not a folder", "for this run only")


@needs_compiler
@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes into read-only folders")
def test_command_with_unwritable_cache(tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    cache.chmod(0o555)
    try:
        proc = _compplan([*MAP_ARGS, "--out", str(tmp_path / "map")], _env(COMPPLAN_CACHE=str(cache)), tmp_path)
    finally:
        cache.chmod(0o755)
    _assert_clean(proc, 1, "is not writable", "for this run only")


@pytest.mark.slow
@needs_compiler
def test_command_with_corrupt_cache(tmp_path):
    cache = tmp_path / "cache"
    env = _env(COMPPLAN_CACHE=str(cache))
    out = ("--out", str(tmp_path / "map"))
    _assert_clean(_compplan([*MAP_ARGS, *out], env, tmp_path), 0)
    libs = sorted(cache.glob("*.so"))
    assert len(libs) >= 2
    libs[0].write_bytes(libs[0].read_bytes()[:1000])  # truncated (dlopen would die of SIGBUS)
    for lib in libs[1:]:
        lib.write_bytes(os.urandom(lib.stat().st_size))  # garbage
    _assert_clean(_compplan([*MAP_ARGS, *out], env, tmp_path), 1, "was corrupt", "rebuilt")
    _assert_clean(_compplan([*MAP_ARGS, *out], env, tmp_path), 0)
    for lib in libs:
        assert compiler.check_library(lib) is None


def test_library_is_silent(monkeypatch, capfd):
    """Falling back prints nothing: the notes are the command line's to print."""
    monkeypatch.setenv(NO_COMPILER_ENV, "1")
    km = KinematicModel(load_robot("ar5"))
    km.C(np.zeros((3, 6)) + 0.3)
    AnalyticIK(load_robot("ar5")).solve(km.tcp(np.zeros((2, 6)) + 0.2))
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert len(codegen_notes()) == 1
