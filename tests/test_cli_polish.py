"""The command line reads as a product: every (sub-)command documents itself, and the robot, pose and
map outputs show numbers with units in aligned columns, never Python reprs, and descriptions whole."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from models import BUILTIN_ROBOTS, load_robot
from planner.cli import build_parser, main

#: What a Python repr looks like on a terminal: a dict, a float at full precision or with its ``.0``
#: in a list (``[5.0, 10.0]``), a NumPy scalar or array.
PYTHON_REPR = re.compile(r"\{'|'\}|\d\.\d{9,}|\d\.0[,\]]|np\.\w+\(|array\(")


def _parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every parser of the tree, by its command line (``compplan robot check``)."""
    out = []

    def walk(name: str, parser: argparse.ArgumentParser) -> None:
        out.append((name, parser))
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub_name, sub in action.choices.items():
                    walk(f"{name} {sub_name}", sub)

    walk("compplan", build_parser())
    return out


PARSERS = _parsers()


@pytest.mark.parametrize("name,parser", PARSERS, ids=[n for n, _ in PARSERS])
def test_every_parser_has_a_description_and_every_option_a_help(name: str, parser: argparse.ArgumentParser) -> None:
    assert (parser.description or "").strip(), f"{name}: no description (its --help says nothing)"
    undocumented = [
        "/".join(a.option_strings) or a.dest
        for a in parser._actions
        if not isinstance(a, argparse._SubParsersAction) and not (a.help or "").strip()
    ]
    assert not undocumented, f"{name}: options without a help string: {undocumented}"
    for action in parser._actions:  # the listing of sub-commands in this parser's --help
        if isinstance(action, argparse._SubParsersAction):
            listed = {c.dest: (c.help or "").strip() for c in action._choices_actions}
            assert all(listed.get(sub) for sub in action.choices), f"{name}: a sub-command without a help line"


def _run(capsys, argv: list[str]) -> str:
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert not PYTHON_REPR.search(out), f"compplan {' '.join(argv)}: a Python repr in {out!r}"
    return out


def test_robot_list_gives_whole_sentences_wrapped_to_the_terminal(capsys, monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    out = _run(capsys, ["robot", "list"])
    assert max(len(line) for line in out.splitlines()) <= 80
    blocks = re.split(r"\n(?=\S)", out.strip())
    assert [b.split()[0] for b in blocks] == list(BUILTIN_ROBOTS)
    for block, name in zip(blocks, BUILTIN_ROBOTS):
        shown = " ".join(block.split()[1:])
        full = " ".join(load_robot(name).description.split())
        assert full.startswith(shown), f"{name}: the list is not the description's beginning"
        after = full[len(shown) :]
        # it ends where a sentence ends: a full stop, then the end or a new sentence
        assert shown.endswith(".") and (not after or re.match(r" [A-Z]", after)), f"{name}: cut at {shown[-30:]!r}"


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_robot_show_prints_the_file_and_check_no_reprs(capsys, name: str) -> None:
    from planner.provenance import builtin_robot_file

    assert main(["robot", "show", name]) == 0  # the packaged file as written (its numbers are its author's)
    assert capsys.readouterr().out == builtin_robot_file(name).read_text(encoding="utf-8")
    _run(capsys, ["robot", "check", name])


def _right_edges(line: str, n: int) -> list[int]:
    """The end columns of the last ``n`` cells of a line (cells are separated by 2+ spaces)."""
    return [m.end() for m in re.finditer(r"\S+(?: \S+)*", line)][-n:]


@pytest.mark.parametrize("name", ["ur5", "kr6_r900", "ar5"])
def test_robot_check_tables_are_aligned(capsys, name: str) -> None:
    lines = _run(capsys, ["robot", "check", name]).splitlines()
    joints = lines[1:9]  # names, units, 6 joints: 7 right-aligned columns
    assert len({tuple(_right_edges(line, 7)) for line in joints}) == 1, "\n".join(joints)
    k = lines.index(next(line for line in lines if line.strip().startswith("chain as")))
    chain = lines[k + 1 : k + 9]  # a, d, alpha, theta_offset
    assert len({tuple(_right_edges(line, 4)) for line in chain}) == 1, "\n".join(chain)


@pytest.mark.parametrize("problem", ["paper_4_4", "kr6_milling"])  # short and long branch labels
def test_pose_prints_aligned_columns_without_reprs(capsys, problem: str) -> None:
    lines = _run(capsys, ["pose", problem]).splitlines()
    head, rows = lines[1], [line.removesuffix(" *") for line in lines[2:] if line.startswith("  ")]
    assert rows
    status_col = head.index("status")
    assert all(row[status_col - 1] == " " and row[status_col] != " " for row in rows)
    # the two errors end under their headers; the six joint angles end together
    mm_ends = [m.end() for m in re.finditer(r"\[mm\]", head)]
    assert len({tuple(_right_edges(row, 8)) for row in rows}) == 1
    assert _right_edges(rows[0], 8)[:2] == mm_ends


def test_map_prints_its_attitude_and_branches_with_units(capsys, tmp_path: Path) -> None:
    out = _run(
        capsys,
        [
            "map",
            "--robot",
            "ur5",
            "--points",
            "3",
            "--rpy-rad",
            "3.141592653589793",
            "0",
            "0",
            "--out",
            str(tmp_path / "m"),
        ],
    )
    assert "attitude rpy [3.1416, 0, 0] rad = [180, 0, 0] deg" in out
    assert re.search(r"branches used: \S+ \(\d+ points\)", out)
