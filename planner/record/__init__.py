"""The run record: what a run produced, owned by neither the plan nor the report.

:class:`RunRecord` holds the typed content of a run's ``summary.json`` and the columns of its CSV
files (:mod:`planner.record.columns` names them once, for the writer and the reader).  The plan
produces it (:func:`planner.plan_record.record_from_plan`), :func:`read_record` reads it back from
a run folder (:mod:`planner.record.read`), and the report reads only it.  Importing this package
imports neither the plan nor the report.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from models.lazy import lazy_exports

if TYPE_CHECKING:
    from planner.record.columns import (
        DYNAMIC_COLUMNS,
        DYNAMIC_KEY,
        LINK_COLUMNS,
        PATH_COLUMNS,
        PROGRAM_KEY,
        PROGRAM_PATH_COLUMNS,
        PROGRAM_TRAJECTORY_COLUMNS,
        TRAJECTORY_COLUMNS,
        TRAJECTORY_FILES,
        WAYPOINT_COLUMNS,
        trajectory_file,
    )
    from planner.record.read import read_record, recorded_model
    from planner.record.record import (
        ProgramRecord,
        RunRecord,
        Workpiece,
        method_name,
        method_order,
        to_program_frame,
    )

#: The submodule defining each name re-exported here, imported on first use (PEP 562): the column
#: names (:mod:`planner.record.columns`) load without the reader's imports (the arm model, CasADi).
_LAZY = {
    name: module
    for module, names in {
        "columns": (
            "DYNAMIC_COLUMNS",
            "DYNAMIC_KEY",
            "LINK_COLUMNS",
            "PATH_COLUMNS",
            "PROGRAM_KEY",
            "PROGRAM_PATH_COLUMNS",
            "PROGRAM_TRAJECTORY_COLUMNS",
            "TRAJECTORY_COLUMNS",
            "TRAJECTORY_FILES",
            "WAYPOINT_COLUMNS",
            "trajectory_file",
        ),
        "read": ("read_record", "recorded_model"),
        "record": ("ProgramRecord", "RunRecord", "Workpiece", "method_name", "method_order", "to_program_frame"),
    }.items()
    for name in names
}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = [
    "DYNAMIC_COLUMNS",
    "DYNAMIC_KEY",
    "LINK_COLUMNS",
    "PATH_COLUMNS",
    "PROGRAM_KEY",
    "PROGRAM_PATH_COLUMNS",
    "PROGRAM_TRAJECTORY_COLUMNS",
    "ProgramRecord",
    "RunRecord",
    "TRAJECTORY_COLUMNS",
    "TRAJECTORY_FILES",
    "WAYPOINT_COLUMNS",
    "Workpiece",
    "method_name",
    "method_order",
    "read_record",
    "recorded_model",
    "to_program_frame",
    "trajectory_file",
]
