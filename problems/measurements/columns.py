"""Column names, units, joint-name presets and CSV dialects of the measurement file format.

The vocabulary of ``docs/measurement-file.md``: the base column names and the
quantity of each, the unit suffixes a column may carry (with their factor to SI),
the column groups (joints, wrench, position, orientation, standard deviations), the
``joint_names`` presets, the two CSV dialects and the file formats (the tracker-dif layout).
Data only; no parsing here.
"""

from __future__ import annotations

import math

# quantity -> {suffix: factor to SI}
UNITS: dict[str, dict[str, float]] = {
    "angle": {"": 1.0, "_rad": 1.0, "_deg": math.pi / 180.0},
    # small angles (orientation standard deviations): also milli- and microradians.  Not
    # offered for q1..q6, whose messages elsewhere quote a column's unit as deg or rad.
    "small_angle": {"": 1.0, "_rad": 1.0, "_deg": math.pi / 180.0, "_mrad": 1e-3, "_urad": 1e-6},
    "length": {"": 1.0, "_m": 1.0, "_mm": 1e-3, "_um": 1e-6},
    "force": {"": 1.0, "_N": 1.0, "_kN": 1e3},
    "moment": {"": 1.0, "_Nm": 1.0, "_Nmm": 1e-3},
    "time": {"": 1.0, "_s": 1.0, "_ms": 1e-3, "_min": 60.0, "_h": 3600.0},
    "temperature": {"": 1.0, "_C": 1.0, "_degC": 1.0},
}

#: Base column name -> quantity.
COLUMNS: dict[str, str] = {
    **{f"q{i}": "angle" for i in range(1, 7)},
    "fx": "force",
    "fy": "force",
    "fz": "force",
    "mx": "moment",
    "my": "moment",
    "mz": "moment",
    "x": "length",
    "y": "length",
    "z": "length",
    "rx": "angle",
    "ry": "angle",
    "rz": "angle",
    "t": "time",
    "temperature": "temperature",
    "sigma": "length",
    "sigma_x": "length",
    "sigma_y": "length",
    "sigma_z": "length",
    "sigma_r": "small_angle",
    "sigma_rx": "small_angle",
    "sigma_ry": "small_angle",
    "sigma_rz": "small_angle",
}
Q_COLUMNS = tuple(f"q{i}" for i in range(1, 7))
WRENCH_COLUMNS = ("fx", "fy", "fz", "mx", "my", "mz")
POSITION_COLUMNS = ("x", "y", "z")
ROTATION_COLUMNS = ("rx", "ry", "rz")
#: Per-axis standard deviations of the position measurement (length).
SIGMA_XYZ_COLUMNS = ("sigma_x", "sigma_y", "sigma_z")
#: Per-axis standard deviations of the orientation measurement (angle).
SIGMA_ROT_COLUMNS = ("sigma_rx", "sigma_ry", "sigma_rz")
#: Columns whose values are labels, not numbers.
LABEL_COLUMNS = ("point",)
#: Prefixes of columns that are carried along but ignored (user annotations).
IGNORED_PREFIXES = ("note", "extra_")

#: CSV dialects: name -> (separator, decimal comma).
DIALECTS: dict[str, tuple[str, bool]] = {"comma": (",", False), "semicolon": (";", True)}
#: Values of the ``dialect`` parameter.
DIALECT_CHOICES = ("auto", *DIALECTS)

#: Presets of ``joint_names``: name -> the six joint column names mapped to q1..q6 in order.
JOINT_NAME_PRESETS: dict[str, tuple[str, ...]] = {
    "ros-ur": (
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    ),
}

# ----------------------------------------------------------------------------------
# File formats (``file_format`` / ``--format``)
# ----------------------------------------------------------------------------------

#: The tracker-dif layout (a laser-tracker export of targets and deviations): the measurement
#: order, the target of the measured point (mm, robot base frame: the acquisition software's
#: nominal forward kinematics), its deviation ``dif`` (mm) and the commanded joints (deg).
TRACKER_ORDER_COLUMN = "step_order"
TRACKER_TARGET_COLUMNS = ("x_t", "y_t", "z_t")
TRACKER_DIF_COLUMNS = ("x_dif", "y_dif", "z_dif")
TRACKER_JOINT_COLUMNS = tuple(f"joint_{i}" for i in range(1, 7))
TRACKER_COLUMNS = (TRACKER_ORDER_COLUMN, *TRACKER_TARGET_COLUMNS, *TRACKER_DIF_COLUMNS, *TRACKER_JOINT_COLUMNS)
#: SI factors of the tracker-dif columns: lengths in mm, joint angles in degrees.
TRACKER_LENGTH_FACTOR = UNITS["length"]["_mm"]
TRACKER_ANGLE_FACTOR = UNITS["angle"]["_deg"]
#: Tracker formats: name -> sign of ``dif`` (measured = target + sign * dif).  ``tracker-dif``:
#: ``dif`` = measured - target; ``tracker-dif-reversed``: ``dif`` = target - measured.
TRACKER_FORMATS: dict[str, float] = {"tracker-dif": 1.0, "tracker-dif-reversed": -1.0}
#: The measurement-file formats: ``compplan`` (docs/measurement-file.md's columns) and the tracker ones.
FORMATS = ("compplan", *TRACKER_FORMATS)
#: Values of the ``file_format`` parameter: ``auto`` tells the formats apart by the header.
FORMAT_CHOICES = ("auto", *FORMATS)


def tracker_columns_text() -> str:
    """The tracker-dif columns with their units, for messages."""
    return (
        f"{TRACKER_ORDER_COLUMN}, {', '.join(TRACKER_TARGET_COLUMNS)} (target, mm), "
        f"{', '.join(TRACKER_DIF_COLUMNS)} (deviation, mm), "
        f"{TRACKER_JOINT_COLUMNS[0]}..{TRACKER_JOINT_COLUMNS[-1]} (deg)"
    )
