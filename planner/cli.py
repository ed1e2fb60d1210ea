"""The ``compplan`` command line (also ``python -m planner``).

Only this module prints.  User mistakes (bad files, unreachable targets,
infeasible problems) print one line ``compplan: error: ...`` and exit with
status 2; an unexpected internal failure exits with status 3 and a traceback
only under ``-v``.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import traceback
from typing import NoReturn
from collections.abc import Callable

from planner.provenance import command_line_scope
from planner.provenance import version as _version

EXIT_OK = 0
EXIT_USER_ERROR = 2
EXIT_INTERNAL = 3

#: Sub-command modules under planner/commands/; each defines ``register(subparsers)``
#: which adds its parser and sets ``func`` (returning an exit code).
COMMAND_MODULES = (
    "demo",
    "report",
    "map",
    "plan",
    "identify",
    "predict",
    "design",
    "robot",
    "problem",
    "export",
    "track",
    "place",
    "cutting",
)


class _Parser(argparse.ArgumentParser):
    """argparse with the product's error format: one line ``compplan: error: ...``, exit 2.

    Sub-command parsers are built by ``add_subparsers`` with the parent's class, so every
    option error (missing, unknown, bad choice, bad value) gets the same one line, naming
    the sub-command, the option and the value, and where the usage is.
    """

    def error(self, message: str) -> NoReturn:  # type: ignore[override]
        cmd = self.prog.removeprefix("compplan").strip()
        where = f"{cmd}: " if cmd else ""
        self.exit(EXIT_USER_ERROR, f"compplan: error: {where}{one_line(message)} (usage: {self.prog} --help)\n")


#: ``np.float64(1.5)``-style reprs (NumPy >= 2) that must not reach a message.
_NUMPY_REPR = re.compile(r"\bnp\.(?:float|int|uint|bool_?|str_)\d*\(([^()]*)\)")


def one_line(message: object) -> str:
    """A message on one line, without NumPy scalar reprs (``np.float64(0.5)`` -> ``0.5``)."""
    text = _NUMPY_REPR.sub(r"\1", str(message))
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def _os_error_message(exc: OSError) -> str:
    """One line for a file-system error (permissions, a full disk, a folder where a file is
    expected ...): the path(s) and the system's reason."""
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    reason = exc.strerror or str(exc) or type(exc).__name__
    return f"{' -> '.join(paths)}: {reason}" if paths else f"{reason} (a file-system error)"


def version_line() -> str:
    """What ``compplan --version`` prints."""
    return f"compplan {_version()}"


def _asks_version(argv: list[str]) -> bool:
    """Whether the parser would stop at ``--version``: it comes before any help option and before
    the command (the top-level options are handled left to right).  Answered without building the
    parser, which imports every command module (and with them NumPy and CasADi)."""
    for token in argv:
        if token == "--version":
            return True
        if token in ("-h", "--help", "--") or not token.startswith("-"):
            return False
    return False


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="compplan", description="Plan, compensate and time 6R arm paths under load.")
    p.add_argument("-v", "--verbose", action="store_true", help="verbose solver output and tracebacks")
    p.add_argument("--version", action="version", version=version_line(), help="print the compplan version and exit")
    sub = p.add_subparsers(dest="command", required=True)

    for name in COMMAND_MODULES:
        importlib.import_module(f"planner.commands.{name}").register(sub)
    _verbose_anywhere(sub)
    return p


def _verbose_anywhere(sub: argparse._SubParsersAction) -> None:
    """Accept ``-v/--verbose`` after the sub-command (and its action) too, as users type it
    (``compplan plan P --out D -v``): the same flag as before the sub-command, left unset when not
    given there so that the top-level one counts."""
    for parser in sub.choices.values():
        parser.add_argument(
            "-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help="as compplan -v (verbose output)"
        )
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                _verbose_anywhere(action)


def _is_user_error(exc: BaseException) -> bool:
    """Whether ``exc`` is a :class:`~models.errors.CompplanError`.  Read from ``sys.modules``: the
    import that raised it (a bad plug-in folder or module, found when a registry package is first
    imported) may have left the ``models`` package itself unimported."""
    errors = sys.modules.get("models.errors")
    return errors is not None and isinstance(exc, errors.CompplanError)


#: Exit status of a command stopped by SIGINT (Ctrl-C) or SIGTERM: 128 + SIGINT, as a shell reports
#: a Ctrl-C; the output it was writing is not written, a previous one is left as it was.
EXIT_INTERRUPTED = 130


def main(argv: list[str] | None = None) -> int:
    """The command line: exit status 0, 2 (user error), 3 (internal error) or 130 (interrupted).

    SIGTERM stops a command as Ctrl-C does (:mod:`models.interrupts`), from the first instruction
    to the last: during the imports, inside a native solver, while an output is written."""
    from models.interrupts import Terminated, command_signals, forget_escaped_interrupt
    from planner.progress import start_clock

    start_clock()

    process = argv is None  # run as a program (the console script, python -m planner): its last work
    try:
        with command_signals(process=process):
            code = _main(argv)
    except KeyboardInterrupt as exc:
        what = "terminated" if isinstance(exc, Terminated) else "interrupted"
        written = _published_outputs()
        if written:  # the signal came after some output was moved into place (whole)
            what += " after writing " + ", ".join(str(p) for p in written) + " (complete)"
        print(f"compplan: {what}", file=sys.stderr)
        code = EXIT_INTERRUPTED
    if process:  # the exit status is the command's, not CPython's record of a caught interrupt
        forget_escaped_interrupt()
    return code


def _run_honouring_signals(func: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """``func(args)``, but a stop signal that arrived meanwhile wins over its outcome: a library
    may have swallowed the interrupt, or turned it into another error (CasADi's ``SystemError``
    "returned a result with an exception set") that was then caught or printed as a failure."""
    from models import interrupts

    try:
        code = func(args)
    except BaseException:
        interrupts.raise_if_pending()
        raise
    interrupts.raise_if_pending()
    return code


def _clear_published_outputs() -> None:
    output = sys.modules.get("planner.output")
    if output is not None:
        output.clear_published_outputs()


def _published_outputs() -> list:
    """The outputs this command moved into place (none when ``planner.output`` was not loaded)."""
    output = sys.modules.get("planner.output")
    return output.published_outputs() if output is not None else []


def _main(argv: list[str] | None) -> int:
    if _asks_version(sys.argv[1:] if argv is None else argv):  # imports nothing more
        print(version_line())
        raise SystemExit(EXIT_OK)  # as argparse's version action does
    try:
        parser = build_parser()  # imports the command modules, and registries find their plug-ins
    except Exception as exc:
        if not _is_user_error(exc):
            raise
        print(f"compplan: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR
    from models.codegen import clear_codegen_notes
    from models.errors import CompplanError

    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], int] = args.func
    clear_codegen_notes()
    _clear_published_outputs()
    # The outputs of the command record its command line (planner.provenance).
    command = ["compplan", *(sys.argv[1:] if argv is None else argv)]
    try:
        with command_line_scope(command):
            code = _run_honouring_signals(func, args)
        _print_codegen_notes()
        return code
    except CompplanError as exc:
        print(f"compplan: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR
    except OSError as exc:  # the environment: permissions, a full disk, a vanished file
        if args.verbose:
            traceback.print_exc()
        print(f"compplan: error: {one_line(_os_error_message(exc))}", file=sys.stderr)
        return EXIT_USER_ERROR
    except MemoryError as exc:  # an input asking for more than the machine has
        print(
            f"compplan: error: not enough memory for this input ({one_line(exc) or 'MemoryError'}); "
            "reduce its size (points, samples, rows)",
            file=sys.stderr,
        )
        return EXIT_USER_ERROR
    except Exception as exc:
        if args.verbose:
            traceback.print_exc()
        print(
            f"compplan: internal error: {type(exc).__name__}: {one_line(exc)} (run with -v for details)",
            file=sys.stderr,
        )
        _print_codegen_notes()
        return EXIT_INTERNAL


def _print_codegen_notes() -> None:
    """One line per note the library recorded in this run (e.g. no C compiler: evaluating
    with CasADi's virtual machine; a compile cache rebuilt or bypassed).  Printed after a
    run that completed or failed internally, not after a user error (its one line stands alone)."""
    from models.codegen import codegen_notes

    for note in codegen_notes():
        print(f"compplan: note: {note}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
