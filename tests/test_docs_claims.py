"""What the docs name exists, and the docs say no "not yet".

Read from every page of ``docs/`` and ``README.md``:

* every command line ``compplan <command> ...`` in code (a code span or a fenced block) names a
  sub-command (and action) the parser built by :func:`planner.cli.build_parser` has, and every
  ``--option`` on it is one of that command's options;
* every shipped problem such a line names (the ``PROBLEM`` argument of ``plan``, ``pose``,
  ``place``, ``problem show``, and ``--problem``) is a file of ``problems/files/``, and every
  built-in robot it names (``--robot``, ``robot show/check``) is in ``BUILTIN_ROBOTS``; a list of
  built-in robots in the prose names all of them, and a problem file's ``model = "..."`` a real one;
* no sentence says a feature is "not yet" there, "in progress", "to come", "TODO" or "planned",
  unless it is on :data:`ALLOWED` with its reason;
* a paragraph that says how long the product takes to compute something ("takes 2.7 s", "48.5 s
  wall") names the benchmark that measures it (``benchmarks/<name>.py``, which exists) or says it
  was measured once with ``time`` (and when): a figure nobody can measure again is not a claim.

The direction parser -> docs is ``tests/test_cli_docs.py``.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from models.robot import BUILTIN_ROBOTS
from planner.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]
PROBLEMS = {p.stem for p in (ROOT / "problems" / "files").glob("*.toml")}

#: Words that say a documented feature is missing or unfinished.
UNFINISHED = re.compile(r"\b(not yet|in progress|to come|TODO|FIXME|will be|in a later)\b", re.IGNORECASE)
#: Sentences with such a word that are true as written: (page, words of the sentence) -> reason.
ALLOWED: dict[tuple[str, str], str] = {
    ("cli.md", "the new campaign will be measured"): "a campaign being designed is measured later, by the user",
}
#: A claim of compute time: "takes 2.7 s", "took 48.5 s", "in about 9 s", "48.5 s wall", "2-5 s on 2 cores".
TIME_CLAIM = re.compile(
    r"\b(?:takes?|took|in about|runs? in)\b[^.;|]{0,40}?\d[\d.,]*\s?(?:ms|s|min|h)\b"
    r"|\d[\d.,]*\s?(?:ms|s|min|h)\s(?:wall|on 2 cores|of CPU)\b",
    re.IGNORECASE,
)
#: Where a time claim comes from: a benchmark script, or a run measured once with ``time`` on a date.
TIME_SOURCE = re.compile(r"benchmarks/(\w+)\.py|measured[^.]{0,80}\b(?:with `time`|20\d\d-\d\d)")
#: Sub-commands whose first argument is a problem (a shipped name or a file).
PROBLEM_COMMANDS = {"plan", "pose", "place", "problem show"}
#: Sub-commands whose first argument is a robot (a built-in name or a file).
ROBOT_COMMANDS = {"robot show", "robot check"}
#: Options whose value is a problem, and a robot.
PROBLEM_OPTIONS, ROBOT_OPTIONS = {"--problem"}, {"--robot"}


def _commands() -> dict[str, argparse.ArgumentParser]:
    """Every (sub-)command parser by its full name (``"plan"``, ``"robot check"``)."""
    out: dict[str, argparse.ArgumentParser] = {}

    def walk(name: str, parser: argparse.ArgumentParser) -> None:
        out[name] = parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub_name, sub in action.choices.items():
                    walk(f"{name} {sub_name}".strip(), sub)

    walk("", build_parser())
    return out


COMMANDS = _commands()


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {o for a in parser._actions for o in a.option_strings}


def code_lines(text: str) -> list[tuple[int, str]]:
    """(line number, code) of a page: every line of a fenced block, every inline code span; shell
    continuations (``\\`` at the end) joined to their next line."""
    out: list[tuple[int, str]] = []
    fenced, held, held_at = False, "", 0
    for n, line in enumerate(text.splitlines(), start=1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            if line.rstrip().endswith("\\"):
                held, held_at = held + line.rstrip()[:-1] + " ", held_at or n
                continue
            out.append((held_at or n, held + line))
            held, held_at = "", 0
        else:
            out += [(n, span) for span in re.findall(r"`([^`\n]+)`", line)]
    return out


def command_claims(text: str) -> list[tuple[int, str, list[str]]]:
    """(line, command name, its words) of each ``compplan <command> ...`` in the code of a page
    (up to a pipe, ``&&``, ``;``, a comment or a closing parenthesis; ``plan/pose`` is two); the
    program's messages quoted in the docs are not command lines."""
    out = []
    for n, code in code_lines(text):
        if re.search(r"compplan: (error|warning|note)|^[^`]*?: .*compplan ", code):  # a message, not a command
            continue
        for m in re.finditer(r"(?<![\w./-])compplan ([a-z][\w/-]*)((?: [^|;&#)\n]*)?)", code):
            for first in m.group(1).split("/"):
                words = m.group(2).split()
                name = first
                if words and f"{first} {words[0]}" in COMMANDS:
                    name, words = f"{first} {words[0]}", words[1:]
                out.append((n, name, words))
    return out


def _claims() -> list[tuple[str, int, str, list[str]]]:
    return [(p.name, n, c, w) for p in PAGES for n, c, w in command_claims(p.read_text(encoding="utf-8"))]


CLAIMS = _claims()


def bad_command_claims(claims: list[tuple[str, int, str, list[str]]]) -> list[str]:
    """What the command lines name that the product does not have, one line each."""
    bad = []
    for page, n, name, words in claims:
        where = f"{page}:{n}: compplan {name}"
        parser = COMMANDS.get(name)
        if parser is None:
            bad.append(f"{where}: no such command")
            continue
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if subs and words and re.fullmatch(r"[a-z]+", words[0]):
            bad.append(f"{where} {words[0]}: no such action (known: {', '.join(subs[0].choices)})")
        known = _options(parser) | _options(COMMANDS[""])
        for k, w in enumerate(words):
            opt = w.split("=")[0]
            if re.fullmatch(r"--[a-z][\w-]*", opt) and opt not in known:
                bad.append(f"{where}: no option {opt}")
            value = words[k + 1] if k + 1 < len(words) else ""
            bad += _named(where, opt, value)
        if words and not words[0].startswith("-"):
            bad += _named(where, name, words[0])
    return bad


def _named(where: str, key: str, value: str) -> list[str]:
    """A shipped problem or built-in robot named as ``key``'s value (a bare name, not a path or a
    placeholder) that does not exist."""
    value = value.strip("`'\",:;.")
    if not re.fullmatch(r"[a-z][a-z0-9_]*", value):
        return []
    if key in PROBLEM_COMMANDS | PROBLEM_OPTIONS and value not in PROBLEMS:
        return [f"{where}: no shipped problem '{value}' (problems/files/)"]
    if key in ROBOT_COMMANDS | ROBOT_OPTIONS and value not in BUILTIN_ROBOTS:
        return [f"{where}: no built-in robot '{value}' (BUILTIN_ROBOTS)"]
    return []


def bad_robot_claims(page: str, text: str) -> list[str]:
    """A list of the built-in robots that leaves some out or names another; a list of shipped
    problems naming one that is not shipped; a ``model = "x"`` (a problem file in the docs) that
    is neither a built-in robot nor a file name."""
    bad = []
    for n, line in enumerate(text.splitlines(), start=1):
        for m in re.finditer(r"built-in (?:robots?|names?|arms?) \(([^)]*)\)", line, re.IGNORECASE):
            names = set(re.findall(r"(?<!\w)[a-z][a-z0-9_]*(?!\w)", m.group(1).split(";")[0]))
            if names and names != set(BUILTIN_ROBOTS):
                bad.append(f"{page}:{n}: built-in robots listed {sorted(names)}; they are {list(BUILTIN_ROBOTS)}")
        for m in re.finditer(r"shipped (?:problems?|names?):? ((?:`[a-z]\w*`[^`|]*)+)", line):
            bad += [
                f"{page}:{n}: no shipped problem '{name}' (problems/files/)"
                for name in re.findall(r"`([a-z]\w*)`", m.group(1))
                if name not in PROBLEMS
            ]
        for m in re.finditer(r'^model = "([^"]+)"', line):
            if "." not in m.group(1) and "/" not in m.group(1) and m.group(1) not in BUILTIN_ROBOTS:
                bad.append(f"{page}:{n}: model = '{m.group(1)}' is no built-in robot")
    return bad


def unfinished_sentences(page: str, text: str) -> list[str]:
    """Sentences saying something is not done, except those on :data:`ALLOWED`."""
    bad = []
    flat = re.sub(r"\s+", " ", text)
    for sentence in re.split(r"(?<=[.!?])\s+(?=[A-Z`*])|\s\|\s", flat):
        m = UNFINISHED.search(sentence)
        if m and not any(p == page and w in sentence for (p, w) in ALLOWED):
            bad.append(f"{page}: ...{sentence[max(0, m.start() - 80) : m.end() + 80].strip()}...")
    return bad


def unsourced_time_claims(page: str, text: str) -> list[str]:
    """Paragraphs with a compute-time claim and no benchmark (that exists) or dated measurement."""
    bad = []
    for para in re.split(r"\n\s*\n", text):
        flat = re.sub(r"\s+", " ", para)
        m = TIME_CLAIM.search(flat)
        if not m:
            continue
        sources = list(TIME_SOURCE.finditer(flat))
        scripts = [x.group(1) for x in sources if x.group(1)]
        if not sources or any(not (ROOT / "benchmarks" / f"{b}.py").is_file() for b in scripts):
            bad.append(f"{page}: ...{flat[max(0, m.start() - 80) : m.end() + 40].strip()}...")
    return bad


def test_the_pages_name_commands() -> None:
    """The parse finds the command lines (a parse that found nothing would check nothing)."""
    names = {c for _, _, c, _ in CLAIMS}
    assert {"plan", "identify", "robot check", "export", "place"} <= names, sorted(names)
    assert len(CLAIMS) > 100


def test_commands_options_problems_and_robots_named_exist() -> None:
    bad = bad_command_claims(CLAIMS)
    assert not bad, "the docs name what the product does not have:\n" + "\n".join(bad)


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_builtin_robot_lists_are_whole(page: Path) -> None:
    bad = bad_robot_claims(page.name, page.read_text(encoding="utf-8"))
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_no_unfinished_sentence(page: Path) -> None:
    bad = unfinished_sentences(page.name, page.read_text(encoding="utf-8"))
    assert not bad, "a sentence says a feature is not done (finish it, reword it, or allow it with a reason):\n" + (
        "\n".join(bad)
    )


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_time_claims_name_their_benchmark(page: Path) -> None:
    bad = unsourced_time_claims(page.name, page.read_text(encoding="utf-8"))
    assert not bad, "a compute time without the benchmark that measures it (or a dated measurement):\n" + (
        "\n".join(bad)
    )


def test_the_checks_can_fail() -> None:
    """Each check finds a false claim injected into a page."""
    page = (
        "Run `compplan plan nosuch_problem --out out/x --no-such-flag` then `compplan frobnicate`,\n"
        "`compplan robot show ur7` and `compplan robot explode ur5`.\n"
    )
    bad = bad_command_claims([("x.md", n, c, w) for n, c, w in command_claims(page)])
    assert any("no shipped problem 'nosuch_problem'" in b for b in bad), bad
    assert any("no option --no-such-flag" in b for b in bad), bad
    assert any("compplan frobnicate: no such command" in b for b in bad), bad
    assert any("no built-in robot 'ur7'" in b for b in bad), bad
    assert any("robot explode: no such action" in b for b in bad), bad
    assert bad_robot_claims("x.md", 'model = "ar5"   # built-in name (ar5, ur5, ur10) or a path\n')
    assert bad_robot_claims("x.md", 'model = "ur3"\n')
    assert bad_robot_claims("x.md", "a file or a shipped name: `paper_4_4`, `paper_9_9` (gone)\n")
    assert not bad_robot_claims("x.md", f"built-in robots ({', '.join(BUILTIN_ROBOTS)})\n")
    assert unfinished_sentences("x.md", "The report does not draw it. Not yet: the cell view.\n")
    assert unfinished_sentences("x.md", "The cell check is in progress.\n")
    assert not unfinished_sentences("x.md", "The report draws the cell.\n")
    assert unsourced_time_claims("x.md", "The sweep takes 2.7 s.\n\nIt is fast.\n")
    assert unsourced_time_claims("x.md", "The plan took 48.5 s wall (benchmarks/bench_nosuch.py).\n")
    assert not unsourced_time_claims("x.md", "The sweep takes 2.7 s (`benchmarks/bench_placement.py`).\n")
    assert not unsourced_time_claims("x.md", "It took 53 s, measured with `time` on 2026-12-07.\n")
    assert not unsourced_time_claims("x.md", "The motion lasts 1.93 s.\n")
