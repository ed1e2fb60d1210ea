"""Reading a run folder into its :class:`~planner.record.record.RunRecord`.

:func:`read_record` reads ``summary.json`` (every key its readers read checked against its
declaration, :func:`planner.summary_schema.read_summary`) and the CSV files beside it, each cell
checked by its column (:func:`check_columns`), a program path's columns of ``path.csv``
(:func:`program_from_folder`) and, for a run planned with an identified arm model, the model file
its summary records, checked against its SHA-256 (:func:`recorded_model`).  A piece the folder
lacks is stated in ``RunRecord.absent``; a malformed one is an :class:`~models.errors.InputError`
naming the file, line, column and value.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from models import Robot, robot_from_dict
from models.arm import ArmModel
from models.errors import CompplanError, InputError

from planner.record.columns import (
    CUT_COLUMNS,
    CUT_FILE,
    CUT_KEY,
    CUT_STOCK_FILE,
    DYNAMIC_COLUMNS,
    DYNAMIC_KEY,
    FLAG_COLUMNS,
    INDEX_COLUMNS,
    JERK_COLUMNS,
    MAGNITUDE_COLUMNS,
    NAN_COLUMNS,
    PROGRAM_KEY,
    TIME_COLUMN,
    TRAJECTORY_COLUMNS,
    WAYPOINT_COLUMNS,
)
from planner.record.record import (
    NO_TRAJECTORY,
    ProgramRecord,
    RunRecord,
    add_trajectory,
    dynamic_file,
    no_dynamic,
    program_record,
    trajectory_files,
)
from planner.summary_schema import read_summary
from models.tables.kinds import MAGNITUDE_MAX

__all__ = [
    "read_csv",
    "read_record",
    "read_run_summary",
    "read_trajectory",
    "recorded_model",
]

#: ``path.csv``'s position columns and its program columns
#: (:data:`~planner.record.columns.PROGRAM_PATH_COLUMNS`).
PATH_POSITION = ("x", "y", "z")
PATH_PROGRAM = ("feed_mm_min", "line", "rapid")


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """Columns of a numeric CSV with a header row, as float arrays, checked by :func:`check_columns`."""
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
    check_columns(path, cols)
    return cols


def check_columns(path: Path, cols: Mapping[str, np.ndarray]) -> None:
    """Refuse a cell that is infinite or above :data:`~models.tables.kinds.MAGNITUDE_MAX`, or NaN
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


def require(path: Path, cols: Mapping[str, np.ndarray], names: list[str]) -> np.ndarray:
    missing = [n for n in names if n not in cols]
    if missing:
        raise InputError(
            f"{path}: column(s) {', '.join(missing)} missing; expected the columns "
            "written by compplan demo/plan (docs/cli.md)"
        )
    return np.column_stack([cols[n] for n in names])


def read_trajectory(path: Path) -> dict[str, np.ndarray | None]:
    """One ``trajectory*.csv`` (every cell finite, times increasing from >= 0); ``qddd`` is None
    when the file has no jerk columns."""
    cols = read_csv(path)
    jerk = None if not any(c in cols for c in JERK_COLUMNS) else require(path, cols, JERK_COLUMNS)
    base = [c for c in TRAJECTORY_COLUMNS if c not in JERK_COLUMNS]
    arr = require(path, cols, base)
    out = {"t": arr[:, 0], "q": arr[:, 1:7], "qd": arr[:, 7:13], "qdd": arr[:, 13:19], "qddd": jerk}
    for c in ("line", "waypoint"):  # a program path's (taken into RunRecord.program by read_record)
        if c in cols:
            out[c] = cols[c]
    return out


#: Largest difference between a method's ``duration_s`` in summary.json and the time span of its
#: trajectory file, s: both are written from the same floats at full precision (1 µs allows a file
#: rewritten with fewer digits; a tampered duration or another run's file differs by far more).
DURATION_TOL_S = 1e-6


def read_run_summary(folder: Path) -> dict[str, Any]:
    """``summary.json`` of a run folder, every key the report reads checked
    (:func:`planner.summary_schema.read_summary`)."""
    if not folder.is_dir():
        raise InputError(
            f"report: folder {str(folder)!r} does not exist; expected the output "
            "folder of compplan demo or compplan plan"
        )
    return read_summary(folder, "report")


def read_record(folder: str | Path) -> RunRecord:
    """Read an output folder of ``compplan demo``/``plan``.

    Raises
    ------
    InputError
        The folder or its ``summary.json`` is missing or malformed (a key that does not fit its
        declaration, :func:`planner.summary_schema.read_summary`: the message names the key), a
        data file present in it is malformed (the message names file, line, column: see
        :func:`check_columns`), or a method's ``duration_s`` is not its trajectory file's.
    """
    folder = Path(folder)
    summary = read_run_summary(folder)
    run = RunRecord(folder, summary)

    wp = folder / "waypoints.csv"
    if wp.is_file():
        run.waypoints = read_csv(wp)
        require(wp, run.waypoints, list(WAYPOINT_COLUMNS))
    else:
        run.absent["waypoints"] = "waypoints.csv absent in this run"

    bp = folder / "branches.csv"
    if bp.is_file():
        run.branches = read_csv(bp)
        require(bp, run.branches, ["k"])
    else:
        run.absent["branches"] = "branches.csv absent in this run"

    read_trajectories(run)
    run.program = program_from_folder(run)
    check_sample_waypoints(run)

    if isinstance(summary.get(DYNAMIC_KEY), Mapping):
        dp = folder / dynamic_file(summary)
        if dp.is_file():
            cols = read_csv(dp)
            require(dp, cols, list(DYNAMIC_COLUMNS))
            run.dynamic = {c: cols[c] for c in DYNAMIC_COLUMNS}
        else:
            run.absent["dynamic"] = no_dynamic(summary)

    if isinstance(summary.get(CUT_KEY), Mapping):
        read_cut(run)

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


def read_cut(run: RunRecord) -> None:
    """``cut.csv`` and ``cut_stock.npz`` of a run whose load is a predicted cut (absent: said why)."""
    cp = run.folder / CUT_FILE
    if cp.is_file():
        cols = read_csv(cp)
        require(cp, cols, list(CUT_COLUMNS))
        check_cut(cp, cols, run)
        run.cut = {c: cols[c] for c in CUT_COLUMNS}
    else:
        run.absent["cut"] = f"{CUT_FILE} absent in this run"
    sp = run.folder / CUT_STOCK_FILE
    if not sp.is_file():
        run.absent["cut_stock"] = f"{CUT_STOCK_FILE} absent in this run"
        return
    try:
        with np.load(sp, allow_pickle=False) as z:
            stock = {k: np.asarray(z[k], dtype=float) for k in ("before", "after", "extent")}
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{sp}: not a stock file (arrays before, after, extent): {exc}") from None
    if stock["before"].ndim != 2 or stock["before"].shape != stock["after"].shape or stock["extent"].shape != (4,):
        raise InputError(f"{sp}: before/after must be two 2-D arrays of one shape and extent 4 numbers")
    run.cut_stock = stock


def check_cut(path: Path, cols: Mapping[str, np.ndarray], run: RunRecord) -> None:
    """Refuse a ``cut.csv`` whose rows are not the program's waypoints or whose ``milling`` is not an
    index into summary.json ``cut.milling_codes``."""
    n = len(cols["line"])
    if run.program is not None and n != run.program.n:
        raise InputError(f"{path}: {n} rows; expected one per waypoint of the program ({run.program.n}, path.csv)")
    codes = run.summary[CUT_KEY].get("milling_codes")
    if isinstance(codes, list) and codes:
        bad = (cols["milling"] < 0) | (cols["milling"] >= len(codes)) | (cols["milling"] != np.round(cols["milling"]))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise InputError(
                f"{path}: line {i + 2}, column milling: {float(cols['milling'][i])!r}; expected a whole number "
                f"from 0 to {len(codes) - 1} (an index into summary.json cut.milling_codes)"
            )


def read_trajectories(run: RunRecord) -> None:
    """The trajectory files of a run folder, each against its ``duration_s`` in the summary; a
    file the summary names (``timing.<method>.file``) but the folder lacks is stated absent."""
    summary, folder = run.summary, run.folder
    timing = summary.get("timing") if isinstance(summary.get("timing"), Mapping) else {}
    named = {m for m, info in timing.items() if isinstance(info, Mapping) and "file" in info}
    durations = summary.get("duration_s") if isinstance(summary.get("duration_s"), Mapping) else {}
    for name, method in trajectory_files(summary, folder):
        path = folder / name
        if not path.is_file():
            if method in named:
                run.absent[f"trajectory {method}"] = f"{name} (timing.{method}.file in summary.json) absent in this run"
            continue
        tr = read_trajectory(path)
        t = tr["t"]
        d = durations.get(method)
        span = float(t[-1] - t[0]) if len(t) else None  # type: ignore[index]
        if d is not None and span is not None and abs(d - span) > DURATION_TOL_S:
            raise InputError(
                f"report: {folder / 'summary.json'}: duration_s.{method} = {d!r} s, but {name} spans {span!r} s "
                f"(t from {float(t[0])!r} to {float(t[-1])!r}); expected the duration of that file: the summary "
                "and the trajectory are not of the same run"
            )
        add_trajectory(run, method, name, tr)
    if not run.trajectories:
        run.absent["trajectory"] = NO_TRAJECTORY


def check_sample_waypoints(run: RunRecord) -> None:
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


def program_from_folder(run: RunRecord) -> ProgramRecord | None:
    """The program record of a run read from its folder (None for a path that is not a program).

    Reads ``path.csv``'s program columns and takes the ``line`` column of each trajectory read into
    ``run.trajectories`` (removing it there, as in the record of a plan).  A missing or malformed
    ``path.csv`` leaves the record None with the reason in ``run.absent["program"]``.
    """
    lines = {m: tr.pop("line", None) for m, tr in run.trajectories.items()}
    waypoints = {m: tr.pop("waypoint", None) for m, tr in run.trajectories.items()}
    if not isinstance(run.summary.get(PROGRAM_KEY), Mapping):
        return None
    path = Path(run.folder) / "path.csv"
    if not path.is_file():
        run.absent[PROGRAM_KEY] = "program path: path.csv absent in this run (the toolpath and feed are not drawn)"
        return None
    cols = read_csv(path)
    missing = [c for c in PATH_POSITION + PATH_PROGRAM if c not in cols]
    if missing:
        run.absent[PROGRAM_KEY] = (
            f"program path: {path.name} has no column(s) {', '.join(missing)} (written before programs were "
            "planned?): the toolpath and feed are not drawn"
        )
        return None
    base = np.column_stack([cols[c] for c in PATH_POSITION])
    view = program_record(run.summary, base, cols["feed_mm_min"], cols["line"], cols["rapid"])
    view.sample_line = {m: np.asarray(v).astype(int) for m, v in lines.items() if v is not None}
    view.sample_waypoint = {m: np.asarray(v).astype(int) for m, v in waypoints.items() if v is not None}
    return view
