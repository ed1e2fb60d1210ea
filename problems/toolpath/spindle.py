"""The spindle along a G-code program: its speed (S) and its turning (M3, M4, M5) at every move.

LinuxCNC's order of execution applies: a line's S and M3/M4/M5 act before its motion, so
``G1 X10 S8000 M3`` cuts at 8000 rev/min.  ``S`` is modal; so is the turning.  ``M3`` turns the
spindle clockwise seen from the spindle looking at the work, ``M4`` counter-clockwise, ``M5``
stops it.  Frames: none (per move).  Units: rev/min at the edge (``S``), rad/s inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .program import Program

__all__ = ["SpindleTrack", "spindle_track"]


@dataclass(frozen=True)
class SpindleTrack:
    """The spindle at every move of a program.

    Attributes
    ----------
    speed_rad_s : ndarray, shape (M,)
        Spindle speed in force during move ``k``, rad/s (0 before any S word); the speed is
        given even while the spindle is stopped (M5), as S is modal.
    sense : ndarray, shape (M,), int
        +1 clockwise (M3), -1 counter-clockwise (M4), 0 stopped (M5, or before any M3/M4).
    s_line : ndarray, shape (M,), int
        The line of the S word in force (0: none yet).
    m_line : ndarray, shape (M,), int
        The line of the M3/M4/M5 word in force (0: none yet).
    """

    speed_rad_s: np.ndarray
    sense: np.ndarray
    s_line: np.ndarray
    m_line: np.ndarray


def spindle_track(program: Program) -> SpindleTrack:
    """The spindle speed and turning at every move of ``program`` (see the module docstring)."""
    n = program.n_moves
    speed = np.zeros(n)
    sense = np.zeros(n, dtype=int)
    s_line = np.zeros(n, dtype=int)
    m_line = np.zeros(n, dtype=int)
    for w in sorted(program.words, key=lambda w: (w.after_move, w.line)):
        k = w.after_move
        if k >= n:
            continue
        code = w.word[0]
        if code == "S":
            speed[k:] = w.value * 2.0 * math.pi / 60.0
            s_line[k:] = w.line
        elif code == "M" and w.value in (3.0, 4.0, 5.0):
            sense[k:] = {3.0: 1, 4.0: -1, 5.0: 0}[w.value]
            m_line[k:] = w.line
    return SpindleTrack(speed, sense, s_line, m_line)
