"""Problem-file sections for a CAM program as the path: ``[path] kind = "gcode" | "toolpath_csv"``
and ``[workpiece]`` (``docs/problem-file.md``, "Programs").

``[path]``: ``file`` (the program, relative to the problem file) and optionally ``tolerance_mm``
(the path tolerance when the program gives no ``G64 P``; default
:data:`problems.toolpath.waypoints.DEFAULT_PATH_TOLERANCE_M`). ``[workpiece]``: ``xyz`` (m, the
program zero in the base frame, required) and ``rpy`` / ``rpy_deg`` (the program frame's
orientation in the base frame, default 0). The waypoints are the program's
(:func:`problems.toolpath.waypoints.program_waypoints`), placed in the base frame by the workpiece;
the TCP's z axis is the tool axis reversed (a 3-axis program: the program's -Z).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, NamedTuple
from collections.abc import Mapping

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError
from problems.problem_file.values import err, rpy_angles
from problems.toolpath.waypoints import DEFAULT_PATH_TOLERANCE_M, ProgramWaypoints
from problems.toolpath.workpiece import Workpiece

__all__ = [
    "PROGRAM_KINDS",
    "ProgramSection",
    "check_reach",
    "parse_program",
]

#: ``[path] kind`` values whose path is a program file.
PROGRAM_KINDS = ("gcode", "toolpath_csv")
#: Largest path tolerance accepted, m (1 mm: beyond it a "tolerance" is a different path).
MAX_TOLERANCE_M = 1e-3


class ProgramSection(NamedTuple):
    """A program path, read and placed.

    Attributes
    ----------
    kind : {"gcode", "toolpath_csv"}
    file : str
        The program file, resolved.
    waypoints : ProgramWaypoints
        In the program frame.
    workpiece : Workpiece
    positions : np.ndarray
        Shape ``(N, 3)``, m, base frame: TCP waypoints.
    rotations : np.ndarray
        Shape ``(N, 3, 3)``: nominal base->TCP rotations, z = the TCP axis (the tool axis reversed).
    units_note : str
        The program's note on units (no G20/G21), or empty.
    """

    kind: str
    file: str
    waypoints: ProgramWaypoints
    workpiece: Workpiece
    positions: np.ndarray
    rotations: np.ndarray
    units_note: str


def tool_frames(z_axes: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) with the given z columns and an x column carried along the path without
    turning about z (parallel transport), starting from the base x (or y) axis made normal to z."""
    Z = np.asarray(z_axes, dtype=float)
    n = len(Z)
    if n and np.allclose(Z, Z[0], atol=1e-15, rtol=0.0):  # 3-axis: one frame
        z = Z[0]
        ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = ref - z * (ref @ z)
        x /= np.linalg.norm(x)
        return np.broadcast_to(np.column_stack([x, np.cross(z, x), z]), (n, 3, 3)).copy()
    X = np.empty_like(Z)
    z = Z[0]
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - z * (ref @ z)
    x /= np.linalg.norm(x)
    for k in range(n):
        z = Z[k]
        x = x - z * (x @ z)
        x /= np.linalg.norm(x)
        X[k] = x
    return np.stack([X, np.cross(Z, X), Z], axis=2)


def check_duration(source: str, seconds: float, longest: str, dt: float) -> None:
    """Refuse a program that runs longer at its feeds than a trajectory can hold at ``dt``.

    Checked from the moves alone, before the program is made into points, so a runaway program
    (a helix of 20 000 turns, a feed in the wrong unit) is refused in seconds with its own reason.

    Parameters
    ----------
    source : str
        The program file, for the message.
    seconds : float
        Its feed moves' time at the programmed feeds, s (:func:`feed_seconds`).
    longest : str
        The longest of them, as the message names it (``line N: <text> (<length> at <feed>)``).
    dt : float
        The controller period, s (``[timing] dt``).

    Raises
    ------
    InputError
        More than :data:`~problems.timing.registry.MAX_TRAJECTORY_SAMPLES` samples at ``dt``.
    """
    from problems.timing.registry import MAX_TRAJECTORY_SAMPLES

    n = seconds / dt + 1.0
    if n <= MAX_TRAJECTORY_SAMPLES:
        return
    raise InputError(
        f"{source}: the program's feed moves last {_duration_words(seconds)} at their programmed feeds "
        f"(longest: {longest}): at dt = {dt:g} s that is at least {n:.3g} trajectory samples, more than the "
        f"cap of {MAX_TRAJECTORY_SAMPLES} (MAX_TRAJECTORY_SAMPLES); split the program into parts planned "
        "one by one, or check its feeds (F, in mm/min with G21, in/min with G20) and turn counts (P)"
    )


def _duration_words(seconds: float) -> str:
    if seconds >= 3600.0:
        return f"{seconds / 3600.0:.3g} h"
    return f"{seconds / 60.0:.3g} min" if seconds >= 60.0 else f"{seconds:.3g} s"


def _move_words(line: int, text: str, length_m: float, feed_m_s: float) -> str:
    """A move as a message names it: ``line N: 'text', L m at F mm/min`` (no text: CL data's row)."""
    said = f" {text.strip()!r}," if text.strip() else ""
    return f"line {line}:{said} {length_m:.4g} m at {feed_m_s * 6e4:.4g} mm/min"


def parse_program(
    where: str,
    pt: Mapping[str, Any],
    wt: Mapping[str, Any] | None,
    base_dir: Path | None,
    dt: float | None = None,
    robot: Any = None,
) -> ProgramSection:
    """Read ``[path]`` (a program kind) and ``[workpiece]``.

    Parameters
    ----------
    where : str
        The problem file, for messages.
    pt, wt : mapping
        The ``[path]`` and ``[workpiece]`` tables (``wt`` None when absent).
    base_dir : Path or None
        The problem file's folder (a relative ``file`` is resolved against it).
    dt : float, optional
        The controller period, s: a G-code or CL program whose feed moves take more samples at it
        than a trajectory holds is refused before it is made into points (:func:`check_duration`).
    robot : Robot, optional
        With it, a G-code move ending beyond the robot's reach is refused first (the likely cause
        of both: a program in another unit).

    Raises
    ------
    InputError
        The problem-file error naming the key, or the program's own error (``file:line``).
    """
    kind = pt["kind"]
    for key in ("start", "end", "points", "positions", "rpy", "rpy_deg"):
        if key in pt:
            raise err(where, f"path.{key}", f"does not apply to kind '{kind}' (the program gives the path)")
    raw = pt.get("file")
    if not isinstance(raw, str) or not raw:
        raise err(where, "path.file", f"is required for kind '{kind}': the program file, got {raw!r}")
    f = Path(raw)
    if not f.is_absolute() and base_dir is not None:
        f = base_dir / f
    if not f.is_file():
        raise err(where, "path.file", f"= {raw!r}: no such file ({f})")
    tol = None
    if "tolerance_mm" in pt:
        v = pt["tolerance_mm"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (0.0 < v <= MAX_TOLERANCE_M * 1e3):
            raise err(where, "path.tolerance_mm", f"must be a number in (0, {MAX_TOLERANCE_M * 1e3:g}] mm, got {v!r}")
        tol = float(v) * 1e-3
    if wt is None:
        raise err(where, "workpiece", f"is required for kind '{kind}': the program zero in the base frame (xyz, m)")
    if "xyz" not in wt:
        raise err(where, "workpiece.xyz", "is required: the program zero in the base frame, m")
    xyz = wt["xyz"]
    if (
        not isinstance(xyz, list)
        or len(xyz) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in xyz)
    ):
        raise err(where, "workpiece.xyz", f"must be a list of 3 numbers (m), got {xyz!r}")
    if max(abs(float(v)) for v in xyz) > PLAUSIBLE_POSITION_MAX_M:
        raise err(where, "workpiece.xyz", f"= {xyz} m is implausible (> {PLAUSIBLE_POSITION_MAX_M:g} m); in metres")
    ang = rpy_angles(where, wt, "workpiece.")
    wp = Workpiece(np.array(xyz, dtype=float), np.zeros(3) if ang is None else ang)
    way, note = _read_program(kind, f, tol, wp, dt, robot)
    positions, z = wp.tcp_targets(way.points_m, way.tool_axis)
    return ProgramSection(kind, str(f), way, wp, positions, tool_frames(z), note)


def _read_program(
    kind: str, f: Path, tol: float | None, wp: Workpiece, dt: float | None, robot: Any
) -> tuple[ProgramWaypoints, str]:
    """The program file ``f`` read, checked from its moves (reach, duration) and made into
    waypoints; with the units note of a G-code program (empty for CL data)."""
    from problems.toolpath.cl_csv import read_cl_csv
    from problems.toolpath.gcode import read_gcode
    from problems.toolpath.program import feed_seconds
    from problems.toolpath.waypoints import cl_waypoints, program_waypoints

    if kind == "gcode":
        prog = read_gcode(f)
        if robot is not None and prog.moves:  # the moves' ends first: a cheap check of the likely causes
            ends = np.array([m.end for m in prog.moves])
            lines = np.array([m.line for m in prog.moves])
            refuse_out_of_reach(str(f), lines, ends, wp.tcp_targets(ends, None)[0], robot, bool(prog.units_note))
        seconds, k = feed_seconds(prog)
        if dt is not None and k >= 0:
            m = prog.moves[k]
            check_duration(str(f), seconds, _move_words(m.line, m.text, m.length_m, m.feed_m_s or 0.0), dt)
        if prog.path_tolerance_m:
            way = program_waypoints(prog)
        elif tol is not None:
            way = program_waypoints(prog, tol, "path.tolerance_mm")
        else:
            way = program_waypoints(prog, DEFAULT_PATH_TOLERANCE_M, "default")
        note = prog.units_note
    else:
        cl = read_cl_csv(f)
        if dt is not None and cl.feed_m_s is not None and cl.n > 1:
            step = np.linalg.norm(np.diff(cl.points_m, axis=0), axis=1)
            feed = cl.feed_m_s[1:]
            t = np.where(~cl.rapid[1:] & (feed > 0.0), step / np.where(feed > 0.0, feed, 1.0), 0.0)
            k = int(np.argmax(t))
            words = _move_words(int(cl.line[k + 1]), "", float(step[k]), float(feed[k]))
            check_duration(str(f), float(np.sum(t)), words, dt)
        way = cl_waypoints(
            cl, DEFAULT_PATH_TOLERANCE_M if tol is None else tol, "default" if tol is None else "path.tolerance_mm"
        )
        note = ""
    return way, note


def reach_bound_m(robot: Any) -> float:
    """An upper bound on the TCP's distance from the base origin, m: the norms of every fixed
    translation of the chain added (base frame, DH ``a`` and ``d`` of every joint, flange, tool)."""
    return float(
        np.linalg.norm(robot.frame02base[:3, 3])
        + np.sum(np.abs(robot.a))
        + np.sum(np.abs(robot.d))
        + np.linalg.norm(robot.flange2frame6[:3, 3])
        + np.linalg.norm(robot.tcp2flange[:3, 3])
    )


def check_reach(sec: ProgramSection, robot: Any) -> None:
    """Refuse a program whose points lie beyond any reach of the robot, naming ``file:line``, the
    point and, when the program gave no G20/G21 (read as millimetres), the likely cause.

    Raises
    ------
    InputError
    """
    w = sec.waypoints
    refuse_out_of_reach(sec.file, w.line, w.points_m, sec.positions, robot, bool(sec.units_note))


def refuse_out_of_reach(
    file: str, line: np.ndarray, points_m: np.ndarray, positions: np.ndarray, robot: Any, no_units: bool
) -> None:
    """Refuse program points ``points_m`` (N, 3) m, program frame, landing at ``positions`` (N, 3) m,
    base frame, beyond any reach of the robot (:func:`reach_bound_m`), naming ``file:line`` of the
    first; ``no_units``: the program gave no G20/G21 (the hint then says so)."""
    r = np.linalg.norm(positions - robot.frame02base[:3, 3], axis=1)
    bound = reach_bound_m(robot)
    far = np.flatnonzero(r > bound)
    if not far.size:
        return
    k = int(far[0])
    p_mm = points_m[k] * 1e3
    hint = (
        " The program gives no G20/G21 and was read in millimetres: if it is in inches, add G20 at its start."
        if no_units
        else " Check [workpiece] xyz (m) and the program's units."
    )
    raise InputError(
        f"{file}:{int(line[k])}: the point ({p_mm[0]:.4g}, {p_mm[1]:.4g}, {p_mm[2]:.4g}) mm of the program "
        f"lands {r[k]:.4g} m from the robot base, beyond the reach of {robot.name} with its tool "
        f"(at most {bound:.4g} m); {len(far)} point(s) are out of reach.{hint}"
    )
