"""The view of one run: the data the report needs, in SI units.

A :class:`Run` is built either from the in-memory result of a plan
(:func:`run_from_plan`, what ``compplan plan`` and ``compplan demo`` use right
after planning) or from the files of an output folder (:func:`load_run`, what
``compplan report DIR`` uses).  Both give the same view: ``summary`` is the
content of ``summary.json`` as JSON values (non-finite numbers are None), the
waypoint, branch and trajectory tables hold the columns of ``waypoints.csv``,
``branches.csv`` and ``trajectory*.csv``, and a plan with dynamic compensation
(``[timing] dynamic = true``) the series of ``dynamic.csv``.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from models import Robot, robot_from_dict
from models.errors import CompplanError, InputError

from planner.output import TRAJECTORY_COLUMNS, jsonable

if TYPE_CHECKING:
    from planner.plan import PlanResult
    from problems.timing import Trajectory

#: Default trajectory files and the method each one holds, used when summary.json has no
#: ``timing.<method>.file`` (a plan names the file of each method there; the controller's
#: trajectory is ``trajectory.csv``, Ruckig when available).
TRAJECTORY_FILES = (("trajectory_toppra.csv", "toppra"), ("trajectory.csv", "ruckig"))
#: Display names of the timing methods (column order of figure 6).
METHOD_NAMES = {"toppra": "TOPP-RA", "jerk_optimal": "jerk-optimal", "ruckig": "Ruckig"}

#: Jerk columns of ``trajectory*.csv`` (absent in files written before they were recorded).
_JERK_COLUMNS = [c for c in TRAJECTORY_COLUMNS if c.startswith("qddd")]
_NO_TRAJECTORY = "no trajectory in this run (trajectory.csv and trajectory_toppra.csv absent)"
#: Columns of ``dynamic.csv`` (dynamic compensation): time (s), moving (0/1), the predicted TCP
#: error along the command without compensation, with the static one and with static + dynamic
#: (m), and the planned TCP speed (m/s).
DYNAMIC_COLUMNS = ("t", "moving", "e_none_m", "e_static_m", "e_static_dynamic_m", "tcp_speed_m_s")
#: The summary.json key of the dynamic-compensation stage.
DYNAMIC_KEY = "dynamic_compensation"


@dataclass
class Run:
    """What the report shows of one run (SI units).

    Attributes
    ----------
    folder : Path
        The output folder the report is written into.
    summary : dict
        ``summary.json`` (JSON values).
    waypoints : dict of column -> ndarray, or None
        The columns of ``waypoints.csv``.
    branches : dict of column -> ndarray, or None
        The columns of ``branches.csv``.
    trajectories : dict method -> {"t", "q", "qd", "qdd", "qddd"}
        ``qddd`` is None for a file written without the jerk columns.
    trajectory_files : dict method -> file name
    robot : Robot or None
        From ``summary["robot_file"]`` (or the plan's robot).
    dynamic : dict of column -> ndarray, or None
        The columns of ``dynamic.csv`` (:data:`DYNAMIC_COLUMNS`) of a run with dynamic
        compensation (summary.json key ``dynamic_compensation``); None otherwise.
    absent : dict of piece -> reason
        What the report could not show and why.
    """

    folder: Path
    summary: dict[str, Any]
    waypoints: dict[str, np.ndarray] | None = None
    branches: dict[str, np.ndarray] | None = None
    trajectories: dict[str, dict[str, np.ndarray | None]] = field(default_factory=dict)
    trajectory_files: dict[str, str] = field(default_factory=dict)
    robot: Robot | None = None
    dynamic: dict[str, np.ndarray] | None = None
    absent: dict[str, str] = field(default_factory=dict)


# ------------------------------------------------------------------------- from a plan result
def run_from_plan(res: "PlanResult", folder: str | Path) -> Run:
    """The view of a successful plan, from its in-memory result.

    Gives the same :class:`Run` as :func:`load_run` on the folder that
    :func:`planner.plan.write_outputs` writes from ``res``, without reading it.

    Parameters
    ----------
    res : PlanResult
    folder : str or Path
        The run's output folder (where the report goes).
    """
    from planner.plan import WAYPOINT_COLUMNS

    res.raise_for_status()
    summary = jsonable(res.summary())
    run = Run(Path(folder), summary, robot=res.problem.robot)
    run.waypoints = dict(zip(WAYPOINT_COLUMNS, res.waypoint_table().T))
    cols, data = res.branch_table()
    run.branches = dict(zip(cols, data.T))
    for name, method in _trajectory_files(summary):
        tr = res.trajectories.get(method)
        if tr is not None:
            _add_trajectory(run, method, name, _trajectory_arrays(tr))
    if not run.trajectories:
        run.absent.setdefault("trajectory", _NO_TRAJECTORY)
    stage = getattr(res, "dynamic", None)
    if stage is not None and getattr(stage, "link", None) is not None:
        cols, rows = stage.series(res.problem.model)
        run.dynamic = {c: np.asarray(rows[:, j], float) for j, c in enumerate(cols)}
    elif isinstance(summary.get(DYNAMIC_KEY), Mapping):
        run.absent["dynamic"] = _no_dynamic(summary)
    return run


def _dynamic_file(summary: Mapping[str, Any]) -> str:
    entry = summary.get(DYNAMIC_KEY)
    name = entry.get("file") if isinstance(entry, Mapping) else None
    return Path(name).name if isinstance(name, str) and name else "dynamic.csv"


def _no_dynamic(summary: Mapping[str, Any]) -> str:
    entry = summary.get(DYNAMIC_KEY)
    status = entry.get("status") if isinstance(entry, Mapping) else None
    return (f"dynamic compensation: {_dynamic_file(summary)} absent in this run"
            + (f" (stage status {status})" if status not in (None, "ok") else ""))


def _trajectory_arrays(tr: "Trajectory") -> dict[str, np.ndarray | None]:
    return {"t": tr.t, "q": tr.q, "qd": tr.qd, "qdd": tr.qdd, "qddd": tr.qddd}


def _add_trajectory(run: Run, method: str, name: str, tr: dict[str, np.ndarray | None]) -> None:
    """Record one method's trajectory, or why it is absent (no samples)."""
    if len(tr["t"]) == 0:                                        # type: ignore[arg-type]
        run.absent[f"trajectory {method}"] = f"{name} has no samples"
        return
    run.trajectories[method] = tr
    run.trajectory_files[method] = name


# ------------------------------------------------------------------------------ from a folder
def _read_csv(path: Path) -> dict[str, np.ndarray]:
    """Columns of a numeric CSV with a header row, as float arrays."""
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    if not rows:
        raise InputError(f"{path}: empty file; expected a header row and data rows")
    header = [h.strip() for h in rows[0]]
    data = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise InputError(f"{path}: line {i} has {len(row)} fields; expected {len(header)} "
                             "(as in the header)")
        for j, v in enumerate(row):
            try:
                data[i - 2, j] = float(v)
            except ValueError:
                raise InputError(f"{path}: line {i}, column {header[j]}: {v!r} is not a number") from None
    return {h: data[:, j] for j, h in enumerate(header)}


def _require(path: Path, cols: Mapping[str, np.ndarray], names: list[str]) -> np.ndarray:
    missing = [n for n in names if n not in cols]
    if missing:
        raise InputError(f"{path}: column(s) {', '.join(missing)} missing; expected the columns "
                         "written by compplan demo/plan (docs/cli.md)")
    return np.column_stack([cols[n] for n in names])


def _trajectory_files(summary: Mapping[str, Any], folder: Path | None = None) -> list[tuple[str, str]]:
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
                pairs.append((p.name, p.stem[len("trajectory_"):]))
    order = {m: i for i, m in enumerate(METHOD_NAMES)}
    return sorted(pairs, key=lambda fm: (order.get(fm[1], len(order)), fm[1]))


def _read_trajectory(path: Path) -> dict[str, np.ndarray | None]:
    """One ``trajectory*.csv``; ``qddd`` is None when the file has no jerk columns."""
    cols = _read_csv(path)
    jerk = None if not any(c in cols for c in _JERK_COLUMNS) else _require(path, cols, _JERK_COLUMNS)
    base = [c for c in TRAJECTORY_COLUMNS if c not in _JERK_COLUMNS]
    arr = _require(path, cols, base)
    return {"t": arr[:, 0], "q": arr[:, 1:7], "qd": arr[:, 7:13], "qdd": arr[:, 13:19],
            "qddd": jerk}


#: Values of ``summary.json``'s ``command`` key of the runs ``compplan report`` reports on.
RUN_COMMANDS = ("plan", "demo")


def _read_summary(folder: Path) -> dict[str, Any]:
    if not folder.is_dir():
        raise InputError(f"report: folder {str(folder)!r} does not exist; expected the output "
                         "folder of compplan demo or compplan plan")
    sp = folder / "summary.json"
    if not sp.is_file():
        raise InputError(f"report: {sp} not found; expected the output folder of compplan demo "
                         "or compplan plan")
    try:
        summary = json.loads(sp.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"report: {sp}: not valid JSON ({exc})") from None
    if not isinstance(summary, dict):
        raise InputError(f"report: {sp}: top level is {type(summary).__name__}; expected an object")
    command = summary.get("command")
    if command == "place":
        raise InputError(f"report: {sp} is a placement study's summary: compplan place writes its report itself "
                         "(run it again without --no-report)")
    if command not in RUN_COMMANDS:
        raise InputError(f"report: {sp}: 'command' is {command!r}, not one of {list(RUN_COMMANDS)}: this is not the "
                         "summary of a compplan plan or demo run (compplan report writes the report of such a folder)")
    return summary


def load_run(folder: str | Path) -> Run:
    """Read an output folder of ``compplan demo``/``plan``.

    Raises
    ------
    InputError
        The folder or its ``summary.json`` is missing or malformed, or a data
        file present in it is malformed (the message names file, line, column).
    """
    from planner.plan import WAYPOINT_COLUMNS

    folder = Path(folder)
    summary = _read_summary(folder)
    run = Run(folder, summary)

    wp = folder / "waypoints.csv"
    if wp.is_file():
        run.waypoints = _read_csv(wp)
        _require(wp, run.waypoints, list(WAYPOINT_COLUMNS))
    else:
        run.absent["waypoints"] = "waypoints.csv absent in this run"

    bp = folder / "branches.csv"
    if bp.is_file():
        run.branches = _read_csv(bp)
        _require(bp, run.branches, ["k"])
    else:
        run.absent["branches"] = "branches.csv absent in this run"

    for name, method in _trajectory_files(summary, folder):
        if (folder / name).is_file():
            _add_trajectory(run, method, name, _read_trajectory(folder / name))
    if not run.trajectories:
        run.absent["trajectory"] = _NO_TRAJECTORY

    if isinstance(summary.get(DYNAMIC_KEY), Mapping):
        dp = folder / _dynamic_file(summary)
        if dp.is_file():
            cols = _read_csv(dp)
            _require(dp, cols, list(DYNAMIC_COLUMNS))
            run.dynamic = {c: cols[c] for c in DYNAMIC_COLUMNS}
        else:
            run.absent["dynamic"] = _no_dynamic(summary)

    rf = summary.get("robot_file")
    if isinstance(rf, dict):
        try:
            run.robot = robot_from_dict(rf, where=f"{folder / 'summary.json'}: robot_file")
        except CompplanError as exc:
            run.absent["robot"] = f"robot_file in summary.json is unusable: {exc}"
    else:
        run.absent["robot"] = "summary.json has no robot_file"
    return run
