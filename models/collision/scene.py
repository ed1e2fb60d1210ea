"""The collision scene: the arm's capsules, the tool's and the cell's objects, and the pairs to check.

As pinocchio holds a robot's geometry once in its ``GeometryModel``, a :class:`Scene` is built once
from the robot (capsules along its chain, :func:`models.collision.capsule_model`), the tool
(:func:`models.collision.tool.with_tool_geometry`: its declared body elements and cutter, else one
capsule flange -> TCP) and the cell's objects (:class:`SceneObject`: a shape of a registered kind,
:mod:`models.collision.shapes`, placed in the base frame), with the pairs checked
(:func:`models.collision.tool.check_pairs`).  Every consumer reads it: the posture NLP's clearance
constraints (:mod:`problems.posture.clearance`), the plan's check (:mod:`planner.cell_check`), the
placement kernel (:mod:`problems.placement.collide`, objects in the cell frame) and the report's
cell view (:mod:`planner.report.cell_view`).

Capsule positions at configurations come from the one kinematic chain
(:func:`models.collision.chain_frames`, :func:`models.collision.chain.chain_frames_sx`).

Units: m.  Frames: the base frame (or the frame the objects are given in).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ..robot import Robot
from .capsules import CapsuleModel, capsule_model
from .chain import capsule_segments, chain_frames
from .shapes import Shape

__all__ = ["Scene", "SceneObject"]


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One shape placed in the scene: the one posed primitive of the collision geometry.

    Attributes
    ----------
    name : str
        Used in messages (``link 3 – table``).
    shape : models.collision.shapes.Shape
        In its own frame.
    pose : ndarray, shape (4, 4)
        ``shape2base``: maps the shape's coordinates to the base frame (or the scene's frame).
    role : {"obstacle", "workpiece"}
    """

    name: str
    shape: Shape
    pose: np.ndarray
    role: str = "obstacle"

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", np.asarray(self.pose, dtype=float))

    @classmethod
    def with_geometry(cls, name: str, shape: Shape, pose: np.ndarray, role: str, geometry: Any) -> SceneObject:
        """An object whose coal geometry is built already (a cell object's)."""
        out = cls(name, shape, pose, role)
        out.__dict__["geometry"] = geometry
        return out

    @cached_property
    def geometry(self) -> Any:
        """Its coal geometry, built on first use (coal loads only then)."""
        return self.shape.geometry()

    @property
    def kind(self) -> str:
        """The shape's kind (``box``)."""
        return self.shape.kind

    @property
    def shape2base(self) -> np.ndarray:
        """``pose``."""
        return self.pose

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """Points (N, 3) from the scene's frame to the shape's, m."""
        P = np.atleast_2d(np.asarray(points, dtype=float))
        R, t = self.pose[:3, :3], self.pose[:3, 3]
        return (P - t) @ R

    def contains(self, points: np.ndarray, tol: float) -> np.ndarray:
        """Whether points (N, 3) of the scene's frame lie inside by more than ``tol`` (m), (N,) bool."""
        return self.shape.contains(self.to_local(points), tol)

    def proxy(self, nlp: bool) -> SceneObject:
        """The object the posture NLP (``nlp``) or the placement kernel measures: the shape's
        proxy (:meth:`~models.collision.shapes.Shape.nlp_proxy`, ``kernel_proxy``) where it is."""
        shape, box2shape = self.shape.nlp_proxy() if nlp else self.shape.kernel_proxy()
        if box2shape is None and shape is self.shape:
            return self
        pose = self.pose if box2shape is None else self.pose @ box2shape
        return SceneObject(self.name, shape, pose, self.role)

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre (scene frame) and radius (m) of a sphere holding the object."""
        c, r = self.shape.bounding_sphere()
        T = self.pose
        return (T[:3, 3].copy() if c is None else T[:3, :3] @ c + T[:3, 3]), r

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Its surface as triangles in the scene's frame: vertices (V, 3) m, faces (F, 3)."""
        v, f = self.shape.triangles()
        return v @ self.pose[:3, :3].T + self.pose[:3, 3], f


@dataclass(frozen=True, eq=False)
class Scene:
    """The arm's capsules (tool included), the objects and the pairs to check (module docstring).

    Attributes
    ----------
    robot : Robot
        Its nominal chain places the capsules.
    arm : CapsuleModel
        The arm's capsules alone.
    model : CapsuleModel
        The arm's capsules plus the tool's, M in all.
    tool : models.collision.tool.ToolCapsules
        Names of the M capsules, which are the tool's, the tip.
    objects : tuple of SceneObject, length K
    checked : ndarray of bool, shape (M, K)
        Which capsule-object pairs are checked (not: the tip with the workpiece, capsules fixed to
        the base).
    self_pairs : ndarray of int, shape (P, 2)
        Capsule index pairs of the self-collision check.
    clearance : float
        m.
    """

    robot: Robot
    arm: CapsuleModel
    model: CapsuleModel
    tool: Any
    objects: tuple[SceneObject, ...]
    checked: np.ndarray
    self_pairs: np.ndarray
    clearance: float

    @classmethod
    def build(
        cls,
        robot: Robot,
        objects: Sequence[SceneObject] = (),
        tool: Any = None,
        clearance: float = 0.0,
        arm: CapsuleModel | None = None,
    ) -> Scene:
        """The scene of a robot (with its tool's ``tcp2flange``), its declared tool geometry
        (:class:`models.collision.tool.ToolGeometry` or None) and objects.

        Parameters
        ----------
        arm : CapsuleModel, optional
            The arm's capsules (default :func:`models.collision.capsule_model`).
        """
        from .tool import check_pairs, with_tool_geometry

        arm = capsule_model(robot) if arm is None else arm
        full, info = with_tool_geometry(arm, robot, tool)
        objects = tuple(objects)
        checked, pairs = check_pairs(arm, full, info, tuple(o.role for o in objects))
        return cls(robot, arm, full, info, objects, checked, pairs, float(clearance))

    @property
    def names(self) -> tuple[str, ...]:
        """Capsule names in messages (``link 3``, ``tool``, a tool element's, ``cutter``)."""
        return self.tool.names

    @property
    def roles(self) -> tuple[str, ...]:
        """Each object's role."""
        return tuple(o.role for o in self.objects)

    @property
    def shapes(self) -> tuple[SceneObject, ...]:
        """``objects``."""
        return self.objects

    @property
    def pair_names(self) -> list[str]:
        """Names of the object pairs (capsule-major, ``m * K + k``), then of the self pairs."""
        obj = [f"{c} – {s.name}" for c in self.names for s in self.objects]
        return obj + [f"{self.names[i]} – {self.names[j]}" for i, j in self.self_pairs]

    @property
    def centre(self) -> np.ndarray:
        """Each object's bounding-sphere centre, (K, 3) m."""
        return self._spheres[0]

    @property
    def bound(self) -> np.ndarray:
        """Each object's bounding-sphere radius, (K,) m."""
        return self._spheres[1]

    @cached_property
    def _spheres(self) -> tuple[np.ndarray, np.ndarray]:
        spheres = [o.bounding_sphere() for o in self.objects]
        k = len(spheres)
        return np.array([c for c, _ in spheres]).reshape(k, 3), np.array([r for _, r in spheres], dtype=float)

    def segments(self, q: np.ndarray) -> np.ndarray:
        """Capsule end points at configurations ``q`` (N, 6) rad: shape (N, M, 2, 3), m."""
        return capsule_segments(self.model, chain_frames(self.robot, np.atleast_2d(q)))
