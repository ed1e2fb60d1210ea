"""The run report: ``report.html`` (self-contained), ``report.md`` and ``figures/*.png|pdf``.

:func:`write_report` reads an output folder of ``compplan demo`` or ``compplan
plan`` (``summary.json``, ``waypoints.csv``, ``branches.csv`` and, when a plan
was timed, ``trajectory.csv`` (Ruckig) and ``trajectory_toppra.csv``) and
writes, next to them:

* ``report.html``: a summary table, then one section per figure; the PNGs are
  embedded as base64 data URIs so the file opens offline on its own;
* ``report.md``: the same tables, referencing ``figures/*.png``;
* ``figures/figN_*.png`` and ``.pdf``: every figure in both formats;
* ``compliance_map.csv``: the data of figure 1.

Whatever piece of a run is absent (no trajectory, no branch table, no robot
description) is stated in the report in place of its figure; it never fails
the report.  The run's own ``summary.json`` is read, never rewritten.

Every number in the HTML summary tables is machine-checkable: its cell carries
``data-key`` (the dotted path into ``summary.json``), ``data-value`` (the JSON
value, full precision) and, when the cell shows the maximum over joints of a
list, ``data-agg="max"``.  The text shows 7 significant digits.

Path figures are drawn from the run's data files, not recomputed; only the
compliance map and the 3-D arm need the robot (``summary.json``'s
``robot_file``).  The compliance map depends only on the robot and the map
options; once drawn it is cached (``$COMPPLAN_CACHE/maps``, default
``~/.cache/compplan/maps``) and reused.  Figures are rendered in up to two
forked processes where the platform allows it.  Everything is built in memory and published at the end
(all or nothing).  The library prints nothing; progress goes to a callback.
"""

from __future__ import annotations

import base64
import csv
import html
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from models import KinematicModel, Robot, robot_from_dict
from models.errors import CompplanError, InputError
from models.ik import BRANCH_LABELS

from planner import figures as F
from planner.compliance_map import ComplianceMap, ProgressFn, compliance_map
from planner.output import TRAJECTORY_COLUMNS, OutputSet, json_bytes

#: File names of the figures, in report order.
FIGURE_NAMES = ("fig1_compliance_map", "fig2_stiffness_error", "fig3_compensation_angles",
                "fig4_error_before_after", "fig5_branches", "fig6_trajectory", "fig7_arm_3d")

#: Default trajectory files and the method each one holds, used when summary.json has no
#: ``timing.<method>.file`` (a plan names the file of each method there; the controller's
#: trajectory is ``trajectory.csv``, Ruckig when available).
TRAJECTORY_FILES = (("trajectory_toppra.csv", "toppra"), ("trajectory.csv", "ruckig"))
#: Display names of the timing methods (column order of figure 6).
METHOD_NAMES = {"toppra": "TOPP-RA", "ruckig": "Ruckig"}

#: Number of poses drawn in figure 7.
ARM_POSES = 4

#: Most processes used to render figures (see :func:`render_items`).
MAX_WORKERS = 2

#: Relative rendering cost of each figure (longest first when rendering in parallel).
_COST = {"fig1_compliance_map": 3.0, "fig6_trajectory": 2.5, "fig4_error_before_after": 1.8,
         "fig3_compensation_angles": 1.6, "fig7_arm_3d": 1.2, "fig2_stiffness_error": 1.0,
         "fig5_branches": 0.8}

_RATIO_KINDS = ("velocity", "acceleration", "jerk")

#: Columns of the branch table when summary.json's branch entries have them (plan, issue 5).
_BRANCH_KEYS = ("status", "rms_error_analytic_mm", "rms_error_mm", "max_error_mm", "cost",
                "iterations")
_BRANCH_HEADERS = {"rms_error_analytic_mm": "RMS error, analytic posture [mm]",
                   "rms_error_mm": "RMS error, optimised posture [mm]",
                   "max_error_mm": "max error, optimised [mm]", "cost": "cost [m²]",
                   "iterations": "solver iterations"}


# ------------------------------------------------------------------------------- reading a run
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
                         "written by compplan demo/plan (docs/output-files.md)")
    return np.column_stack([cols[n] for n in names])


@dataclass
class Run:
    """The contents of an output folder that the report uses (SI units).

    Attributes
    ----------
    summary : dict
        ``summary.json``.
    waypoints : dict of column -> ndarray, or None
    branches : dict of column -> ndarray, or None
    trajectories : dict method -> {"t", "q", "qd", "qdd"}
    trajectory_files : dict method -> file name
    robot : Robot or None
        From ``summary["robot_file"]``.
    absent : dict of piece -> reason
        What the report could not show and why.
    """

    folder: Path
    summary: dict[str, Any]
    waypoints: dict[str, np.ndarray] | None = None
    branches: dict[str, np.ndarray] | None = None
    trajectories: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    trajectory_files: dict[str, str] = field(default_factory=dict)
    robot: Robot | None = None
    absent: dict[str, str] = field(default_factory=dict)


def _trajectory_files(summary: Mapping[str, Any], folder: Path) -> list[tuple[str, str]]:
    """(file, method) pairs, TOPP-RA first: from ``timing.<method>.file`` or the defaults."""
    pairs: list[tuple[str, str]] = []
    timing = summary.get("timing")
    if isinstance(timing, Mapping):
        for m, info in timing.items():
            if isinstance(info, Mapping) and isinstance(info.get("file"), str):
                pairs.append((Path(info["file"]).name, str(m)))
    if not pairs:
        pairs = list(TRAJECTORY_FILES)
        known = {f for f, _ in pairs}
        for p in sorted(folder.glob("trajectory_*.csv")):
            if p.name not in known:
                pairs.append((p.name, p.stem[len("trajectory_"):]))
    order = {m: i for i, m in enumerate(METHOD_NAMES)}
    return sorted(pairs, key=lambda fm: (order.get(fm[1], len(order)), fm[1]))


def load_run(folder: str | Path) -> Run:
    """Read an output folder of ``compplan demo``/``plan``.

    Raises
    ------
    InputError
        The folder or its ``summary.json`` is missing or malformed, or a data
        file present in it is malformed (the message names file, line, column).
    """
    folder = Path(folder)
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
    run = Run(folder, summary)

    wp = folder / "waypoints.csv"
    if wp.is_file():
        run.waypoints = _read_csv(wp)
        from planner.demo import WAYPOINT_COLUMNS
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
        p = folder / name
        if p.is_file():
            cols = _read_csv(p)
            arr = _require(p, cols, TRAJECTORY_COLUMNS)
            if len(arr) == 0:
                run.absent[f"trajectory {method}"] = f"{name} has no samples"
                continue
            run.trajectories[method] = {"t": arr[:, 0], "q": arr[:, 1:7], "qd": arr[:, 7:13],
                                        "qdd": arr[:, 13:19]}
            run.trajectory_files[method] = name
    if not run.trajectories:
        run.absent["trajectory"] = ("no trajectory in this run (trajectory.csv and "
                                    "trajectory_toppra.csv absent)")

    rf = summary.get("robot_file")
    if isinstance(rf, dict):
        try:
            run.robot = robot_from_dict(rf, where=f"{sp}: robot_file")
        except CompplanError as exc:
            run.absent["robot"] = f"robot_file in summary.json is unusable: {exc}"
    else:
        run.absent["robot"] = "summary.json has no robot_file"
    return run


# ------------------------------------------------------------------------------- value helpers
def lookup(summary: Mapping[str, Any], key: str) -> Any:
    """Value at a dotted path in ``summary`` (``KeyError`` if absent)."""
    cur: Any = summary
    for part in key.split("."):
        if not isinstance(cur, Mapping) or part not in cur:
            raise KeyError(key)
        cur = cur[part]
    return cur


def fmt(v: Any) -> str:
    """Display text of a table value: numbers with 7 significant digits."""
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "n/a" if not math.isfinite(float(v)) else f"{float(v):.7g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    return str(v)


def _flat_numbers(v: Any) -> list[float]:
    if isinstance(v, (list, tuple)):
        return [x for item in v for x in _flat_numbers(item)]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return [float(v)]
    return []


@dataclass
class Cell:
    """One table cell: display text and, for values from summary.json, where they come from."""

    text: str
    key: str | None = None
    value: Any = None
    agg: str | None = None

    def html(self) -> str:
        if self.key is None:
            return f"<td>{html.escape(self.text)}</td>"
        attrs = f' data-key="{html.escape(self.key)}" data-value="{html.escape(json.dumps(self.value))}"'
        if self.agg:
            attrs += f' data-agg="{self.agg}"'
        cls = "text" if isinstance(self.value, str) else "num"
        return f'<td class="{cls}"{attrs}>{html.escape(self.text)}</td>'


def value_cell(summary: Mapping[str, Any], key: str, agg: str | None = None) -> Cell:
    """A cell showing ``summary[key]`` (or the max of its numbers with ``agg="max"``)."""
    try:
        v = lookup(summary, key)
    except KeyError:
        return Cell("absent")
    if agg == "max":
        nums = [x for x in _flat_numbers(v) if math.isfinite(x)]
        if not nums:
            return Cell("n/a")
        shown = max(nums)
        return Cell(fmt(shown), key, shown, "max")
    if isinstance(v, Mapping):
        return Cell(json.dumps(v))
    return Cell(fmt(v), key, v)


@dataclass
class Table:
    title: str
    header: list[str]
    rows: list[list[Cell]]
    note: str = ""

    def html(self) -> str:
        out = [f"<h3>{html.escape(self.title)}</h3>", '<table class="summary">',
               "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in self.header) + "</tr>"]
        out += ["<tr>" + "".join(c.html() for c in row) + "</tr>" for row in self.rows]
        out.append("</table>")
        if self.note:
            out.append(f'<p class="note">{html.escape(self.note)}</p>')
        return "\n".join(out)

    def markdown(self) -> str:
        def esc(s: str) -> str:
            return s.replace("|", "\\|")
        out = [f"### {self.title}", "", "| " + " | ".join(esc(h) for h in self.header) + " |",
               "|" + "---|" * len(self.header)]
        out += ["| " + " | ".join(esc(c.text) for c in row) + " |" for row in self.rows]
        if self.note:
            out += ["", self.note]
        return "\n".join(out)


def _ratio_methods(lr: Any) -> dict[str, str]:
    """Method name -> dotted key prefix of the limit ratios (per-method or single)."""
    if not isinstance(lr, Mapping):
        return {}
    if any(k in lr for k in _RATIO_KINDS):
        return {"trajectory": "limit_ratio"}
    return {m: f"limit_ratio.{m}" for m, v in lr.items() if isinstance(v, Mapping)}


def _scenario_key(s: Mapping[str, Any]) -> str:
    """Where the run names its scenario: ``scenario`` (demo) or ``problem.name`` (plan)."""
    if "scenario" not in s and isinstance(s.get("problem"), Mapping) and "name" in s["problem"]:
        return "problem.name"
    return "scenario"


def _title(s: Mapping[str, Any]) -> str:
    try:
        scen = str(lookup(s, _scenario_key(s)))
    except KeyError:
        scen = "unnamed run"
    return f"compplan report: {s.get('robot', '?')}, {scen}"


def summary_tables(summary: Mapping[str, Any], absent: Mapping[str, str]) -> list[Table]:
    """The tables that head the report (numbers traceable to summary.json)."""
    s = summary
    branch_key = "chosen_branch" if "chosen_branch" in s else "branch"
    run_rows = [
        [Cell("robot"), value_cell(s, "robot"), Cell("")],
        [Cell("scenario"), value_cell(s, _scenario_key(s)), Cell("")],
        [Cell("load: force F"), value_cell(s, "wrench.F_N"), Cell("N")],
        [Cell("load: moment M"), value_cell(s, "wrench.M_Nm"), Cell("N·m")],
        [Cell("load: frame / point"),
         Cell(f"{s.get('wrench', {}).get('frame', '?')} frame, at the "
              f"{s.get('wrench', {}).get('point', '?')}"), Cell("")],
        [Cell("IK branch used"), value_cell(s, branch_key), Cell("")],
        [Cell("waypoints"), value_cell(s, "n_waypoints"), Cell("")],
        [Cell("compensation status, closed form"), value_cell(s, "status.closed_form"), Cell("")],
        [Cell("compensation status, exact"), value_cell(s, "status.exact"), Cell("")],
    ]
    optional = (("plan status", "plan_status", ""), ("reason", "reason", ""),
                ("default IK branch (nearest home)", "default_branch", ""),
                ("error gain vs default branch", "gain.vs_default", "×"),
                ("error gain vs best analytic posture", "gain.vs_best_analytic", "×"),
                ("controller trajectory", "controller_trajectory", ""))
    for label, key, unit in optional:
        try:
            v = lookup(s, key)
        except KeyError:
            continue
        if v is None or v == "":
            continue
        run_rows.append([Cell(label), value_cell(s, key), Cell(unit)])
    tables = [Table("Run", ["quantity", "value", "unit"], run_rows)]

    err_rows = []
    for label, key in (("before compensation", "error_before"),
                       ("after closed form (paper eqs. 32/47)", "error_after.closed_form"),
                       ("after exact compensation", "error_after.exact")):
        err_rows.append([Cell(label), value_cell(s, f"{key}.max_mm"), value_cell(s, f"{key}.rms_mm")])
    tables.append(Table("TCP position error under load [mm]", ["case", "max [mm]", "RMS [mm]"],
                        err_rows, "Euclidean norm of (reached - target) TCP position over the "
                                  "waypoints, deflected equilibrium of the joint-compliance model."))

    methods = _ratio_methods(s.get("limit_ratio"))
    dur = s.get("duration_s")
    if isinstance(dur, Mapping):
        for m in dur:
            methods.setdefault(m, f"limit_ratio.{m}")
    t_rows = []
    for m, prefix in methods.items():
        if isinstance(dur, Mapping):
            dcell = value_cell(s, f"duration_s.{m}")
        elif dur is not None and m == "trajectory":
            dcell = value_cell(s, "duration_s")
        else:
            dcell = Cell("absent")
        t_rows.append([Cell(METHOD_NAMES.get(m, m)), dcell]
                      + [value_cell(s, f"{prefix}.{k}", agg="max") for k in _RATIO_KINDS]
                      + [value_cell(s, f"timing.{m}.status")])
    note = ("Limit ratio: peak |value| / limit, maximum over the joints (1 = at the limit). "
            "TOPP-RA limits velocity and acceleration only; its jerk ratio is reported, not "
            "enforced.")
    if not t_rows:
        t_rows = [[Cell(absent.get("trajectory", "no trajectory in this run"))]
                  + [Cell("—")] * 5]
        note = "No trajectory in this run: durations and limit ratios are not available."
    tables.append(Table("Timing", ["method", "duration [s]", "velocity ratio",
                                   "acceleration ratio", "jerk ratio", "status"], t_rows, note))

    br = s.get("branches")
    if isinstance(br, Mapping) and br:
        keys: list[str] = []
        for info in br.values():
            if isinstance(info, Mapping):
                for k, v in info.items():
                    if k not in keys and (isinstance(v, (int, float, str, bool)) or v is None):
                        keys.append(k)
        preferred = [k for k in _BRANCH_KEYS if k in keys]
        keys = preferred or keys[:8]
        rows = []
        chosen = s.get("chosen_branch")
        for label, info in br.items():
            name = f"{label} (chosen)" if label == chosen else str(label)
            rows.append([Cell(name)] + [value_cell(s, f"branches.{label}.{k}") for k in keys])
        tables.append(Table("IK branches", ["branch"] + [_BRANCH_HEADERS.get(k, k) for k in keys],
                            rows))
    return tables


# ----------------------------------------------------------------------------------- figures
@dataclass
class FigureItem:
    name: str
    title: str
    caption: str
    png: bytes | None = None
    pdf: bytes | None = None
    absent: str = ""
    #: ``(figure function, args, kwargs)`` to render; None when absent or already rendered.
    job: tuple[Callable[..., Any], tuple, dict] | None = None
    #: Key under which the rendered figure is cached (compliance map only).
    cache_key: str | None = None


def _xyz(wp: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    """Columns ``<prefix>x, <prefix>y, <prefix>z`` of waypoints.csv as an (N, 3) array."""
    return np.column_stack([wp[f"{prefix}{a}"] for a in "xyz"])


def _joints(wp: Mapping[str, np.ndarray], prefix: str) -> np.ndarray:
    """Columns ``<prefix>1 .. <prefix>6`` of waypoints.csv as an (N, 6) array."""
    return np.column_stack([wp[f"{prefix}{i}"] for i in range(1, 7)])


def _job(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[Callable[..., Any], tuple, dict]:
    return fn, args, kwargs


def _render_job(job: tuple[Callable[..., Any], tuple, dict]) -> tuple[bytes, bytes]:
    """Build one figure from its arrays and render it to PNG and PDF bytes."""
    fn, args, kwargs = job
    return F.render(fn(*args, **kwargs))


def _fork_available() -> bool:
    import multiprocessing
    return "fork" in multiprocessing.get_all_start_methods()


def default_workers() -> int:
    """Processes used to render figures: 2 where ``fork`` exists and 2+ CPUs, else 1."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return min(MAX_WORKERS, cpus) if _fork_available() else 1


def render_items(items: list[FigureItem], progress: ProgressFn | None = None,
                 workers: int | None = None) -> None:
    """Render every item that has a job, filling ``png`` and ``pdf``.

    With ``workers > 1`` the figures are rendered in forked processes (they
    inherit the imported matplotlib, so start-up is cheap); the jobs hold only
    arrays and strings.  Without ``fork`` (Windows) or with ``workers=1`` they
    are rendered here, one after the other.
    """
    todo = [it for it in items if it.job is not None]
    total = len(todo)
    n = default_workers() if workers is None else max(1, int(workers))
    n = min(n, total)

    def tick(i: int) -> None:
        if progress is not None:
            progress("figures", i, total)

    if n <= 1 or not _fork_available():
        for i, it in enumerate(todo, start=1):
            it.png, it.pdf = _render_job(it.job)  # type: ignore[arg-type]
            tick(i)
        return
    import multiprocessing
    # Most expensive first, so the two processes finish together.
    order = sorted(todo, key=lambda it: -_COST.get(it.name, 1.0))
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(processes=n) as pool:
        results = pool.imap(_render_job, [it.job for it in order], chunksize=1)
        for i, (it, (png, pdf)) in enumerate(zip(order, results), start=1):
            it.png, it.pdf = png, pdf
            tick(i)


def _wrench(summary: Mapping[str, Any]) -> np.ndarray:
    w = summary.get("wrench", {})
    try:
        return np.r_[np.asarray(w["F_N"], float), np.asarray(w["M_Nm"], float)]
    except (KeyError, TypeError, ValueError):
        raise InputError("summary.json: wrench.F_N / wrench.M_Nm missing or not numeric; "
                         "expected 3 + 3 numbers (N, N*m)") from None


def _fmt_vec(v: np.ndarray, unit: str) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + f"] {unit}"


def _map_figure(run: Run, map_options: Mapping[str, Any], progress: ProgressFn | None,
                files: dict[str, bytes]) -> tuple[Any, str]:
    cm = compliance_map(run.robot, progress=progress, **dict(map_options))  # type: ignore[arg-type]
    files["compliance_map.csv"] = cm.csv_bytes()
    return map_job(cm)


# The compliance map depends only on the robot and the map options, not on the run, and it is
# the most expensive figure.  Its PNG, PDF, CSV and caption are kept in a small on-disk cache
# (next to the compiled kernels: $COMPPLAN_CACHE, default ~/.cache/compplan) keyed by a hash of
# the robot description, the options and the source of the code that draws it.  The cache is
# best effort: any failure to read or write it just means the map is computed again.
_MAP_CACHE_FILES = ("map.png", "map.pdf", "map.csv", "caption.txt")


def _map_cache_dir(key: str) -> Path:
    root = os.environ.get("COMPPLAN_CACHE") or os.path.join(os.path.expanduser("~"), ".cache",
                                                              "compplan")
    return Path(root) / "maps" / key


def _map_cache_key(robot: Robot, map_options: Mapping[str, Any]) -> str:
    import hashlib
    import inspect

    import matplotlib

    from planner import compliance_map as cmod
    sig = inspect.signature(cmod.compliance_map)
    opts = {k: p.default for k, p in sig.parameters.items()
            if p.default is not inspect.Parameter.empty and k not in ("progress", "chunk")}
    opts.update({k: v for k, v in map_options.items() if k not in ("progress", "chunk")})
    from models.arm import ArmModel
    desc = (robot.nominal.to_dict() | {"theta": robot.theta, "const": robot.const,
                                       "effects": list(robot.active_effects)}
            if isinstance(robot, ArmModel) else robot.to_dict())
    blob = json.dumps({"robot": desc, "options": opts}, sort_keys=True,
                      default=lambda o: np.asarray(o, float).tolist())
    h = hashlib.sha256(blob.encode())
    for mod in (F, cmod):
        h.update(Path(mod.__file__).read_bytes())
    h.update(Path(__file__).read_bytes())
    h.update(matplotlib.__version__.encode())
    return h.hexdigest()[:24]


def _map_cache_get(key: str) -> tuple[bytes, bytes, bytes, str] | None:
    d = _map_cache_dir(key)
    try:
        png, pdf, csv_, cap = (d / n for n in _MAP_CACHE_FILES)
        return png.read_bytes(), pdf.read_bytes(), csv_.read_bytes(), cap.read_text()
    except OSError:
        return None


def _map_cache_put(key: str, png: bytes, pdf: bytes, csv_: bytes, caption: str) -> None:
    from planner.output import atomic_write_bytes
    d = _map_cache_dir(key)
    try:
        for name, data in zip(_MAP_CACHE_FILES, (png, pdf, csv_, caption.encode())):
            atomic_write_bytes(d / name, data)
    except OSError:
        pass


def map_job(cm: ComplianceMap) -> tuple[tuple[Callable[..., Any], tuple, dict], str]:
    """The figure job and caption of a compliance map."""
    used = cm.branches_used()
    rule = ("per point, the IK branch nearest the home configuration" if cm.branch_rule == "home"
            else f"fixed branch {cm.branch_rule}")
    title = (f"{cm.robot}: diagonal compliance over the plane {cm.plane} = {cm.offset_m:g} m, "
             f"{cm.u_axis} ∈ [{cm.u_m[0]:g}, {cm.u_m[-1]:g}] m, "
             f"{cm.v_axis} ∈ [{cm.v_m[0]:g}, {cm.v_m[-1]:g}] m "
             f"({len(cm.u_m)}×{len(cm.v_m)} points)\n"
             f"end attitude (roll, pitch, yaw) = ({', '.join(f'{a:g}' for a in cm.rpy_rad)}) rad, "
             f"R = Rz(yaw)·Ry(pitch)·Rx(roll)\n"
             f"branch: {rule} ({', '.join(f'{k} at {v} points' for k, v in used.items()) or 'none'}); "
             f"{cm.n_unreachable} of {cm.n_points} points unreachable")
    job = _job(F.compliance_map_figure, cm.u_m, cm.v_m, cm.diag, u_label=cm.u_axis, v_label=cm.v_axis,
                                  title=title, branch=cm.branch, branch_labels=BRANCH_LABELS)
    reasons = "; ".join(f"{k}: {v}" for k, v in cm.unreachable_reasons.items())
    caption = (f"Paper Fig. 5. C11–C33: translational compliance (mm/N); C44–C66: rotational "
               f"compliance (deg/(N·m)). {cm.n_unreachable} of {cm.n_points} grid points "
               f"unreachable (hatched){' — ' + reasons if reasons else ''}. "
               f"Branch: {rule}. Data: compliance_map.csv (SI).")
    return job, caption


def build_figures(run: Run, progress: ProgressFn | None = None,
                  map_options: Mapping[str, Any] | None | bool = None,
                  files: dict[str, bytes] | None = None,
                  map_cache: bool = True) -> list[FigureItem]:
    """Prepare every figure the run allows (its ``job``); absent ones carry the reason.

    Only the compliance map is computed here (with progress); the figures are
    drawn by :func:`render_items`.

    Parameters
    ----------
    map_options : mapping, None or False
        Keyword arguments of :func:`planner.compliance_map.compliance_map`
        (default: the paper's section-4.3 plane); ``False`` skips the map.
    files : dict, optional
        Extra data files produced on the way (``compliance_map.csv``) are added here.
    map_cache : bool
        Reuse a compliance map drawn earlier for the same robot and options (see
        :func:`_map_cache_key`).
    """
    files = {} if files is None else files
    s = run.summary
    items: list[FigureItem] = []
    wp = run.waypoints
    robot_name = s.get("robot", "?")
    try:
        wrench = _wrench(s)
    except InputError as exc:
        wrench = None
        run.absent.setdefault("wrench", str(exc))
    load = (f"F = {_fmt_vec(wrench[:3], 'N')}, M = {_fmt_vec(wrench[3:], 'N·m')} (base frame, at the TCP)"
            if wrench is not None else "load unknown")
    if wrench is not None and s.get("wrench", {}).get("per_waypoint"):
        load = f"per-waypoint load, waypoint 0: {load}"
    branch = s.get("chosen_branch", s.get("branch", "?"))

    # 1. compliance map
    item = FigureItem(FIGURE_NAMES[0], "Compliance maps C11…C66 over a plane (paper §4.3)", "")
    if map_options is False:
        item.absent = "compliance map not requested (--no-map)"
    elif run.robot is None:
        item.absent = f"compliance map not computed: {run.absent.get('robot', 'no robot')}"
    else:
        key = _map_cache_key(run.robot, map_options or {}) if map_cache else None
        hit = _map_cache_get(key) if key else None
        if hit is not None:
            item.png, item.pdf, files["compliance_map.csv"], item.caption = hit
            if progress is not None:
                progress("compliance map", 1, 1)
        else:
            try:
                item.job, item.caption = _map_figure(run, map_options or {}, progress, files)
                item.cache_key = key
            except CompplanError as exc:
                item.absent = f"compliance map not computed: {exc}"
    items.append(item)

    n_absent = run.absent.get("waypoints", "")
    k = wp["k"] if wp is not None else None
    # 2. stiffness and error along the path
    item = FigureItem(FIGURE_NAMES[1], "Directional stiffness and load-induced error along the path",
                      "Paper Figs. 6–7. (a) stiffness 1/(uᵀ C u) along base X, Y, Z (N/m); "
                      "(b) TCP error under load without compensation, per base axis and norm (mm).")
    if wp is None:
        item.absent = n_absent
    else:
        K = _xyz(wp, "k")
        E = _xyz(wp, "eb")
        item.job = _job(F.stiffness_error_figure, k, K, E, title=f"{robot_name}, branch {branch}, {load}")
    items.append(item)

    # 3. compensation angles
    item = FigureItem(FIGURE_NAMES[2], "Compensation angle per joint along the path",
                      "Paper Fig. 8. Δθ = q_command − q_target (deg): exact compensation (solid) "
                      "and the paper's closed form, eqs. 32/47 (dashed).")
    if wp is None:
        item.absent = n_absent
    else:
        qt = _joints(wp, "qt")
        qc = _joints(wp, "qc")
        qf = _joints(wp, "qf")
        item.job = _job(F.compensation_figure, k, qc - qt, qf - qt,
                                    title=f"{robot_name}, branch {branch}: joint compensation angles, {load}")
    items.append(item)

    # 4. error before / after
    item = FigureItem(FIGURE_NAMES[3], "TCP error before and after compensation",
                      "Paper Figs. 9 and 13. Top: error before (solid) and after compensation "
                      "(closed form dashed, exact dotted), mm; bottom: the residuals alone, µm.")
    if wp is None:
        item.absent = n_absent
    else:
        eb = _xyz(wp, "eb")
        ef = _xyz(wp, "ef")
        ee = _xyz(wp, "ee")
        stats = (f"max |Δ|: before {np.linalg.norm(eb, axis=1).max() * 1e3:.4g} mm, closed form "
                 f"{np.linalg.norm(ef, axis=1).max() * 1e3:.4g} mm, exact "
                 f"{np.linalg.norm(ee, axis=1).max() * 1e3:.3g} mm")
        item.job = _job(F.error_before_after_figure, k, eb, ef, ee,
                                          title=f"{robot_name}, branch {branch}, {load}\n{stats}")
    items.append(item)

    # 5. branches
    item = FigureItem(FIGURE_NAMES[4], "Branch comparison",
                      "Load-induced TCP error norm along the path for every feasible IK branch "
                      "(analytic posture solid, optimised posture dashed when present); the branch "
                      "used is thick with markers.")
    if run.branches is None:
        item.absent = run.absent.get("branches", "branches.csv absent")
    else:
        ana = {c[: -len("_analytic_m")]: v for c, v in run.branches.items() if c.endswith("_analytic_m")}
        opt = {c[: -len("_optimised_m")]: v for c, v in run.branches.items() if c.endswith("_optimised_m")}
        for lab in opt:
            ana.setdefault(lab, np.full_like(opt[lab], np.nan))
        if not ana:
            item.absent = "branches.csv has no <branch>_analytic_m columns"
        else:
            rej = s.get("rejected_branches") or {}
            by_reason: dict[str, list[str]] = {}
            for b, r in rej.items():
                by_reason.setdefault(str(r), []).append(str(b))
            note = ("not feasible: " + "; ".join(f"{', '.join(bs)} ({r})" for r, bs in by_reason.items())
                    if rej else "")
            if not opt:
                item.caption += " No optimised postures in this run."
            item.job = _job(F.branch_figure, run.branches["k"], ana, opt or None, branch,
                                  title=f"{robot_name}: load-induced error per IK branch, {load}",
                                  note=_wrap(note, 120))
    items.append(item)

    # 6. trajectory
    item = FigureItem(FIGURE_NAMES[5], "Trajectory: q, q̇, q̈ and jerk against time",
                      "Joint position, velocity, acceleration and jerk (finite difference of q̈ "
                      "over t) for each timing method, with the limits dashed.")
    if not run.trajectories:
        item.absent = run.absent.get("trajectory", "no trajectory in this run")
    else:
        limits, src = _limits(run)
        item.caption += f" Limits: {src}."
        trajs, headers = {}, {}
        for method, tr in run.trajectories.items():
            pretty = METHOD_NAMES.get(method, method)
            trajs[pretty] = tr
            headers[pretty] = _traj_header(s, method, pretty, run.trajectory_files[method], tr)
        missing = [METHOD_NAMES.get(m, m) for m in METHOD_NAMES if m not in run.trajectories]
        if missing:
            item.caption += f" No {', '.join(missing)} trajectory in this run."
        item.job = _job(F.trajectory_figure, trajs, limits, title=f"{robot_name}: joint trajectories",
                                  headers=headers)
    items.append(item)

    # 7. the arm in 3-D
    item = FigureItem(FIGURE_NAMES[6], "The arm in 3-D, nominal and deflected", "")
    if run.robot is None:
        item.absent = f"arm not drawn: {run.absent.get('robot')}"
    elif wp is None:
        item.absent = f"arm not drawn: {n_absent}"
    elif wrench is None:
        item.absent = f"arm not drawn: {run.absent.get('wrench')}"
    else:
        item.job, item.caption = _arm(run, wp, wrench, branch, load)
    items.append(item)
    return items


def _wrap(text: str, width: int) -> str:
    import textwrap
    return "\n".join(textwrap.wrap(text, width)) if text else ""


def _limits(run: Run) -> tuple[dict[str, np.ndarray | None], str]:
    lim: dict[str, np.ndarray | None] = {"q_min": None, "q_max": None, "velocity": None,
                                         "acceleration": None, "jerk": None}
    src = []
    given = run.summary.get("limits")
    if isinstance(given, Mapping):
        found = []
        for k in lim:
            try:
                v = np.broadcast_to(np.asarray(given.get(k), float), (6,)).copy()
            except (TypeError, ValueError):
                continue
            if np.all(np.isfinite(v)):
                lim[k] = v
                found.append(k)
        if found:
            src.append(f"{', '.join(found)} from summary.json limits")
    if run.robot is not None:
        r = run.robot
        for k, v in (("q_min", r.q_min), ("q_max", r.q_max), ("velocity", r.v_max),
                     ("acceleration", r.a_max), ("jerk", r.j_max)):
            if lim[k] is None:
                lim[k] = v
                src.append(f"{k} from the robot file")
    return lim, "; ".join(src) or "none available"


def _traj_header(s: Mapping[str, Any], method: str, pretty: str, fname: str,
                 tr: Mapping[str, np.ndarray]) -> str:
    dur = s.get("duration_s")
    d = dur.get(method) if isinstance(dur, Mapping) else None
    if d is None:
        d = float(tr["t"][-1] - tr["t"][0])
    ctrl = " — controller" if s.get("controller_trajectory") == method else ""
    head = f"{pretty} ({fname}{ctrl}): duration {float(d):.4g} s"
    lr = s.get("limit_ratio")
    if isinstance(lr, Mapping):
        sub = lr.get(method) if method in lr else (lr if any(k in lr for k in _RATIO_KINDS) else None)
        if isinstance(sub, Mapping):
            parts = []
            for k, short in zip(_RATIO_KINDS, ("v", "a", "j")):
                nums = _flat_numbers(sub.get(k))
                if nums:
                    parts.append(f"{short} {max(nums):.3g}")
            if parts:
                head += "\npeak |value|/limit: " + ", ".join(parts)
    return head


def _polylines(model: KinematicModel, q: np.ndarray) -> np.ndarray:
    """(P, L, 3) points through the base, each link's offset corner, the frame origins and the TCP."""
    frames = model.batch(model.fk_frames, q)          # 6 x (P, 4, 4)
    tcp = model.tcp(q)[:, :3, 3]
    P = len(q)
    pts = [np.zeros((P, 3))]
    prev_o, prev_z = np.zeros((P, 3)), np.tile([0.0, 0.0, 1.0], (P, 1))
    d = model.robot.d
    for i, Tf in enumerate(frames):
        if model.robot.convention == "standard_dh" and abs(d[i]) > 0:
            pts.append(prev_o + d[i] * prev_z)         # the d_i offset along z_{i-1}
        o = Tf[:, :3, 3]
        pts.append(o)
        prev_o, prev_z = o, Tf[:, :3, 2]
    pts.append(tcp)
    return np.stack(pts, axis=1)


def _arm(run: Run, wp: Mapping[str, np.ndarray], wrench: np.ndarray, branch: str,
         load: str) -> tuple[Any, str]:
    model = KinematicModel(run.robot)                  # type: ignore[arg-type]
    qt = _joints(wp, "qt")
    n = len(qt)
    idx = np.unique(np.round(np.linspace(0, n - 1, min(ARM_POSES, n))).astype(int))
    q = qt[idx]
    W = np.broadcast_to(wrench, (len(idx), 6))
    rows = run.summary.get("wrench", {}).get("rows")
    if rows is not None:                              # a per-waypoint wrench (plan)
        try:
            W = np.asarray(rows, float)[idx].reshape(len(idx), 6)
        except (ValueError, IndexError, TypeError):
            pass
    dq = model.batch(model.joint_deflection, q, np.ascontiguousarray(W))[0]  # K^-1 J^T F, rad
    eb = _xyz(wp, "eb")
    true_max = float(np.linalg.norm(eb, axis=1).max())
    factor = F.nice_factor(true_max)
    nominal = _polylines(model, q)
    deflected = _polylines(model, q + factor * dq)
    path = _xyz(wp, "")
    labels = [f"k = {int(wp['k'][i])}" for i in idx]
    title = (f"{run.summary.get('robot', '?')}, branch {branch}: poses along the path, "
             f"deflection exaggerated ×{factor:g}\n(true TCP deflection up to "
             f"{true_max * 1e3:.3g} mm under {load})")
    job = _job(F.arm_figure, nominal, deflected, path, labels, factor, title=title)
    caption = (f"Links drawn through the DH frame origins (with each link's d offset) at "
               f"{len(idx)} waypoints: nominal configuration q_target (solid) and loaded "
               f"q_target + {factor:g}·K⁻¹Jᵀ(q)F (dashed), i.e. the joint deflection exaggerated "
               f"×{factor:g}.")
    return job, caption


# ------------------------------------------------------------------------------ HTML and MD
_CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;max-width:1250px;margin:2em auto;
     padding:0 1em;color:#222}
table.summary{border-collapse:collapse;margin:0.5em 0 1em}
table.summary td,table.summary th{border:1px solid #bbb;padding:3px 8px;text-align:left}
table.summary th{background:#eee} td.num{font-family:monospace;text-align:right}
img{max-width:100%;border:1px solid #ddd} .note{color:#555;font-size:90%}
.absent{background:#fff4e0;border-left:4px solid #e0a030;padding:0.5em 1em}
figure{margin:1em 0 2em} figcaption{color:#333;font-size:92%;margin-top:0.3em}
"""


def render_html(run: Run, tables: list[Table], items: list[FigureItem]) -> str:
    s = run.summary
    title = _title(s)
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
           f"<h1>{html.escape(title)}</h1>",
           f'<p class="note">Output folder: {html.escape(str(run.folder))}. All values from '
           "summary.json and the CSV files of this folder; SI inside, mm and deg in the "
           "displays.</p>", "<h2>Summary</h2>"]
    out += [t.html() for t in tables]
    rej = s.get("rejected_branches") or {}
    if rej:
        out.append("<h3>IK branches not feasible along the path</h3><ul>"
                   + "".join(f"<li>{html.escape(str(b))}: {html.escape(str(r))}</li>"
                             for b, r in rej.items()) + "</ul>")
    warn = s.get("warnings") or []
    if warn:
        out.append("<h3>Warnings</h3><ul>" + "".join(f"<li>{html.escape(str(w))}</li>" for w in warn) + "</ul>")
    if run.absent:
        out.append("<h3>Absent in this run</h3><ul>"
                   + "".join(f"<li>{html.escape(v)}</li>" for v in run.absent.values()) + "</ul>")
    out.append("<h2>Figures</h2>")
    for i, it in enumerate(items, start=1):
        out.append(f'<h3 id="{it.name}">Figure {i}. {html.escape(it.title)}</h3>')
        if it.png is None:
            out.append(f'<p class="absent" data-absent="{it.name}">{html.escape(it.absent)}</p>')
            continue
        b64 = base64.b64encode(it.png).decode("ascii")
        out.append(f'<figure><img data-figure="{it.name}" alt="{html.escape(it.title)}" '
                   f'src="data:image/png;base64,{b64}">'
                   f"<figcaption>{html.escape(it.caption)} Files: "
                   f'<a href="figures/{it.name}.png">PNG</a>, '
                   f'<a href="figures/{it.name}.pdf">PDF</a>.</figcaption></figure>')
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def render_markdown(run: Run, tables: list[Table], items: list[FigureItem]) -> str:
    s = run.summary
    out = [f"# {_title(s)}", "",
           "All values from summary.json and the CSV files of this folder; SI inside, mm and deg "
           "in the displays.", "", "## Summary", ""]
    for t in tables:
        out += [t.markdown(), ""]
    rej = s.get("rejected_branches") or {}
    if rej:
        out += ["### IK branches not feasible along the path", ""] + [
            f"- {b}: {r}" for b, r in rej.items()] + [""]
    warn = s.get("warnings") or []
    if warn:
        out += ["### Warnings", ""] + [f"- {w}" for w in warn] + [""]
    if run.absent:
        out += ["### Absent in this run", ""] + [f"- {v}" for v in run.absent.values()] + [""]
    out += ["## Figures", ""]
    for i, it in enumerate(items, start=1):
        out += [f"### Figure {i}. {it.title}", ""]
        if it.png is None:
            out += [f"*{it.absent}*", ""]
            continue
        out += [f"![Figure {i}. {it.title}](figures/{it.name}.png)", "",
                f"{it.caption} ([PDF](figures/{it.name}.pdf))", ""]
    return "\n".join(out)


# ------------------------------------------------------------------------------- entry point
def write_report(folder: str | Path, progress: ProgressFn | None = None, *,
                 map_options: Mapping[str, Any] | None | bool = None,
                 workers: int | None = None, map_cache: bool = True) -> Path:
    """Write ``report.html``, ``report.md`` and ``figures/*.png|pdf`` into a run folder.

    Parameters
    ----------
    folder : str or Path
        Output folder of ``compplan demo`` or ``compplan plan``.
    progress : callable, optional
        ``progress(stage, done, total)`` with stage ``"compliance map"`` (per
        chunk of grid points) and ``"figures"`` (per figure).
    map_options : mapping, None or False
        Options of :func:`planner.compliance_map.compliance_map` for figure 1
        (default: the paper's section-4.3 plane with the run's robot);
        ``False`` leaves the map out.
    workers : int, optional
        Processes that render the figures (default :func:`default_workers`;
        1 renders in this process).
    map_cache : bool
        Reuse the compliance map drawn earlier for the same robot and options
        (kept under ``$COMPPLAN_CACHE/maps``, default ``~/.cache/compplan``).

    Returns
    -------
    Path
        The path of ``report.html``.

    Raises
    ------
    InputError
        The folder is not a run folder or one of its files is malformed.
    """
    run = load_run(folder)
    files: dict[str, bytes] = {}
    items = build_figures(run, progress, map_options, files, map_cache)
    render_items(items, progress, workers)
    for it in items:
        if it.cache_key and it.png is not None:
            _map_cache_put(it.cache_key, it.png, it.pdf, files["compliance_map.csv"], it.caption)
    tables = summary_tables(run.summary, run.absent)
    out = OutputSet(run.folder)
    for it in items:
        if it.png is not None:
            out.add_bytes(f"figures/{it.name}.png", it.png)
            out.add_bytes(f"figures/{it.name}.pdf", it.pdf)  # type: ignore[arg-type]
    for name, data in files.items():
        out.add_bytes(name, data)
    out.add_bytes("report.md", render_markdown(run, tables, items).encode())
    out.add_bytes("report.html", render_html(run, tables, items).encode())
    out.publish()
    # Figures of an earlier report that this run no longer has would mislead: remove them.
    for it in items:
        if it.png is None:
            for ext in ("png", "pdf"):
                stale = run.folder / "figures" / f"{it.name}.{ext}"
                if stale.exists():
                    stale.unlink()
    if map_options is False or items[0].png is None:
        stale = run.folder / "compliance_map.csv"
        if stale.exists():
            stale.unlink()
    return run.folder / "report.html"


def write_map(robot: Robot, folder: str | Path, progress: ProgressFn | None = None,
              **options: Any) -> tuple[ComplianceMap, list[Path]]:
    """Compute a compliance map and write it (``compplan map``).

    Writes ``compliance_map.csv`` (SI), ``compliance_map.json`` (what was
    computed, ranges in SI) and ``figures/fig1_compliance_map.png|pdf`` into
    ``folder`` (all or nothing).

    Parameters
    ----------
    robot : Robot
    folder : str or Path
    progress : callable, optional
        ``progress(stage, done, total)``.
    **options
        Keyword arguments of :func:`planner.compliance_map.compliance_map`.

    Returns
    -------
    (ComplianceMap, list of Path)
    """
    cm = compliance_map(robot, progress=progress, **options)
    job, caption = map_job(cm)
    png, pdf = _render_job(job)
    if progress is not None:
        progress("figures", 1, 1)
    out = OutputSet(folder)
    out.add_bytes("compliance_map.csv", cm.csv_bytes())
    out.add_bytes("compliance_map.json", json_bytes({**cm.summary(), "caption": caption}))
    out.add_bytes(f"figures/{FIGURE_NAMES[0]}.png", png)
    out.add_bytes(f"figures/{FIGURE_NAMES[0]}.pdf", pdf)
    return cm, out.publish()
