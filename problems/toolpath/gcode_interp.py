"""The modal interpreter behind :func:`problems.toolpath.gcode.parse_gcode`.

State and order of execution within a line follow LinuxCNC's RS-274/NGC interpreter
(``src/emc/rs274ngc/interp_execute.cc``, ``interp_convert.cc``, ``interp_cycles.cc``) and the NIST
RS274NGC v3 report (Kramer, Proctor, Messina 2000, sec. 3.8 "Order of execution"): F, S, T, M
recorded, G4 dwell, plane, units, cutter compensation (G40 only), tool length, work offset, path
control, distance modes, retract mode, then the motion; M0/M1/M2/M30 last.
"""

from __future__ import annotations

import math

from .textfile import PROGRAM_MAX_BYTES
from .arcs import (
    CENTER_ARC_RADIUS_TOLERANCE_INCH_M,
    INCH_M,
    CENTER_ARC_RADIUS_TOLERANCE_MM_M,
    RADIUS_TOLERANCE_INCH_M,
    RADIUS_TOLERANCE_MM_M,
    ArcGeometry,
    Plane,
    centre_ijk,
    centre_r,
)
from .gcode_cycles import run_cycle
from .gcode_words import Word, fail
from .program import Direction, Event, EventKind, Move, MoveKind, Program, RecordedWord

__all__ = ["GCODE_MAX_BYTES", "Interpreter"]

#: Largest program read (bytes): the limit of every program file.
GCODE_MAX_BYTES = PROGRAM_MAX_BYTES

_MOTION = {"G0", "G1", "G2", "G3", "G80", "G81", "G82", "G83"}
_CYCLES = {"G81", "G82", "G83"}
#: Accepted G codes and their modal group (two of one group on a line are an error).
_GROUP = {
    **{g: "motion" for g in _MOTION},
    "G4": "dwell",
    "G17": "plane",
    "G18": "plane",
    "G19": "plane",
    "G20": "units",
    "G21": "units",
    "G40": "cutter compensation",
    "G43": "tool length",
    "G49": "tool length",
    "G61": "path control",
    "G61.1": "path control",
    "G64": "path control",
    "G90": "distance",
    "G91": "distance",
    "G90.1": "arc distance",
    "G91.1": "arc distance",
    "G94": "feed mode",
    "G98": "retract",
    "G99": "retract",
    **{f"G{k}": "work offset" for k in (54, 55, 56, 57, 58, 59)},
    **{f"G59.{k}": "work offset" for k in (1, 2, 3)},
}
_WHY = {
    "G41": "active cutter radius compensation is not supported; post the tool-centre path from CAM (G40)",
    "G28": "a return to a stored position depends on the machine set-up; post an explicit G0 instead",
    "G30": "a return to a stored position depends on the machine set-up; post an explicit G0 instead",
    "G92": "coordinate offsets are not supported; the program zero is the [workpiece] frame",
    "G10": "setting offsets/tables from the program is not supported; remove it (the program zero is [workpiece])",
    "G53": "machine coordinates are not supported; the program's frame is the [workpiece] frame",
    "G93": "only G94 feed (units per minute) is supported; post with G94",
    "G95": "only G94 feed (units per minute) is supported; post with G94",
    "G5": "splines are not supported; post the path as G1/G2/G3",
    "G43.1": "dynamic tool length offsets are not supported; the TCP comes from the robot's tool",
    "G43.2": "dynamic tool length offsets are not supported; the TCP comes from the robot's tool",
    "G7": "lathe diameter mode is not supported (milling programs only)",
    "G8": "lathe radius mode is not supported (milling programs only)",
    "G33": "spindle-synchronised motion (threading) is not supported",
    "G38": "probing is not supported",
    "G76": "threading cycles are not supported",
}
for _g in ("G41.1", "G42", "G42.1"):
    _WHY[_g] = _WHY["G41"]
for _g in ("G28.1", "G30.1"):
    _WHY[_g] = _WHY["G28"]
for _g in ("G92.1", "G92.2", "G92.3"):
    _WHY[_g] = _WHY["G92"]
for _g in ("G5.1", "G5.2", "G5.3"):
    _WHY[_g] = _WHY["G5"]
for _g in ("G38.2", "G38.3", "G38.4", "G38.5"):
    _WHY[_g] = _WHY["G38"]
for _g in ("G73", "G74", "G84", "G85", "G86", "G87", "G88", "G89"):
    _WHY[_g] = "this canned cycle is not supported; use G81, G82 or G83, or post the cycle as G0/G1 moves"
_M_REFUSED = {"M98": "subprogram calls", "M99": "subprogram returns"}
_AXES = "XYZ"
_ALLOWED = set("XYZIJKRPQLFSTHDGM")


def _gcode(w: Word, name: str, line: int) -> str:
    tenths = w.value * 10.0
    k = round(tenths)
    if abs(tenths - k) > 1e-6 or k < 0:
        raise fail(name, line, w.text, "not a G code (at most one decimal, e.g. G90.1)")
    return f"G{k // 10}" if k % 10 == 0 else f"G{k // 10}.{k % 10}"


class Interpreter:
    """Modal state of one program; :meth:`run` executes one line, :meth:`program` gives the result."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.scale = 1e-3  # m per program unit
        self.den = 1000.0  # a length v in program units is v * num / den m (correctly rounded for
        self.num = 1.0  # whole numbers: 3 in -> 762/10000 = 0.0762 m exactly as written)
        self.units_seen: set[str] = set()
        self.absolute = True
        self.ijk_absolute = False
        self.plane = Plane.XY
        self.motion: str | None = None  # LinuxCNC starts in G80
        self.prev_motion: str | None = None
        self.feed: float | None = None
        self.pos = [math.nan, math.nan, math.nan]  # m; NaN: not yet programmed
        self.start: tuple[float, float, float] | None = None
        self.start_line = 0
        self.r_plane_retract = False  # G98 (initial level) by default
        self.cycle_r = math.nan
        self.cycle_z = math.nan
        self.cycle_p = math.nan
        self.cycle_q = math.nan
        self.cycle_il: float | None = None
        self.moves: list[Move] = []
        self.events: list[Event] = []
        self.words: list[RecordedWord] = []
        self.tolerances: list[float] = []
        self.offsets: dict[str, int] = {}
        self.end_line = 0
        self.line = 0
        self.text = ""

    # ------------------------------------------------------------------ helpers
    def m(self, v: float) -> float:
        """A length in program units in m."""
        return v * self.num / self.den

    def err(self, word: str | None, what: str) -> Exception:
        return fail(self.name, self.line, word, what)

    def _event(self, kind: EventKind, value: float | None = None) -> None:
        self.events.append(Event(kind, self.line, self.text, len(self.moves), value))

    def _check_words(self, words: list[Word]) -> tuple[list[str], list[Word], dict[str, Word]]:
        gs: list[str] = []
        ms: list[Word] = []
        other: dict[str, Word] = {}
        groups: dict[str, str] = {}
        for w in words:
            c = w.letter
            if c == "G":
                g = _gcode(w, self.name, self.line)
                if g in _WHY:
                    raise self.err(w.text, _WHY[g])
                grp = _GROUP.get(g)
                if grp is None:
                    raise self.err(w.text, "not in the supported G-code subset (see docs/gcode.md); remove it")
                if grp in groups:
                    raise self.err(w.text, f"two {grp} codes on one line ({groups[grp]} and {g}); keep one")
                groups[grp] = g
                gs.append(g)
            elif c == "M":
                ms.append(w)
            elif c in "ABCUVW":
                raise self.err(w.text, "rotary and extra axes are not supported; this reads 3-axis (X, Y, Z) programs")
            elif c not in _ALLOWED:
                raise self.err(w.text, f"the letter {c} is not supported; remove the word")
            elif c in other:
                raise self.err(w.text, f"two {c} words on one line ({other[c].text} and {w.text}); keep one")
            else:
                other[c] = w
        return gs, ms, other

    # ------------------------------------------------------------------ one line
    def run(self, words: list[Word], line: int, text: str) -> bool:
        """Execute one line's words; True when the program ends (M2/M30)."""
        self.line, self.text = line, text
        gs, ms, w = self._check_words(words)
        self._units(gs)
        if "F" in w:
            f = w["F"].value
            if f < 0:
                raise self.err(w["F"].text, "a negative feed; give the feed in units per minute, > 0")
            self.feed = self.m(f) / 60.0
        for c in "STHD":
            if c in w:
                self.words.append(RecordedWord(w[c].text, w[c].value, line, len(self.moves)))
        for m in ms:
            if m.text in _M_REFUSED or f"M{m.value:g}" in _M_REFUSED:
                raise self.err(m.text, f"{_M_REFUSED[f'M{m.value:g}']} are not supported; post the program flat")
            self.words.append(RecordedWord(m.text, m.value, line, len(self.moves)))
        self._modes(gs, w)
        motion = next((g for g in gs if g in _MOTION), None)
        self.prev_motion = self.motion
        if motion is not None:
            if motion not in _CYCLES:
                self.cycle_il = None
            self.motion = None if motion == "G80" else motion
        has_axes = any(c in w for c in _AXES)
        used = self._motion(w) if (has_axes or (motion is not None and motion != "G80")) else set()
        self._unused(w, gs, used)
        return self._stops(ms)

    def _units(self, gs: list[str]) -> None:
        # F on the same line as G20/G21 is taken in the new units (what posts mean; see docs/gcode.md)
        if "G20" in gs:
            self.scale, self.num, self.den = INCH_M, 254.0, 10000.0
            self.units_seen.add("inch")
        elif "G21" in gs:
            self.scale, self.num, self.den = 1e-3, 1.0, 1000.0
            self.units_seen.add("mm")

    def _modes(self, gs: list[str], w: dict[str, Word]) -> None:
        for g in gs:
            if g == "G4":
                if "P" not in w:
                    raise self.err("G4", "a dwell needs its time; write G4 P<seconds>")
                if w["P"].value < 0:
                    raise self.err(w["P"].text, "a negative dwell time; give seconds >= 0")
                self._event(EventKind.DWELL, w["P"].value)
            elif g in ("G17", "G18", "G19"):
                self.plane = Plane(int(g[1:]))
            elif g in ("G61", "G61.1"):
                self._event(EventKind.EXACT_STOP)
            elif g == "G64":
                p = self.m(w["P"].value) if "P" in w else None
                if p is not None and p < 0:
                    raise self.err(w["P"].text, "a negative path tolerance; give G64 P<tolerance> >= 0")
                if p is not None:
                    self.tolerances.append(p)
                self._event(EventKind.BLENDING, p)
            elif g in ("G90", "G91"):
                self.absolute = g == "G90"
            elif g in ("G90.1", "G91.1"):
                self.ijk_absolute = g == "G90.1"
            elif g in ("G98", "G99"):
                self.r_plane_retract = g == "G99"
            elif g.startswith(("G54", "G55", "G56", "G57", "G58", "G59")):
                self.offsets.setdefault(g, self.line)
                if len(self.offsets) > 1:
                    first = ", ".join(f"{k} (line {v})" for k, v in self.offsets.items())
                    raise self.err(
                        g,
                        f"a second work offset ({first}); one program has one program zero, "
                        "the [workpiece] frame: split the program per work offset",
                    )

    def _unused(self, w: dict[str, Word], gs: list[str], used: set[str]) -> None:
        users = {"P": ("G4", "G64"), "Q": ("G64",)}
        for c in "IJKRPQL":
            if c in w and c not in used and not any(g in gs for g in users.get(c, ())):
                raise self.err(
                    w[c].text,
                    "no G code on the line uses it (I/J/K/R: G2/G3 and cycles; "
                    "P: G4, G64, G82, G2/G3 turns; Q: G83; L: cycles); remove it",
                )

    def _stops(self, ms: list[Word]) -> bool:
        for m in ms:
            if m.value in (0.0, 1.0, 60.0):
                self._event(EventKind.PROGRAM_STOP)
            elif m.value in (2.0, 30.0):
                self._event(EventKind.PROGRAM_END)
                self.end_line = self.line
                return True
        return False

    # ------------------------------------------------------------------ motion
    def _target(self, w: dict[str, Word]) -> list[float]:
        end = list(self.pos)
        for k, c in enumerate(_AXES):
            if c in w:
                v = self.m(w[c].value)
                if not self.absolute:
                    if math.isnan(self.pos[k]):
                        raise self.err(
                            w[c].text,
                            f"an incremental (G91) move while {c} is not yet known; "
                            "position all axes with G90 G0 X.. Y.. Z.. first",
                        )
                    v += self.pos[k]
                end[k] = v
        return end

    def _motion(self, w: dict[str, Word]) -> set[str]:
        if self.motion is None:
            c = next(c for c in _AXES if c in w)
            raise self.err(
                w[c].text, "an axis word with no motion mode (at the start or after G80); put G0 or G1 on the line"
            )
        if self.motion in _CYCLES:
            return run_cycle(self, w)
        end = self._target(w)
        if self.motion == "G0":
            self._straight(MoveKind.RAPID, end, None)
            return set()
        feed = self._need_feed()
        if self.motion == "G1":
            self._straight(MoveKind.LINEAR, end, feed)
            return set()
        return self._arc(w, end, feed)

    def _need_feed(self, word: str | None = None) -> float:
        if self.feed is None or self.feed <= 0.0:
            raise self.err(
                word or self.motion,
                "a feed move before any F word (or with F0); "
                "give the feed, e.g. F600 (units per minute), on this or an earlier line",
            )
        return self.feed

    def _unknown(self) -> bool:
        p = self.pos
        return p[0] != p[0] or p[1] != p[1] or p[2] != p[2]  # NaN test without function calls

    def _known_start(self, word: str | None) -> tuple[float, float, float]:
        if self._unknown():
            missing = "".join(c for k, c in enumerate(_AXES) if math.isnan(self.pos[k]))
            raise self.err(
                word or self.motion,
                f"the start of this feed move is unknown ({missing} not yet "
                "programmed); position X, Y and Z with G0 before the first feed move",
            )
        return (self.pos[0], self.pos[1], self.pos[2])

    def _straight(self, kind: MoveKind, end: list[float], feed: float | None, cycle: str | None = None) -> None:
        if self._unknown():
            if kind is not MoveKind.RAPID:
                self._known_start(None)
            self.pos = end
            if not self._unknown():
                self.start = (end[0], end[1], end[2])
                self.start_line = self.line
            return
        if end == self.pos:
            return
        s = (self.pos[0], self.pos[1], self.pos[2])
        self.moves.append(Move(kind, s, (end[0], end[1], end[2]), feed, self.line, self.text, cycle=cycle))
        self.pos = end

    def _arc(self, w: dict[str, Word], end: list[float], feed: float) -> set[str]:
        g = self.motion or "G2"
        start = self._known_start(g)
        ia, ib, inn = self.plane.axes
        la, lb = self.plane.offsets
        has_r = "R" in w
        ijk = [c for c in "IJK" if c in w]
        if not has_r and not ijk:
            raise self.err(g, "an arc needs its centre (I/J/K) or its radius (R); give one of them")
        if has_r and ijk:
            raise self.err(w["R"].text, "an arc with both R and I/J/K; give only one of them")
        wrong = next((c for c in ijk if c not in (la, lb)), None)
        if wrong is not None:
            raise self.err(
                w[wrong].text,
                f"not an offset of the G{self.plane.value} plane (which uses {la} and "
                f"{lb}); select the arc's plane (G17/G18/G19) or remove the word",
            )
        turns = 1
        if "P" in w:
            turns = round(w["P"].value)
            if abs(w["P"].value - turns) > 1e-6 or turns < 1:
                raise self.err(w["P"].text, "the number of turns P must be a whole number >= 1")
        ccw = g == "G3"
        a0, b0 = start[ia], start[ib]
        a1, b1 = float(end[ia]), float(end[ib])
        inch = self.scale == INCH_M
        rtol = RADIUS_TOLERANCE_INCH_M if inch else RADIUS_TOLERANCE_MM_M
        if has_r:
            if not any(c in w for c in (_AXES[ia], _AXES[ib])):
                raise self.err(
                    w["R"].text,
                    f"an R arc needs an end point in the plane ({_AXES[ia]}/{_AXES[ib]}); use I/J/K for a full circle",
                )
            geo = centre_r((a0, b0), (a1, b1), self.m(w["R"].value), ccw, turns, rtol)
            word = w["R"].text
        else:
            if self.ijk_absolute:
                for c in (la, lb):
                    if c not in w:
                        raise self.err(g, f"{c} missing in an absolute-centre (G90.1) arc; give both {la} and {lb}")
                ca, cb = self.m(w[la].value), self.m(w[lb].value)
            else:
                ca = a0 + (self.m(w[la].value) if la in w else 0.0)
                cb = b0 + (self.m(w[lb].value) if lb in w else 0.0)
            stol = CENTER_ARC_RADIUS_TOLERANCE_INCH_M if inch else CENTER_ARC_RADIUS_TOLERANCE_MM_M
            geo = centre_ijk((a0, b0), (a1, b1), (ca, cb), ccw, turns, stol, rtol)
            word = w[ijk[0]].text
        if isinstance(geo, str):
            raise self.err(word, geo + "; correct the arc in the program")
        self._emit_arc(geo, start, end, feed, turns, ccw)
        return {"I", "J", "K", "R", "P"}

    def _emit_arc(self, geo: ArcGeometry, start, end: list[float], feed: float, turns: int, ccw: bool) -> None:
        ia, ib, inn = self.plane.axes
        c = [0.0, 0.0, 0.0]
        c[ia], c[ib], c[inn] = geo.centre[0], geo.centre[1], start[inn]
        e = (float(end[0]), float(end[1]), float(end[2]))
        self.moves.append(
            Move(
                MoveKind.ARC,
                start,
                e,
                feed,
                self.line,
                self.text,
                centre=(c[0], c[1], c[2]),
                plane=self.plane,
                direction=Direction.CCW if ccw else Direction.CW,
                turns=turns,
                sweep_rad=geo.sweep,
                radius_m=geo.r0,
                helical_m=e[inn] - start[inn],
            )
        )
        self.pos = list(e)

    # ------------------------------------------------------------------ result
    def program(self) -> Program:
        if not self.moves:
            raise fail(
                self.name,
                0,
                None,
                "no moves: the program is empty or only sets modes; expected a G-code program with G0/G1/G2/G3 moves",
            )
        units = " and ".join(u for u in ("mm", "inch") if u in self.units_seen) or "mm"
        note = "" if self.units_seen else "no G20/G21: millimetres"
        return Program(
            source=self.name,
            moves=tuple(self.moves),
            start_m=self.start,
            start_line=self.start_line,
            events=tuple(self.events),
            words=tuple(self.words),
            units=units,
            units_note=note,
            path_tolerance_m=min(self.tolerances) if self.tolerances else None,
            work_offset=next(iter(self.offsets), None),
            end_line=self.end_line,
        )
