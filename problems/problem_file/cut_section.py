"""``[material]``, ``[stock]`` and ``[cut]``: what a program cuts, so its load is predicted
(``docs/cutting.md``).

With both ``[material]`` and ``[stock]`` on a program path, the plan's load is the cut: the stock
is cut by the program in order with the cutter of ``[robot.tool.cutter]`` (an end mill), and the
mechanistic force of every waypoint becomes its wrench (:mod:`problems.cutting.program_cut`).

* ``[material]``: ``name`` (a row of the shipped table, ``compplan cutting materials``), or the six
  coefficients ``Ktc``, ``Krc``, ``Kac`` (N/m²) and ``Kte``, ``Kre``, ``Kae`` (N/m) with a
  ``source`` (a ``name`` beside them labels them, as in ``compplan cutting fit``'s
  ``coefficients.toml``);
* ``[stock]``: a box ``box_min``/``box_max`` (m, program frame) or a closed ``mesh`` (a file next to
  the problem file, program frame, ``mesh_unit`` ``"m"`` or ``"mm"``); ``resolution`` (m, the
  z-map's cell);
* ``[cut]`` (optional): ``spindle_rpm`` and ``spindle`` (``"cw"``/``"ccw"``) for CL data (G-code
  gives S and M3/M4), ``slice_height`` (m), and ``stand_in`` (a constant wrench, ``frame``,
  ``force`` N, ``moment`` N·m, that the report compares the prediction with).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError
from problems.problem_file.values import VALUES, err, number, positive, table, vector

__all__ = ["COEFFICIENT_KEYS", "CutSetup", "parse_cut_setup"]

#: ``[material]``'s coefficient keys and their units.
COEFFICIENT_KEYS = {"Ktc": "N/m²", "Krc": "N/m²", "Kac": "N/m²", "Kte": "N/m", "Kre": "N/m", "Kae": "N/m"}
MATERIAL_KEYS = ("name", "source", *COEFFICIENT_KEYS)
STOCK_KEYS = ("box_min", "box_max", "mesh", "mesh_unit", "resolution")
CUT_KEYS = ("spindle_rpm", "spindle", "slice_height", "stand_in")
STAND_IN_KEYS = ("frame", "force", "moment")
#: Mesh file units accepted and their size in m.
MESH_UNITS = {"m": 1.0, "mm": 1e-3}
#: A z-map cell outside this range (m) is refused: below it the memory explodes, above it the
#: engagement of a small cutter is lost.
RESOLUTION_RANGE_M = (1e-5, 2e-3)
#: Largest spindle speed accepted, rev/min.
MAX_SPINDLE_RPM = 200_000.0


@dataclass(frozen=True)
class CutSetup:
    """The cut's sections as read (SI).

    Attributes
    ----------
    mill : models.cutting.cutter.EndMill
    coefficients : models.cutting.material.CuttingCoefficients
    stock : Any
        :class:`problems.cutting.stock.StockBox` or ``StockMesh`` (program frame).
    resolution_m : float or None
        The z-map cell, m (None: the stock's default).
    spindle_rpm : float or None
        CL data: the spindle speed, rev/min (G-code: None, the program's S).
    spindle_cw : bool
        CL data: the spindle's turning (G-code: from M3/M4).
    slice_height_m : float or None
    stand_in : ndarray or None
        Shape (6,), N and N·m, in ``stand_in_frame``.
    stand_in_frame : str
    table : dict
        The sections in the problem-file schema (for the run's record).
    """

    mill: Any
    coefficients: Any
    stock: Any
    resolution_m: float | None
    spindle_rpm: float | None
    spindle_cw: bool
    slice_height_m: float | None
    stand_in: np.ndarray | None
    stand_in_frame: str
    table: dict[str, Any]


def parse_cut_setup(
    where: str, data: Mapping[str, Any], base_dir: Path | None, program: Any, tcp2flange: np.ndarray
) -> CutSetup | None:
    """``[material]``, ``[stock]`` and ``[cut]`` (None when neither ``[material]`` nor ``[stock]``).

    Parameters
    ----------
    program : problems.problem_file.ProgramSection or None
        The program path (the cut needs one).
    tcp2flange : ndarray, shape (4, 4)
        The tool (the cutter must fit its holder).

    Raises
    ------
    ProblemFileError
        One section without the other, no program path, no end mill, a coefficient in N/mm² under
        its SI key, a stock of the wrong shape, ``[cut]`` keys that do not apply.
    """
    has_m, has_s = "material" in data, "stock" in data
    if not (has_m or has_s):
        if "cut" in data:
            raise err(where, "cut", "applies only with [material] and [stock] (docs/cutting.md)")
        return None
    if not (has_m and has_s):
        missing = "stock" if has_m else "material"
        raise err(where, missing, f"is required with [{'material' if has_m else 'stock'}]: the cut needs both")
    if program is None:
        raise err(where, "path.kind", "must be a program ('gcode' or 'toolpath_csv') to predict its cut")
    from problems.problem_file.cutter_section import parse_tool_cutter

    cutter = parse_tool_cutter(where, data, tcp2flange)
    if cutter is None or cutter.mill is None:
        raise err(
            where,
            "robot.tool.cutter",
            "must describe the end mill (shape, diameter, flutes, helix_deg, flute_length, length) to predict the cut",
        )
    coeffs, mtab = _material(where, data)
    stock, stab, res = _stock(where, data, base_dir)
    cut = _cut(where, data, program)
    tab = {"material": mtab, "stock": stab}
    if cut["table"]:
        tab["cut"] = cut["table"]
    return CutSetup(
        cutter.mill,
        coeffs,
        stock,
        res,
        cut["rpm"],
        cut["cw"],
        cut["slice"],
        cut["stand_in"],
        cut["frame"],
        tab,
    )


def _material(where: str, data: Mapping[str, Any]) -> tuple[Any, dict[str, Any]]:
    from models.cutting.material import CuttingCoefficients, material, material_names, unit_mistake

    mt = table(where, data, "material", MATERIAL_KEYS)
    given = [k for k in COEFFICIENT_KEYS if k in mt]
    if "name" in mt and not given:  # a row of the shipped table; with coefficients, name labels them
        try:
            c = material(str(mt["name"]))
        except InputError:
            raise err(
                where, "material.name", f"= {mt['name']!r} is not in the table; shipped: {list(material_names())}"
            ) from None
        return c, {"name": str(mt["name"]).strip()}  # the table key (c.name is the row's display name)
    if len(given) != len(COEFFICIENT_KEYS):
        missing = [k for k in COEFFICIENT_KEYS if k not in mt]
        raise err(where, f"material.{missing[0]}", "is required (or material.name, a row of the shipped table)")
    vals = {k: number(where, f"material.{k}", mt[k]) for k in COEFFICIENT_KEYS}
    for k, v in vals.items():
        if v < 0.0 or (k == "Ktc" and v <= 0.0):
            raise err(where, f"material.{k}", f"= {v:g} {COEFFICIENT_KEYS[k]}; expected >= 0 (Ktc > 0)")
        wrong = unit_mistake(k, v)
        if wrong:
            raise err(where, f"material.{k}", wrong)
    source = str(mt.get("source", ""))
    if not source.strip():
        raise err(where, "material.source", "is required with the coefficients: where they come from")
    label = str(mt.get("name", "")).strip()
    try:
        c = CuttingCoefficients(**vals, name=label or "(problem file)", source=source)
    except InputError as exc:
        raise err(where, "material", str(exc)) from None
    return c, {**vals, "source": source, **({"name": label} if label else {})}


def _stock(where: str, data: Mapping[str, Any], base_dir: Path | None) -> tuple[Any, dict[str, Any], float | None]:
    from problems.cutting.stock import StockBox, StockMesh

    st = table(where, data, "stock", STOCK_KEYS)
    res = None
    if "resolution" in st:
        res = positive(where, "stock.resolution", st["resolution"])
        lo, hi = RESOLUTION_RANGE_M
        if not lo <= res <= hi:
            raise err(where, "stock.resolution", f"= {res:g} m; expected a z-map cell in [{lo:g}, {hi:g}] m")
    box = "box_min" in st or "box_max" in st
    if box == ("mesh" in st):
        raise err(where, "stock", "give either box_min and box_max (m, program frame) or mesh (a file), one of them")
    tab: dict[str, Any] = {} if res is None else {"resolution": res}
    if box:
        for k in ("box_min", "box_max"):
            if k not in st:
                raise err(where, f"stock.{k}", "is required with a box stock (m, program frame)")
        lo_m = vector(where, "stock.box_min", st["box_min"], 3)
        hi_m = vector(where, "stock.box_max", st["box_max"], 3)
        if np.max(np.abs(np.r_[lo_m, hi_m])) > PLAUSIBLE_POSITION_MAX_M:
            raise err(where, "stock.box_min", "is implausible (> 5 m); in metres (millimetres given?)")
        if not np.all(hi_m > lo_m):
            raise err(where, "stock.box_max", f"= {hi_m.tolist()} must exceed box_min = {lo_m.tolist()} on every axis")
        tab.update(box_min=lo_m.tolist(), box_max=hi_m.tolist())
        return StockBox(lo_m, hi_m), tab, res
    raw = st["mesh"]
    if not isinstance(raw, str) or not raw:
        raise err(where, "stock.mesh", f"must be a file name, got {raw!r}")
    f = Path(raw)
    if not f.is_absolute() and base_dir is not None:
        f = base_dir / f
    if not f.is_file():
        raise err(where, "stock.mesh", f"= {raw!r}: no such file ({f})")
    unit = st.get("mesh_unit", "m")
    if unit not in MESH_UNITS:
        raise err(where, "stock.mesh_unit", f"= {unit!r}; expected one of {list(MESH_UNITS)}")
    try:
        stock = StockMesh(f, MESH_UNITS[unit])
    except InputError as exc:
        raise err(where, "stock.mesh", str(exc)) from None
    tab.update(mesh=str(f), mesh_unit=unit)
    return stock, tab, res


def _cut(where: str, data: Mapping[str, Any], program: Any) -> dict[str, Any]:
    ct = table(where, data, "cut", CUT_KEYS) if "cut" in data else {}
    gcode = program.kind == "gcode"
    out: dict[str, Any] = {"rpm": None, "cw": True, "slice": None, "stand_in": None, "frame": "tool", "table": {}}
    for k in ("spindle_rpm", "spindle"):
        if k in ct and gcode:
            raise err(where, f"cut.{k}", "applies to CL data only: a G-code program gives S and M3/M4")
    if not gcode:
        if "spindle_rpm" not in ct:
            raise err(where, "cut.spindle_rpm", "is required for CL data (rev/min; G-code gives S)")
        rpm = positive(where, "cut.spindle_rpm", ct["spindle_rpm"])
        if rpm > MAX_SPINDLE_RPM:
            raise err(where, "cut.spindle_rpm", f"= {rpm:g} rev/min is implausible (> {MAX_SPINDLE_RPM:g})")
        sense = ct.get("spindle", "cw")
        if sense not in ("cw", "ccw"):
            raise err(where, "cut.spindle", f"= {sense!r}; expected 'cw' (M3) or 'ccw' (M4)")
        out.update(rpm=rpm, cw=sense == "cw")
        out["table"].update(spindle_rpm=rpm, spindle=sense)
    if "slice_height" in ct:
        h = positive(where, "cut.slice_height", ct["slice_height"])
        if not 1e-6 <= h <= 2e-3:
            raise err(where, "cut.slice_height", f"= {h:g} m; expected a slice of 0.001 to 2 mm, in m")
        out["slice"] = h
        out["table"]["slice_height"] = h
    if "stand_in" in ct:
        si = ct["stand_in"]
        if not isinstance(si, Mapping):
            raise err(where, "cut.stand_in", f"must be a table (frame, force N, moment N·m), got {si!r}")
        VALUES.unknown_keys(f"{where}: [cut.stand_in]", si, STAND_IN_KEYS)
        frame = si.get("frame", "tool")
        if frame not in ("tool", "base"):
            raise err(where, "cut.stand_in.frame", f"= {frame!r}; expected 'tool' or 'base'")
        if "force" not in si:
            raise err(where, "cut.stand_in.force", "is required (N)")
        f = vector(where, "cut.stand_in.force", si["force"], 3)
        m = vector(where, "cut.stand_in.moment", si.get("moment", [0.0, 0.0, 0.0]), 3)
        out.update(stand_in=np.r_[f, m], frame=frame)
        out["table"]["stand_in"] = {"frame": frame, "force": f.tolist(), "moment": m.tolist()}
    return out
