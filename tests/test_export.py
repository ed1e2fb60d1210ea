"""Exports (``planner/export``, ``compplan export``, ``plan/demo --export``).

Every format is read back by a parser written here, independently of the writers (regular
expressions, PyYAML), and compared with the trajectory: positions to the printed precision
(:data:`POS_TOL_RAD`), times to :data:`TIME_TOL_S`, joint order, units (degrees for RAPID
and KRL) and the controller's sign and offset.  Golden files (``tests/golden/export``) pin
the text of each format for a small trajectory; ``COMPPLAN_UPDATE_GOLDEN=1`` rewrites them and
fails those tests (a run with it set never passes: review the diff, run again without it).
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from models.robot import load_robot
from planner.cli import main
from planner.export import EXPORT_FORMATS, ExportData, ExportError, export_files, verify_limits

GOLDEN = Path(__file__).parent / "golden" / "export"
#: Set to rewrite the golden files: the tests that do so fail (the run cannot pass with it set).
UPDATE_GOLDEN_ENV = "COMPPLAN_UPDATE_GOLDEN"
#: Positions: URScript prints 9 decimals of rad, ROS 2 12 significant digits, RAPID/KRL 6 of deg.
POS_TOL_RAD = 1e-8
#: Times: servoj's t and RAPID's \T print 6 decimals; ROS 2 nanoseconds.
TIME_TOL_S = 1e-6
FORMATS = ("urscript", "urscript_movej", "ros2", "rapid", "krl")
#: Options of the golden files and of the exports of a run: a movej list without blend stops at every
#: target, which a jerk-limited plan's motion is not (refused), so the movej golden file blends.
GOLDEN_OPTIONS = {"urscript_movej": {"blend_radius": 0.001}}
NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


# ------------------------------------------------------------------ independent parsers
def _floats(text: str) -> list[float]:
    return [float(v) for v in re.findall(NUM, text)]


def parse_urscript(text: str) -> dict:
    """def/end balance, then every movej / servoj as (q, keyword arguments)."""
    body = [ln.split("#", 1)[0].strip() for ln in text.splitlines()]
    body = [ln for ln in body if ln]
    assert re.fullmatch(r"def [A-Za-z_]\w*\(\):", body[0]) and body[-1] == "end", (body[0], body[-1])
    depth = 0
    for ln in body:
        assert ln.count("(") == ln.count(")") and ln.count("[") == ln.count("]"), ln
        depth += ln.endswith(":") - (ln == "end")
        assert depth >= 0, ln
    assert depth == 0
    moves = []
    for ln in body[1:-1]:
        m = re.fullmatch(r"(movej|servoj)\(\[([^\]]*)\], (.*)\)", ln)
        if m is None:
            assert re.fullmatch(r"stopj\(" + NUM + r"\)", ln), ln
            continue
        kw = dict(re.fullmatch(r"(\w+)=(" + NUM + ")", a.strip()).groups() for a in m.group(3).split(","))
        moves.append((m.group(1), np.array(_floats(m.group(2))), {k: float(v) for k, v in kw.items()}))
    return {"moves": moves}


def parse_rapid(text: str) -> dict:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.strip().startswith("!")]
    assert lines[0].startswith("MODULE ") and lines[-1] == "ENDMODULE"
    assert lines.count("PROC main()") == 1 and lines.count("ENDPROC") == 1
    targets = {}
    for name, axes, ext in re.findall(r"CONST jointtarget (\w+):=\[\[([^\]]*)\],\[([^\]]*)\]\];", text):
        targets[name] = np.array(_floats(axes))
        assert len(targets[name]) == 6 and len(ext.split(",")) == 6
    moves = re.findall(r"MoveAbsJ (\w+)\\NoEOffs, v(\d+)(?:\\T:=(" + NUM + r"))?, (fine|z\d+), tool0;", text)
    assert len(moves) == sum(ln.startswith("MoveAbsJ") for ln in lines)
    return {"targets": targets, "moves": [(n, float(t) if t else None, z) for n, _v, t, z in moves]}


def parse_krl(src: str, dat: str) -> dict:
    s = [ln.strip() for ln in src.splitlines() if ln.strip() and not ln.strip().startswith(";")]
    d = [ln.strip() for ln in dat.splitlines() if ln.strip() and not ln.strip().startswith(";")]
    name = re.fullmatch(r"DEF (\w+)\( \)", s[2]).group(1)
    assert s[:2] == ["&ACCESS RVP", "&REL 1"] and s[-1] == "END"
    assert d[2] == f"DEFDAT {name} PUBLIC" and d[-1] == "ENDDAT"
    points = {}
    for pname, body in re.findall(r"DECL E6AXIS (\w+)=\{([^}]*)\}", dat):
        kv = dict((k, float(v)) for k, v in re.findall(r"([AE]\d) (" + NUM + ")", body))
        points[pname] = np.array([kv[f"A{i}"] for i in range(1, 7)])
    moves, vel, parts, end = [], {}, [], None
    depth = 0
    for ln in s:
        depth += ln == "PTP_SPLINE"
        depth -= ln == "ENDSPLINE"
        assert depth in (0, 1), ln
        m = re.fullmatch(r"TIME_BLOCK PART = (" + NUM + ")", ln)
        if m:
            parts.append(float(m.group(1)))
        m = re.fullmatch(r"TIME_BLOCK END = (" + NUM + ")", ln)
        if m:
            end = float(m.group(1))
        m = re.fullmatch(r"\$(VEL|ACC)_AXIS\[(\d)\]=(\d+)", ln)
        if m:
            vel[(m.group(1), int(m.group(2)))] = int(m.group(3))
            assert 1 <= int(m.group(3)) <= 100
        m = re.fullmatch(r"\$APO.CPTP=(\d+)", ln)
        if m:
            assert 1 <= int(m.group(1)) <= 100
        m = re.fullmatch(r"S?PTP (\w+)( C_PTP)?", ln)
        if m:
            moves.append(m.group(1))
            assert m.group(1) in points
    assert depth == 0
    times = None
    if parts:
        assert end is not None and abs(sum(parts) - end) < 1e-5 and len(parts) == len(moves) - 1
        times = np.cumsum([0.0] + parts)
    return {"name": name, "points": points, "moves": moves, "axis_percent": vel, "times": times}


# ------------------------------------------------------------------ a small trajectory
def small_data(**kw) -> ExportData:
    """0.12 s quintic rest-to-rest move at 8 ms, a controller map with a sign and an offset."""
    dt = 0.008
    t = np.arange(16) * dt
    T = t[-1]
    s = t / T
    p = 10 * s**3 - 15 * s**4 + 6 * s**5
    pd = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    pdd = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    pddd = (60 - 360 * s + 360 * s**2) / T**3
    q0 = np.array([0.1, -1.2, 1.3, -0.4, 1.5707963, 0.2])
    dq = np.array([0.02, -0.03, 0.05, 0.01, -0.02, 0.04])
    args = dict(
        name="small",
        robot="ur5",
        joint_names=tuple(f"j{i}" for i in range(1, 7)),
        t=t,
        q=q0 + np.outer(p, dq),
        qd=np.outer(pd, dq),
        qdd=np.outer(pdd, dq),
        qddd=np.outer(pddd, dq),
        dt=dt,
        v_max=np.full(6, 3.14),
        a_max=np.full(6, 21.0),  # joint 3 peaks at 20.04 rad/s^2 between the samples (20 at them)
        j_max=np.full(6, 2000.0),
        q_min=np.full(6, -2 * math.pi),
        q_max=np.full(6, 2 * math.pi),
        sign=np.array([1, -1, 1, 1, 1, 1.0]),
        offset=np.radians([0, 0, 90, 0, 0, -180.0]),
        source="test",
    )
    args.update(kw)
    return ExportData(**args)


def bang_data(room: float = 1.0, tau: float = 0.05, jerk: float = 400.0, **kw) -> ExportData:
    """A rest-to-rest move at 8 ms whose jerk is +J, -J, -J, +J for ``tau`` each (switching between
    the samples), integrated exactly; the jerk and acceleration limits are its peaks times ``room``
    (``kw``: other fields of :func:`small_data`)."""
    h = 1e-5  # integration step: a divisor of tau and of the period, so the switches and samples fall on it
    n = int(round(4 * tau / h))
    sign = np.where((np.arange(n) < n // 4) | (np.arange(n) >= 3 * n // 4), 1.0, -1.0)
    scale = np.array([1.0, -0.6, 0.8, 0.3, -0.5, 0.7])
    q, v, a = np.array([0.1, -1.2, 1.3, -0.4, 1.5707963, 0.2]), np.zeros(6), np.zeros(6)
    rows, every = [], int(round(0.008 / h))
    for k in range(n + 1):
        j = jerk * scale * (sign[k] if k < n else 0.0)
        if k % every == 0 or k == n:
            rows.append(np.r_[k * h, q, v, a, j])
        if k < n:  # exact over a step of constant jerk
            q, v, a = q + v * h + a * h**2 / 2 + j * h**3 / 6, v + a * h + j * h**2 / 2, a + j * h
    r = np.array(rows)
    return small_data(
        t=r[:, 0],
        q=r[:, 1:7],
        qd=r[:, 7:13],
        qdd=r[:, 13:19],
        qddd=r[:, 19:25],
        **{"a_max": jerk * tau * np.abs(scale) * room * 1.0001, "j_max": jerk * np.abs(scale) * room, **kw},
    )


@pytest.fixture
def fixed_version(monkeypatch):
    import planner.provenance as prov

    monkeypatch.setattr(prov, "version", lambda: "0.0.0-golden")


@pytest.mark.parametrize("fmt", FORMATS)
def test_golden_files(fmt, fixed_version):
    """The text of each format equals its golden file.  ``COMPPLAN_UPDATE_GOLDEN=1`` rewrites the
    files instead and fails the test, naming them: review the diff, then run again without it (a
    run with the variable set never passes)."""
    data = small_data()
    files = export_files(data, fmt, Path(f"golden_{fmt}"), GOLDEN_OPTIONS.get(fmt))
    if os.environ.get(UPDATE_GOLDEN_ENV):
        written = []
        for path, text in files.items():
            golden = GOLDEN / path.name
            if not golden.is_file() or golden.read_text(encoding="utf-8") != text:
                golden.write_text(text, encoding="utf-8")
                written.append(golden.name)
        pytest.fail(
            f"{UPDATE_GOLDEN_ENV} is set: golden files of {fmt} "
            + (f"rewritten: {', '.join(written)}" if written else "unchanged")
            + f"; check them (git diff {GOLDEN}) and run the tests without {UPDATE_GOLDEN_ENV}"
        )
    for path, text in files.items():
        golden = GOLDEN / path.name
        assert golden.is_file(), f"missing golden file {golden} ({UPDATE_GOLDEN_ENV}=1 writes it)"
        assert text == golden.read_text(encoding="utf-8"), f"{path.name} differs from {golden}"


def _ctrl(data: ExportData) -> np.ndarray:
    """Controller angles computed here: sign * q + offset (rad)."""
    return data.q * data.sign + data.offset


def test_urscript_round_trip(fixed_version):
    data = small_data()
    text = next(iter(export_files(data, "urscript", Path("p"), {"lookahead_time": 0.05, "gain": 500}).values()))
    moves = parse_urscript(text)["moves"]
    assert moves[0][0] == "movej" and all(m[0] == "servoj" for m in moves[1:])
    q = np.array([m[1] for m in moves])
    assert q.shape == data.q.shape
    np.testing.assert_allclose(q, _ctrl(data), atol=POS_TOL_RAD)
    for _, _, kw in moves[1:]:
        assert kw == {"t": pytest.approx(data.dt, abs=TIME_TOL_S), "lookahead_time": 0.05, "gain": 500.0}
    # CB3: resampled to 8 ms from a 2 ms trajectory keeps the positions at those times
    fine = small_data(dt=0.002, t=np.arange(61) * 0.002)
    t = fine.t / fine.t[-1]
    pos = 10 * t**3 - 15 * t**4 + 6 * t**5
    dq = np.array([0.02, -0.03, 0.05, 0.01, -0.02, 0.04])
    vel = (30 * t**2 - 60 * t**3 + 30 * t**4) / fine.t[-1]
    acc = (60 * t - 180 * t**2 + 120 * t**3) / fine.t[-1] ** 2
    fine = small_data(
        dt=0.002,
        t=np.arange(61) * 0.002,
        q=fine.q[0] + np.outer(pos, dq),
        qd=np.outer(vel, dq),
        qdd=np.outer(acc, dq),
        qddd=np.zeros((61, 6)),
        enforced=("velocity", "acceleration"),
    )
    text = next(iter(export_files(fine, "urscript", Path("p"), {"period": 0.008, "slow_down": "no"}).values()))
    moves = parse_urscript(text)["moves"]
    q = np.array([m[1] for m in moves])
    np.testing.assert_allclose(q, _ctrl(fine)[::4], atol=POS_TOL_RAD)
    assert all(m[2]["t"] == pytest.approx(0.008) for m in moves[1:])


def test_urscript_movej_round_trip(fixed_version):
    data = small_data()
    text = next(iter(export_files(data, "urscript_movej", Path("p"), {"step_s": 0.04, "blend_radius": 0.002}).values()))
    moves = parse_urscript(text)["moves"]
    idx = data.decimated(0.04)
    np.testing.assert_allclose(np.array([m[1] for m in moves]), _ctrl(data)[idx], atol=POS_TOL_RAD)
    times = np.cumsum([0.0] + [m[2]["t"] for m in moves[1:]])
    np.testing.assert_allclose(times, data.t[idx], atol=TIME_TOL_S * len(idx))
    assert [m[2]["r"] for m in moves[1:]] == [0.002] * (len(idx) - 2) + [0.0]


def test_ros2_round_trip(fixed_version):
    data = small_data()
    msg = yaml.safe_load(next(iter(export_files(data, "ros2", Path("p")).values())))
    assert msg["joint_names"] == list(data.joint_names)
    pts = msg["points"]
    assert len(pts) == len(data.t)
    np.testing.assert_allclose([p["positions"] for p in pts], _ctrl(data), atol=POS_TOL_RAD)
    np.testing.assert_allclose([p["velocities"] for p in pts], data.qd * data.sign, atol=1e-10)
    np.testing.assert_allclose([p["accelerations"] for p in pts], data.qdd * data.sign, rtol=1e-10, atol=1e-10)
    t = [p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in pts]
    np.testing.assert_allclose(t, data.t, atol=TIME_TOL_S)


def test_rapid_round_trip(fixed_version):
    data = small_data()
    parsed = parse_rapid(next(iter(export_files(data, "rapid", Path("p"), {"step_s": 0.024}).values())))
    idx = data.decimated(0.024)
    q = np.radians([parsed["targets"][n] for n, _t, _z in parsed["moves"]])
    np.testing.assert_allclose(q, _ctrl(data)[idx], atol=POS_TOL_RAD)
    times = np.cumsum([0.0] + [t for _n, t, _z in parsed["moves"][1:]])
    np.testing.assert_allclose(times, data.t[idx], atol=TIME_TOL_S * len(idx))
    assert parsed["moves"][0][2] == parsed["moves"][-1][2] == "fine"


def test_krl_round_trip(fixed_version):
    data = small_data()
    files = export_files(data, "krl", Path("out/p.src"), {"step_s": 0.024})
    assert sorted(p.name for p in files) == ["p.dat", "p.src"]
    by = {p.suffix: t for p, t in files.items()}
    parsed = parse_krl(by[".src"], by[".dat"])
    idx = data.decimated(0.024)
    q = np.radians([parsed["points"][n] for n in parsed["moves"]])
    np.testing.assert_allclose(q, _ctrl(data)[idx], atol=POS_TOL_RAD)
    np.testing.assert_allclose(parsed["times"], data.t[idx], atol=TIME_TOL_S * len(idx))
    # motion ptp: the velocity percentages cover each segment's peak, ceil(100 |qd| / v_max)
    files = export_files(data, "krl", Path("out/p.src"), {"step_s": 0.024, "motion": "ptp"})
    by = {p.suffix: t for p, t in files.items()}
    parsed = parse_krl(by[".src"], by[".dat"])
    assert parsed["times"] is None
    np.testing.assert_allclose(
        np.radians([parsed["points"][n] for n in parsed["moves"]]), _ctrl(data)[idx], atol=POS_TOL_RAD
    )
    last = int(np.ceil(100 * np.abs(data.qd[idx[-2] : idx[-1] + 1]).max(axis=0)[2] / data.v_max[2] - 1e-9))
    assert parsed["axis_percent"][("VEL", 3)] == max(1, last)
    with pytest.raises(ExportError, match="motion = 'lin'"):
        export_files(data, "krl", Path("p.src"), {"motion": "lin"})


def test_verify_limits_names_the_joint_sample_and_limit():
    data = small_data()
    verify_limits(data, "here")
    qd = data.qd.copy()
    qd[5, 2] = 3.5
    with pytest.raises(ExportError, match=r"here: joint 3 velocity 3.5 rad/s at sample 5 .* above its limit \(3.14"):
        verify_limits(small_data(qd=qd), "here")
    q = data.q.copy()
    q[0, 0] = 7.0
    with pytest.raises(ExportError, match="joint 1 position 7 rad at sample 0 .* above q_max"):
        verify_limits(small_data(q=q), "here")
    qddd = data.qddd * 100
    with pytest.raises(ExportError, match="jerk"):
        verify_limits(small_data(qddd=qddd), "here")
    verify_limits(small_data(qddd=qddd, enforced=("velocity", "acceleration")), "toppra: jerk not enforced")
    t = data.t.copy()
    t[7] += 0.001
    with pytest.raises(ExportError, match="sample 7 .* expected the period"):
        verify_limits(small_data(t=t), "here")
    # issue 24: a jump of the positions the rate columns do not show (0.5 rad in one sample)
    q = data.q.copy()
    q[6:, 1] += 0.5
    with pytest.raises(ExportError, match=r"joint 2 velocity by finite differences .* over samples 5 to 6"):
        verify_limits(small_data(q=q), "here")


def test_unknown_format_and_bad_options_are_refused():
    data = small_data()
    with pytest.raises(ExportError, match="unknown format 'fanuc'"):
        export_files(data, "fanuc", Path("x"))
    with pytest.raises(ExportError, match=r"no option\(s\) \['lookahead'\]"):
        export_files(data, "urscript", Path("x"), {"lookahead": 0.1})
    with pytest.raises(ExportError, match=r"gain = 50: expected a number in \[100, 2000\]"):
        export_files(data, "urscript", Path("x"), {"gain": "50"})
    with pytest.raises(ExportError, match=r"period 0.001 s is outside"):
        export_files(small_data(dt=0.001, t=np.arange(16) * 0.001), "urscript", Path("x"))


# ------------------------------------------------------------------ from a run folder
ROBOT_WITH_CONTROLLER = """
[controller]
joint_sign = [1, -1, 1, 1, -1, 1]
joint_offset_deg = [0.0, 90.0, 0.0, -90.0, 0.0, 180.0]
"""


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    """A demo run (12 waypoints) on a UR5 whose robot file maps joints 2 and 5 and offsets three,
    with plan --export of every format."""
    base = tmp_path_factory.mktemp("export")
    from planner.provenance import builtin_robot_file

    robot = base / "ur5_ctrl.toml"
    text = Path(builtin_robot_file("ur5")).read_text(encoding="utf-8")
    start = text.index("[controller]")  # the file's own (identity) table, replaced by this one
    end = text.index("\n[", start + 1) + 1
    robot.write_text(text[:start] + text[end:] + ROBOT_WITH_CONTROLLER, encoding="utf-8")
    out = base / "run"
    argv = ["demo", "--points", "12", "--robot", str(robot), "--out", str(out), "--no-report"]
    for f in FORMATS:
        argv += ["--export", f]
    assert main(argv) == 0
    return out


def _trajectory_csv(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    a = np.array(rows[1:], dtype=float)
    return {h: a[:, i] for i, h in enumerate(rows[0])}


def _csv_controller_q(run: Path) -> tuple[np.ndarray, np.ndarray]:
    tr = _trajectory_csv(run / "trajectory.csv")
    q = np.column_stack([tr[f"q{i}"] for i in range(1, 7)])
    sign = np.array([1, -1, 1, 1, -1, 1.0])
    off = np.radians([0.0, 90.0, 0.0, -90.0, 0.0, 180.0])
    return tr["t"], q * sign + off


@pytest.mark.parametrize("fmt", FORMATS)
def _set(fmt: str) -> list[str]:
    """``--set`` arguments of :data:`GOLDEN_OPTIONS` for ``fmt``."""
    return [a for k, v in GOLDEN_OPTIONS.get(fmt, {}).items() for a in ("--set", f"{k}={v}")]


def _slow_factor(t_written: np.ndarray, t: np.ndarray, text: str) -> float:
    """How much slower than the plan an export runs (1 unless its header says it was slowed down)."""
    k = float(t_written[-1] / t[-1])
    m = re.search(r"slowed down x(" + NUM + ")", text)
    assert (m is None and k == pytest.approx(1.0, abs=1e-9)) or (m and k == pytest.approx(float(m.group(1)), abs=1e-4))
    return k


@pytest.mark.parametrize("fmt", FORMATS)
def test_export_of_a_run_matches_trajectory_csv(fmt, run_folder, tmp_path, capsys):
    out = tmp_path / f"prog_{fmt}"
    assert main(["export", str(run_folder), "--format", fmt, "--out", str(out), *_set(fmt)]) == 0
    t, qc = _csv_controller_q(run_folder)
    written = sorted(tmp_path.iterdir())
    texts = {p.suffix: p.read_text(encoding="utf-8") for p in written}
    if fmt == "urscript":
        moves = parse_urscript(texts[".script"])["moves"]
        np.testing.assert_allclose([m[1] for m in moves], qc, atol=POS_TOL_RAD)
        dt = json.loads((run_folder / "summary.json").read_text())["timing"]["jerk_optimal"]["dt"]
        assert all(abs(m[2]["t"] - dt) <= TIME_TOL_S for m in moves[1:])
    elif fmt == "ros2":
        msg = yaml.safe_load(texts[".yaml"])
        assert msg["joint_names"] == [
            "shoulder_pan_joint",
            "shoulder_lift_joint",
            "elbow_joint",
            "wrist_1_joint",
            "wrist_2_joint",
            "wrist_3_joint",
        ]
        np.testing.assert_allclose([p["positions"] for p in msg["points"]], qc, atol=POS_TOL_RAD)
        ts = np.array([p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in msg["points"]])
        k = _slow_factor(ts, t, texts[".yaml"])  # the same path, k times slower if the header says so
        np.testing.assert_allclose(ts, k * t, atol=TIME_TOL_S)
    else:
        if fmt == "urscript_movej":
            moves = parse_urscript(texts[".script"])["moves"]
            q, steps = np.array([m[1] for m in moves]), [m[2]["t"] for m in moves[1:]]
        elif fmt == "rapid":
            p = parse_rapid(texts[".mod"])
            q = np.radians([p["targets"][n] for n, _t, _z in p["moves"]])
            steps = [s for _n, s, _z in p["moves"][1:]]
        else:
            p = parse_krl(texts[".src"], texts[".dat"])
            q = np.radians([p["points"][n] for n in p["moves"]])
            steps = list(np.diff(p["times"]))
        if steps is not None:
            times = np.cumsum([0.0] + steps)
            k = np.rint(times / (t[1] - t[0])).astype(int)
            np.testing.assert_allclose(times, t[k], atol=TIME_TOL_S * len(k))
        else:
            k = np.array([int(np.argmin(np.abs(qc - qi).max(axis=1))) for qi in q])
            assert k[0] == 0 and k[-1] == len(t) - 1 and np.all(np.diff(k) > 0)
        np.testing.assert_allclose(q, qc[k], atol=POS_TOL_RAD)


def test_plan_export_equals_export_of_the_run(run_folder, tmp_path, capsys):
    """plan/demo --export (in memory) writes what compplan export writes from the folder; a format the
    export refuses at its default options (a movej list without blend) is left out of the run."""
    written = []
    for fmt in FORMATS:
        code = main(["export", str(run_folder), "--format", fmt, "--out", str(tmp_path / f"paper_4_4_{fmt}")])
        assert code == (2 if fmt == "urscript_movej" else 0), fmt
        written += [fmt] if code == 0 else []
    assert "blend_radius 0 stops the arm at every target" in capsys.readouterr().err
    assert not list(run_folder.glob("*urscript_movej*"))
    assert len(list(tmp_path.iterdir())) == len(written) + 1
    for p in tmp_path.iterdir():
        mine = (run_folder / p.name).read_text(encoding="utf-8")
        body = [ln for ln in p.read_text(encoding="utf-8").splitlines() if "generated by compplan" not in ln]
        assert body == [ln for ln in mine.splitlines() if "generated by compplan" not in ln], p.name


def _copy_run(run: Path, dst: Path) -> Path:
    shutil.copytree(run, dst)
    return dst


def test_a_trajectory_violating_a_limit_is_refused(run_folder, tmp_path, capsys):
    run = _copy_run(run_folder, tmp_path / "run")
    path = run / "trajectory.csv"
    rows = list(csv.reader(path.open(newline="")))
    col = rows[0].index("qd2")
    v2 = json.loads((run / "summary.json").read_text())["limits"]["velocity"][1]
    rows[5][col] = repr(1.5 * v2)
    with path.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
    out = tmp_path / "p.script"
    assert main(["export", str(run), "--format", "urscript", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "joint 2 velocity" in err and "at sample 4" in err and "refusing to export" in err
    assert not out.exists()


def test_a_trajectory_not_ok_is_refused(run_folder, tmp_path, capsys):
    run = _copy_run(run_folder, tmp_path / "run")
    s = json.loads((run / "summary.json").read_text())
    s["timing"][s["controller_trajectory"]]["status"] = "limit_exceeded"
    (run / "summary.json").write_text(json.dumps(s))
    out = tmp_path / "p.yaml"
    assert main(["export", str(run), "--format", "ros2", "--out", str(out)]) == 2
    assert "not ok" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--format", "ros2", "--out", "{tmp}/x.yaml"], "RUN_DIR required"),
        (["{tmp}/nope", "--format", "ros2", "--out", "{tmp}/x.yaml"], "no such folder"),
        (["{run}", "--format", "ros2", "--out", "{tmp}/x.json"], "ends in .yaml, not '.json'"),
        (["{run}", "--format", "rapid", "--out", "{run}/trajectory.csv"], "ends in .mod"),
        (["{run}", "--format", "urscript", "--out", "{tmp}/x", "--set", "gain"], "expected KEY=VALUE"),
        (["{run}", "--format", "krl", "--out", "{tmp}/x", "--set", "step_s=0"], "step_s = 0"),
    ],
)
def test_export_command_errors(argv, needle, run_folder, tmp_path, capsys):
    argv = [a.format(tmp=tmp_path, run=run_folder) for a in argv]
    assert main(["export", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("compplan: error:") and needle in err and "Traceback" not in err
    assert not any(tmp_path.glob("x*"))


def test_export_refuses_to_overwrite_its_input(run_folder, tmp_path, capsys):
    run = _copy_run(run_folder, tmp_path / "run")
    s = json.loads((run / "summary.json").read_text())
    s["timing"][s["controller_trajectory"]]["file"] = "prog.script"
    shutil.copy(run / "trajectory.csv", run / "prog.script")
    (run / "summary.json").write_text(json.dumps(s))
    before = (run / "prog.script").read_bytes()
    assert main(["export", str(run), "--format", "urscript", "--out", str(run / "prog.script")]) == 2
    assert "is also the input" in capsys.readouterr().err
    assert (run / "prog.script").read_bytes() == before


def test_krl_pair_is_written_whole_or_not_at_all(run_folder, tmp_path, monkeypatch, capsys):
    import planner.output as output

    real = output._write_new_file
    calls = []

    def full_on_second(path, data):
        calls.append(path)
        if len(calls) == 2:
            raise OSError(28, "No space left on device", str(path))
        real(path, data)

    monkeypatch.setattr(output, "_write_new_file", full_on_second)
    assert main(["export", str(run_folder), "--format", "krl", "--out", str(tmp_path / "p.src")]) == 2
    assert "No space left" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == []


def test_formats_are_registered():
    assert set(FORMATS) <= set(EXPORT_FORMATS)


# ------------------------------------------------------------------ rosbag2
def test_rosbag2_round_trip(run_folder, tmp_path, capsys):
    """The bag read back by rosbags' reader, and its metadata by PyYAML, against trajectory.csv."""
    rosbag2 = pytest.importorskip("rosbags.rosbag2")
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "bag"
    assert main(["export", str(run_folder), "--format", "rosbag2", "--out", str(bag), "--set", "start_time_s=100"]) == 0
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    t, qc = _csv_controller_q(run_folder)
    assert counts == {"/joint_trajectory": 1, "/joint_states": len(t)}
    store = get_typestore(Stores.ROS2_HUMBLE)
    states, stamps = [], []
    with rosbag2.Reader(bag) as reader:
        for con, stamp, raw in reader.messages():
            msg = store.deserialize_cdr(raw, con.msgtype)
            if con.topic == "/joint_trajectory":
                np.testing.assert_allclose([p.positions for p in msg.points], qc, atol=1e-12)
                assert msg.joint_names[0] == "shoulder_pan_joint"
            else:
                states.append(msg.position)
                stamps.append(stamp)
    np.testing.assert_allclose(states, qc, atol=1e-12)
    stamps = (np.array(stamps) - 100e9) * 1e-9
    k = _slow_factor(stamps, t, capsys.readouterr().out)  # the change line says how much slower, as the header
    np.testing.assert_allclose(stamps, k * t, atol=TIME_TOL_S)
    # a bag folder is written whole, never merged: into a folder holding other files it is refused
    (bag / "notes.txt").write_text("mine")
    assert main(["export", str(run_folder), "--format", "rosbag2", "--out", str(bag)]) == 2
    assert "give a new or empty folder" in capsys.readouterr().err


def test_plan_export_rosbag2_is_a_folder_of_the_run(tmp_path):
    pytest.importorskip("rosbags")
    out = tmp_path / "run"
    assert main(["demo", "--points", "12", "--out", str(out), "--no-report", "--export", "rosbag2"]) == 0
    bag = out / "paper_4_4_rosbag2"
    assert (bag / "metadata.yaml").is_file() and any(bag.glob("*.db3"))


def test_a_vendor_export_without_a_controller_table_warns():
    """Issue 24: the research arm (ar5) or any robot file without [controller] exported to a vendor format
    proceeded silently with identity signs; the CLI now warns, naming the table to fill."""
    from planner.export import VENDOR_FORMATS, controller_warning

    undeclared = small_data(controller_declared=False)
    for fmt in VENDOR_FORMATS:
        w = controller_warning(undeclared, fmt)
        assert "no [controller] table" in w and "joint_sign" in w and "joint_offset_deg" in w
    assert controller_warning(undeclared, "ros2") == ""  # joint names and the model's angles
    assert controller_warning(small_data(), "urscript") == ""
    assert load_robot("ur10").controller_declared and not load_robot("ar5").controller_declared


def test_plan_export_of_the_research_arm_warns_on_stderr(tmp_path, capsys):
    code = main(["demo", "--out", str(tmp_path / "run"), "--no-report"])
    assert code == 0
    capsys.readouterr()
    assert main(["export", str(tmp_path / "run"), "--format", "rapid", "--out", str(tmp_path / "m.mod")]) == 0
    err = capsys.readouterr().err
    assert "compplan: warning: robot ar5 has no [controller] table" in err


def test_a_servoj_export_resampled_beyond_the_limits_is_refused_or_slowed_down():
    """Issue 24: ``--set period=0.002`` of an 8 ms plan resampled without a check (1.17x the jerk limit on
    kr6_milling); the setpoints are now checked at the servoj period by finite differences, and refused
    (``slow_down=no``) or slowed down, saying so."""
    from planner.export import build_export

    tight = bang_data()  # at its jerk limit, jerk switches between the samples
    verify_limits(tight, "at its own period")  # inside its limits at 8 ms
    assert not build_export(tight, "urscript", Path("x")).warnings  # at its own period: nothing resampled
    with pytest.raises(
        ExportError,
        match=r"urscript: joint \d (acceleration|jerk) .* by finite differences of the servoj setpoints every 0.002 s "
        r"at t = .* is .*x its limit .*refusing to export \(--set slow_down=auto .*plan --dt 0.002",
    ):
        export_files(tight, "urscript", Path("x"), {"period": 0.002, "slow_down": "no"})
    slowed = build_export(tight, "urscript", Path("x"), {"period": 0.002})
    assert not slowed.warnings and slowed.status.value == "slowed"
    (change,) = [c for c in slowed.changes if c.startswith("slowed down")]  # one short line, the export's result
    k = float(re.search(r"slowed down x(" + NUM + ")", change).group(1))
    assert 1.0 < k < 1.5 and "its limit at the plan's timing" in change
    assert any("to the servoj period 2 ms" in c for c in slowed.changes)
    moves = parse_urscript(next(iter(slowed.files.values())))["moves"]
    assert len(moves) - 1 == pytest.approx(k * tight.t[-1] / 0.002, abs=1.0)  # k times as many setpoints
    roomy = bang_data(room=1.2)
    as_planned = build_export(roomy, "urscript", Path("x"), {"period": 0.002})
    assert not as_planned.warnings and as_planned.status.value == "ok"  # with room: as planned
    assert not any(c.startswith("slowed") for c in as_planned.changes)
