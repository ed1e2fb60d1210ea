"""The ``compplan`` command line (also ``python -m planner``).

Only this module prints.  User mistakes (bad files, unreachable targets,
infeasible problems) print one line ``compplan: error: ...`` and exit with
status 2; an unexpected internal failure exits with status 3 and a traceback
only under ``-v``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback
from typing import Callable

from models.errors import CompplanError

EXIT_OK = 0
EXIT_USER_ERROR = 2
EXIT_INTERNAL = 3

#: Sub-command modules under planner/commands/; each defines ``register(subparsers)``
#: which adds its parser and sets ``func`` (returning an exit code).
COMMAND_MODULES = ("demo", "report", "map", "plan", "identify")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="compplan",
                                description="Plan, compensate and time 6R arm paths under load.")
    p.add_argument("-v", "--verbose", action="store_true", help="verbose solver output and tracebacks")
    sub = p.add_subparsers(dest="command", required=True)

    for name in COMMAND_MODULES:
        importlib.import_module(f"planner.commands.{name}").register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except CompplanError as exc:
        print(f"compplan: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("compplan: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - last-resort guard at the boundary
        if args.verbose:
            traceback.print_exc()
        print(f"compplan: internal error: {type(exc).__name__}: {exc} (run with -v for details)",
              file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
