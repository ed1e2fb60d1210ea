"""``compplan problem list | show NAME``: the shipped problems, as ``compplan robot`` does for robots.

``list`` names each shipped problem (``problems/files/*.toml``) with its robot, path kind and size and
the first line of its description; ``show NAME`` prints the packaged file unchanged, a template to copy
(``compplan problem show machining_offaxis > my_task.toml``; format: ``docs/problem-file.md``). A
problem whose path is a program names its file; ``show NAME --program`` prints that.
"""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``compplan problem`` and its actions."""
    r = sub.add_parser(
        "problem",
        help="list the shipped problems or print one's problem file (a template)",
        description="The shipped problem files (problems/files/*.toml), which plan and place take by name: "
        "'list' names them, 'show NAME' prints one unchanged, e.g. compplan problem show machining_offaxis "
        "> my_task.toml (format: docs/problem-file.md).",
    )
    acts = r.add_subparsers(dest="problem_action", required=True)
    ls = acts.add_parser(
        "list",
        help="the shipped problems, one a line: name, robot, path, description",
        description="The shipped problems, one a line: name, robot, path kind and size, and the first line "
        "of the description; plan and place take them by name.",
    )
    ls.set_defaults(func=run_list)
    sh = acts.add_parser(
        "show",
        help="print a shipped problem file (TOML) to stdout",
        description="Print a shipped problem file (TOML) unchanged, a template to copy: compplan problem show "
        "machining_offaxis > my_task.toml; --program prints the program file a program problem names.",
    )
    sh.add_argument("name", help="shipped problem name (compplan problem list)")
    sh.add_argument("--program", action="store_true", help="print the program file a program problem names")
    sh.set_defaults(func=run_show)


def _files() -> object:
    from importlib import resources

    return resources.files("problems").joinpath("files")


def run_list(args: argparse.Namespace) -> int:
    """Print the shipped problems: name, robot, path kind and size, the first line of the description."""
    import tomllib

    from problems.problem import shipped_problems

    for name in shipped_problems():
        data = tomllib.loads(_files().joinpath(f"{name}.toml").read_text(encoding="utf-8"))  # type: ignore[attr-defined]
        path = data.get("path", {})
        kind = path.get("kind", "?")
        size = {
            "line": f"{path.get('points', '?')} points",
            "waypoints": f"{len(path.get('positions', []))} waypoints",
        }.get(kind, str(path.get("file", "")))
        robot = data.get("robot", {}).get("model", "?")
        desc = str(data.get("description", "")).strip().splitlines()
        print(f"{name:<24} {robot:<9} {kind} ({size}): {desc[0] if desc else ''}")
    return 0


def run_show(args: argparse.Namespace) -> int:
    """Print the packaged problem file of ``args.name`` (exit 2 for an unknown name)."""
    import tomllib

    from models.errors import InputError
    from problems.problem import shipped_problems

    if args.name not in shipped_problems():
        raise InputError(
            f"problem show: {args.name!r} is not a shipped problem; expected one of {', '.join(shipped_problems())} "
            "(a problem file of your own is given by its path)"
        )
    text = _files().joinpath(f"{args.name}.toml").read_text(encoding="utf-8")  # type: ignore[attr-defined]
    file = tomllib.loads(text).get("path", {}).get("file")
    if args.program:
        if not file:
            raise InputError(f"problem show --program: {args.name!r} has no program path (its path is not a file)")
        sys.stdout.write(_files().joinpath(file).read_text(encoding="utf-8"))  # type: ignore[attr-defined]
        return 0
    sys.stdout.write(text)
    if file:
        print(
            f"compplan: {args.name}.toml names the program {file}: save it beside the copy with "
            f"compplan problem show {args.name} --program > {file}",
            file=sys.stderr,
        )
    return 0
