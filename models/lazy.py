"""Names a package re-exports from its submodules, imported on first use (PEP 562).

A package that re-exports many names would otherwise import every submodule (CasADi,
matplotlib, SciPy) when it is imported, and ``compplan --version`` would pay for them.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, namespace: dict[str, Any], table: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package whose names load on first use.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    namespace : dict
        The package's ``globals()``: a name, once imported, is kept there.
    table : mapping of str to str
        Re-exported name -> the submodule (relative to ``package``) that defines it.

    Returns
    -------
    (callable, callable)
        ``__getattr__(name)`` (raises ``AttributeError`` for a name not in ``table``) and
        ``__dir__()``.
    """

    def getattr_(name: str) -> Any:
        if name in table:
            value = getattr(importlib.import_module(f"{package}.{table[name]}"), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def dir_() -> list[str]:
        return sorted(set(namespace) | set(table))

    return getattr_, dir_
