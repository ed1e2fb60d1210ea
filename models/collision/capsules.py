"""Capsules along the links of a DH robot: the arm's collision geometry, apart from data.

A :class:`CapsuleModel` is the *description* (which segments, fixed in which DH frame, with which
radius, on which body); the positions of its segments at configurations are computed from it
(:func:`capsule_segments`), as pinocchio keeps ``GeometryModel`` apart from ``GeometryData``.

Bodies: body 0 is the base, body *i* (1..6) the link moved by joint *i*.  Body *i* holds the DH
offsets of its own row: ``d_i`` along joint *i*'s axis, then the common normal ``a_i`` to the next
axis (``standard_dh``: ``O_{i-1} -> O_{i-1} + d_i z_{i-1} -> O_i``; ``modified_dh``:
``O_i - d_i z_i -> O_i -> O_i + a_i x_i``, ``a_i`` being row *i+1*'s ``a``).  A zero offset gives no
segment; a body with no segment is a sphere at its point on joint *i*'s axis (a spherical wrist's
centre).  Body 0 holds what lies before joint 1 (``frame02base``'s offset, ``modified_dh`` row 1's
``a``); body 6 also the segment from DH frame 6 to the flange.  The tool is not part of this model.

Self-collision is checked between bodies that are not adjacent: ``|i - j| > 1``, bodies on either
side of a zero-length body count as adjacent (they meet at its joint centre), and the arm's allowed
pairs (:data:`BUILTIN_ALLOWED_PAIRS`: pairs the structure keeps apart) are left out.

Units: m.  Frames: the base frame (``docs/conventions.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..robot import Robot

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
    "capsule_segments",
    "chain_frames",
    "default_radii",
    "self_collision_body_pairs",
    "self_collision_pairs",
]

#: Offsets shorter than this (m) give no capsule segment (a DH ``d`` or ``a`` of zero).
MIN_SEGMENT_LENGTH_M = 1e-9

#: Capsule radius per body (m), body 0 (base) .. 6 (flange link), of the built-in arms.
#: Approximate: half the outer diameter of each link's housing, read off the makers' dimension
#: drawings and rounded *up* to 5 mm (a capsule must contain the link it stands for), see
#: :data:`BUILTIN_RADII_SOURCE`.  A robot file without its own radii (planned ``[collision]``
#: table) of another arm gets :func:`default_radii`'s generic values.
BUILTIN_RADII_M: dict[str, tuple[float, ...]] = {
    # UR5 (CB3): base foot diameter 149 mm, size-3 joint housings (shoulder, elbow) about 120 mm,
    # size-1 wrist housings about 90 mm, wrist-3 / tool flange about 75 mm.
    "ur5": (0.075, 0.075, 0.065, 0.060, 0.045, 0.045, 0.040),
    # The seed paper's arm: UR5 proportions (docs/paper-reproduction.md), UR5's radii.
    "ar5": (0.075, 0.075, 0.065, 0.060, 0.045, 0.045, 0.040),
    # UR10 (CB3): base foot diameter 190 mm, size-4 shoulder/elbow housings about 150 mm,
    # size-2 wrist housings about 110 mm.
    "ur10": (0.095, 0.095, 0.080, 0.070, 0.055, 0.055, 0.045),
    # UR5e: base foot diameter 149 mm, housings as the UR5's (slightly larger wrist flange).
    "ur5e": (0.075, 0.075, 0.065, 0.060, 0.045, 0.045, 0.045),
    # KUKA KR 6 R900 sixx (KR AGILUS): rotating column about 200 mm wide, link arm about 150 mm,
    # arm (A3-A4 housing) about 130 mm, in-line wrist about 100 mm, flange 63 mm (ISO 9409-1-A31.5).
    "kr6_r900": (0.100, 0.100, 0.075, 0.065, 0.055, 0.050, 0.040),
}

#: Where :data:`BUILTIN_RADII_M` come from (one line per arm; what docs/cell.md says).
BUILTIN_RADII_SOURCE: dict[str, str] = {
    "ur5": "Universal Robots UR5 (CB3) dimension drawing: outer diameters of the joint housings, rounded up",
    "ar5": "the seed paper's arm has UR5 proportions: the UR5 radii",
    "ur10": "Universal Robots UR10 (CB3) dimension drawing: outer diameters of the joint housings, rounded up",
    "ur5e": "Universal Robots UR5e dimension drawing: outer diameters of the joint housings, rounded up",
    "kr6_r900": "KUKA KR AGILUS sixx (KR 6 R900) specification drawing: widths of column, link arm, arm, wrist",
}

#: Body pairs (i < j) of a built-in arm left out of self-collision: pairs the structure keeps apart
#: at every configuration (a joint-axis offset between them larger than their radii), so a check
#: would only add a nearly constant distance.  UR-type wrists: the forearm (3) and wrist 2 (5) lie in
#: parallel planes ``d_4`` apart, wrist 1 (4) and wrist 3 (6) in planes ``d_5`` apart (UR's MoveIt
#: configuration also disables wrist_1 - wrist_3 as "never in collision").
BUILTIN_ALLOWED_PAIRS: dict[str, tuple[tuple[int, int], ...]] = {
    "ur5": ((3, 5), (4, 6)),
    "ar5": ((3, 5), (4, 6)),
    "ur10": ((3, 5), (4, 6)),
    "ur5e": ((3, 5), (4, 6)),
    "kr6_r900": (),
}

#: Allowed pairs whose capsules *do* overlap at every configuration: the seed paper's arm puts
#: wrist 1's offset at ``d_4 = -0.026`` m (its DH reading, not a physical arm), 26 mm between the
#: forearm's line and wrist 2's, less than their radii.  Every other allowed pair never touches
#: (``tests/test_collision_geometry.py`` samples it).
BUILTIN_OVERLAPPING_ALLOWED: dict[str, tuple[tuple[int, int], ...]] = {"ar5": ((3, 5),)}

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
    """

    frame_a: np.ndarray
    frame_b: np.ndarray
    local_a: np.ndarray
    local_b: np.ndarray
    radius: np.ndarray
    body: np.ndarray
    allowed_pairs: tuple[tuple[int, int], ...] = ()
    radii_source: str = ""

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


def chain_frames(robot: Robot, q: np.ndarray) -> np.ndarray:
    """DH frames 0..6 of the robot's nominal chain at N configurations, base frame.

    Parameters
    ----------
    robot : Robot
    q : ndarray, shape (N, 6) or (6,)
        Joint angles, rad.

    Returns
    -------
    ndarray, shape (N, 7, 4, 4)
        ``frame_i2base`` for i = 0..6 (frame 0 is ``frame02base``).
    """
    qa = np.atleast_2d(np.asarray(q, dtype=float))
    n = qa.shape[0]
    th = qa + robot.theta_offset
    ct, st = np.cos(th), np.sin(th)
    ca, sa = np.cos(robot.alpha), np.sin(robot.alpha)
    a, d = robot.a, robot.d
    A = np.zeros((n, 6, 4, 4))
    A[..., 3, 3] = 1.0
    if robot.convention == "standard_dh":
        A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca, st * sa, a * ct
        A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca, -ct * sa, a * st
        A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, d
    else:
        A[..., 0, 0], A[..., 0, 1], A[..., 0, 3] = ct, -st, a
        A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st * ca, ct * ca, -sa, -sa * d
        A[..., 2, 0], A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = st * sa, ct * sa, ca, ca * d
    F = np.empty((n, 7, 4, 4))
    F[:, 0] = robot.frame02base
    for i in range(6):
        F[:, i + 1] = F[:, i] @ A[:, i]
    return F


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


def _point_at_zero(robot: Robot, frame: int, local: np.ndarray) -> np.ndarray:
    F = chain_frames(robot, np.zeros(6))[0]
    T = np.eye(4) if frame < 0 else F[frame]
    return T[:3, :3] @ local + T[:3, 3]


def _body_segments(robot: Robot) -> list[list[tuple[tuple[int, np.ndarray], tuple[int, np.ndarray]]]]:
    """Per body, its non-degenerate segments; a link body without one is a sphere on its axis."""
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


def default_radii(robot: Robot) -> tuple[np.ndarray, str]:
    """Capsule radius per body 0..6 (m) and where it comes from.

    A built-in arm (by name) gets :data:`BUILTIN_RADII_M`; any other arm a generic radius per body,
    :data:`GENERIC_RADIUS_PER_LENGTH` times the body's length, kept between
    :data:`GENERIC_RADIUS_MIN_PER_REACH` and :data:`GENERIC_RADIUS_MAX_PER_REACH` times the reach.

    Returns
    -------
    radii : ndarray, shape (7,)
    source : str
    """
    if robot.name in BUILTIN_RADII_M:
        return np.array(BUILTIN_RADII_M[robot.name]), BUILTIN_RADII_SOURCE[robot.name]
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


def capsule_model(
    robot: Robot, radii: np.ndarray | None = None, allowed_pairs: tuple[tuple[int, int], ...] | None = None
) -> CapsuleModel:
    """The capsules along a DH robot's links (module docstring).

    Parameters
    ----------
    robot : Robot
    radii : ndarray, shape (7,), optional
        Radius per body 0..6, m; default :func:`default_radii`.
    allowed_pairs : tuple of (int, int), optional
        Body pairs left out of self-collision; default :data:`BUILTIN_ALLOWED_PAIRS` of a built-in
        arm, none for another.
    """
    if radii is None:
        r, source = default_radii(robot)
    else:
        r, source = np.asarray(radii, dtype=float).reshape(N_BODIES), "given"
    if allowed_pairs is None:
        allowed_pairs = BUILTIN_ALLOWED_PAIRS.get(robot.name, ())
    rows = [(b, pa, pb) for b, segs in enumerate(_body_segments(robot)) for pa, pb in segs]
    return CapsuleModel(
        frame_a=np.array([pa[0] for _, pa, _ in rows], dtype=int),
        frame_b=np.array([pb[0] for _, _, pb in rows], dtype=int),
        local_a=np.array([pa[1] for _, pa, _ in rows], dtype=float),
        local_b=np.array([pb[1] for _, _, pb in rows], dtype=float),
        radius=np.array([r[b] for b, _, _ in rows], dtype=float),
        body=np.array([b for b, _, _ in rows], dtype=int),
        allowed_pairs=tuple(tuple(sorted(p)) for p in allowed_pairs),  # type: ignore[misc]
        radii_source=source,
    )


def capsule_segments(model: CapsuleModel, frames: np.ndarray) -> np.ndarray:
    """End points of every capsule's segment at N configurations, base frame.

    Parameters
    ----------
    model : CapsuleModel
    frames : ndarray, shape (N, 7, 4, 4)
        DH frames 0..6 (:func:`chain_frames`).

    Returns
    -------
    ndarray, shape (N, M, 2, 3)
        ``[..., 0, :]`` end a, ``[..., 1, :]`` end b, m.
    """
    n = frames.shape[0]
    ext = np.concatenate([np.broadcast_to(np.eye(4), (n, 1, 4, 4)), frames], axis=1)  # index 0: base
    out = np.empty((n, model.n_capsules, 2, 3))
    for end, (fr, loc) in enumerate(((model.frame_a, model.local_a), (model.frame_b, model.local_b))):
        T = ext[:, fr + 1]  # (N, M, 4, 4)
        out[:, :, end] = np.einsum("nmij,mj->nmi", T[..., :3, :3], loc) + T[..., :3, 3]
    return out


def _bridged(model: CapsuleModel) -> set[tuple[int, int]]:
    """Body pairs (i-1, i+1) joined through a zero-length body i (they meet at its centre)."""
    out = set()
    for b in range(1, N_BODIES - 1):
        sel = model.body == b
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
    """Capsule index pairs checked for self-collision, shape (P, 2) of int (from the body pairs)."""
    pairs = set(self_collision_body_pairs(model))
    idx = [
        (k, m)
        for k in range(model.n_capsules)
        for m in range(k + 1, model.n_capsules)
        if (int(model.body[k]), int(model.body[m])) in pairs
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
    )
    return tool, True
