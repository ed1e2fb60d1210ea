"""Where an export's :class:`~planner.export.data.ExportData` comes from: a plan in memory
(:func:`data_from_plan`) or a run folder (:func:`data_from_run`: its ``summary.json`` and
``trajectory.csv``), each checked by :func:`~planner.export.limits.verify_limits`."""

from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from planner.export.data import ExportData, program_name
from planner.export.errors import ExportError
from planner.export.limits import verify_limits

__all__ = ["data_from_plan", "data_from_run"]


#: The rate limits a timing method enforces when a run's summary does not say (older runs).
_DEFAULT_ENFORCED = ("velocity", "acceleration", "jerk")


def data_from_plan(res: Any) -> ExportData:
    """The controller's trajectory of a :class:`~planner.plan.PlanResult` (in memory), checked
    by :func:`verify_limits`."""
    from problems.timing import get_method

    pr = res.problem
    if res.controller is None or res.controller not in res.trajectories:
        raise ExportError("export: the plan has no timed trajectory (the plan stopped before timing)")
    tr = res.trajectories[res.controller]
    if not tr.status.ok or not res.ok:
        raise ExportError(
            f"export: the trajectory is not ok (plan {res.status.value}, {res.controller} "
            f"{tr.status.value}: {tr.reason}); refusing to export it"
        )
    r, lim = pr.robot, pr.limits
    data = ExportData(
        name=program_name(pr.name),
        robot=r.name,
        joint_names=_names(r.joint_names),
        t=tr.t,
        q=tr.q,
        qd=tr.qd,
        qdd=tr.qdd,
        qddd=tr.qddd,
        dt=tr.dt,
        v_max=_vec6(lim.velocity),
        a_max=_vec6(lim.acceleration),
        j_max=_vec6(lim.jerk),
        q_min=_vec6(r.q_min),
        q_max=_vec6(r.q_max),
        enforced=tuple(get_method(res.controller).checked_limits),
        sign=np.asarray(r.controller_sign, float),
        offset=np.asarray(r.controller_offset, float),
        controller_declared=bool(r.controller_declared),
        source=f"problem {pr.name}",
        program=_program_name(getattr(pr, "program", None)),
        robot_v_max=_vec6(r.v_max),
        robot_a_max=_vec6(r.a_max),
        robot_j_max=_vec6(r.j_max),
    )
    verify_limits(data, f"export of problem {pr.name} ({res.controller})")
    return data


def _program_name(program: Any) -> str:
    """The file name of a problem's CAM program (its ``program`` section), or "" for another task."""
    if program is None:
        return ""
    return Path(str(getattr(program, "file", "") or "program")).name


def _vec6(v: Any) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(6)


def _names(names: Any) -> tuple[str, ...]:
    return tuple(str(n) for n in names) if names else tuple(f"joint_{i}" for i in range(1, 7))


def _summary(folder: Path) -> dict[str, Any]:
    summary = folder / "summary.json"
    if not folder.is_dir():
        raise ExportError(f"RUN_DIR {folder}: no such folder; expected the output folder of compplan plan or demo")
    if not summary.is_file():
        raise ExportError(f"RUN_DIR {folder}: no summary.json; expected the output folder of compplan plan or demo")
    try:
        s = json.loads(summary.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ExportError(f"{summary}: not readable JSON ({exc})") from None
    if not isinstance(s, dict) or s.get("command") not in (None, "plan", "demo"):
        raise ExportError(
            f"{summary}: not the summary of a plan (key 'command' = {s.get('command')!r} "
            "if a dict); expected the output folder of compplan plan or demo"
        )
    return s


def _limit(summary: Path, lim: dict[str, Any], key: str) -> np.ndarray:
    v = lim.get(key)
    try:
        a = np.asarray(v, dtype=float).reshape(6)
    except (TypeError, ValueError):
        raise ExportError(f"{summary}: limits.{key} = {v!r}; expected 6 numbers") from None
    if np.any(np.isnan(a)):
        raise ExportError(f"{summary}: limits.{key} = {v!r}; expected 6 numbers")
    return a


def data_from_run(folder: str | Path) -> ExportData:
    """The controller's trajectory of a run folder (``summary.json`` and its ``trajectory.csv``),
    checked by :func:`verify_limits`."""
    folder = Path(folder)
    s = _summary(folder)
    summary = folder / "summary.json"
    ctrl = s.get("controller_trajectory")
    timing = (s.get("timing") or {}).get(ctrl or "", {})
    if not ctrl or not timing:
        raise ExportError(f"{summary}: the run has no controller trajectory (key 'controller_trajectory')")
    if s.get("plan_status") != "ok" or timing.get("status") != "ok":
        raise ExportError(
            f"{summary}: the trajectory is not ok (plan_status {s.get('plan_status')!r}, {ctrl} "
            f"status {timing.get('status')!r}: {timing.get('reason', '')}); refusing to export it"
        )
    path = folder / str(timing.get("file", "trajectory.csv"))
    t, q, qd, qdd, qddd, link_q = _read_trajectory(path)
    rf = s.get("robot_file") or {}
    ctrl_map = rf.get("controller") or {}
    lim = s.get("limits") or {}
    data = ExportData(
        name=program_name(str((s.get("problem") or {}).get("name", folder.name))),
        robot=str(rf.get("name", s.get("robot", "robot"))),
        joint_names=_names(rf.get("joint_names")),
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        qddd=qddd,
        dt=float(timing.get("dt") or (t[1] - t[0])),
        v_max=_limit(summary, lim, "velocity"),
        a_max=_limit(summary, lim, "acceleration"),
        j_max=_limit(summary, lim, "jerk"),
        q_min=_limit(summary, lim, "q_min"),
        q_max=_limit(summary, lim, "q_max"),
        enforced=tuple(timing.get("limits_enforced") or _DEFAULT_ENFORCED),
        sign=np.asarray(ctrl_map.get("joint_sign", [1] * 6), float),
        offset=np.asarray(ctrl_map.get("joint_offset", [0.0] * 6), float),
        controller_declared="controller" in rf,
        source=f"run {folder}",
        inputs=(summary, path),
        link_q=link_q,
        program=_run_program(s),
        **_robot_limits(summary, rf),
    )
    verify_limits(data, str(path))
    return data


def _robot_limits(summary: Path, rf: dict[str, Any]) -> dict[str, np.ndarray | None]:
    """The robot's own rate limits as a run recorded its robot (``robot_file.joints[i].v_max``,
    ``a_max``, ``j_max``: the robot file's, before the problem's ``[limits]``), as the
    ``robot_*_max`` fields of :class:`ExportData`; all None for a summary without ``robot_file``
    (the plan's limits are then the controller's)."""
    joints = rf.get("joints") if isinstance(rf, dict) else None
    if joints is None:
        return {}
    if not isinstance(joints, list) or len(joints) != 6 or not all(isinstance(j, dict) for j in joints):
        raise ExportError(f"{summary}: robot_file.joints = {str(joints)[:60]!r}; expected 6 joint tables")
    out: dict[str, np.ndarray | None] = {}
    for key in ("v_max", "a_max", "j_max"):
        vals = []
        for i, j in enumerate(joints):
            v = j.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
                raise ExportError(f"{summary}: robot_file.joints[{i}].{key} = {v!r}; expected a number > 0")
            vals.append(float(v))
        out[f"robot_{key}"] = np.asarray(vals)
    return out


def _run_program(s: dict[str, Any]) -> str:
    """The file name of the CAM program a run's plan ran at its feed (``program.file`` of its
    summary), or "" for another task."""
    prog = s.get("program")
    if not isinstance(prog, dict):
        return ""
    return Path(str(prog.get("file") or "program")).name


def _read_trajectory(path: Path) -> tuple[np.ndarray, ...]:
    """``t, q, qd, qdd, qddd`` of a ``trajectory*.csv`` (columns by name, any order), and the link
    side ``ql1..ql6`` when the file has it (else None).

    The numbers are parsed by :func:`numpy.loadtxt` (C parser, exact round trip of the written
    floats, no per-cell Python objects: a 10^6-sample file reads in seconds in the size of its
    array); a file it cannot parse is read again row by row for a message naming the bad row.
    """
    if not path.is_file():
        raise ExportError(f"{path}: no such trajectory file")
    try:
        with path.open(newline="", encoding="utf-8") as f:
            head = None
            for line in f:
                if line.strip() and not line.startswith("#"):
                    head = [h.strip() for h in next(csv.reader([line]))]
                    break
            if head is None:
                raise ExportError(f"{path}: empty; expected a header row and samples")
            need, has_link = _columns(path, head)
            try:
                with warnings.catch_warnings():  # "input contained no data": refused below
                    warnings.simplefilter("ignore", UserWarning)
                    a = np.loadtxt(f, delimiter=",", comments="#", usecols=[head.index(c) for c in need], ndmin=2)
            except ValueError:
                a = None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ExportError(f"{path}: not a readable CSV file ({exc})") from None
    if a is None or a.shape[1] != len(need):
        a = _read_rows(path, need)
    if a.shape[0] < 2 or not np.all(np.isfinite(a)):
        raise ExportError(f"{path}: expected at least 2 rows of finite numbers")
    return a[:, 0], a[:, 1:7], a[:, 7:13], a[:, 13:19], a[:, 19:25], (a[:, 25:31] if has_link else None)


def _columns(path: Path, head: list[str]) -> tuple[list[str], bool]:
    """The columns to read (``t``, ``q*``, ``qd*``, ``qdd*``, ``qddd*``, and ``ql*`` when all six are
    there) and whether the link side is among them (the run record's columns,
    :mod:`planner.record.columns`)."""
    from planner.record.columns import LINK_COLUMNS, TRAJECTORY_COLUMNS

    need = list(TRAJECTORY_COLUMNS)
    missing = [c for c in need if c not in head]
    if missing:
        raise ExportError(f"{path}: missing column(s) {', '.join(missing)}")
    link = LINK_COLUMNS
    has_link = all(c in head for c in link)
    return need + (link if has_link else []), has_link


def _read_rows(path: Path, need: list[str]) -> np.ndarray:
    """The columns ``need`` row by row (the slow path: its messages name the bad row)."""
    try:
        with path.open(newline="", encoding="utf-8") as f:
            rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ExportError(f"{path}: not a readable CSV file ({exc})") from None
    head = [h.strip() for h in rows[0]]
    cols = [head.index(c) for c in need]
    a = np.empty((len(rows) - 1, len(need)))
    for n, r in enumerate(rows[1:]):
        try:
            a[n] = [float(r[c]) for c in cols]
        except (ValueError, IndexError):
            raise ExportError(f"{path}: row {n + 2} is not {len(head)} numbers: {','.join(r)[:80]!r}") from None
    return a
