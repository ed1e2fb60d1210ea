"""The registry of export formats: :class:`ExportFormat`, :func:`register_format`, and the lazy
import of the format modules (those of :mod:`planner.export` and of the folders named by
``$COMPPLAN_EXPORT_PATH``) when the formats are first asked for (:func:`formats`); the command
line's names (:func:`format_names`) without importing a format module."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any
from collections.abc import Callable, Mapping

from models.errors import PluginError
from models.plugins import import_plugins, plugin_folders

from planner.export.data import ExportData

if TYPE_CHECKING:
    from planner.export.motion import ControllerMotion

__all__ = [
    "BUILTIN_FORMATS",
    "EXPORT_PATH_VARIABLE",
    "ExportFormat",
    "format_names",
    "formats",
    "load_formats",
    "register_format",
]


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
    changes : callable or None
        ``changes(data, options) -> tuple of str``: what the files make of the (checked, maybe
        slowed) trajectory, one short line each (resampled to the controller's period, decimated,
        split into parts, streamed or one self-contained program); it raises
        :class:`~planner.export.errors.ExportRefusal` for options that cannot write it (a streamed
        program without its host).  None: nothing to say.
    """

    name: str
    suffixes: tuple[str, ...]
    write: Callable[[ExportData, str, Mapping[str, Any]], Mapping[str, str | bytes]]
    options: Mapping[str, tuple[Any, str, Callable[[Any], Any]]]
    description: str
    folder: bool = False
    motion: Callable[[ExportData, Mapping[str, Any]], ControllerMotion] | None = None
    timing_options: tuple[str, ...] = ()
    changes: Callable[[ExportData, Mapping[str, Any]], tuple[str, ...]] | None = None


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
        import_plugins(__package__, sys.modules[__package__].__path__, EXPORT_PATH_VARIABLE)
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
