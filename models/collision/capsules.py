"""Capsules along the links of a DH robot: the arm's collision geometry, apart from data.

A :class:`CapsuleModel` is the *description* (which segments, fixed in which DH frame, with which
radius, on which body); the positions of its segments at configurations are computed from it
(:func:`models.collision.chain.capsule_segments`, ``capsule_points_sx``), as pinocchio keeps
``GeometryModel`` apart from ``GeometryData``.

Bodies: body 0 is the base, body *i* (1..6) the link moved by joint *i*.  Body *i* holds the DH
offsets of its own row: ``d_i`` along joint *i*'s axis, then the common normal ``a_i`` to the next
axis (``standard_dh``: ``O_{i-1} -> O_{i-1} + d_i z_{i-1} -> O_i``; ``modified_dh``:
``O_i - d_i z_i -> O_i -> O_i + a_i x_i``, ``a_i`` being row *i+1*'s ``a``).  A zero offset gives no
segment; a body with no segment is a sphere at its point on joint *i*'s axis (a spherical wrist's
centre).  Body 0 holds what lies before joint 1 (``frame02base``'s offset, ``modified_dh`` row 1's
``a``); body 6 also the segment from DH frame 6 to the flange.  The tool is not part of this model
(:func:`with_tool` appends it).

On top of these come the robot's own segments (:class:`models.robot.RobotCollision`: a robot
file's ``[collision]`` table, a URDF's ``<collision>`` elements): the UR arms' upper arm and forearm
beside the DH line (``models/robots/ur*.toml``), for example; one that lies within a DH capsule of its
body is dropped.  Last the *lines*, the arm's kinematic skeleton where no material need be: the
straight line between consecutive DH frame origins where a row has both offsets (``standard_dh`` body
*i* ``O_{i-1} -> O_i``; ``modified_dh`` body *i-1* ``O_{i-1} -> O_i``), the lines between a URDF's
joint origins, declared lines.  A line is a thin capsule (:data:`LINE_RADIUS_M`) cut to its part
outside its body's other capsules, checked against the cell's objects and left out of
self-collision (``CapsuleModel.line``).  So every line between consecutive joint origins lies inside
the capsules of its body.

Self-collision is checked between bodies that are not adjacent: ``|i - j| > 1``, bodies on either
side of a zero-length body count as adjacent (they meet at its joint centre), and the arm's allowed
pairs (:data:`BUILTIN_ALLOWED_PAIRS`: pairs the structure keeps apart) and the lines are left out.

The built-in arms' radii, allowed pairs and offsets are their robot files' ``[collision]`` tables
(one source); :data:`BUILTIN_COLLISION` and the ``BUILTIN_*`` tables below are read from them.

Units: m.  Frames: the base frame (``docs/conventions.md``).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, replace
from importlib import resources

import numpy as np

from ..robot import BUILTIN_ROBOTS, Robot, RobotCollision, parse_collision_table
from .chain import chain_frames

__all__ = [
    "TOOL_BODY",
    "TOOL_MIN_LENGTH_M",
    "TOOL_SELF_MAX_BODY",
    "with_tool",
    "BUILTIN_ALLOWED_PAIRS",
    "BUILTIN_OVERLAPPING_ALLOWED",
    "BUILTIN_RADII_M",
    "BUILTIN_RADII_SOURCE",
    "CapsuleModel",
    "body_name",
    "capsule_model",
    "default_radii",
    "self_collision_body_pairs",
    "self_collision_pairs",
]

#: Offsets shorter than this (m) give no capsule segment (a DH ``d`` or ``a`` of zero).
MIN_SEGMENT_LENGTH_M = 1e-9

#: A declared segment whose ends lie within this distance (m) of a DH capsule's segment of the same
#: body (and whose radius is not larger) adds nothing and is dropped.
COVERED_TOL_M = 1e-9
#: Radius (m) of a line: a segment of the arm's kinematic skeleton that stands for no material (a
#: diagonal of the DH chain, a line between a URDF's joint origins), so that it is contained in the
#: capsules without making the arm fatter; it is cut to its part outside the body's capsules.
LINE_RADIUS_M = 0.010
#: Grid (points along a line) on which a line's covered part is searched, then refined by bisection.
LINE_GRID = 201
#: Bisection steps refining the ends of a line's covered part (2^-50 of its length).
LINE_BISECTIONS = 50


def _read_builtin_collision() -> dict[str, RobotCollision]:
    """The ``[collision]`` tables of the built-in robot files (``models/robots/*.toml``)."""
    folder = resources.files("models").joinpath("robots")
    out = {}
    for name in BUILTIN_ROBOTS:
        data = tomllib.loads(folder.joinpath(f"{name}.toml").read_text(encoding="utf-8"))
        if "collision" in data:
            out[name] = parse_collision_table(f"built-in robot '{name}'", data["collision"])
    return out


#: The built-in arms' collision geometry, read from their robot files' ``[collision]`` tables (the
#: one source of these facts): radii, allowed pairs, offsets.  A robot without its own geometry but
#: with a built-in name gets their radii and allowed pairs (:func:`robot_collision`).
BUILTIN_COLLISION: dict[str, RobotCollision] = _read_builtin_collision()

#: Capsule radius per body (m), body 0 (base) .. 6 (flange link), of the built-in arms (from
#: :data:`BUILTIN_COLLISION`).  Approximate: half the outer diameter of each link's housing, read off
#: the makers' dimension drawings and rounded *up* to 5 mm (a capsule must contain the link it stands
#: for), see :data:`BUILTIN_RADII_SOURCE`.  Another arm without its own ``radii_m`` gets
#: :func:`default_radii`'s generic values.
BUILTIN_RADII_M: dict[str, tuple[float, ...]] = {
    n: tuple(float(r) for r in c.radii) for n, c in BUILTIN_COLLISION.items() if c.radii is not None
}

#: Where :data:`BUILTIN_RADII_M` come from (the robot files' ``[collision] source``).
BUILTIN_RADII_SOURCE: dict[str, str] = {n: c.source for n, c in BUILTIN_COLLISION.items()}

#: Body pairs (i < j) of a built-in arm left out of self-collision (the robot files'
#: ``[collision] allowed_pairs``): pairs the structure keeps apart at every configuration.  UR-type
#: wrists: the forearm (3) and wrist 2 (5) lie in parallel planes about ``d_4`` apart, wrist 1 (4) and
#: wrist 3 (6) in planes ``d_5`` apart (UR's MoveIt configuration also disables wrist_1 - wrist_3 as
#: "never in collision").
BUILTIN_ALLOWED_PAIRS: dict[str, tuple[tuple[int, int], ...]] = {
    n: (c.allowed_pairs or ()) for n, c in BUILTIN_COLLISION.items()
}

#: Allowed pairs whose capsules *do* touch (the other allowed pairs never do:
#: ``tests/test_collision_geometry.py`` samples them).  The seed paper's arm puts wrist 1's offset at
#: ``d_4 = -0.026`` m (its DH reading, not a physical arm): forearm and wrist 2 overlap everywhere.  The
#: UR5's and UR10's forearm tube lies ``s - e`` (16 and 49 mm) off the DH line towards wrist 2's plane
#: (``d_4``), so its capsule, as thick as the elbow housing, meets wrist 2's where the forearm ends
#: (12 and 10 mm; the thinner tube stays clear).  The KR 6's link 3 is only the A3 housing
#: (``a_3`` = 35 mm): links 2 and 4 overlap at joint 3 as neighbours do.
BUILTIN_OVERLAPPING_ALLOWED: dict[str, tuple[tuple[int, int], ...]] = {
    "ar5": ((3, 5),),
    "ur5": ((3, 5),),
    "ur10": ((3, 5),),
    "kr6_r900": ((2, 4),),
}

#: Generic radius of a body without a table entry: this fraction of its length (m/m) ...
GENERIC_RADIUS_PER_LENGTH = 0.15
#: ... but at least this fraction of the arm's reach (sum of |a| and |d|) ...
GENERIC_RADIUS_MIN_PER_REACH = 0.05
#: ... and at most this fraction of it.
GENERIC_RADIUS_MAX_PER_REACH = 0.10

N_BODIES = 7


@dataclass(frozen=True)
class CapsuleModel:
    """Capsules of an arm, each a segment fixed in one DH frame with a radius, on a body.

    Attributes
    ----------
    frame_a, frame_b : ndarray of int, shape (M,)
        DH frame (0..6) each end point is fixed in; ``-1`` is the base frame.
    local_a, local_b : ndarray, shape (M, 3)
        End points in those frames, m.
    radius : ndarray, shape (M,)
        Capsule radii, m.
    body : ndarray of int, shape (M,)
        Body of each capsule: 0 base, i link moved by joint i.
    allowed_pairs : tuple of (int, int)
        Body pairs (i < j) left out of self-collision.
    radii_source : str
        Where the radii come from.
    line : ndarray of bool, shape (M,), or None
        Which capsules are lines (:data:`LINE_RADIUS_M`: the arm's kinematic skeleton, no
        material): checked against the cell's objects, left out of self-collision
        (:func:`self_collision_pairs`).  None: none is; capsules beyond its length are not.
    """

    frame_a: np.ndarray
    frame_b: np.ndarray
    local_a: np.ndarray
    local_b: np.ndarray
    radius: np.ndarray
    body: np.ndarray
    allowed_pairs: tuple[tuple[int, int], ...] = ()
    radii_source: str = ""
    line: np.ndarray | None = None

    @property
    def is_line(self) -> np.ndarray:
        """Whether each capsule is a line, shape (M,) of bool (see ``line``)."""
        out = np.zeros(self.n_capsules, dtype=bool)
        if self.line is not None:
            n = min(len(self.line), self.n_capsules)
            out[:n] = np.asarray(self.line, dtype=bool)[:n]
        return out

    @property
    def n_capsules(self) -> int:
        """Number of capsules M."""
        return int(self.body.shape[0])

    @property
    def names(self) -> tuple[str, ...]:
        """A name per capsule: its body's name (``link 3``), with ``#k`` when a body has several."""
        out = []
        for k, b in enumerate(self.body):
            same = np.flatnonzero(self.body == b)
            name = body_name(int(b))
            out.append(name if same.size == 1 else f"{name}#{int(np.searchsorted(same, k)) + 1}")
        return tuple(out)


def body_name(body: int) -> str:
    """The name of a body in messages: ``base`` for 0, ``link i`` for i = 1..6."""
    return "base" if body == 0 else f"link {body}"


def _body_points(robot: Robot) -> list[list[tuple[int, np.ndarray]]]:
    """Per body 0..6, the chain of points (frame index, local point) its segments join."""
    z = np.zeros(3)
    a, d = robot.a, robot.d
    pts: list[list[tuple[int, np.ndarray]]] = [[] for _ in range(N_BODIES)]
    pts[0] = [(-1, z), (0, z)]
    if robot.convention == "standard_dh":
        for i in range(1, 7):  # O_{i-1} -> O_{i-1} + d_i z_{i-1} -> O_i
            pts[i] = [(i - 1, z), (i - 1, np.array([0.0, 0.0, d[i - 1]])), (i, z)]
    else:
        pts[0].append((0, np.array([a[0], 0.0, 0.0])))
        for i in range(1, 7):  # O_i - d_i z_i -> O_i -> O_i + a_i x_i
            nxt = [(i, np.array([a[i], 0.0, 0.0]))] if i < 6 else []
            pts[i] = [(i, np.array([0.0, 0.0, -d[i - 1]])), (i, z), *nxt]
    pts[6].append((6, np.asarray(robot.flange2frame6, dtype=float)[:3, 3]))
    return pts


def _point_at_zero(robot: Robot, frame: int, local: np.ndarray, F: np.ndarray | None = None) -> np.ndarray:
    """A point (frame, local coordinates) in the base frame at q = 0 (``F``: the frames there)."""
    F = chain_frames(robot, np.zeros(6))[0] if F is None else F
    T = np.eye(4) if frame < 0 else F[frame]
    return T[:3, :3] @ local + T[:3, 3]


def _dh_diagonals(robot: Robot) -> list[tuple[int, tuple[int, np.ndarray], tuple[int, np.ndarray]]]:
    """The straight lines between consecutive DH frame origins where a row has both offsets,
    each on the body it is fixed to (module docstring)."""
    z = np.zeros(3)
    a, d = robot.a, robot.d
    out = []
    for i in range(1, 7):
        if abs(d[i - 1]) <= MIN_SEGMENT_LENGTH_M or abs(a[i - 1]) <= MIN_SEGMENT_LENGTH_M:  # row i's d and a
            continue
        if robot.convention == "standard_dh":  # row i: O_{i-1} -> O_i on body i
            out.append((i, (i - 1, z), (i, z)))
        elif i > 1:  # row i holds a_{i-1}: O_{i-1} -> O_i on body i-1 (O_i lies on joint i's axis)
            out.append((i - 1, (i - 1, z), (i, z)))
        else:  # O_0 -> O_1 on the base, both ends in DH frame 0 (O_1 lies on joint 1's axis)
            F = chain_frames(robot, np.zeros(6))[0]
            o1 = np.linalg.inv(F[0]) @ F[1][:, 3]
            out.append((0, (0, z), (0, o1[:3])))
    return out


def _body_segments(robot: Robot) -> list[list[tuple[tuple[int, np.ndarray], tuple[int, np.ndarray]]]]:
    """Per body, its non-degenerate DH offset segments; a link body without one is a sphere on its axis."""
    out = []
    for b, chain in enumerate(_body_points(robot)):
        segs = []
        for pa, pb in zip(chain[:-1], chain[1:]):
            if np.linalg.norm(_point_at_zero(robot, *pa) - _point_at_zero(robot, *pb)) > MIN_SEGMENT_LENGTH_M:
                segs.append((pa, pb))
        if not segs and b > 0:
            segs.append((chain[0], chain[0]))
        out.append(segs)
    return out


def robot_collision(robot: Robot) -> RobotCollision | None:
    """The robot's own collision geometry (its file's ``[collision]`` table, its URDF's collision
    elements and link frames); radii and allowed pairs it does not give are the built-in arm's of
    that name (:data:`BUILTIN_COLLISION`).  A robot without its own geometry but with a built-in name
    (a robot dictionary written before robot files had the table) gets the built-in radii and allowed
    pairs, not its segments (they are given in the built-in file's DH frames).  None: neither."""
    own, builtin = robot.collision, BUILTIN_COLLISION.get(robot.name)
    if builtin is None:
        return own
    if own is None:
        return RobotCollision(radii=builtin.radii, allowed_pairs=builtin.allowed_pairs, source=builtin.source)
    if own.radii is None and builtin.radii is not None:
        own = replace(own, radii=builtin.radii, source="; ".join(t for t in (own.source, builtin.source) if t))
    if own.allowed_pairs is None:
        own = replace(own, allowed_pairs=builtin.allowed_pairs)
    return own


def _generic_radii(robot: Robot) -> tuple[np.ndarray, str]:
    reach = float(np.sum(np.abs(robot.a)) + np.sum(np.abs(robot.d)))
    lengths = np.zeros(N_BODIES)
    for b, segs in enumerate(_body_segments(robot)):
        lengths[b] = sum(np.linalg.norm(_point_at_zero(robot, *pa) - _point_at_zero(robot, *pb)) for pa, pb in segs)
    r = np.clip(
        GENERIC_RADIUS_PER_LENGTH * lengths, GENERIC_RADIUS_MIN_PER_REACH * reach, GENERIC_RADIUS_MAX_PER_REACH * reach
    )
    r[1:] = np.minimum.accumulate(np.maximum(r[1:], r[-1]))  # links no thicker than the one before
    r[0] = max(r[0], r[1])
    return r, (
        f"generic: {GENERIC_RADIUS_PER_LENGTH:g} x link length, between {GENERIC_RADIUS_MIN_PER_REACH:g} "
        f"and {GENERIC_RADIUS_MAX_PER_REACH:g} x reach ({reach:.3f} m)"
    )


def default_radii(robot: Robot) -> tuple[np.ndarray, str]:
    """Capsule radius per body 0..6 (m) and where it comes from.

    The robot's own ``radii_m`` (:func:`robot_collision`: its ``[collision]`` table, or the
    built-in arm's of that name); else a generic radius per body,
    :data:`GENERIC_RADIUS_PER_LENGTH` times the body's length (its DH offsets), kept between
    :data:`GENERIC_RADIUS_MIN_PER_REACH` and :data:`GENERIC_RADIUS_MAX_PER_REACH` times the reach.

    Returns
    -------
    radii : ndarray, shape (7,)
    source : str
    """
    col = robot_collision(robot)
    if col is not None and col.radii is not None:
        return np.array(col.radii, dtype=float), col.source or "robot file"
    r, source = _generic_radii(robot)
    if col is not None and col.source:
        source = f"{col.source}; body radii {source}"
    return r, source


def _point_segment_distance(P: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances (m) of points ``P`` (N, 3) from the segment a-b."""
    ab = b - a
    L2 = float(ab @ ab)
    t = np.zeros(len(P)) if L2 == 0.0 else np.clip((P - a) @ ab / L2, 0.0, 1.0)
    return np.linalg.norm(P - (a + t[:, None] * ab), axis=1)


def _covered(p0: np.ndarray, p1: np.ndarray, radius: float, segs: list[tuple[np.ndarray, np.ndarray, float]]) -> bool:
    """Whether the capsule (p0, p1, radius) lies within one of ``segs`` (end points, radius; m)."""
    return any(
        radius <= r and float(np.max(_point_segment_distance(np.array([p0, p1]), a, b))) <= COVERED_TOL_M
        for a, b, r in segs
    )


def _covered_span(p0: np.ndarray, p1: np.ndarray, level: float, a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """The parameters ``[lo, hi]`` of the points ``p0 + t (p1 - p0)`` within ``level`` (m) of the
    segment a-b (an interval: the distance is convex in t); ``lo > hi`` when there is none.  Found on
    a grid of :data:`LINE_GRID` points, refined by bisection (a dip between grid points is missed:
    the line then stays longer, never shorter)."""
    t = np.linspace(0.0, 1.0, LINE_GRID)

    def f(tt: np.ndarray) -> np.ndarray:
        return _point_segment_distance(p0 + np.outer(tt, p1 - p0), a, b) - level

    v = f(t)
    k = int(np.argmin(v))
    if v[k] > 0.0:
        return 1.0, 0.0

    def edge(inside: float, outside: float) -> float:
        for _ in range(LINE_BISECTIONS):
            mid = 0.5 * (inside + outside)
            inside, outside = (mid, outside) if f(np.array([mid]))[0] <= 0.0 else (inside, mid)
        return inside

    lo = 0.0 if v[0] <= 0.0 else edge(t[k], 0.0)
    hi = 1.0 if v[-1] <= 0.0 else edge(t[k], 1.0)
    return lo, hi


def _uncovered_hull(spans: list[tuple[float, float]]) -> tuple[float, float] | None:
    """The smallest ``[t0, t1]`` of [0, 1] holding every parameter no span covers; None: all covered."""
    spans = sorted((lo, hi) for lo, hi in spans if lo <= hi)
    t, gaps = 0.0, []
    for lo, hi in spans:
        if lo > t:
            gaps.append((t, lo))
        t = max(t, hi)
    if t < 1.0:
        gaps.append((t, 1.0))
    if not gaps:
        return None
    return gaps[0][0], gaps[-1][1]


def _trim_line(
    robot: Robot, body: int, pa: tuple, pb: tuple, rho: float, covers: list[tuple[np.ndarray, np.ndarray, float]]
) -> tuple[tuple, tuple] | None:
    """A line of ``body`` (ends ``pa``, ``pb``: (frame, local)), thin radius ``rho``, cut to the part
    not inside ``covers`` (the body's capsules: ends at q = 0, radius; a part is inside when its
    thin capsule is); None: all inside."""
    F0 = chain_frames(robot, np.zeros(6))[0]
    p0, p1 = _point_at_zero(robot, *pa, F0), _point_at_zero(robot, *pb, F0)
    spans = [_covered_span(p0, p1, r - rho + COVERED_TOL_M, a, b) for a, b, r in covers if r >= rho]
    hull = _uncovered_hull(spans)
    if hull is None:
        return None
    t0, t1 = hull
    if t0 <= 0.0 and t1 >= 1.0:
        return pa, pb
    frame = body if body > 0 else -1  # the body's own frame
    T = np.eye(4) if frame < 0 else F0[frame]
    x0, x1 = (T[:3, :3].T @ (p0 + t * (p1 - p0) - T[:3, 3]) for t in (t0, t1))
    return (frame, x0), (frame, x1)


def capsule_model(
    robot: Robot, radii: np.ndarray | None = None, allowed_pairs: tuple[tuple[int, int], ...] | None = None
) -> CapsuleModel:
    """The capsules of a robot (module docstring): its DH offsets, its own segments, its lines.

    Material capsules come first: the DH offsets of every body not in ``replace_dh`` (the body's
    radius), then the robot's declared segments (:func:`robot_collision`; their own radius or the
    body's; one within a capsule of its body is dropped).  Then the lines, thin capsules of
    :data:`LINE_RADIUS_M` (or their own radius): the DH chain's diagonals and the declared lines
    (URDF joint origins), each cut to its part outside its body's other capsules.

    Parameters
    ----------
    robot : Robot
    radii : ndarray, shape (7,), optional
        Radius per body 0..6, m; default :func:`default_radii` (the robot's ``[collision]``
        ``radii_m``, the built-in arm's, else generic).  A declared segment with its own radius
        keeps it.
    allowed_pairs : tuple of (int, int), optional
        Body pairs left out of self-collision; default the robot's ``allowed_pairs``
        (:func:`robot_collision`), none for another arm.
    """
    if radii is None:
        r, source = default_radii(robot)
    else:
        r, source = np.asarray(radii, dtype=float).reshape(N_BODIES), "given"
    col = robot_collision(robot)
    if allowed_pairs is None:
        allowed_pairs = col.allowed_pairs if col is not None and col.allowed_pairs is not None else ()
    replaced = set(col.replace_dh) if col is not None else set()
    declared = list(col.segments) if col is not None else []
    F0 = chain_frames(robot, np.zeros(6))[0]

    def at0(end: tuple) -> np.ndarray:
        return _point_at_zero(robot, *end, F0)

    rows = [
        (b, pa, pb, float(r[b])) for b, segs in enumerate(_body_segments(robot)) if b not in replaced for pa, pb in segs
    ]
    n_dh = len(rows)
    for seg in (s for s in declared if not s.line):
        rad = float(r[seg.body]) if seg.radius is None else float(seg.radius)
        pa, pb = (seg.frame_a, np.asarray(seg.xyz_a, float)), (seg.frame_b, np.asarray(seg.xyz_b, float))
        same = [(at0(ra), at0(rb), rr) for b, ra, rb, rr in rows if b == seg.body]
        if not _covered(at0(pa), at0(pb), rad, same):
            rows.append((seg.body, pa, pb, rad))
    lines = [(b, pa, pb, LINE_RADIUS_M) for b, pa, pb in _dh_diagonals(robot) if b not in replaced]
    lines += [
        (
            s.body,
            (s.frame_a, np.asarray(s.xyz_a, float)),
            (s.frame_b, np.asarray(s.xyz_b, float)),
            LINE_RADIUS_M if s.radius is None else float(s.radius),
        )
        for s in declared
        if s.line
    ]
    n_material = len(rows)
    for b, pa, pb, rho in lines:  # each cut by the capsules of its body so far
        covers = [(at0(ra), at0(rb), rr) for bb, ra, rb, rr in rows if bb == b]
        cut = _trim_line(robot, b, pa, pb, rho, covers)
        if cut is not None:
            rows.append((b, *cut, rho))
    is_line = [k >= n_material for k in range(len(rows))]
    # a body's capsules together: its declared segments, its lines, its DH offsets last (the last
    # capsule of link 6 ends at the flange, where the tool begins)
    group = [2 if k < n_dh else (1 if is_line[k] else 0) for k in range(len(rows))]
    order = sorted(range(len(rows)), key=lambda k: (rows[k][0], group[k]))
    rows, is_line = [rows[k] for k in order], [is_line[k] for k in order]
    return CapsuleModel(
        frame_a=np.array([pa[0] for _, pa, _, _ in rows], dtype=int),
        frame_b=np.array([pb[0] for _, _, pb, _ in rows], dtype=int),
        local_a=np.array([pa[1] for _, pa, _, _ in rows], dtype=float).reshape(-1, 3),
        local_b=np.array([pb[1] for _, _, pb, _ in rows], dtype=float).reshape(-1, 3),
        radius=np.array([rr for _, _, _, rr in rows], dtype=float),
        body=np.array([b for b, _, _, _ in rows], dtype=int),
        allowed_pairs=tuple(tuple(sorted(p)) for p in allowed_pairs),  # type: ignore[misc]
        radii_source=source,
        line=np.array(is_line, dtype=bool),
    )


def _bridged(model: CapsuleModel) -> set[tuple[int, int]]:
    """Body pairs (i-1, i+1) joined through a zero-length body i (they meet at its centre)."""
    out = set()
    for b in range(1, N_BODIES - 1):
        sel = (model.body == b) & ~model.is_line
        if sel.any() and np.all(
            (model.frame_a[sel] == model.frame_b[sel]) & np.all(model.local_a[sel] == model.local_b[sel], axis=1)
        ):
            out.add((b - 1, b + 1))
    return out


def self_collision_body_pairs(model: CapsuleModel) -> list[tuple[int, int]]:
    """Body pairs (i < j) checked for self-collision: present, not adjacent, not bridged, not allowed."""
    present = sorted(set(int(b) for b in model.body))
    skip = _bridged(model) | set(model.allowed_pairs)
    return [(i, j) for i in present for j in present if j > i + 1 and (i, j) not in skip]


def self_collision_pairs(model: CapsuleModel) -> np.ndarray:
    """Capsule index pairs checked for self-collision, shape (P, 2) of int (from the body pairs;
    lines, ``CapsuleModel.line``, stand for no material and are left out)."""
    pairs = set(self_collision_body_pairs(model))
    line = model.is_line
    idx = [
        (k, m)
        for k in range(model.n_capsules)
        for m in range(k + 1, model.n_capsules)
        if (int(model.body[k]), int(model.body[m])) in pairs and not (line[k] or line[m])
    ]
    return np.array(idx, dtype=int).reshape(-1, 2)


#: The tool capsule's body number (after links 0..6).
TOOL_BODY = 7
#: A TCP closer than this to the flange (m) has no tool capsule: link 6 then ends at the TCP.
TOOL_MIN_LENGTH_M = 1e-6
#: The tool is checked for self-collision against bodies up to this one (links 5 and 6 meet it at
#: the wrist).
TOOL_SELF_MAX_BODY = 4


def with_tool(model: CapsuleModel, robot: Robot) -> tuple[CapsuleModel, bool]:
    """The capsule model with the tool capsule appended (flange -> TCP in DH frame 6, link 6's
    radius, body :data:`TOOL_BODY`; until problem files describe the tool body), and whether
    there is one (a TCP within :data:`TOOL_MIN_LENGTH_M` of the flange has none)."""
    f6 = np.asarray(robot.flange2frame6, dtype=float)
    flange = f6[:3, 3]
    tcp = (f6 @ np.asarray(robot.tcp2flange, dtype=float))[:3, 3]
    if np.linalg.norm(tcp - flange) < TOOL_MIN_LENGTH_M:
        return model, False
    r6 = float(model.radius[model.body == 6].max())
    tool = replace(
        model,
        frame_a=np.r_[model.frame_a, 6],
        frame_b=np.r_[model.frame_b, 6],
        local_a=np.vstack([model.local_a, flange]),
        local_b=np.vstack([model.local_b, tcp]),
        radius=np.r_[model.radius, r6],
        body=np.r_[model.body, TOOL_BODY],
        line=None if model.line is None else np.r_[model.is_line, False],
    )
    return tool, True
