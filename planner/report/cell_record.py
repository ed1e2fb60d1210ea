"""The cell a run recorded (``summary.json`` key ``problem.cell``), read back and checked.

Light (no plotting imports): :mod:`planner.summary_schema` checks the key with :func:`cell_block`
when any command reads a summary, and :mod:`planner.report.cell_view` draws from its result.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from models.errors import InputError

__all__ = ["cell_block"]


def _vec(where: str, v: Any, n: int) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (n,) or not np.all(np.isfinite(a)) or isinstance(v, (str, bytes)):
        raise InputError(f"{where} = {v!r}; expected {n} finite numbers")
    return a


def cell_block(value: Any, where: str) -> tuple[float, list[dict[str, Any]]]:
    """The cell recorded in a run's summary (``problem.cell``), checked: clearance and objects.

    Parameters
    ----------
    value : mapping
        ``{"clearance": m, "objects": [{"name", "shape", "size" | "file", "scale", "xyz", "rpy",
        "role"}, ...]}`` (:meth:`problems.cell.Cell.to_dict`).
    where : str
        The key, for messages (``problem.cell``).

    Returns
    -------
    clearance : float
        m.
    objects : list of dict
        Per object: ``name``, ``shape``, ``role``, ``object2base`` (4, 4), and its kind's keys
        (:meth:`models.collision.shapes.Shape.check_record`: ``size`` (ndarray, m), or a mesh's
        ``file`` (str) and ``scale`` (float)).

    Raises
    ------
    InputError
        Naming the key (``problem.cell.objects[1].size``), the value and what was expected.
    """
    from models.transforms import rpy_to_matrix, transform
    from models.collision.shapes import shape_class, shape_kinds
    from problems.cell import OBJECT_ROLES

    if not isinstance(value, Mapping):
        raise InputError(f"{where} = {value!r}; expected a table (the problem's [cell])")
    c = value.get("clearance")
    if isinstance(c, bool) or not isinstance(c, (int, float)) or not np.isfinite(c) or c < 0:
        raise InputError(f"{where}.clearance = {c!r}; expected a number >= 0 (m)")
    raw = value.get("objects")
    if not isinstance(raw, list):
        raise InputError(f"{where}.objects = {raw!r}; expected a list of objects")
    out = []
    for i, o in enumerate(raw):
        key = f"{where}.objects[{i}]"
        if not isinstance(o, Mapping):
            raise InputError(f"{key} = {o!r}; expected a table")
        name, shape, role = o.get("name"), o.get("shape"), o.get("role", "obstacle")
        if not isinstance(name, str) or not name:
            raise InputError(f"{key}.name = {name!r}; expected a non-empty string")
        if shape not in shape_kinds():
            raise InputError(f"{key}.shape = {shape!r}; expected one of {list(shape_kinds())}")
        if role not in OBJECT_ROLES:
            raise InputError(f"{key}.role = {role!r}; expected one of {list(OBJECT_ROLES)}")
        T = transform(rpy_to_matrix(_vec(f"{key}.rpy", o.get("rpy"), 3)), _vec(f"{key}.xyz", o.get("xyz"), 3))
        rec: dict[str, Any] = {"name": name, "shape": shape, "role": role, "object2base": T}
        rec.update(shape_class(shape).check_record(o, key, _vec))
        out.append(rec)
    return float(c), out
