"""The compliance map of a report (figure 1) and of ``compplan map``, and its cache.

The compliance map depends only on the robot and the map options, not on the
run, and it is the most expensive figure.  Its PNG, PDF, CSV and caption are
kept in a small on-disk cache (next to the compiled kernels: ``$COMPPLAN_CACHE``,
default ``~/.cache/compplan``, under ``maps/``) keyed by a hash of the robot
description, the options and the source of the code that draws it.  The cache
is best effort: any failure to read or write it just means the map is computed
again.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from models import Robot
from models.errors import CompplanError
from models.ik import BRANCH_LABELS

from planner.compliance_map import ComplianceMap, ProgressFn, compliance_map
from planner.output import OutputSet, atomic_write_bytes, json_bytes
from planner.report import plots
from planner.report.rendering import FigureItem, Job, job, render_job
from planner.report.run import Run

#: File name (without extension) of the compliance-map figure.
MAP_FIGURE = "fig1_compliance_map"

_MAP_CACHE_FILES = ("map.png", "map.pdf", "map.csv", "caption.txt")


def map_job(cm: ComplianceMap) -> tuple[Job, str]:
    """The figure job and caption of a compliance map."""
    used = cm.branches_used()
    rule = ("per point, the IK branch nearest the home configuration" if cm.branch_rule == "home"
            else f"fixed branch {cm.branch_rule}")
    title = (f"{cm.robot}: diagonal compliance over the plane {cm.plane} = {cm.offset_m:g} m, "
             f"{cm.u_axis} ∈ [{cm.u_m[0]:g}, {cm.u_m[-1]:g}] m, "
             f"{cm.v_axis} ∈ [{cm.v_m[0]:g}, {cm.v_m[-1]:g}] m "
             f"({len(cm.u_m)}×{len(cm.v_m)} points)\n"
             f"end attitude (roll, pitch, yaw) = ({', '.join(f'{a:g}' for a in cm.rpy_rad)}) rad, "
             f"R = Rz(yaw)·Ry(pitch)·Rx(roll)\n"
             f"branch: {rule} ({', '.join(f'{k} at {v} points' for k, v in used.items()) or 'none'}); "
             f"{cm.n_unreachable} of {cm.n_points} points unreachable")
    jb = job(plots.compliance_map_figure, cm.u_m, cm.v_m, cm.diag, u_label=cm.u_axis,
             v_label=cm.v_axis, title=title, branch=cm.branch, branch_labels=BRANCH_LABELS)
    reasons = "; ".join(f"{k}: {v}" for k, v in cm.unreachable_reasons.items())
    caption = (f"Paper Fig. 5. C11–C33: translational compliance (mm/N); C44–C66: rotational "
               f"compliance (deg/(N·m)). {cm.n_unreachable} of {cm.n_points} grid points "
               f"unreachable (hatched){' — ' + reasons if reasons else ''}. "
               f"Branch: {rule}. Data: compliance_map.csv (SI).")
    return jb, caption


def map_item(run: Run, map_options: Mapping[str, Any] | None | bool,
             progress: ProgressFn | None, files: dict[str, bytes], map_cache: bool) -> FigureItem:
    """Figure 1 of a report: from the cache, or computed here (its job still to render).

    ``compliance_map.csv`` is added to ``files``.  With ``map_options=False`` or
    without a robot the figure is absent.
    """
    item = FigureItem(MAP_FIGURE, "Compliance maps C11…C66 over a plane (paper §4.3)", "")
    if map_options is False:
        item.absent = "compliance map not requested (--no-map)"
        return item
    if run.robot is None:
        item.absent = f"compliance map not computed: {run.absent.get('robot', 'no robot')}"
        return item
    opts = dict(map_options or {})
    key = _map_cache_key(run.robot, opts) if map_cache else None
    hit = _map_cache_get(key) if key else None
    if hit is not None:
        item.png, item.pdf, files["compliance_map.csv"], item.caption = hit
        if progress is not None:
            progress("compliance map", 1, 1)
        return item
    try:
        cm = compliance_map(run.robot, progress=progress, **opts)
    except CompplanError as exc:
        item.absent = f"compliance map not computed: {exc}"
        return item
    files["compliance_map.csv"] = cm.csv_bytes()
    item.job, item.caption = map_job(cm)
    item.cache_key = key
    return item


def cache_rendered_maps(items: list[FigureItem], files: Mapping[str, bytes]) -> None:
    """Keep every freshly rendered compliance map (its ``cache_key`` set) in the cache."""
    for it in items:
        if it.cache_key and it.png is not None and it.pdf is not None:
            _map_cache_put(it.cache_key, it.png, it.pdf, files["compliance_map.csv"], it.caption)


# ------------------------------------------------------------------------------------ cache
def _map_cache_dir(key: str) -> Path:
    root = os.environ.get("COMPPLAN_CACHE") or os.path.join(os.path.expanduser("~"), ".cache",
                                                              "compplan")
    return Path(root) / "maps" / key


def _map_cache_key(robot: Robot, map_options: Mapping[str, Any]) -> str:
    """Hash of the robot, the map options (defaults filled in), the drawing code and matplotlib."""
    import hashlib
    import inspect

    import matplotlib

    from models.arm import ArmModel
    from planner import compliance_map as cmod
    sig = inspect.signature(cmod.compliance_map)
    opts = {k: p.default for k, p in sig.parameters.items()
            if p.default is not inspect.Parameter.empty and k not in ("progress", "chunk")}
    opts.update({k: v for k, v in map_options.items() if k not in ("progress", "chunk")})
    desc = (robot.nominal.to_dict() | {"theta": robot.theta, "const": robot.const,
                                       "effects": list(robot.active_effects)}
            if isinstance(robot, ArmModel) else robot.to_dict())
    blob = json.dumps({"robot": desc, "options": opts}, sort_keys=True,
                      default=lambda o: np.asarray(o, float).tolist())
    h = hashlib.sha256(blob.encode())
    for path in (plots.__file__, cmod.__file__, __file__):
        h.update(Path(path).read_bytes())
    h.update(matplotlib.__version__.encode())
    return h.hexdigest()[:24]


def _map_cache_get(key: str) -> tuple[bytes, bytes, bytes, str] | None:
    d = _map_cache_dir(key)
    try:
        png, pdf, csv_, cap = (d / n for n in _MAP_CACHE_FILES)
        return png.read_bytes(), pdf.read_bytes(), csv_.read_bytes(), cap.read_text()
    except OSError:
        return None


def _map_cache_put(key: str, png: bytes, pdf: bytes, csv_: bytes, caption: str) -> None:
    d = _map_cache_dir(key)
    try:
        for name, data in zip(_MAP_CACHE_FILES, (png, pdf, csv_, caption.encode())):
            atomic_write_bytes(d / name, data)
    except OSError:
        pass


# ------------------------------------------------------------------------------ compplan map
def write_map(robot: Robot, folder: str | Path, progress: ProgressFn | None = None,
              **options: Any) -> tuple[ComplianceMap, list[Path]]:
    """Compute a compliance map and write it (``compplan map``).

    Writes ``compliance_map.csv`` (SI), ``compliance_map.json`` (what was
    computed, ranges in SI) and ``figures/fig1_compliance_map.png|pdf`` into
    ``folder`` (all or nothing).

    Parameters
    ----------
    robot : Robot
    folder : str or Path
    progress : callable, optional
        ``progress(stage, done, total)``.
    **options
        Keyword arguments of :func:`planner.compliance_map.compliance_map`.

    Returns
    -------
    (ComplianceMap, list of Path)
    """
    cm = compliance_map(robot, progress=progress, **options)
    jb, caption = map_job(cm)
    png, pdf = render_job(jb)
    if progress is not None:
        progress("figures", 1, 1)
    out = OutputSet(folder)
    out.add_bytes("compliance_map.csv", cm.csv_bytes())
    out.add_bytes("compliance_map.json", json_bytes({**cm.summary(), "caption": caption}))
    out.add_bytes(f"figures/{MAP_FIGURE}.png", png)
    out.add_bytes(f"figures/{MAP_FIGURE}.pdf", pdf)
    return cm, out.publish()
