"""ROS 2: a ``trajectory_msgs/msg/JointTrajectory`` as YAML.

The form ``ros2 topic pub /joint_trajectory_controller/joint_trajectory
trajectory_msgs/msg/JointTrajectory "$(cat file.yaml)"`` and MoveIt accept: ``joint_names``
from the robot file (its URDF joint names), and one point per sample with ``positions``
(rad), ``velocities`` (rad/s), ``accelerations`` (rad/s^2) and ``time_from_start``
(``sec``, ``nanosec``), in the controller's convention (sign and offset of the robot file's
``[controller]``).  A rosbag2 is not written (no pure-Python writer is a dependency here).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Mapping

from planner.export import ExportData, ExportFormat, header_lines, register_format

#: Printed significant digits of positions, velocities and accelerations.
DIGITS = 12


def _list(v: Any) -> str:
    return "[" + ", ".join(f"{float(x):.{DIGITS}g}" for x in v) + "]"


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, str]:
    q = data.controller_q()
    qd, qdd = data.controller_rates(data.qd), data.controller_rates(data.qdd)
    lines = header_lines(data, "ros2 trajectory_msgs/msg/JointTrajectory", "#")
    lines += [
        "header:",
        "  stamp: {sec: 0, nanosec: 0}",
        f"  frame_id: '{o['frame_id']}'",
        "joint_names: [" + ", ".join(f"'{n}'" for n in data.joint_names) + "]",
        "points:",
    ]
    for t, a, b, c in zip(data.t, q, qd, qdd):
        ns = int(round(float(t) * 1e9))
        lines += [
            f"- positions: {_list(a)}",
            f"  velocities: {_list(b)}",
            f"  accelerations: {_list(c)}",
            "  effort: []",
            f"  time_from_start: {{sec: {ns // 1_000_000_000}, nanosec: {ns % 1_000_000_000}}}",
        ]
    return {f"{stem}.yaml": "\n".join(lines) + "\n"}


def _frame(v: Any) -> str:
    return str(v)


register_format(
    ExportFormat(
        "ros2",
        (".yaml",),
        write,
        {"frame_id": ("", "header.frame_id", _frame)},
        "trajectory_msgs/msg/JointTrajectory as YAML (ros2 topic pub, MoveIt)",
    )
)
