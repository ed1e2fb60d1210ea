"""Plug-in discovery, one rule for every registry.

A registry of the product (effects, IK families, timing methods, export formats) is a package
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
timing methods         ``problems.timing``            ``COMPPLAN_TIMING_PATH``
export formats         ``planner.export``             ``COMPPLAN_EXPORT_PATH``
=====================  =============================  ===========================

A folder that does not exist is an error naming the variable and the folder (a typo would
otherwise drop the plug-in silently).
"""

from __future__ import annotations

import importlib
import os
import pkgutil
from pathlib import Path
from typing import Iterable, MutableSequence

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
            raise InputError(f"${variable}: {p!r} is not a folder (expected folders of plug-in modules, "
                             f"separated by {os.pathsep!r})")
        out.append(p)
    return out


def import_plugins(package: str, path: MutableSequence[str], variable: str,
                   skip: Iterable[str] = (), first: Iterable[str] = ()) -> list[str]:
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
    """
    for folder in plugin_folders(variable):
        if folder not in path:
            path.append(folder)
    names = list(first)
    for m in pkgutil.iter_modules(path):
        if m.name not in names and m.name not in set(skip):
            names.append(m.name)
    for name in names:
        importlib.import_module(f"{package}.{name}")
    return names
