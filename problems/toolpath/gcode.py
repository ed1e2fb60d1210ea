"""Read RS-274/NGC (G-code) milling programs into moves, with LinuxCNC's semantics.

The subset CAM posts for 3-axis milling (see ``docs/gcode.md`` for the table of words):
G0/G1/G2/G3 (I/J/K or R, full circles, helical, G17/G18/G19), G20/G21, G90/G91, G90.1/G91.1, F
(G94), G4, G61/G61.1/G64 P, G81/G82/G83 with G98/G99, the set-up codes CAM posts open with (G40,
G49, G80, G94, G54–G59.3, G43 H), and M/S/T/H/D recorded. Everything else is refused with a
:class:`GCodeError` naming ``file:line``, the word and what to do.

SI inside: positions in m in the program frame (the program's own X, Y, Z; G20 inches converted
exactly, 1 in = 25.4 mm), feeds in m/s. Every move carries its 1-based line and the line's text.
"""

from __future__ import annotations

from pathlib import Path

from .arcs import INCH_M
from .gcode_interp import GCODE_MAX_BYTES, Interpreter
from .gcode_words import GCodeError, split_line
from .program import Direction, Event, EventKind, Move, MoveKind, Program, RecordedWord, discretise
from .textfile import read_program_text

__all__ = [
    "GCODE_MAX_BYTES",
    "INCH_M",
    "Direction",
    "Event",
    "EventKind",
    "GCodeError",
    "Move",
    "MoveKind",
    "Program",
    "RecordedWord",
    "discretise",
    "parse_gcode",
    "read_gcode",
]


def read_gcode(path: str | Path) -> Program:
    """Read a G-code file (see the module docstring for the subset).

    Raises
    ------
    GCodeError
        Missing, unreadable, binary, empty or too large file, or any refused or malformed word.
    """
    text = read_program_text(path, "G-code", "a G-code program as text", GCodeError, latin1_fallback=True)
    return parse_gcode(text, str(path))


def parse_gcode(text: str, name: str = "<string>") -> Program:
    """Interpret G-code text (see the module docstring for the subset).

    Parameters
    ----------
    text : str
        The program.
    name : str
        The file name for messages.

    Raises
    ------
    GCodeError
        An empty program, or any refused or malformed word (``file:line: word 'X': ...``).
    """
    if "\0" in text:
        raise GCodeError(f"{name}: a binary file (it holds NUL bytes); expected a G-code program as text")
    interp = Interpreter(name)
    for k, raw in enumerate(text.splitlines(), start=1):
        words = split_line(raw, name, k)
        if words and interp.run(words, k, raw):
            break
    return interp.program()
