"""The tool as collision geometry: its body (spindle, holder, gripper) and its cutter, as capsules.

A problem file may describe the tool under ``[robot.tool]`` (``docs/problem-file.md``,
``docs/cell.md``, "The tool"): body elements (:class:`ToolElement`: a box, a cylinder, a sphere or a
closed triangle mesh, each placed in the **flange** frame by ``element2flange``) and a cutter
(:class:`Cutter`: a cylinder of ``radius`` and ``length`` along the TCP's z axis, ending at the TCP).
:class:`ToolGeometry` holds both.

:func:`with_tool_geometry` appends one bounding capsule per element, fixed in DH frame 6
(``flange2frame6 @ element2flange``), body :data:`TOOL_BODY`, to the arm's capsule model, its
shape's :meth:`~models.collision.shapes.Shape.bounding_capsule`:

* box: the segment along its longest side (the full side), radius the half-diagonal of the
  cross-section;
* cylinder: its axis (the full length), its radius;
* sphere: its centre (a point), its radius;
* mesh: the principal axis of its vertices (largest variance), the radius the largest distance of a
  vertex from that axis, the ends as close together as containing every vertex allows (the capsule
  is convex, so it holds the vertices' convex hull and with it the closed mesh);

and the cutter as a capsule from the TCP back along the tool z axis by ``length``, of ``radius``,
body :data:`CUTTER_BODY`.  A capsule holds its element but is larger: its caps reach one radius
beyond a box's or cylinder's end faces.

The rules (:func:`check_pairs`, used by the plan's check and the placement kernel alike): every
capsule is checked against every object except the capsules fixed to the base and the **tip**
capsule against the workpiece; the tip is the cutter when one is declared; else it is today's tool
capsule (flange -> TCP, link 6's radius, :func:`models.collision.capsules.with_tool`), kept for that
purpose, or link 6 when the TCP is at the flange.  Every body element is checked against the
workpiece and every obstacle.  Self-collision: the arm's self pairs, and every tool capsule against
the links 0..:data:`TOOL_SELF_MAX_BODY`.  Without declared tool geometry the model, the names and
the rules are exactly those of :func:`~models.collision.capsules.with_tool`.

Units: m.  Frames: the flange frame (elements), the TCP frame (cutter), DH frame 6 (capsules).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import InputError
from ..robot import Robot
from .shapes import Shape, shape_class, shape_kinds, shape_to_dict
from .capsules import TOOL_BODY, TOOL_SELF_MAX_BODY, CapsuleModel, self_collision_pairs, with_tool

__all__ = [
    "CUTTER_BODY",
    "Cutter",
    "ToolElement",
    "ToolGeometry",
    "check_pairs",
    "reserved_name",
    "with_tool_geometry",
]

#: The cutter capsule's body number (after the tool body, :data:`TOOL_BODY`).
CUTTER_BODY = 8
#: The cutter's capsule name in messages (``cutter – fixture``).
CUTTER_NAME = "cutter"
#: The name of today's tool capsule (flange -> TCP, link 6's radius) in messages.
LEGACY_TOOL_NAME = "tool"
#: Names an element may not have: the arm's capsule names, the tool's and the cutter's.
_RESERVED = re.compile(r"^(base|tool|cutter|link \d+(#\d+)?)$")


def reserved_name(name: str) -> bool:
    """Whether ``name`` is one the capsules already use (``base``, ``link 3``, ``tool``, ``cutter``)."""
    return bool(_RESERVED.match(name.strip().lower()))


def _rigid(T: Any, what: str) -> np.ndarray:
    A = np.asarray(T, dtype=float)
    if A.shape != (4, 4) or not np.all(np.isfinite(A)) or not np.allclose(A[:3, :3] @ A[:3, :3].T, np.eye(3)):
        raise InputError(f"{what}: must be a finite 4x4 rigid transform")
    return A


@dataclass(frozen=True, eq=False)
class ToolElement:
    """One element of the tool's body, placed in the flange frame.

    Attributes
    ----------
    name : str
        Unique in the tool; not a reserved name (:func:`reserved_name`); used in messages
        (``spindle – fixture``).
    shape : str
        A registered shape kind (:func:`models.collision.shapes.shape_kinds`: ``box``, ``cylinder``,
        ``sphere``, ``mesh`` and the plug-ins').
    size : ndarray
        m: box ``(3,)`` x, y, z extents; cylinder ``(2,)`` radius, length (along z); sphere ``(1,)``
        radius; mesh ``(3,)`` the extents of its axis-aligned bounding box in the element frame.
    element2flange : ndarray, shape (4, 4)
        Maps element-frame coordinates to the flange frame: the centre (primitives) or the file's
        origin (mesh) and the element's axes in the flange frame.
    mesh : trimesh.Trimesh or None
        The mesh in the element frame, in m (meshes only).
    mesh_file : str or None
        The mesh file read (resolved path), meshes only.
    mesh_scale : float
        Mesh file unit to m.
    form : models.collision.shapes.Shape
        The shape of its kind built from the above (its bounding capsule, its dictionary form).

    Raises
    ------
    InputError
        Unknown shape, a size of the wrong length or not positive, a bad transform, a mesh element
        without its mesh, an empty or reserved name.
    """

    name: str
    shape: str
    size: np.ndarray
    element2flange: np.ndarray
    mesh: Any = field(default=None, repr=False)
    mesh_file: str | None = None
    mesh_scale: float = 1.0
    form: Shape = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise InputError(f"tool element: name must be a non-empty string, got {self.name!r}")
        if reserved_name(self.name):
            raise InputError(
                f"tool element '{self.name}': the name is taken by a capsule (base, link i, tool, cutter); "
                "choose another"
            )
        if self.shape not in shape_kinds():
            raise InputError(
                f"tool element '{self.name}': shape must be one of {list(shape_kinds())}, got {self.shape!r}"
            )
        object.__setattr__(self, "element2flange", _rigid(self.element2flange, f"tool element '{self.name}'"))
        form = shape_class(self.shape).build(
            self.size, f"tool element '{self.name}'", self.mesh, self.mesh_file, self.mesh_scale
        )
        object.__setattr__(self, "form", form)
        object.__setattr__(self, "size", form.size)

    def to_dict(self) -> dict[str, Any]:
        """The element in the problem-file schema (``[[robot.tool.body]]``: SI, radians, flange frame)."""
        return shape_to_dict(self.name, self.form, self.element2flange)


@dataclass(frozen=True)
class Cutter:
    """The cutter: a cylinder of ``radius`` along the TCP's z axis, from ``length`` behind the TCP
    to the TCP (m).  It may be longer than the flange -> TCP distance (it then reaches into the
    flange link; nothing is said).

    Raises
    ------
    InputError
        A radius or length not finite and positive.
    """

    radius: float
    length: float
    #: The end mill this capsule bounds (:class:`models.cutting.cutter.EndMill`), when the file
    #: describes one (``shape``, ``diameter``, ...); None for a bare ``radius`` and ``length``.
    mill: Any = None

    def __post_init__(self) -> None:
        for key in ("radius", "length"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not np.isfinite(v) or v <= 0:
                raise InputError(f"tool cutter: {key} must be a finite number > 0 (m), got {v!r}")
            object.__setattr__(self, key, float(v))

    def to_dict(self) -> dict[str, Any]:
        """The cutter in the problem-file schema (``[robot.tool.cutter]``, m): the end mill's
        description when it has one."""
        if self.mill is not None:
            return self.mill.to_dict()
        return {"radius": self.radius, "length": self.length}


@dataclass(frozen=True, eq=False)
class ToolGeometry:
    """The tool's declared collision geometry: body elements and an optional cutter.

    Attributes
    ----------
    elements : tuple of ToolElement
        Unique names.
    cutter : Cutter or None
    """

    elements: tuple[ToolElement, ...] = ()
    cutter: Cutter | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "elements", tuple(self.elements))
        names = [e.name for e in self.elements]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise InputError(f"tool: element names must be unique, repeated: {dup}")

    @property
    def declared(self) -> bool:
        """Whether anything is declared (an element or a cutter)."""
        return bool(self.elements) or self.cutter is not None

    @property
    def names(self) -> tuple[str, ...]:
        """The elements' names, in file order."""
        return tuple(e.name for e in self.elements)

    def mesh_files(self) -> tuple[str, ...]:
        """The mesh files the elements were read from (resolved paths, in element order)."""
        return tuple(e.mesh_file for e in self.elements if e.mesh_file is not None)

    def to_dict(self) -> dict[str, Any]:
        """``body`` and ``cutter`` of ``[robot.tool]`` in the problem-file schema (SI, radians)."""
        d: dict[str, Any] = {}
        if self.elements:
            d["body"] = [e.to_dict() for e in self.elements]
        if self.cutter is not None:
            d["cutter"] = self.cutter.to_dict()
        return d


def element_capsule(element: ToolElement) -> tuple[np.ndarray, np.ndarray, float]:
    """The bounding capsule of a tool element (module docstring), in the flange frame.

    Returns
    -------
    a, b : ndarray, shape (3,)
        Segment ends, flange frame, m.
    radius : float
        m.
    """
    a, b, r = element.form.bounding_capsule()
    T = element.element2flange
    return T[:3, :3] @ a + T[:3, 3], T[:3, :3] @ b + T[:3, 3], r


@dataclass(frozen=True)
class ToolCapsules:
    """What :func:`with_tool_geometry` added, for the checks and the messages.

    Attributes
    ----------
    names : tuple of str, length M
        A name per capsule of the full model: the arm's (``link 3``, ``link 2#1``), ``tool``
        (today's flange -> TCP capsule), the elements' names, ``cutter``.
    n_arm : int
        The arm's capsules come first: indices ``0 .. n_arm - 1``.
    tool : ndarray of int
        Indices of the tool's capsules (today's tool capsule, the elements, the cutter).
    tip : int
        The capsule that may touch the workpiece: the cutter; else today's tool capsule; else
        link 6's last capsule (TCP at the flange).
    declared : bool
        Whether the tool geometry was declared (else the model is :func:`with_tool`'s).
    """

    names: tuple[str, ...]
    n_arm: int
    tool: np.ndarray
    tip: int
    declared: bool = False

    @property
    def has_tool(self) -> bool:
        """Whether there is any tool capsule."""
        return bool(self.tool.size)


def with_tool_geometry(
    model: CapsuleModel, robot: Robot, tool: ToolGeometry | None = None
) -> tuple[CapsuleModel, ToolCapsules]:
    """The arm's capsule model with the tool's capsules appended (module docstring).

    Parameters
    ----------
    model : CapsuleModel
        The arm's capsules (:func:`models.collision.capsule_model`), M0 of them.
    robot : Robot
        With its tool (``tcp2flange``) and ``flange2frame6``.
    tool : ToolGeometry, optional
        The declared tool geometry; None or nothing declared: exactly
        :func:`models.collision.capsules.with_tool` (one capsule flange -> TCP of link 6's radius,
        body :data:`TOOL_BODY`, named ``tool``, the tip).

    Returns
    -------
    CapsuleModel
        The arm's capsules first, then today's tool capsule (unless a cutter is declared), the
        elements (body :data:`TOOL_BODY`), the cutter (body :data:`CUTTER_BODY`).
    ToolCapsules
    """
    n_arm = model.n_capsules
    declared = tool is not None and tool.declared
    if not declared or tool.cutter is None:  # type: ignore[union-attr]
        full, has_legacy = with_tool(model, robot)
    else:
        full, has_legacy = model, False
    names = list(model.names) + ([LEGACY_TOOL_NAME] if has_legacy else [])
    tip = n_arm if has_legacy else int(np.flatnonzero(model.body == 6)[-1])
    if declared:
        f2six = np.asarray(robot.flange2frame6, dtype=float)
        rows: list[tuple[np.ndarray, np.ndarray, float, int, str]] = []
        for e in tool.elements:  # type: ignore[union-attr]
            a, b, r = element_capsule(e)
            rows.append((f2six[:3, :3] @ a + f2six[:3, 3], f2six[:3, :3] @ b + f2six[:3, 3], r, TOOL_BODY, e.name))
        if tool.cutter is not None:  # type: ignore[union-attr]
            c = tool.cutter  # type: ignore[union-attr]
            tcp2six = f2six @ np.asarray(robot.tcp2flange, dtype=float)
            back = tcp2six[:3, :3] @ np.array([0.0, 0.0, -c.length]) + tcp2six[:3, 3]
            tip = full.n_capsules + len(rows)
            rows.append((back, tcp2six[:3, 3].copy(), c.radius, CUTTER_BODY, CUTTER_NAME))
        if rows:
            full = replace(
                full,
                frame_a=np.r_[full.frame_a, np.full(len(rows), 6, dtype=int)],
                frame_b=np.r_[full.frame_b, np.full(len(rows), 6, dtype=int)],
                local_a=np.vstack([full.local_a, *[r[0][None] for r in rows]]),
                local_b=np.vstack([full.local_b, *[r[1][None] for r in rows]]),
                radius=np.r_[full.radius, [r[2] for r in rows]],
                body=np.r_[full.body, [r[3] for r in rows]].astype(int),
            )
            names += [r[4] for r in rows]
    info = ToolCapsules(tuple(names), n_arm, np.arange(n_arm, full.n_capsules, dtype=int), tip, declared)
    return full, info


def check_pairs(
    arm: CapsuleModel, full: CapsuleModel, info: ToolCapsules, roles: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    """Which capsule-object pairs and which self pairs a cell check computes (module docstring).

    Parameters
    ----------
    arm : CapsuleModel
        The arm's capsules alone (its self pairs: :func:`models.collision.self_collision_pairs`).
    full, info : CapsuleModel, ToolCapsules
        From :func:`with_tool_geometry`.
    roles : sequence of str, length K
        Each object's role (``obstacle`` or ``workpiece``).

    Returns
    -------
    checked : ndarray of bool, shape (M, K)
        Not checked: capsules fixed to the base (both ends in the base frame or DH frame 0), and the
        tip (:attr:`ToolCapsules.tip`) against the workpiece.
    self_pairs : ndarray of int, shape (P, 2)
        The arm's self pairs, then each tool capsule against every arm capsule of a body up to
        :data:`TOOL_SELF_MAX_BODY`.
    """
    m, k = full.n_capsules, len(roles)
    checked = np.ones((m, k), dtype=bool)
    checked[(full.frame_a <= 0) & (full.frame_b <= 0)] = False
    for j, role in enumerate(roles):
        if role == "workpiece":
            checked[info.tip, j] = False
    near = [(c, int(t)) for t in info.tool for c in range(arm.n_capsules) if arm.body[c] <= TOOL_SELF_MAX_BODY]
    pairs = np.vstack([self_collision_pairs(arm).reshape(-1, 2), np.array(near, dtype=int).reshape(-1, 2)])
    return checked, pairs.astype(int)
