"""Plausibility of identified geometry: a model identified with the wrong robot file.

A real arm is built to its drawing within millimetres; geometric "corrections" of centimetres or
degrees mean the data come from another arm than the robot file describes.  Identification
(`problems/identify/engine.py`) and planning with a model (`ArmModel.caveats`) both say so.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .effects import GROUP_SLICES, PARAM_NAMES, make_layout
from .robot import Robot

#: An identified DH length correction (``da``, ``dd``) larger than this is implausible for the
#: declared robot (m): a real arm is built to its drawing within millimetres, so such a
#: "correction" means the data come from another arm than the robot file describes.
IMPLAUSIBLE_LENGTH_ERROR_M = 0.020
#: The same for an angle correction (``dalpha``, ``dtheta``, ``dbeta``, joint offsets), rad (2 deg).
IMPLAUSIBLE_ANGLE_ERROR_RAD = float(np.radians(2.0))
#: Parameter groups checked against those thresholds.
GEOMETRY_GROUPS = ("joint_offset.dtheta", "geometric.da", "geometric.dalpha", "geometric.dd", "geometric.dbeta")


def implausible_geometry(robot: Robot, theta: np.ndarray, held: Sequence[int] = ()) -> str | None:
    """A message naming the identified geometry corrections that are implausibly large for the
    declared robot (:data:`IMPLAUSIBLE_LENGTH_ERROR_M`, :data:`IMPLAUSIBLE_ANGLE_ERROR_RAD`), or
    None.  Parameters in ``held`` (indices) stay at their nominal values and are not checked.

    Parameters
    ----------
    robot : Robot
        The declared robot (named in the message).
    theta : ndarray, shape (N_PARAMS,)
        Identified parameters, SI.
    """
    layout = make_layout(robot)
    held_set = set(int(i) for i in held)
    found: list[tuple[float, str]] = []
    for g in GEOMETRY_GROUPS:
        for i in range(GROUP_SLICES[g].start, GROUP_SLICES[g].stop):
            if i in held_set:
                continue
            v = float(theta[i] - layout.nominal[i])
            if layout.units[i] == "m" and abs(v) > IMPLAUSIBLE_LENGTH_ERROR_M:
                found.append((abs(v) / IMPLAUSIBLE_LENGTH_ERROR_M, f"{PARAM_NAMES[i]} = {v * 1e3:.1f} mm"))
            elif layout.units[i] == "rad" and abs(v) > IMPLAUSIBLE_ANGLE_ERROR_RAD:
                found.append((abs(v) / IMPLAUSIBLE_ANGLE_ERROR_RAD, f"{PARAM_NAMES[i]} = {np.degrees(v):.2f} deg"))
    if not found:
        return None
    found.sort(key=lambda x: -x[0])
    names = ", ".join(t for _r, t in found[:6]) + (f" and {len(found) - 6} more" if len(found) > 6 else "")
    return (
        f"implausible geometry for robot '{robot.name}': the identified corrections {names} exceed "
        f"{IMPLAUSIBLE_LENGTH_ERROR_M * 1e3:g} mm (lengths) / {np.degrees(IMPLAUSIBLE_ANGLE_ERROR_RAD):g} deg "
        "(angles), far more than a real arm differs from its drawing; the data probably come from another arm "
        "than the robot file describes: check --robot (the robot file) before using this model"
    )
