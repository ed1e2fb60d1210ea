"""``[robot.tool.cutter]``: the cutter, one description for the cut and the cell.

Two forms (``docs/cutting.md``, "The cutter"; ``docs/cell.md``, "The tool"):

* an **end mill**: ``shape`` (``flat``, ``ball``, ``bull_nose``), ``diameter`` (m), ``corner_radius``
  (m; bull-nose only: a ball's is ``diameter / 2``, a flat's 0), ``flutes``, ``helix_deg``,
  ``flute_length`` (m) and ``length`` (m, the stick-out from the holder to the tip).  The cut force
  and the material removal use it; the cell's collision capsule is built from it
  (:meth:`models.cutting.cutter.EndMill.capsule`);
* a bare **capsule** for the cell only: ``radius`` and ``length`` (m).

The cutter hangs from the TCP (its tip) back along the TCP's z axis: it cannot be longer than the
TCP is from the flange (it would pass through the holder and the flange).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.cutting.cutter import CutterShape, EndMill
from models.errors import InputError
from problems.problem_file.values import VALUES, err, integer, number, positive

__all__ = ["CAPSULE_KEYS", "END_MILL_KEYS", "parse_cutter_table", "parse_tool_cutter"]

#: The keys of an end mill.
END_MILL_KEYS = ("shape", "diameter", "corner_radius", "flutes", "helix_deg", "flute_length", "length")
#: The keys of a bare collision capsule.
CAPSULE_KEYS = ("radius", "length")
#: Largest plausible cutter diameter, m (a 200 mm face mill; beyond it millimetres were given).
PLAUSIBLE_CUTTER_DIAMETER_MAX_M = 0.2


def _length(where: str, key: str, v: Any) -> float:
    x = positive(where, key, v)
    if x > PLAUSIBLE_POSITION_MAX_M:
        raise err(
            where,
            key,
            f"= {x:g} m is implausible for a cutter (> {PLAUSIBLE_POSITION_MAX_M:g} m); in metres (millimetres given?)",
        )
    return x


def parse_cutter_table(
    where: str, ct: Mapping[str, Any], prefix: str = "robot.tool.cutter", length_required: bool = True
) -> EndMill:
    """An end mill from its table (keys :data:`END_MILL_KEYS`; messages name ``prefix.key``).

    ``length_required`` False (a cutter file for ``compplan cutting fit``): the stick-out defaults to
    the flute length.

    Raises
    ------
    ProblemFileError
        A missing or unknown key, a value of the wrong kind or range (a diameter in millimetres,
        a corner radius that does not fit the shape, a flute length beyond the stick-out).
    """
    VALUES.unknown_keys(f"{where}: [{prefix}]", ct, END_MILL_KEYS)
    for k in ("shape", "diameter", "flutes", "flute_length") + (("length",) if length_required else ()):
        if k not in ct:
            given = ", ".join(sorted(set(ct) & set(END_MILL_KEYS))) or "none"
            raise err(
                where,
                f"{prefix}.{k}",
                f"is required for an end mill (the table gives {given}; see docs/cutting.md, 'The cutter')",
            )
    names = [s.value for s in CutterShape]
    if ct["shape"] not in names:
        raise err(where, f"{prefix}.shape", f"= {ct['shape']!r}; expected one of {names}")
    shape = CutterShape(ct["shape"])
    d = positive(where, f"{prefix}.diameter", ct["diameter"])
    if d > PLAUSIBLE_CUTTER_DIAMETER_MAX_M:
        raise err(
            where,
            f"{prefix}.diameter",
            f"= {d:g} m is implausible (> {PLAUSIBLE_CUTTER_DIAMETER_MAX_M:g} m); in metres (millimetres given?)",
        )
    if shape is CutterShape.BULL_NOSE:
        if "corner_radius" not in ct:
            raise err(where, f"{prefix}.corner_radius", "is required for a bull-nose end mill (m)")
        r = positive(where, f"{prefix}.corner_radius", ct["corner_radius"])
        if not r < d / 2.0:
            raise err(where, f"{prefix}.corner_radius", f"= {r:g} m must be below diameter / 2 = {d / 2:g} m")
    else:
        r = 0.0 if shape is CutterShape.FLAT else d / 2.0
        if "corner_radius" in ct and not math.isclose(number(where, f"{prefix}.corner_radius", ct["corner_radius"]), r):
            raise err(
                where, f"{prefix}.corner_radius", f"= {ct['corner_radius']!r} m; a {shape.value} end mill's is {r:g} m"
            )
    flutes = integer(where, f"{prefix}.flutes", ct["flutes"], 1, 64)
    helix = number(where, f"{prefix}.helix_deg", ct.get("helix_deg", 0.0))
    if not 0.0 <= helix < 75.0:
        raise err(where, f"{prefix}.helix_deg", f"= {helix:g} deg; expected a helix angle in [0, 75) degrees")
    flute = _length(where, f"{prefix}.flute_length", ct["flute_length"])
    length = _length(where, f"{prefix}.length", ct["length"]) if "length" in ct else flute
    if flute > length:
        raise err(
            where,
            f"{prefix}.flute_length",
            f"= {flute:g} m is longer than the cutter's stick-out {prefix}.length = {length:g} m",
        )
    if flute < r:
        raise err(where, f"{prefix}.flute_length", f"= {flute:g} m is shorter than the corner radius {r:g} m")
    try:
        return EndMill(shape, d, r, flutes, math.radians(helix), flute, length)
    except InputError as exc:
        raise err(where, prefix, str(exc)) from None


def parse_tool_cutter(where: str, data: Mapping[str, Any], tcp2flange: np.ndarray | None = None) -> Any:
    """``[robot.tool.cutter]`` as the cell's collision capsule (:class:`models.collision.tool.Cutter`,
    with its end mill when the table describes one), or None when absent.

    ``tcp2flange`` (4, 4): the tool's TCP in the flange frame; an end mill longer than the TCP is
    from the flange along the TCP's z axis is refused (it cannot fit its holder).  A bare capsule
    may be longer (a conservative collision body reaching into the flange link, as before).

    Raises
    ------
    ProblemFileError
    """
    robot = data.get("robot")
    tt = robot.get("tool") if isinstance(robot, Mapping) else None
    if not isinstance(tt, Mapping) or "cutter" not in tt:
        return None
    from models.collision.tool import Cutter  # loads coal: only for a declared cutter

    ct = tt["cutter"]
    key = "robot.tool.cutter"
    if not isinstance(ct, Mapping):
        raise err(where, key, f"must be a table (an end mill, or radius and length in m), got {ct!r}")
    if any(k in ct for k in END_MILL_KEYS if k != "length"):
        mill = parse_cutter_table(where, ct, key)
        cutter = mill.capsule()
    else:
        VALUES.unknown_keys(f"{where}: [{key}]", ct, CAPSULE_KEYS)
        for k in CAPSULE_KEYS:
            if k not in ct:
                raise err(where, f"{key}.{k}", "is required (m), or describe an end mill (docs/cutting.md)")
        mill, cutter = (
            None,
            Cutter(_length(where, f"{key}.radius", ct["radius"]), _length(where, f"{key}.length", ct["length"])),
        )
    if mill is not None and tcp2flange is not None:
        T = np.asarray(tcp2flange, dtype=float)
        reach = float((T[:3, :3].T @ T[:3, 3])[2])  # how far behind the tip (along -z of the TCP) the flange is
        if cutter.length > reach + 1e-12:
            raise err(
                where,
                f"{key}.length",
                f"= {cutter.length:g} m is longer than its holder allows: the TCP (the cutter's tip) is "
                f"{max(reach, 0.0):g} m from the flange along the tool axis (robot.tool xyz/rpy), so the cutter "
                "would reach through the holder into the flange; give the stick-out from the holder, or the TCP "
                "at the cutter's tip",
            )
    return cutter
