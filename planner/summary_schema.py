"""``summary.json`` of a run, read back and checked: what ``report``, ``export`` and ``track`` read.

:data:`SUMMARY` declares, once, every key of ``summary.json`` that ``compplan report``
(:mod:`planner.report`), ``compplan export`` (:mod:`planner.export`) and ``compplan track`` read:
its kind (table, list of n numbers, number with range and unit, string from a set, file name, ...)
and which command needs it (``need``; every other key is optional: a summary written before a key
existed still reads). :func:`read_summary` reads a run folder's ``summary.json`` and refuses a
foreign or tampered one with one line: the file, the key path (``timing.ruckig.file``,
``limits.q_min[2]``), the value (shortened) and what was expected; never a traceback, never a
report drawn from nonsense. Keys it does not declare are allowed and not checked, so a key read by
one of these commands must be declared here (``tests/test_tampered_summary.py`` records what the
report and the export read and fails on an undeclared key; it tampers with every declared key).

What :func:`planner.plan_summary.plan_summary` writes is the source of these shapes; the status
words come from the status enums themselves.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from models.errors import InputError
from models.tables.kinds import (
    Ctx,
    Either,
    External,
    Flag,
    ListOf,
    MapOf,
    Number,
    Refused,
    Row,
    Table,
    Text,
    Vector,
    check,
    dotted,
    shown,
)

__all__ = [
    "COMMANDS",
    "SUMMARY",
    "SummaryError",
    "read_summary",
]

#: The commands that read a run's summary.json (the ``need`` of a key names some of them).
COMMANDS = ("report", "export", "track")
#: Values of ``command`` in the summary of a run these commands read.
RUN_COMMANDS = ("plan", "demo")
#: Joints of the arms compplan plans for (6R).
N_JOINTS = 6
#: The limited quantities (:data:`problems.timing.trajectory.LIMIT_KEYS`, not imported: that
#: package is slow to import and the export command needs no timing).
LIMIT_KEYS = ("velocity", "acceleration", "jerk")

_EXPORT = frozenset({"export", "track"})  # track reads the run through the export's reader
_REPORT = frozenset({"report"})
_TRACK = frozenset({"track"})


class SummaryError(InputError):
    """A run's ``summary.json`` is missing, not JSON, or has a key that does not fit its declaration."""


def _statuses(module: str, name: str) -> Callable[[], tuple[str, ...]]:
    """The words of a status enum (imported when first needed)."""

    def words() -> tuple[str, ...]:
        import importlib

        return tuple(s.value for s in getattr(importlib.import_module(module), name))

    return words


def _robot_file(value: Any, where: str) -> None:
    """A run's ``robot_file``: the DH-table robot file the run recorded (:meth:`Robot.to_dict`)."""
    from models.robot import robot_from_dict

    if "urdf" in value:  # a run records its robot as a DH table; never read another file from here
        raise InputError(f"{where}: key 'urdf': a run records its robot as a DH table, not a URDF reference")
    robot_from_dict(value, where=where)


def _cell(value: Any, where: str) -> None:
    """A run's ``problem.cell``: the cell as the problem had it (:meth:`problems.cell.Cell.to_dict`;
    the report's cell view draws it, :mod:`planner.report.cell_view`)."""
    from planner.report.cell_record import cell_block

    cell_block(value, where)


def _limits_ordered(table: Mapping[str, Any], path: tuple, ctx: Ctx) -> None:
    """``limits.q_min`` below ``limits.q_max``, joint by joint."""
    lo, hi = table.get("q_min"), table.get("q_max")
    if not (isinstance(lo, list) and isinstance(hi, list)):
        return
    for j, (a, b) in enumerate(zip(lo, hi)):
        if a is not None and b is not None and not a < b:
            raise Refused((*path, "q_min", j), a, f"a joint angle below limits.q_max[{j}] = {b:g} rad")


# ------------------------------------------------------------------------------ kinds of value
def _mm(**kw: Any) -> Number:
    """A TCP error (mm, >= 0; null when not computed)."""
    return Number(unit="mm", lo=0.0, nullable=True, **kw)


def _seconds(nullable: bool = False) -> Number:
    """A duration or a time (s, >= 0)."""
    return Number(unit="s", lo=0.0, nullable=nullable)


def _maybe_text(**kw: Any) -> Text:
    """A string or null (a reason, a note, a label a run may not have)."""
    return Text(nullable=True, **kw)


_SHA256 = dict(pattern="[0-9a-f]{64}", pattern_text="a SHA-256 (64 lower-case hex digits)", sample="0" * 64)
_RATIOS = Table(fields={k: Vector(n=N_JOINTS, item=Number(lo=0.0, nullable=True)) for k in LIMIT_KEYS})
_ERROR_STATS = Table(fields={"max_mm": _mm(), "rms_mm": _mm()}, nullable=True)

_TIMING_ENTRY = Table(
    fields={
        "status": Text(choices=_statuses("problems.timing.trajectory", "TimingStatus"), need=_EXPORT),
        "reason": _maybe_text(),
        "limits_enforced": ListOf(item=Text(choices=LIMIT_KEYS)),
        "display_name": Text(),
        "file": Text(file_name=True),
        "dt": Number(unit="s", lo=0.0, lo_open=True),
        "limit_use": Table(
            fields={
                "peak": _maybe_text(),
                "binding": ListOf(
                    item=Table(
                        fields={
                            "limit": Text(choices=LIMIT_KEYS),
                            "joint": Number(lo=1, hi=N_JOINTS, integer=True),
                            "fraction_of_time": Number(lo=0.0, hi=1.0),
                        }
                    )
                ),
                "under_half": Flag(),
            },
            nullable=True,
        ),
    }
)

_BRANCH_ENTRY = Table(
    fields={
        "status": Text(choices=_statuses("problems.posture.task", "BranchStatus")),
        "reason": _maybe_text(),
        "posture": _maybe_text(),
        **{k: Number(unit="m^2", lo=0.0, nullable=True) for k in ("cost", "cost_analytic", "cost_warm_start")},
        **{
            k: _mm()
            for k in (
                "rms_error_mm",
                "rms_error_analytic_mm",
                "max_error_mm",
                "rms_error_equilibrium_mm",
                "max_error_equilibrium_mm",
            )
        },
        "iterations": Number(lo=0, integer=True, nullable=True),
        "solve_time_s": _seconds(nullable=True),
    }
)

#: The dynamic headline's cases (the keys of :data:`planner.dynamic.HEADLINE_CASES`, not imported:
#: that module is slow to import and the export command needs none of it).
DYNAMIC_HEADLINE_CASES = ("uncompensated", "static_command", "motor_side_command")
_DYNAMIC_HEADLINE = Table(
    fields={
        **{f"error_{w}_max_{c}_mm": _mm() for w in ("motion", "rest") for c in DYNAMIC_HEADLINE_CASES},
        "numerical_floor_mm": Number(unit="mm", lo=0.0, lo_open=True),
        "below_numerical_floor": ListOf(item=Text()),
    },
    nullable=True,
)

_HEADLINE = Table(
    fields={
        "status": Text(choices=_statuses("planner.plan", "PlanStatus")),
        "reason": _maybe_text(),
        "branch": _maybe_text(),
        "branch_posture": _maybe_text(),
        "default_branch": _maybe_text(),
        "gain_vs_default": Number(lo=0.0, nullable=True),
        **{
            f"error_{k}_mm": _mm()
            for k in ("before_max", "before_rms", "after_max", "after_rms", "after_closed_form_max")
        },
        "numerical_floor_mm": Number(unit="mm", lo=0.0, lo_open=True),
        "below_numerical_floor": ListOf(item=Text()),
        "duration_s": _seconds(nullable=True),
        "duration_note": _maybe_text(),
        "duration_time_optimal_s": _seconds(nullable=True),
        "duration_time_optimal_method": _maybe_text(),
        "dynamic_compensation": _DYNAMIC_HEADLINE,
    }
)

_PROVENANCE = Table(
    fields={
        "compplan_version": Text(),
        "command_line": _maybe_text(),
        "date_utc": Text(),
        "inputs": ListOf(
            item=Table(
                fields={
                    "role": Text(),
                    "name": _maybe_text(),
                    "path": _maybe_text(),
                    "sha256": _maybe_text(**_SHA256),
                    "note": _maybe_text(),
                }
            )
        ),
    }
)

_DYNAMIC = Table(
    fields={
        "status": Text(choices=_statuses("planner.dynamic", "DynamicStageStatus")),
        "reason": _maybe_text(),
        "passes": Number(lo=0, integer=True, nullable=True),
        "limit_scale": MapOf(item=Number(lo=0.0, lo_open=True), name="limit"),
        "smoothing_s": _seconds(nullable=True),
        "smoothing_edge_s": _seconds(nullable=True),
        "smoothing_blend_s": _seconds(nullable=True),
        "predicted_tcp_error": MapOf(
            item=Table(fields={k: _mm() for k in ("motion_max_mm", "motion_rms_mm", "rest_max_mm")}), name="case"
        ),
        "mismatch": ListOf(
            item=Table(
                fields={
                    "stiffness_factor": Number(lo=0.0, lo_open=True),
                    "payload_factor": Number(lo=0.0),
                    "static_motion_max_mm": _mm(),
                    "static_dynamic_motion_max_mm": _mm(),
                    "gain": Number(lo=0.0, nullable=True),
                }
            )
        ),
        "definition": _maybe_text(),
        "assumptions": _maybe_text(),
        "file": Text(file_name=True),
    },
    nullable=True,
)

_PROGRAM = Table(
    fields={
        "file": Text(),
        "kind": Text(),
        "units_note": _maybe_text(),
        "n_waypoints": Number(lo=1, integer=True),
        "n_lines": Number(lo=0, integer=True),
        "n_stops": Number(lo=0, integer=True),
        "dwell_s": _seconds(),
        "path_tolerance_mm": Number(unit="mm", lo=0.0, nullable=True),
        "path_tolerance_source": _maybe_text(),
        "cutting_length_m": Number(unit="m", lo=0.0),
        "workpiece": Table(
            fields={
                "xyz_m": Vector(n=3, item=Number(unit="m"), need=_REPORT),
                "rpy_rad": Vector(n=3, item=Number(unit="rad"), need=_REPORT),
            },
            need=_REPORT,
        ),
        "feed": MapOf(
            item=Table(
                fields={
                    "programmed_time_s": _seconds(),
                    "cutting_time_s": _seconds(nullable=True),
                    "cutting_time_over_programmed": Number(lo=0.0, nullable=True),
                    "duration_s": _seconds(),
                    "peak_feed_ratio": Number(lo=0.0, nullable=True),
                    "n_stretches": Number(lo=0, integer=True, nullable=True),
                    "slowed_lines": ListOf(item=Row(items=(Number(lo=0, integer=True), Number(lo=0.0)))),
                    # the slowed lines by cause and the path deviation: optional (the report draws a summary
                    # written before them with one kind of slowed line and no deviation)
                    "slowed_by_limit": ListOf(
                        item=Row(
                            items=(
                                Number(lo=0, integer=True),
                                Number(lo=0.0),
                                Number(lo=1, integer=True),
                                Text(choices=LIMIT_KEYS),
                            )
                        ),
                    ),
                    "n_lines_slowed_by_neighbours": Number(lo=0, integer=True),
                    "path_deviation_mm": Number(unit="mm", lo=0.0, nullable=True),
                }
            ),
            name="method",
        ),
    },
    nullable=True,
)

_ERROR_MM = Table(fields={"max": Number(unit="mm", lo=0.0), "rms": Number(unit="mm", lo=0.0)})


def _range_of(unit: str) -> Table:
    """``{"min", "max"}`` over the cutting waypoints (null: none cut)."""
    return Table(fields={"min": Number(unit=unit, lo=0.0), "max": Number(unit=unit, lo=0.0)}, nullable=True)


#: The predicted cut (``[material]`` + ``[stock]``, :func:`planner.plan_cut.cut_summary`).
_CUT = Table(
    fields={
        "cutter": Table(
            fields={
                "shape": Text(choices=("flat", "ball", "bull_nose")),
                "diameter": Number(unit="m", lo=0.0),
                "flutes": Number(lo=1, integer=True),
                "corner_radius": Number(unit="m", lo=0.0),
                "helix_deg": Number(unit="deg"),
            }
        ),
        "material": Table(fields={"name": Text(), "source": Text()}),
        "stock_volume_mm3": Number(unit="mm^3", lo=0.0),
        "removed_mm3": Number(unit="mm^3", lo=0.0),
        "resolution_mm": Number(unit="mm", lo=0.0),
        "cutting_waypoints": Number(lo=0, integer=True),
        "milling_codes": ListOf(item=Text()),
        "force_N": Table(
            fields={
                "max": Number(unit="N", lo=0.0),
                "max_line": Number(lo=0, integer=True),
                "mean_cutting": Number(unit="N", lo=0.0),
                "peak_max": Number(unit="N", lo=0.0),
            }
        ),
        "error_mm": Table(
            fields={
                "uncompensated": _ERROR_MM,
                "compensated": _ERROR_MM,
                "stand_in_compensated": _ERROR_MM,
            }
        ),
        "spindle_rpm": _range_of("rev/min"),
        "feed_per_tooth_mm": _range_of("mm"),
        "stand_in": Table(
            fields={
                "frame": Text(choices=("tool", "base")),
                "F_N": Vector(n=3, item=Number(unit="N")),
                "M_Nm": Vector(n=3, item=Number(unit="N m")),
            }
        ),
        "warnings": ListOf(item=Text()),
    }
)


#: Every key of ``summary.json`` that report, export and track read (see the module docstring).
SUMMARY = Table(
    fields={
        "command": Text(choices=RUN_COMMANDS, need=_REPORT),
        "plan_status": Text(choices=_statuses("planner.plan", "PlanStatus"), need=_EXPORT),
        "reason": _maybe_text(),
        "scenario": Text(),
        "problem": Table(
            fields={
                "name": Text(),
                "cell": External(
                    reader=_cell,
                    what="the problem's cell: clearance and objects (docs/problem-file.md, [cell])",
                    errors=(InputError,),
                    nullable=True,
                ),
            }
        ),
        "robot": Text(),
        "robot_file": External(
            reader=_robot_file,
            what="the robot as a robot-file table (docs/robot-file.md)",
            errors=(InputError,),
            need=_TRACK,
        ),
        "headline": _HEADLINE,
        "provenance": _PROVENANCE,
        "wrench": Table(
            fields={
                "frame": Text(choices=("base", "tool")),
                "point": Text(),
                "F_N": Vector(n=3, item=Number(unit="N")),
                "M_Nm": Vector(n=3, item=Number(unit="N*m")),
                "per_waypoint": Flag(),
            }
        ),
        "payload": Table(
            fields={
                "mass_kg": Number(unit="kg", lo=0.0),
                "com_m_tcp_frame": Vector(n=3, item=Number(unit="m")),
            },
            nullable=True,
        ),
        "model": Table(
            fields={
                "file": _maybe_text(),
                "sha256": _maybe_text(**_SHA256),
                "identified": Flag(),
                "effects": ListOf(item=Text()),
            }
        ),
        "n_waypoints": Number(lo=1, integer=True),
        "limits": Table(
            fields={
                **{
                    k: Vector(n=N_JOINTS, item=Number(unit=u, lo=0.0, lo_open=True), need=_EXPORT)
                    for k, u in zip(LIMIT_KEYS, ("rad/s", "rad/s^2", "rad/s^3"))
                },
                "q_min": Vector(n=N_JOINTS, item=Number(unit="rad"), need=_EXPORT),
                "q_max": Vector(n=N_JOINTS, item=Number(unit="rad"), need=_EXPORT),
            },
            rules=(_limits_ordered,),
            need=_EXPORT,
        ),
        "warnings": ListOf(item=Text()),
        "model_sigma": Table(
            fields={
                "available": Flag(),
                "reason": Text(),
                "frame": Text(choices=("base",)),
                "n_evaluated": Number(lo=0, integer=True),
                "mean_m": Number(unit="m", lo=0.0, nullable=True),
                "max_m": Number(unit="m", lo=0.0, nullable=True),
                "max_waypoint": Number(lo=0, integer=True, nullable=True),
                "n_outside_range": Number(lo=0, integer=True),
                "outside_range": ListOf(item=Table(fields={"waypoint": Number(lo=0, integer=True), "joints": Text()})),
                "excluded": ListOf(
                    item=Table(
                        fields={
                            "name": Text(),
                            "effect": Text(),
                            "std_ratio": Number(lo=0.0),
                            "through_load": Flag(),
                        }
                    )
                ),
                "text": Text(),
            },
            nullable=True,
        ),
        "branches": MapOf(item=_BRANCH_ENTRY, name="branch"),
        "branch_labels": ListOf(item=Text()),
        "rejected_branches": MapOf(item=Text(), name="branch"),
        "default_branch": _maybe_text(),
        "chosen_branch": _maybe_text(),
        "branch": _maybe_text(),
        "gain": Table(
            fields={"vs_default": Number(lo=0.0, nullable=True), "vs_best_analytic": Number(lo=0.0, nullable=True)}
        ),
        "error_before": _ERROR_STATS,
        "error_after": Table(fields={"closed_form": _ERROR_STATS, "exact": _ERROR_STATS}, nullable=True),
        "status": Table(
            fields={
                k: Text(choices=_statuses("problems.compensation", "CompensationStatus"))
                for k in ("closed_form", "exact")
            }
        ),
        # a run of one timing method written before the per-method tables: a number / one table
        "duration_s": Either(
            first=_seconds(),
            second=MapOf(item=_seconds(), name="method"),
            pick=lambda v: int(isinstance(v, Mapping)),
        ),
        "limit_ratio": Either(
            first=_RATIOS,
            second=MapOf(item=_RATIOS, name="method"),
            pick=lambda v: int(not (isinstance(v, Mapping) and any(k in v for k in LIMIT_KEYS))),
        ),
        "timing": MapOf(item=_TIMING_ENTRY, name="method", need=_EXPORT),
        "controller_trajectory": Text(key_of="timing", nullable=True, need=_EXPORT),
        "dynamic_compensation": _DYNAMIC,
        "program": _PROGRAM,
        "cut": _CUT,
    }
)


# ------------------------------------------------------------------------------------- reading
def summary_refusal(command: str, file: Path | str, exc: Refused) -> SummaryError:
    """The one-line error of a key that does not fit (``command: file: key = value; expected ...``)."""
    if exc.detail:
        return SummaryError(f"{command}: {file}: {exc.detail}")
    key = dotted(exc.path)
    if exc.missing:
        return SummaryError(f"{command}: {file}: key {key} missing; expected {exc.expected}")
    return SummaryError(f"{command}: {file}: {key} = {shown(exc.value)}; expected {exc.expected}")


def read_summary(folder: str | Path, command: str) -> dict[str, Any]:
    """The ``summary.json`` of run folder ``folder``, checked against :data:`SUMMARY` for
    ``command`` (one of :data:`COMMANDS`: the keys it needs must be there).

    Returns
    -------
    dict
        The JSON content, unchanged (keys not declared included).

    Raises
    ------
    SummaryError
        The folder or its summary.json is missing, not UTF-8 JSON, not an object, the summary of
        another command, or a key does not fit its declaration: the message names the file, the
        key path, the value (shortened) and what was expected.
    """
    assert command in COMMANDS, command
    folder = Path(folder)
    if not folder.is_dir():
        raise SummaryError(
            f"{command}: RUN_DIR {folder}: no such folder; expected the output folder of compplan plan or demo"
        )
    path = folder / "summary.json"
    if not path.is_file():
        raise SummaryError(f"{command}: {path} not found; expected the output folder of compplan plan or demo")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:  # (RecursionError: nested too deep)
        raise SummaryError(f"{command}: {path}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise SummaryError(
            f"{command}: {path}: top level is {shown(doc)}; expected an object (the summary of compplan plan or demo)"
        )
    if doc.get("command") == "place":
        raise SummaryError(
            f"{command}: {path} is a placement study's summary (command 'place'); expected the output folder "
            "of compplan plan or demo"
            + (
                " (compplan place writes its report itself: run it again without --no-report)"
                if command == "report"
                else ""
            )
        )
    try:
        check(SUMMARY, doc, (), Ctx(command=command, root=doc))
    except Refused as exc:
        raise summary_refusal(command, path, exc) from None
    return doc
