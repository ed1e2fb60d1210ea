"""docs/cli.md and the command line agree: every sub-command, every option, every shipped problem
and every export format the parser knows is in the page (a new option or format that is not
documented fails here)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from planner.cli import build_parser

CLI_DOC = Path(__file__).resolve().parents[1] / "docs" / "cli.md"


def _parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every (sub-)command parser under ``compplan``, by its full command name."""
    out: list[tuple[str, argparse.ArgumentParser]] = []

    def walk(name: str, parser: argparse.ArgumentParser) -> None:
        out.append((name, parser))
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub_name, sub in action.choices.items():
                    walk(f"{name} {sub_name}".strip(), sub)

    walk("", build_parser())
    return out[1:]


PARSERS = _parsers()


@pytest.fixture(scope="module")
def doc() -> str:
    return CLI_DOC.read_text(encoding="utf-8")


@pytest.mark.parametrize("name,parser", PARSERS, ids=[n for n, _ in PARSERS])
def test_every_option_is_documented(name: str, parser: argparse.ArgumentParser, doc: str) -> None:
    missing = [
        opt
        for action in parser._actions
        for opt in action.option_strings
        if opt.startswith("--")
        and opt not in ("--help", "--verbose")
        and not re.search(r"(?<![\w-])" + re.escape(opt) + r"(?![\w-])", doc)
    ]
    assert not missing, f"compplan {name}: options not in docs/cli.md: {missing}"


@pytest.mark.parametrize("name,parser", PARSERS, ids=[n for n, _ in PARSERS])
def test_every_subcommand_is_documented(name: str, parser: argparse.ArgumentParser, doc: str) -> None:
    words = name.split()
    # the sub-command (and its action) appear together in a heading or a code span
    assert re.search(r"compplan " + r"[^\n`]*".join(map(re.escape, words)), doc), f"compplan {name} not in docs/cli.md"


def test_every_shipped_problem_is_named(doc: str) -> None:
    from problems.problem import shipped_problems

    missing = [p for p in shipped_problems() if f"`{p}`" not in doc]
    assert not missing, f"shipped problems not named in docs/cli.md: {missing}"


def test_every_export_format_is_named(doc: str) -> None:
    from planner.export import formats

    missing = [f for f in formats() if f"`{f}`" not in doc]
    assert not missing, f"export formats not named in docs/cli.md: {missing}"
