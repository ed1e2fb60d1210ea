"""The grid of candidate base placements of a placement study.

A *placement* puts the robot's base frame in the *cell frame*: the frame the problem's
path, orientations and base-frame wrench are written in.  The problem as written is the
placement at the origin (base frame = cell frame).  A placement is five numbers
``[x, y, z, yaw, tilt]`` (m, m, m, rad, rad) and its transform (pytransform3d naming:
``base2cell`` maps base coordinates to cell coordinates) is::

    base2cell = Trans(x, y, z) @ Rot_z(yaw) @ Rot_x(tilt)

``tilt`` = 0 is a floor mount, pi/2 a wall mount, pi a ceiling mount.  A grid is the
Cartesian product of one value list per axis (``GRID_AXES``), given in a problem file's
``[placement]`` table or on the command line (``--grid``), with the unit in the key:
``x_m``, ``y_m``, ``z_m`` (metres) and ``yaw_deg``, ``tilt_deg`` (degrees).  Each axis is a
single value or an inclusive range ``start:stop:count`` (``[start, stop, count]`` in a file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any
from collections.abc import Mapping

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError
from models.tables import TableReader

#: The grid axes: key (unit in the name), SI scale from the key's unit, what it is.
GRID_AXES: dict[str, tuple[float, str]] = {
    "x_m": (1.0, "base origin x in the cell frame"),
    "y_m": (1.0, "base origin y in the cell frame"),
    "z_m": (1.0, "base origin z in the cell frame"),
    "yaw_deg": (math.pi / 180.0, "base rotation about the cell z axis"),
    "tilt_deg": (math.pi / 180.0, "base rotation about its own x axis (90: wall, 180: ceiling)"),
}
#: Keys of the ``[placement]`` table that are not axes.
OTHER_KEYS = ("top",)
#: Most placements in one grid (a larger study is split into several runs).
MAX_PLACEMENTS = 10_000_000
#: Most values on one axis.
MAX_AXIS_VALUES = 100_000
#: Default number of best placements planned in full.
DEFAULT_TOP = 3
#: Largest accepted ``top``.
MAX_TOP = 10


class PlacementGridError(InputError):
    """A malformed grid: the message names the key, the value and what was expected."""


#: The value kinds of a grid.
VALUES = TableReader(PlacementGridError, lists=(list, tuple))


@dataclass(frozen=True)
class PlacementGrid:
    """Candidate base placements (SI units).

    Attributes
    ----------
    axes : dict str -> ndarray
        Values per axis key of :data:`GRID_AXES`, in SI units (m, rad); each 1-D.
    top : int
        How many of the best placements are planned in full.
    """

    axes: dict[str, np.ndarray]
    top: int = DEFAULT_TOP

    @property
    def shape(self) -> tuple[int, ...]:
        """Values per axis, in the order of :data:`GRID_AXES`."""
        return tuple(len(self.axes[k]) for k in GRID_AXES)

    @property
    def size(self) -> int:
        """Number of placements."""
        return math.prod(self.shape)  # Python integers: no overflow

    def placements(self) -> np.ndarray:
        """Every placement ``[x, y, z, yaw, tilt]`` (m, rad), shape (P, 5), x fastest.

        The order is fixed (x varies fastest, then y, z, yaw, tilt), so a placement's
        index is the same in every run of the same grid.
        """
        vals = [self.axes[k] for k in GRID_AXES]
        mesh = np.meshgrid(*vals, indexing="ij")
        # x fastest: transpose so the last axis of the ravel is x
        return np.stack([m.transpose(4, 3, 2, 1, 0).ravel() for m in mesh], axis=1)

    def describe(self) -> dict[str, Any]:
        """The grid in its edge units (m, deg) for summaries."""
        out: dict[str, Any] = {}
        for k, (scale, _) in GRID_AXES.items():
            v = self.axes[k] / scale
            out[k] = [float(v[0]), float(v[-1]), int(len(v))] if len(v) > 1 else float(v[0])
        out["placements"] = self.size
        out["top"] = self.top
        return out


def base2cell(placements: np.ndarray) -> np.ndarray:
    """Homogeneous ``base2cell`` transforms of placements (P, 5) -> (P, 4, 4).

    ``base2cell = Trans(x, y, z) Rot_z(yaw) Rot_x(tilt)``: maps base-frame coordinates to
    cell-frame coordinates.
    """
    p = np.atleast_2d(np.asarray(placements, dtype=float))
    cy, sy = np.cos(p[:, 3]), np.sin(p[:, 3])
    ct, st = np.cos(p[:, 4]), np.sin(p[:, 4])
    T = np.zeros((len(p), 4, 4))
    # Rz(yaw) @ Rx(tilt)
    T[:, 0, 0], T[:, 0, 1], T[:, 0, 2] = cy, -sy * ct, sy * st
    T[:, 1, 0], T[:, 1, 1], T[:, 1, 2] = sy, cy * ct, -cy * st
    T[:, 2, 1], T[:, 2, 2] = st, ct
    T[:, :3, 3] = p[:, :3]
    T[:, 3, 3] = 1.0
    return T


def cell2base(placements: np.ndarray) -> np.ndarray:
    """Inverse of :func:`base2cell`: maps cell-frame coordinates to the base frame, (P, 4, 4)."""
    T = base2cell(placements)
    R = T[:, :3, :3].transpose(0, 2, 1)
    out = np.zeros_like(T)
    out[:, :3, :3] = R
    out[:, :3, 3] = -np.einsum("pij,pj->pi", R, T[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out


def describe_placement(p: np.ndarray) -> dict[str, float]:
    """One placement (5,) in its edge units: ``x_m, y_m, z_m, yaw_deg, tilt_deg``."""
    return {k: float(p[i] / GRID_AXES[k][0]) for i, k in enumerate(GRID_AXES)}


def placement_label(p: np.ndarray) -> str:
    """A short human label of one placement, e.g. ``x=0.30 m, y=-0.20 m, yaw=45 deg``
    (z and tilt only where non-zero)."""
    d = describe_placement(p)
    parts = [f"x={d['x_m']:.3g} m", f"y={d['y_m']:.3g} m"]
    if d["z_m"]:
        parts.append(f"z={d['z_m']:.3g} m")
    parts.append(f"yaw={d['yaw_deg']:.4g} deg")
    if d["tilt_deg"]:
        parts.append(f"tilt={d['tilt_deg']:.4g} deg")
    return ", ".join(parts)


# --------------------------------------------------------------------------------------
# Parsing
# --------------------------------------------------------------------------------------


def axis_values(key: str, v: Any, where: str = "grid") -> np.ndarray:
    """One axis from a number or ``[start, stop, count]`` (edge units) -> SI values (n,).

    Raises
    ------
    PlacementGridError
        Unknown key, not a number, a count < 1 or > :data:`MAX_AXIS_VALUES`, or
        ``start > stop``.
    """
    if key not in GRID_AXES:
        raise PlacementGridError(f"{where}: unknown grid key {key!r}; allowed: {list(GRID_AXES)}")
    scale = GRID_AXES[key][0]
    if isinstance(v, (list, tuple)):
        if len(v) != 3:
            raise PlacementGridError(f"{where}: key '{key}' must be a number or [start, stop, count], got {v!r}")
        a, b = VALUES.number(where, f"{key}[0]", v[0]), VALUES.number(where, f"{key}[1]", v[1])
        n = v[2]
        if isinstance(n, float) and n.is_integer():
            n = int(n)
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_AXIS_VALUES:
            raise PlacementGridError(
                f"{where}: key '{key}' count must be an integer in [1, {MAX_AXIS_VALUES}], got {v[2]!r}"
            )
        if a > b:
            raise PlacementGridError(f"{where}: key '{key}' start {a:g} is above stop {b:g}")
        if n == 1 and a != b:
            raise PlacementGridError(f"{where}: key '{key}' has count 1 but start {a:g} != stop {b:g}")
        vals = np.linspace(a, b, n)
    else:
        vals = np.array([VALUES.number(where, key, v)])
    if key.endswith("_m") and np.max(np.abs(vals)) > PLAUSIBLE_POSITION_MAX_M:
        raise PlacementGridError(
            f"{where}: key '{key}' reaches {float(np.max(np.abs(vals))):g} m, implausible for a robot base in a cell "
            f"(> {PLAUSIBLE_POSITION_MAX_M:g} m); the grid is in metres (millimetres given?)"
        )
    return vals * scale


def grid_from_table(
    tab: Mapping[str, Any], where: str = "[placement]", base: PlacementGrid | None = None
) -> PlacementGrid:
    """A grid from a ``[placement]`` table (keys of :data:`GRID_AXES` and ``top``), over
    ``base`` (every axis not given keeps ``base``'s values, or 0)."""
    VALUES.unknown_keys(where, tab, list(GRID_AXES) + list(OTHER_KEYS))
    axes = {k: (base.axes[k] if base is not None else np.zeros(1)) for k in GRID_AXES}
    for k, v in tab.items():
        if k in GRID_AXES:
            axes[k] = axis_values(k, v, where)
    top = base.top if base is not None else DEFAULT_TOP
    if "top" in tab:
        top = VALUES.integer(where, "top", tab["top"], 0, MAX_TOP)
    grid = PlacementGrid(axes, top)
    if grid.size > MAX_PLACEMENTS:
        raise PlacementGridError(
            f"{where}: {grid.size} placements is more than {MAX_PLACEMENTS}; split the study into several runs"
        )
    return grid


def parse_grid_text(text: str, base: PlacementGrid | None = None, where: str = "--grid") -> PlacementGrid:
    """A grid from command-line text, e.g. ``"x_m=-0.4:0.4:9, y_m=0.2, yaw_deg=0:315:8"``.

    Each comma-separated item is ``key=value`` or ``key=start:stop:count``; axes not
    given keep ``base``'s values.
    """
    tab: dict[str, Any] = {}
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        key, sep, val = (s.strip() for s in item.partition("="))
        if not sep or not val:
            raise PlacementGridError(
                f"{where}: item {item!r} must be KEY=VALUE or KEY=START:STOP:COUNT "
                f"with KEY one of {list(GRID_AXES) + list(OTHER_KEYS)}"
            )
        parts = val.split(":")
        if key == "top":
            if not val.isdecimal():
                raise PlacementGridError(
                    f"{where}: item {item!r}: top must be a whole number in [0, {MAX_TOP}], got {val!r}"
                )
            tab[key] = int(val)
            continue
        bad = PlacementGridError(f"{where}: item {item!r}: value {val!r} must be a number or START:STOP:COUNT")
        if len(parts) not in (1, 3):
            raise bad
        try:
            if len(parts) == 3:
                cnt = float(parts[2])
                tab[key] = [float(parts[0]), float(parts[1]), int(cnt) if cnt.is_integer() else cnt]
            else:
                tab[key] = float(val)
        except ValueError:
            raise bad from None
    return grid_from_table(tab, where, base)


def default_grid(positions_cell: np.ndarray, reach_m: float) -> PlacementGrid:
    """The grid used when neither the problem nor the command line gives one: the base
    origin over a square of half-width ``reach_m`` around the path's centroid (x, y; 21 x 21),
    on the floor (z = 0, tilt = 0), at 8 yaws 45 deg apart."""
    c = np.asarray(positions_cell, dtype=float).mean(axis=0)
    h = float(reach_m)
    return PlacementGrid(
        {
            "x_m": np.linspace(c[0] - h, c[0] + h, 21),
            "y_m": np.linspace(c[1] - h, c[1] + h, 21),
            "z_m": np.zeros(1),
            "yaw_deg": np.radians(np.arange(0.0, 360.0, 45.0)),
            "tilt_deg": np.zeros(1),
        }
    )


__all__ = [
    "GRID_AXES",
    "PlacementGrid",
    "PlacementGridError",
    "base2cell",
    "cell2base",
    "default_grid",
    "describe_placement",
    "grid_from_table",
    "parse_grid_text",
    "placement_label",
]
