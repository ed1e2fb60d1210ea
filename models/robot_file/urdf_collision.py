"""The collision geometry of a URDF-based robot: the URDF's ``<collision>`` elements and link
frames as capsules (``docs/cell.md``, "URDF collision elements"); a box, cylinder or sphere element
through its shape kind (``models/collision/shapes/``), a mesh by the capsule of its vertices."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from models.description import CollisionSegment, RobotCollision, RobotFileError

from .collision_table import parse_collision_table
from .urdf_chain import UrdfChain, chain_joints, joint_origin
from .urdf_dh import DHChain

# --------------------------------------------------------------------------------------
# Collision geometry: the URDF's <collision> elements and link frames as capsules
# --------------------------------------------------------------------------------------

#: Two URDF joint origins closer than this (m) give no link-frame capsule segment.
ORIGIN_SEGMENT_MIN_M = 1e-9
#: A link-frame segment within this distance (m) of joint i+1's axis lies on it (it then belongs to
#: link i+1, as the DH capsules' offsets along joint axes do).
ON_AXIS_TOL_M = 1e-9
#: A mesh's bounding capsule is at least this thick (m): a mesh of collinear vertices.
MESH_MIN_RADIUS_M = 1e-6


def _mesh_path(urdf_path: Path, link: str, filename: str) -> Path:
    """The file of a ``<mesh filename>``: ``package://pkg/sub/file`` relative to the URDF's folder (or
    its parent, the package), ``file://`` absolute, else relative to the URDF's folder."""
    folder = urdf_path.parent
    if filename.startswith("package://"):
        rest = filename[len("package://") :]
        sub = rest.partition("/")[2]
        candidates = [folder / sub, folder.parent / sub, folder / rest, folder.parent / rest]
    elif filename.startswith("file://"):
        candidates = [Path(filename[len("file://") :])]
    else:
        candidates = [Path(filename) if Path(filename).is_absolute() else folder / filename]
    for c in candidates:
        if c.is_file():
            return c
    raise RobotFileError(
        f"{urdf_path}: link '{link}': <collision> mesh '{filename}' not found (looked for "
        f"{', '.join(str(c) for c in dict.fromkeys(candidates))}); put the mesh there or remove the element"
    )


def points_capsule(V: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A capsule containing points (and so their convex hull): along their principal axis.

    Parameters
    ----------
    V : ndarray, shape (N, 3)
        Points, m.

    Returns
    -------
    p0, p1 : ndarray, shape (3,)
        Segment ends, same frame, m.
    radius : float
        The largest distance of a point from the axis (at least :data:`MESH_MIN_RADIUS_M`), m; the
        segment is as short as that radius allows.
    """
    c = V.mean(axis=0)
    X = V - c
    axis = np.linalg.svd(X, full_matrices=False)[2][0] if len(V) > 1 else np.array([0.0, 0.0, 1.0])
    t = X @ axis
    rho = np.linalg.norm(X - np.outer(t, axis), axis=1)
    r = max(float(rho.max()), MESH_MIN_RADIUS_M)
    slack = np.sqrt(np.maximum(r * r - rho * rho, 0.0))
    lo, hi = float(np.min(t + slack)), float(np.max(t - slack))
    if lo > hi:  # a short, thick part: a sphere about the middle
        lo = hi = 0.5 * (lo + hi)
        r = max(r, float(np.max(np.linalg.norm(X - lo * axis, axis=1))))
    return c + lo * axis, c + hi * axis, r


def _element_capsule(where: str, urdf_path: Path, link: str, geom: Any) -> tuple[np.ndarray, np.ndarray, float, str]:
    """The bounding capsule of one ``<collision>`` geometry in its own frame: ends, radius (m), kind."""
    from models.collision.shapes import shape_class, shape_kinds

    if geom is None:
        raise RobotFileError(f"{urdf_path}: link '{link}': a <collision> element without <geometry>")
    for kind in shape_kinds():  # the shape kinds that read a URDF element: their bounding capsule
        cls = shape_class(kind)
        element = getattr(geom, cls.urdf_element, None) if cls.urdf_element else None
        if element is not None:
            return (*cls.from_urdf(element).bounding_capsule(), kind)
    if geom.mesh is not None:  # a mesh: the capsule of its vertices, scaled per axis (points_capsule)
        path = _mesh_path(urdf_path, link, geom.mesh.filename)
        try:
            import trimesh

            mesh = trimesh.load(str(path), force="mesh")
            V = np.asarray(mesh.vertices, dtype=float)
        except Exception as exc:
            raise RobotFileError(f"{path}: link '{link}': cannot read the <collision> mesh: {exc}") from None
        if V.ndim != 2 or len(V) == 0 or not np.all(np.isfinite(V)):
            raise RobotFileError(f"{path}: link '{link}': the <collision> mesh has no finite vertices")
        scale = 1.0 if geom.mesh.scale is None else np.asarray(geom.mesh.scale, dtype=float)
        p0, p1, r = points_capsule(V * scale)
        return p0, p1, r, f"mesh {path.name}"
    raise RobotFileError(f"{urdf_path}: link '{link}': a <collision> <geometry> that is no box, cylinder, sphere, mesh")


def _body_links(model: Any, chain: UrdfChain, base_link: str) -> list[list[tuple[str, np.ndarray]]]:
    """Per body 0..6, the links rigidly attached to it and each link's frame in the body's frame:
    body 0 the links joined to ``base_link`` by fixed joints (base_link frame), body i those after
    joint i (its child link's frame)."""
    chain_names = set(chain.joint_names)
    by_parent: dict[str, list[Any]] = {}
    by_child: dict[str, Any] = {}
    for j in model.joints:
        by_parent.setdefault(j.parent, []).append(j)
        by_child[j.child] = j

    def origin(j: Any) -> np.ndarray:
        return np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)

    def component(start: str, up: bool) -> list[tuple[str, np.ndarray]]:
        seen, out, stack = {start}, [], [(start, np.eye(4))]
        while stack:
            name, T = stack.pop()
            out.append((name, T))
            nxt = [(j.child, T @ origin(j)) for j in by_parent.get(name, []) if j.type == "fixed"]
            pj = by_child.get(name)
            if up and pj is not None and pj.type == "fixed":
                nxt.append((pj.parent, T @ np.linalg.inv(origin(pj))))
            for n, Tn in nxt:
                if n not in seen:
                    seen.add(n)
                    stack.append((n, Tn))
        return out

    joints = {j.name: j for j in model.joints if j.name in chain_names}
    return [component(base_link, up=True)] + [component(joints[n].child, up=False) for n in chain.joint_names]


def _element_segments(
    where: str, urdf_path: Path, chain: UrdfChain, ch: DHChain, base_link: str
) -> list[CollisionSegment]:
    """The URDF's ``<collision>`` elements as bounding capsules fixed in the DH frame of their body."""
    links = {lk.name: lk for lk in chain.model.links}
    out = []
    for body, parts in enumerate(_body_links(chain.model, chain, base_link)):
        # body frame (base link / joint frame i) -> the frame the capsule is given in (base / DH frame i)
        to_dh = np.eye(4) if body == 0 else np.linalg.inv(ch.frames0[body]) @ chain.frames[body - 1]
        for name, link2body in parts:
            for k, col in enumerate(links[name].collisions or []):
                p0, p1, r, kind = _element_capsule(where, urdf_path, name, col.geometry)
                if not (math.isfinite(r) and r > 0 and np.all(np.isfinite(p0)) and np.all(np.isfinite(p1))):
                    raise RobotFileError(f"{urdf_path}: link '{name}': <collision> {kind} has no positive finite size")
                el2link = np.eye(4) if col.origin is None else np.asarray(col.origin, dtype=float)
                if not np.all(np.isfinite(el2link)):
                    raise RobotFileError(f"{urdf_path}: link '{name}': <collision> <origin> is not finite (NaN or inf)")
                T = to_dh @ link2body @ el2link
                a, b = (T[:3, :3] @ p + T[:3, 3] for p in (p0, p1))
                label = col.name or f"#{k + 1}"
                out.append(
                    CollisionSegment(
                        body=body,
                        frame_a=body if body else -1,
                        xyz_a=a,
                        frame_b=body if body else -1,
                        xyz_b=b,
                        radius=float(r),
                        name=f"urdf link '{name}' <collision> {label} ({kind})",
                    )
                )
    return out


def _origin_segments(
    where: str, chain: UrdfChain, ch: DHChain, base_link: str, tip_link: str
) -> list[CollisionSegment]:
    """The lines between consecutive URDF joint origins from ``base_link`` to ``tip_link`` (the
    links' frames, where a URDF's author put its links), each fixed in the DH frame of its link; a
    line on the next joint's axis belongs to that joint's link (as the DH offsets along an axis)."""
    common2base, joints = chain_joints(where, chain.model, base_link, tip_link)
    w, p = chain.zero_axes()
    T, body = common2base.copy(), 0
    pts = [(np.zeros(3), 0, base_link)]
    for j in joints:
        T = T @ joint_origin(where, j)
        body += int(j.type != "fixed")
        pts.append((T[:3, 3].copy(), body, j.name))
    out = []
    for (pa, b, na), (pb, _, nb) in zip(pts[:-1], pts[1:]):
        if np.linalg.norm(pb - pa) <= ORIGIN_SEGMENT_MIN_M:
            continue
        on_next_axis = b < 6 and all(np.linalg.norm(np.cross(x - p[b], w[b])) <= ON_AXIS_TOL_M for x in (pa, pb))
        # link b's line, given in DH frame b (the base frame for the base); on joint b+1's axis it is
        # link b+1's, still given in DH frame b (fixed there too; DH frame 0 for a line on joint 1's axis)
        frame = b if (b > 0 or on_next_axis) else -1
        body = b + 1 if on_next_axis else b
        inv = np.linalg.inv(ch.frames0[frame]) if frame >= 0 else np.eye(4)
        la, lb = ((inv @ np.append(x, 1.0))[:3] for x in (pa, pb))
        out.append(
            CollisionSegment(
                body=body,
                frame_a=frame,
                xyz_a=la,
                frame_b=frame,
                xyz_b=lb,
                line=True,
                name=f"urdf joint origins {na} -> {nb}",
            )
        )
    return out


def urdf_collision(
    where: str,
    urdf_path: Path,
    chain: UrdfChain,
    ch: DHChain,
    base_link: str,
    tip_link: str,
    table: Any = None,
) -> RobotCollision | None:
    """The collision geometry of a URDF-based robot: the robot file's ``[collision]`` table, the
    URDF's ``<collision>`` elements (each a bounding capsule fixed in its link's DH frame; a body
    with elements is described by them alone: ``replace_dh``), and for the other bodies the lines
    between the URDF's joint origins (``docs/cell.md``, "URDF collision elements").

    Box: along its longest side, radius the half-diagonal of the other two; cylinder: along its
    axis, its radius and length; sphere: a point with its radius; mesh (``package://`` relative to
    the URDF's folder, read with trimesh): along its vertices' principal axis (:func:`points_capsule`).

    Raises
    ------
    RobotFileError
        A malformed ``[collision]`` table, a mesh that cannot be found or read (naming the file and link).
    """
    declared = parse_collision_table(where, table) if table is not None else None
    elements = _element_segments(where, urdf_path, chain, ch, base_link)
    replaced = set(declared.replace_dh if declared is not None else ()) | {s.body for s in elements}
    frames = [s for s in _origin_segments(where, chain, ch, base_link, tip_link) if s.body not in replaced]
    if declared is None and not elements and not frames:
        return None
    source = declared.source if declared is not None else ""
    if elements:
        linked = sorted({lk.name for lk in chain.model.links if lk.collisions})
        what = f"{urdf_path.name}: <collision> elements of link(s) {', '.join(linked)}"
        source = f"{source}; {what}" if source else what
    return RobotCollision(
        radii=declared.radii if declared is not None else None,
        allowed_pairs=declared.allowed_pairs if declared is not None else None,
        segments=(declared.segments if declared is not None else ()) + tuple(elements) + tuple(frames),
        replace_dh=tuple(sorted(replaced)),
        source=source,
    )
