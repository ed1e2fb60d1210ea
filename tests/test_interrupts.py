"""Interrupts honoured inside native solvers (models/interrupts.py).

IPOPT through CasADi swallows the ``KeyboardInterrupt`` of a Ctrl-C (it stops with
``NonIpopt_Exception_Thrown`` and the call returns as a failed solve); :func:`native_call` raises it
again.  A library that turns the interrupt into another error, or catches it, cannot lose it under
:func:`command_signals`: :func:`raise_if_pending` raises it again.  Tested with real signals sent to
this process at a random moment of the call (the seed is in the message).
"""

from __future__ import annotations

import io
import os
import random
import signal
import subprocess
import sys
import threading
import time

import casadi as ca
import pytest

from models import interrupts

#: From the signal to the ``KeyboardInterrupt`` out of an IPOPT solve, s: the solver polls
#: Python's signals once per iteration (milliseconds here); the margin is for a loaded machine.
SOLVE_STOP_S = 1.0


def _long_solve() -> ca.Function:
    """An IPOPT problem that runs for seconds (a 3000-variable Rosenbrock chain, tight tolerance)."""
    n = 3000
    x = ca.SX.sym("x", n)
    f = ca.sum1(100 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2)
    opts = {"print_time": 0, "ipopt": {"print_level": 0, "sb": "yes", "max_iter": 100000, "tol": 1e-300}}
    return ca.nlpsol("long", "ipopt", {"x": x, "f": f}, opts)


def _send_later(signum: int, after_s: float) -> list[float]:
    sent: list[float] = []

    def send() -> None:
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signum)

    threading.Timer(after_s, send).start()
    return sent


@pytest.fixture
def default_handlers():
    """Python's own handlers for the test (pytest may run with SIGINT ignored)."""
    previous = {s: signal.signal(s, h) for s, h in ((signal.SIGINT, signal.default_int_handler),)}
    yield
    for s, h in previous.items():
        signal.signal(s, h)


def test_ipopt_swallows_ctrl_c_without_the_guard(default_handlers):
    """The reason for the guard: without it, the solve returns as a failed solve and the caller goes on."""
    solver = _long_solve()
    _send_later(signal.SIGINT, 0.3)
    err = io.StringIO()
    stderr, sys.stderr = sys.stderr, err
    try:
        solver(x0=[-1.2] * 3000)
    finally:
        sys.stderr = stderr
    assert solver.stats()["return_status"] == "NonIpopt_Exception_Thrown"
    assert "KeyboardInterruptException" in err.getvalue()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_native_call_raises_the_interrupt_ipopt_swallowed(default_handlers, signum):
    seed = random.randrange(10**6)
    at = random.Random(seed).uniform(0.05, 0.6)
    solver = _long_solve()
    err = io.StringIO()
    stderr, sys.stderr = sys.stderr, err
    with interrupts.command_signals():
        sent = _send_later(signum, at)
        expected = interrupts.Terminated if signum == signal.SIGTERM else KeyboardInterrupt
        try:
            with pytest.raises(expected):
                with interrupts.native_call():
                    solver(x0=[-1.2] * 3000)
        finally:
            sys.stderr = stderr
        stopped = time.perf_counter()
    assert sent, f"seed {seed}: the solve ended before the signal at {at:.2f} s"
    assert stopped - sent[0] < SOLVE_STOP_S, f"seed {seed}: {stopped - sent[0]:.2f} s from the signal"
    assert "KeyboardInterruptException" not in err.getvalue(), err.getvalue()  # reported once, by the CLI


def test_native_call_passes_other_writes_and_errors(default_handlers):
    err = io.StringIO()
    stderr, sys.stderr = sys.stderr, err
    try:
        with pytest.raises(ValueError):
            with interrupts.native_call():
                sys.stderr.write("a warning ")
                sys.stderr.write("in two pieces\n")
                sys.stderr.write("CasADi - WARNING(")
                sys.stderr.write('"KeyboardInterruptException") [ipopt_nlp.cpp:95]\n')
                sys.stderr.write("unfinished")
                raise ValueError("not an interrupt")
    finally:
        sys.stderr = stderr
    assert err.getvalue() == "a warning in two pieces\nunfinished"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_a_library_swallowed_is_raised_again(default_handlers, signum):
    """A broad ``except`` (or CasADi's ``SystemError`` caught as a failure) cannot lose a signal."""
    with interrupts.command_signals():
        try:
            os.kill(os.getpid(), signum)
            time.sleep(0.05)
        except BaseException:
            pass
        assert interrupts.pending() == signum
        with pytest.raises(KeyboardInterrupt) as exc:
            interrupts.raise_if_pending()
        assert isinstance(exc.value, interrupts.Terminated) == (signum == signal.SIGTERM)
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_deferred_holds_both_signals_to_the_end_of_the_block(default_handlers):
    reached: list[str] = []
    with interrupts.command_signals():
        with pytest.raises(interrupts.Terminated):
            with interrupts.deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.05)
                reached.append("moved in")
    assert reached == ["moved in"]


def test_a_forked_worker_ends_on_sigterm_without_a_traceback(tmp_path):
    """A worker forked inside a command must not run the command's handlers (a traceback per worker)."""
    code = (
        "import os, signal, sys, time\n"
        "from models import interrupts\n"
        "with interrupts.command_signals():\n"
        "    pid = os.fork()\n"
        "    if pid == 0:\n"
        "        interrupts.forked_worker_signals()\n"
        "        time.sleep(30)\n"
        "        os._exit(0)\n"
        "    time.sleep(0.5)\n"
        "    os.kill(pid, signal.SIGINT)\n"  # ignored: the parent answers Ctrl-C
        "    time.sleep(0.2)\n"
        "    os.kill(pid, signal.SIGTERM)\n"
        "    _, status = os.waitpid(pid, 0)\n"
        "    print(os.WIFSIGNALED(status), os.WTERMSIG(status))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.stdout.split() == ["True", str(int(signal.SIGTERM))], r.stdout + r.stderr
    assert "Traceback" not in r.stderr, r.stderr


def test_a_signal_handled_inside_a_destructor_is_not_lost_nor_printed(default_handlers, capsys):
    """Python cannot raise out of a destructor: it prints "Exception ignored in ..." with a traceback
    and goes on.  The signal is recorded, the report dropped, and the next check raises it."""

    class Slow:
        def __del__(self) -> None:
            time.sleep(0.3)  # the signal is handled here, between two bytecodes of the destructor

    with interrupts.command_signals():
        _send_later(signal.SIGINT, 0.1)
        obj = Slow()
        del obj
        assert interrupts.pending() == signal.SIGINT  # went on: the destructor swallowed it
        with pytest.raises(KeyboardInterrupt):
            interrupts.raise_if_pending()
    err = capsys.readouterr().err
    assert "Exception ignored" not in err and "KeyboardInterrupt" not in err, err


def test_a_progress_tick_raises_a_lost_signal(default_handlers):
    from planner.progress import TqdmProgress

    with interrupts.command_signals():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)
        except KeyboardInterrupt:  # lost by a library
            pass
        with pytest.raises(interrupts.Terminated):
            TqdmProgress()("posture", 0, 1)


# ------------------------------------------------------------------------------ run as a program
def _program(body: str) -> subprocess.CompletedProcess:
    """``body`` run as a program (a process of its own: the re-raise timer and the signal rules
    of the command line run as a program change the process's handlers)."""
    code = "import os, signal, sys, time\nfrom models import interrupts\n" + body
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env)


#: A library that loses the interrupt (CasADi's overload resolution discards what the Python code
#: it calls raised), then goes on working for up to 5 s unless the interrupt is raised again.
_LOST_THEN_WORK = (
    "try:\n"
    "    with interrupts.command_signals(process={process}):\n"
    "        try:\n"
    "            os.kill(os.getpid(), signal.SIGTERM)\n"
    "            time.sleep(0.05)\n"
    "        except KeyboardInterrupt:\n"
    "            pass\n"
    "        end = time.monotonic() + 5\n"
    "        while time.monotonic() < end:\n"
    "            sum(range(1000))\n"
    "        print('lost')\n"
    "except interrupts.Terminated:\n"
    "    print('raised again')\n"
)


def test_a_lost_signal_is_raised_again_while_the_command_runs():
    """Run as a program, a stop signal a library lost without a trace is raised again (every
    RERAISE_INTERVAL_S) while the command goes on; not so without ``process`` (the reason)."""
    r = _program(_LOST_THEN_WORK.format(process=True))
    assert (r.stdout.strip(), r.returncode) == ("raised again", 0), r.stdout + r.stderr
    r = _program(_LOST_THEN_WORK.format(process=False))
    assert r.stdout.strip() == "lost", r.stdout + r.stderr


def test_the_raise_again_spares_the_unwinding_and_deferred_blocks():
    """The clean-up of the first raise (``finally``, an ``except`` inside it) and a deferred block
    (an output moved into place) run to their end; the interrupt is raised again after the block."""
    body = (
        "done = []\n"
        "try:\n"
        "  with interrupts.command_signals(process=True):\n"
        "    try:\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "        time.sleep(0.05)\n"
        "    finally:\n"
        "        end = time.monotonic() + 0.5\n"
        "        while time.monotonic() < end:\n"
        "            try:\n"
        "                raise OSError('a file already gone')\n"
        "            except OSError:\n"
        "                sum(range(1000))\n"
        "        done.append('clean-up')\n"
        "except interrupts.Terminated:\n"
        "  pass\n"
        "try:\n"
        "  with interrupts.command_signals(process=True):\n"
        "    try:\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "        time.sleep(0.05)\n"
        "    except KeyboardInterrupt:\n"
        "        pass\n"
        "    with interrupts.deferred():\n"
        "        end = time.monotonic() + 0.5\n"
        "        while time.monotonic() < end:\n"
        "            sum(range(1000))\n"
        "        done.append('moved in')\n"
        "    end = time.monotonic() + 5\n"
        "    while time.monotonic() < end:\n"
        "        sum(range(1000))\n"
        "    done.append('lost')\n"
        "except interrupts.Terminated:\n"
        "  pass\n"
        "print(' '.join(done))\n"
    )
    r = _program(body)
    assert r.stdout.strip() == "clean-up moved in", r.stdout + r.stderr


def test_run_as_a_program_a_late_signal_is_ignored():
    """Once the command has answered, a stop signal (during the interpreter's shutdown) leaves the
    exit status as it is, instead of killing the process without its line."""
    r = _program(
        "with interrupts.command_signals(process=True):\n"
        "    pass\n"
        "os.kill(os.getpid(), signal.SIGTERM)\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.1)\n"
        "print('answered')\n"
        "sys.exit(130)\n"
    )
    assert (r.returncode, r.stdout.strip()) == (130, "answered"), r.stdout + r.stderr


@pytest.mark.parametrize("forget", [False, True])
def test_an_interrupt_caught_after_escaping_an_exec_keeps_the_exit_status(tmp_path, forget):
    """CPython kills a process run with ``python -m`` by SIGINT at exit when a ``KeyboardInterrupt``
    left code run from a string (``exec``: every dataclass decorator during the imports), even one
    the program caught: ``python -m planner`` interrupted then printed its line and died by SIGINT
    instead of exiting 130 (the reason, ``forget`` False); :func:`forget_escaped_interrupt` keeps
    the status."""
    (tmp_path / "caught_interrupt.py").write_text(
        "import sys\n"
        "from models import interrupts\n"
        "try:\n"
        "    exec('raise KeyboardInterrupt')\n"
        "except KeyboardInterrupt:\n"
        "    print('compplan: interrupted')\n"
        f"if {forget}:\n"
        "    interrupts.forget_escaped_interrupt()\n"
        "sys.exit(130)\n"
    )
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), root, os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-m", "caught_interrupt"], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == (130 if forget else -signal.SIGINT), r.stdout + r.stderr
