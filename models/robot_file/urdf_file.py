"""Robot files that name a URDF: the chain between two links, read with ``yourdfpy``, as a DH model.

A URDF-based robot file (``docs/robot-file.md``) gives ``urdf``, ``base_link``, ``tip_link``
(the flange) and the joint stiffnesses.  This module reads the file: the kinematic chain from
``base_link`` down to ``tip_link`` (:mod:`~models.robot_file.urdf_chain`) is turned, exactly
(:mod:`~models.robot_file.urdf_dh`), into the product's one chain form:
a **modified-DH** table (Khalil-Kleinfinger / Craig) with a fixed transform ``frame02base``
(DH frame 0 -> base link) before it and ``flange2frame6`` (tip link -> DH frame 6) after it.
Every model function, effect, IK family and identification parametrisation then works on it
unchanged.  Its collision geometry is :mod:`~models.robot_file.urdf_collision`.

Reading the URDF (``docs/robot-file.md``, "URDF-based robot files"):

* only ``revolute`` joints move; ``fixed`` joints are folded into the neighbouring
  transforms; ``continuous`` joints need limits in the robot file; ``prismatic``,
  ``planar``, ``floating`` joints and ``mimic`` joints in the chain are errors;
* exactly 6 revolute joints between ``base_link`` and ``tip_link``;
* a joint's angle ``q`` is the URDF joint variable (same zero, same sign), so the
  controller's angles are the model's;
* link masses, centres of mass and inertias: every link rigidly attached after joint *i*
  (fixed joints, also off the chain) is one body; its mass, centre of mass and inertia
  about the centre of mass are combined and expressed in DH frame *i*.  Links hanging
  off the chain by a moving joint are left out (a note says which).

The DH frames are chosen so that frame *i*'s z axis is joint *i*'s URDF axis: frame 0 is the
base link's frame when joint 1 turns about its z axis (else a frame on joint 1's axis),
each common normal is taken from joint *i* towards joint *i + 1* (``a >= 0``), frames on
parallel axes keep ``d = 0``, and frame 6 sits where the tip link's origin projects on
joint 6's axis, with ``theta_offset_6 = 0``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from models.constants import PLAUSIBLE_JOINT_SPEED_MAX_RAD_S, STANDARD_GRAVITY
from models.degenerate import URDF_HINT, check_chain, poe_axes
from models.description import Joint, Robot, RobotFileError

from .collision_table import check_collision_fixed
from .sections import parse_controller, parse_frame_table
from .urdf_chain import UrdfChain, read_chain
from .urdf_collision import urdf_collision
from .urdf_dh import DHChain, check_dh, dh_from_axes
from .values import VALUES, angle, vector

#: Keys of a URDF-based robot file.
URDF_TOP_KEYS = (
    "name",
    "description",
    "source",
    "urdf",
    "base_link",
    "tip_link",
    "stiffness",
    "a_max",
    "j_max",
    "gravity",
    "tool",
    "joints",
    "identified",
    "controller",
    "collision",
)
#: Per-joint override keys (``[joints.<urdf joint name>]``).
URDF_JOINT_KEYS = ("q_min", "q_max", "q_min_deg", "q_max_deg", "v_max", "a_max", "j_max")
#: A URDF joint limit beyond two turns (rad) is implausible: degrees written as radians.
PLAUSIBLE_URDF_LIMIT_RAD = 4.0 * math.pi * (1.0 + 1e-9)
#: Without an ``a_max`` the acceleration limit is ``v_max / DEFAULT_TIME_TO_SPEED_S`` (full speed in this time).
DEFAULT_TIME_TO_SPEED_S = 0.5
#: Without a ``j_max`` the jerk limit is ``a_max / DEFAULT_TIME_TO_ACCEL_S``.
DEFAULT_TIME_TO_ACCEL_S = 0.1


# --------------------------------------------------------------------------------------
# The robot file
# --------------------------------------------------------------------------------------


def _six(where: str, data: Mapping[str, Any], key: str, positive: bool = True) -> np.ndarray | None:
    if key not in data:
        return None
    v = vector(where, key, data[key], 6)
    if positive and np.any(v <= 0):
        i = int(np.argmax(v <= 0))
        raise RobotFileError(f"{where}: key '{key}'[{i}] (joint {i + 1}) must be > 0, got {v[i]:g}")
    return v


def _joint_limits(where: str, chain: UrdfChain, overrides: Mapping[str, Any], i: int) -> dict[str, float]:
    """q_min, q_max, v_max of chain joint ``i``: the URDF's, replaced by the robot file's overrides."""
    name = chain.joint_names[i]
    ov = overrides.get(name, {})
    w = f"{where}: joints.{name}"
    lo, hi, vel = chain.limits[i]
    out: dict[str, float] = {}
    for key, urdf_val in (("q_min", lo), ("q_max", hi)):
        if key in ov or f"{key}_deg" in ov:
            out[key] = angle(w, ov, key)
        elif chain.continuous[i]:
            raise RobotFileError(
                f"{where}: joint '{name}' is continuous (no position limits in the URDF); give "
                f"its limits in the robot file: [joints.{name}] q_min_deg = ..., q_max_deg = ..."
            )
        elif urdf_val is None or not math.isfinite(float(urdf_val)):
            raise RobotFileError(
                f"{where}: joint '{name}': the URDF gives no finite "
                f"<limit {key.replace('q_min', 'lower').replace('q_max', 'upper')}>; "
                f"give it in the robot file: [joints.{name}] {key}_deg = ..."
            )
        elif abs(float(urdf_val)) > PLAUSIBLE_URDF_LIMIT_RAD:
            tag = "lower" if key == "q_min" else "upper"
            raise RobotFileError(
                f"{where}: URDF joint '{name}': <limit {tag}=\"{float(urdf_val):g}\"> rad is implausible "
                f"(|value| > {PLAUSIBLE_URDF_LIMIT_RAD:.4g} rad, two turns; URDF limits are in radians); "
                f"override it in the robot file: [joints.{name}] {key}_deg = ..."
            )
        else:
            out[key] = float(urdf_val)
    if out["q_min"] >= out["q_max"]:
        raise RobotFileError(
            f"{where}: joint '{name}': lower limit {out['q_min']:g} rad must be below the upper "
            f"limit {out['q_max']:g} rad"
        )
    if "v_max" in ov:
        out["v_max"] = _positive(where, name, ov, "v_max")
    elif vel is None or not math.isfinite(float(vel)) or float(vel) <= 0:
        raise RobotFileError(
            f"{where}: joint '{name}': the URDF gives no positive <limit velocity> ({vel!r}); "
            f"give it in the robot file: [joints.{name}] v_max = ... (rad/s)"
        )
    else:
        out["v_max"] = float(vel)
    if out["v_max"] <= 0:
        raise RobotFileError(f"{w}: key 'v_max' must be > 0, got {out['v_max']:g}")
    if out["v_max"] > PLAUSIBLE_JOINT_SPEED_MAX_RAD_S:
        raise RobotFileError(
            f"{where}: joint '{name}': velocity limit {out['v_max']:g} rad/s is implausible "
            f"(> {PLAUSIBLE_JOINT_SPEED_MAX_RAD_S:g} rad/s); URDF and robot-file speeds are in rad/s "
            "(degrees per second given?)"
        )
    return out


def _positive(where: str, joint: str, row: Mapping[str, Any], key: str) -> float:
    """An override that must be a positive number (``[joints.<joint>] key``)."""
    return VALUES.positive(f"{where}: joints.{joint}", key, row[key], show=lambda v: f"{float(v):g}")


def _overrides(where: str, data: Mapping[str, Any], chain: UrdfChain) -> Mapping[str, Any]:
    ov = data.get("joints", {})
    if not isinstance(ov, Mapping):
        raise RobotFileError(
            f"{where}: key 'joints' of a URDF-based robot file is a table of per-joint overrides "
            "([joints.<URDF joint name>]), not an array of DH rows"
        )
    for name, row in ov.items():
        if name not in chain.joint_names:
            raise RobotFileError(
                f"{where}: joints.{name}: no such moving joint in the chain; joints: {chain.joint_names}"
            )
        if not isinstance(row, Mapping):
            raise RobotFileError(f"{where}: joints.{name}: expected a table of overrides")
        VALUES.unknown_keys(f"{where}: joints.{name}", row, URDF_JOINT_KEYS)
    return ov


def _str_key(where: str, data: Mapping[str, Any], key: str) -> str:
    return VALUES.text(where, key, data.get(key), empty=False)


def _urdf_joint(
    where: str,
    chain: UrdfChain,
    ch: DHChain,
    ov: Mapping[str, Any],
    lim: Mapping[str, float],
    i: int,
    a_max: np.ndarray | None,
    j_max: np.ndarray | None,
    stiffness: float,
    has_mass: bool,
) -> Joint:
    """Joint ``i`` (0-based) in its DH form ``ch``: its limits ``lim``, its acceleration and jerk
    limits (the joint's ``[joints.<name>]`` override, else the file's six, else the defaults), its
    stiffness (N*m/rad) and, when the URDF gives masses, its link's mass, centre of mass and inertia
    in DH frame ``i + 1``."""
    row_ov = ov.get(chain.joint_names[i], {})
    am = (
        _positive(where, chain.joint_names[i], row_ov, "a_max")
        if "a_max" in row_ov
        else (float(a_max[i]) if a_max is not None else lim["v_max"] / DEFAULT_TIME_TO_SPEED_S)
    )
    jm = (
        _positive(where, chain.joint_names[i], row_ov, "j_max")
        if "j_max" in row_ov
        else (float(j_max[i]) if j_max is not None else am / DEFAULT_TIME_TO_ACCEL_S)
    )
    mass_kw: dict[str, Any] = {}
    if has_mass:
        b = chain.bodies[i]
        D2J = np.linalg.inv(chain.frames[i]) @ ch.frames0[i + 1]  # DH frame i+1 -> joint frame
        R = D2J[:3, :3]
        com = R.T @ (b.com - D2J[:3, 3])
        mass_kw = {"mass": b.mass, "com": com, "inertia": R.T @ b.inertia @ R}
    return Joint(
        a=float(ch.a[i]),
        alpha=float(ch.alpha[i]),
        d=float(ch.d[i]),
        theta_offset=float(ch.theta_offset[i]),
        q_min=lim["q_min"],
        q_max=lim["q_max"],
        v_max=lim["v_max"],
        a_max=am,
        j_max=jm,
        stiffness=stiffness,
        **mass_kw,
    )


def _default_notes(a_max: np.ndarray | None, j_max: np.ndarray | None, has_mass: bool) -> list[str]:
    """The robot's notes on what the file leaves to defaults (acceleration, jerk, masses)."""
    notes = []
    if a_max is None:
        notes.append(
            f"a_max not given: v_max / {DEFAULT_TIME_TO_SPEED_S:g} s assumed (full speed in "
            f"{DEFAULT_TIME_TO_SPEED_S:g} s)"
        )
    if j_max is None:
        notes.append(f"j_max not given: a_max / {DEFAULT_TIME_TO_ACCEL_S:g} s assumed")
    if not has_mass:
        notes.append("the URDF gives no link masses: no self-weight model")
    return notes


def robot_from_urdf_dict(data: Mapping[str, Any], where: str, base_dir: Path | None) -> Robot:
    """Build a :class:`Robot` from a URDF-based robot-file dictionary (see ``docs/robot-file.md``).

    Parameters
    ----------
    data : mapping
        The parsed TOML document (has the key ``urdf``).
    where : str
        The robot file, for messages.
    base_dir : Path or None
        Folder the ``urdf`` path is relative to (the robot file's); None: the working folder.
    """
    unknown = sorted(set(data) - set(URDF_TOP_KEYS))
    if unknown:
        hint = "; 'convention' and [[joints]] DH rows belong to DH robot files" if "convention" in unknown else ""
        raise RobotFileError(
            f"{where}: unknown key(s) {unknown} for a URDF-based robot file; allowed: {list(URDF_TOP_KEYS)}{hint}"
        )
    name = _str_key(where, data, "name")
    urdf_rel = _str_key(where, data, "urdf")
    path = Path(urdf_rel) if base_dir is None or Path(urdf_rel).is_absolute() else base_dir / urdf_rel
    base_link, tip_link = _str_key(where, data, "base_link"), _str_key(where, data, "tip_link")
    if "stiffness" not in data:
        raise RobotFileError(f"{where}: missing key 'stiffness' (6 joint stiffnesses, N*m/rad, base to tip)")
    stiffness = _six(where, data, "stiffness")
    chain = read_chain(where, path, base_link, tip_link)
    ov = _overrides(where, data, chain)
    w, p = chain.zero_axes()
    limits = [_joint_limits(where, chain, ov, i) for i in range(6)]
    q_lo, q_hi = (np.array([lim[k] for lim in limits]) for k in ("q_min", "q_max"))
    check_chain(where, poe_axes(w, p), q_lo, q_hi, chain.joint_names, URDF_HINT)  # before its DH form
    ch = dh_from_axes(where, w, p, chain.tip)
    check_dh(where, w, p, chain.tip, ch)
    notes = list(chain.notes)
    a_max, j_max = _six(where, data, "a_max"), _six(where, data, "j_max")
    has_mass = any(b.mass > 0 for b in chain.bodies)
    joints = [
        _urdf_joint(where, chain, ch, ov, limits[i], i, a_max, j_max, float(stiffness[i]), has_mass) for i in range(6)
    ]
    notes.extend(_default_notes(a_max, j_max, has_mass))
    tcp2flange = parse_frame_table(where, "tool", data.get("tool", {}))
    gravity = vector(where, "gravity", data.get("gravity", [0.0, 0.0, -STANDARD_GRAVITY]), 3)
    for key in ("description", "source"):
        if not isinstance(data.get(key, ""), str):
            raise RobotFileError(f"{where}: key '{key}' must be a string")
    identified = data.get("identified")
    if identified is not None and not isinstance(identified, Mapping):
        raise RobotFileError(f"{where}: key 'identified' must be a table")
    robot = Robot(
        name=name,
        convention="modified_dh",
        joints=tuple(joints),
        tcp2flange=tcp2flange,
        gravity=gravity,
        description=data.get("description", ""),
        source=data.get("source", ""),
        identified=dict(identified) if identified is not None else None,
        frame02base=ch.frame02base,
        flange2frame6=ch.flange2frame6,
        joint_names=tuple(chain.joint_names),
        urdf={"path": str(path), "base_link": base_link, "tip_link": tip_link},
        notes=tuple(notes),
        **parse_controller(where, data.get("controller")),
        controller_declared="controller" in data,
        collision=urdf_collision(where, path, chain, ch, base_link, tip_link, data.get("collision")),
    )
    check_collision_fixed(where, robot)
    return robot
