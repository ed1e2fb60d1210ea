"""Problem files: a planning problem as data (TOML), validated.

A problem names the robot and tool, the path, the orientation rule, the load,
the limits, the cost weights, the NLP solver and the time-parametrisation
settings.  The format is documented in ``docs/problem-file.md``; the shipped
problems live in ``problems/files/*.toml`` and are loaded by name.

Every error names the file, the key (dotted, e.g. ``path.points``) and, for
tables of rows, the row; the value found; and what was expected.  All values
are converted to SI units (m, rad, N, N*m, s) on loading.

The file format itself (one validating parser per section, the settings
dataclasses, the error type) is :mod:`problems.problem_file`; its public names
are re-exported here.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from models.arm import ArmModel, load_arm
from models.load import Load
from models.robot import Robot
from models.transforms import matrix_to_rpy
from problems.cell import Cell
from problems.problem_file.cell_section import parse_cell
from problems.path import line_positions
from problems.posture import OrientationRule, PostureTask, SolverSettings
from problems.problem_file import (
    DEFAULT_RPY,
    WRENCH_FRAMES,
    Limits,
    ProblemFileError,
    TimingSettings,
    check_timing,
    parse_branch,
    parse_cost,
    parse_header,
    parse_limits,
    parse_orientation,
    parse_path,
    parse_payload,
    parse_placement,
    parse_robot,
    parse_solver,
    parse_timing,
    parse_wrench,
    is_program_path,
)


@dataclass(frozen=True)
class Problem:
    """A validated planning problem (SI units, base frame).

    Attributes
    ----------
    name, description, source : str
        ``source`` is where it was read from (file path or shipped name).
    robot_spec : str
        The robot as named in the file (built-in name or resolved path).
    robot : Robot
        With the problem's tool applied.
    path_kind : {"line", "waypoints", "gcode", "toolpath_csv"}
    line : tuple (start (3,), end (3,)) or None
        For ``line`` paths, m.
    positions : ndarray, shape (N, 3)
        TCP waypoints, m.
    rotations : ndarray, shape (N, 3, 3)
        Nominal base->TCP rotations.
    rule : OrientationRule
    cone_half_angle : float
        rad (rule ``cone``), else 0.
    scan : int
        Scanned rotations about the tool axis for the warm starts.
    wrench : ndarray, shape (N, 6)
        [N, N*m] on the TCP, in the frame ``wrench_frame``.
    wrench_per_waypoint : bool
    wrench_frame : {"base", "tool"}
        ``tool``: the TCP frame (the wrench turns with the tool along the path).
    payload_mass_kg : float
    payload_com_m : ndarray, shape (3,)
        Payload centre of mass, TCP frame, m.
    gravity : ndarray, shape (3,)
        Gravity acting on the payload, base frame, m/s^2.
    arm : ArmModel
        The arm model (chain and deflection model) with the problem's tool; ``robot`` is
        its description.
    limits : Limits
    smoothness : float
        mm^2/rad^2.
    solver : SolverSettings
    home_q : ndarray, shape (6,)
        rad.
    timing : TimingSettings
    """

    name: str
    description: str
    source: str
    robot_spec: str
    robot: Robot
    path_kind: str
    line: tuple[np.ndarray, np.ndarray] | None
    positions: np.ndarray
    rotations: np.ndarray
    rule: OrientationRule
    cone_half_angle: float
    scan: int
    wrench: np.ndarray
    wrench_per_waypoint: bool
    limits: Limits
    smoothness: float
    solver: SolverSettings
    home_q: np.ndarray
    timing: TimingSettings
    nominal_rpy: np.ndarray = field(default_factory=lambda: DEFAULT_RPY.copy())
    wrench_frame: str = "base"
    payload_mass_kg: float = 0.0
    payload_com_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gravity: np.ndarray | None = None
    arm: ArmModel | None = None
    #: The file's own ``source`` text (where the task comes from); ``source`` above is
    #: where the file was read from.
    source_text: str = ""
    #: The ``[placement]`` grid of ``compplan place`` (a
    #: :class:`~problems.placement.grid.PlacementGrid`), or None.
    placement: Any = None
    #: A program path (``path_kind`` ``gcode`` / ``toolpath_csv``): the program read and placed
    #: (:class:`problems.problem_file.ProgramSection`: file, waypoints with their program lines,
    #: feeds, rapids and stops, the workpiece), else None.
    program: Any = None
    #: The ``[cell]`` table: the objects around the robot (base frame) and the clearance, or None
    #: when the file has none (:class:`problems.cell.Cell`).
    cell: Cell | None = None
    #: The cut of a program path with ``[material]`` and ``[stock]``: the predicted cutting wrench
    #: at every waypoint and what made it (:class:`problems.cutting.prediction.CutPrediction`), else
    #: None.  The load adds it to the ``[wrench]`` (``docs/cutting.md``).
    cut: Any = None
    #: The cut's sections as read (:class:`problems.problem_file.cut_section.CutSetup`), or None.
    cut_setup: Any = None

    @property
    def n(self) -> int:
        """Number of waypoints N."""
        return int(len(self.positions))

    @property
    def model(self) -> ArmModel:
        """The arm model the problem is planned with (the robot file's nominal one unless
        the file, or ``--robot``, names an identified model)."""
        return self.arm if self.arm is not None else ArmModel.from_robot(self.robot)

    @property
    def load(self) -> Load:
        """The load on the TCP: the wrench (in its frame), the predicted cut's wrench (base frame, per
        waypoint) and the payload."""
        g = self.robot.gravity if self.gravity is None else self.gravity
        W = self.wrench
        base = W if self.wrench_frame == "base" else np.zeros(6)
        if self.cut is not None:
            base = self.cut.wrench_base + base
        return Load(
            wrench_base=base,
            wrench_tool=W if self.wrench_frame == "tool" else np.zeros(6),
            payload_mass_kg=self.payload_mass_kg,
            payload_com_m=self.payload_com_m,
            gravity=g,
        )

    def task(self) -> PostureTask:
        """The posture task of this problem."""
        return PostureTask(
            self.positions,
            self.rotations,
            self.rule,
            self.load.rows(self.n),
            cone_half_angle=self.cone_half_angle,
            max_joint_step=self.limits.max_joint_step,
            smoothness=self.smoothness,
            scan=self.scan,
        )

    def with_points(self, n: int) -> Problem:
        """The same line path re-sampled with ``n`` points (line paths only)."""
        if self.path_kind != "line" or self.line is None:
            raise ProblemFileError(
                f"{self.source}: key 'path.points' can only be changed for a line path "
                f"(this path is '{self.path_kind}')"
            )
        if self.wrench_per_waypoint:
            raise ProblemFileError(f"{self.source}: cannot re-sample a path with a per-waypoint wrench")
        if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n:
            raise ProblemFileError(f"{self.source}: path.points must be an integer >= 2, got {n!r}")
        P = line_positions(self.line[0], self.line[1], n)
        R = np.broadcast_to(self.rotations[0], (n, 3, 3)).copy()
        W = np.broadcast_to(self.wrench[0], (n, 6)).copy()
        return replace(self, positions=P, rotations=R, wrench=W)

    def with_robot(self, robot_spec: str | ArmModel) -> Problem:
        """The same problem on another arm model (built-in name, robot file, identified model
        file, or an :class:`ArmModel`), keeping the problem's tool."""
        arm = load_arm(robot_spec).with_tool(self.robot.tcp2flange)
        spec = robot_spec if isinstance(robot_spec, str) else (arm.source or arm.name)
        return replace(self, robot_spec=str(spec), robot=arm.nominal, arm=arm)

    def with_timing(self, **changes: Any) -> Problem:
        """The same problem with other timing settings (e.g. ``dt=0.002``)."""
        t = replace(self.timing, **changes)
        check_timing(self.source, t)
        return replace(self, timing=t)

    def to_dict(self) -> dict[str, Any]:
        """The problem as a dictionary in the problem-file schema (SI units, radians)."""
        d: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "source": self.source_text,
            "robot": self._robot_dict(),
        }
        d.update(self._path_dicts())
        d["orientation"] = self._orientation_dict()
        wrench = self._wrench_dict()
        if wrench is not None:
            d["wrench"] = wrench
        if self.payload_mass_kg:
            d["payload"] = {"mass_kg": float(self.payload_mass_kg), "com_m": [float(v) for v in self.payload_com_m]}
            if self.gravity is not None:
                d["payload"]["gravity_m_s2"] = [float(v) for v in self.gravity]
        d["limits"] = {
            "velocity": self.limits.velocity.tolist(),
            "acceleration": self.limits.acceleration.tolist(),
            "jerk": self.limits.jerk.tolist(),
            "max_joint_step": self.limits.max_joint_step,
        }
        d["cost"] = {"smoothness": self.smoothness}
        d["solver"] = {
            "name": self.solver.name,
            "max_iter": self.solver.max_iter,
            "tol": self.solver.tol,
            "codegen": self.solver.codegen,
        }
        d["branch"] = {"home": self.home_q.tolist()}
        d["timing"] = self._timing_dict()
        if self.placement is not None:
            g = self.placement.describe()
            d["placement"] = {k: v for k, v in g.items() if k != "placements"}
        if self.cell is not None:
            d["cell"] = self.cell.to_dict()
        if self.cut_setup is not None:
            d.update(self.cut_setup.table)
            d["robot"]["tool"]["cutter"] = self.cut_setup.mill.to_dict()
        return d

    def _robot_dict(self) -> dict[str, Any]:
        """``[robot]``: the model and the tool (its TCP, and its body and cutter when the cell has them)."""
        T = self.robot.tcp2flange
        robot: dict[str, Any] = {
            "model": self.robot_spec,
            "tool": {"xyz": [float(v) for v in T[:3, 3]], "rpy": [float(v) for v in matrix_to_rpy(T[:3, :3])]},
        }
        tool = getattr(self.cell, "tool", None)
        if tool is not None:  # the tool's body and cutter ([robot.tool] body, cutter)
            robot["tool"].update(tool.to_dict())
        return robot

    def _path_dicts(self) -> dict[str, Any]:
        """``[path]`` (a program, a line or waypoints) and, for a program, ``[workpiece]``."""
        if self.program is not None:
            path: dict[str, Any] = {"kind": self.path_kind, "file": self.program.file}
            w = self.program.waypoints
            if w.tolerance_source != "G64 P":
                path["tolerance_mm"] = w.tolerance_m * 1e3
            workpiece = {
                "xyz": [float(v) for v in self.program.workpiece.xyz_m],
                "rpy": [float(v) for v in self.program.workpiece.rpy_rad],
            }
            return {"path": path, "workpiece": workpiece}
        if self.path_kind == "line" and self.line is not None:
            return {
                "path": {
                    "kind": "line",
                    "start": [float(v) for v in self.line[0]],
                    "end": [float(v) for v in self.line[1]],
                    "points": self.n,
                }
            }
        return {
            "path": {
                "kind": "waypoints",
                "positions": self.positions.tolist(),
                "rpy": [matrix_to_rpy(R).tolist() for R in self.rotations],
            }
        }

    def _orientation_dict(self) -> dict[str, Any]:
        """``[orientation]``: the rule, the scan, the nominal orientation (not for a program), the cone."""
        o: dict[str, Any] = {"rule": self.rule.value, "scan": self.scan}
        if self.program is None:
            o["rpy"] = [float(v) for v in self.nominal_rpy]
        if self.rule is OrientationRule.CONE:
            o["half_angle"] = self.cone_half_angle
        return o

    def _wrench_dict(self) -> dict[str, Any] | None:
        """``[wrench]``: per waypoint or constant; None when the program's CL file gives it."""
        if self.wrench_per_waypoint and self.program is not None and self.program.waypoints.wrench is not None:
            return None  # the CL file gives it
        if self.wrench_per_waypoint:
            return {"frame": self.wrench_frame, "per_waypoint": self.wrench.tolist()}
        return {
            "frame": self.wrench_frame,
            "force": self.wrench[0, :3].tolist(),
            "moment": self.wrench[0, 3:].tolist(),
        }

    def _timing_dict(self) -> dict[str, Any]:
        """``[timing]`` with its ``[timing.<method>]`` tables."""
        timing: dict[str, Any] = {
            "methods": list(self.timing.methods),
            "dt": self.timing.dt,
            "toppra_gridpoints": self.timing.toppra_gridpoints,
            "toppra_max_iterations": self.timing.toppra_max_iterations,
            "ruckig_max_iterations": self.timing.ruckig_max_iterations,
            "dynamic": self.timing.dynamic,
        }
        for m, opts in self.timing.method_options.items():  # [timing.<method>] tables
            timing[m] = dict(opts)
        return timing


# --------------------------------------------------------------------------------------
# The loader
# --------------------------------------------------------------------------------------


def problem_from_dict(data: Mapping[str, Any], where: str = "problem", base_dir: Path | None = None) -> Problem:
    """Build and validate a :class:`Problem` from a parsed problem file.

    The sections are parsed in file order (see :mod:`problems.problem_file`), so the
    first malformed section is the one reported.

    Parameters
    ----------
    data : mapping
        The parsed TOML document (see ``docs/problem-file.md``).
    where : str
        The source, used in error messages (usually the file path).
    base_dir : Path, optional
        Directory against which a relative ``robot.model`` path is resolved.

    Raises
    ------
    ProblemFileError
        Naming the file, the key (and row), the value and the expectation.
    """
    head = parse_header(where, data)
    spec, arm = parse_robot(where, data, base_dir)
    program = is_program_path(data)
    orient = parse_orientation(where, data, program)
    timing = parse_timing(where, data, program)
    path = parse_path(where, data, orient.rotation, base_dir, arm.nominal, timing.dt)
    cl_wrench = path.program.waypoints.wrench if path.program is not None else None
    cutting = "material" in data or "stock" in data
    wrench = parse_wrench(where, data, len(path.positions), cl_wrench, optional=cutting)
    payload = parse_payload(where, data)
    limits = parse_limits(where, data, arm.nominal)
    smoothness = parse_cost(where, data)
    if cutting and "smoothness" not in (data.get("cost") or {}):
        smoothness = CUT_SMOOTHNESS
    solver = parse_solver(where, data)
    home = parse_branch(where, data)
    placement = parse_placement(where, data)
    cell = parse_cell(where, data, base_dir, arm.nominal, path.positions, path.program)
    cut_setup, cut = _cut(where, data, base_dir, path.program, arm.nominal.tcp2flange)
    return Problem(
        name=head.name,
        description=head.description,
        source=where,
        source_text=head.source_text,
        robot_spec=spec,
        robot=arm.nominal,
        path_kind=path.kind,
        line=path.line,
        positions=path.positions,
        rotations=path.rotations,
        rule=orient.rule,
        cone_half_angle=orient.cone_half_angle,
        scan=orient.scan,
        wrench=wrench.wrench,
        wrench_per_waypoint=wrench.per_waypoint,
        limits=limits,
        smoothness=smoothness,
        solver=solver,
        home_q=home,
        timing=timing,
        nominal_rpy=orient.nominal_rpy,
        wrench_frame=wrench.frame,
        payload_mass_kg=payload.mass_kg,
        payload_com_m=payload.com_m,
        gravity=payload.gravity,
        arm=arm,
        placement=placement,
        program=path.program,
        cell=cell,
        cut=cut,
        cut_setup=cut_setup,
    )


#: ``[cost] smoothness`` of a problem whose load is a predicted cut, when the file gives none,
#: mm^2/rad^2.  The cut's force turns with the feed at every corner and steps at every entry and exit;
#: at the default (1) the posture's rotation about the tool axis chases it waypoint by waypoint, and
#: the joints' jerk holds the feed down.  Measured on benchmarks/bench_forces.py's pocket (2 000 moves):
#: 1.461x length/F and 163 µm from the path at 1, 1.022x and 7.6 µm at 100; on milling_pocket 1465 s
#: against 920 s, for 2 % more first-order load-induced error before the exact compensation removes it.
CUT_SMOOTHNESS = 100.0


def _cut(where: str, data: Mapping[str, Any], base_dir: Path | None, program: Any, tcp2flange: np.ndarray) -> tuple:
    """The cut's sections and the predicted cut of the program (both None without a cut)."""
    from problems.problem_file.cut_section import parse_cut_setup

    setup = parse_cut_setup(where, data, base_dir, program, tcp2flange)
    if setup is None:
        return None, None
    from problems.cutting.program_cut import predict_cut

    return setup, predict_cut(setup, program.waypoints, program.workpiece.program2base[:3, :3])


def shipped_problems() -> tuple[str, ...]:
    """Names of the problems shipped in ``problems/files`` (without ``.toml``)."""
    files = resources.files("problems").joinpath("files")
    return tuple(sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml")))


def load_problem(spec: str | Path) -> Problem:
    """Load a problem by shipped name (see :func:`shipped_problems`) or TOML file path.

    Raises
    ------
    ProblemFileError
        The file is missing, not TOML, or fails validation (the message names the key).
    """
    s = str(spec)
    path = Path(s)
    if path.is_file() or (path.exists() and s not in shipped_problems()):
        from models.robot import read_text_file

        text = read_text_file(path, "problem file (TOML)", ProblemFileError)
        where, base = str(path), path.parent
    elif s in shipped_problems():
        res = resources.files("problems").joinpath(f"files/{s}.toml")
        text = res.read_text(encoding="utf-8")
        folder = Path(str(resources.files("problems").joinpath("files")))
        where, base = f"shipped problem '{s}'", (folder if folder.is_dir() else None)
    else:
        raise ProblemFileError(
            f"problem '{s}': no such file, and not a shipped problem (shipped: {', '.join(shipped_problems())})"
        )
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProblemFileError(f"{where}: not valid TOML: {exc}") from None
    return problem_from_dict(data, where, base)


__all__ = [
    "DEFAULT_RPY",
    "WRENCH_FRAMES",
    "Limits",
    "Problem",
    "ProblemFileError",
    "TimingSettings",
    "load_problem",
    "problem_from_dict",
    "shipped_problems",
]
