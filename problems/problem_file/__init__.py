"""The problem-file format (``docs/problem-file.md``): one validating parser per section, split by job.

A problem file (TOML) has the sections header (``name``, ``description``, ``source``), ``[robot]``
(with its tool), ``[orientation]``, ``[path]``, ``[wrench]``, ``[payload]``, ``[limits]``, ``[cost]``,
``[solver]``, ``[branch]``, ``[timing]``, ``[placement]``, ``[workpiece]`` and ``[cell]``. Each
``parse_*`` function validates one section of the parsed document and returns its values in SI units
(m, rad, N, N*m, kg, s); :func:`problems.problem.problem_from_dict` calls them in file order and
assembles the :class:`~problems.problem.Problem`.

The modules: ``values.py`` (:class:`ProblemFileError`, the keys each table may hold
(``TABLE_KEYS``), the value kinds: the one reader of :mod:`models.tables` bound to
:class:`ProblemFileError`, the angle and plausibility checks), ``sections.py`` (header,
``[robot]``, ``[orientation]``, ``[wrench]``, ``[payload]``, ``[limits]``, ``[cost]``,
``[solver]``, ``[branch]``, ``[placement]`` and their types), ``path_section.py`` (``[path]``),
``program_section.py`` (a CAM program as the path, with ``[workpiece]``), ``timing_section.py``
(``[timing]`` against the timing registry) and ``cell_section.py`` (``[cell]`` and the tool's
collision geometry). The names here are the package's public surface; the program's and the
cell's are imported on first use.

Every error is a :class:`ProblemFileError` naming the file, the key (dotted, e.g.
``path.points``) and, for tables of rows, the row; the value found; and what was expected.
"""

from typing import TYPE_CHECKING

from models.lazy import lazy_exports
from problems.problem_file.path_section import is_program_path, parse_path
from problems.problem_file.sections import (
    DEFAULT_RPY,
    WRENCH_FRAMES,
    Limits,
    parse_branch,
    parse_cost,
    parse_header,
    parse_limits,
    parse_orientation,
    parse_payload,
    parse_placement,
    parse_robot,
    parse_solver,
    parse_wrench,
)
from problems.problem_file.timing_section import TimingSettings, check_timing, parse_timing
from problems.problem_file.values import (
    PLAUSIBLE_JOINT_MAX_RAD,
    PLAUSIBLE_JOINT_STEP_MAX_RAD,
    PLAUSIBLE_RPY_MAX_RAD,
    ProblemFileError,
)

if TYPE_CHECKING:
    from problems.problem_file.cell_section import parse_cell, parse_tool_geometry
    from problems.problem_file.program_section import PROGRAM_KINDS, ProgramSection, check_reach, parse_program

#: The submodule defining each name imported on first use (PEP 562).
_LAZY = {
    **dict.fromkeys(("parse_cell", "parse_tool_geometry"), "cell_section"),
    **dict.fromkeys(("PROGRAM_KINDS", "ProgramSection", "check_reach", "parse_program"), "program_section"),
}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = [
    "DEFAULT_RPY",
    "PLAUSIBLE_JOINT_MAX_RAD",
    "PLAUSIBLE_JOINT_STEP_MAX_RAD",
    "PLAUSIBLE_RPY_MAX_RAD",
    "PROGRAM_KINDS",
    "WRENCH_FRAMES",
    "Limits",
    "ProblemFileError",
    "ProgramSection",
    "TimingSettings",
    "check_reach",
    "check_timing",
    "is_program_path",
    "parse_branch",
    "parse_cell",
    "parse_cost",
    "parse_header",
    "parse_limits",
    "parse_orientation",
    "parse_path",
    "parse_payload",
    "parse_placement",
    "parse_program",
    "parse_robot",
    "parse_solver",
    "parse_timing",
    "parse_tool_geometry",
    "parse_wrench",
]
