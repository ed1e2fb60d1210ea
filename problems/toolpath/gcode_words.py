"""Lexer of RS-274/NGC G-code lines: comments, block delete, words and numbers.

Follows the word syntax of LinuxCNC's reader (``src/emc/rs274ngc/interp_read.cc``) for the subset
:mod:`problems.toolpath.gcode` interprets: a line is ``[/][N<int>] {<letter><number>}`` with
``( ... )`` comments anywhere (not nested) and ``;`` starting a comment to the end of the line.
Spaces and tabs between and inside words are ignored and letters are case-insensitive, as in
LinuxCNC. A number is ``[+-]digits[.digits]`` (no exponent, as in LinuxCNC). Parameters (``#``),
expressions (``[ ]``) and o-words (subroutines, loops) are refused here with a :class:`GCodeError`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from models.errors import InputError

__all__ = ["GCodeError", "Word", "fail", "split_line"]

_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")
_WORDS = re.compile(r"(?:[A-Z][+-]?(?:\d+\.?\d*|\.\d+))*")
_OWORD = re.compile(r"(?:N\d+)?(O(?:\d+|<[^>]*>)?)")
_OWORD_WHY = "o-words (subroutines, loops, conditions) are not supported; post the program flat"
_SPACE = str.maketrans("", "", " \t\r\f\v")


class GCodeError(InputError):
    """A G-code program that cannot be read; the message is ``file:line: word 'X': what; what to do``."""


def fail(name: str, line: int, word: str | None, what: str) -> GCodeError:
    """Build the error for ``word`` (None for a whole-line problem) at ``name:line``."""
    where = f"{name}:{line}: " if line > 0 else f"{name}: "
    return GCodeError(f"{where}word '{word}': {what}" if word else f"{where}{what}")


@dataclass(frozen=True, slots=True)
class Word:
    """One word of a line.

    Attributes
    ----------
    letter : str
        The upper-case letter.
    value : float
        The number, in the program's units (unconverted).
    text : str
        The word as written, upper-cased, spaces removed (``"G90.1"``), for messages.
    """

    letter: str
    value: float
    text: str


def _strip_comments(raw: str, name: str, line: int) -> str:
    """The line without its comments (``( )`` and ``;``)."""
    out: list[str] = []
    k = 0
    n = len(raw)
    while k < n:
        c = raw[k]
        if c == ";":
            break
        if c == "(":
            end = raw.find(")", k + 1)
            if end < 0:
                raise fail(name, line, None, "comment '(' without its ')'; close the comment on the same line")
            if "(" in raw[k + 1 : end]:
                raise fail(name, line, None, "nested comment '( ( )'; comments do not nest, remove the inner '('")
            k = end + 1
            continue
        if c == ")":
            raise fail(name, line, None, "')' without its '('; open the comment or remove the ')'")
        out.append(c)
        k += 1
    return "".join(out)


def split_line(raw: str, name: str, line: int) -> list[Word]:
    """The words of one line, in order (the ``N`` word removed).

    Parameters
    ----------
    raw : str
        The line as read, without its newline.
    name, line : str, int
        File name and 1-based line number, for messages.

    Returns
    -------
    list of Word
        Empty for a blank line, a comment-only line or a ``%`` program delimiter.

    Raises
    ------
    GCodeError
        A malformed number, a letter without a number, a parameter, an expression, an o-word,
        an unclosed or nested comment, or any other character.
    """
    text = raw if "(" not in raw and ";" not in raw and ")" not in raw else _strip_comments(raw, name, line)
    text = text.translate(_SPACE).upper()
    if text.startswith("/"):  # block delete: the line is run, as with the switch off
        text = text[1:]
    if not text or text == "%":
        return []
    o = _OWORD.match(text)
    if o is not None:
        raise fail(name, line, o.group(1), _OWORD_WHY)
    if _WORDS.fullmatch(text) is None:
        _explain(text, name, line)
    words = [Word(m.group(1), float(m.group(2)), m.group(0)) for m in _WORD.finditer(text)]
    if words and words[0].letter == "N":
        if not words[0].text[1:].isdigit():
            raise fail(name, line, words[0].text, "a line number must be a whole number; write N followed by digits")
        words = words[1:]
    for w in words:
        if w.letter == "O":
            raise fail(name, line, w.text, _OWORD_WHY)
        if w.letter == "N":
            raise fail(name, line, w.text, "a line number may only open the line; move it to the front or remove it")
    return words


def _explain(text: str, name: str, line: int) -> None:
    """Raise the error for the first thing in ``text`` that is not a word."""
    k = 0
    while k < len(text):
        m = _WORD.match(text, k)
        if m is not None:
            k = m.end()
            continue
        c = text[k]
        rest = text[k : k + 12]
        nxt = text[k + 1 : k + 2] if c.isalpha() else c
        if nxt == "#":
            raise fail(name, line, rest, "parameters (#) are not supported; post the program with plain numbers")
        if nxt == "[":
            raise fail(name, line, rest, "expressions ([ ]) are not supported; post the program with plain numbers")
        if c.isalpha():
            raise fail(name, line, rest, f"'{c}' is not followed by a number; write a number like 1, -2.5 or .5")
        raise fail(name, line, rest, f"unexpected character '{c}'; a line holds words like G1 X10.5 (and comments)")
