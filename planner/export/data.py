"""What every export format writes: :class:`ExportData` (the controller's trajectory of a plan, the
robot's joint names and controller convention), the program name and header lines every file
starts with, and the warning for a vendor format of a robot without a ``[controller]`` table."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

__all__ = ["VENDOR_FORMATS", "ExportData", "controller_warning", "header_lines", "program_name"]


@dataclass(frozen=True)
class ExportData:
    """What every export format writes (SI units, the model's joint convention).

    Attributes
    ----------
    name : str
        Program name (letters, digits, underscores).
    robot : str
    joint_names : tuple of str, length 6
        Base to tip (the robot file's ``joint_names``, else ``joint_1`` ... ``joint_6``).
    t : ndarray, shape (M,)
        Sample times, s, from 0 every ``dt``.
    q, qd, qdd, qddd : ndarray, shape (M, 6)
        Joint positions (rad), velocities (rad/s), accelerations (rad/s^2) and jerks (rad/s^3),
        model convention.
    dt : float
        The trajectory's sample period, s.
    v_max, a_max, j_max : ndarray, shape (6,)
        The plan's velocity (rad/s), acceleration (rad/s^2) and jerk (rad/s^3) limits: those its
        timing method kept (the problem's ``[limits]``), which :func:`verify_limits` checks.
    q_min, q_max : ndarray, shape (6,)
        The robot's joint position limits, rad (model convention).
    enforced : tuple of str
        The rate limits the timing method enforced (``velocity``, ``acceleration``, ``jerk``);
        :func:`verify_limits` checks these and the positions.
    sign, offset : ndarray, shape (6,)
        Controller angle = ``sign * q + offset`` (rad).
    source : str
        Where it came from (run folder, problem), for the file header.
    inputs : tuple of Path
        The files it was read from (none for a plan in memory).
    link_q : ndarray, shape (M, 6), or None
        The planned link side (``ql1..ql6``) of a run with dynamic compensation, rad.
    slow_factor : float
        How much slower than planned (1: as planned; :meth:`slowed`).
    program : str
        The CAM program (G-code, CL data) the plan runs at its programmed feed, by file name; empty
        for any other task.  Slowing such a plan down changes its feed: ``slow_down=auto`` refuses it
        (:func:`~planner.export.limits.check_motion`).
    robot_v_max, robot_a_max, robot_j_max : ndarray, shape (6,), or None
        The robot's own velocity, acceleration and jerk limits (its robot file's, before the
        problem's ``[limits]`` scaled or replaced them): what its controller allows, which what a
        format sends is checked against (:meth:`robot_limit`); None: not known (a run summary
        without ``robot_file``), the plan's are used.
    """

    name: str
    robot: str
    joint_names: tuple[str, ...]
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qddd: np.ndarray
    dt: float
    v_max: np.ndarray
    a_max: np.ndarray
    j_max: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    enforced: tuple[str, ...] = ("velocity", "acceleration", "jerk")
    sign: np.ndarray = field(default_factory=lambda: np.ones(6))
    offset: np.ndarray = field(default_factory=lambda: np.zeros(6))
    #: The robot file declared its controller's signs and zeros (``[controller]``); False: the identity
    #: is assumed (:func:`controller_warning`).
    controller_declared: bool = True
    source: str = ""
    inputs: tuple[Path, ...] = ()
    link_q: np.ndarray | None = None
    slow_factor: float = 1.0
    program: str = ""
    robot_v_max: np.ndarray | None = None
    robot_a_max: np.ndarray | None = None
    robot_j_max: np.ndarray | None = None

    def plan_limit(self, name: str) -> np.ndarray:
        """The plan's limit of rate ``name`` (``velocity``, ``acceleration``, ``jerk``), shape (6,)."""
        return {"velocity": self.v_max, "acceleration": self.a_max, "jerk": self.j_max}[name]

    def robot_limit(self, name: str) -> np.ndarray:
        """The robot's own limit of rate ``name`` (its controller's), else the plan's, shape (6,)."""
        own = {"velocity": self.robot_v_max, "acceleration": self.robot_a_max, "jerk": self.robot_j_max}[name]
        return self.plan_limit(name) if own is None else own

    @property
    def robot_limits_known(self) -> bool:
        """The robot's own limits are known (else :meth:`robot_limit` gives the plan's)."""
        return self.robot_v_max is not None and self.robot_a_max is not None and self.robot_j_max is not None

    def slowed(self, k: float) -> ExportData:
        """The same path ``k`` times slower: times and ``dt`` times ``k``, velocities over ``k``,
        accelerations over ``k^2``, jerks over ``k^3`` (every rate's peak divided by ``k`` to its order)."""
        return replace(
            self,
            t=self.t * k,
            qd=self.qd / k,
            qdd=self.qdd / k**2,
            qddd=self.qddd / k**3,
            dt=self.dt * k,
            slow_factor=self.slow_factor * k,
        )

    def controller_q(self, q: np.ndarray | None = None) -> np.ndarray:
        """Joint positions in the controller's convention (rad), (M, 6)."""
        return (self.q if q is None else q) * self.sign + self.offset

    def controller_rates(self, x: np.ndarray) -> np.ndarray:
        """Velocities or accelerations in the controller's convention (the sign only)."""
        return x * self.sign

    def decimated(self, step_s: float) -> np.ndarray:
        """Sample indices about ``step_s`` apart, always including the first and the last."""
        k = max(1, int(round(step_s / self.dt)))
        idx = np.arange(0, len(self.t), k)
        return idx if idx[-1] == len(self.t) - 1 else np.r_[idx, len(self.t) - 1]


#: Formats whose joint angles go to a vendor's controller in its own signs and zeros.
VENDOR_FORMATS = ("urscript", "urscript_movej", "rapid", "krl")


def controller_warning(data: ExportData, fmt: str) -> str:
    """The warning for a vendor format of a robot whose file has no ``[controller]`` table (the
    identity is then assumed for the controller's joint signs and zeros), or empty."""
    if fmt not in VENDOR_FORMATS or data.controller_declared:
        return ""
    return (
        f"robot {data.robot} has no [controller] table: the {fmt} angles assume its controller's joint signs "
        "and zeros are the model's (sign +1, offset 0); check them and fill [controller] joint_sign and "
        "joint_offset_deg in its robot file (docs/robot-file.md)"
    )


def program_name(text: str) -> str:
    """``text`` as a program name: letters, digits and underscores, not starting with a digit."""
    out = "".join(c if c.isalnum() else "_" for c in text).strip("_") or "compplan"
    return ("t_" + out) if out[0].isdigit() else out


def header_lines(data: ExportData, fmt: str, comment: str) -> list[str]:
    """A few comment lines every file starts with (what, where from, the conventions)."""
    from planner.provenance import version

    return [
        f"{comment} generated by compplan {version()} ({fmt}) from {data.source}: robot {data.robot}, "
        f"{len(data.t)} samples at {data.dt * 1e3:g} ms, {data.t[-1]:.6g} s",
        f"{comment} joints {', '.join(data.joint_names)}; controller angle = sign * q + offset, "
        f"sign {[int(v) for v in data.sign]}, offset {[round(math.degrees(v), 6) for v in data.offset]} deg "
        "(docs/export.md)",
    ] + (
        [
            f"{comment} slowed down x{data.slow_factor:.4f} from the plan's timing "
            f"({data.t[-1] / data.slow_factor:.6g} s) so that what the controller runs stays within every limit "
            "(docs/export.md)"
        ]
        if data.slow_factor != 1.0
        else []
    )
