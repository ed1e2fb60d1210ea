"""Trajectories a controller can run: URScript, ROS 2 (YAML, rosbag2), ABB RAPID, KUKA KRL.

One module per format registers an :class:`ExportFormat` with :func:`register_format` (extend by
adding a file: every module of this package, and every module in the folders named by
``$COMPPLAN_EXPORT_PATH``, is imported when the formats are first asked for: :func:`formats`,
:func:`build_export`, ``EXPORT_FORMATS``; the command line's ``--format`` choices come from
:func:`format_names`, which imports no format module unless plug-in folders are named). Every
format reads an :class:`ExportData`: the controller's trajectory of a plan (``trajectory.csv``:
joint positions, velocities and accelerations at the controller period), the robot's joint
names and the mapping from the model's joint angles to the controller's
(``controller_angle = sign * q + offset``, ``[controller]`` of the robot file), built from a
plan in memory (:func:`data_from_plan`) or from a run folder (:func:`data_from_run`).
A trajectory whose status is not ``ok`` or outside its limits is refused (:class:`ExportError`), and
so is what a format would send its controller over a limit under the interpolation that controller
applies (``ExportFormat.motion``; :mod:`planner.export.limits`: refused, or slowed down and said so,
:func:`build_export`).  Conventions
of each vendor (joint order, units, signs, zeros): ``docs/export.md``.  Big programs (10^5-10^6
samples): above its limit each format writes numbered parts (:func:`part_ranges`,
:func:`part_label`) and a main file, or a stream, as its controller needs (``docs/export.md``,
"Big programs").
"""

from __future__ import annotations

import csv
import json
import math
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any
from collections.abc import Callable, Mapping

import numpy as np

from models.errors import InputError, PluginError
from models.plugins import import_plugins, plugin_folders

__all__ = [
    "EXPORT_FD_TOL",
    "EXPORT_FORMATS",
    "EXPORT_LIMIT_TOL",
    "EXPORT_PATH_VARIABLE",
    "EXPORT_POSITION_TOL",
    "EXPORT_TIME_TOL",
    "SLOW_DOWN_OPTION",
    "ControllerMotion",
    "Export",
    "ExportData",
    "ExportError",
    "ExportFormat",
    "ExportLimitError",
    "Interpolation",
    "VENDOR_FORMATS",
    "BUILTIN_FORMATS",
    "build_export",
    "check_motion",
    "choice",
    "controller_warning",
    "counted",
    "data_from_plan",
    "data_from_run",
    "export_files",
    "format_names",
    "formats",
    "load_formats",
    "part_label",
    "part_ranges",
    "ranged",
    "register_format",
    "verify_limits",
]


class ExportError(InputError):
    """The trajectory cannot be exported (not ok, no trajectory, a bad option); the message says why."""


class ExportLimitError(ExportError):
    """What a format would send its controller exceeds a limit (:func:`~planner.export.limits.check_motion`)."""


@dataclass(frozen=True)
class ExportData:
    """What every export format writes (SI units, the model's joint convention).

    Attributes
    ----------
    name : str
        Program name (letters, digits, underscores).
    robot : str
    joint_names : tuple of str, length 6
        Base to tip (the robot file's ``joint_names``, else ``joint_1`` ... ``joint_6``).
    t : ndarray, shape (M,)
        Sample times, s, from 0 every ``dt``.
    q, qd, qdd, qddd : ndarray, shape (M, 6)
        Joint positions (rad), velocities (rad/s), accelerations (rad/s^2) and jerks (rad/s^3),
        model convention.
    dt : float
        The trajectory's sample period, s.
    v_max, a_max, j_max : ndarray, shape (6,)
        The plan's velocity (rad/s), acceleration (rad/s^2) and jerk (rad/s^3) limits.
    q_min, q_max : ndarray, shape (6,)
        The robot's joint position limits, rad (model convention).
    enforced : tuple of str
        The rate limits the timing method enforced (``velocity``, ``acceleration``, ``jerk``);
        :func:`verify_limits` checks these and the positions.
    sign, offset : ndarray, shape (6,)
        Controller angle = ``sign * q + offset`` (rad).
    source : str
        Where it came from (run folder, problem), for the file header.
    inputs : tuple of Path
        The files it was read from (none for a plan in memory).
    link_q : ndarray, shape (M, 6), or None
        The planned link side (``ql1..ql6``) of a run with dynamic compensation, rad.
    slow_factor : float
        How much slower than planned (1: as planned; :meth:`slowed`).
    """

    name: str
    robot: str
    joint_names: tuple[str, ...]
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qddd: np.ndarray
    dt: float
    v_max: np.ndarray
    a_max: np.ndarray
    j_max: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    enforced: tuple[str, ...] = ("velocity", "acceleration", "jerk")
    sign: np.ndarray = field(default_factory=lambda: np.ones(6))
    offset: np.ndarray = field(default_factory=lambda: np.zeros(6))
    #: The robot file declared its controller's signs and zeros (``[controller]``); False: the identity
    #: is assumed (:func:`controller_warning`).
    controller_declared: bool = True
    source: str = ""
    inputs: tuple[Path, ...] = ()
    link_q: np.ndarray | None = None
    slow_factor: float = 1.0

    def slowed(self, k: float) -> ExportData:
        """The same path ``k`` times slower: times and ``dt`` times ``k``, velocities over ``k``,
        accelerations over ``k^2``, jerks over ``k^3`` (every rate's peak divided by ``k`` to its order)."""
        return replace(
            self,
            t=self.t * k,
            qd=self.qd / k,
            qdd=self.qdd / k**2,
            qddd=self.qddd / k**3,
            dt=self.dt * k,
            slow_factor=self.slow_factor * k,
        )

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
        ``write(data, stem, options) -> {file name: text or bytes}``.
    options : mapping
        Option name -> (default, one-line help, validator returning the value or raising).
    description : str
    folder : bool
        The format writes a folder (``--out`` names it; the file names are inside it), e.g. a
        rosbag2; otherwise files beside ``--out``.
    motion : callable or None
        ``motion(data, options) -> ControllerMotion``: what the controller runs from the files
        ``write`` makes of the same data and options (times and positions as written, the
        interpolation the controller applies), checked against every limit before anything is
        written (:func:`planner.export.limits.check_motion`).  None (a plug-in that declares
        none): only the trajectory itself is checked, and the export warns so.
    timing_options : tuple of str
        The options that change what the controller runs (periods, steps, blends, motion types):
        the tests export every format over their whole ranges.
    """

    name: str
    suffixes: tuple[str, ...]
    write: Callable[[ExportData, str, Mapping[str, Any]], Mapping[str, str | bytes]]
    options: Mapping[str, tuple[Any, str, Callable[[Any], Any]]]
    description: str
    folder: bool = False
    motion: Callable[[ExportData, Mapping[str, Any]], ControllerMotion] | None = None
    timing_options: tuple[str, ...] = ()


#: Extra folders searched for export format modules (``os.pathsep``-separated): each ``*.py``
#: there is imported as ``planner.export.<name>`` and registers its format(s) with
#: :func:`register_format`, as the built-in modules do.
EXPORT_PATH_VARIABLE = "COMPPLAN_EXPORT_PATH"

_FORMATS: dict[str, ExportFormat] = {}

#: The formats the modules of this package register, in the order they register when the package's
#: modules are imported (``rapid`` before ``krl``, which imports it): the command line offers these
#: names without importing the modules (start-up), and :func:`formats` lists them in this order.
#: ``tests/test_startup.py`` checks that it is what the modules register.
BUILTIN_FORMATS: tuple[str, ...] = ("rapid", "krl", "ros2", "rosbag2", "urscript", "urscript_movej")

#: Whether the modules of this package and of the plug-in folders have been imported (:func:`load_formats`).
_loaded = False


def register_format(fmt: ExportFormat) -> ExportFormat:
    """Add an export format (a module calls this when imported)."""
    if fmt.name in _FORMATS:
        raise PluginError(f"export format '{fmt.name}' registered twice; expected one format per name")
    _FORMATS[fmt.name] = fmt
    return fmt


def load_formats() -> None:
    """Import the format modules of this package and of the folders of ``$COMPPLAN_EXPORT_PATH``,
    once (:func:`models.plugins.import_plugins`; a bad folder or plug-in raises its
    :class:`~models.errors.InputError`)."""
    global _loaded
    if not _loaded:
        import_plugins(__name__, __path__, EXPORT_PATH_VARIABLE)
        _loaded = True


def formats() -> dict[str, ExportFormat]:
    """The registered export formats by name: the built-in ones in :data:`BUILTIN_FORMATS`' order,
    then the others (plug-ins) in the order they registered."""
    load_formats()
    first = [n for n in BUILTIN_FORMATS if n in _FORMATS]
    return {n: _FORMATS[n] for n in first + [n for n in _FORMATS if n not in first]}


def format_names() -> tuple[str, ...]:
    """The ``--format`` names, sorted, for the command line: :data:`BUILTIN_FORMATS` (and any format
    registered already) without importing a format module while no plug-in folder is named in
    ``$COMPPLAN_EXPORT_PATH``; else every format, the plug-ins imported (their errors raised here)."""
    if _loaded or plugin_folders(EXPORT_PATH_VARIABLE):
        return tuple(sorted(formats()))
    return tuple(sorted({*BUILTIN_FORMATS, *_FORMATS}))


# --------------------------------------------------------------------------------------
# Big programs: numbered parts
# --------------------------------------------------------------------------------------

#: Digits of the part number in a part's name (``NAME_p001``); more when there are more parts.
PART_DIGITS = 3


def part_ranges(n: int, limit: int) -> list[tuple[int, int]]:
    """``[start, stop)`` index ranges that cover ``range(n)`` in order, each at most ``limit`` long
    (all but the last exactly ``limit``)."""
    if limit < 1:
        raise ValueError(f"part size limit {limit}: expected at least 1")
    return [(a, min(a + limit, n)) for a in range(0, n, limit)]


def part_label(k: int, count: int) -> str:
    """The name tag of part ``k`` (1-based) of ``count``: ``p001`` ... (zero-padded to
    :data:`PART_DIGITS`, or to the digits of ``count``)."""
    return f"p{k:0{max(PART_DIGITS, len(str(count)))}d}"


#: Formats whose joint angles go to a vendor's controller in its own signs and zeros.
VENDOR_FORMATS = ("urscript", "urscript_movej", "rapid", "krl")


def controller_warning(data: ExportData, fmt: str) -> str:
    """The warning for a vendor format of a robot whose file has no ``[controller]`` table (the
    identity is then assumed for the controller's joint signs and zeros), or empty."""
    if fmt not in VENDOR_FORMATS or data.controller_declared:
        return ""
    return (
        f"robot {data.robot} has no [controller] table: the {fmt} angles assume its controller's joint signs "
        "and zeros are the model's (sign +1, offset 0); check them and fill [controller] joint_sign and "
        "joint_offset_deg in its robot file (docs/robot-file.md)"
    )


def _program_name(text: str) -> str:
    out = "".join(c if c.isalnum() else "_" for c in text).strip("_") or "compplan"
    return ("t_" + out) if out[0].isdigit() else out


# --------------------------------------------------------------------------------------
# Sources
# --------------------------------------------------------------------------------------

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
        name=_program_name(pr.name),
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
    )
    verify_limits(data, f"export of problem {pr.name} ({res.controller})")
    return data


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
        name=_program_name(str((s.get("problem") or {}).get("name", folder.name))),
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
    )
    verify_limits(data, str(path))
    return data


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


# --------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Export:
    """An export ready to write: ``files`` (path -> text, or bytes for binary formats) and the
    ``warnings`` the command line prints (what the vendor does not document, a slow-down)."""

    files: dict[Path, str | bytes]
    warnings: tuple[str, ...] = ()


def build_export(data: ExportData, fmt: str, out: str | Path, options: Mapping[str, Any] | None = None) -> Export:
    """The files of ``data`` in format ``fmt`` for output ``out`` (a file, or the folder of a
    folder format such as ``rosbag2``), after checking what the controller runs against every
    limit (:func:`~planner.export.limits.check_motion`: refused, or slowed down and said so).

    Options not given take the format's defaults; unknown options and bad values raise
    :class:`ExportError` naming them.  Nothing is written here (the caller writes the set
    whole or not at all).
    """
    f = formats().get(fmt)
    if f is None:
        raise ExportError(f"export: unknown format {fmt!r}; formats: {', '.join(sorted(_FORMATS))}")
    opts = dict(options or {})
    unknown = sorted(set(opts) - set(f.options))
    if unknown:
        raise ExportError(f"export: format {fmt} has no option(s) {unknown}; options: {sorted(f.options)}")
    values = {k: (check(opts[k]) if k in opts else default) for k, (default, _h, check) in f.options.items()}
    if f.motion is None:
        notes = [
            f"{fmt}: the format declares no controller motion (ExportFormat.motion): what it writes is not checked "
            "against the limits beyond the trajectory's own samples (docs/export.md)"
        ]
    else:
        motion = f.motion
        data, notes = check_motion(data, fmt, lambda d: motion(d, values), values.get("slow_down") == "auto")
    out = Path(out)
    stem = out.stem if out.suffix else out.name
    texts = f.write(data, _program_name(stem), values)
    if f.folder:
        files = {out / name: text for name, text in texts.items()}
    else:
        files = {out.with_name(name): text for name, text in texts.items()}
    return Export(files, tuple(notes))


def export_files(
    data: ExportData, fmt: str, out: str | Path, options: Mapping[str, Any] | None = None
) -> dict[Path, str | bytes]:
    """The files of :func:`build_export` (its warnings dropped)."""
    return build_export(data, fmt, out, options).files


def header_lines(data: ExportData, fmt: str, comment: str) -> list[str]:
    """A few comment lines every file starts with (what, where from, the conventions)."""
    from planner.provenance import version

    return [
        f"{comment} generated by compplan {version()} ({fmt}) from {data.source}: robot {data.robot}, "
        f"{len(data.t)} samples at {data.dt * 1e3:g} ms, {data.t[-1]:.6g} s",
        f"{comment} joints {', '.join(data.joint_names)}; controller angle = sign * q + offset, "
        f"sign {[int(v) for v in data.sign]}, offset {[round(math.degrees(v), 6) for v in data.offset]} deg "
        "(docs/export.md)",
    ] + (
        [
            f"{comment} slowed down x{data.slow_factor:.4f} from the plan's timing "
            f"({data.t[-1] / data.slow_factor:.6g} s) so that what the controller runs stays within every limit "
            "(docs/export.md)"
        ]
        if data.slow_factor != 1.0
        else []
    )


# the checks and the options' validators (they need ExportError and ExportData above)
from planner.export.options import SLOW_DOWN_OPTION, choice, counted, ranged  # noqa: E402
from planner.export.limits import (  # noqa: E402
    EXPORT_FD_TOL,
    EXPORT_LIMIT_TOL,
    EXPORT_POSITION_TOL,
    EXPORT_TIME_TOL,
    ControllerMotion,
    Interpolation,
    check_motion,
    verify_limits,
)


def __getattr__(name: str) -> Any:
    """``EXPORT_FORMATS``: the ``--format`` names, built-in and plug-in, sorted (the modules imported
    on first use, :func:`load_formats`)."""
    if name == "EXPORT_FORMATS":
        return tuple(sorted(formats()))
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
