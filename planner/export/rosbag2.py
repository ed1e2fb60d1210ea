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

Big programs: ``/joint_trajectory`` carries the trajectory in the messages of the ``ros2``
format's parts (at most ``max_points`` points each, default
:data:`planner.export.ros2.ROS2_MAX_POINTS`): part k at bag time (and header stamp)
``start_time_s`` + its start, the previous part's last sample (``docs/export.md``, "Big
programs").  ``/joint_states`` is one small message per sample whatever the length.
"""

from __future__ import annotations

import struct
import tempfile
from pathlib import Path
from typing import Any
from collections.abc import Mapping

import numpy as np

from planner.export import (
    SLOW_DOWN_OPTION,
    ControllerMotion,
    ExportData,
    ExportError,
    ExportFormat,
    counted,
    part_ranges,
    ranged,
    register_format,
)
from planner.export.ros2 import MAX_POINTS_LIMIT, ROS2_MAX_POINTS, nanoseconds, part_start_ns, spline_motion
from planner.export.ros2 import changes as ros2_changes

#: ROS 2 distribution whose message definitions are written.
TYPESTORE = "ROS2_HUMBLE"
TOPIC_TRAJECTORY = "/joint_trajectory"
TOPIC_STATES = "/joint_states"
#: Largest ``sec`` of a ``builtin_interfaces/msg/Time`` (an int32).
STAMP_SEC_MAX = 2**31 - 1


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
    ns = nanoseconds(data.t)
    if (t0 + ns[-1]) // 1_000_000_000 > STAMP_SEC_MAX:
        raise ExportError(
            f"rosbag2: start_time_s + the duration ({(t0 + ns[-1]) * 1e-9:.0f} s) is past the last time a "
            f"ROS 2 stamp holds ({STAMP_SEC_MAX} s, an int32); give an earlier start_time_s"
        )
    names = list(data.joint_names)
    frame = str(o["frame_id"])
    with tempfile.TemporaryDirectory(prefix="compplan-bag-") as tmp:
        bag = Path(tmp) / stem
        with Writer(bag, version=int(o["version"])) as w:
            c_traj = w.add_connection(TOPIC_TRAJECTORY, "trajectory_msgs/msg/JointTrajectory", typestore=store)
            c_state = w.add_connection(TOPIC_STATES, "sensor_msgs/msg/JointState", typestore=store)
            for a, b in part_ranges(len(ns), int(o["max_points"])):
                start = part_start_ns(ns, a)
                traj = T["trajectory_msgs/msg/JointTrajectory"](
                    header=T["std_msgs/msg/Header"](
                        stamp=_stamp(T, "builtin_interfaces/msg/Time", t0 + start), frame_id=frame
                    ),
                    joint_names=names,
                    points=[
                        T["trajectory_msgs/msg/JointTrajectoryPoint"](
                            positions=q[k].astype(np.float64),
                            velocities=qd[k].astype(np.float64),
                            accelerations=qdd[k].astype(np.float64),
                            effort=np.zeros(0),
                            time_from_start=_stamp(T, "builtin_interfaces/msg/Duration", ns[k] - start),
                        )
                        for k in range(a, b)
                    ],
                )
                w.write(c_traj, t0 + start, store.serialize_cdr(traj, traj.__msgtype__))
                del traj
            states = JointStates(store, names, frame)
            for k in range(len(ns)):
                w.write(c_state, t0 + ns[k], states.cdr(t0 + ns[k], q[k], qd[k]))
        return {p.relative_to(bag).as_posix(): p.read_bytes() for p in sorted(bag.rglob("*")) if p.is_file()}


class JointStates:
    """CDR bytes of ``sensor_msgs/msg/JointState`` messages that differ only in stamp, position and
    velocity (same names and frame): one message is serialised by ``rosbags`` and the others are
    that template with those fields replaced at their byte offsets (the layout of the fields
    before them does not change), which is exact and many times faster for 10^5-10^6 samples.
    The template is checked against ``rosbags``' own serialisation of a second message; if the
    layout is not the expected one every message is serialised by ``rosbags``."""

    def __init__(self, store: Any, names: list[str], frame: str) -> None:
        self.store, self.names, self.frame = store, names, frame
        self.template = self._slow(0, np.zeros(6), np.zeros(6))
        # stamp: right after the 4-byte encapsulation header; the message ends with position (6
        # doubles, 8-aligned), velocity (4-byte length, 4 bytes padding, 6 doubles) and the empty
        # effort (4-byte length)
        n = len(self.template)
        self.vel = n - 4 - 48
        self.pos = self.vel - 8 - 48
        self.fast = True
        q, v = np.arange(1.0, 7.0) * 0.1, -np.arange(1.0, 7.0)
        self.fast = self.cdr(1_234_567_891_011, q, v) == self._slow(1_234_567_891_011, q, v)

    def _slow(self, ns: int, q: np.ndarray, v: np.ndarray) -> bytes:
        T = self.store.types
        msg = T["sensor_msgs/msg/JointState"](
            header=T["std_msgs/msg/Header"](stamp=_stamp(T, "builtin_interfaces/msg/Time", ns), frame_id=self.frame),
            name=self.names,
            position=np.asarray(q, dtype=np.float64),
            velocity=np.asarray(v, dtype=np.float64),
            effort=np.zeros(0),
        )
        return bytes(self.store.serialize_cdr(msg, msg.__msgtype__))

    def cdr(self, ns: int, q: np.ndarray, v: np.ndarray) -> bytes:
        """The serialised message stamped ``ns`` (ns since the epoch) with positions ``q`` and
        velocities ``v`` (rad, rad/s)."""
        if not self.fast:
            return self._slow(ns, q, v)
        t = self.template
        return b"".join(
            (
                t[:4],
                struct.pack("<iI", ns // 1_000_000_000, ns % 1_000_000_000),
                t[12 : self.pos],
                np.asarray(q, dtype="<f8").tobytes(),
                t[self.pos + 48 : self.vel],
                np.asarray(v, dtype="<f8").tobytes(),
                t[self.vel + 48 :],
            )
        )


def motion(data: ExportData, o: Mapping[str, Any]) -> ControllerMotion:
    """The ``/joint_trajectory`` points (float64, as the ``ros2`` format's without its rounding) and
    the quintic a joint_trajectory_controller lays between them; ``/joint_states`` holds the same
    positions and velocities at the same times."""
    return spline_motion(data, None, "the /joint_trajectory points")


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
                ranged("start_time_s", 0.0, float(STAMP_SEC_MAX)),
            ),
            "frame_id": ("", "header.frame_id", str),
            "version": (8, "rosbag2 metadata version (8 or 9)", _version),
            "max_points": (
                ROS2_MAX_POINTS,
                "most points in one /joint_trajectory message; a longer trajectory is split into several",
                counted("max_points", 2, MAX_POINTS_LIMIT),
            ),
            "slow_down": SLOW_DOWN_OPTION,
        },
        "ROS 2 bag folder (rosbags): /joint_trajectory (one JointTrajectory) and /joint_states per sample",
        folder=True,
        motion=motion,
        timing_options=("slow_down",),
        changes=ros2_changes,
    )
)
