"""The report's 3-D view of the cell: the robot as its capsules at a few postures along the path,
the cell's objects, the tool and the path coloured by the load-induced error.

Drawn only for a run whose problem has a ``[cell]`` (``summary.json`` key ``problem.cell``, the
cell as :meth:`problems.cell.Cell.to_dict` writes it: SI units, radians, base frame); a run without
one has no such figure, not an absent one.  The view is built from the run alone, never from the
problem file: the objects from ``problem.cell``, a mesh object's triangles read again from the file
it records after checking the SHA-256 that ``provenance.inputs`` holds for it (role ``cell mesh``;
a file moved or changed since the run is not drawn, and the caption says so), the robot from
``robot_file`` (:attr:`~planner.record.RunRecord.robot`), the postures and the errors from
``waypoints.csv``.

* the robot: its collision capsules (:func:`models.collision.capsule_model`, the geometry the cell
  check uses) along the nominal chain at the **commanded** joints ``q_command`` (what the controller
  runs and the cell check checks) of :data:`CELL_POSES` waypoints (first, last and evenly spread
  between), the last solid and the others faded, each with its capsule axes (the segment ends: the
  DH frame origins and the offsets along the joint axes) and the tool as a line from the flange
  to the TCP;
* the objects: boxes, cylinders and spheres as triangle meshes, meshes as read; obstacles grey,
  the workpiece orange;
* the path (the TCP targets) coloured by the load-induced TCP error before compensation (mm,
  colour bar); the base frame's axes at the origin; equal scale on x, y, z (m).

Two renderings of the same :class:`CellScene`: an interactive plotly figure embedded in
``report.html`` (:func:`cell_plotly_div`; the plotly.js bundle is embedded once per report by
:func:`planner.report.rendering.render_html`, so the report needs no network), and a static
matplotlib figure (:func:`cell_figure`) for ``figures/*.png|pdf`` and ``report.md``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from models.errors import InputError

from planner.numbers import format_number
from planner.report.cell_record import cell_block
from planner.report.figure_base import new_figure, styled
from planner.report.rendering import FigureItem, job
from planner.record import RunRecord
from planner.report.tables import load_words

if TYPE_CHECKING:
    from models.collision.scene import SceneObject

__all__ = [
    "CELL_FIGURE",
    "cell_items",
]

#: File name of the cell view (fixed, like the other optional figures' names).
CELL_FIGURE = "fig11_cell"
#: Postures of the robot drawn: the first and last waypoints and evenly spread ones between.
CELL_POSES = 5
#: Sides of a capsule's mesh around its axis (interactive view; the static one uses half).
CAPSULE_SIDES = 16
#: Opacity of the faded (earlier) postures, of the last posture, and of the objects.
FADED_OPACITY = 0.18
SOLID_OPACITY = 1.0
OBJECT_OPACITY = 0.45
#: Colours: obstacles, the workpiece, the robot, its capsule axes, the tool.
OBSTACLE_COLOUR = "#8c8c8c"
WORKPIECE_COLOUR = "#e69f00"
ROBOT_COLOUR = "#3a6ea5"
AXIS_COLOUR = "#1b2a3a"
TOOL_COLOUR = "#c0392b"
#: Colour scale of the path's error (plotly name, matplotlib name).
ERROR_SCALE = ("Viridis", "viridis")
#: Length of the drawn base-frame axes, as a share of the scene's largest extent (m/m).
BASE_AXES_SHARE = 0.12
#: Zoom of the static view's 3-D box (matplotlib leaves wide margins around it otherwise).
STATIC_ZOOM = 1.1
#: Width of the colour scale when every waypoint has the same error, mm (a scale needs a width).
FLAT_SCALE_MM = 1e-9
#: The provenance role of a cell's mesh files (:func:`planner.provenance.problem_provenance`).
MESH_ROLE = "cell mesh"
#: The plotly figure's height in report.html, px.
PLOTLY_HEIGHT_PX = 720
#: The ``id`` of the plotly figure's element in report.html.
PLOTLY_DIV_ID = "cell_view_3d"


@dataclass(frozen=True)
class DrawnObject:
    """One cell object as triangles in the base frame.

    Attributes
    ----------
    name, shape, role : str
    vertices : ndarray, shape (V, 3)
        Base frame, m.
    faces : ndarray of int, shape (F, 3)
    """

    name: str
    shape: str
    role: str
    vertices: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True)
class CellScene:
    """What the cell view draws (base frame, m).

    Attributes
    ----------
    objects : list of DrawnObject
    waypoints : ndarray of int, shape (P,)
        The waypoints whose commanded postures are drawn (the last is drawn solid).
    segments : ndarray, shape (P, M, 2, 3)
        Capsule segment ends per posture (:func:`models.collision.capsule_segments`), m.
    radius : ndarray, shape (M,)
        Capsule radii, m.
    capsule_names : tuple of str
    tool : ndarray, shape (P, 2, 3)
        Flange and TCP per posture, m.
    path : ndarray, shape (N, 3)
        TCP targets, m.
    error_mm : ndarray, shape (N,)
        Load-induced TCP error before compensation, mm.
    clearance_m : float
    notes : list of str
        What is not drawn and why (a mesh file changed since the run).
    """

    objects: list[DrawnObject]
    waypoints: np.ndarray
    segments: np.ndarray
    radius: np.ndarray
    capsule_names: tuple[str, ...]
    tool: np.ndarray
    path: np.ndarray
    error_mm: np.ndarray
    clearance_m: float
    notes: list[str] = field(default_factory=list)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners of everything drawn, m."""
        pts = [self.path, self.segments.reshape(-1, 3), self.tool.reshape(-1, 3), np.zeros((1, 3))]
        pts += [o.vertices for o in self.objects]
        allp = np.vstack(pts)
        return allp.min(axis=0), allp.max(axis=0)


# ------------------------------------------------------------------------ the recorded cell
def _mesh_hashes(summary: Mapping[str, Any]) -> dict[str, str]:
    """Resolved path -> SHA-256 of the cell's mesh files in ``provenance.inputs``."""
    prov = summary.get("provenance")
    inputs = prov.get("inputs") if isinstance(prov, Mapping) else None
    out = {}
    for e in inputs if isinstance(inputs, list) else ():
        if isinstance(e, Mapping) and e.get("role") == MESH_ROLE and e.get("path") and e.get("sha256"):
            out[str(Path(e["path"]).resolve())] = str(e["sha256"])
    return out


def _scene_object(rec: Mapping[str, Any], hashes: Mapping[str, str]) -> SceneObject | str:
    """A recorded object (:func:`cell_block`) as the collision scene holds it, or why it is not drawn."""
    from models.collision.scene import SceneObject
    from models.collision.shapes import shape_class

    if "file" in rec:  # a shape read from a file: drawn only if the file is the one the run read
        path = Path(rec["file"]).resolve()
        try:
            data = path.read_bytes()
        except OSError as exc:
            return f"mesh '{rec['name']}' not drawn: {path} cannot be read ({exc.strerror})"
        sha = hashlib.sha256(data).hexdigest()
        recorded = hashes.get(str(path))
        if recorded is not None and sha != recorded:
            return (
                f"mesh '{rec['name']}' not drawn: {path} has changed since the run (SHA-256 recorded "
                f"{recorded[:12]}…, now {sha[:12]}…)"
            )
    return SceneObject(rec["name"], shape_class(rec["shape"]).from_record(rec), rec["object2base"], rec["role"])


# ------------------------------------------------------------------------------- the scene
def _pose_indices(n: int, k: int = CELL_POSES) -> np.ndarray:
    """First, last and evenly spread waypoints between, at most ``k`` (sorted, unique)."""
    return np.unique(np.round(np.linspace(0, n - 1, min(k, n))).astype(int))


def cell_scene(run: RunRecord) -> CellScene | str | None:
    """The cell view of ``run``: None without a cell, a reason (str) when it cannot be drawn.

    The objects from ``summary["problem"]["cell"]`` (:func:`cell_block`), the robot's capsules at
    the commanded joints (``waypoints.csv`` ``qc1..qc6``) of :func:`_pose_indices`, the path
    (``x, y, z``) and its error before compensation (``ebx, eby, ebz``).
    """
    from models.collision import capsule_segments, chain_frames
    from models.collision.scene import Scene

    prob = run.summary.get("problem")
    block = prob.get("cell") if isinstance(prob, Mapping) else None
    if block is None:
        return None
    where = "summary.json problem.cell"
    if run.robot is None:
        return f"cell view not drawn: {run.absent.get('robot', 'the robot is unknown')}"
    wp = run.waypoints
    if wp is None:
        return f"cell view not drawn: {run.absent.get('waypoints', 'waypoints.csv absent')}"
    clearance, recs = cell_block(block, where)
    hashes = _mesh_hashes(run.summary)
    found = [_scene_object(rec, hashes) for rec in recs]
    notes = [o for o in found if isinstance(o, str)]
    robot = run.robot
    scene = Scene.build(robot, [o for o in found if not isinstance(o, str)], clearance=clearance)
    objects = [DrawnObject(o.name, o.kind, o.role, *o.triangles()) for o in scene.objects]
    qc = np.column_stack([wp[f"qc{i}"] for i in range(1, 7)])
    idx = _pose_indices(len(qc))
    model = scene.arm
    frames = chain_frames(robot, qc[idx])  # (P, 7, 4, 4)
    flange = frames[:, 6] @ np.asarray(robot.flange2frame6, dtype=float)
    tcp = flange @ np.asarray(robot.tcp2flange, dtype=float)
    path = np.column_stack([wp[a] for a in "xyz"])
    err = np.linalg.norm(np.column_stack([wp[f"eb{a}"] for a in "xyz"]), axis=1) * 1e3
    return CellScene(
        objects,
        idx,
        capsule_segments(model, frames),
        np.asarray(model.radius, dtype=float),
        tuple(model.names),
        np.stack([flange[:, :3, 3], tcp[:, :3, 3]], axis=1),
        path,
        err,
        clearance,
        notes,
    )


def capsule_mesh(
    a: np.ndarray, b: np.ndarray, radius: float, sides: int = CAPSULE_SIDES
) -> tuple[np.ndarray, np.ndarray]:
    """A capsule (segment ``a``-``b`` swept by a sphere of ``radius``, m) as triangles.

    A UV sphere whose upper half is moved along the axis by the segment's length: vertices (V, 3)
    in the base frame, faces (F, 3).
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    rings = max(2, sides // 4)  # rings per hemisphere
    lat = np.r_[np.linspace(-np.pi / 2, 0.0, rings + 1), np.linspace(0.0, np.pi / 2, rings + 1)]
    shift = np.r_[np.zeros(rings + 1), np.full(rings + 1, length)]  # the equator twice: the cylinder
    lon = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    cl, sl = np.cos(lat)[:, None], np.sin(lat)[:, None]
    local = (
        np.stack([cl * np.cos(lon), cl * np.sin(lon), np.broadcast_to(sl, (len(lat), sides))], axis=-1) * radius
    )  # (R, S, 3)
    local[..., 2] += shift[:, None]
    verts = a + local.reshape(-1, 3) @ np.stack([x, y, z])
    R = len(lat)
    i, j = np.meshgrid(np.arange(R - 1), np.arange(sides), indexing="ij")
    p00, p01 = i * sides + j, i * sides + (j + 1) % sides
    p10, p11 = p00 + sides, p01 + sides
    faces = np.concatenate([np.stack([p00, p01, p11], -1).reshape(-1, 3), np.stack([p00, p11, p10], -1).reshape(-1, 3)])
    return verts, faces


def _robot_mesh(segments: np.ndarray, radius: np.ndarray, sides: int) -> tuple[np.ndarray, np.ndarray]:
    """All capsules of one posture (segments (M, 2, 3)) as one triangle mesh."""
    vs, fs, n = [], [], 0
    for (a, b), r in zip(segments, radius):
        v, f = capsule_mesh(a, b, float(r), sides)
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return np.vstack(vs), np.vstack(fs)


def _axis_points(segments: np.ndarray) -> np.ndarray:
    """The capsule axes of one posture as one polyline with NaN breaks: (3M, 3)."""
    m = segments.shape[0]
    out = np.full((m, 3, 3), np.nan)
    out[:, :2] = segments
    return out.reshape(-1, 3)


# ------------------------------------------------------------------------------ the items
def cell_items(run: RunRecord) -> list[FigureItem]:
    """The cell view of ``run`` (static job and interactive HTML), or none without a cell."""
    try:
        scene = cell_scene(run)
    except InputError as exc:
        scene = f"cell view not drawn: {exc}"
    if scene is None:
        return []
    item = FigureItem(CELL_FIGURE, "The cell in 3-D: the robot's collision capsules, the objects and the path", "")
    if isinstance(scene, str):
        item.absent = scene
        return [item]
    s = run.summary
    k = ", ".join(str(int(run.waypoints["k"][i])) for i in scene.waypoints)  # type: ignore[index]
    title = (
        f"{s.get('robot', '?')}, branch {s.get('chosen_branch', s.get('branch', '?'))}: the cell, "
        f"the robot at waypoints {k} (commanded joints)"
    )
    item.job = job(cell_figure, scene, title=title)
    item.interactive = cell_plotly_div(scene, title)
    names = ", ".join(f"{o.name} ({o.role})" for o in scene.objects) or "none drawn"
    item.caption = (
        f"The robot as its collision capsules (the geometry the cell check uses: radii per link, "
        f"docs/cell.md) on the nominal chain at the commanded joints q_command of waypoints {k} "
        "(what the controller runs), the last solid, the earlier faded, with their axes (the segment ends: "
        "joint centres and link offsets) and the tool from the flange to the TCP (red). Objects: "
        f"{names}; obstacles grey, the workpiece orange; clearance required "
        f"{format_number(scene.clearance_m * 1e3)} mm. The path (TCP targets) coloured by the "
        f"load-induced TCP error before compensation, mm (load: {load_words(s)}). Base frame, m, equal "
        "scale on x, y, z. report.html holds the interactive view (turn, zoom, hide a trace in the legend)."
        + ("" if not scene.notes else " Not drawn: " + "; ".join(scene.notes) + ".")
    )
    return [item]


# ------------------------------------------------------------------------ plotly (interactive)
def _scene_range(scene: CellScene) -> tuple[np.ndarray, np.ndarray, float]:
    lo, hi = scene.bounds()
    span = float(np.max(hi - lo)) or 1.0
    return lo, hi, span


def cell_plotly_div(scene: CellScene, title: str) -> str:
    """The interactive view as an HTML ``<div>`` with its script, **without** plotly.js (the
    report embeds the bundle once: :func:`planner.report.rendering.render_html`)."""
    import plotly.graph_objects as go

    traces = _object_traces(scene) + _pose_traces(scene)
    P, e = scene.path, scene.error_mm
    bar = {"title": {"text": "error<br>before<br>[mm]"}, "len": 0.7}  # on the right; the legend below the scene
    traces.append(
        go.Scatter3d(
            x=P[:, 0], y=P[:, 1], z=P[:, 2], mode="lines+markers", name="path (error before compensation)",
            line={"color": e, "colorscale": ERROR_SCALE[0], "width": 6},
            marker={"size": 3, "color": e, "colorscale": ERROR_SCALE[0], "colorbar": bar},
            meta={"kind": "path"}, customdata=np.arange(len(P)),
            hovertemplate="waypoint %{customdata}<br>error before %{marker.color:.3f} mm<extra></extra>",
        )
    )  # fmt: skip
    lo, hi, span = _scene_range(scene)
    traces += _base_axis_traces(span)
    fig = go.Figure(traces)
    fig.update_layout(
        title={"text": title, "font": {"size": 14}},
        height=PLOTLY_HEIGHT_PX,
        margin={"l": 0, "r": 0, "t": 50, "b": 60},
        scene={
            "aspectmode": "data",
            "xaxis": {"title": {"text": "x [m]"}},
            "yaxis": {"title": {"text": "y [m]"}},
            "zaxis": {"title": {"text": "z [m]"}},
        },
        legend={"itemsizing": "constant", "orientation": "h", "x": 0.0, "y": 0.0, "yanchor": "top"},
    )
    return fig.to_html(
        full_html=False,
        include_plotlyjs=False,
        include_mathjax=False,
        div_id=PLOTLY_DIV_ID,
        config={"displaylogo": False, "responsive": True},
    )


def _object_traces(scene: CellScene) -> list[Any]:
    """The cell's objects as plotly meshes (workpiece and obstacles)."""
    import plotly.graph_objects as go

    traces: list[Any] = []
    for o in scene.objects:
        v, f = o.vertices, o.faces
        colour = WORKPIECE_COLOUR if o.role == "workpiece" else OBSTACLE_COLOUR
        traces.append(
            go.Mesh3d(
                x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2],
                name=o.name, color=colour, opacity=OBJECT_OPACITY, flatshading=True, showlegend=True,
                meta={"kind": "object", "role": o.role, "shape": o.shape},
                hovertemplate=f"{o.name} ({o.shape}, {o.role})<extra></extra>",
            )
        )  # fmt: skip
    return traces


def _pose_traces(scene: CellScene) -> list[Any]:
    """Per drawn waypoint: the robot's capsules, their axes and the tool (the last pose solid, the others faded)."""
    import plotly.graph_objects as go

    traces: list[Any] = []
    last = len(scene.waypoints) - 1
    for p, k in enumerate(scene.waypoints):
        v, f = _robot_mesh(scene.segments[p], scene.radius, CAPSULE_SIDES)
        op = SOLID_OPACITY if p == last else FADED_OPACITY
        group = f"pose{int(k)}"
        traces.append(
            go.Mesh3d(
                x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2],
                name=f"robot, waypoint {int(k)}", color=ROBOT_COLOUR, opacity=op, flatshading=False,
                legendgroup=group, showlegend=True, meta={"kind": "robot", "waypoint": int(k)}, hoverinfo="skip",
            )
        )  # fmt: skip
        ax = _axis_points(scene.segments[p])
        traces.append(
            go.Scatter3d(
                x=ax[:, 0], y=ax[:, 1], z=ax[:, 2], mode="lines+markers", legendgroup=group, showlegend=False,
                name=f"capsule axes, waypoint {int(k)}", line={"color": AXIS_COLOUR, "width": 3},
                marker={"size": 2, "color": AXIS_COLOUR}, meta={"kind": "capsule_axes", "waypoint": int(k)},
                opacity=1.0 if p == last else 0.5, hoverinfo="skip",
            )
        )  # fmt: skip
        t = scene.tool[p]
        traces.append(
            go.Scatter3d(
                x=t[:, 0], y=t[:, 1], z=t[:, 2], mode="lines", legendgroup=group, showlegend=False,
                name=f"tool, waypoint {int(k)}", line={"color": TOOL_COLOUR, "width": 6},
                meta={"kind": "tool", "waypoint": int(k)}, hoverinfo="skip",
            )
        )  # fmt: skip
    return traces


def _base_axis_traces(span: float) -> list[Any]:
    """The base frame's three axes, ``BASE_AXES_SHARE`` of the scene's ``span`` (m) long."""
    import plotly.graph_objects as go

    traces: list[Any] = []
    L = BASE_AXES_SHARE * span
    for n, (name, col) in enumerate((("x", "#d62728"), ("y", "#2ca02c"), ("z", "#1f77b4"))):
        end = np.zeros(3)
        end[n] = L
        traces.append(
            go.Scatter3d(
                x=[0.0, end[0]], y=[0.0, end[1]], z=[0.0, end[2]], mode="lines+text", text=["", f"base {name}"],
                line={"color": col, "width": 5}, name="base frame", legendgroup="base", showlegend=n == 0,
                meta={"kind": "base_axis"}, hoverinfo="skip",
            )
        )  # fmt: skip
    return traces


# ---------------------------------------------------------------------- matplotlib (static)
@styled
def cell_figure(scene: CellScene, *, title: str) -> Figure:
    """The static view (PNG/PDF): the same scene on matplotlib's 3-D axes, equal scale."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    fig = new_figure(9.5, 6.8)
    ax = fig.add_axes((0.0, 0.0, 0.86, 0.93), projection="3d")
    for o in scene.objects:
        colour = WORKPIECE_COLOUR if o.role == "workpiece" else OBSTACLE_COLOUR
        pc = Poly3DCollection(o.vertices[o.faces], facecolors=colour, alpha=OBJECT_OPACITY, edgecolor="none")
        ax.add_collection3d(pc)
    last = len(scene.waypoints) - 1
    for p in range(len(scene.waypoints)):
        v, f = _robot_mesh(scene.segments[p], scene.radius, CAPSULE_SIDES // 2)
        solid = p == last
        ax.add_collection3d(
            Poly3DCollection(
                v[f], facecolors=ROBOT_COLOUR, alpha=0.85 if solid else FADED_OPACITY, edgecolor="none", shade=True
            )
        )
        ax.add_collection3d(
            Line3DCollection(list(scene.segments[p]), colors=AXIS_COLOUR, linewidths=1.2 if solid else 0.6)
        )
        ax.plot(*scene.tool[p].T, color=TOOL_COLOUR, lw=2.0 if solid else 1.0)
    P, e = scene.path, scene.error_mm
    norm = Normalize(float(e.min()), float(e.max()) if e.max() > e.min() else float(e.min()) + FLAT_SCALE_MM)
    segs = np.stack([P[:-1], P[1:]], axis=1)
    mid_e = 0.5 * (e[:-1] + e[1:])
    ax.add_collection3d(Line3DCollection(list(segs), cmap=ERROR_SCALE[1], norm=norm, linewidths=3.0, array=mid_e))
    ax.scatter(*P.T, c=e, cmap=ERROR_SCALE[1], norm=norm, s=6, depthshade=False)
    lo, hi, span = _scene_range(scene)
    L = BASE_AXES_SHARE * span
    for n, col in enumerate(("#d62728", "#2ca02c", "#1f77b4")):
        end = np.zeros(3)
        end[n] = L
        ax.plot([0, end[0]], [0, end[1]], [0, end[2]], color=col, lw=2)
        ax.text(*(1.08 * end), "xyz"[n], color=col)
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo) + 0.02 * span
    ax.set_xlim(mid[0] - half[0], mid[0] + half[0])
    ax.set_ylim(mid[1] - half[1], mid[1] + half[1])
    ax.set_zlim(mid[2] - half[2], mid[2] + half[2])
    ax.set_box_aspect(tuple(half), zoom=STATIC_ZOOM)  # equal scale on x, y, z
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=25.0, azim=-60.0)
    cax = fig.add_axes((0.9, 0.2, 0.02, 0.55))
    fig.colorbar(ScalarMappable(norm=norm, cmap=ERROR_SCALE[1]), cax=cax, label="TCP error before compensation [mm]")
    fig.suptitle(title)
    _legend(fig, scene)
    return fig


def _legend(fig: Figure, scene: CellScene) -> None:
    from matplotlib.patches import Patch
    from matplotlib.lines import Line2D

    handles: list[Any] = [
        Patch(color=ROBOT_COLOUR, label=f"robot at waypoint {int(scene.waypoints[-1])} (earlier: faded)"),
        Line2D([], [], color=TOOL_COLOUR, label="tool (flange to TCP)"),
    ]
    roles = {o.role for o in scene.objects}
    handles += [Patch(color=OBSTACLE_COLOUR, alpha=OBJECT_OPACITY, label="obstacle")] if "obstacle" in roles else []
    handles += [Patch(color=WORKPIECE_COLOUR, alpha=OBJECT_OPACITY, label="workpiece")] if "workpiece" in roles else []
    fig.legend(handles=handles, loc="lower left", fontsize=8, frameon=False)
