"""Plug-in discovery, one rule for every registry.

A registry of the product (effects, IK families, shape kinds, timing methods, export formats) is a package
whose modules register themselves when imported. :func:`import_plugins` imports every module
of such a package and every ``*.py`` module in the folders named by the registry's environment
variable (``os.pathsep``-separated), as ``<package>.<module>``: a plug-in outside the installed
product is one file in one folder, written as the built-in modules are (relative imports such
as ``from .base import Effect`` work), with no edit anywhere else.

=====================  =============================  ===========================
registry               package                        environment variable
=====================  =============================  ===========================
effects                ``models.effects``             ``COMPPLAN_EFFECT_PATH``
IK families            ``models.ik``                  ``COMPPLAN_IK_PATH``
shape kinds            ``models.collision.shapes``    ``COMPPLAN_SHAPE_PATH``
timing methods         ``problems.timing``            ``COMPPLAN_TIMING_PATH``
export formats         ``planner.export``             ``COMPPLAN_EXPORT_PATH``
=====================  =============================  ===========================

A folder that does not exist is an error naming the variable and the folder (a typo would
otherwise drop the plug-in silently); so is a plug-in module named like a module of the package
or of an earlier plug-in folder (one of the two would be ignored).  A plug-in module that fails
to import (a syntax error, a missing name, a registration refused) is an :class:`InputError`
naming the variable and the module's file, with the original error chained: the command line
prints it as one line.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
from collections.abc import Iterable, MutableSequence
from pathlib import Path

from models.errors import InputError

__all__ = ["import_plugins", "plugin_folders"]


def plugin_folders(variable: str) -> list[str]:
    """The folders named by the environment variable ``variable`` (``os.pathsep``-separated).

    Raises
    ------
    InputError
        A named folder does not exist or is not a folder: the message names the variable and
        the folder.
    """
    out = []
    for p in os.environ.get(variable, "").split(os.pathsep):
        if not p:
            continue
        if not Path(p).is_dir():
            raise InputError(
                f"${variable}: {p!r} is not a folder (expected folders of plug-in modules, separated by {os.pathsep!r})"
            )
        out.append(p)
    return out


def import_plugins(
    package: str, path: MutableSequence[str], variable: str, skip: Iterable[str] = (), first: Iterable[str] = ()
) -> list[str]:
    """Import the modules of a registry package and of its plug-in folders.

    Parameters
    ----------
    package : str
        The package's name (``__name__`` of its ``__init__``).
    path : list of str
        The package's ``__path__``; the folders of ``$variable`` are appended to it, so a
        plug-in module is imported as ``<package>.<module>``.
    variable : str
        The environment variable naming the plug-in folders.
    skip : iterable of str
        Modules of the package that are not plug-ins (the registry itself, helpers).
    first : iterable of str
        Modules imported first, in this order (registration order matters where a registry
        tries its entries in order, or lays out parameters in it); the others follow as
        :func:`pkgutil.iter_modules` lists them: the package's own in name order, then each
        plug-in folder's in name order.

    Returns
    -------
    list of str
        The names of the modules imported, in import order.

    Raises
    ------
    InputError
        A folder of ``$variable`` is not a folder; a plug-in module has the name of a module
        of the package or of an earlier folder's; a plug-in module fails to import (the
        message names the variable and the file; the original error is its ``__cause__``).
    """
    skip, first = set(skip), tuple(first)
    own = [m.name for m in pkgutil.iter_modules(list(path))]
    names = list(first) + [n for n in own if n not in skip and n not in first]
    plugins: dict[str, Path] = {}
    for folder in dict.fromkeys(plugin_folders(variable)):
        for m in pkgutil.iter_modules([folder]):
            where = Path(folder) / (m.name if m.ispkg else f"{m.name}.py")
            if m.name in own or m.name in plugins:
                other = "a module of " + package if m.name in own else str(plugins[m.name])
                raise InputError(f"${variable}: plug-in module {where} has the name of {other}; rename it")
            plugins[m.name] = where
            names.append(m.name)
        if folder not in path:
            path.append(folder)
    for name in names:
        try:
            importlib.import_module(f"{package}.{name}")
        except Exception as exc:
            if name not in plugins:
                raise
            raise InputError(
                f"${variable}: plug-in module {plugins[name]} failed to import ({type(exc).__name__}: {exc})"
            ) from exc
    return names
