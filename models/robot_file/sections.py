"""The tables of a robot file beside the joints: transforms (``[tool]``, ``[frame0_in_base]``,
``[flange_in_frame6]``), ``[controller]`` and ``joint_names``; shared by the DH-table and the
URDF-based readers."""

from __future__ import annotations

from typing import Any
from collections.abc import Mapping

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.description import RobotFileError
from models.transforms import rpy_to_matrix, transform

from .values import VALUES, check_radians, vector

#: Keys of the ``[controller]`` table: the controller's joint angle is ``sign * q + offset``.
_CONTROLLER_KEYS = ("joint_sign", "joint_offset", "joint_offset_deg")
#: Keys of a transform table (``[tool]``, ``[frame0_in_base]``, ``[flange_in_frame6]``).
_FRAME_KEYS = ("xyz", "rpy", "rpy_deg")


def parse_frame_table(where: str, key: str, table: Any) -> np.ndarray:
    """A transform table ``{xyz (m), rpy (rad) | rpy_deg}`` of a robot file as a 4x4 matrix.

    ``R = Rz(yaw) Ry(pitch) Rx(roll)`` with ``rpy = [roll, pitch, yaw]``; missing keys are zero.
    Raises :class:`RobotFileError` naming ``key`` and the offending entry.
    """
    if not isinstance(table, Mapping):
        raise RobotFileError(f"{where}: key '{key}' must be a table")
    w = f"{where}: {key}"
    VALUES.unknown_keys(w, table, _FRAME_KEYS)
    xyz = vector(w, "xyz", table.get("xyz", [0.0, 0.0, 0.0]), 3)
    if np.max(np.abs(xyz)) > PLAUSIBLE_POSITION_MAX_M:
        raise RobotFileError(
            f"{w}: key 'xyz' = {[float(v) for v in xyz]} is implausible (> "
            f"{PLAUSIBLE_POSITION_MAX_M:g} m); lengths are in metres (millimetres given?)"
        )
    if "rpy" in table and "rpy_deg" in table:
        raise RobotFileError(f"{w}: give either 'rpy' (rad) or 'rpy_deg', not both")
    if "rpy_deg" in table:
        rpy = np.radians(vector(w, "rpy_deg", table["rpy_deg"], 3))
    else:
        rpy = vector(w, "rpy", table.get("rpy", [0.0, 0.0, 0.0]), 3)
        for i, v in enumerate(rpy):
            check_radians(w, f"rpy[{i}]", float(v), deg_key="rpy_deg")
    return transform(rpy_to_matrix(rpy), xyz)


def parse_controller(where: str, table: Any) -> dict[str, np.ndarray]:
    """The optional ``[controller]`` table: ``joint_sign`` (6 of +1/-1) and ``joint_offset``
    (rad) or ``joint_offset_deg``: the controller's angle is ``sign * q + offset``."""
    if table is None:
        return {}
    w = f"{where}: controller"
    if not isinstance(table, Mapping):
        raise RobotFileError(f"{where}: key 'controller' must be a table")
    VALUES.unknown_keys(w, table, _CONTROLLER_KEYS)
    out: dict[str, np.ndarray] = {}
    if "joint_sign" in table:
        sign = vector(w, "joint_sign", table["joint_sign"], 6)
        bad = [i for i, v in enumerate(sign) if v not in (1.0, -1.0)]
        if bad:
            raise RobotFileError(
                f"{w}: key 'joint_sign'[{bad[0]}] (joint {bad[0] + 1}) = {sign[bad[0]]:g}; expected +1 or -1"
            )
        out["controller_sign"] = sign
    if "joint_offset" in table and "joint_offset_deg" in table:
        raise RobotFileError(f"{w}: give either 'joint_offset' (rad) or 'joint_offset_deg', not both")
    if "joint_offset_deg" in table:
        out["controller_offset"] = np.radians(vector(w, "joint_offset_deg", table["joint_offset_deg"], 6))
    elif "joint_offset" in table:
        off = vector(w, "joint_offset", table["joint_offset"], 6)
        for i, v in enumerate(off):
            check_radians(w, f"joint_offset[{i}]", float(v), deg_key="joint_offset_deg")
        out["controller_offset"] = off
    return out


def parse_joint_names(where: str, names: Any) -> tuple[str, ...] | None:
    """The optional ``joint_names`` (6 distinct non-empty strings, base to tip)."""
    if names is None:
        return None
    if (
        not isinstance(names, list)
        or len(names) != 6
        or not all(isinstance(n, str) and n for n in names)
        or len(set(names)) != 6
    ):
        raise RobotFileError(
            f"{where}: key 'joint_names' must be a list of 6 distinct non-empty strings, got {names!r}"
        )
    return tuple(names)
