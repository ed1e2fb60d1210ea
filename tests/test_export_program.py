"""Exports that cannot fail silently on the robot (issue 34, ``docs/export.md``).

A program plan (a small G-code part, ``tests/test_program_path.py``, planned at 2 ms) exported to
every format at its controller's period: written, with one change line each on stdout, or refused
with one line naming the option and what to give, nothing written and the run untouched.  A streamed
URScript needs a valid ``stream_host``; an export that would slow a program plan down (its programmed
feed changed) is refused unless ``slow_down=yes``, naming the ``[limits]`` scale that plans the
program for that controller: what the controller runs is checked against the robot's own limits,
so a plan made with that headroom exports at its feed.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from planner.cli import main
from planner.commands.export import print_changes
from planner.export import ExportData, ExportError, ExportLimitError, build_export, data_from_run, network_host
from planner.export.headroom import HEADROOM_MARGIN
from tests.test_export import NUM, bang_data, small_data
from tests.test_program_path import PROBLEM, PROGRAM

#: The plan's period (the problem's ``[timing] dt``), s: the e-series servoj period.
PLAN_DT_S = 0.002
#: A one-line error, no traceback.
ERROR = re.compile(r"\Acompplan: error: [^\n]+\n\Z")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """``compplan plan`` of a 13-move G-code part at 2 ms (about 7,400 samples, 15 s)."""
    base = tmp_path_factory.mktemp("program")
    (base / "part.ngc").write_text(PROGRAM)
    (base / "p.toml").write_text(PROBLEM.format(file="part.ngc"))
    out = base / "run"
    assert main(["plan", str(base / "p.toml"), "--out", str(out), "--no-report", "--no-figures"]) == 0
    return out


def _digest(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def _export(run: Path, fmt: str, out: Path, *sets: str) -> int:
    return main(["export", str(run), "--format", fmt, "--out", str(out), *(a for s in sets for a in ("--set", s))])


def _files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


# ------------------------------------------------------------------ streamed URScript
def test_a_streamed_urscript_without_a_host_is_refused(run, tmp_path, capsys):
    """7,429 servoj setpoints, more than max_motions: no stream_host, no program opening a socket to ""."""
    assert _export(run, "urscript", tmp_path / "o" / "p") == 2
    cap = capsys.readouterr()
    assert ERROR.match(cap.err) and not cap.out, cap.err
    for words in ("more than max_motions 2000", "stream_host is not set", "--set stream_host=IP", "--set max_motions="):
        assert words in cap.err, words
    assert "--set period=0.008" in cap.err  # the self-contained program this size allows
    assert not _files(tmp_path / "o")


@pytest.mark.parametrize("host", ["999.1.1.1", "10.0.0.256", "1.2.3", "pc_1", "-pc", "pc.123", "a..b", 'pc");halt'])
def test_a_streamed_urscript_with_a_bad_host_is_refused(host, run, tmp_path, capsys):
    assert _export(run, "urscript", tmp_path / "o" / "p", f"stream_host={host}") == 2
    err = capsys.readouterr().err
    assert ERROR.match(err), err
    assert f"stream_host = {host!r}" in err and "expected" in err and "4 numbers 0-255" in err
    assert not _files(tmp_path / "o")


@pytest.mark.parametrize("host", ["10.0.0.2", "fe80::1", "pc-7.lab.example"])
def test_a_streamed_urscript_with_a_good_host_is_written_and_says_so(host, run, tmp_path, capsys):
    assert _export(run, "urscript", tmp_path / "p", f"stream_host={host}", "stream_port=50123") == 0
    out = capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.script", "p_stream.txt"]
    assert f'socket_open("{host}", 50123, "compplan_stream")' in (tmp_path / "p.script").read_text()
    assert f"urscript: streamed from {host}:50123: 7429 servoj setpoints" in out
    assert len((tmp_path / "p_stream.txt").read_text().splitlines()) == 7429


def test_a_short_urscript_is_one_self_contained_program_and_says_so(run, tmp_path, capsys):
    """At the CB3 period the same plan fits in one program: no host needed, the choice said."""
    assert _export(run, "urscript", tmp_path / "p", "period=0.008") == 0
    out = capsys.readouterr().out.splitlines()
    assert [p.name for p in tmp_path.iterdir()] == ["p.script"]
    assert "socket_open" not in (tmp_path / "p.script").read_text()
    assert (
        out[1]
        == "urscript: resampled from 2 ms to the servoj period 8 ms (the quintic through the samples): 1858 setpoints"
    )
    assert out[2] == "urscript: one self-contained program: 1858 servoj motions, within max_motions 2000"


@pytest.mark.parametrize("host", ["192.168.1.10", "::1", "fe80::1", "localhost", "pc-1.lab", "a" * 63 + ".b"])
def test_good_hosts(host):
    assert network_host("stream_host")(host) == host


@pytest.mark.parametrize(
    "host", ["999.1.1.1", "256.0.0.1", "1.2.3.4.5", "a" * 64, "x.-y", "pc 1", "::g", "a." * 127 + "b"]
)
def test_bad_hosts_name_the_option_the_value_and_what_is_expected(host):
    with pytest.raises(ExportError, match=r"export option stream_host = .*: .*expected .*(IPv4|4 numbers 0-255)"):
        network_host("stream_host")(host)


# ------------------------------------------------------------------ a program's feed
def test_a_program_export_that_would_change_the_feed_is_refused_by_default(run, tmp_path, capsys):
    """ROS 2's quintic through the 2 ms samples is over the jerk limit: slowing down would run the
    program below its feed, so the default refuses; ``slow_down=yes`` accepts it and says so."""
    for how in ((), ("slow_down=auto",)):
        assert _export(run, "ros2", tmp_path / "o" / "p", *how) == 2
        err = capsys.readouterr().err
        assert ERROR.match(err), err
        assert re.search(r"ros2: joint \d jerk .* is \S+x its limit", err)
        assert "refusing to slow a program plan down (x1.1" in err and "part.ngc below its programmed feed" in err
        assert "--set slow_down=yes" in err and "--format urscript" in err
        assert not _files(tmp_path / "o")
    assert _export(run, "ros2", tmp_path / "o" / "p", "slow_down=no") == 2
    assert "--set slow_down=yes slows it down, below the programmed feed of part.ngc" in capsys.readouterr().err
    assert _export(run, "ros2", tmp_path / "yes" / "p", "slow_down=yes") == 0
    out = capsys.readouterr().out.splitlines()
    m = re.fullmatch(
        r"ros2: slowed down x(" + NUM + r") \(\S+ s -> \S+ s\): joint \d jerk \S+x its limit at the plan's "
        r"timing; part.ngc below its programmed feed \(slow_down=yes\)",
        out[1],
    )
    assert m, out
    msg = yaml.safe_load((tmp_path / "yes" / "p.yaml").read_text())
    end = msg["points"][-1]["time_from_start"]
    data = data_from_run(run)
    assert end["sec"] + 1e-9 * end["nanosec"] == pytest.approx(float(m.group(1)) * data.t[-1], rel=1e-4)


def test_only_a_program_plan_is_refused_a_slow_down_by_default():
    """The same over-limit servoj export: a non-program plan is slowed down (the default kept), a
    program plan refused unless ``slow_down=yes``."""
    plain = bang_data()
    program = bang_data(program="part.ngc")
    assert build_export(plain, "urscript", Path("x"), {"period": 0.002}).status.value == "slowed"
    with pytest.raises(
        ExportLimitError, match=r"refusing to slow a program plan down .*plan --dt 0.002.*slow_down=yes"
    ):
        build_export(program, "urscript", Path("x"), {"period": 0.002})
    yes = build_export(program, "urscript", Path("x"), {"period": 0.002, "slow_down": "yes"})
    assert yes.status.value == "slowed" and yes.reason.startswith("slowed down x")
    assert "part.ngc below its programmed feed" in yes.changes[0]


# ------------------------------------------------------------------ every format at its controller's period
#: Each format at its controller's period or finest step (URScript: e-series 2 ms, CB3 8 ms).
AT_PERIOD = [
    ("urscript", ("period=0.002",)),
    ("urscript", ("period=0.002", "stream_host=10.0.0.2")),
    ("urscript", ("period=0.008",)),
    ("urscript_movej", ("step_s=0.008", "blend_radius=0.0005")),
    ("urscript_movej", ("step_s=0.008", "blend_radius=0.0005", "stream_host=10.0.0.2")),
    ("ros2", ()),
    ("ros2", ("slow_down=yes",)),
    ("rosbag2", ()),
    ("rapid", ("step_s=0.004",)),
    ("krl", ("step_s=0.012",)),
    ("krl", ("step_s=0.012", "motion=ptp")),
]


@pytest.mark.parametrize("fmt,sets", AT_PERIOD, ids=[f"{f}-{'-'.join(s)}" for f, s in AT_PERIOD])
def test_program_exports_at_the_controllers_period(fmt, sets, run, tmp_path, capsys):
    """Written whole with its change lines, or refused in one line with nothing written; the run's
    files never touched."""
    if fmt == "rosbag2":
        pytest.importorskip("rosbags")
    before = _digest(run)
    code = _export(run, fmt, tmp_path / "o" / "p", *sets)
    cap = capsys.readouterr()
    assert _digest(run) == before
    if code == 2:
        assert ERROR.match(cap.err) and cap.err.startswith(f"compplan: error: {fmt}: "), cap.err
        assert re.search(r"--set \w+=", cap.err), cap.err  # says which option writes it
        assert not _files(tmp_path / "o") and not cap.out
        return
    assert code == 0, cap.err
    assert "Traceback" not in cap.err and _files(tmp_path / "o")
    lines = cap.out.splitlines()
    assert lines[0].startswith(f"{fmt}: 7429 samples") and len(lines) >= 2
    assert all(ln.startswith(f"{fmt}: ") and len(ln) <= 200 for ln in lines[1:]), lines  # one short line each


def test_a_refused_export_leaves_what_was_there(run, tmp_path, capsys):
    """A refusal writes nothing: a file already at --out keeps its content."""
    (tmp_path / "p.yaml").write_text("mine\n")
    assert main(["export", str(run), "--format", "ros2", "--out", str(tmp_path / "p"), "--force"]) == 2
    capsys.readouterr()
    assert [p.name for p in tmp_path.iterdir()] == ["p.yaml"] and (tmp_path / "p.yaml").read_text() == "mine\n"


def test_plan_export_of_a_program_leaves_out_what_it_refuses(tmp_path, capsys):
    """``plan --export``: the refused format left out with a warning, the others written with their change lines."""
    (tmp_path / "part.ngc").write_text(PROGRAM)
    (tmp_path / "p.toml").write_text(PROBLEM.format(file="part.ngc"))
    argv = ["plan", str(tmp_path / "p.toml"), "--out", str(tmp_path / "run"), "--no-report", "--no-figures"]
    assert main([*argv, "--export", "ros2", "--export", "rapid"]) == 0
    cap = capsys.readouterr()
    assert "compplan: warning: --export ros2 not written: ros2: " in cap.err and "programmed feed" in cap.err
    assert "--export rapid: decimated to a MoveAbsJ every ~0.05 s" in cap.out
    assert (tmp_path / "run" / "part_rapid.mod").is_file() and not list((tmp_path / "run").glob("*ros2*"))


# ------------------------------------------------------------------ the change lines
def test_an_export_as_planned_says_it_changed_nothing(capsys):
    export = build_export(small_data(), "ros2", Path("x"))
    assert export.status.value == "ok" and export.changes == () and export.reason == "at the plan's timing"
    print_changes("ros2", export)
    assert capsys.readouterr().out == "ros2: unchanged: the plan's samples at its timing\n"


def test_the_change_lines_of_parts(capsys):
    """Split into parts: one line each, with the counts."""
    data = small_data()
    assert build_export(data, "ros2", Path("x"), {"max_points": 4}).changes == (
        "split into 4 JointTrajectory messages of at most 4 points (max_points): 16 points in all",
    )
    rapid = build_export(data, "rapid", Path("x"), {"step_s": 0.008, "max_targets": 5}).changes
    assert rapid == (
        "decimated to a MoveAbsJ every ~0.008 s: 16 of 16 samples, the controller's own motion between them",
        "split into 4 part modules of at most 5 targets (max_targets): 16 targets in all",
    )


def test_export_data_of_a_run_knows_its_program(run):
    assert data_from_run(run).program == "part.ngc"
    assert isinstance(small_data(), ExportData) and small_data().program == ""
    assert np.isclose(data_from_run(run).dt, PLAN_DT_S)


# ------------------------------------------------------------------ planning a program for its controller
#: The end of a program plan's refusal that names the ``[limits]`` scale to plan it with.
HEADROOM = re.compile(
    r"; or plan it for this controller: in the problem's \[limits\] set jerk_scale = (" + NUM + r") "
    r"\(what the controller runs reaches jerk (" + NUM + r")x the plan's limit on joint \d; "
)


def _headroom(err: str) -> tuple[float, float]:
    """The advised ``jerk_scale`` and the ratio of the controller's jerk to the plan's limit."""
    m = HEADROOM.search(err)
    assert m, err
    return float(m.group(1)), float(m.group(2))


@pytest.fixture(scope="module")
def planned_for_ros2(run, tmp_path_factory) -> tuple[Path, float]:
    """The same part planned again with the ``jerk_scale`` that ``run``'s ros2 refusal advises."""
    base = tmp_path_factory.mktemp("headroom")
    with pytest.raises(ExportLimitError) as refused:
        build_export(data_from_run(run), "ros2", base / "x")
    scale, _reach = _headroom(str(refused.value))
    (base / "part.ngc").write_text(PROGRAM)
    problem = PROBLEM.format(file="part.ngc").replace(
        "max_joint_step = 0.3", f"max_joint_step = 0.3\njerk_scale = {scale}"
    )
    (base / "p.toml").write_text(problem)
    out = base / "run"
    assert main(["plan", str(base / "p.toml"), "--out", str(out), "--no-report", "--no-figures"]) == 0
    return out, scale


def test_a_program_refusal_names_the_scale_that_plans_it_for_the_controller(run, tmp_path, capsys):
    """The quintic's jerk is r times the plan's limit: plan at 1 / (r (1 + margin)) of the robot's,
    rounded down to two digits, each quantity's scale for its own quantity."""
    assert _export(run, "ros2", tmp_path / "o" / "p") == 2
    err = capsys.readouterr().err
    scale, reach = _headroom(err)
    assert 1.2 < reach < 1.6  # the spline's overshoot where the jerk switches between samples
    assert scale == math.floor(100.0 / (reach * (1.0 + HEADROOM_MARGIN))) / 100.0
    assert "velocity_scale, acceleration_scale and jerk_scale each give headroom to their own quantity only" in err
    assert "instead of" not in err  # planned at the robot's own limits
    assert err.index("plan it for this controller") < err.index("--format urscript") < err.index("slow_down=yes")
    assert _export(run, "ros2", tmp_path / "o" / "p", "slow_down=no") == 2
    assert _headroom(capsys.readouterr().err) == (scale, reach)
    assert not _files(tmp_path / "o")


def test_a_program_planned_with_the_advised_scale_exports_to_ros2_at_its_feed(planned_for_ros2, tmp_path, capsys):
    """Its quintic still overshoots the plan's (lowered) jerk limit, but not the robot's: written as
    planned, no slow-down, the last point at the plan's duration."""
    folder, scale = planned_for_ros2
    s = json.loads((folder / "summary.json").read_text())
    robot_jerk = np.array([j["j_max"] for j in s["robot_file"]["joints"]])
    assert np.allclose(s["limits"]["jerk"], scale * robot_jerk)
    assert _export(folder, "ros2", tmp_path / "p") == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1] == "ros2: unchanged: the plan's samples at its timing", out
    data = data_from_run(folder)
    end = yaml.safe_load((tmp_path / "p.yaml").read_text())["points"][-1]["time_from_start"]
    assert end["sec"] + 1e-9 * end["nanosec"] == pytest.approx(data.t[-1], abs=1e-9)
    # checked against the plan's own limits instead, the same export would be refused
    own = replace(data, robot_v_max=None, robot_a_max=None, robot_j_max=None)
    with pytest.raises(ExportLimitError, match=r"jerk .* is 1\.\d+x its limit .*refusing to slow a program plan"):
        build_export(own, "ros2", tmp_path / "q")


def test_the_controllers_motion_is_checked_against_the_robots_limits():
    """A program plan made with headroom (its limits below the robot's): the quintic over the plan's
    jerk limit but within the robot's is written unchanged; without the robot's limits, refused."""
    plan = bang_data(program="part.ngc")
    with pytest.raises(ExportLimitError, match=r"jerk .*refusing to slow a program plan down") as refused:
        build_export(plan, "ros2", Path("x"))
    assert "set jerk to x0.6 of the plan's jerk limits (what the controller runs reaches jerk 1.563x" in str(
        refused.value
    )  # the robot's own limits not known: relative to the plan's
    headroom = replace(plan, robot_v_max=plan.v_max, robot_a_max=plan.a_max / 0.8, robot_j_max=plan.j_max / 0.5)
    export = build_export(headroom, "ros2", Path("x"))
    assert export.status.value == "ok" and export.changes == ()
    # verify_limits still holds the plan's samples to the plan's own limits
    assert headroom.plan_limit("jerk") is plan.j_max and np.allclose(headroom.robot_limit("jerk"), 2 * plan.j_max)


def test_a_motion_beyond_the_robots_limits_is_still_slowed_or_refused():
    """Limits above the robot's (a problem raising them): what the controller runs is held to the
    robot's, slowed down for a plan that is not a program, refused for a program naming the scale."""
    plain = bang_data(room=2.0)  # the quintic's jerk 1.563 / 2 of the plan's limit: within it
    assert build_export(plain, "ros2", Path("x")).status.value == "ok"
    robot = {"robot_v_max": plain.v_max, "robot_a_max": plain.a_max / 2.0, "robot_j_max": plain.j_max / 2.0}
    slowed = build_export(replace(plain, **robot), "ros2", Path("x"))
    assert slowed.status.value == "slowed" and re.fullmatch(
        r"slowed down x1\.\d+ \(0\.2 s -> \S+ s\): joint 5 jerk 1\.563x its limit at the plan's timing",
        slowed.changes[0],
    ), slowed.changes
    with pytest.raises(ExportLimitError) as refused:
        build_export(replace(plain, program="part.ngc", **robot), "ros2", Path("x"))
    assert re.search(r"set jerk_scale = 1\.2 instead of 2 \(", str(refused.value)), str(refused.value)


def test_export_data_of_a_run_knows_the_robots_own_limits(run, tmp_path):
    """From ``summary.json``'s ``robot_file`` (ur10's limits); without it, the plan's; a bad entry named."""
    data = data_from_run(run)
    s = json.loads((run / "summary.json").read_text())
    for key, name in (("v_max", "velocity"), ("a_max", "acceleration"), ("j_max", "jerk")):
        assert np.array_equal(data.robot_limit(name), [j[key] for j in s["robot_file"]["joints"]])
    copy = tmp_path / "run"
    copy.mkdir()
    (copy / "trajectory.csv").write_bytes((run / "trajectory.csv").read_bytes())
    del s["robot_file"]["joints"]
    (copy / "summary.json").write_text(json.dumps(s))
    old = data_from_run(copy)
    assert not old.robot_limits_known and old.robot_limit("jerk") is old.j_max
    s["robot_file"]["joints"] = [{"j_max": 40.0}] * 6
    (copy / "summary.json").write_text(json.dumps(s))
    with pytest.raises(ExportError, match=r"summary.json: robot_file.joints\[0\].v_max = None; expected a number > 0"):
        data_from_run(copy)
