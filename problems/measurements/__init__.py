"""Measurement files: loading, validation and writing (see ``docs/measurement-file.md``).

A measurement file is a CSV table with one header row and one row per
measurement, in measurement order.  Lines starting with ``#`` are comments.
Column names carry their unit as a suffix (``x_mm``, ``q1_deg``, ``fx_N``);
a plain name is SI (m, rad, N, N*m, s, deg C).  Inside the library everything
is SI.

Two CSV dialects are read (``dialect``): ``comma`` (``,`` separator, ``.``
decimal point) and ``semicolon`` (``;`` separator, decimal comma ``1,5``; a
spreadsheet's or tracker software's export in a German/French locale); ``auto``
tells them apart by the header line and records that it did in
:attr:`Measurements.notes`.  Joint columns may carry other names than
``q1..q6`` (``joint_names``: the ROS preset ``"ros-ur"`` or six names).  Besides this
``compplan`` format, ``file_format`` reads a tracker export of targets and deviations
(``tracker-dif``: ``step_order, x_t.., x_dif.., joint_1..``; ``auto`` recognises its header).

Every problem is an :class:`~models.errors.InputError` whose one-line message
names the file, the row (file line number) or column, the value and what was
expected; nothing is dropped silently.  The library prints nothing: what it
decided on its own (a detected dialect, date-times read as times, a joint-name
mapping) is stored in :attr:`Measurements.notes` for the caller to show.

Modules
-------
:mod:`~problems.measurements.columns`
    Column names and their units, column groups, ``joint_names`` presets, CSV dialects,
    file formats.
:mod:`~problems.measurements.header`
    Header names to quantities and units (:func:`resolve_joint_names`, the unknown-column
    message listing every format's columns).
:mod:`~problems.measurements.table`
    The :class:`Measurements` table and :func:`sigma_rms`.
:mod:`~problems.measurements.cells`
    Cells: numbers in either dialect, date-times, the ``t`` column.
:mod:`~problems.measurements.parse`
    :func:`read_measurements`, :func:`parse_measurements`: dialect and format detection,
    building the table.
:mod:`~problems.measurements.tracker`
    The tracker-dif formats (measured point = target + dif, the target kept).
:mod:`~problems.measurements.validation`
    :func:`validate` and the plausibility limits (``PLAUSIBLE_*``).
:mod:`~problems.measurements.write`
    :func:`measurements_to_csv`, :func:`commands_csv`.

Dependencies run one way: ``columns`` and ``table`` and ``cells`` import nothing of
the package; ``header``, ``validation`` and ``write`` use ``columns`` and ``table``;
``tracker`` uses those and ``cells``; ``parse`` uses all but ``write``.
"""

from __future__ import annotations


from .columns import (
    DIALECT_CHOICES,
    FORMAT_CHOICES,
    JOINT_NAME_PRESETS,
    POSITION_COLUMNS,
    TRACKER_COLUMNS,
    TRACKER_FORMATS,
)
from .header import resolve_joint_names
from .parse import parse_measurements, read_measurements
from .table import Measurements
from .validation import PLAUSIBLE_FORCE_MAX_N, PLAUSIBLE_MOMENT_MAX_NM, PLAUSIBLE_NOMINAL_DEVIATION_M
from .write import commands_csv, measurements_to_csv

__all__ = [
    # the table
    "Measurements",
    # reading
    "read_measurements",
    "parse_measurements",
    "resolve_joint_names",
    # checks and their limits
    "PLAUSIBLE_FORCE_MAX_N",
    "PLAUSIBLE_MOMENT_MAX_NM",
    "PLAUSIBLE_NOMINAL_DEVIATION_M",
    # writing
    "measurements_to_csv",
    "commands_csv",
    # the format's vocabulary
    "POSITION_COLUMNS",
    "DIALECT_CHOICES",
    "JOINT_NAME_PRESETS",
    "FORMAT_CHOICES",
    "TRACKER_COLUMNS",
    "TRACKER_FORMATS",
]
