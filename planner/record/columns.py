"""The files of a run folder and their columns: what ``compplan plan``/``demo`` write and what the
folder reader (:mod:`planner.record.read`), the report, the exports and ``track`` read.

One place for the names: the writer (:mod:`planner.plan_outputs`) and the reader take them from here.
Angles in rad, lengths in m, times in s unless a column's name says otherwise.
"""

from __future__ import annotations

from planner.output import TRAJECTORY_COLUMNS

__all__ = [
    "CUT_COLUMNS",
    "CUT_FILE",
    "CUT_KEY",
    "CUT_STOCK_FILE",
    "DYNAMIC_COLUMNS",
    "DYNAMIC_KEY",
    "FLAG_COLUMNS",
    "INDEX_COLUMNS",
    "JERK_COLUMNS",
    "LINK_COLUMNS",
    "MAGNITUDE_COLUMNS",
    "MM_MIN_PER_M_S",
    "NAN_COLUMNS",
    "PATH_COLUMNS",
    "PROGRAM_KEY",
    "PROGRAM_PATH_COLUMNS",
    "PROGRAM_TRAJECTORY_COLUMNS",
    "TIME_COLUMN",
    "TRAJECTORY_COLUMNS",
    "TRAJECTORY_FILES",
    "WAYPOINT_COLUMNS",
    "trajectory_file",
]

#: Columns of ``waypoints.csv`` (see docs/cli.md): k, path parameter s, target position,
#: planned (deflected) joints qt, exact command qc, closed-form command qf, TCP errors
#: before / after closed form / after exact (m, base frame), directional stiffness (N/m).
WAYPOINT_COLUMNS = (
    ["k", "s", "x", "y", "z"]
    + [f"qt{i}" for i in range(1, 7)]
    + [f"qc{i}" for i in range(1, 7)]
    + [f"qf{i}" for i in range(1, 7)]
    + ["ebx", "eby", "ebz", "efx", "efy", "efz", "eex", "eey", "eez", "kx", "ky", "kz"]
)
#: Columns of ``path.csv``.
PATH_COLUMNS = ["x", "y", "z"] + [f"q{i}" for i in range(1, 7)]
#: Columns ``path.csv`` adds for a program path: the programmed feed of the move ending at the
#: waypoint (mm/min, nan for rapids and waypoint 0), its program line, 1 for a rapid.
PROGRAM_PATH_COLUMNS = ["feed_mm_min", "line", "rapid"]
#: Columns ``trajectory*.csv`` adds for a program path: the program line of the move each sample runs,
#: and the waypoint (0-based row of ``path.csv``) that move ends at.
PROGRAM_TRAJECTORY_COLUMNS = ["line", "waypoint"]
#: Extra columns of ``trajectory.csv`` with dynamic compensation: the planned link side, rad.
LINK_COLUMNS = [f"ql{i}" for i in range(1, 7)]
#: Jerk columns of ``trajectory*.csv`` (absent in files written before they were recorded).
JERK_COLUMNS = [c for c in TRAJECTORY_COLUMNS if c.startswith("qddd")]
#: Columns of ``dynamic.csv`` (dynamic compensation): time (s), moving (0/1), the predicted TCP
#: error along the command without compensation, with the static one and with static + dynamic
#: (m), and the planned TCP speed (m/s).
DYNAMIC_COLUMNS = ("t", "moving", "e_none_m", "e_static_m", "e_static_dynamic_m", "tcp_speed_m_s")
#: The summary.json key of the dynamic-compensation stage.
DYNAMIC_KEY = "dynamic_compensation"
#: The ``summary.json`` key of a program path (:func:`planner.plan_summary.program_summary`).
PROGRAM_KEY = "program"
#: m/s -> mm/min (``path.csv``'s ``feed_mm_min``).
MM_MIN_PER_M_S = 6e4

#: The trajectory files of runs whose summary.json has no ``timing.<method>.file`` (made before
#: a plan named the file of each method there; their ``trajectory.csv`` was Ruckig's).
TRAJECTORY_FILES = (("trajectory_toppra.csv", "toppra"), ("trajectory.csv", "ruckig"))

#: Columns checked by name in every CSV file of a run the folder reader reads: the time column
#: (s, >= 0, strictly increasing), the whole-number columns (waypoint index, program line, row of
#: path.csv), the 0/1 columns, and the columns of magnitudes (>= 0; m, m/s, mm/min).
TIME_COLUMN = "t"
INDEX_COLUMNS = ("k", "line", "waypoint")
FLAG_COLUMNS = ("rapid", "moving")
MAGNITUDE_COLUMNS = (
    "e_none_m",
    "e_static_m",
    "e_static_dynamic_m",
    "tcp_speed_m_s",
    "feed_mm_min",
    "force_N",
    "peak_force_N",
    "axial_depth_mm",
    "radial_width_mm",
    "feed_per_tooth_mm",
    "spindle_rpm",
)
#: The columns of a file that may hold NaN, "none" (``"*"``: every column but the indices): a branch
#: without a posture at a waypoint, the feed of a rapid and of waypoint 0.  Every other cell of
#: every file must be a finite number (a trajectory's samples, the waypoints, dynamic.csv, ...).
NAN_COLUMNS: dict[str, tuple[str, ...] | str] = {
    "branches.csv": "*",
    "path.csv": ("feed_mm_min",),
    # the engagement angles in the air; the stand-in's error without one
    "cut.csv": ("entry_deg", "exit_deg", "error_stand_in_mm", "error_uncompensated_mm", "error_compensated_mm"),
}


def trajectory_file(method: str, controller: str | None) -> str:
    """The file of timing method ``method``'s trajectory: ``trajectory.csv`` for the controller's,
    ``trajectory_<method>.csv`` for the others."""
    return "trajectory.csv" if method == controller else f"trajectory_{method}.csv"


#: summary.json key of a run whose load is a predicted cut (``[material]`` + ``[stock]``).
CUT_KEY = "cut"
#: The run's per-waypoint cut (``docs/cutting.md``, "Outputs").
CUT_FILE = "cut.csv"
#: The stock's top before and after the program (NumPy ``.npz``: ``before``, ``after`` (ny, nx) m,
#: NaN: no material; ``extent`` x_min, x_max, y_min, y_max, m, program frame).
CUT_STOCK_FILE = "cut_stock.npz"
#: The columns of ``cut.csv``, one row per waypoint: the program line; the predicted wrench on the
#: tool (program frame, N; moment about the tool tip, N·m); its force magnitude and peak over a
#: revolution (N); the engagement (mm, deg; ``milling``: index into summary.json
#: ``cut.milling_codes``); the feed per tooth (mm) and the spindle (rev/min); the TCP error (mm, the
#: norm) under the predicted load: uncompensated, compensated for it (exact), compensated for the
#: ``[cut] stand_in`` instead (NaN without one).
CUT_COLUMNS = [
    "line",
    "fx_N",
    "fy_N",
    "fz_N",
    "mx_Nm",
    "my_Nm",
    "mz_Nm",
    "force_N",
    "peak_force_N",
    "axial_depth_mm",
    "radial_width_mm",
    "entry_deg",
    "exit_deg",
    "milling",
    "feed_per_tooth_mm",
    "spindle_rpm",
    "error_uncompensated_mm",
    "error_compensated_mm",
    "error_stand_in_mm",
]
