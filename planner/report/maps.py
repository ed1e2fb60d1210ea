"""The compliance map of a report (figure 1) and of ``compplan map``, and its cache.

In a report the map is drawn, by default, over the plane of the run's own path
(:func:`path_plane`: the plane through the waypoints, or for a straight line the
vertical plane that contains it), at the TCP attitude of the middle waypoint and
on the run's IK branch, with the path drawn on it; points that branch cannot
reach at that attitude are hatched and counted.  With explicit map options the
requested axis-aligned plane is drawn (paper section 4.3 style) and the path is
projected onto it, its distance from the plane stated.

The map is the run's arm model's (an identified model's compliance, not its robot
file's).  It depends only on that model, the plane and the options, and it
is the most expensive figure.  Its PNG, PDF, CSV and caption are
kept in a small on-disk cache (next to the compiled kernels: ``$COMPPLAN_CACHE``,
default ``~/.cache/compplan``, under ``maps/``) keyed by a hash of the arm model
(description, parameters, constants, effects), the options and the source of the code
that draws it.  The cache is best effort: any failure to read or write it just means the
map is computed again.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from models import Robot
from models.arm import ArmModel
from models.errors import CompplanError
from models.ik import IK_REASONS, IKStatus

from planner.compliance_map import DEFAULT_POINTS, PLANE_AXES, ComplianceMap, GridCounts, ProgressFn, compliance_map
from planner.numbers import format_number
from planner.output import OutputSet, atomic_write_bytes, json_bytes
from planner.provenance import provenance, robot_input
from planner.report import figure_base, plots
from planner.report.rendering import FigureItem, Job, job, render_job
from planner.record import RunRecord

#: File name (without extension) of the compliance-map figure.
MAP_FIGURE = "fig1_compliance_map"

_MAP_CACHE_FILES = ("map.png", "map.pdf", "map.csv", "caption.txt")

#: Margin around the path in the plane of a path map: this fraction of the path's extent,
#: and at least :data:`PATH_MAP_MIN_MARGIN_M`.
PATH_MAP_MARGIN = 0.3
PATH_MAP_MIN_MARGIN_M = 0.1
#: The shorter side of a path map's grid is at least this fraction of the longer one.
PATH_MAP_MIN_ASPECT = 0.55
#: A path whose second principal extent is below this fraction of the first is a straight line.
PATH_LINE_REL_TOL = 1e-6
#: A plane normal within this of a base axis is that axis (the plane is axis-aligned).
AXIS_ALIGNED_TOL = 1e-9
_AXIS_NAMES = ("x", "y", "z")


@dataclass
class PathPlane:
    """The plane of a run's path, with in-plane coordinates ``p = origin + u e_u + v e_v``.

    Attributes
    ----------
    origin, e_u, e_v, normal : ndarray, shape (3,)
        Base frame, m (unit vectors).
    u_label, v_label : str
        Names of the in-plane axes (base axis names for an axis-aligned plane).
    description : str
        The plane in words (e.g. ``"x = 0.7 m"`` or the oblique plane's vectors).
    off_plane_m : float
        Largest distance of a waypoint from the plane, m (0 for a planar path).
    """

    origin: np.ndarray
    e_u: np.ndarray
    e_v: np.ndarray
    normal: np.ndarray
    u_label: str
    v_label: str
    description: str
    off_plane_m: float = 0.0

    def uv(self, P: np.ndarray) -> np.ndarray:
        """In-plane coordinates (N, 2) of points ``P`` (N, 3), m."""
        d = np.asarray(P, float) - self.origin
        return np.column_stack([d @ self.e_u, d @ self.e_v])

    def points(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Base-frame points (len(u) * len(v), 3) of the grid ``u x v`` (u-major)."""
        U, V = np.meshgrid(u, v, indexing="ij")
        return self.origin + U.reshape(-1, 1) * self.e_u + V.reshape(-1, 1) * self.e_v


def _vec(v: np.ndarray) -> str:
    return "(" + ", ".join(format_number(float(x), 3) for x in v) + ")"


def path_plane(P: np.ndarray) -> PathPlane:
    """The plane of a path of waypoints ``P`` (N, 3), m.

    A planar path gives its own plane (principal directions: ``e_u`` along the largest
    extent, oriented from the first waypoint towards the last); a straight line, the
    vertical plane that contains it (``e_v`` upwards; the x-z plane through it for a
    vertical line); a single point, the vertical plane x-z through it.  A plane whose
    normal is a base axis is reported with the base axes' names and coordinates.
    """
    P = np.asarray(P, float).reshape(-1, 3)
    c = P.mean(axis=0)
    X = P - c
    _, S, Vt = np.linalg.svd(X, full_matrices=False) if len(P) > 1 else (None, np.zeros(3), np.eye(3))
    if S[0] <= 0.0:  # one point
        n = np.array([0.0, 1.0, 0.0])
    elif len(S) < 2 or S[1] <= PATH_LINE_REL_TOL * S[0]:  # a straight line: the vertical plane through it
        d = Vt[0]
        up = np.array([0.0, 0.0, 1.0]) - d * d[2]
        if np.linalg.norm(up) < 1e-9:  # a vertical line: the x-z plane through it
            up = np.array([1.0, 0.0, 0.0]) - d * d[0]
        n = np.cross(d, up / np.linalg.norm(up))
    else:
        n = Vt[2] if len(Vt) > 2 else np.cross(Vt[0], Vt[1])
    n = n / np.linalg.norm(n)
    axis = int(np.argmax(np.abs(n)))
    if abs(abs(n[axis]) - 1.0) <= AXIS_ALIGNED_TOL:  # axis-aligned: base coordinates in the plane
        _, iu, iv = PLANE_AXES[_AXIS_NAMES[axis]]
        e_u, e_v = np.eye(3)[iu], np.eye(3)[iv]
        origin = np.zeros(3)
        origin[axis] = c[axis]
        off = float(np.max(np.abs(P[:, axis] - c[axis])))
        return PathPlane(
            origin,
            e_u,
            e_v,
            np.eye(3)[axis],
            _AXIS_NAMES[iu],
            _AXIS_NAMES[iv],
            f"{_AXIS_NAMES[axis]} = {format_number(float(c[axis]))} m",
            off,
        )
    e_u = Vt[0] if S[0] > 0 else np.array([1.0, 0.0, 0.0])
    e_u = e_u - n * float(e_u @ n)
    e_u /= np.linalg.norm(e_u)
    if len(P) > 1 and float((P[-1] - P[0]) @ e_u) < 0:
        e_u = -e_u
    e_v = np.cross(n, e_u)
    if e_v[2] < 0 or (abs(e_v[2]) < 1e-12 and e_v[1] < 0):
        e_v, n = -e_v, -n
    off = float(np.max(np.abs(X @ n)))
    kind = "the vertical plane through the path" if abs(n[2]) < 1e-9 else "the plane of the path"
    desc = f"{kind}: origin at its first waypoint {_vec(P[0])} m, u along {_vec(e_u)}, v along {_vec(e_v)} (base frame)"
    v_label = "v, upwards" if abs(n[2]) < 1e-9 and e_v[2] > 0 else "v, across the path"
    return PathPlane(P[0].copy(), e_u, e_v, n, "u, along the path", v_label, desc, off)


@dataclass
class PlaneMap(GridCounts):
    """Diagonal compliance over the grid of a :class:`PathPlane` (a report's figure 1).

    Attributes
    ----------
    robot : str
    plane : PathPlane
    u_m, v_m : ndarray
        In-plane grid coordinates, m.
    R : ndarray, shape (3, 3)
        TCP attitude (TCP -> base rotation) at every grid point.
    branch_label : str
        The fixed IK branch.
    branch : ndarray of int, shape (nu, nv)
        Branch index per point (-1: unreachable).
    diag : ndarray, shape (nu, nv, 6)
        ``C11..C66`` (m/N, rad/(N*m)); NaN where unreachable.
    unreachable_reasons : dict of str to int
    labels : tuple of str
        The IK family's branch labels (index -> label).
    """

    robot: str
    plane: PathPlane
    u_m: np.ndarray
    v_m: np.ndarray
    R: np.ndarray
    branch_label: str
    branch: np.ndarray
    diag: np.ndarray
    unreachable_reasons: dict[str, int] = field(default_factory=dict)
    labels: tuple[str, ...] = ()

    def csv_bytes(self) -> bytes:
        """``compliance_map.csv``: u, v (m, in the plane), x, y, z (m, base frame), branch index
        (-1 unreachable), C11..C33 (m/N), C44..C66 (rad/(N*m))."""
        import io

        P = self.plane.points(self.u_m, self.v_m)
        U, V = np.meshgrid(self.u_m, self.v_m, indexing="ij")
        cols = ["u_m", "v_m", "x_m", "y_m", "z_m", "branch"] + [
            f"C{i}{i}_{'m_per_N' if i <= 3 else 'rad_per_Nm'}" for i in range(1, 7)
        ]
        rows = np.column_stack([U.ravel(), V.ravel(), P, self.branch.ravel(), self.diag.reshape(-1, 6)])
        buf = io.StringIO()
        buf.write(",".join(cols) + "\n")
        np.savetxt(buf, rows, fmt="%.17g", delimiter=",")
        return buf.getvalue().encode()


def _grid(lo: float, hi: float, n: int) -> np.ndarray:
    return np.linspace(lo, hi, max(2, int(n)))


def path_plane_map(
    robot: Robot | ArmModel,
    P: np.ndarray,
    R: np.ndarray,
    branch: str,
    points: int = DEFAULT_POINTS,
    progress: ProgressFn | None = None,
) -> PlaneMap:
    """Diagonal compliance over the plane of the path ``P`` (N, 3), at attitude ``R``, on one branch.

    ``robot``: the arm model whose compliance is mapped (a :class:`Robot` stands for its nominal
    model); its ``kinematics`` are used as they are.  The grid covers the path with a margin
    (:data:`PATH_MAP_MARGIN`, at least :data:`PATH_MAP_MIN_MARGIN_M`), ``points`` along the
    longer in-plane side and the same spacing along the other.
    """
    from models.arm import load_arm
    from planner.compliance_map import evaluate_grid

    plane = path_plane(P)
    uv = plane.uv(P)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    ext = float(np.max(hi - lo))
    m = max(PATH_MAP_MIN_MARGIN_M, PATH_MAP_MARGIN * ext)
    lo, hi = lo - m, hi + m
    short = int(np.argmin(hi - lo))  # keep the grid at least PATH_MAP_MIN_ASPECT : 1
    want = PATH_MAP_MIN_ASPECT * float(np.max(hi - lo))
    if hi[short] - lo[short] < want:
        mid = 0.5 * (hi[short] + lo[short])
        lo[short], hi[short] = mid - 0.5 * want, mid + 0.5 * want
    size = hi - lo
    step = float(np.max(size)) / (max(2, int(points)) - 1)
    nu, nv = (int(round(size[i] / step)) + 1 for i in (0, 1))
    u, v = _grid(lo[0], hi[0], nu), _grid(lo[1], hi[1], nv)
    arm = load_arm(robot)
    labels = arm.ik.labels
    b = labels.index(branch) if branch in labels else None
    q, chosen, diag, status_ref = evaluate_grid(
        arm, plane.points(u, v), np.asarray(R, float), b, max(1, len(u) * len(v)), progress
    )
    reasons: dict[str, int] = {}
    bad = chosen < 0
    if bad.any():
        codes, counts = np.unique(status_ref[bad], return_counts=True)
        for c_, k in zip(codes, counts):
            reasons[IK_REASONS[IKStatus.from_code(c_)]] = int(k)
    shape = (len(u), len(v))
    return PlaneMap(
        arm.nominal.name,
        plane,
        u,
        v,
        np.asarray(R, float),
        branch if b is not None else "home",
        chosen.reshape(shape),
        diag.reshape(shape + (6,)),
        reasons,
        labels,
    )


def _path_map_job(pm: PlaneMap, path: np.ndarray, k_mid: int) -> tuple[Job, str]:
    """The figure job and caption of a path-plane map."""
    rpy = _rpy_deg(pm.R)
    n_bad = pm.n_unreachable
    on = (
        "the path lies in this plane"
        if pm.plane.off_plane_m < 1e-6
        else f"the path is up to {format_number(pm.plane.off_plane_m * 1e3)} mm off this best-fit plane"
    )
    title = (
        f"{pm.robot}: diagonal compliance over the plane of the path ({len(pm.u_m)}×{len(pm.v_m)} points); "
        f"{on}\n{pm.plane.description}\n"
        f"TCP attitude of waypoint k = {k_mid} (roll, pitch, yaw = {', '.join(format_number(a, 3) for a in rpy)} "
        f"deg), branch {pm.branch_label} at every point; {n_bad} of {pm.n_points} points outside its "
        "reach at this attitude (hatched)"
    )
    jb = job(
        plots.compliance_map_figure,
        pm.u_m,
        pm.v_m,
        pm.diag,
        u_label=pm.plane.u_label,
        v_label=pm.plane.v_label,
        title=title,
        branch=pm.branch,
        branch_labels=pm.labels,
        path_uv_m=pm.plane.uv(path),
        path_label="the run's path (● first waypoint, ▶ last)",
    )
    reasons = "; ".join(f"{k}: {v}" for k, v in pm.unreachable_reasons.items())
    caption = (
        f"Paper Fig. 5, over the plane of this run's path with the path drawn on it (red). "
        f"C11–C33: translational compliance along base x, y, z (mm/N); C44–C66: rotational "
        f"compliance (deg/(N·m)). Every grid point is solved on the run's branch {pm.branch_label} at "
        f"the TCP attitude of waypoint k = {k_mid}; {n_bad} of {pm.n_points} points are outside its "
        f"reach (hatched){' — ' + reasons if reasons else ''}. Data: compliance_map.csv (SI; u, v in "
        "the plane and x, y, z in the base frame)."
    )
    return jb, caption


def _rpy_deg(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (deg) of ``R = Rz(yaw) Ry(pitch) Rx(roll)``."""
    pitch = np.arcsin(-np.clip(R[2, 0], -1.0, 1.0))
    roll = np.arctan2(R[2, 1], R[2, 2])
    yaw = np.arctan2(R[1, 0], R[0, 0])
    out = np.degrees([roll, pitch, yaw])
    return np.where(np.abs(out) < 1e-9, 0.0, out) + 0.0


def map_job(cm: ComplianceMap, path: np.ndarray | None = None) -> tuple[Job, str]:
    """The figure job and caption of an axis-aligned compliance map (``compplan map``; a report
    with explicit map options), with the run's ``path`` (N, 3), m, projected onto the plane."""
    used = cm.branches_used()
    rule = (
        "per point, the IK branch nearest the home configuration"
        if cm.branch_rule == "home"
        else f"fixed branch {cm.branch_rule}"
    )
    title = (
        f"{cm.robot}: diagonal compliance over the plane {cm.plane} = {cm.offset_m:g} m, "
        f"{cm.u_axis} ∈ [{cm.u_m[0]:g}, {cm.u_m[-1]:g}] m, "
        f"{cm.v_axis} ∈ [{cm.v_m[0]:g}, {cm.v_m[-1]:g}] m "
        f"({len(cm.u_m)}×{len(cm.v_m)} points)\n"
        f"end attitude (roll, pitch, yaw) = ({', '.join(f'{a:g}' for a in cm.rpy_rad)}) rad, "
        f"R = Rz(yaw)·Ry(pitch)·Rx(roll)\n"
        f"branch: {rule} ({', '.join(f'{k} at {v} points' for k, v in used.items()) or 'none'}); "
        f"{cm.n_unreachable} of {cm.n_points} points unreachable (hatched)"
    )
    path_uv, path_label, path_note = None, "", ""
    if path is not None and len(path):
        n_axis, iu, iv = PLANE_AXES[cm.plane]
        P = np.asarray(path, float)
        path_uv = P[:, [iu, iv]]
        off = P[:, n_axis] - cm.offset_m
        lo, hi = float(off.min()) * 1e3, float(off.max()) * 1e3
        path_label = "the run's path, projected onto the plane (● first waypoint, ▶ last)"
        path_note = " The run's path is drawn projected onto the plane; it lies " + (
            "in the plane."
            if max(abs(lo), abs(hi)) < 1e-3
            else f"{format_number(lo)} to {format_number(hi)} mm from it along {cm.plane}: the "
            "compliance along the path differs from the map's."
        )
    jb = job(
        plots.compliance_map_figure,
        cm.u_m,
        cm.v_m,
        cm.diag,
        u_label=cm.u_axis,
        v_label=cm.v_axis,
        title=title,
        branch=cm.branch,
        branch_labels=cm.labels,
        path_uv_m=path_uv,
        path_label=path_label,
    )
    reasons = "; ".join(f"{k}: {v}" for k, v in cm.unreachable_reasons.items())
    caption = (
        f"Paper Fig. 5. C11–C33: translational compliance (mm/N); C44–C66: rotational "
        f"compliance (deg/(N·m)). {cm.n_unreachable} of {cm.n_points} grid points "
        f"unreachable (hatched){' — ' + reasons if reasons else ''}. "
        f"Branch: {rule}. Data: compliance_map.csv (SI).{path_note}"
    )
    return jb, caption


def _run_path(run: RunRecord) -> tuple[np.ndarray, np.ndarray, int] | None:
    """The run's waypoints (N, 3), the TCP attitude of its middle waypoint (on the run's arm
    model) and that waypoint's index, or None without waypoints."""
    wp = run.waypoints
    if wp is None or run.model is None:
        return None
    P = np.column_stack([wp[a] for a in "xyz"])
    k = len(P) // 2
    qt = np.array([wp[f"qt{i}"][k] for i in range(1, 7)])
    R = run.model.kinematics.tcp(qt)[:3, :3]
    return P, R, int(wp["k"][k])


def map_item(
    run: RunRecord,
    map_options: Mapping[str, Any] | None | bool,
    progress: ProgressFn | None,
    files: dict[str, bytes],
    map_cache: bool,
) -> FigureItem:
    """Figure 1 of a report: from the cache, or computed here (its job still to render).

    The map is the run's arm model's (``run.model``: an identified model's, not its robot
    file's).  ``map_options`` None: over the plane of the run's path, at the attitude of its
    middle waypoint, on its IK branch (without waypoints: the paper's section-4.3 plane); a
    mapping: that axis-aligned plane (:func:`planner.compliance_map.compliance_map`) with
    the path projected onto it; ``False``: absent.  ``compliance_map.csv`` is added to ``files``.
    """
    item = FigureItem(MAP_FIGURE, "Compliance maps C11…C66 over the plane of the path (paper §4.3)", "")
    if map_options is False:
        item.absent = "compliance map not requested (--no-map)"
        return item
    model = run.model
    if model is None:
        why = run.absent.get("model") or run.absent.get("robot", "no robot")
        item.absent = f"compliance map not computed: {why}"
        return item
    path = _run_path(run)
    branch = run.summary.get("chosen_branch", run.summary.get("branch"))
    path_mode = map_options is None and path is not None and isinstance(branch, str) and bool(branch)
    if path_mode:
        P, R, k_mid = path  # type: ignore[misc]
        key_opts: dict[str, Any] = {
            "mode": "path plane",
            "path": P,
            "R": R,
            "branch": branch,
            "points": DEFAULT_POINTS,
            "k_mid": k_mid,
        }
    else:
        opts = dict(map_options or {})
        item.title = "Compliance maps C11…C66 over a plane (paper §4.3)"
        if "branch" in opts:  # the user's option: an unknown label is their error (exit 2), not an absent map
            from planner.compliance_map import branch_index

            branch_index(opts["branch"], tuple(model.ik.labels))
        key_opts = {**opts, "path": None if path is None else path[0]}
    key = _map_cache_key(model, key_opts) if map_cache else None
    hit = _map_cache_get(key) if key else None
    if hit is not None:
        item.png, item.pdf, files["compliance_map.csv"], item.caption = hit
        if progress is not None:
            progress("compliance map", 1, 1)
        return item
    try:
        if path_mode:
            pm = path_plane_map(model, P, R, branch, progress=progress)
            files["compliance_map.csv"] = pm.csv_bytes()
            item.job, item.caption = _path_map_job(pm, P, k_mid)
        else:
            cm = compliance_map(model, progress=progress, **opts)
            files["compliance_map.csv"] = cm.csv_bytes()
            item.job, item.caption = map_job(cm, None if path is None else path[0])
    except CompplanError as exc:
        item.absent = f"compliance map not computed: {exc}"
        return item
    item.cache_key = key
    return item


def cache_rendered_maps(items: list[FigureItem], files: Mapping[str, bytes]) -> None:
    """Keep every freshly rendered compliance map (its ``cache_key`` set) in the cache."""
    for it in items:
        if it.cache_key and it.png is not None and it.pdf is not None:
            _map_cache_put(it.cache_key, it.png, it.pdf, files["compliance_map.csv"], it.caption)


# ------------------------------------------------------------------------------------ cache
def _map_cache_dir(key: str) -> Path:
    root = os.environ.get("COMPPLAN_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "compplan")
    return Path(root) / "maps" / key


def _model_description(arm: ArmModel) -> dict[str, Any]:
    """Everything of an arm model its kinematic functions are built from (the cache key's part)."""
    return arm.nominal.to_dict() | {
        "theta": arm.theta,
        "const": arm.planning_const,
        "effects": list(arm.arm_effects),
        "temperature_C": arm.temperature_ref,
    }


def _map_cache_key(robot: Robot | ArmModel, map_options: Mapping[str, Any]) -> str:
    """Hash of the arm model (a :class:`Robot`: its nominal one), the map options (defaults
    filled in), the drawing code and matplotlib."""
    import hashlib
    import inspect

    import matplotlib

    from planner import compliance_map as cmod
    from planner import numbers

    sig = inspect.signature(cmod.compliance_map)
    opts = {
        k: p.default
        for k, p in sig.parameters.items()
        if p.default is not inspect.Parameter.empty and k not in ("progress", "chunk")
    }
    opts.update({k: v for k, v in map_options.items() if k not in ("progress", "chunk")})
    desc = _model_description(robot if isinstance(robot, ArmModel) else ArmModel.from_robot(robot))
    blob = json.dumps({"robot": desc, "options": opts}, sort_keys=True, default=lambda o: np.asarray(o, float).tolist())
    h = hashlib.sha256(blob.encode())
    for path in (plots.__file__, figure_base.__file__, cmod.__file__, numbers.__file__, __file__):
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
def write_map(
    robot: Robot, folder: str | Path, progress: ProgressFn | None = None, **options: Any
) -> tuple[ComplianceMap, list[Path]]:
    """Compute a compliance map and write it (``compplan map``).

    Writes ``compliance_map.csv`` (SI), ``compliance_map.json`` (its provenance, what
    was computed, ranges in SI) and ``figures/fig1_compliance_map.png|pdf`` into
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
    from models.arm import ArmModel

    src = robot.source if isinstance(robot, ArmModel) and robot.source else robot.name
    sha = robot.sha256 if isinstance(robot, ArmModel) else None
    prov = provenance([robot_input(src, sha256=sha or None)])
    out.add_bytes("compliance_map.json", json_bytes({"provenance": prov, **cm.summary(), "caption": caption}))
    out.add_bytes(f"figures/{MAP_FIGURE}.png", png)
    out.add_bytes(f"figures/{MAP_FIGURE}.pdf", pdf)
    return cm, out.publish()
