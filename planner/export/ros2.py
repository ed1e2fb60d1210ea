"""ROS 2: a ``trajectory_msgs/msg/JointTrajectory`` as YAML.

The form ``ros2 topic pub /joint_trajectory_controller/joint_trajectory
trajectory_msgs/msg/JointTrajectory "$(cat file.yaml)"`` and MoveIt accept: ``joint_names``
from the robot file (its URDF joint names), and one point per sample with ``positions``
(rad), ``velocities`` (rad/s), ``accelerations`` (rad/s^2) and ``time_from_start``
(``sec``, ``nanosec``), in the controller's convention (sign and offset of the robot file's
``[controller]``).  The bag form is the ``rosbag2`` format.  Checked (:func:`spline_motion`): the
quintic a joint_trajectory_controller lays between the points, against every limit (slowed down,
saying so, or refused: option ``slow_down``).

Big programs: a trajectory of more than ``max_points`` samples (default
:data:`ROS2_MAX_POINTS`) is written as numbered messages ``NAME_p001.yaml`` ... of at most
``max_points`` points each, and ``NAME.yaml`` becomes their index: part k starts where part
k - 1 ends (its ``time_from_start`` counts from the previous part's last sample, so its first
point is one period after it), to be sent in order with ``header.stamp`` = the first part's
start + the part's ``start`` (``docs/export.md``, "Big programs").
"""

from __future__ import annotations

import math
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import (
    SLOW_DOWN_OPTION,
    ControllerMotion,
    ExportData,
    ExportFormat,
    Interpolation,
    counted,
    header_lines,
    part_label,
    part_ranges,
    register_format,
)
from planner.export.parts import parts_change

#: Printed significant digits of positions, velocities and accelerations.
DIGITS = 12
#: Most points in one JointTrajectory message; a longer trajectory is split into several.  The
#: message has no size limit (``points`` is an unbounded sequence) and ros2_control's
#: joint_trajectory_controller keeps a whole message in memory; 10,000 points are 1.8 MB
#: of CDR and 4.1 MB of YAML.  Drivers built on micro-ROS take far fewer (MotoROS2: 200 points
#: per goal): set ``max_points`` for yours.
ROS2_MAX_POINTS = 10_000
#: Most ``max_points`` accepted (the option's range).
MAX_POINTS_LIMIT = 10**9
NS_PER_S = 1_000_000_000


#: A row of six numbers as printed: ``[a, b, c, d, e, f]``, :data:`DIGITS` significant digits.
_ROW6 = "[" + ", ".join([f"%.{DIGITS}g"] * 6) + "]"


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str | bytes]:
    q = data.controller_q()
    qd, qdd = data.controller_rates(data.qd), data.controller_rates(data.qdd)
    ns = nanoseconds(data.t)
    head = header_lines(data, "ros2 trajectory_msgs/msg/JointTrajectory", "#")
    limit = int(o["max_points"])
    if len(ns) <= limit:
        return {f"{stem}.yaml": _message(head, data, o, q, qd, qdd, ns, 0, len(ns), 0)}
    ranges = part_ranges(len(ns), limit)
    files: dict[str, str | bytes] = {}
    index = head + [
        f"# {len(ranges)} JointTrajectory messages of at most {limit} points (max_points; docs/export.md "
        '"Big programs"): send them in order,',
        "# each with header.stamp = the start of the first + its start (its first point is one period after the "
        "previous part's last)",
        f"frame_id: '{o['frame_id']}'",
        "joint_names: [" + ", ".join(f"'{n}'" for n in data.joint_names) + "]",
        f"samples: {len(ns)}",
        "parts:",
    ]
    for k, (a, b) in enumerate(ranges, 1):
        name = f"{stem}_{part_label(k, len(ranges))}.yaml"
        start = part_start_ns(ns, a)
        note = (
            f"# part {k} of {len(ranges)}: samples {a} to {b - 1} of {len(ns)}; starts {_stamp(start)} after the "
            f"first part (header.stamp = its start + that; {stem}.yaml lists the parts)"
        )
        # bytes at once: a big trajectory's text is then held once, not also as str
        files[name] = _message(head + [note], data, o, q, qd, qdd, ns, a, b, start).encode()
        index.append(f"- {{file: {name}, start: {_stamp(start)}, first_sample: {a}, points: {b - a}}}")
    return {f"{stem}.yaml": "\n".join(index) + "\n", **files}


def spline_motion(data: ExportData, digits: int | None = None, label: str = "the points") -> ControllerMotion:
    """The points at their times (whole nanoseconds) with their velocities and accelerations, as
    written (``digits`` significant digits, or float64 as they are), and the quintic a
    joint_trajectory_controller lays between them (``splines``, its default)."""
    q, qd, qdd = data.controller_q(), data.controller_rates(data.qd), data.controller_rates(data.qdd)
    eps = 0.0
    if digits is not None:
        q, qd, qdd = (significant(x, digits) for x in (q, qd, qdd))
        eps = 0.5 * 10.0 ** (math.floor(math.log10(max(float(np.abs(q).max()), 1e-300))) - digits + 1)
    return ControllerMotion(
        Interpolation.QUINTIC,
        f"the joint_trajectory_controller's quintic spline through {label}",
        np.rint(data.t * 1e9) * 1e-9,
        (q - data.offset) * data.sign,
        qd * data.sign,
        qdd * data.sign,
        eps=eps,
    )


def significant(x: np.ndarray, digits: int) -> np.ndarray:
    """``x`` rounded to ``digits`` significant digits, as ``%.{digits}g`` prints it (up to ties)."""
    mag = np.floor(np.log10(np.abs(x), out=np.zeros_like(x), where=x != 0.0))
    scale = 10.0 ** (digits - 1 - mag)
    return np.round(x * scale) / scale


def motion(data: ExportData, o: Mapping[str, Any]) -> ControllerMotion:
    """What a joint_trajectory_controller runs from the YAML (:data:`DIGITS` significant digits)."""
    return spline_motion(data, DIGITS)


def nanoseconds(t: np.ndarray) -> list[int]:
    """Sample times as whole nanoseconds (``time_from_start``, bag time stamps)."""
    return [int(round(float(x) * 1e9)) for x in t]


def part_start_ns(ns: list[int], a: int) -> int:
    """Where a part that begins at sample ``a`` starts: at the previous sample (the last of the
    previous part), so that its first point comes one period after it; 0 for the first part."""
    return ns[a - 1] if a > 0 else 0


def _stamp(ns: int) -> str:
    return f"{{sec: {ns // NS_PER_S}, nanosec: {ns % NS_PER_S}}}"


def _message(
    head: list[str],
    data: ExportData,
    o: Mapping[str, Any],
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    ns: list[int],
    a: int,
    b: int,
    start: int,
) -> str:
    """One JointTrajectory message (YAML) of samples ``a`` to ``b - 1``, ``time_from_start``
    counted from ``start`` (ns)."""
    lines = head + [
        "header:",
        "  stamp: {sec: 0, nanosec: 0}",
        f"  frame_id: '{o['frame_id']}'",
        "joint_names: [" + ", ".join(f"'{n}'" for n in data.joint_names) + "]",
        "points:",
    ]
    P, V, A = q[a:b].tolist(), qd[a:b].tolist(), qdd[a:b].tolist()
    for k in range(b - a):
        lines += [
            f"- positions: {_ROW6 % tuple(P[k])}",
            f"  velocities: {_ROW6 % tuple(V[k])}",
            f"  accelerations: {_ROW6 % tuple(A[k])}",
            "  effort: []",
            f"  time_from_start: {_stamp(ns[a + k] - start)}",
        ]
    return "\n".join(lines) + "\n"


def changes(data: ExportData, o: Mapping[str, Any]) -> tuple[str, ...]:
    """One message, or split into several (``max_points``)."""
    return parts_change(len(data.t), int(o["max_points"]), "points", "max_points", "JointTrajectory message")


def _frame(v: Any) -> str:
    return str(v)


register_format(
    ExportFormat(
        "ros2",
        (".yaml",),
        write,
        {
            "frame_id": ("", "header.frame_id", _frame),
            "max_points": (
                ROS2_MAX_POINTS,
                "most points in one message; a longer trajectory is split into NAME_p001.yaml ...",
                counted("max_points", 2, MAX_POINTS_LIMIT),
            ),
            "slow_down": SLOW_DOWN_OPTION,
        },
        "trajectory_msgs/msg/JointTrajectory as YAML (ros2 topic pub, MoveIt)",
        motion=motion,
        timing_options=("slow_down",),
        changes=changes,
    )
)
