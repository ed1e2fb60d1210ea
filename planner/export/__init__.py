"""Trajectories a controller can run: URScript, ROS 2, ABB RAPID, KUKA KRL.

One module per format registers an :class:`ExportFormat` (extend by adding a file). Every
format reads an :class:`ExportData`: the controller's trajectory of a plan (``trajectory.csv``:
joint positions, velocities and accelerations at the controller period), the robot's joint
names and the mapping from the model's joint angles to the controller's
(``controller_angle = sign * q + offset``, ``[controller]`` of the robot file), built from a
plan in memory (:func:`data_from_plan`) or from a run folder (:func:`data_from_run`).
A trajectory whose status is not ``ok`` is refused (:class:`ExportError`).  Conventions
of each vendor (joint order, units, signs, zeros): ``docs/export.md``.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from models.errors import InputError

__all__ = ["EXPORT_FORMATS", "ExportData", "ExportError", "ExportFormat", "data_from_plan", "data_from_run",
           "export_files", "formats", "register_format"]


class ExportError(InputError):
    """The trajectory cannot be exported (not ok, no trajectory, a bad option); the message says why."""


@dataclass(frozen=True)
class ExportData:
    """What every export format writes (SI units, the model's joint convention).

    Attributes
    ----------
    name : str
        Program name (letters, digits, underscores).
    robot : str
    joint_names : tuple of str, length 6
    t : ndarray, shape (M,)
        Sample times, s, from 0 at the controller period ``dt``.
    q, qd, qdd : ndarray, shape (M, 6)
        Joint positions (rad), velocities (rad/s), accelerations (rad/s^2), model convention.
    dt : float
        The trajectory's sample period, s.
    v_max, a_max : ndarray, shape (6,)
        The robot's velocity (rad/s) and acceleration (rad/s^2) limits.
    sign, offset : ndarray, shape (6,)
        Controller angle = ``sign * q + offset`` (rad).
    source : str
        Where it came from (run folder, problem), for the file header.
    """

    name: str
    robot: str
    joint_names: tuple[str, ...]
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    dt: float
    v_max: np.ndarray
    a_max: np.ndarray
    sign: np.ndarray = field(default_factory=lambda: np.ones(6))
    offset: np.ndarray = field(default_factory=lambda: np.zeros(6))
    source: str = ""

    def controller_q(self, q: np.ndarray | None = None) -> np.ndarray:
        """Joint positions in the controller's convention (rad), (M, 6)."""
        return (self.q if q is None else q) * self.sign + self.offset

    def controller_rates(self, x: np.ndarray) -> np.ndarray:
        """Velocities or accelerations in the controller's convention (the sign only)."""
        return x * self.sign

    def decimated(self, step_s: float) -> np.ndarray:
        """Sample indices about ``step_s`` apart, always including the first and the last."""
        k = max(1, int(round(step_s / self.dt)))
        idx = np.arange(0, len(self.t), k)
        return idx if idx[-1] == len(self.t) - 1 else np.r_[idx, len(self.t) - 1]


@dataclass(frozen=True)
class ExportFormat:
    """One export format.

    Attributes
    ----------
    name : str
        ``--format`` value.
    suffixes : tuple of str
        File suffixes it writes (the first is the ``--out`` file's; KRL adds ``.dat``).
    write : callable
        ``write(data, stem, options) -> {file name: text}``.
    options : mapping
        Option name -> (default, one-line help, validator returning the value or raising).
    description : str
    """

    name: str
    suffixes: tuple[str, ...]
    write: Callable[[ExportData, str, Mapping[str, Any]], dict[str, str]]
    options: Mapping[str, tuple[Any, str, Callable[[Any], Any]]]
    description: str


_FORMATS: dict[str, ExportFormat] = {}


def register_format(fmt: ExportFormat) -> ExportFormat:
    """Add an export format (a module calls this when imported)."""
    if fmt.name in _FORMATS:
        raise TypeError(f"export format '{fmt.name}' registered twice")
    _FORMATS[fmt.name] = fmt
    return fmt


def formats() -> dict[str, ExportFormat]:
    """The registered export formats by name."""
    return dict(_FORMATS)


def ranged(name: str, lo: float, hi: float) -> Callable[[Any], float]:
    """Validator: a number in [lo, hi], the message naming the option and the range."""
    def check(v: Any) -> float:
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ExportError(f"export option {name} = {v!r}: expected a number in [{lo:g}, {hi:g}]") from None
        if not (math.isfinite(x) and lo <= x <= hi):
            raise ExportError(f"export option {name} = {x:g}: expected a number in [{lo:g}, {hi:g}]")
        return x
    return check


def _program_name(text: str) -> str:
    out = "".join(c if c.isalnum() else "_" for c in text).strip("_") or "compplan"
    return ("t_" + out) if out[0].isdigit() else out


# --------------------------------------------------------------------------------------
# Sources
# --------------------------------------------------------------------------------------

def data_from_plan(res: Any) -> ExportData:
    """The controller's trajectory of a :class:`~planner.plan.PlanResult` (in memory)."""
    pr = res.problem
    if res.controller is None or res.controller not in res.trajectories:
        raise ExportError("export: the plan has no timed trajectory (the plan stopped before timing)")
    tr = res.trajectories[res.controller]
    if tr.status.value != "ok" or res.status.value != "ok":
        raise ExportError(f"export: the trajectory is not ok (plan {res.status.value}, {res.controller} "
                          f"{tr.status.value}: {tr.reason}); refusing to export it")
    r = pr.robot
    return ExportData(name=_program_name(pr.name), robot=r.name, joint_names=_names(r.joint_names), t=tr.t,
                      q=tr.q, qd=tr.qd, qdd=tr.qdd, dt=tr.dt, v_max=r.v_max, a_max=r.a_max,
                      sign=np.asarray(r.controller_sign, float), offset=np.asarray(r.controller_offset, float),
                      source=f"problem {pr.name}")


def _names(names: Any) -> tuple[str, ...]:
    return tuple(names) if names else tuple(f"joint_{i}" for i in range(1, 7))


def data_from_run(folder: str | Path) -> ExportData:
    """The controller's trajectory of a run folder (``summary.json`` and its ``trajectory.csv``)."""
    folder = Path(folder)
    summary = folder / "summary.json"
    if not summary.is_file():
        raise ExportError(f"{folder}: no summary.json; expected the output folder of compplan plan or demo")
    try:
        s = json.loads(summary.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise ExportError(f"{summary}: not readable JSON ({exc})") from None
    ctrl = s.get("controller_trajectory")
    timing = (s.get("timing") or {}).get(ctrl or "", {})
    if not ctrl or not timing:
        raise ExportError(f"{summary}: the run has no controller trajectory (key 'controller_trajectory')")
    if s.get("plan_status") != "ok" or timing.get("status") != "ok":
        raise ExportError(f"{summary}: the trajectory is not ok (plan_status {s.get('plan_status')!r}, {ctrl} "
                          f"status {timing.get('status')!r}: {timing.get('reason', '')}); refusing to export it")
    path = folder / timing.get("file", "trajectory.csv")
    t, q, qd, qdd = _read_trajectory(path)
    rf = s.get("robot_file") or {}
    ctrl_map = rf.get("controller") or {}
    lim = s.get("limits") or {}
    v_max = np.asarray(lim.get("velocity") or [math.inf] * 6, float)
    a_max = np.asarray(lim.get("acceleration") or [math.inf] * 6, float)
    return ExportData(name=_program_name((s.get("problem") or {}).get("name", folder.name)),
                      robot=str(rf.get("name", "robot")), joint_names=_names(rf.get("joint_names")),
                      t=t, q=q, qd=qd, qdd=qdd, dt=float(timing.get("dt") or (t[1] - t[0])),
                      v_max=v_max, a_max=a_max, sign=np.asarray(ctrl_map.get("joint_sign", [1] * 6), float),
                      offset=np.asarray(ctrl_map.get("joint_offset", [0.0] * 6), float), source=f"run {folder}")


def _read_trajectory(path: Path) -> tuple[np.ndarray, ...]:
    if not path.is_file():
        raise ExportError(f"{path}: no such trajectory file")
    with path.open(newline="", encoding="utf-8") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    head = rows[0]
    need = ["t"] + [f"{c}{i}" for c in ("q", "qd", "qdd") for i in range(1, 7)]
    missing = [c for c in need if c not in head]
    if missing:
        raise ExportError(f"{path}: missing column(s) {missing}")
    try:
        a = np.array([[float(r[head.index(c)]) for c in need] for r in rows[1:]])
    except (ValueError, IndexError) as exc:
        raise ExportError(f"{path}: a row is not numeric ({exc})") from None
    if a.shape[0] < 2 or not np.all(np.isfinite(a)):
        raise ExportError(f"{path}: expected at least 2 finite rows")
    return a[:, 0], a[:, 1:7], a[:, 7:13], a[:, 13:19]


# --------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------

def export_files(data: ExportData, fmt: str, out: str | Path, options: Mapping[str, Any] | None = None
                 ) -> dict[Path, str]:
    """The files (path -> text) of ``data`` in format ``fmt`` for output file ``out``.

    Options not given take the format's defaults; unknown options and bad values raise
    :class:`ExportError` naming them.  Nothing is written here (the caller writes the set
    whole or not at all).
    """
    f = _FORMATS.get(fmt)
    if f is None:
        raise ExportError(f"export: unknown format {fmt!r}; formats: {', '.join(sorted(_FORMATS))}")
    opts = dict(options or {})
    unknown = sorted(set(opts) - set(f.options))
    if unknown:
        raise ExportError(f"export: format {fmt} has no option(s) {unknown}; options: {sorted(f.options)}")
    values = {k: (check(opts[k]) if k in opts else default) for k, (default, _h, check) in f.options.items()}
    out = Path(out)
    stem = out.stem if out.suffix else out.name
    texts = f.write(data, _program_name(stem), values)
    return {out.with_name(name): text for name, text in texts.items()}


def header_lines(data: ExportData, fmt: str, comment: str) -> list[str]:
    """A few comment lines every file starts with (what, where from, the conventions)."""
    from planner.provenance import version
    return [f"{comment} generated by compplan {version()} ({fmt}) from {data.source}: robot {data.robot}, "
            f"{len(data.t)} samples at {data.dt * 1e3:g} ms, {data.t[-1]:.6g} s",
            f"{comment} joints {', '.join(data.joint_names)}; controller angle = sign * q + offset, "
            f"sign {[int(v) for v in data.sign]}, offset {[round(math.degrees(v), 6) for v in data.offset]} deg "
            "(docs/export.md)"]


EXPORT_FORMATS: tuple[str, ...] = ()

from planner.export import krl, rapid, ros2, urscript  # noqa: E402,F401  (register the formats)

EXPORT_FORMATS = tuple(sorted(_FORMATS))
