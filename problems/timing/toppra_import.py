"""toppra, imported on demand and without ``matplotlib.pyplot``.

toppra imports ``matplotlib.pyplot`` when it is imported (``toppra.algorithm.algorithm`` and
``toppra.parametrizer``), for plotting helpers this package never calls.  pyplot is the most
expensive part of importing toppra (0.2-0.3 s: its backend machinery and global state), and
nothing else in compplan uses it (the report draws on matplotlib's ``Figure`` and the Agg
canvas).  :func:`import_toppra` imports toppra with a stand-in for pyplot in ``sys.modules``
for the duration of that import: toppra's ``plt`` is the stand-in, which imports the real
pyplot on its first use (never, in compplan), and the stand-in leaves ``sys.modules`` at once,
so any later ``import matplotlib.pyplot`` is the real one.  A pyplot already imported is used
as it is.
"""

from __future__ import annotations

import importlib
import sys
import threading
from types import ModuleType
from typing import Any

__all__ = ["import_toppra"]

#: The module toppra imports only for its plotting helpers.
_PYPLOT = "matplotlib.pyplot"
_LOCK = threading.Lock()


class _PyplotOnUse(ModuleType):
    """Stands in for ``matplotlib.pyplot`` in the modules that imported it while it was in
    ``sys.modules``: its first attribute read imports the real pyplot and reads from it."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):  # the import system's probes: not pyplot's names
            raise AttributeError(name)
        return getattr(importlib.import_module(_PYPLOT), name)


def import_toppra() -> ModuleType:
    """The ``toppra`` package (with ``toppra.algorithm`` and ``toppra.constraint``), imported on
    the first call without importing ``matplotlib.pyplot``."""
    module = sys.modules.get("toppra")
    if module is not None:
        return module
    with _LOCK:
        stand_in = None
        if _PYPLOT not in sys.modules:
            stand_in = sys.modules[_PYPLOT] = _PyplotOnUse(_PYPLOT)
        try:
            return importlib.import_module("toppra")
        finally:
            if stand_in is not None and sys.modules.get(_PYPLOT) is stand_in:
                del sys.modules[_PYPLOT]
