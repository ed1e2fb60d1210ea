"""Generate ``problems/files/milling_pocket.ngc``: a real-size 3-axis milling program of the kind a
CAM post writes for LinuxCNC, the program of the shipped problem ``milling_pocket``.

Run from the repository root::

    PYTHONPATH=. python benchmarks/make_milling_program.py [--out FILE] [--check]

``--check`` writes nothing and exits 1 when the shipped file differs from what this script makes
(``tests/test_milling_example.py`` checks the same). The output is deterministic: plain arithmetic,
no randomness, coordinates rounded to 0.001 mm as the post prints them.

The part (aluminium 6061-T6), in the program frame (G54: X, Y at the block's centre, Z0 on the
faced top face; mm):

* stock 120 x 80 x 31 (Z -30 .. +1), clamped in a vice by its lowest 10 mm;
* a rectangular pocket 52 x 44 x 12 deep with 10 mm corner radii, centred at (-28, 0);
* a Ø22 boss standing 8 mm deep in a Ø44 circular recess, centred at (31, 0);
* 4 Ø8 holes 25 deep at (±48, ±30), 2 Ø8 holes 4 deep in the pocket floor, a spot on the boss;
* the outline, 20 mm deep, a superellipse |x/58.5|^8 + |y/38.5|^8 = 1 (a spline in the CAD model,
  posted as straight chords: most of the program's lines, as in real CAM output).

One tool, T1: a Ø8 mm 3-flute centre-cutting carbide end mill (the robot carries one spindle and
one tool, so the holes are plunged with it too). Operations:

1. facing: a zig-zag raster at Z0 (1 mm), 16 passes, F2500;
2. pocket roughing: 12 levels of 1 mm, each entered by a helical ramp (G2 half turns, 3°) at the
   centre and cleared by 7 concentric rounded-rectangle passes outward (G3 corners, climb),
   0.25 mm left on the walls, F1800;
3. boss roughing: 8 levels of 1 mm, each a helical full circle (G2, Z down) then a full circle on
   the boss side (G2) and one on the recess wall (G3), 0.25 mm left, F1600;
4. drilling: G83 peck (Q3) at the corners, G81 in the pocket floor, G82 spot with dwell on the boss;
5. outline roughing: 10 levels of 2 mm, 0.2 mm left, arc lead-in and lead-out, F1500;
6. finishing contour under G64 P0.01: pocket walls, boss and recess walls, the outline at full
   depth, F1000.

Rapids go to the clearance plane Z15 between operations and to the retract plane Z5 within one.
Modal words are not repeated (G1, F, unchanged axes), as a post does.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "problems" / "files" / "milling_pocket.ngc"

# --- part, tool and cutting data (mm, mm/min) ---------------------------------------------------
TOOL_R = 4.0  # Ø8 end mill
CLEAR_Z = 15.0  # clearance plane between operations
RETRACT_Z = 5.0  # retract plane within an operation
BLOCK_X, BLOCK_Y = 60.0, 40.0  # half sizes of the 120 x 80 block
STOCK_TOP = 1.0  # faced off by operation 1

F_FACE, F_POCKET, F_BOSS, F_CONTOUR, F_FINISH = 2500.0, 1800.0, 1600.0, 1500.0, 1000.0
F_RAMP, F_PLUNGE, F_DRILL = 900.0, 600.0, 600.0

POCKET_C = (-28.0, 0.0)
POCKET_HALF = (26.0, 22.0)  # wall half sizes (52 x 44)
POCKET_R = 10.0  # wall corner radius
POCKET_DEPTH, POCKET_STEP = 12.0, 1.0
POCKET_STOCK = 0.25  # left on the walls for finishing
POCKET_STEPOVER = 2.5
# Smallest corner radius of an inner pass (the CAM's corner smoothing). At least 2 mm: under the
# program's 0.01 mm path tolerance the chords of a smaller arc turn by so much that every chord end
# would be an exact stop (problems/toolpath/waypoints.py, CORNER_MIN_APPROACH_M).
POCKET_MIN_R = 2.0
HELIX_R, HELIX_DEG = 2.5, 3.0

BOSS_C = (31.0, 0.0)
BOSS_R, RECESS_R = 11.0, 22.0
BOSS_DEPTH, BOSS_STEP = 8.0, 1.0
BOSS_STOCK = 0.25

OUTLINE_A, OUTLINE_B, OUTLINE_N = 58.5, 38.5, 8
OUTLINE_DEPTH, OUTLINE_STEP = 20.0, 2.0
OUTLINE_STOCK = 0.2
CHORD_TOL = 0.002  # the post's chordal tolerance for the spline, mm
CHORD_MAX = 0.5  # and its longest chord, mm
LEAD_R = 5.0  # outline lead-in / lead-out arc radius

CORNER_HOLES = ((-48.0, -30.0), (48.0, -30.0), (48.0, 30.0), (-48.0, 30.0))
FLOOR_HOLES = ((-40.0, 0.0), (-16.0, 0.0))


def fmt(v: float) -> str:
    """A coordinate as the post prints it: 3 decimals, trailing zeros dropped, ``12.`` for 12."""
    s = f"{v:.3f}".rstrip("0")
    return "0." if s in ("-0.", "0.") else s


class Post:
    """Writes lines, suppressing modal repeats (motion code, F, unchanged axes), and keeps the
    position as printed (rounded), so that arc centres are given relative to the printed start."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.pos: list[float | None] = [None, None, None]
        self.motion: str | None = None
        self.feed: float | None = None
        self.moves = 0  # G0/G1/G2/G3 lines
        self.holes = 0  # drilling-cycle holes

    def out(self, text: str) -> None:
        self.lines.append(text)

    def comment(self, text: str) -> None:
        self.out(f"({text.upper()})")

    def _motion(self, code: str) -> list[str]:
        if code == self.motion:
            return []
        self.motion = code
        return [code]

    def _axes(self, x, y, z, force_xy: bool = False) -> list[str]:
        words = []
        for k, (letter, v) in enumerate(zip("XYZ", (x, y, z))):
            if v is None:
                continue
            s = fmt(v)
            if force_xy and k < 2 or self.pos[k] is None or fmt(self.pos[k]) != s:
                words.append(letter + s)
            self.pos[k] = float(s)
        return words

    def _feed(self, f: float) -> list[str]:
        if f == self.feed:
            return []
        self.feed = f
        return ["F" + fmt(f)]

    def rapid(self, x=None, y=None, z=None, pre: str = "", extra: str = "") -> None:
        axes = self._axes(x, y, z)
        if axes:
            self.moves += 1
            self.out(" ".join(self._motion("G0") + ([pre] if pre else []) + axes + ([extra] if extra else [])))

    def line(self, x=None, y=None, z=None, f: float = F_FINISH) -> None:
        axes = self._axes(x, y, z)
        if axes:
            self.moves += 1
            self.out(" ".join(self._motion("G1") + axes + self._feed(f)))

    def arc(self, cw: bool, x: float, y: float, cx: float, cy: float, f: float, z: float | None = None) -> None:
        """G2/G3 in G17 to (x, y[, z]) about the centre (cx, cy); I, J from the printed start."""
        sx, sy = self.pos[0], self.pos[1]
        i, j = fmt(cx - sx), fmt(cy - sy)
        axes = self._axes(x, y, z, force_xy=True)
        self.moves += 1
        self.out(" ".join(self._motion("G2" if cw else "G3") + axes + [f"I{i}", f"J{j}"] + self._feed(f)))

    def cycle_end(self) -> None:
        self.out("G80")
        self.motion = None


# --- geometry -------------------------------------------------------------------------------------
def rounded_rect_ccw(p: Post, c, hx: float, hy: float, r: float, f: float) -> None:
    """A rounded rectangle, counter-clockwise, from and back to the middle of its +X side."""
    cx, cy = c
    p.line(cx + hx, cy + hy - r, f=f)
    p.arc(False, cx + hx - r, cy + hy, cx + hx - r, cy + hy - r, f)
    p.line(cx - hx + r, cy + hy, f=f)
    p.arc(False, cx - hx, cy + hy - r, cx - hx + r, cy + hy - r, f)
    p.line(cx - hx, cy - hy + r, f=f)
    p.arc(False, cx - hx + r, cy - hy, cx - hx + r, cy - hy + r, f)
    p.line(cx + hx - r, cy - hy, f=f)
    p.arc(False, cx + hx, cy - hy + r, cx + hx - r, cy - hy + r, f)
    p.line(cx + hx, cy, f=f)


def levels(depth: float, step: float) -> list[float]:
    n = math.ceil(depth / step - 1e-9)
    return [-depth * (k + 1) / n for k in range(n)]


def outline_path(offset: float) -> list[tuple[float, float]]:
    """The tool-centre path around the superellipse outline, ``offset`` outside it, clockwise from
    and back to its +X point, as chords within CHORD_TOL and no longer than CHORD_MAX."""
    a, b, n = OUTLINE_A, OUTLINE_B, OUTLINE_N
    th = -np.linspace(0.0, 2.0 * math.pi, 72001)  # polar angle, clockwise
    c, s = np.cos(th), np.sin(th)
    r = (np.abs(c / a) ** n + np.abs(s / b) ** n) ** (-1.0 / n)
    x, y = r * c, r * s
    gx = np.sign(x) * np.abs(x / a) ** (n - 1) / a  # the implicit function's gradient: the normal
    gy = np.sign(y) * np.abs(y / b) ** (n - 1) / b
    g = np.hypot(gx, gy)
    P = np.column_stack([x + offset * gx / g, y + offset * gy / g])
    P[-1] = P[0]
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(P, axis=0).T))])  # arc length

    def fits(i: int, j: int) -> bool:
        d = P[j] - P[i]
        L = math.hypot(d[0], d[1])
        if L > CHORD_MAX:
            return False
        q = P[i + 1 : j] - P[i]
        return bool(np.all(np.abs(q[:, 0] * d[1] - q[:, 1] * d[0]) <= CHORD_TOL * L))

    out, i, last = [tuple(P[0])], 0, len(P) - 1
    while i < last:
        lo, hi = i + 1, min(int(np.searchsorted(cum, cum[i] + 1.01 * CHORD_MAX)), last)
        while lo < hi:  # the farthest j that fits (fitting is monotone on a convex curve)
            mid = (lo + hi + 1) // 2
            if fits(i, mid):
                lo = mid
            else:
                hi = mid - 1
        i = lo
        out.append(tuple(P[i]))
    return [(float(u), float(v)) for u, v in out]


# --- operations ----------------------------------------------------------------------------------
def header(p: Post) -> None:
    p.out("%")
    p.comment("milling_pocket - 120 x 80 x 31 block, aluminium 6061-T6")
    p.comment("made by benchmarks/make_milling_program.py - do not edit")
    p.comment("G54: X0 Y0 block centre, Z0 faced top face; stock Z-30 .. Z1")
    p.comment("T1 D8 3FL carbide flat end mill, centre cutting, H1")
    p.out("G21 G90 G17 G94 G40 G49 G80 G54")
    p.out("G64 P0.05")
    p.out("T1 M6")
    p.out("S12000 M3")
    p.rapid(-BLOCK_X - TOOL_R - 2.0, -BLOCK_Y + TOOL_R - 1.0)
    p.rapid(z=CLEAR_Z, pre="G43", extra="H1")  # tool length offset with the first Z move, as posts write it
    p.out("M8")


def facing(p: Post) -> None:
    p.comment("op1 facing - Z0, 1 mm, zig-zag, stepover 4.93")
    x0 = BLOCK_X + TOOL_R + 2.0
    y0 = BLOCK_Y - TOOL_R + 1.0
    n = math.ceil(2 * y0 / 5.0)
    p.rapid(-x0, -y0)
    p.rapid(z=RETRACT_Z)
    p.line(z=0.0, f=F_PLUNGE)
    for k in range(n + 1):
        y = -y0 + 2 * y0 * k / n
        p.line(y=y, f=F_FACE)
        p.line(x=x0 if k % 2 == 0 else -x0, f=F_FACE)
    p.rapid(z=CLEAR_Z)


def pocket(p: Post) -> None:
    cx, cy = POCKET_C
    hx0 = POCKET_HALF[0] - TOOL_R - POCKET_STOCK
    hy0 = POCKET_HALF[1] - TOOL_R - POCKET_STOCK
    r0 = POCKET_R - TOOL_R - POCKET_STOCK
    rings = []
    d = 0.0
    while hy0 - d >= 2.0:
        hx, hy = hx0 - d, hy0 - d
        rings.append((hx, hy, min(max(r0 - d, POCKET_MIN_R), hy)))
        d += POCKET_STEPOVER
    rings.reverse()  # from the centre outward
    p.comment(f"op2 pocket roughing - 52 x 44 x 12, R10, {len(rings)} passes, 1 mm levels, helical entry")
    per_half = math.pi * HELIX_R * math.tan(math.radians(HELIX_DEG))
    z_prev = 0.0
    p.rapid(cx + HELIX_R, cy)
    for z in levels(POCKET_DEPTH, POCKET_STEP):
        p.rapid(cx + HELIX_R, cy, RETRACT_Z)
        p.rapid(z=z_prev + 1.0)
        z_top = z_prev + 1.0
        halves = math.ceil((z_top - z) / per_half)
        for k in range(1, halves + 1):
            side = -1.0 if k % 2 else 1.0
            p.arc(True, cx + side * HELIX_R, cy, cx, cy, F_RAMP, z=z_top + (z - z_top) * k / halves)
        if halves % 2:  # end the ramp where it began
            p.arc(True, cx + HELIX_R, cy, cx, cy, F_RAMP)
        p.arc(True, cx + HELIX_R, cy, cx, cy, F_POCKET)  # a flat full circle: the ramp's floor
        for hx, hy, r in rings:
            p.line(cx + hx, cy, f=F_POCKET)
            rounded_rect_ccw(p, POCKET_C, hx, hy, r, F_POCKET)
        p.rapid(z=RETRACT_Z)
        z_prev = z
    p.rapid(z=CLEAR_Z)


def boss(p: Post) -> None:
    cx, cy = BOSS_C
    r_in = BOSS_R + TOOL_R + BOSS_STOCK
    r_out = RECESS_R - TOOL_R - BOSS_STOCK
    r_mid = 0.5 * (r_in + r_out)
    p.comment("op3 boss roughing - D22 boss in a D44 recess 8 deep, 1 mm levels, helical full circles")
    z_prev = 0.0
    p.rapid(cx + r_mid, cy)
    for z in levels(BOSS_DEPTH, BOSS_STEP):
        p.rapid(cx + r_mid, cy, z_prev + 1.0)
        p.arc(True, cx + r_mid, cy, cx, cy, F_RAMP, z=z)  # one helical turn down
        p.line(cx + r_in, cy, f=F_BOSS)
        p.arc(True, cx + r_in, cy, cx, cy, F_BOSS)  # boss side, climb
        p.line(cx + r_out, cy, f=F_BOSS)
        p.arc(False, cx + r_out, cy, cx, cy, F_BOSS)  # recess wall, climb
        p.rapid(z=z + 1.0)
        z_prev = z
    p.rapid(z=CLEAR_Z)


def drilling(p: Post) -> None:
    p.comment("op4 drilling - 4 x D8 25 deep peck Q3, 2 x D8 4 deep in the pocket floor, spot on the boss")

    def hole(codes: str, x: float, y: float, params: str = "") -> None:
        words = [f"X{fmt(x)}" if codes or x != p.pos[0] else "", f"Y{fmt(y)}" if codes or y != p.pos[1] else ""]
        p.out(" ".join(w for w in [codes, *words, params] if w))
        p.pos[0], p.pos[1] = x, y
        p.holes += 1

    x, y = CORNER_HOLES[0]
    p.rapid(x, y)
    p.rapid(z=RETRACT_Z)  # the initial level, where G98 returns between holes
    p.feed = F_DRILL
    hole("G98 G83", x, y, f"Z-25. R2. Q3. F{fmt(F_DRILL)}")
    for x, y in CORNER_HOLES[1:]:
        hole("", x, y)
    for k, (x, y) in enumerate(FLOOR_HOLES):
        hole(
            "G81" if k == 0 else "", x, y, f"Z{fmt(-POCKET_DEPTH - 4.0)} R{fmt(-POCKET_DEPTH + 1.0)}" if k == 0 else ""
        )
    hole("G82", *BOSS_C, "Z-1.5 R2. P0.3")
    p.cycle_end()
    p.pos[2] = RETRACT_Z
    p.rapid(z=CLEAR_Z)


def outline_loop(p: Post, z: float, pts: list[tuple[float, float]], f: float) -> None:
    """Lead-in arc, the clockwise loop, lead-out arc, at height z (outside the block)."""
    x0, y0 = pts[0]
    p.rapid(x0 + LEAD_R, y0 + LEAD_R)
    p.rapid(z=RETRACT_Z)
    p.rapid(z=z + 1.0)
    p.line(z=z, f=F_PLUNGE)
    p.arc(False, x0, y0, x0 + LEAD_R, y0, f)
    for x, y in pts[1:]:
        p.line(x, y, f=f)
    p.arc(False, x0 + LEAD_R, y0 - LEAD_R, x0 + LEAD_R, y0, f)
    p.rapid(z=RETRACT_Z)


def outline_roughing(p: Post) -> None:
    pts = outline_path(TOOL_R + OUTLINE_STOCK)
    p.comment(f"op5 outline roughing - superellipse 117 x 77 n8, 20 deep, 2 mm levels, {len(pts) - 1} chords a level")
    for z in levels(OUTLINE_DEPTH, OUTLINE_STEP):
        outline_loop(p, z, pts, F_CONTOUR)
    p.rapid(z=CLEAR_Z)


def finishing(p: Post) -> None:
    p.comment("op6 finishing contour - pocket walls, boss, recess wall, outline; path tolerance 0.01")
    p.out("G64 P0.01")
    # pocket walls at the floor, arc lead-in from the inside, counter-clockwise (climb)
    cx, cy = POCKET_C
    hx, hy = POCKET_HALF[0] - TOOL_R, POCKET_HALF[1] - TOOL_R
    lr = 4.0
    p.rapid(cx + hx - lr, cy - lr)
    p.rapid(z=RETRACT_Z)
    p.rapid(z=-POCKET_DEPTH + 1.0)
    p.line(z=-POCKET_DEPTH, f=F_PLUNGE)
    p.arc(False, cx + hx, cy, cx + hx - lr, cy, F_FINISH)
    rounded_rect_ccw(p, POCKET_C, hx, hy, POCKET_R - TOOL_R, F_FINISH)
    p.arc(False, cx + hx - lr, cy + lr, cx + hx - lr, cy, F_FINISH)
    p.rapid(z=CLEAR_Z)
    # boss side (clockwise) and recess wall (counter-clockwise), full circles at the floor
    bx, by = BOSS_C
    r_in, r_out = BOSS_R + TOOL_R, RECESS_R - TOOL_R
    p.rapid(bx + r_in + 2.0, by + 2.0)
    p.rapid(z=RETRACT_Z)
    p.rapid(z=-BOSS_DEPTH + 1.0)
    p.line(z=-BOSS_DEPTH, f=F_PLUNGE)
    p.arc(False, bx + r_in, by, bx + r_in + 2.0, by, F_FINISH)
    p.arc(True, bx + r_in, by, bx, by, F_FINISH)
    p.arc(False, bx + r_in + 2.0, by - 2.0, bx + r_in + 2.0, by, F_FINISH)
    p.line(bx + r_out - 1.5, by - 1.5, f=F_FINISH)
    p.arc(False, bx + r_out, by, bx + r_out - 1.5, by, F_FINISH)
    p.arc(False, bx + r_out, by, bx, by, F_FINISH)
    p.arc(False, bx + r_out - 1.5, by + 1.5, bx + r_out - 1.5, by, F_FINISH)
    p.rapid(z=CLEAR_Z)
    # the outline at full depth
    outline_loop(p, -OUTLINE_DEPTH, outline_path(TOOL_R), F_FINISH)
    p.rapid(z=CLEAR_Z)


def build() -> Post:
    """The program, posted."""
    p = Post()
    header(p)
    facing(p)
    pocket(p)
    boss(p)
    drilling(p)
    outline_roughing(p)
    finishing(p)
    p.out("M5")
    p.out("M9")
    p.out("M30")
    p.out("%")
    return p


def generate() -> str:
    """The program's text (ASCII, one newline after every line)."""
    return "\n".join(build().lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=OUT, help=f"output file (default {OUT})")
    ap.add_argument("--check", action="store_true", help="compare with the file instead of writing it")
    args = ap.parse_args(argv)
    p = build()
    text = "\n".join(p.lines) + "\n"
    if args.check:
        same = args.out.is_file() and args.out.read_bytes() == text.encode("ascii")
        print(f"{args.out}: {'up to date' if same else 'differs from the generator'}")
        return 0 if same else 1
    args.out.write_bytes(text.encode("ascii"))
    print(f"wrote {args.out}: {len(p.lines)} lines, {p.moves} G0/G1/G2/G3 moves, {p.holes} cycle holes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
