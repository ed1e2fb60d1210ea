"""What a run produced, as one typed record: :class:`RunRecord`.

A run record holds the content of ``summary.json`` (JSON values: non-finite numbers are None) and
the columns of the run's CSV files (``waypoints.csv``, ``branches.csv``, ``trajectory*.csv``,
``dynamic.csv``, a program path's columns of ``path.csv``), in SI units, with the arm model the run
was planned with and, for a program path, its :class:`ProgramRecord` (the waypoints in the
workpiece frame that the run records).  It is built by the plan that made the run
(:func:`planner.plan_record.record_from_plan`) or read from the run's folder
(:func:`planner.record.read.read_record`); both give the same record, and the report reads nothing
else.  This module is a leaf: it imports neither the plan nor the report.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from models import Robot
from models.arm import ArmModel
from models.errors import InputError
from models.transforms import rpy_to_matrix

from planner.record.columns import DYNAMIC_KEY, MM_MIN_PER_M_S, PROGRAM_KEY, TRAJECTORY_FILES

__all__ = [
    "NO_TRAJECTORY",
    "ProgramRecord",
    "RunRecord",
    "Workpiece",
    "add_trajectory",
    "dynamic_file",
    "method_name",
    "method_order",
    "no_dynamic",
    "program_record",
    "to_program_frame",
    "trajectory_files",
]

#: Why a run without any trajectory shows none.
NO_TRAJECTORY = "no trajectory in this run (trajectory.csv and trajectory_toppra.csv absent)"


@dataclass(frozen=True)
class Workpiece:
    """The program (workpiece) frame of a program path in the base frame (``summary.json``
    ``program.workpiece``): ``p_B = R p_P + t`` with ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    Attributes
    ----------
    xyz_m : np.ndarray
        Shape ``(3,)``, m, base frame: ``t``.
    rpy_rad : np.ndarray
        Shape ``(3,)``, rad: roll, pitch, yaw of ``R``.
    """

    xyz_m: np.ndarray
    rpy_rad: np.ndarray

    @classmethod
    def from_summary(cls, workpiece: Mapping[str, Any]) -> Workpiece:
        """The frame of ``workpiece`` (``xyz_m``, ``rpy_rad``).

        Raises
        ------
        InputError
            ``workpiece`` lacks 3 finite numbers for ``xyz_m`` or ``rpy_rad``.
        """
        try:
            t = np.asarray(workpiece["xyz_m"], float).reshape(3)
            rpy = np.asarray(workpiece["rpy_rad"], float).reshape(3)
        except (KeyError, TypeError, ValueError):
            raise InputError(
                "summary.json: program.workpiece.xyz_m / rpy_rad missing or not 3 numbers each (m, rad)"
            ) from None
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(rpy))):
            raise InputError("summary.json: program.workpiece.xyz_m / rpy_rad are not finite")
        return cls(t, rpy)

    def to_program_frame(self, points_base_m: np.ndarray) -> np.ndarray:
        """Base-frame points, shape ``(N, 3)``, m, in the program frame: ``R^T (p - t)``."""
        R = rpy_to_matrix(self.rpy_rad)
        return (np.asarray(points_base_m, float) - self.xyz_m) @ R  # R^T (p - t), row by row


def to_program_frame(points_base_m: np.ndarray, workpiece: Mapping[str, Any]) -> np.ndarray:
    """Base-frame points (N, 3), m, in the program frame of ``workpiece`` (``xyz_m`` (3,) and
    ``rpy_rad`` (3,), as ``summary.json`` ``program.workpiece``; :class:`Workpiece`).

    Raises
    ------
    InputError
        ``workpiece`` lacks 3 finite numbers for ``xyz_m`` or ``rpy_rad``.
    """
    return Workpiece.from_summary(workpiece).to_program_frame(points_base_m)


@dataclass
class ProgramRecord:
    """The program of a run (SI units): what a program path's run recorded.

    Attributes
    ----------
    points_m : np.ndarray
        Shape ``(N, 3)``, m, program (workpiece) frame: the TCP waypoints.
    line : np.ndarray
        Shape ``(N,)``, int: the program line of the move ending at each waypoint.
    rapid : np.ndarray
        Shape ``(N,)``, bool: that move is a rapid.
    feed_m_s : np.ndarray
        Shape ``(N,)``, m/s: its programmed feed; NaN for rapids and waypoint 0.
    sample_line : dict of method -> np.ndarray
        Shape ``(M,)``, int: the program line of the move each sample of the method's trajectory
        runs (the ``line`` column of its ``trajectory*.csv``); a method without one is left out.
    sample_waypoint : dict of method -> np.ndarray
        Shape ``(M,)``, int: the waypoint (row of ``path.csv``) that move ends at.
    workpiece : Workpiece or None
        The program frame in the base frame, as the run recorded it.
    """

    points_m: np.ndarray
    line: np.ndarray
    rapid: np.ndarray
    feed_m_s: np.ndarray
    sample_line: dict[str, np.ndarray] = field(default_factory=dict)
    sample_waypoint: dict[str, np.ndarray] = field(default_factory=dict)
    workpiece: Workpiece | None = None

    @property
    def n(self) -> int:
        """Number of waypoints N."""
        return len(self.points_m)


def program_record(
    summary: Mapping[str, Any], base_m: np.ndarray, feed_mm_min: np.ndarray, line: Any, rapid: Any
) -> ProgramRecord:
    """The program record from ``path.csv``'s columns (the same arrays from a plan or a folder):
    the base-frame waypoints ``base_m`` (N, 3), m, taken into the workpiece frame the summary records,
    the feeds (mm/min) in m/s."""
    wp = Workpiece.from_summary(summary[PROGRAM_KEY].get("workpiece") or {})
    return ProgramRecord(
        points_m=wp.to_program_frame(base_m),
        line=np.asarray(line).astype(int),
        rapid=np.asarray(rapid).astype(bool),
        feed_m_s=np.asarray(feed_mm_min, float) / MM_MIN_PER_M_S,
        workpiece=wp,
    )


@dataclass
class RunRecord:
    """What one run produced (SI units).

    Attributes
    ----------
    folder : Path
        The run's output folder.
    summary : dict
        ``summary.json`` (JSON values; from a folder, every key its readers read checked against its
        declaration, :mod:`planner.summary_schema`).
    waypoints : dict of column -> ndarray, or None
        The columns of ``waypoints.csv`` (:data:`~planner.record.columns.WAYPOINT_COLUMNS`).
    branches : dict of column -> ndarray, or None
        The columns of ``branches.csv``.
    trajectories : dict method -> {"t", "q", "qd", "qdd", "qddd"}
        ``qddd`` is None for a file written without the jerk columns.
    trajectory_files : dict method -> file name
    robot : Robot or None
        From ``summary["robot_file"]`` (or the plan's robot).
    model : ArmModel or None
        The arm model the run was planned with: the plan's own, or from a folder the identified
        model file ``summary["model"]`` records, read again and checked against its SHA-256
        (:func:`planner.record.read.recorded_model`), else the nominal model of ``robot``.  None
        when it cannot be known (``absent["model"]`` or ``absent["robot"]`` says why).
    dynamic : dict of column -> ndarray, or None
        The columns of ``dynamic.csv`` (:data:`~planner.record.columns.DYNAMIC_COLUMNS`) of a run
        with dynamic compensation (summary.json key ``dynamic_compensation``); None otherwise.
    program : ProgramRecord or None
        A program path's waypoints in the program frame, lines, rapids, feeds and the program line
        of each sample (summary.json key ``program``); None otherwise.
    cut : dict of column -> ndarray, or None
        The columns of ``cut.csv`` (:data:`~planner.record.columns.CUT_COLUMNS`) of a run whose load
        is a predicted cut (summary.json key ``cut``); None otherwise.
    cut_stock : dict or None
        ``cut_stock.npz``: ``before``, ``after`` (ny, nx) m and ``extent`` (4,) m, program frame.
    absent : dict of piece -> reason
        What the run does not hold and why.
    """

    folder: Path
    summary: dict[str, Any]
    waypoints: dict[str, np.ndarray] | None = None
    branches: dict[str, np.ndarray] | None = None
    trajectories: dict[str, dict[str, np.ndarray | None]] = field(default_factory=dict)
    trajectory_files: dict[str, str] = field(default_factory=dict)
    robot: Robot | None = None
    model: ArmModel | None = None
    dynamic: dict[str, np.ndarray] | None = None
    program: ProgramRecord | None = None
    cut: dict[str, np.ndarray] | None = None
    cut_stock: dict[str, np.ndarray] | None = None
    absent: dict[str, str] = field(default_factory=dict)


def method_order() -> tuple[str, ...]:
    """The registered timing methods, in registration order (the column order of figure 6;
    :func:`problems.timing.available_methods`)."""
    from problems.timing import available_methods

    return available_methods()


def method_name(summary: Mapping[str, Any], method: str) -> str:
    """The display name of timing method ``method`` (``"TOPP-RA"``): the run's
    ``timing.<method>.display_name``, else the registered method's, else ``method``."""
    info = (summary.get("timing") or {}).get(method) if isinstance(summary.get("timing"), Mapping) else None
    if isinstance(info, Mapping) and isinstance(info.get("display_name"), str):
        return info["display_name"]
    from problems.timing import display_name

    return display_name(method)


def trajectory_files(summary: Mapping[str, Any], folder: Path | None = None) -> list[tuple[str, str]]:
    """(file, method) pairs, TOPP-RA first: from ``timing.<method>.file`` or, without it,
    the defaults and the ``trajectory_*.csv`` files of ``folder``."""
    pairs: list[tuple[str, str]] = []
    timing = summary.get("timing")
    if isinstance(timing, Mapping):
        for m, info in timing.items():
            if isinstance(info, Mapping) and isinstance(info.get("file"), str):
                pairs.append((Path(info["file"]).name, str(m)))
    if not pairs:
        pairs = list(TRAJECTORY_FILES)
        known = {f for f, _ in pairs}
        for p in sorted(folder.glob("trajectory_*.csv")) if folder is not None else ():
            if p.name not in known:
                pairs.append((p.name, p.stem[len("trajectory_") :]))
    order = {m: i for i, m in enumerate(method_order())}
    return sorted(pairs, key=lambda fm: (order.get(fm[1], len(order)), fm[1]))


def add_trajectory(run: RunRecord, method: str, name: str, tr: dict[str, np.ndarray | None]) -> None:
    """Record one method's trajectory, or why it is absent (no samples)."""
    if len(tr["t"]) == 0:  # type: ignore[arg-type]
        run.absent[f"trajectory {method}"] = f"{name} has no samples"
        return
    run.trajectories[method] = tr
    run.trajectory_files[method] = name


def dynamic_file(summary: Mapping[str, Any]) -> str:
    """The file of the dynamic-compensation series (``dynamic_compensation.file``, else ``dynamic.csv``)."""
    entry = summary.get(DYNAMIC_KEY)
    name = entry.get("file") if isinstance(entry, Mapping) else None
    return Path(name).name if isinstance(name, str) and name else "dynamic.csv"


def no_dynamic(summary: Mapping[str, Any]) -> str:
    """Why a run whose summary has the dynamic-compensation block holds no series."""
    entry = summary.get(DYNAMIC_KEY)
    status = entry.get("status") if isinstance(entry, Mapping) else None
    return f"dynamic compensation: {dynamic_file(summary)} absent in this run" + (
        f" (stage status {status})" if status not in (None, "ok") else ""
    )
