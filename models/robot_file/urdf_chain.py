"""The chain of a URDF between two links, read with ``yourdfpy`` (``docs/robot-file.md``,
"URDF-based robot files"): the joints from ``base_link`` down to ``tip_link`` (fixed joints folded,
only revolute joints moving), their frames and axes at q = 0, limits, and the mass properties of
the body after each joint (links rigidly attached, combined)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from xml.etree import ElementTree
from pathlib import Path
from typing import Any

import numpy as np

from models.description import RobotFileError
from models.tables.text_file import read_text_file

from .values import inertia_matrix

#: A joint axis shorter than this (URDF ``<axis xyz>``) is refused as zero.
AXIS_MIN_NORM = 1e-9


@dataclass
class Body:
    """Mass properties of one rigid body, in the frame of the body's first link.

    ``mass`` kg; ``com`` (3,) m; ``inertia`` (3, 3) kg*m^2 about the centre of mass.
    """

    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    links: list[str] = field(default_factory=list)

    def add(self, mass: float, com: np.ndarray, inertia: np.ndarray) -> None:
        """Add a part (mass, com, inertia about its own com, all in this body's frame)."""
        if mass <= 0.0:
            return
        total = self.mass + mass
        c = (self.mass * self.com + mass * com) / total
        I = _shift(self.inertia, self.mass, self.com - c) + _shift(inertia, mass, com - c)
        self.mass, self.com, self.inertia = total, c, I


def _shift(I: np.ndarray, m: float, r: np.ndarray) -> np.ndarray:
    """Inertia about a point at ``-r`` from the centre of mass (parallel-axis theorem)."""
    return I + m * (float(r @ r) * np.eye(3) - np.outer(r, r))


@dataclass
class UrdfChain:
    """The moving part of a URDF between two links, at q = 0.

    Attributes
    ----------
    joint_names : list of str, length 6
    frames : ndarray, shape (6, 4, 4)
        Joint frame *i* (the child link frame of joint *i*) in the base link frame at q = 0.
    axes : ndarray, shape (6, 3)
        Unit axis of joint *i* in its joint frame.
    tip : ndarray, shape (4, 4)
        Tip link frame in the base link frame at q = 0.
    limits : list of (lower, upper, velocity) with None where the URDF gives none
    continuous : list of bool
    bodies : list of Body, length 6
        Mass properties after joint *i*, in joint frame *i*.
    notes : list of str
    """

    joint_names: list[str]
    frames: np.ndarray
    axes: np.ndarray
    tip: np.ndarray
    limits: list[tuple[float | None, float | None, float | None]]
    continuous: list[bool]
    bodies: list[Body]
    notes: list[str]
    #: The parsed URDF (yourdfpy), for its collision elements and link frames (``urdf_collision``).
    model: Any = field(default=None, repr=False)

    def zero_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit axes ``w`` (6, 3) and points ``p`` (6, 3), base link frame, at q = 0."""
        w = np.einsum("nij,nj->ni", self.frames[:, :3, :3], self.axes)
        return w, self.frames[:, :3, 3].copy()


def joint_origin(where: str, j: Any) -> np.ndarray:
    T = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float)
    if not np.all(np.isfinite(T)):
        raise RobotFileError(f"{where}: joint '{j.name}': <origin> is not finite (NaN or inf)")
    return T


def _load_urdf(where: str, path: Path) -> Any:
    try:
        import yourdfpy
    except ImportError:  # pragma: no cover - a declared dependency
        raise RobotFileError(f"{where}: reading a URDF needs the package 'yourdfpy' (pip install yourdfpy)") from None
    text = read_text_file(path, "URDF file", RobotFileError)
    if "<robot" not in text:
        raise RobotFileError(f"{path}: not a URDF (no <robot> element)")
    try:  # well-formedness first: the URDF parser would otherwise guess at broken XML
        ElementTree.fromstring(text.encode("utf-8"))
    except ElementTree.ParseError as exc:
        line, col = exc.position
        raise RobotFileError(f"{path}: not well-formed XML at line {line}, column {col + 1}: {exc}") from None
    try:
        return yourdfpy.URDF.load(
            str(path), build_scene_graph=False, load_meshes=False, load_collision_meshes=False
        ).robot
    except Exception as exc:
        raise RobotFileError(f"{path}: not a readable URDF: {exc}") from None


def chain_joints(where: str, model: Any, base_link: str, tip_link: str) -> tuple[np.ndarray, list[Any]]:
    """The path from base_link to tip_link: the fixed transform from base_link up to the
    links' common ancestor (fixed joints only), and the joints from there down to tip_link."""
    links = {lk.name for lk in model.links}
    for key, name in (("base_link", base_link), ("tip_link", tip_link)):
        if name not in links:
            raise RobotFileError(f"{where}: key '{key}' = {name!r}: no such link in the URDF; links: {sorted(links)}")
    parent_joint = {j.child: j for j in model.joints}

    def up(link: str) -> list[Any]:
        out = []
        while link in parent_joint:
            out.append(parent_joint[link])
            link = parent_joint[link].parent
        return out

    tip_up, base_up = up(tip_link), up(base_link)
    tip_links = [tip_link] + [j.parent for j in tip_up]
    base_links = [base_link] + [j.parent for j in base_up]
    common = next((lk for lk in base_links if lk in tip_links), None)
    if common is None:
        raise RobotFileError(f"{where}: base_link {base_link!r} and tip_link {tip_link!r} are in different trees")
    rise = base_up[: base_links.index(common)]
    moving = [j.name for j in rise if j.type != "fixed"]
    if moving:
        raise RobotFileError(
            f"{where}: tip_link {tip_link!r} is not below base_link {base_link!r} in the URDF tree: "
            f"the path from the base goes up through the moving joint(s) {moving} to {common!r}; "
            "the chain must run from base_link down to tip_link"
        )
    base2common = np.eye(4)
    for j in rise:  # base_link -> ... -> common, all fixed
        base2common = joint_origin(where, j) @ base2common
    return np.linalg.inv(base2common), tip_up[: tip_links.index(common)][::-1]


def _check_joint(where: str, j: Any) -> None:
    if j.mimic is not None:
        raise RobotFileError(
            f"{where}: joint '{j.name}' mimics joint '{j.mimic.joint}': mimic joints are not "
            "supported in the chain (every chain joint must be driven)"
        )
    if j.type in ("prismatic", "planar", "floating"):
        raise RobotFileError(
            f"{where}: joint '{j.name}' is {j.type}: only revolute (and fixed) joints may be in "
            "the chain between base_link and tip_link"
        )
    if j.type not in ("revolute", "continuous", "fixed"):
        raise RobotFileError(f"{where}: joint '{j.name}' has unknown type {j.type!r}")


def read_chain(where: str, urdf_path: Path, base_link: str, tip_link: str) -> UrdfChain:
    """Read the chain between two links of a URDF (see the module docstring for the rules).

    Raises
    ------
    RobotFileError
        Naming the file, the joint or link, the value and what was expected.
    """
    model = _load_urdf(where, urdf_path)
    common2base, joints = chain_joints(where, model, base_link, tip_link)
    for j in joints:
        _check_joint(where, j)
    moving = [j for j in joints if j.type != "fixed"]
    if len(moving) != 6:
        raise RobotFileError(
            f"{where}: {len(moving)} moving joint(s) between {base_link!r} and {tip_link!r} "
            f"({[j.name for j in moving]}); expected 6 revolute joints"
        )
    T = common2base.copy()
    frames, axes, limits = [], [], []
    for j in joints:
        T = T @ joint_origin(where, j)
        if j.type == "fixed":
            continue
        ax = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, dtype=float)
        if not np.all(np.isfinite(ax)):
            raise RobotFileError(f"{where}: joint '{j.name}': <axis xyz> = {[float(x) for x in ax]} is not finite")
        n = float(np.linalg.norm(ax))
        if n < AXIS_MIN_NORM:
            raise RobotFileError(
                f"{where}: joint '{j.name}': <axis xyz> = {[float(x) for x in ax]} is zero; expected a direction"
            )
        frames.append(T.copy())
        axes.append(ax / n)
        lim = j.limit
        limits.append((None, None, None) if lim is None else (lim.lower, lim.upper, lim.velocity))
    notes: list[str] = []
    bodies = _bodies(where, model, moving, notes)
    return UrdfChain(
        joint_names=[j.name for j in moving],
        frames=np.array(frames),
        axes=np.array(axes),
        tip=T,
        limits=limits,
        continuous=[j.type == "continuous" for j in moving],
        bodies=bodies,
        notes=notes,
        model=model,
    )


def _check_inertial(where: str, link: str, mass: float, origin: np.ndarray, inertia: np.ndarray) -> None:
    """A link's <inertial>: finite, mass >= 0, a physical inertia tensor (clear error naming the link)."""
    if not (math.isfinite(mass) and np.all(np.isfinite(origin)) and np.all(np.isfinite(inertia))):
        raise RobotFileError(f"{where}: link '{link}': <inertial> has a non-finite value")
    if mass < 0:
        raise RobotFileError(f"{where}: link '{link}': <mass value=\"{mass:g}\"> must be >= 0 (kg)")
    v = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    try:
        inertia_matrix(f"{where}: link '{link}': <inertia>", np.array(v))
    except RobotFileError as exc:
        raise RobotFileError(str(exc).replace("key 'inertia'", "<inertia ixx iyy izz ixy ixz iyz>")) from None


def _bodies(where: str, model: Any, moving: list[Any], notes: list[str]) -> list[Body]:
    """Mass properties of the body after each moving joint, in that joint's frame."""
    link_map = {lk.name: lk for lk in model.links}
    children: dict[str, list[Any]] = {}
    for j in model.joints:
        children.setdefault(j.parent, []).append(j)
    chain_names = {j.name for j in moving}
    bodies = []
    for mj in moving:
        body = Body()
        stack = [(mj.child, np.eye(4))]
        while stack:
            name, T = stack.pop()
            body.links.append(name)
            inert = link_map[name].inertial
            if inert is not None and inert.mass is not None:
                O = np.eye(4) if inert.origin is None else np.asarray(inert.origin, dtype=float)
                I = np.zeros((3, 3)) if inert.inertia is None else np.asarray(inert.inertia, dtype=float)
                _check_inertial(where, name, float(inert.mass), O, I)
                R = T[:3, :3] @ O[:3, :3]
                body.add(float(inert.mass), (T @ O)[:3, 3], R @ I @ R.T)
            for cj in children.get(name, []):
                if cj.type == "fixed":
                    stack.append((cj.child, T @ (np.eye(4) if cj.origin is None else np.asarray(cj.origin, float))))
                elif cj.name not in chain_names:
                    notes.append(
                        f"link '{cj.child}' (joint '{cj.name}', {cj.type}) hangs off the chain by a moving "
                        "joint: its mass is left out"
                    )
        bodies.append(body)
    return bodies
