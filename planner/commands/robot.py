"""``compplan robot list | show NAME [--urdf] | check FILE``: the built-in robot files, and a check of yours.

``compplan robot show ur5 > my_ur5.toml`` prints the packaged file
``models/robots/ur5.toml`` unchanged (a complete, valid robot file: six joints,
limits, stiffness, masses); edit it and give it back with ``--robot my_ur5.toml``.
A URDF-based built-in (``ur5e``, ``kr6_r900``) names its URDF: ``show NAME --urdf``
prints that.  ``check FILE`` reads a robot file as ``plan`` would and prints what was
understood: joints, limits, the chain as DH, the IK family and its parameters, the notes.
The format is ``docs/robot-file.md``.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``compplan robot`` and its actions."""
    r = sub.add_parser(
        "robot",
        help="list the built-in robots, print one's robot file (a template) or check a robot file",
        description="The built-in robot files (models/robots/*.toml): 'list' names them, "
        "'show NAME' prints one unchanged, e.g. compplan robot show ur5 > my_ur5.toml, "
        "'check FILE' reads a robot file as plan would and prints what was understood "
        "(format: docs/robot-file.md).",
    )
    acts = r.add_subparsers(dest="robot_action", required=True)
    ls = acts.add_parser(
        "list",
        help="the built-in robots: name and the first sentence of its description",
        description="The built-in robots, each with the first sentence of its description (wrapped to the "
        "terminal); 'compplan robot show NAME' prints the whole file.",
    )
    ls.set_defaults(func=run_list)
    sh = acts.add_parser(
        "show",
        help="print a built-in robot file (TOML) to stdout",
        description="Print a built-in robot file (TOML) unchanged, a complete file to start your own from: "
        "compplan robot show ur5 > my_ur5.toml; --urdf prints the URDF a URDF-based built-in names.",
    )
    sh.add_argument("name", help="built-in robot name (compplan robot list)")
    sh.add_argument("--urdf", action="store_true", help="print the URDF a URDF-based built-in robot file names")
    sh.set_defaults(func=run_show)
    ck = acts.add_parser(
        "check",
        help="read a robot file (or built-in name) and print what was understood",
        description="Read a robot file (or a built-in name) as plan would and print what was understood: the "
        "joints with their limits, stiffness and masses, the chain as DH, the TCP, the IK family and the "
        "notes. A mistake, a degenerate chain included, is one line naming the file and the key or joints "
        "(exit 2).",
    )
    ck.add_argument("robot", help="robot file (TOML) or built-in name")
    ck.set_defaults(func=run_check)


#: ``robot list`` wraps a description to the terminal's width, but not narrower than this (characters).
LIST_MIN_WIDTH = 60
#: ... and not wider than this, for readability.
LIST_MAX_WIDTH = 120
#: Width of the name column of ``robot list`` (the longest built-in name and a space).
LIST_NAME_WIDTH = 10


def first_sentence(text: str) -> str:
    """The first sentence of ``text`` on one line: up to the first ``"."`` outside parentheses and
    brackets that ends the text or is followed by a space and an upper-case letter (so ``"Appl. Sci."``
    in a citation, ``"A1..A6"`` or ``"e.g. the"`` do not end it); the whole text if none does."""
    flat = " ".join(text.split())
    depth = 0
    for i, ch in enumerate(flat):
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth = max(0, depth - 1)
        elif ch == "." and depth == 0:
            rest = flat[i + 1 : i + 3]
            if not rest or (rest[0] == " " and rest[1:].isupper()):
                return flat[: i + 1]
    return flat


def run_list(args: argparse.Namespace) -> int:
    """Print the built-in robots: name and the first sentence of the description, wrapped."""
    import shutil
    import textwrap

    from models import BUILTIN_ROBOTS, load_robot

    width = min(max(shutil.get_terminal_size((100, 24)).columns, LIST_MIN_WIDTH), LIST_MAX_WIDTH)
    for name in BUILTIN_ROBOTS:
        text = first_sentence(load_robot(name).description) or "(no description)"
        lines = textwrap.wrap(text, width - LIST_NAME_WIDTH, break_on_hyphens=False) or [""]
        print(f"{name:<{LIST_NAME_WIDTH}}{lines[0]}")
        for line in lines[1:]:
            print(" " * LIST_NAME_WIDTH + line)
    return 0


def run_show(args: argparse.Namespace) -> int:
    """Print the packaged robot file of ``args.name`` (exit 2 for an unknown name)."""
    from models import BUILTIN_ROBOTS
    from models.errors import InputError
    from planner.provenance import builtin_robot_file

    path = builtin_robot_file(args.name)
    if path is None:
        raise InputError(
            f"robot show: {args.name!r} is not a built-in robot; expected one of "
            f"{', '.join(BUILTIN_ROBOTS)} (a robot file of your own is read with --robot FILE)"
        )
    if args.urdf:
        from models import load_robot

        urdf = load_robot(args.name).urdf
        if urdf is None:
            raise InputError(f"robot show --urdf: {args.name!r} is a DH robot file; it names no URDF")
        from pathlib import Path

        sys.stdout.write(Path(urdf["path"]).read_text(encoding="utf-8"))
        return 0
    sys.stdout.write(path.read_text(encoding="utf-8"))
    if "\nurdf = " in "\n" + path.read_text(encoding="utf-8"):
        print(
            f"compplan: {args.name}.toml names a URDF: save it beside the copy with "
            f"compplan robot show {args.name} --urdf > {args.name}.urdf",
            file=sys.stderr,
        )
    return 0


#: A length below this (m) is shown as 0: rounding residue of a chain turned into DH form (a DH
#: length of a nanometre is no arm's).
SHOWN_ZERO_M = 1e-12
#: An angle below this (deg) is shown as 0, for the same reason.
SHOWN_ZERO_DEG = 1e-9


def _number(v: float, digits: int = 6, zero_below: float = 0.0) -> str:
    """A number for a table: ``digits`` significant digits, no trailing zeros; ``0`` for ``-0`` and
    for a magnitude below ``zero_below`` (rounding residue)."""
    from planner.numbers import format_number

    return format_number(0.0 if abs(v) < zero_below else v + 0.0, digits)  # -0.0 + 0.0 == 0.0


def _vector(values: Any, unit: str, digits: int = 6, zero_below: float = 0.0) -> str:
    """``"[0, 0, 0.031] m"``: a vector with significant digits and its unit, not a Python list."""
    return "[" + ", ".join(_number(float(v), digits, zero_below) for v in values) + f"] {unit}"


def table_lines(header: list[tuple[str, str]], rows: list[list[str]], indent: str = "  ") -> list[str]:
    """Rows in aligned columns under a two-line header (names, then ``[unit]`` or ``""``): the first
    column left-aligned, the others right-aligned (numbers), each as wide as its widest cell, two
    spaces apart."""
    names = [h[0] for h in header]
    units = [f"[{h[1]}]" if h[1] else "" for h in header]
    widths = [max(len(r[c]) for r in [names, units, *rows]) for c in range(len(header))]

    def line(cells: list[str]) -> str:
        first = cells[0].ljust(widths[0])
        return (indent + "  ".join([first, *(s.rjust(w) for s, w in zip(cells[1:], widths[1:]))])).rstrip()

    return [line(names), *([line(units)] if any(units) else []), *(line(r) for r in rows)]


def run_check(args: argparse.Namespace) -> int:
    """Read a robot file and print what was understood (exit 2 with the reason if it is bad)."""
    import math

    from models import load_robot
    from models.ik import IKStructureError, ik_solver
    from models.transforms import matrix_to_rpy

    r = load_robot(args.robot)
    src = (
        f"URDF {r.urdf['path']} from '{r.urdf['base_link']}' to '{r.urdf['tip_link']}'"
        if r.urdf
        else f"DH table ({r.convention})"
    )
    print(f"robot {r.name}: {src}")
    names = r.joint_names or tuple(f"joint {i + 1}" for i in range(6))
    header = [("joint", ""), ("q_min", "deg"), ("q_max", "deg"), ("v_max", "rad/s"), ("a_max", "rad/s^2")]
    header += [("j_max", "rad/s^3"), ("stiffness", "N*m/rad"), ("mass", "kg")]
    rows = [
        [n, f"{math.degrees(j.q_min):.1f}", f"{math.degrees(j.q_max):.1f}"]
        + [_number(v, 3) for v in (j.v_max, j.a_max, j.j_max)]
        + [_number(j.stiffness, 4), f"{j.mass:.3f}" if j.mass is not None else "-"]
        for n, j in zip(names, r.joints)
    ]
    print("\n".join(table_lines(header, rows)))
    print(f"  chain as {r.convention}:")
    rows = [
        [n]
        + [_number(v, zero_below=SHOWN_ZERO_M) for v in (j.a, j.d)]
        + [_number(math.degrees(v), zero_below=SHOWN_ZERO_DEG) for v in (j.alpha, j.theta_offset)]
        for n, j in zip(names, r.joints)
    ]
    header = [("joint", ""), ("a", "m"), ("d", "m"), ("alpha", "deg"), ("theta_offset", "deg")]
    print("\n".join(table_lines(header, rows)))
    rpy = [math.degrees(v) for v in matrix_to_rpy(r.tcp2flange[:3, :3])]
    print(
        f"  TCP in the flange frame: xyz {_vector(r.tcp2flange[:3, 3], 'm', zero_below=SHOWN_ZERO_M)}, "
        f"rpy {_vector(rpy, 'deg', zero_below=SHOWN_ZERO_DEG)}"
    )
    try:
        ik = ik_solver(r)
        line = f"  IK family: {ik.family} ({ik.description})\n  IK branches: {', '.join(ik.labels)}"
        geom = getattr(ik, "geom", None)
        if geom is not None and hasattr(geom, "opw_parameters"):
            p = geom.opw_parameters()
            line += "\n  OPW parameters (m): " + ", ".join(
                f"{k} = {_number(p[k])}" for k in ("a1", "a2", "b", "c1", "c2", "c3", "c4")
            )
        print(line)
    except IKStructureError as exc:
        print(f"  IK family: none ({exc})")
    for note in r.notes:
        print(f"  note: {note}")
    return 0
