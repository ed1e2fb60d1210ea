"""Drilling cycles G81, G82, G83 expanded into rapids, feed moves and dwells.

Semantics of LinuxCNC (``src/emc/rs274ngc/interp_cycles.cc``: ``convert_cycle_xy``,
``convert_cycle_g81/g82/g83``; ``CYCLE_MACRO`` in ``interp_internal.hh``), XY plane (G17) only:

* G90: the hole is at X, Y (the current ones when not given), R is the retract plane, Z the
  bottom. G91: X, Y are increments repeated L times, R is relative to the initial level and Z
  relative to R. R and Z are kept from the previous line of the same cycle when not given.
* The initial level is the Z where the cycle mode was entered. If it is below R, the tool first
  rapids up to R. Retract after each hole: to R with G99, to the initial level with G98.
* Per hole: rapid in XY at the current height, rapid down to R, then G81: feed to Z, rapid out;
  G82: feed to Z, dwell P seconds, rapid out; G83: feed down by Q, rapid up to R, rapid back down to
  the last depth plus the peck clearance, repeat until Z, rapid out.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from .arcs import INCH_M, Plane
from .program import EventKind, MoveKind

if TYPE_CHECKING:
    from .gcode_interp import Interpreter
    from .gcode_words import Word

__all__ = [
    "run_cycle",
]

#: G83 peck clearance (LinuxCNC's default ``parameter_g83_peck_clearance``, ``rs274ngc_pre.cc``):
#: 1 mm in G21 ...
G83_PECK_CLEARANCE_MM_M = 1e-3
#: ... and 0.050 in in G20.
G83_PECK_CLEARANCE_INCH_M = 0.050 * INCH_M


def _levels(it: Interpreter, w: dict[str, Word], g: str) -> tuple[float, float, float, float, float]:
    """(x, y, r, bottom, initial level) of the first hole, m, and the XY increments in ``it``."""
    if it.prev_motion != g and "Z" not in w:
        raise it.err(g, "the first line of a drilling cycle needs Z (the hole bottom); give Z")
    if "R" in w:
        it.cycle_r = it.m(w["R"].value)
    elif it.prev_motion != g:
        raise it.err(g, "the first line of a drilling cycle needs R (the retract plane); give R")
    if "Z" in w:
        it.cycle_z = it.m(w["Z"].value)
    if it.cycle_il is None:
        it.cycle_il = it.pos[2]
    old = it.cycle_il
    if it.absolute:
        x = it.m(w["X"].value) if "X" in w else (it.pos[0])
        y = it.m(w["Y"].value) if "Y" in w else (it.pos[1])
        return x, y, it.cycle_r, it.cycle_z, old
    r = it.cycle_r + old
    return (it.pos[0]), (it.pos[1]), r, r + it.cycle_z, old


def _dwell_depth(it: Interpreter, w: dict[str, Word], g: str) -> None:
    if g == "G82":
        if "P" in w:
            it.cycle_p = w["P"].value
        elif it.prev_motion != g:
            raise it.err(g, "G82 needs its dwell time; give P<seconds>")
        if it.cycle_p < 0:
            raise it.err(w["P"].text if "P" in w else g, "a negative dwell time; give seconds >= 0")
    if g == "G83":
        if "Q" in w:
            it.cycle_q = it.m(w["Q"].value)
        elif it.prev_motion != g:
            raise it.err(g, "G83 needs its peck depth; give Q > 0")
        if not it.cycle_q > 0:
            raise it.err(w["Q"].text if "Q" in w else g, "the peck depth Q must be > 0")


def run_cycle(it: Interpreter, w: dict[str, Word]) -> set[str]:
    """Expand one line of a G81/G82/G83 cycle into ``it``'s moves; the letters it used."""
    g = it.motion or "G81"
    if it.plane is not Plane.XY:
        raise it.err(
            g,
            f"drilling cycles are supported in G17 (XY) only, not G{it.plane.value}; "
            "select G17 or post the cycle as G0/G1 moves",
        )
    feed = it._need_feed(g)
    if it._unknown():
        raise it.err(g, "a drilling cycle before X, Y and Z are all known; position them with G0 first")
    repeats = 1
    if "L" in w:
        repeats = round(w["L"].value)
        if abs(w["L"].value - repeats) > 1e-6 or repeats < 1:
            raise it.err(w["L"].text, "the number of repeats L must be a whole number >= 1")
    _dwell_depth(it, w, g)
    x, y, r, bottom, old = _levels(it, w, g)
    dx = it.m(w["X"].value) if (not it.absolute and "X" in w) else 0.0
    dy = it.m(w["Y"].value) if (not it.absolute and "Y" in w) else 0.0
    if r < bottom:
        raise it.err(w["R"].text if "R" in w else g, "the retract plane R is below the hole bottom Z; correct R or Z")
    current = it.pos[2]
    if old < r:
        _go(it, MoveKind.RAPID, (it.pos[0]), (it.pos[1]), r, None, g)
        old = current = r
    clear = r if it.r_plane_retract else old
    clearance = G83_PECK_CLEARANCE_INCH_M if it.scale == INCH_M else G83_PECK_CLEARANCE_MM_M
    for k in range(repeats):
        x, y = x + dx, y + dy
        if k == 0 and current > r:
            _go(it, MoveKind.RAPID, x, y, current, None, g)
        else:
            _go(it, MoveKind.RAPID, x, y, clear, None, g)
        _go(it, MoveKind.RAPID, x, y, r, None, g)
        if g == "G83":
            depth = r - it.cycle_q
            while depth > bottom:
                _go(it, MoveKind.LINEAR, x, y, depth, feed, g)
                _go(it, MoveKind.RAPID, x, y, r, None, g)
                _go(it, MoveKind.RAPID, x, y, depth + clearance, None, g)
                depth -= it.cycle_q
        _go(it, MoveKind.LINEAR, x, y, bottom, feed, g)
        if g == "G82":
            it._event(EventKind.DWELL, it.cycle_p)
        _go(it, MoveKind.RAPID, x, y, clear, None, g)
    used = {"R", "L"}
    used |= {"P"} if g == "G82" else set()
    used |= {"Q"} if g == "G83" else set()
    return used


def _go(it: Interpreter, kind: MoveKind, x: float, y: float, z: float, feed: float | None, g: str) -> None:
    if math.isnan(z):
        raise it.err(g, "the cycle's Z is unknown; give Z")
    it._straight(kind, [x, y, z], feed, cycle=g)
