"""The ``[path]`` section of a problem file: a line, explicit waypoints, or a CAM program.

Holds :class:`PathSection` (the waypoints and their nominal rotations), :func:`parse_path` (a
``line`` from ``start`` to ``end``, ``waypoints`` with optional per-row rpy, or a program file
placed by ``[workpiece]``) and :func:`is_program_path`. A program path (``kind = "gcode"`` /
``"toolpath_csv"``) is read by :mod:`problems.problem_file.program_section`; the error type and the
value validators are :mod:`problems.problem_file.values`; the package :mod:`problems.problem_file`
re-exports the names here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple
from collections.abc import Mapping

import numpy as np

from models.robot import Robot
from models.transforms import rpy_to_matrix
from problems.path import line_positions
from problems.problem_file.values import (
    PLAUSIBLE_RPY_MAX_RAD,
    angle_pair,
    check_positions,
    check_radians,
    err,
    integer,
    rows,
    table,
    vector,
)


class PathSection(NamedTuple):
    """The ``[path]`` section.

    Attributes
    ----------
    kind : {"line", "waypoints", "gcode", "toolpath_csv"}
    line : tuple (start (3,), end (3,)) or None
        For ``line`` paths, m, base frame.
    positions : ndarray, shape (N, 3)
        TCP waypoints, m, base frame.
    rotations : ndarray, shape (N, 3, 3)
        Nominal base->TCP rotations (the path's own or the orientation's nominal one).
    program : problems.problem_file.program_section.ProgramSection or None
        For a program path (``gcode``, ``toolpath_csv``): the program read and placed.
    """

    kind: str
    line: tuple[np.ndarray, np.ndarray] | None
    positions: np.ndarray
    rotations: np.ndarray
    program: Any = None


def is_program_path(data: Mapping[str, Any]) -> bool:
    """Whether the document's path is a program file (``[path] kind`` in ``PROGRAM_KINDS``)."""
    from problems.problem_file.program_section import PROGRAM_KINDS

    pt = data.get("path") if isinstance(data, Mapping) else None
    return isinstance(pt, Mapping) and pt.get("kind") in PROGRAM_KINDS


def parse_path(
    where: str,
    data: Mapping[str, Any],
    R_nom: np.ndarray,
    base_dir: Path | None = None,
    robot: Robot | None = None,
    dt: float | None = None,
) -> PathSection:
    """The ``[path]`` section: a line, explicit waypoints, or a program file (with ``[workpiece]``).

    Parameters
    ----------
    R_nom : ndarray, shape (3, 3)
        The orientation's nominal base->TCP rotation, used where the path gives none.
    base_dir : Path, optional
        Directory against which a relative ``path.file`` is resolved.
    robot : Robot, optional
        The robot with its tool: a program point beyond its reach is refused with ``file:line``.
    dt : float, optional
        The controller period, s: a program longer at its feeds than a trajectory can hold at it is
        refused before it is made into points (:func:`~problems.problem_file.program_section.check_duration`).
    """
    from problems.problem_file.program_section import PROGRAM_KINDS, check_reach, parse_program

    pt = table(where, data, "path")
    kind = pt.get("kind")
    if kind != "gcode" and kind != "toolpath_csv" and "workpiece" in data:
        raise err(where, "workpiece", f"only applies to a program path (kind {list(PROGRAM_KINDS)}); kind is {kind!r}")
    for key in ("file", "tolerance_mm"):
        if key in pt and kind not in PROGRAM_KINDS:
            raise err(where, f"path.{key}", f"only applies to kinds {list(PROGRAM_KINDS)}")
    if kind == "line":
        return _line_path(where, pt, R_nom)
    if kind == "waypoints":
        return _waypoints_path(where, pt, R_nom)
    if kind in PROGRAM_KINDS:
        wt = table(where, data, "workpiece") if "workpiece" in data else None
        sec = parse_program(where, pt, wt, base_dir, dt, robot)
        if robot is not None:
            check_reach(sec, robot)
        return PathSection(kind, None, sec.positions, sec.rotations, sec)
    raise err(where, "path.kind", f"must be one of {['line', 'waypoints', *PROGRAM_KINDS]}, got {kind!r}")


def _line_path(where: str, pt: Mapping[str, Any], R_nom: np.ndarray) -> PathSection:
    """A ``kind = "line"`` path: ``points`` waypoints from ``start`` to ``end`` (m, base frame)."""
    for key in ("positions", "rpy", "rpy_deg"):
        if key in pt:
            raise err(where, f"path.{key}", "only applies to kind 'waypoints'")
    for key in ("start", "end", "points"):
        if key not in pt:
            raise err(where, f"path.{key}", "is required for kind 'line'")
    start = vector(where, "path.start", pt["start"], 3)
    end = vector(where, "path.end", pt["end"], 3)
    n = integer(where, "path.points", pt["points"], 2)
    check_positions(where, "path.start/end", np.vstack([start, end]))
    if np.linalg.norm(end - start) < 1e-9:
        raise err(where, "path.end", f"equals path.start {start.tolist()}; a line needs two distinct points")
    P = line_positions(start, end, n)
    R = np.broadcast_to(R_nom, (n, 3, 3)).copy()
    return PathSection("line", (start, end), P, R)


def _waypoints_path(where: str, pt: Mapping[str, Any], R_nom: np.ndarray) -> PathSection:
    """A ``kind = "waypoints"`` path: explicit positions (m) and optional per-row rpy."""
    for key in ("start", "end", "points"):
        if key in pt:
            raise err(where, f"path.{key}", "only applies to kind 'line'")
    if "positions" not in pt:
        raise err(where, "path.positions", "is required for kind 'waypoints'")
    P = rows(where, "path.positions", pt["positions"], 3)
    n = len(P)
    check_positions(where, "path.positions", P)
    got = angle_pair(where, pt, "rpy", "path.")
    if got is not None:
        raw, deg = got
        key = f"path.rpy{'_deg' if deg else ''}"
        A = rows(where, key, raw, 3)
        if len(A) != n:
            raise err(where, key, f"has {len(A)} rows but path.positions has {n}")
        if not deg:
            for i, row in enumerate(A):
                check_radians(where, f"path.rpy[{i}]", row, PLAUSIBLE_RPY_MAX_RAD, "path.rpy_deg")
        R = np.stack([rpy_to_matrix(np.radians(a) if deg else a) for a in A])
    else:
        R = np.broadcast_to(R_nom, (n, 3, 3)).copy()
    return PathSection("waypoints", None, P, R)
