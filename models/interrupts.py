"""Interrupts honoured inside native solvers: the one home of the signal rules.

Python delivers a signal by running its handler between two bytecodes of the main thread.  Native
code that polls for signals (CasADi's IPOPT interface calls ``PyErr_CheckSignals`` once per
iteration) runs the handler too, but then *swallows* the ``KeyboardInterrupt`` it raises: IPOPT
stops with ``NonIpopt_Exception_Thrown``, CasADi prints a warning and the call returns as if it
had merely failed.  The caller would go on and finish the command with a different result.

:func:`native_call` is the guard every such call goes through: the signal is recorded, the solver
stops at its next poll, and when the call returns the interrupt is raised again as
:class:`KeyboardInterrupt` (SIGINT) or :class:`Terminated` (SIGTERM, a subclass), so it reaches
the command line, which exits 130 and leaves the previous output whole.

:func:`deferred` holds a signal across a block that must not be cut in two (moving an output into
place, closing a cluster).  :func:`command_signals` is the command line's scope: SIGTERM stops a
command the way Ctrl-C does, and every stop signal is recorded (:func:`pending`) so that no library
can lose it; :func:`raise_if_pending` raises it again where it must not be lost.
:func:`forked_worker_signals` is the rule of a worker process a command forks.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

#: The signals a command stops on: Ctrl-C and the polite kill of a job scheduler or ``timeout``.
STOP_SIGNALS: tuple[int, ...] = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Python raises ``KeyboardInterrupt`` for SIGINT."""


#: Seconds between the raises of a stop signal that a library lost, until the command unwinds
#: (:func:`command_signals` run as a program): the latency a lost signal adds.
RERAISE_INTERVAL_S = 0.1
#: The signal of the interval timer that raises a lost stop signal again.
RERAISE_SIGNAL: int = signal.SIGALRM

#: The stop signals that arrived under :func:`command_signals` (the command line's scope).
_PENDING: list[int] = []
#: Whether the scope of :func:`command_signals` run as a program is open (the re-raise timer's).
_RERAISING = [False]
#: How many :func:`deferred` blocks are open (the re-raise timer waits for their end).
_DEFERRING = [0]


def _interrupt_for(signum: int) -> KeyboardInterrupt:
    return Terminated(f"signal {signal.Signals(signum).name}") if signum == signal.SIGTERM else KeyboardInterrupt()


def _command_handler(signum: int, frame: FrameType | None = None) -> None:
    """The handler :func:`command_signals` installs: record, then raise (and, run as a program,
    start the timer that raises it again if it is lost)."""
    if not _PENDING and _RERAISING[0]:
        signal.setitimer(signal.ITIMER_REAL, RERAISE_INTERVAL_S, RERAISE_INTERVAL_S)
    _PENDING.append(signum)
    raise _interrupt_for(signum)


def _unwinding() -> bool:
    """Whether the code running handles an interrupt: an ``except``, ``finally`` or ``__exit__``
    on its way out (or an exception raised in one: its implicit context is the interrupt)."""
    exc: BaseException | None = sys.exc_info()[1]
    while exc is not None:
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc = exc.__context__
    return False


def _reraise_handler(signum: int, frame: FrameType | None = None) -> None:
    """The re-raise timer's handler: raise the stop signal again if it was lost.

    A library can lose the ``KeyboardInterrupt`` a handler raised without a trace: CasADi's
    bindings choose among a function's overloads by calling Python (an argument's ``shape``) and
    discard what that raised, so a signal arriving while a symbolic expression is built was lost
    and the command went on to its end (measured: ``compplan design`` stopped 1.5 to 2.9 s after the
    signal, at the check before its output is moved in).  The timer raises the interrupt again
    every :data:`RERAISE_INTERVAL_S` until the command has unwound, but never into the unwinding
    itself (the clean-up of the first raise) nor into a :func:`deferred` block."""
    if not _RERAISING[0] or not _PENDING or _DEFERRING[0] or _unwinding():
        return
    raise _interrupt_for(_PENDING[0])


def pending() -> int | None:
    """The first stop signal that arrived in the command's scope, or None.

    A native library may swallow the exception a handler raises (or turn it into another one that
    a fallback catches); the signal is still recorded here, and :func:`raise_if_pending` raises it
    again where it must not be lost: before an output is moved into place, when the command ends."""
    return _PENDING[0] if _PENDING else None


def raise_if_pending() -> None:
    """Raise the interrupt of a stop signal that arrived in the command's scope, if one did.

    Called where a lost signal must not go further: before an output is moved into place, when a
    command ends, at every progress tick and before every native solve (so a signal Python could
    not raise, in a destructor, stops the command at the next of them)."""
    if _PENDING:
        raise _interrupt_for(_PENDING[0])


@contextmanager
def command_signals(process: bool = False) -> Iterator[None]:
    """SIGINT raises ``KeyboardInterrupt`` and SIGTERM :class:`Terminated` in this block (the command
    line's scope), and both are recorded (:func:`pending`), so a terminated command unwinds as an
    interrupted one and no library can lose the signal.  Only the main thread can set a handler:
    elsewhere, nothing changes.

    With ``process`` (the command is the last work of its process: the command line run as a
    program), the stop signals are *ignored* from the end of the block on instead of restored: the
    command has answered, and a signal arriving while it prints its last line or while the
    interpreter shuts down (a few hundred milliseconds: atexit, the modules' teardown, where
    Python has already put back the default actions) would otherwise kill it by the signal, with no
    line and without its exit status, a finished command's 0 or an interrupted one's 130.  See
    also :func:`forget_escaped_interrupt`."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _PENDING.clear()
    if process:  # the timer that raises a lost signal again (:func:`_reraise_handler`)
        signal.signal(RERAISE_SIGNAL, _reraise_handler)
        _RERAISING[0] = True
    previous = {s: signal.signal(s, _command_handler) for s in STOP_SIGNALS}
    unraisable = sys.unraisablehook
    sys.unraisablehook = _quiet_recorded_interrupts(unraisable)
    try:
        yield
    finally:
        sys.unraisablehook = unraisable
        for s, handler in previous.items():
            signal.signal(s, signal.SIG_IGN if process else handler)
        if process:  # its handler stays (a no-op now): one already due finds it, not a default action
            _RERAISING[0] = False
            signal.setitimer(signal.ITIMER_REAL, 0)
        _PENDING.clear()  # outside the scope no signal is recorded, and none is pending


def _quiet_recorded_interrupts(hook: Any) -> Any:
    """``sys.unraisablehook`` that drops the report of an interrupt raised where Python cannot pass
    it on (a signal handled inside a destructor or a weak-reference callback: "Exception ignored
    in ..." and its traceback).  The signal is recorded (:func:`pending`) and raised again at the
    next check (:func:`raise_if_pending`); every other report goes to ``hook``."""

    def quiet(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _PENDING:
            return
        hook(unraisable)

    return quiet


def forget_escaped_interrupt() -> None:
    """Forget CPython's record of a ``KeyboardInterrupt`` that escaped an ``exec`` of a string.

    CPython (3.8 and later) marks the process when a ``KeyboardInterrupt`` leaves code it runs from a
    string (``exec``/``eval`` of text: every ``dataclass`` decorator and ``namedtuple`` during the
    imports, several libraries' generated code), and at exit kills the process with SIGINT if the
    mark is set, *even when the program caught the exception*: a command interrupted during such an
    ``exec`` (a few tenths of a second at its start) printed ``compplan: interrupted`` and then died
    by SIGINT instead of exiting 130.  The mark is cleared by the next string run that ends without
    one: this runs an empty one.  The command line calls it once the command has answered, when it
    is run as a program (the mark concerns the process's exit only)."""
    exec("pass", {})  # a constant: the string run itself is the point


def forked_worker_signals() -> None:
    """In a worker process forked by a command: Ctrl-C is the parent's to answer (a terminal sends
    it to the whole process group), and SIGTERM (its pool's ``terminate``) ends it at once, without
    the parent's handlers and their tracebacks."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _PENDING.clear()
    _RERAISING[0] = False  # the parent's timer is not inherited; nor is its task


def _redeliver(signum: int, previous: Any) -> None:
    """Act on a signal recorded while its handler was replaced, as ``previous`` would have."""
    if callable(previous):
        previous(signum, None)
    elif previous == signal.SIG_DFL:  # the default action: SIGINT raises, SIGTERM ends the process
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        os.kill(os.getpid(), signum)
    # SIG_IGN: ignored, as it would have been


@contextmanager
def deferred(signals: tuple[int, ...] = STOP_SIGNALS) -> Iterator[None]:
    """``signals`` recorded instead of acted on inside the block; on the way out the previous
    handlers are restored and the first recorded signal is delivered to its handler.

    For blocks that must finish once started (closing worker processes).  Only the main thread
    can set a handler: elsewhere, nothing changes."""
    with _recording(signals, raise_inside=False):
        yield


@contextmanager
def native_call(signals: tuple[int, ...] = STOP_SIGNALS) -> Iterator[None]:
    """A call into a native solver that swallows interrupts (IPOPT through CasADi).

    Inside, a stop signal is recorded *and* raised as ``KeyboardInterrupt`` (so the solver stops
    at its next poll of Python's signals, and pure-Python code stops at once); on the way out, a
    recorded signal is delivered to the previous handler, whatever the solver made of the
    exception.  CasADi's warning about the exception it caught (written through ``sys.stderr``)
    is dropped: the interrupt is reported once, by whoever handles it.  Only the main thread can
    set a handler: elsewhere, nothing changes."""
    raise_if_pending()  # one a library lost since the last check: not into another solve
    stderr, filtered = sys.stderr, _WithoutInterruptWarnings(sys.stderr)
    sys.stderr = filtered
    try:
        with _recording(signals, raise_inside=True):
            yield
    finally:
        sys.stderr = stderr
        filtered.close_line()


#: What CasADi writes when a solver caught the ``KeyboardInterrupt`` of a signal handler.
CASADI_INTERRUPT_WARNING = "KeyboardInterruptException"


class _WithoutInterruptWarnings:
    """A text stream that passes everything to ``stream`` but the lines of CasADi's interrupt
    warnings (CasADi writes a warning in several pieces: lines are held until complete)."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream
        self._line = ""

    def write(self, text: str) -> int:
        self._line += text
        *lines, self._line = self._line.split("\n")
        for line in lines:
            if CASADI_INTERRUPT_WARNING not in line:
                self._stream.write(line + "\n")
        return len(text)

    def close_line(self) -> None:
        """Pass on an unfinished last line (not a warning's)."""
        if self._line and CASADI_INTERRUPT_WARNING not in self._line:
            self._stream.write(self._line)
        self._line = ""

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


@contextmanager
def _recording(signals: tuple[int, ...], raise_inside: bool) -> Iterator[None]:
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    arrived: list[int] = []

    def record(signum: int, frame: FrameType | None) -> None:
        arrived.append(signum)
        if raise_inside:
            raise KeyboardInterrupt

    previous = {s: signal.signal(s, record) for s in signals}
    _DEFERRING[0] += not raise_inside
    try:
        yield
    except BaseException:
        if not arrived:  # not an interrupt: as it was
            raise
        # interrupted: the signal wins over whatever the block made of it (a failed solve)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        _DEFERRING[0] -= not raise_inside
    if arrived:
        _redeliver(arrived[0], previous[arrived[0]])
