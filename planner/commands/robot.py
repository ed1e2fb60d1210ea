"""``compplan robot list | show NAME``: the built-in robot files, to start a robot file from.

``compplan robot show ur5 > my_ur5.toml`` prints the packaged file
``models/robots/ur5.toml`` unchanged (a complete, valid robot file: six joints,
limits, stiffness, masses); edit it and give it back with ``--robot my_ur5.toml``.
The format is ``docs/robot-file.md``.
"""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``compplan robot`` and its actions."""
    r = sub.add_parser("robot", help="list the built-in robots or print one's robot file (a template)",
                       description="The built-in robot files (models/robots/*.toml): 'list' names them, "
                                   "'show NAME' prints one unchanged, e.g. compplan robot show ur5 > my_ur5.toml "
                                   "(format: docs/robot-file.md).")
    acts = r.add_subparsers(dest="robot_action", required=True)
    ls = acts.add_parser("list", help="the built-in robots, one a line: name and the first line of its description")
    ls.set_defaults(func=run_list)
    sh = acts.add_parser("show", help="print a built-in robot file (TOML) to stdout")
    sh.add_argument("name", help="built-in robot name (compplan robot list)")
    sh.set_defaults(func=run_show)


def run_list(args: argparse.Namespace) -> int:
    """Print the built-in robots: name, description."""
    from models import BUILTIN_ROBOTS, load_robot
    for name in BUILTIN_ROBOTS:
        lines = load_robot(name).description.strip().splitlines()
        print(f"{name:<6} {lines[0] if lines else ''}")
    return 0


def run_show(args: argparse.Namespace) -> int:
    """Print the packaged robot file of ``args.name`` (exit 2 for an unknown name)."""
    from models import BUILTIN_ROBOTS
    from models.errors import InputError
    from planner.provenance import builtin_robot_file

    path = builtin_robot_file(args.name)
    if path is None:
        raise InputError(f"robot show: {args.name!r} is not a built-in robot; expected one of "
                         f"{', '.join(BUILTIN_ROBOTS)} (a robot file of your own is read with --robot FILE)")
    sys.stdout.write(path.read_text(encoding="utf-8"))
    return 0
