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
:func:`build_export`; a program plan, whose feed a slow-down would change, only with
``slow_down=yes``).  :func:`build_export` returns an :class:`Export`: the files, a status
(:class:`ExportStatus`), a one-line reason and the changes, one short line each, that the command
line prints (slowed down, resampled, decimated, split into parts, streamed or self-contained).  Conventions
of each vendor (joint order, units, signs, zeros): ``docs/export.md``.  Big programs (10^5-10^6
samples): above its limit each format writes numbered parts (:func:`part_ranges`,
:func:`part_label`) and a main file, or a stream, as its controller needs (``docs/export.md``,
"Big programs").

The package only re-exports; each concept has its module: the errors (``errors.py``), the data a
format writes (``data.py``), where it comes from (``sources.py``), the numbered parts
(``parts.py``), the registry of formats (``registry.py``), what a controller runs and the
tolerances (``motion.py``), the checks (``limits.py``), the options' validators (``options.py``)
and the files of an export (``build.py``).
"""

from __future__ import annotations

from typing import Any

from planner.export.build import Export, ExportStatus, build_export, export_files
from planner.export.data import VENDOR_FORMATS, ExportData, controller_warning, header_lines
from planner.export.errors import ExportError, ExportLimitError, ExportRefusal
from planner.export.limits import check_motion, verify_limits
from planner.export.motion import (
    EXPORT_FD_TOL,
    EXPORT_LIMIT_TOL,
    EXPORT_POSITION_TOL,
    EXPORT_TIME_TOL,
    ControllerMotion,
    Interpolation,
)
from planner.export.options import SLOW_DOWN_CHOICES, SLOW_DOWN_OPTION, choice, counted, network_host, ranged
from planner.export.parts import PART_DIGITS, part_label, part_ranges
from planner.export.registry import (
    BUILTIN_FORMATS,
    EXPORT_PATH_VARIABLE,
    ExportFormat,
    format_names,
    formats,
    load_formats,
    register_format,
)
from planner.export.sources import data_from_plan, data_from_run

__all__ = [
    "EXPORT_FD_TOL",
    "EXPORT_FORMATS",
    "EXPORT_LIMIT_TOL",
    "EXPORT_PATH_VARIABLE",
    "EXPORT_POSITION_TOL",
    "EXPORT_TIME_TOL",
    "SLOW_DOWN_CHOICES",
    "SLOW_DOWN_OPTION",
    "ControllerMotion",
    "Export",
    "ExportData",
    "ExportError",
    "ExportFormat",
    "ExportLimitError",
    "ExportRefusal",
    "ExportStatus",
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
    "header_lines",
    "format_names",
    "formats",
    "load_formats",
    "network_host",
    "PART_DIGITS",
    "part_label",
    "part_ranges",
    "ranged",
    "register_format",
    "verify_limits",
]


def __getattr__(name: str) -> Any:
    """``EXPORT_FORMATS``: the ``--format`` names, built-in and plug-in, sorted (the modules imported
    on first use, :func:`load_formats`)."""
    if name == "EXPORT_FORMATS":
        return tuple(sorted(formats()))
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
