"""ROS 2 bag (rosbag2, SQLite 3 storage) written with the pure-Python ``rosbags`` library.

A folder (``--out BAG``) holding ``metadata.yaml`` and ``BAG_0.db3`` with two topics:

* ``/joint_trajectory`` (``trajectory_msgs/msg/JointTrajectory``): the whole trajectory as one
  message, the same content as the ``ros2`` YAML export, at the bag's start time;
* ``/joint_states`` (``sensor_msgs/msg/JointState``): one message per sample, stamped (header and
  bag time) ``start_time_s + t``, position and velocity: the motion as a controller should
  play it, for replay (``ros2 bag play``), plotting or comparison with a recorded bag.

Angles in rad in the controller's convention (``[controller]`` of the robot file); joint
names from the robot file.  Bag format version ``version`` (8: ROS 2 Iron and later read it;
9: Jazzy).  Needs the optional dependency ``rosbags`` (``pip install "compplan[ros]"``).
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import ExportData, ExportError, ExportFormat, ranged, register_format

#: ROS 2 distribution whose message definitions are written.
TYPESTORE = "ROS2_HUMBLE"
TOPIC_TRAJECTORY = "/joint_trajectory"
TOPIC_STATES = "/joint_states"


def _ns(t: float) -> int:
    return int(round(float(t) * 1e9))


def _stamp(types: Any, cls: str, ns: int) -> Any:
    return types[cls](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def write(data: ExportData, stem: str, o: Mapping[str, Any]) -> dict[str, bytes]:
    try:
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise ExportError(
            'rosbag2: needs the Python package rosbags (pip install "compplan[ros]" or '
            "pip install rosbags); the ros2 format writes the same trajectory as YAML"
        ) from None
    store = get_typestore(getattr(Stores, TYPESTORE))
    T = store.types
    q = data.controller_q()
    qd, qdd = data.controller_rates(data.qd), data.controller_rates(data.qdd)
    t0 = _ns(o["start_time_s"])
    names = list(data.joint_names)
    header = T["std_msgs/msg/Header"](stamp=_stamp(T, "builtin_interfaces/msg/Time", t0), frame_id=str(o["frame_id"]))
    points = [
        T["trajectory_msgs/msg/JointTrajectoryPoint"](
            positions=q[k].astype(np.float64),
            velocities=qd[k].astype(np.float64),
            accelerations=qdd[k].astype(np.float64),
            effort=np.zeros(0),
            time_from_start=_stamp(T, "builtin_interfaces/msg/Duration", _ns(data.t[k])),
        )
        for k in range(len(data.t))
    ]
    traj = T["trajectory_msgs/msg/JointTrajectory"](header=header, joint_names=names, points=points)
    with tempfile.TemporaryDirectory(prefix="compplan-bag-") as tmp:
        bag = Path(tmp) / stem
        with Writer(bag, version=int(o["version"])) as w:
            c_traj = w.add_connection(TOPIC_TRAJECTORY, traj.__msgtype__, typestore=store)
            c_state = w.add_connection(TOPIC_STATES, "sensor_msgs/msg/JointState", typestore=store)
            w.write(c_traj, t0, store.serialize_cdr(traj, traj.__msgtype__))
            for k in range(len(data.t)):
                ns = t0 + _ns(data.t[k])
                msg = T["sensor_msgs/msg/JointState"](
                    header=T["std_msgs/msg/Header"](
                        stamp=_stamp(T, "builtin_interfaces/msg/Time", ns), frame_id=str(o["frame_id"])
                    ),
                    name=names,
                    position=q[k].astype(np.float64),
                    velocity=qd[k].astype(np.float64),
                    effort=np.zeros(0),
                )
                w.write(c_state, ns, store.serialize_cdr(msg, msg.__msgtype__))
        return {p.relative_to(bag).as_posix(): p.read_bytes() for p in sorted(bag.rglob("*")) if p.is_file()}


def _version(v: Any) -> int:
    x = int(ranged("version", 8, 9)(v))
    if x not in (8, 9):
        raise ExportError(f"export option version = {v!r}: expected 8 or 9")
    return x


register_format(
    ExportFormat(
        "rosbag2",
        ("",),
        write,
        {
            "start_time_s": (
                0.0,
                "bag time of the first sample, s since the epoch",
                ranged("start_time_s", 0.0, 4.0e9),
            ),
            "frame_id": ("", "header.frame_id", str),
            "version": (8, "rosbag2 metadata version (8 or 9)", _version),
        },
        "ROS 2 bag folder (rosbags): /joint_trajectory (one JointTrajectory) and /joint_states per sample",
        folder=True,
    )
)
