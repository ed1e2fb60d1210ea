"""The optional ``[collision]`` table of a robot file (the arm's own capsules, ``docs/cell.md``),
read into :class:`~models.description.RobotCollision`, and the check that a declared segment is
fixed to its body.  The functions are moved verbatim from ``models/robot.py``."""

from __future__ import annotations

from typing import Any
from collections.abc import Mapping, Sequence

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.description import CollisionSegment, Robot, RobotCollision, RobotFileError

from .values import VALUES, finite, vector

#: Keys of the optional ``[collision]`` table (the arm's own collision geometry, ``docs/cell.md``).
COLLISION_KEYS = ("radii_m", "allowed_pairs", "segments", "replace_dh", "source")
#: Keys of one ``[[collision.segments]]`` entry.
COLLISION_SEGMENT_KEYS = ("body", "frame_a", "xyz_a", "frame_b", "xyz_b", "radius_m", "line", "name")
#: Collision bodies: 0 the base, i = 1..6 the link moved by joint i.
COLLISION_N_BODIES = 7
#: A segment end may be fixed in the base frame (-1) or a DH frame 0..6.
COLLISION_FRAMES = tuple(range(-1, 7))
#: A segment end whose position in its body's frame changes by more than this (m, per m of the
#: arm's reach) between configurations is not fixed to that body.
COLLISION_FIXED_TOL_M_PER_M = 1e-9


def _int_in(where: str, key: str, value: Any, allowed: Sequence[int], what: str) -> int:
    """An integer key that must be one of ``allowed`` (a body or frame number)."""
    if isinstance(value, bool) or not isinstance(value, int) or value not in allowed:
        raise RobotFileError(
            f"{where}: key '{key}' = {value!r}; expected {what} (an integer {allowed[0]}..{allowed[-1]})"
        )
    return int(value)


def _radius(where: str, key: str, value: Any) -> float:
    """A capsule radius: finite, > 0, plausible in metres."""
    r = finite(where, key, value)
    if r <= 0:
        raise RobotFileError(f"{where}: key '{key}' = {r:g}; expected a radius > 0 (m)")
    if r > PLAUSIBLE_POSITION_MAX_M:
        raise RobotFileError(
            f"{where}: key '{key}' = {r:g} m is implausible for a capsule radius (> "
            f"{PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres (millimetres given?)"
        )
    return r


def _collision_point(where: str, key: str, value: Any) -> np.ndarray:
    p = vector(where, key, value, 3)
    if np.max(np.abs(p)) > PLAUSIBLE_POSITION_MAX_M:
        raise RobotFileError(
            f"{where}: key '{key}' = {[float(v) for v in p]} is implausible (> {PLAUSIBLE_POSITION_MAX_M:g} m); "
            "lengths are in metres (millimetres given?)"
        )
    return p


def _collision_segment(where: str, seg: Any) -> CollisionSegment:
    if not isinstance(seg, Mapping):
        raise RobotFileError(f"{where}: expected a table (body, frame_a, xyz_a, frame_b, xyz_b), got {seg!r}")
    VALUES.unknown_keys(where, seg, COLLISION_SEGMENT_KEYS)
    for key in ("body", "frame_a", "xyz_a", "frame_b", "xyz_b"):
        if key not in seg:
            raise RobotFileError(f"{where}: missing key '{key}'")
    frames = COLLISION_FRAMES
    name = seg.get("name", "")
    if not isinstance(name, str):
        raise RobotFileError(f"{where}: key 'name' must be a string, got {name!r}")
    line = seg.get("line", False)
    if not isinstance(line, bool):
        raise RobotFileError(f"{where}: key 'line' must be true or false, got {line!r}")
    return CollisionSegment(
        body=_int_in(where, "body", seg["body"], range(COLLISION_N_BODIES), "a body: 0 base, i link moved by joint i"),
        frame_a=_int_in(where, "frame_a", seg["frame_a"], frames, "a frame: -1 base, 0..6 DH frame"),
        xyz_a=_collision_point(where, "xyz_a", seg["xyz_a"]),
        frame_b=_int_in(where, "frame_b", seg["frame_b"], frames, "a frame: -1 base, 0..6 DH frame"),
        xyz_b=_collision_point(where, "xyz_b", seg["xyz_b"]),
        radius=_radius(where, "radius_m", seg["radius_m"]) if "radius_m" in seg else None,
        line=line,
        name=name,
    )


def parse_collision_table(where: str, table: Any) -> RobotCollision:
    """The optional ``[collision]`` table of a robot file (``docs/robot-file.md``, ``docs/cell.md``).

    Keys: ``radii_m`` (7 radii, m, body 0 base .. 6), ``allowed_pairs`` (pairs of two different
    bodies 0..6), ``replace_dh`` (bodies), ``source`` (text), ``[[collision.segments]]`` (``body``,
    ``frame_a``, ``xyz_a``, ``frame_b``, ``xyz_b``, optional ``radius_m``, ``line`` and ``name``).

    Raises
    ------
    RobotFileError
        Naming the file, the key (``collision.segments[2]: key 'body'``), the value and what was expected.
    """
    w = f"{where}: collision"
    if not isinstance(table, Mapping):
        raise RobotFileError(f"{where}: key 'collision' must be a table, got {table!r}")
    VALUES.unknown_keys(w, table, COLLISION_KEYS)
    radii = None
    if "radii_m" in table:
        raw = table["radii_m"]
        if not isinstance(raw, (list, tuple)) or len(raw) != COLLISION_N_BODIES:
            raise RobotFileError(
                f"{w}: key 'radii_m' must be a list of {COLLISION_N_BODIES} radii (m, body 0 base .. 6), got {raw!r}"
            )
        radii = np.array([_radius(w, f"radii_m[{i}]", v) for i, v in enumerate(raw)])
    pairs = None
    if "allowed_pairs" in table:
        raw = table["allowed_pairs"]
        if not isinstance(raw, (list, tuple)):
            raise RobotFileError(f"{w}: key 'allowed_pairs' must be a list of [i, j] body pairs, got {raw!r}")
        out = []
        for k, pair in enumerate(raw):
            key = f"allowed_pairs[{k}]"
            bodies = range(COLLISION_N_BODIES)
            if (
                not isinstance(pair, (list, tuple))
                or len(pair) != 2
                or any(isinstance(b, bool) or not isinstance(b, int) or b not in bodies for b in pair)
                or pair[0] == pair[1]
            ):
                raise RobotFileError(
                    f"{w}: key '{key}' = {pair!r}; expected two different bodies [i, j] (integers 0..6)"
                )
            out.append((min(pair), max(pair)))
        pairs = tuple(sorted(set(out)))
    replace_dh: tuple[int, ...] = ()
    if "replace_dh" in table:
        raw = table["replace_dh"]
        if not isinstance(raw, (list, tuple)):
            raise RobotFileError(f"{w}: key 'replace_dh' must be a list of bodies (integers 0..6), got {raw!r}")
        replace_dh = tuple(
            sorted({_int_in(w, f"replace_dh[{k}]", b, range(COLLISION_N_BODIES), "a body") for k, b in enumerate(raw)})
        )
    segs_raw = table.get("segments", [])
    if not isinstance(segs_raw, (list, tuple)):
        raise RobotFileError(f"{w}: key 'segments' must be an array of tables ([[collision.segments]])")
    segments = tuple(_collision_segment(f"{w}.segments[{k}]", seg) for k, seg in enumerate(segs_raw))
    missing = sorted(set(replace_dh) - {s.body for s in segments})
    if missing:
        raise RobotFileError(
            f"{w}: key 'replace_dh' = {list(replace_dh)}: body {missing[0]} has no segment to replace its DH capsules"
        )
    source = table.get("source", "")
    if not isinstance(source, str):
        raise RobotFileError(f"{w}: key 'source' must be a string, got {source!r}")
    source = " ".join(source.split())  # one line (messages, summary.json)
    return RobotCollision(radii=radii, allowed_pairs=pairs, segments=segments, replace_dh=replace_dh, source=source)


def check_collision_fixed(where: str, robot: Robot, n: int = 4) -> None:
    """Refuse a declared collision segment whose ends move relative to its body.

    Body 0 moves with the base, body i with DH frame i; an end given in another frame is fixed
    to the body only when it lies on the joint axes between (e.g. a point on joint i's axis given
    in DH frame i-1 or i). Checked at ``n`` fixed pseudo-random configurations within the limits.
    """
    col = robot.collision
    if col is None or not col.segments:
        return
    from models.transforms import dh_chain_frames

    rng = np.random.default_rng(0)
    qs = rng.uniform(robot.q_min, robot.q_max, (n, 6))
    F = [
        dh_chain_frames(robot.convention, robot.a, robot.alpha, robot.d, robot.theta_offset, q, robot.frame02base)
        for q in qs
    ]
    reach = float(np.sum(np.abs(robot.a)) + np.sum(np.abs(robot.d)))
    tol = COLLISION_FIXED_TOL_M_PER_M * max(1.0, reach)
    for k, seg in enumerate(col.segments):
        for end, frame, xyz in (("a", seg.frame_a, seg.xyz_a), ("b", seg.frame_b, seg.xyz_b)):
            local = []
            for Fq in F:
                T = np.eye(4) if frame < 0 else Fq[frame]
                p = T[:3, :3] @ xyz + T[:3, 3]
                B = np.eye(4) if seg.body == 0 else Fq[seg.body]
                local.append(B[:3, :3].T @ (p - B[:3, 3]))
            spread = float(np.max(np.ptp(np.array(local), axis=0)))
            if spread > tol:
                raise RobotFileError(
                    f"{where}: collision.segments[{k}]: end {end} (frame_{end} = {frame}, xyz_{end} = "
                    f"{[float(v) for v in xyz]}) is not fixed to body {seg.body}: it moves by {spread:.3g} m "
                    f"relative to it; a point of body {seg.body} is given in DH frame {seg.body}"
                    + (" (or the base frame -1 / DH frame 0)" if seg.body == 0 else "")
                    + ", or in a neighbouring frame only when it lies on the joint axis between"
                )
