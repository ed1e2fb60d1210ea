"""The view of one run: the data the report needs, in SI units.

A :class:`Run` is built either from the in-memory result of a plan
(:func:`run_from_plan`, what ``compplan plan`` and ``compplan demo`` use right
after planning) or from the files of an output folder (:func:`load_run`, what
``compplan report DIR`` uses).  Both give the same view: ``summary`` is the
content of ``summary.json`` as JSON values (non-finite numbers are None; from a folder, every key
the report reads checked against its declaration, :mod:`planner.summary_schema`), the
waypoint, branch and trajectory tables hold the columns of ``waypoints.csv``,
``branches.csv`` and ``trajectory*.csv``, and a plan with dynamic compensation
(``[timing] dynamic = true``) the series of ``dynamic.csv``.  ``model`` is the arm model the
run was planned with (an identified model's, not its robot file's): the plan's own object, or
from a folder the model file its summary records, read again after checking its SHA-256.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any
from collections.abc import Mapping

import numpy as np

from models import Robot, robot_from_dict
from models.arm import ArmModel
from models.errors import CompplanError, InputError

from planner.output import TRAJECTORY_COLUMNS, jsonable
from planner.summary_schema import read_summary
from planner.summary_specs import MAGNITUDE_MAX

if TYPE_CHECKING:
    from planner.plan import PlanResult, RunView
    from problems.timing import Trajectory

#: The trajectory files of runs whose summary.json has no ``timing.<method>.file`` (made before
#: a plan named the file of each method there; their ``trajectory.csv`` was Ruckig's).
TRAJECTORY_FILES = (("trajectory_toppra.csv", "toppra"), ("trajectory.csv", "ruckig"))


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
    model : ArmModel or None
        The arm model the run was planned with, which the compliance map and the arm figure
        draw: the plan's own (:func:`run_from_plan`), or from a folder the identified model
        file ``summary["model"]`` records, read again and checked against its SHA-256
        (:func:`recorded_model`), else the nominal model of ``robot``.  None when it cannot be
        known (``absent["model"]`` or ``absent["robot"]`` says why).
    dynamic : dict of column -> ndarray, or None
        The columns of ``dynamic.csv`` (:data:`DYNAMIC_COLUMNS`) of a run with dynamic
        compensation (summary.json key ``dynamic_compensation``); None otherwise.
    program : planner.report.toolpath.ProgramView or None
        A program path's waypoints in the program frame, lines, rapids, feeds and the program line
        of each sample (summary.json key ``program``); None otherwise.
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
    model: ArmModel | None = None
    dynamic: dict[str, np.ndarray] | None = None
    program: Any = None
    absent: dict[str, str] = field(default_factory=dict)


# ------------------------------------------------------------------------- from a plan result
def run_from_plan(res: PlanResult, folder: str | Path, view: RunView | None = None) -> Run:
    """The view of a successful plan, from its in-memory result.

    Gives the same :class:`Run` as :func:`load_run` on the folder that
    :func:`planner.plan.write_outputs` writes from ``res``, without reading it, with the
    plan's own arm model (``res.problem.model``).

    Parameters
    ----------
    res : PlanResult
    folder : str or Path
        The run's output folder (where the report goes).
    view : RunView, optional
        The plan's summary and tables (:meth:`~planner.plan.PlanResult.view`) when the caller
        has them; else they are computed here.
    """
    from planner.plan import WAYPOINT_COLUMNS

    view = res.view() if view is None else view
    assert view.result is res, "the view of another plan"
    summary = jsonable(view.summary)
    run = Run(Path(folder), summary, robot=res.problem.robot, model=view.model)
    run.waypoints = dict(zip(WAYPOINT_COLUMNS, view.waypoints.T))
    run.branches = dict(zip(view.branch_columns, view.branches.T))
    for name, method in _trajectory_files(summary):
        tr = res.trajectories.get(method)
        if tr is not None:
            _add_trajectory(run, method, name, _trajectory_arrays(tr))
    if not run.trajectories:
        run.absent.setdefault("trajectory", _NO_TRAJECTORY)
    from planner.report.toolpath import program_from_plan

    run.program = program_from_plan(res, summary)
    if view.dynamic is not None:
        cols, rows = view.dynamic
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
    return f"dynamic compensation: {_dynamic_file(summary)} absent in this run" + (
        f" (stage status {status})" if status not in (None, "ok") else ""
    )


def _trajectory_arrays(tr: Trajectory) -> dict[str, np.ndarray | None]:
    return {"t": tr.t, "q": tr.q, "qd": tr.qd, "qdd": tr.qdd, "qddd": tr.qddd}


def _add_trajectory(run: Run, method: str, name: str, tr: dict[str, np.ndarray | None]) -> None:
    """Record one method's trajectory, or why it is absent (no samples)."""
    if len(tr["t"]) == 0:  # type: ignore[arg-type]
        run.absent[f"trajectory {method}"] = f"{name} has no samples"
        return
    run.trajectories[method] = tr
    run.trajectory_files[method] = name


# ------------------------------------------------------------------------------ from a folder
#: Columns checked by name in every CSV file of a run the report reads (what
#: :func:`planner.plan.write_outputs` writes there): the time column (s, >= 0, strictly increasing),
#: the whole-number columns (waypoint index, program line, row of path.csv), the 0/1 columns, and
#: the columns of magnitudes (>= 0; m, m/s, mm/min).
TIME_COLUMN = "t"
INDEX_COLUMNS = ("k", "line", "waypoint")
FLAG_COLUMNS = ("rapid", "moving")
MAGNITUDE_COLUMNS = ("e_none_m", "e_static_m", "e_static_dynamic_m", "tcp_speed_m_s", "feed_mm_min")
#: The columns of a file that may hold NaN, "none" (``"*"``: every column but the indices): a branch
#: without a posture at a waypoint, the feed of a rapid and of waypoint 0.  Every other cell of
#: every file must be a finite number (a trajectory's samples, the waypoints, dynamic.csv, ...).
NAN_COLUMNS: dict[str, tuple[str, ...] | str] = {"branches.csv": "*", "path.csv": ("feed_mm_min",)}


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    """Columns of a numeric CSV with a header row, as float arrays, checked by :func:`_check_columns`."""
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{path}: not a readable CSV file ({exc})") from None
    if not rows:
        raise InputError(f"{path}: empty file; expected a header row and data rows")
    header = [h.strip() for h in rows[0]]
    data = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise InputError(f"{path}: line {i} has {len(row)} fields; expected {len(header)} (as in the header)")
        for j, v in enumerate(row):
            try:
                data[i - 2, j] = float(v)
            except ValueError:
                raise InputError(f"{path}: line {i}, column {header[j]}: {v!r} is not a number") from None
    cols = {h: data[:, j] for j, h in enumerate(header)}
    _check_columns(path, cols)
    return cols


def _check_columns(path: Path, cols: Mapping[str, np.ndarray]) -> None:
    """Refuse a cell that is infinite or above :data:`~planner.summary_specs.MAGNITUDE_MAX`, or NaN
    outside :data:`NAN_COLUMNS`; a time column that is negative or does not increase, an index that
    is not a whole number >= 0, a flag not 0 or 1, a negative magnitude (:data:`TIME_COLUMN`, ...).
    The message names the file, the line (the header is line 1), the column and the value."""

    def refuse(col: str, bad: np.ndarray, expected: str) -> None:
        if np.any(bad):
            i = int(np.argmax(bad))
            raise InputError(f"{path}: line {i + 2}, column {col}: {float(cols[col][i])!r}; expected {expected}")

    nan_ok = NAN_COLUMNS.get(path.name, ())
    for col, v in cols.items():
        ruled = col == TIME_COLUMN or col in INDEX_COLUMNS or col in FLAG_COLUMNS
        may_be_nan = not ruled and (nan_ok == "*" or col in nan_ok)
        refuse(
            col,
            (np.abs(v) > MAGNITUDE_MAX) | (np.isnan(v) & (not may_be_nan)),
            f"a finite number, at most {MAGNITUDE_MAX:g} in magnitude",
        )
        if col == TIME_COLUMN:
            refuse(col, v < 0.0, "a time >= 0 s")
            refuse(col, np.r_[False, np.diff(v) <= 0.0], "a time after the previous line's (increasing)")
        elif col in INDEX_COLUMNS:
            refuse(col, (v < 0) | (v != np.round(v)), "a whole number >= 0")
        elif col in FLAG_COLUMNS:
            refuse(col, (v != 0.0) & (v != 1.0), "0 or 1")
        elif col in MAGNITUDE_COLUMNS:
            refuse(col, v < 0.0, "a number >= 0")


def _require(path: Path, cols: Mapping[str, np.ndarray], names: list[str]) -> np.ndarray:
    missing = [n for n in names if n not in cols]
    if missing:
        raise InputError(
            f"{path}: column(s) {', '.join(missing)} missing; expected the columns "
            "written by compplan demo/plan (docs/cli.md)"
        )
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
                pairs.append((p.name, p.stem[len("trajectory_") :]))
    order = {m: i for i, m in enumerate(method_order())}
    return sorted(pairs, key=lambda fm: (order.get(fm[1], len(order)), fm[1]))


def _read_trajectory(path: Path) -> dict[str, np.ndarray | None]:
    """One ``trajectory*.csv`` (every cell finite, times increasing from >= 0); ``qddd`` is None
    when the file has no jerk columns."""
    cols = _read_csv(path)
    jerk = None if not any(c in cols for c in _JERK_COLUMNS) else _require(path, cols, _JERK_COLUMNS)
    base = [c for c in TRAJECTORY_COLUMNS if c not in _JERK_COLUMNS]
    arr = _require(path, cols, base)
    out = {"t": arr[:, 0], "q": arr[:, 1:7], "qd": arr[:, 7:13], "qdd": arr[:, 13:19], "qddd": jerk}
    for c in ("line", "waypoint"):  # a program path's (taken into Run.program by load_run)
        if c in cols:
            out[c] = cols[c]
    return out


#: Largest difference between a method's ``duration_s`` in summary.json and the time span of its
#: trajectory file, s: both are written from the same floats at full precision (1 µs allows a file
#: rewritten with fewer digits; a tampered duration or another run's file differs by far more).
DURATION_TOL_S = 1e-6


def _read_summary(folder: Path) -> dict[str, Any]:
    """``summary.json`` of a run folder, every key the report reads checked
    (:func:`planner.summary_schema.read_summary`)."""
    if not folder.is_dir():
        raise InputError(
            f"report: folder {str(folder)!r} does not exist; expected the output "
            "folder of compplan demo or compplan plan"
        )
    return read_summary(folder, "report")


def load_run(folder: str | Path) -> Run:
    """Read an output folder of ``compplan demo``/``plan``.

    Raises
    ------
    InputError
        The folder or its ``summary.json`` is missing or malformed (a key that does not fit its
        declaration, :func:`planner.summary_schema.read_summary`: the message names the key), a
        data file present in it is malformed (the message names file, line, column: see
        :func:`_check_columns`), or a method's ``duration_s`` is not its trajectory file's.
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

    _read_trajectories(run)
    from planner.report.toolpath import program_from_folder

    run.program = program_from_folder(run)
    _check_sample_waypoints(run)

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
    if run.robot is not None:
        run.model = recorded_model(summary, run.robot, folder / "summary.json", run.absent)
    return run


def _read_trajectories(run: Run) -> None:
    """The trajectory files of a run folder, each against its ``duration_s`` in the summary; a
    file the summary names (``timing.<method>.file``) but the folder lacks is stated absent."""
    summary, folder = run.summary, run.folder
    timing = summary.get("timing") if isinstance(summary.get("timing"), Mapping) else {}
    named = {m for m, info in timing.items() if isinstance(info, Mapping) and "file" in info}
    durations = summary.get("duration_s") if isinstance(summary.get("duration_s"), Mapping) else {}
    for name, method in _trajectory_files(summary, folder):
        path = folder / name
        if not path.is_file():
            if method in named:
                run.absent[f"trajectory {method}"] = f"{name} (timing.{method}.file in summary.json) absent in this run"
            continue
        tr = _read_trajectory(path)
        t = tr["t"]
        d = durations.get(method)
        span = float(t[-1] - t[0]) if len(t) else None  # type: ignore[index]
        if d is not None and span is not None and abs(d - span) > DURATION_TOL_S:
            raise InputError(
                f"report: {folder / 'summary.json'}: duration_s.{method} = {d!r} s, but {name} spans {span!r} s "
                f"(t from {float(t[0])!r} to {float(t[-1])!r}); expected the duration of that file: the summary "
                "and the trajectory are not of the same run"
            )
        _add_trajectory(run, method, name, tr)
    if not run.trajectories:
        run.absent["trajectory"] = _NO_TRAJECTORY


def _check_sample_waypoints(run: Run) -> None:
    """A program path's ``waypoint`` column of each trajectory file must name rows of path.csv."""
    view = run.program
    if view is None:
        return
    for method, k in view.sample_waypoint.items():
        bad = np.asarray(k) >= view.n
        if np.any(bad):
            i = int(np.argmax(bad))
            raise InputError(
                f"{run.folder / run.trajectory_files.get(method, 'trajectory.csv')}: line {i + 2}, column waypoint: "
                f"{int(k[i])}; expected a row of path.csv (0 to {view.n - 1})"
            )


def recorded_model(summary: Mapping[str, Any], robot: Robot, where: Path, absent: dict[str, str]) -> ArmModel | None:
    """The arm model a run was planned with, from its ``summary.json`` (``where``).

    A nominal model (``summary["model"]["identified"]`` false) is the one of the recorded
    ``robot`` (``robot_file``).  An identified model is read again from the model file the
    summary records (``model.file``), after checking the file's SHA-256 against ``model.sha256``,
    and given the run's tool.  An identified model without a recorded file (built in memory) is
    None, with the reason in ``absent["model"]``: its maps cannot be drawn from the nominal robot.

    Raises
    ------
    InputError
        The recorded model file is missing or no longer the file the run was planned with
        (the message names the file, both SHA-256 and what to do).
    """
    md = summary.get("model")
    if not isinstance(md, Mapping) or not md.get("identified"):
        return ArmModel.from_robot(robot)
    path, sha = md.get("file"), md.get("sha256")
    if not isinstance(path, str) or not path or not isinstance(sha, str) or not sha:
        absent["model"] = (
            "the run was planned with an identified arm model that has no file (model.file in "
            "summary.json is empty: built in memory), so the compliance map and the arm are not "
            "drawn (the nominal robot is not the model the run used)"
        )
        return None
    import hashlib

    from models.arm_file import load_model

    again = (
        f"restore the model file the run was planned with at {path}, or plan again with the model as it "
        f"is now (compplan plan PROBLEM --robot MODEL --out {where.parent}) and report on that run"
    )
    try:
        actual = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as exc:
        raise InputError(
            f"report: {where}: model.file {path!r} (SHA-256 {sha}), the identified arm model the run "
            f"was planned with, cannot be read ({exc.strerror}: moved or deleted?); {again}"
        ) from None
    if actual != sha:
        raise InputError(
            f"report: {where}: the identified arm model file {path} has changed since the run was "
            f"planned: SHA-256 recorded in model.sha256 {sha}, the file's now {actual}; {again}"
        )
    return load_model(path).with_tool(robot.tcp2flange)
