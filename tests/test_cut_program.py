"""The load from the cut (issue 35): a G-code program's predicted cutting wrench against an
independent implementation written here.

* the engagement from the geometry of each pass (which side of the feed has material) and
  Altintas' closed-form mean forces and moments of a flat end mill (*Manufacturing Automation*, 2nd
  ed., 2012, ch. 2: the linear edge-force model integrated over the immersion), turned into the
  program frame by the feed direction;
* the removed volume against the analytic volume of slots, a pocket and a ramp;
* the compensated commands of a planned cut, run through an independent arm (pinocchio kinematics,
  the robot file's joint stiffness) under the independently computed cutting wrench, land on the
  waypoints;
* bad inputs: one clear message, exit status 2, nothing written;
* ``Problem.to_dict`` round trip.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from models.errors import InputError
from problems.cutting.prediction import MILLING_CODES, Milling
from problems.problem import ProblemFileError, load_problem, problem_from_dict

#: Predicted mean force against the closed form, relative to the closed form's magnitude (issue 35).
FORCE_REL_TOL = 0.05
#: Predicted mean moment (about the tool tip) against the closed form, relative to its magnitude.
MOMENT_REL_TOL = 0.05
#: Removed volume against the analytic volume, relative (issue 35).
VOLUME_REL_TOL = 0.01
#: The compensated commands land on the waypoints under the independent arm within this, m.
LANDING_TOL_M = 1e-6
#: The cut must bend the uncompensated arm by more than this for the landing check to mean something, m.
MIN_DEFLECTION_M = 1e-4
#: Wrench of every waypoint, transitions included, against the closed form with the engagement from
#: the geometry, relative to the program's largest (the programs here put every engagement boundary
#: on a whole degree, where the product's angle bins end).
ALL_WAYPOINTS_REL_TOL = 1e-3
#: Fixed point of the static equilibrium: iterate until the joint update is below this, rad.
EQUILIBRIUM_STEP_RAD = 1e-14

# The end mill and the material (SI), as written into the problem files below.
DIAMETER_M = 0.008
RADIUS_M = DIAMETER_M / 2.0
FLUTES = 3
#: Al7075-T6 (Altintas' worked example, as in the shipped table), N/m^2 and N/m.
KTC, KRC, KAC = 796e6, 168.8e6, 222e6
KTE, KRE, KAE = 27.7e3, 30.8e3, 1.4e3
SPINDLE_RPM = 10000.0
DEPTH_M = 0.002  # every cut of these programs is 2 mm deep (the slots) unless said otherwise
MM = 1e-3

#: A flat end mill, the six coefficients in SI, a box stock in the program frame.
PROBLEM = """\
name = "cut"
[robot]
model = "ur10"
[robot.tool]
xyz = [0.08, 0.0, {tool_z}]
[robot.tool.cutter]
shape = "flat"
diameter = {diameter}
flutes = 3
helix_deg = 30.0
flute_length = {flute_length}
length = 0.035
[path]
kind = "{kind}"
file = "{file}"
[workpiece]
xyz = [0.65, 0.0, 0.10]
rpy_deg = [0.0, 0.0, {yaw_deg}]
{orientation}
[material]
Ktc = {ktc}
Krc = 168.8e6
Kac = 222e6
Kte = 27.7e3
Kre = 30.8e3
Kae = 1.4e3
source = "Altintas, Manufacturing Automation, 2nd ed., ch. 2 (Al7075-T6)"
[stock]
box_min = [{stock_min}]
box_max = [{stock_max}]
resolution = 0.0001
{cut}
[timing]
dt = 0.002
[limits]
max_joint_step = 0.3
"""
DEFAULTS = {
    "tool_z": "0.12",
    "diameter": "0.008",
    "flute_length": "0.026",
    "kind": "gcode",
    "yaw_deg": "0.0",
    "orientation": '[orientation]\nrule = "free_tool_axis"',
    "ktc": "796e6",
    "stock_min": "0.0, -0.040, -0.010",
    "stock_max": "0.060, 0.060, 0.0",
    "cut": "",
}

HEAD = "%\nG21 G90 G17 G94 G40 G49 G80 G54\n"

#: Item 1: a slot along X, an up-milling and a down-milling pass beside it along its walls, an L slot,
#: a slot at F100, a feed move above the stock, then M4: a half-immersion pass and a slot.
PROGRAM_1 = (
    HEAD
    + """S10000 M3
G0 X-10 Y0 Z5
G0 Z-2
G1 X70 F600
G0 Z5
G0 X-10 Y4
G0 Z-2
G1 X70 F600
G0 Z5
G0 X-10 Y-4
G0 Z-2
G1 X70 F600
G0 Z5
G0 X-10 Y20
G0 Z-2
G1 X30 F600
G1 Y70
G0 Z5
G0 X-10 Y-32
G0 Z-2
G1 X70 F100
G0 Z5
G0 X-10 Y40
G0 Z1
G1 X70 F600
G0 Z5
M5
S10000 M4
G0 X-10 Y-8
G0 Z-2
G1 X70 F600
G0 Z5
G0 X-10 Y-20
G0 Z-2
G1 X70 F600
G0 Z5
M5
M30
%
"""
)

#: The passes of PROGRAM_1 (mm): start, end, expected engagement, feed (mm/min), spindle sense
#: (+1 M3, -1 M4).  Up/down by the rule: the material on the left of the feed with M3 (on the right
#: with M4) is up-milling.
PASSES_1 = (
    ((-10, 0), (70, 0), Milling.SLOT, 600, 1),
    ((-10, 4), (70, 4), Milling.UP, 600, 1),  # material at y > 4: left of +X
    ((-10, -4), (70, -4), Milling.DOWN, 600, 1),  # material at y < -4: right of +X
    ((-10, 20), (30, 20), Milling.SLOT, 600, 1),
    ((30, 20), (30, 70), Milling.SLOT, 600, 1),  # the L turns: the force turns with the feed
    ((-10, -32), (70, -32), Milling.SLOT, 100, 1),
    ((-10, -8), (70, -8), Milling.UP, 600, -1),  # M4, material at y < -8: right of +X
    ((-10, -20), (70, -20), Milling.SLOT, 600, -1),
)
STOCK_MM = ((0.0, 60.0), (-40.0, 60.0))


def _write(tmp_path: Path, program: str, name: str = "part.ngc", **fields: str) -> Path:
    (tmp_path / name).write_text(program)
    f = tmp_path / "p.toml"
    f.write_text(PROBLEM.format(**{**DEFAULTS, "file": name, **fields}))
    return f


# --------------------------------------------------------------------------------------------------
# The independent model
# --------------------------------------------------------------------------------------------------


def closed_form_wrench(phi_st: float, phi_ex: float, a: float, c: float) -> np.ndarray:
    """Mean wrench over a revolution of a flat end mill engaged over ``[phi_st, phi_ex]`` (rad) on an
    axial depth ``a`` (m) with feed per tooth ``c`` (m), shape (6,): force on the tool (N) and moment
    about the tool tip (N m), feed frame (x feed, z tool axis, y = z x x), clockwise spindle.

    Per unit height at immersion ``phi``: ``ft = Ktc c sin(phi) + Kte`` (likewise ``fr``, ``fa``),
    ``fx = -ft cos - fr sin``, ``fy = ft sin - fr cos``, ``fz = -fa`` at the edge point
    ``(R sin, R cos, z)``; the mean is ``N / (2 pi)`` times the integral over ``phi`` and ``z``."""
    n, r = FLUTES, RADIUS_M

    def at(p: float) -> np.ndarray:
        s2, c2 = math.sin(2 * p), math.cos(2 * p)
        sin, cos = math.sin(p), math.cos(p)
        fx = c * (KTC * c2 - KRC * (2 * p - s2)) / 4 + (-KTE * sin + KRE * cos)
        fy = c * (KTC * (2 * p - s2) + KRC * c2) / 4 - (KTE * cos + KRE * sin)
        fa = -KAC * c * cos + KAE * p  # integral of fa
        ft = -KTC * c * cos + KTE * p  # integral of ft
        cos_fa = KAC * c * sin * sin / 2 + KAE * sin  # integral of cos(phi) fa
        sin_fa = KAC * c * (2 * p - s2) / 4 - KAE * cos  # integral of sin(phi) fa
        return np.array([fx, fy, -fa, ft, cos_fa, sin_fa])

    i = (at(phi_ex) - at(phi_st)) * n / (2 * math.pi)
    f = a * i[:3]
    mx = -a * r * i[4] - a / 2 * f[1]
    my = a / 2 * f[0] + a * r * i[5]
    mz = a * r * i[3]
    return np.r_[f, mx, my, mz]


def feed_frame_to_program(w_feed: np.ndarray, direction: np.ndarray, sense: int) -> np.ndarray:
    """A feed-frame wrench (shape (6,)) in the program frame: x the horizontal feed direction, z the
    program's +Z, y = z x x.  For a counter-clockwise spindle the wrench was computed in the mirrored
    frame (y -> -y): forces mirror, moments (axial vectors) mirror and change sign."""
    x = np.array([direction[0], direction[1], 0.0]) / math.hypot(direction[0], direction[1])
    z = np.array([0.0, 0.0, 1.0])
    y = np.cross(z, x)
    f, m = w_feed[:3].copy(), w_feed[3:].copy()
    if sense < 0:
        f[1] = -f[1]
        m = -m * np.array([1.0, -1.0, 1.0])
    R = np.column_stack([x, y, z])
    return np.r_[R @ f, R @ m]


def feed_per_tooth(feed_mm_min: float) -> float:
    """``c = F / (N S)``, m."""
    return feed_mm_min * MM / 60.0 / (FLUTES * SPINDLE_RPM / 60.0)


ENGAGEMENT = {Milling.SLOT: (0.0, math.pi), Milling.UP: (0.0, math.pi / 2), Milling.DOWN: (math.pi / 2, math.pi)}


def _on_pass(p: np.ndarray, d: np.ndarray, pas: tuple) -> float | None:
    """Distance travelled along the pass to ``p`` (mm) when ``p`` lies on it moving along it, else None."""
    a, b = np.array(pas[0], float), np.array(pas[1], float)
    u = (b - a) / np.linalg.norm(b - a)
    s = float((p - a) @ u)
    off = np.linalg.norm(p - a - s * u)
    if off > 1e-6 or not (0.0 < s <= np.linalg.norm(b - a) + 1e-9) or np.linalg.norm(d) == 0.0:
        return None
    return s if float(d @ u) > 0.999 * np.linalg.norm(d) else None


def _steady(p: np.ndarray, s: float, stock: tuple) -> bool:
    """At least a cutter diameter past the pass's start and inside the stock's sides (mm)."""
    dia = DIAMETER_M / MM
    (x0, x1), (y0, y1) = stock
    return s >= dia and x0 + dia <= p[0] <= x1 - dia and y0 + dia <= p[1] <= y1 - dia


# --------------------------------------------------------------------------------------------------
# 1. The wrench of each pass against the closed form
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def problem_1(tmp_path_factory):
    return load_problem(_write(tmp_path_factory.mktemp("cut1"), PROGRAM_1))


def test_wrench_of_each_pass_matches_the_closed_form(problem_1):
    pr = problem_1
    cut, way = pr.cut, pr.program.waypoints
    P = way.points_m[:, :2] / MM
    Z = way.points_m[:, 2] / MM
    compared = dict.fromkeys(range(len(PASSES_1)), 0)
    worst_f = worst_m = 0.0
    for k in range(1, pr.n):
        if way.rapid[k] or abs(Z[k] + DEPTH_M / MM) > 1e-9:
            continue
        for i, pas in enumerate(PASSES_1):
            s = _on_pass(P[k], P[k] - P[k - 1], pas)
            if s is None:
                continue
            if not _steady(P[k], s, STOCK_MM):
                break
            kind, feed, sense = pas[2], pas[3], pas[4]
            assert MILLING_CODES[cut.milling[k]] is kind, (k, pas, MILLING_CODES[cut.milling[k]])
            w_feed = closed_form_wrench(*ENGAGEMENT[kind], DEPTH_M, feed_per_tooth(feed))
            ref = feed_frame_to_program(w_feed, np.subtract(pas[1], pas[0]), sense)
            got = cut.wrench_program[k]
            ef = np.linalg.norm(got[:3] - ref[:3]) / np.linalg.norm(ref[:3])
            em = np.linalg.norm(got[3:] - ref[3:]) / np.linalg.norm(ref[3:])
            assert ef < FORCE_REL_TOL, (k, pas, got[:3], ref[:3])
            assert em < MOMENT_REL_TOL, (k, pas, got[3:], ref[3:])
            worst_f, worst_m = max(worst_f, ef), max(worst_m, em)
            compared[i] += 1
            break
    # every pass was compared on its steady part (the check is not vacuous)
    assert min(compared.values()) >= 5, compared
    print(f"max relative force error {worst_f:.2e}, moment error {worst_m:.2e}")


def test_the_l_slot_force_turns_with_the_feed(problem_1):
    """On the L slot's second leg the force is the first leg's turned by 90 deg about +Z."""
    cut, P = problem_1.cut, problem_1.program.waypoints.points_m / MM
    first = np.flatnonzero((np.abs(P[:, 1] - 20) < 1e-9) & (np.abs(P[:, 0] - 20) < 1e-9) & (P[:, 2] < 0))
    second = np.flatnonzero((np.abs(P[:, 0] - 30) < 1e-9) & (np.abs(P[:, 1] - 40) < 1e-9) & (P[:, 2] < 0))
    assert first.size == 1 and second.size == 1
    f1, f2 = cut.wrench_program[first[0], :3], cut.wrench_program[second[0], :3]
    turned = np.array([-f1[1], f1[0], f1[2]])
    assert np.linalg.norm(f2 - turned) < FORCE_REL_TOL * np.linalg.norm(f1), (f1, f2)
    assert np.linalg.norm(f2 - f1) > 0.5 * np.linalg.norm(f1)  # it did turn


def test_air_and_rapid_waypoints_carry_no_wrench(problem_1):
    cut, way = problem_1.cut, problem_1.program.waypoints
    Z = way.points_m[:, 2]
    air = (~way.rapid) & (Z > 0.0)  # feed moves above the stock's top
    assert air.sum() >= 10
    assert np.all(cut.wrench_program[air] == 0.0)
    assert np.all(cut.wrench_program[way.rapid] == 0.0)
    assert np.all(np.asarray(cut.milling)[air | way.rapid] == MILLING_CODES.index(Milling.AIR))
    # and the cut does load the feed moves in the stock
    assert np.abs(cut.wrench_program[(~way.rapid) & (Z < 0.0)]).max() > 10.0


def test_every_waypoint_matches_the_engagement_from_the_geometry(problem_1):
    """Transitions included (entries, exits, the L's corner), with the engagement found from the
    block and the slots the earlier moves left."""
    way = problem_1.program.waypoints
    pts = way.points_m / MM
    m4_line = PROGRAM_1.splitlines().index("S10000 M4") + 1
    sense = np.where(way.line > m4_line, -1, 1)
    feed = np.where(np.abs(pts[:, 1] + 32.0) < 1e-9, 100.0, 600.0)
    W = independent_program_wrench(pts, way.rapid, feed, sense, way.stop)
    got = problem_1.cut.wrench_program
    err = np.abs(got - W) / np.abs(W).max(axis=0)
    assert err.max() < ALL_WAYPOINTS_REL_TOL, (np.unravel_index(err.argmax(), err.shape), err.max())
    partial = [k for k in range(problem_1.n) if 0 < np.linalg.norm(W[k, :3]) < 0.95 * np.abs(W[:, :3]).max()]
    assert len(partial) >= 10  # transitions were compared
    print(f"all waypoints: max error {err.max():.2e} of the largest wrench component")


# --------------------------------------------------------------------------------------------------
# 2. Removed volume
# --------------------------------------------------------------------------------------------------

#: A pocket (zigzag and contour around a 30 x 12 mm rectangle, plunged in, 3 mm deep) and a ramp
#: descending 3 mm over 80 mm along y = 45, in a 60 x 60 x 10 mm block.
PROGRAM_2 = (
    HEAD
    + """S10000 M3
G0 X10 Y10 Z3
G1 Z-3 F200
G1 X40 F600
G1 Y16
G1 X10
G1 Y22
G1 X40
G1 Y10
G1 X10
G1 Y22
G0 Z3
G0 X-10 Y45
G1 Z0 F200
G1 X70 Z-3 F600
G0 Z5
M5
M30
%
"""
)


def test_removed_volume_of_the_slots_matches_the_analytic_volume(problem_1):
    r = RADIUS_M / MM
    strips = 8 + 4 + 4 + 8 + 4 + 8  # slot, up, down, F100 slot, M4 half, M4 slot: widths, mm
    # the L: leg along y = 20 to x = 30 and leg along x = 30 from y = 20 out of the block, their
    # overlap counted once, and the quarter disc the corner leaves outside both legs
    l_slot = 30 * 8 + 8 * 40 - 4 * 4 + math.pi * r * r / 4
    expected = (60 * strips + l_slot) * DEPTH_M / MM * MM**3
    got = problem_1.cut.removed_m3
    assert abs(got - expected) < VOLUME_REL_TOL * expected, (got, expected)
    block = 60 * 100 * 10 * MM**3
    assert problem_1.cut.stock_volume_m3 == pytest.approx(block, rel=1e-12)
    print(f"slots: removed {got * 1e9:.2f} mm^3, analytic {expected * 1e9:.2f} mm^3")


def test_removed_volume_of_a_pocket_and_a_ramp(tmp_path):
    pr = load_problem(_write(tmp_path, PROGRAM_2, stock_min="0.0, 0.0, -0.010", stock_max="0.060, 0.060, 0.0"))
    r = RADIUS_M / MM
    # the pocket: the rectangle 30 x 12 mm grown by the radius, its corners rounded
    pocket = (30 + 2 * r) * (12 + 2 * r) - 4 * (r * r - math.pi * r * r / 4)
    pocket_mm3 = pocket * 3.0
    # the ramp: tip height z(x) = -3 (x + 10) / 80 mm; a flat bottom at distance d from the axis is at
    # the lowest tip within reach, x + sqrt(r^2 - d^2) ahead: depth s (x + 10 + w(d)) for x in 0..60
    s, length = 3.0 / 80.0, 60.0
    ramp_mm3 = s * (2 * r * (length**2 / 2 + 10 * length) + length * math.pi * r * r / 2)
    expected = (pocket_mm3 + ramp_mm3) * MM**3
    got = pr.cut.removed_m3
    assert abs(got - expected) < VOLUME_REL_TOL * expected, (got, expected)
    # the pocket's plunge (line 5) is reported, the plunge in the air before the ramp (line 16) is not
    plunges = [w for w in pr.cut.warnings if "plunge" in w]
    assert len(plunges) == 1 and "1 program line(s)" in plunges[0] and "(lines 5)" in plunges[0], plunges
    # a vertical move is a plunge where it removes material, air above the stock or beside it
    way, codes = pr.program.waypoints, np.asarray(pr.cut.milling)
    vertical = np.r_[False, np.all(np.diff(way.points_m[:, :2], axis=0) == 0.0, axis=1)] & ~way.rapid
    into = vertical & (way.points_m[:, 2] < 0.0) & (way.line == 5)
    # the plunge's end is a stop where the pocket's cut starts: it carries that cut (docs/cutting.md)
    start = into & way.stop
    assert start.sum() == 1 and codes[start][0] not in (
        MILLING_CODES.index(Milling.AIR),
        MILLING_CODES.index(Milling.PLUNGE),
    )
    assert np.abs(pr.cut.wrench_program[start, :3]).max() > 1.0
    assert (into & ~start).sum() >= 1 and np.all(codes[into & ~start] == MILLING_CODES.index(Milling.PLUNGE))
    above = vertical & ((way.points_m[:, 2] >= 0.0) | (way.line == 16))
    assert above.sum() >= 2 and np.all(codes[above] == MILLING_CODES.index(Milling.AIR)), codes[above]
    assert np.all(pr.cut.wrench_program[vertical & ~start] == 0.0)
    print(f"pocket + ramp: removed {got * 1e9:.2f} mm^3, analytic {expected * 1e9:.2f} mm^3")


# --------------------------------------------------------------------------------------------------
# 3. The compensated commands of a planned cut land under an independent arm
# --------------------------------------------------------------------------------------------------

#: A slot entering the block from its side, then turning 90 deg: 28 waypoints, in a program frame
#: turned 30 deg about the base's z.
PROGRAM_3 = (
    HEAD
    + """S10000 M3
G0 X-6 Y0 Z3
G0 Z-2
G1 X20 F600
G1 Y16
G0 Z3
M5
M30
%
"""
)
YAW_3_DEG = 30.0
WORKPIECE_3_M = np.array([0.65, 0.0, 0.10])
TOOL_3_M = np.array([0.08, 0.0, 0.12])
#: Immersion grid on which the engaged set is found (then its ends refined by bisection).
PHI_GRID = 721
BISECTION_STEPS = 60


def _in_material(
    q: np.ndarray, cuts: list[tuple[np.ndarray, np.ndarray]], r: float = RADIUS_M / MM, block: bool = True
) -> np.ndarray:
    """Whether points ``q`` (M, 2) of the 2 mm deep layer (mm) are in the block (STOCK_MM; anywhere
    when ``block`` is False) and not within ``r`` (mm, the cutter's radius) of an earlier cutting
    move's axis (the slot it left)."""
    (x0, x1), (y0, y1) = STOCK_MM
    inside = np.ones(len(q), dtype=bool)
    if block:
        inside = (q[:, 0] >= x0) & (q[:, 0] <= x1) & (q[:, 1] >= y0) & (q[:, 1] <= y1)
    for a, b in cuts:
        ab = b - a
        t = np.clip(((q - a) @ ab) / float(ab @ ab), 0.0, 1.0)
        inside &= np.linalg.norm(q - a - t[:, None] * ab, axis=1) >= r
    return inside


def _engaged_intervals(tip: np.ndarray, x: np.ndarray, sense: int, cuts: list) -> list[tuple[float, float]]:
    """The immersion intervals (rad) of ``[0, pi]`` where the edge (radius R) is in material; the
    edge point at ``phi`` is ``tip + R (sin phi x + sense cos phi y)``, ``y`` left of the feed ``x``
    (mm; ``sense`` -1 for M4, the mirrored frame)."""
    r = RADIUS_M / MM
    y = sense * np.array([-x[1], x[0]])
    near = [(a, b) for a, b in cuts if not _in_material(tip[None, :], [(a, b)], 2 * r, False)[0]]

    def inside(phi: np.ndarray) -> np.ndarray:
        q = tip[None, :] + r * (np.sin(phi)[:, None] * x[None, :] + np.cos(phi)[:, None] * y[None, :])
        return _in_material(q, near)

    phi = np.linspace(0.0, math.pi, PHI_GRID)
    m = inside(phi)
    ends = [0.0] if m[0] else []
    for i in np.flatnonzero(m[1:] != m[:-1]):
        lo, hi = phi[i], phi[i + 1]
        for _ in range(BISECTION_STEPS):
            mid = 0.5 * (lo + hi)
            if inside(np.array([mid]))[0] == m[i]:
                lo = mid
            else:
                hi = mid
        ends.append(0.5 * (lo + hi))
    if m[-1]:
        ends.append(math.pi)
    return list(zip(ends[::2], ends[1::2]))


#: Where the product samples a move first (its spacing, ``problems.cutting.program_cut.SAMPLE_SPACING_M``):
#: a waypoint where the cutter starts cutting carries the force of that first sample (docs/cutting.md).
START_SAMPLE_MM = 1.0


def independent_program_wrench(
    points_mm: np.ndarray, rapid: np.ndarray, feed_mm_min: np.ndarray, sense: np.ndarray, stop: np.ndarray
) -> np.ndarray:
    """The mean cutting wrench at every waypoint of a program cutting 2 mm deep layers of STOCK_MM
    (program frame), shape (N, 6): the engagement from the geometry against the stock left by the
    earlier moves, the closed form over each engaged interval."""
    W = np.zeros((len(points_mm), 6))
    cuts: list[tuple[np.ndarray, np.ndarray]] = []
    for k in range(1, len(points_mm)):
        a, b = points_mm[k - 1], points_mm[k]
        if rapid[k] or b[2] > 0.0:
            continue
        assert abs(a[2] - b[2]) < 1e-9 and abs(b[2] + DEPTH_M / MM) < 1e-9  # a horizontal cut 2 mm deep
        d = b[:2] - a[:2]
        x = d / np.linalg.norm(d)
        c = feed_per_tooth(feed_mm_min[k])
        parts = _engaged_intervals(b[:2], x, int(sense[k]), cuts)
        w = sum((closed_form_wrench(p0, p1, DEPTH_M, c) for p0, p1 in parts), np.zeros(6))
        W[k] = feed_frame_to_program(w, d, int(sense[k]))
        if stop[k - 1] and not W[k - 1].any():  # the cutter starts cutting at a stop: it carries that cut
            first = a[:2] + d / math.ceil(np.linalg.norm(d) / START_SAMPLE_MM - 1e-9)
            parts = _engaged_intervals(first, x, int(sense[k]), cuts)
            w = sum((closed_form_wrench(p0, p1, DEPTH_M, c) for p0, p1 in parts), np.zeros(6))
            W[k - 1] = feed_frame_to_program(w, d, int(sense[k]))
        cuts.append((a[:2].copy(), b[:2].copy()))
    return W


def _pinocchio_arm(tcp_xyz: np.ndarray):
    """The UR10 of its robot file (standard DH, read here) as a pinocchio model with the TCP frame,
    and the joint stiffness of the file, N m/rad."""
    import tomllib

    import pinocchio as pin

    root = Path(__file__).resolve().parents[1]
    data = tomllib.loads((root / "models" / "robots" / "ur10.toml").read_text())
    model = pin.Model()
    parent, prev = 0, pin.SE3.Identity()
    for i, j in enumerate(data["joints"]):
        rz = pin.SE3(pin.utils.rotate("z", j["theta_offset"]), np.zeros(3))
        parent = model.addJoint(parent, pin.JointModelRZ(), prev * rz, f"j{i + 1}")
        model.appendBodyToJoint(parent, pin.Inertia.Random(), pin.SE3.Identity())
        prev = pin.SE3(np.eye(3), np.array([0.0, 0.0, j["d"]])) * pin.SE3(
            pin.utils.rotate("x", math.radians(j["alpha_deg"])), np.array([j["a"], 0.0, 0.0])
        )
    fid = model.addFrame(pin.Frame("tcp", parent, 0, prev * pin.SE3(np.eye(3), tcp_xyz), pin.FrameType.OP_FRAME))
    stiffness = np.array([j["stiffness"] for j in data["joints"]])
    return model, fid, stiffness


def _landing(model, fid, stiffness, q_command: np.ndarray, wrench_base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The TCP where the arm settles under the wrench (base frame, at the TCP): the fixed point of
    q = q_c + K^-1 J(q)^T W, and the TCP at the command itself."""
    import pinocchio as pin

    data = model.createData()
    q = q_command.copy()
    for _ in range(200):
        J = pin.computeFrameJacobian(model, data, q, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        q_new = q_command + (J.T @ wrench_base) / stiffness
        step = np.abs(q_new - q).max()
        q = q_new
        if step < EQUILIBRIUM_STEP_RAD:
            break
    pin.framesForwardKinematics(model, data, q)
    landed = data.oMf[fid].translation.copy()
    pin.framesForwardKinematics(model, data, q_command)
    return landed, data.oMf[fid].translation.copy()


def test_compensated_cut_lands_under_an_independent_arm(tmp_path):
    from planner.plan import plan

    pr = load_problem(_write(tmp_path, PROGRAM_3, yaw_deg=str(YAW_3_DEG)))
    assert not pr.model.effects and not pr.model.gravity_on and pr.payload_mass_kg == 0.0  # springs only
    way = pr.program.waypoints
    pts = way.points_m / MM
    W_prog = independent_program_wrench(pts, way.rapid, np.full(pr.n, 600.0), np.ones(pr.n), way.stop)
    # the product's wrench equals the independent one at every waypoint, transitions included
    scale = np.abs(W_prog).max(axis=0)
    err = np.abs(pr.cut.wrench_program - W_prog) / np.maximum(scale, 1e-12)
    assert err.max() < ALL_WAYPOINTS_REL_TOL, (np.unravel_index(err.argmax(), err.shape), err.max())
    assert np.count_nonzero(np.abs(W_prog[:, 0]) > 0) >= 15
    res = plan(pr)
    assert res.ok, res.reason
    yaw = math.radians(YAW_3_DEG)
    Rz = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    model, fid, stiffness = _pinocchio_arm(TOOL_3_M)
    worst = deflection = 0.0
    for k in range(pr.n):
        wb = np.r_[Rz @ W_prog[k, :3], Rz @ W_prog[k, 3:]]
        target = WORKPIECE_3_M + Rz @ way.points_m[k]
        landed, commanded = _landing(model, fid, stiffness, res.exact.q_command[k], wb)
        worst = max(worst, float(np.linalg.norm(landed - target)))
        deflection = max(deflection, float(np.linalg.norm(landed - commanded)))
    print(f"landing error {worst:.2e} m under deflections up to {deflection:.2e} m")
    assert worst < LANDING_TOL_M, worst
    assert deflection > MIN_DEFLECTION_M, deflection  # the cut does bend the arm


# --------------------------------------------------------------------------------------------------
# 4. Bad inputs
# --------------------------------------------------------------------------------------------------

PROGRAM_SLOT = HEAD + "S10000 M3\nG0 X-10 Y0 Z5\nG0 Z-2\nG1 X20 F600\nG0 Z5\nM5\nM30\n%\n"


def _cl_tilted() -> str:
    rows = ["x_mm,y_mm,z_mm,i,j,k,feed_mm_min,rapid", "-10,0,5,0,0,1,600,1", "-10,0,-2,0,0,1,600,1"]
    for k in range(0, 21):
        a = math.radians(10.0) * k / 20
        rows.append(f"{k},0,-2,{math.sin(a):.9f},0,{math.cos(a):.9f},600,0")
    return "\n".join(rows) + "\n"


#: (id, program, problem fields, text replacements, file name, what the message must name)
BAD = [
    (
        "no_S",
        PROGRAM_SLOT.replace("S10000 M3", "M3"),
        {},
        (),
        "part.ngc",
        [r"part\.ngc:6:", "no spindle speed", "add S"],
    ),
    (
        "stock_untouched",
        PROGRAM_SLOT,
        {"stock_min": "0.200, 0.200, -0.010", "stock_max": "0.260, 0.260, 0.0"},
        (),
        "part.ngc",
        ["never touches the \\[stock\\]", "program frame"],
    ),
    (
        "cutter_too_long",
        PROGRAM_SLOT,
        {"tool_z": "0.03"},
        (),
        "part.ngc",
        ["robot.tool.cutter.length", "0.035", "0.03"],
    ),
    ("ktc_in_n_mm2", PROGRAM_SLOT, {"ktc": "796"}, (), "part.ngc", ["material.Ktc", "796", "N/mm"]),
    (
        "material_without_stock",
        PROGRAM_SLOT,
        {},
        (("[stock]\n", "[nostock]\n"),),
        "part.ngc",
        ["stock", "required with \\[material\\]"],
    ),
    (
        "rapid_through_stock",
        PROGRAM_SLOT.replace("G1 X20 F600", "G0 X20"),
        {},
        (),
        "part.ngc",
        [r"part\.ngc:6:", "rapid", "crash", r"\(1 rapid line"],
    ),
    (
        "cl_5_axis",
        _cl_tilted(),
        {"kind": "toolpath_csv", "orientation": "", "cut": "[cut]\nspindle_rpm = 10000.0"},
        (),
        "part.csv",
        [r"part\.csv:5:", "tilted", "3-axis"],
    ),
    ("flute_longer_than_cutter", PROGRAM_SLOT, {"flute_length": "0.040"}, (), "part.ngc", ["flute_length", "0.04"]),
    (
        "diameter_in_mm",
        PROGRAM_SLOT,
        {"diameter": "8"},
        (),
        "part.ngc",
        ["robot.tool.cutter.diameter", "= 8 ", "millimetres"],
    ),
]


def _bad_file(tmp_path: Path, program: str, fields: dict, replace: tuple, name: str) -> Path:
    f = _write(tmp_path, program, name=name, **fields)
    text = f.read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    if "[nostock]" in text:  # drop the table: [material] alone
        head, _, tail = text.partition("[nostock]\n")
        text = head + tail[tail.index("[timing]") :]
    f.write_text(text)
    return f


@pytest.mark.parametrize("case", BAD, ids=[b[0] for b in BAD])
def test_bad_cut_input_is_one_clear_error(case, tmp_path, capsys):
    from planner.cli import main

    _id, program, fields, replace, name, words = case
    f = _bad_file(tmp_path, program, fields, replace, name)
    with pytest.raises((ProblemFileError, InputError)) as info:
        load_problem(f)
    msg = str(info.value)
    for w in words:
        assert re.search(w, msg), (w, msg)
    out = tmp_path / "out"
    capsys.readouterr()
    code = main(["plan", str(f), "--out", str(out), "--no-report", "--no-figures"])
    _stdout, err = capsys.readouterr()
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert all(re.search(w, lines[0]) for w in words), (words, err)
    assert not out.exists() or not any(out.iterdir()), sorted(out.rglob("*"))


# --------------------------------------------------------------------------------------------------
# 5. Problem.to_dict round trip
# --------------------------------------------------------------------------------------------------


def test_to_dict_round_trip_predicts_the_same_wrench(problem_1):
    d = problem_1.to_dict()
    assert Path(d["path"]["file"]).is_absolute()
    assert set(d["material"]) == {"Ktc", "Krc", "Kac", "Kte", "Kre", "Kae", "source"}
    assert d["material"]["Ktc"] == KTC and d["material"]["Kae"] == KAE
    assert d["stock"]["box_min"] == pytest.approx([0.0, -0.040, -0.010]) and d["stock"]["resolution"] == 1e-4
    cutter = d["robot"]["tool"]["cutter"]
    assert {"shape", "diameter", "flutes", "helix_deg", "flute_length", "length"} <= set(cutter)
    assert cutter["diameter"] == DIAMETER_M and cutter["flutes"] == FLUTES
    assert cutter["helix_deg"] == pytest.approx(30.0, rel=1e-12)
    again = problem_from_dict(d)
    np.testing.assert_allclose(again.cut.wrench_program, problem_1.cut.wrench_program, rtol=0, atol=1e-9)
    assert again.cut.removed_m3 == pytest.approx(problem_1.cut.removed_m3, rel=1e-12)
    np.testing.assert_allclose(again.load.wrench_base, problem_1.load.wrench_base, rtol=0, atol=1e-9)


def test_a_named_material_round_trips_and_equals_its_coefficients(tmp_path):
    """``[material] name`` is written back as the table's key (not the row's display name), and the
    shipped row predicts what its six coefficients given in SI do."""
    f = _write(tmp_path, PROGRAM_SLOT)
    text = f.read_text()
    start, end = text.index("[material]\n"), text.index("[stock]\n")
    f2 = tmp_path / "named.toml"
    f2.write_text(text[:start] + '[material]\nname = "al7075_t6"\n' + text[end:])
    named, si = load_problem(f2), load_problem(f)
    d = named.to_dict()
    assert d["material"] == {"name": "al7075_t6"}
    again = problem_from_dict(d)
    np.testing.assert_allclose(again.cut.wrench_program, named.cut.wrench_program, rtol=0, atol=1e-9)
    scale = np.abs(si.cut.wrench_program).max()
    assert scale > 10.0
    np.testing.assert_allclose(named.cut.wrench_program, si.cut.wrench_program, rtol=0, atol=1e-12 * scale)


def test_a_fitted_coefficients_file_pasted_as_it_is_is_the_material(tmp_path):
    """``compplan cutting fit``'s ``coefficients.toml`` (a ``name`` with the six coefficients) pasted as
    the problem's ``[material]`` (docs/cutting-fit.md, "Outputs"): its coefficients, its name as the label."""
    fitted = (
        "# status: ok\n[material]\n"
        'name = "my-al"\nsource = "fitted from al.csv on 2026-12-08"\n'
        "Ktc = 796000000.0  # +- 1e6 N/m^2 (2 sigma)\nKrc = 168800000.0\nKac = 222000000.0\n"
        "Kte = 27700.0\nKre = 30800.0\nKae = 1400.0\n"
    )
    text = PROBLEM.format(**{**DEFAULTS, "file": "part.ngc"})
    text = text[: text.index("[material]")] + fitted[fitted.index("[material]") :] + text[text.index("[stock]") :]
    (tmp_path / "part.ngc").write_text(PROGRAM_SLOT)
    (tmp_path / "p.toml").write_text(text)
    pr = load_problem(tmp_path / "p.toml")
    m = pr.cut.material
    assert (m.name, m.Ktc, m.Kae) == ("my-al", 796e6, 1400.0)
    assert pr.to_dict()["material"]["name"] == "my-al"
    same = load_problem(_write(tmp_path, PROGRAM_SLOT))  # the same six without a name
    np.testing.assert_array_equal(pr.cut.wrench_program, same.cut.wrench_program)
