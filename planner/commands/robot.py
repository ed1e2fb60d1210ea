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


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``compplan robot`` and its actions."""
    r = sub.add_parser(
        "robot",
        help="list the built-in robots or print one's robot file (a template)",
        description="The built-in robot files (models/robots/*.toml): 'list' names them, "
        "'show NAME' prints one unchanged, e.g. compplan robot show ur5 > my_ur5.toml "
        "(format: docs/robot-file.md).",
    )
    acts = r.add_subparsers(dest="robot_action", required=True)
    ls = acts.add_parser("list", help="the built-in robots, one a line: name and the first line of its description")
    ls.set_defaults(func=run_list)
    sh = acts.add_parser("show", help="print a built-in robot file (TOML) to stdout")
    sh.add_argument("name", help="built-in robot name (compplan robot list)")
    sh.add_argument("--urdf", action="store_true", help="print the URDF a URDF-based built-in robot file names")
    sh.set_defaults(func=run_show)
    ck = acts.add_parser("check", help="read a robot file (or built-in name) and print what was understood")
    ck.add_argument("robot", help="robot file (TOML) or built-in name")
    ck.set_defaults(func=run_check)


def run_list(args: argparse.Namespace) -> int:
    """Print the built-in robots: name, description."""
    from models import BUILTIN_ROBOTS, load_robot

    for name in BUILTIN_ROBOTS:
        lines = load_robot(name).description.strip().splitlines()
        print(f"{name:<9} {lines[0] if lines else ''}")
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


def run_check(args: argparse.Namespace) -> int:
    """Read a robot file and print what was understood (exit 2 with the reason if it is bad)."""
    import math

    from models import load_robot
    from models.ik import IKStructureError, ik_solver

    r = load_robot(args.robot)
    src = (
        f"URDF {r.urdf['path']} from '{r.urdf['base_link']}' to '{r.urdf['tip_link']}'"
        if r.urdf
        else f"DH table ({r.convention})"
    )
    print(f"robot {r.name}: {src}")
    names = r.joint_names or tuple(f"joint {i + 1}" for i in range(6))
    w = max(len(n) for n in names) + 2
    print(
        f"  {'joint':<{w}}{'q_min':>9}{'q_max':>9}{'v_max':>9}{'a_max':>9}{'j_max':>9}{'k [N*m/rad]':>13}"
        f"{'mass [kg]':>11}"
    )
    for n, j in zip(names, r.joints):
        mass = f"{j.mass:.3f}" if j.mass is not None else "-"
        print(
            f"  {n:<{w}}{math.degrees(j.q_min):>8.1f}°{math.degrees(j.q_max):>8.1f}°{j.v_max:>9.3g}"
            f"{j.a_max:>9.3g}{j.j_max:>9.3g}{j.stiffness:>13.4g}{mass:>11}"
        )
    print(
        f"  chain as {r.convention} (m, deg): "
        + "; ".join(
            f"{i + 1}: a={j.a:.6g} alpha={math.degrees(j.alpha):.6g} d={j.d:.6g} "
            f"offset={math.degrees(j.theta_offset):.6g}"
            for i, j in enumerate(r.joints)
        )
    )
    try:
        ik = ik_solver(r)
        line = f"  IK family: {ik.family} ({ik.description}); branches: {', '.join(ik.labels)}"
        geom = getattr(ik, "geom", None)
        if geom is not None and hasattr(geom, "opw_parameters"):
            p = geom.opw_parameters()
            line += "\n  OPW parameters (m): " + ", ".join(
                f"{k} = {p[k]:.6g}" for k in ("a1", "a2", "b", "c1", "c2", "c3", "c4")
            )
        print(line)
    except IKStructureError as exc:
        print(f"  IK family: none ({exc})")
    for note in r.notes:
        print(f"  note: {note}")
    return 0
