"""Exports of big programs (``docs/export.md``, "Big programs"): 10^4-10^6 samples.

Above its size limit each format writes numbered parts (RAPID, KRL, ROS 2 YAML, the rosbag2's
``/joint_trajectory``) or a stream (URScript).  Checked here on synthetic trajectories (no
planning): the expected files, every part within its limit, the parts read back by independent
parsers and joined equal the one-file export of the same trajectory value for value (the same
printed numbers) and the trajectory itself, a trajectory at the limit is written as today
(one file), and a split set is written whole or not at all.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from models.robot import load_robot
from planner.cli import main
from planner.export import ExportData, export_files, part_label, part_ranges
from planner.export import krl as krl_mod
from planner.export import rapid as rapid_mod
from planner.export import ros2 as ros2_mod
from planner.export import urscript as ur_mod
from planner.output import TRAJECTORY_COLUMNS
from tests.test_export import NUM, parse_krl, parse_rapid, parse_urscript

#: Positions are printed to 1e-9 rad (URScript), 12 digits (ROS 2), 1e-6 deg (RAPID, KRL).
POS_TOL_RAD = 1e-8
#: Samples of the synthetic trajectory at 8 ms: above every format's default limit
#: (URScript 2,000 motions, ROS 2 10,000 points, RAPID 5,000 targets every 0.05 s, KRL 1,000
#: points every 0.1 s).
BIG = 31_000
DT = 0.008
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def wave(n: int, dt: float = DT, name: str = "big") -> ExportData:
    """``n`` samples of a slow joint-space sine sweep, well inside the limits below, with a
    controller map (a sign and offsets), like a long CAM program's trajectory."""
    t = np.arange(n) * dt
    w = 2 * math.pi / 40.0
    amp = np.array([0.5, -0.3, 0.4, 0.2, -0.25, 0.6])
    phase = np.linspace(0.0, 1.0, 6)
    s = np.sin(w * t[:, None] + phase)
    c = np.cos(w * t[:, None] + phase)
    q0 = np.array([0.1, -1.2, 1.3, -0.4, 1.5707963, 0.2])
    return ExportData(
        name=name,
        robot="ur10",
        joint_names=tuple(f"j{i}" for i in range(1, 7)),
        t=t,
        q=q0 + amp * s,
        qd=amp * w * c,
        qdd=-amp * w**2 * s,
        qddd=-amp * w**3 * c,
        dt=dt,
        v_max=np.full(6, 3.14),
        a_max=np.full(6, 20.0),
        j_max=np.full(6, 2000.0),
        q_min=np.full(6, -2 * math.pi),
        q_max=np.full(6, 2 * math.pi),
        sign=np.array([1, -1, 1, 1, 1, 1.0]),
        offset=np.radians([0, 0, 90, 0, 0, -180.0]),
        source="test",
    )


@pytest.fixture(scope="module")
def big() -> ExportData:
    return wave(BIG)


@pytest.fixture(autouse=True)
def fixed_version(monkeypatch):
    import planner.provenance as prov

    monkeypatch.setattr(prov, "version", lambda: "0.0.0-test")


def _ctrl(data: ExportData) -> np.ndarray:
    return data.q * data.sign + data.offset


def _text(content: str | bytes) -> str:
    return content.decode() if isinstance(content, bytes) else content


def _files(data: ExportData, fmt: str, out: str, **options) -> dict[str, str]:
    return {p.name: _text(c) for p, c in export_files(data, fmt, Path(out), options).items()}


def _numbers(text: str) -> list[str]:
    return re.findall(NUM, text)


# ------------------------------------------------------------------ the parts
def test_part_ranges_and_labels():
    assert part_ranges(10, 4) == [(0, 4), (4, 8), (8, 10)]
    assert part_ranges(8, 4) == [(0, 4), (4, 8)]
    assert part_ranges(3, 5) == [(0, 3)]
    for n, lim in ((1, 1), (999, 7), (10_000, 333)):
        r = part_ranges(n, lim)
        assert r[0][0] == 0 and r[-1][1] == n and all(b - a <= lim for a, b in r)
        assert all(r[i][1] == r[i + 1][0] for i in range(len(r) - 1))
    assert part_label(1, 9) == "p001" and part_label(12, 1500) == "p0012"
    with pytest.raises(ValueError):
        part_ranges(5, 0)


# ------------------------------------------------------------------ URScript: streamed
def _stream(text: str, width: int) -> list[list[str]]:
    rows = []
    for line in text.splitlines():
        m = re.fullmatch(r"\(([^()]*)\)", line)
        assert m, line
        vals = m.group(1).split(",")
        assert len(vals) == width, line
        rows.append(vals)
    return rows


def test_urscript_servoj_above_the_limit_is_streamed(big):
    files = _files(big, "urscript", "prog", stream_host="10.0.0.2", stream_port=50123)
    assert sorted(files) == ["prog.script", "prog_stream.txt"]
    prog = files["prog.script"]
    # the program stays small: no setpoint in it, one servoj statement in a loop
    assert len(prog.splitlines()) < 60 and prog.count("servoj(") == 1
    assert re.search(r'socket_open\("10\.0\.0\.2", 50123, "compplan_stream"\)', prog)
    assert f"while k < {BIG}:" in prog and "socket_read_ascii_float(6," in prog
    assert prog.startswith("def prog():") and prog.rstrip().endswith("end")
    rows = _stream(files["prog_stream.txt"], 6)
    assert len(rows) == BIG
    # every setpoint, value for value, as the one-program export prints it
    single = _files(big, "urscript", "prog", max_motions=BIG)["prog.script"]
    assert len(parse_urscript(single)["moves"]) == BIG
    one = [_numbers(ln)[:6] for ln in single.splitlines() if ln.lstrip().startswith(("movej(", "servoj("))]
    assert rows == one
    np.testing.assert_allclose(np.array(rows, dtype=float), _ctrl(big), atol=POS_TOL_RAD)


def test_urscript_movej_above_the_limit_is_streamed(big):
    step, r = 0.04, 0.002
    idx = big.decimated(step)
    assert len(idx) > ur_mod.URSCRIPT_MAX_MOTIONS
    files = _files(big, "urscript_movej", "mj", step_s=step, blend_radius=r, stream_host="pc.lab")
    assert sorted(files) == ["mj.script", "mj_stream.txt"]
    assert "movej([q[1], q[2], q[3], q[4], q[5], q[6]], t=q[7], r=q[8])" in files["mj.script"]
    rows = _stream(files["mj_stream.txt"], 8)
    assert len(rows) == len(idx)
    single = parse_urscript(
        _files(big, "urscript_movej", "mj", step_s=step, blend_radius=r, max_motions=10**6)["mj.script"]
    )["moves"]
    q = np.array(rows, dtype=float)[:, :6]
    np.testing.assert_array_equal(q, np.array([m[1] for m in single]))
    # t and r of every move after the first, as the one-program form has them
    assert [(float(x[6]), float(x[7])) for x in rows[1:]] == [(m[2]["t"], m[2]["r"]) for m in single[1:]]
    np.testing.assert_allclose(q, _ctrl(big)[idx], atol=POS_TOL_RAD)


def test_urscript_at_the_limit_is_one_program_as_before(big):
    data = wave(ur_mod.URSCRIPT_MAX_MOTIONS)
    files = _files(data, "urscript", "p")
    assert list(files) == ["p.script"] and "socket" not in files["p.script"]
    assert len(parse_urscript(files["p.script"])["moves"]) == ur_mod.URSCRIPT_MAX_MOTIONS
    over = wave(ur_mod.URSCRIPT_MAX_MOTIONS + 1)
    assert sorted(_files(over, "urscript", "p", stream_host="10.0.0.2")) == ["p.script", "p_stream.txt"]


# ------------------------------------------------------------------ ROS 2 YAML: numbered messages
def _ros2_parts(files: dict[str, str], stem: str) -> tuple[dict, list[dict]]:
    index = yaml.load(files[f"{stem}.yaml"], Loader=SAFE_LOADER)
    parts = [yaml.load(files[p["file"]], Loader=SAFE_LOADER) for p in index["parts"]]
    return index, parts


def test_ros2_default_limit(big):
    limit = ros2_mod.ROS2_MAX_POINTS
    files = _files(big, "ros2", "traj")
    n = math.ceil(BIG / limit)
    assert sorted(files) == ["traj.yaml"] + [f"traj_p{k:03d}.yaml" for k in range(1, n + 1)]
    counts = [files[f"traj_p{k:03d}.yaml"].count("\n- positions: ") for k in range(1, n + 1)]
    assert counts == [limit] * (n - 1) + [BIG - (n - 1) * limit]


def test_ros2_above_the_limit_is_split_into_messages():
    data, limit = wave(2500), 1000
    files = _files(data, "ros2", "traj", frame_id="base", max_points=limit)
    assert sorted(files) == ["traj.yaml", "traj_p001.yaml", "traj_p002.yaml", "traj_p003.yaml"]
    index, parts = _ros2_parts(files, "traj")
    assert index["joint_names"] == list(data.joint_names) and index["samples"] == 2500
    assert [p["points"] for p in index["parts"]] == [len(m["points"]) for m in parts] == [1000, 1000, 500]
    ns = np.round(data.t * 1e9).astype(np.int64)
    times, points = [], []
    for entry, msg in zip(index["parts"], parts):
        assert msg["joint_names"] == list(data.joint_names) and msg["header"]["frame_id"] == "base"
        start = entry["start"]["sec"] * 10**9 + entry["start"]["nanosec"]
        # a part starts at the previous part's last sample: its first point is one period later
        assert start == (0 if entry["first_sample"] == 0 else ns[entry["first_sample"] - 1])
        for p in msg["points"]:
            times.append(start + p["time_from_start"]["sec"] * 10**9 + p["time_from_start"]["nanosec"])
            points.append(p)
    np.testing.assert_array_equal(times, ns)
    # the joined points are those of the one-message export, number for number
    single = yaml.load(_files(data, "ros2", "traj", frame_id="base")["traj.yaml"], Loader=SAFE_LOADER)
    assert len(single["points"]) == 2500
    for key in ("positions", "velocities", "accelerations"):
        assert [p[key] for p in points] == [p[key] for p in single["points"]]
    np.testing.assert_allclose([p["positions"] for p in points], _ctrl(data), atol=POS_TOL_RAD)


def test_ros2_at_the_limit_is_one_message_as_before():
    data = wave(50)
    files = _files(data, "ros2", "t", max_points=50)
    assert list(files) == ["t.yaml"]
    assert files["t.yaml"] == _files(data, "ros2", "t")["t.yaml"]
    assert sorted(_files(data, "ros2", "t", max_points=49)) == ["t.yaml", "t_p001.yaml", "t_p002.yaml"]


# ------------------------------------------------------------------ ABB RAPID: part modules
def test_rapid_above_the_limit_is_split_into_loaded_modules(big):
    limit = rapid_mod.RAPID_MAX_TARGETS
    idx = big.decimated(0.05)
    n = math.ceil((len(idx) - 1) / limit)
    files = _files(big, "rapid", "cut", load_path="HOME:/cam")
    parts = [f"cut_p{k:03d}.mod" for k in range(1, n + 1)]
    assert sorted(files) == ["cut.mod"] + parts
    drv = files["cut.mod"]
    # the driver: first target, then each part loaded (the next while the current runs), called, unloaded
    assert drv.count("MoveAbsJ") == 1 and drv.count("CONST jointtarget") == 1
    assert f'Load \\Dynamic, "HOME:/cam" \\File:="{parts[0]}";' in drv
    calls = re.findall(r'%"(\w+)"%;', drv)
    assert calls == [f"cut_p{k:03d}" for k in range(1, n + 1)]
    for k in range(1, n):
        assert f'StartLoad \\Dynamic, "HOME:/cam" \\File:="{parts[k]}", compplan_load;' in drv
        assert f'WaitLoad \\UnloadPath:="HOME:/cam" \\UnloadFile:="{parts[k - 1]}", compplan_load;' in drv
    assert drv.index(f'File:="{parts[1]}"') < drv.index(f'%"{calls[0]}"%')  # loads ahead
    assert f'UnLoad "HOME:/cam" \\File:="{parts[-1]}";' in drv
    targets = {"jt0": parse_rapid(drv)["targets"]["jt0"]}
    moves = parse_rapid(drv)["moves"]
    for name, proc in zip(parts, calls):
        text = files[name]
        assert re.search(rf"^MODULE {proc}$", text, re.M) and f"PROC {proc}()" in text
        parsed = parse_rapid(text.replace(f"PROC {proc}()", "PROC main()"))
        assert len(parsed["moves"]) <= limit and len(parsed["targets"]) == len(parsed["moves"])
        targets.update(parsed["targets"])
        moves += parsed["moves"]
    single = parse_rapid(_files(big, "rapid", "cut", max_targets=len(idx))["cut.mod"])
    assert moves == single["moves"]
    assert {k: list(v) for k, v in targets.items()} == {k: list(v) for k, v in single["targets"].items()}
    q = np.radians([targets[m[0]] for m in moves])
    np.testing.assert_allclose(q, _ctrl(big)[idx], atol=POS_TOL_RAD)
    assert moves[-1][2] == "fine" and all(m[2] == "z1" for m in moves[1:-1])


# ------------------------------------------------------------------ KUKA KRL: part modules
def _krl_part(src: str, dat: str) -> dict:
    """A part module (no PTP to a first point of its own): name, points, moves, time-block parts."""
    s = [ln.strip() for ln in src.splitlines() if ln.strip() and not ln.strip().startswith(";")]
    name = re.fullmatch(r"DEF (\w+)\( \)", s[2]).group(1)
    assert s[:2] == ["&ACCESS RVP", "&REL 1"] and s[-1] == "END"
    assert re.search(rf"^DEFDAT {name} PUBLIC$", dat, re.M) and dat.rstrip().endswith("ENDDAT")
    if "PTP_SPLINE" in s:
        assert s.count("PTP_SPLINE") == s.count("ENDSPLINE") == 1 and s.index("PTP_SPLINE") < s.index("ENDSPLINE")
    points = {}
    for pname, body in re.findall(r"DECL E6AXIS (\w+)=\{([^}]*)\}", dat):
        kv = dict((k, float(v)) for k, v in re.findall(r"([AE]\d) (" + NUM + ")", body))
        points[pname] = np.array([kv[f"A{i}"] for i in range(1, 7)])
    moves = [m for ln in s for m in re.findall(r"^S?PTP (\w+)(?: C_PTP)?$", ln)]
    assert all(m in points for m in moves)
    parts = [float(v) for ln in s for v in re.findall(r"^TIME_BLOCK PART = (" + NUM + ")$", ln)]
    end = [float(v) for ln in s for v in re.findall(r"^TIME_BLOCK END = (" + NUM + ")$", ln)]
    return {"name": name, "points": points, "moves": moves, "parts": parts, "end": end[0] if end else None}


@pytest.mark.parametrize("motion", ["spline", "ptp"])
def test_krl_above_the_limit_is_split_into_called_modules(big, motion):
    limit = krl_mod.KRL_MAX_POINTS
    idx = big.decimated(0.1)
    n = math.ceil((len(idx) - 1) / limit)
    files = _files(big, "krl", "cut.src", motion=motion)
    names = [f"cut_p{k:03d}" for k in range(1, n + 1)]
    assert sorted(files) == sorted(["cut.src", "cut.dat"] + [f"{p}{s}" for p in names for s in (".src", ".dat")])
    main_ = parse_krl(files["cut.src"], files["cut.dat"])
    assert main_["moves"] == ["XP0"] and list(main_["points"]) == ["XP0"]
    assert re.findall(r"^  (\w+)\( \)$", files["cut.src"], re.M) == names
    points, moves, times = dict(main_["points"]), ["XP0"], [0.0]
    for p in names:
        part = _krl_part(files[f"{p}.src"], files[f"{p}.dat"])
        assert part["name"] == p and len(part["moves"]) <= limit and len(part["points"]) == len(part["moves"])
        assert "GLOBAL" not in files[f"{p}.dat"]  # XPk are local to their module
        points.update(part["points"])
        moves += part["moves"]
        if motion == "spline":  # each part's own TIME_BLOCK, from where the previous one ended
            assert len(part["parts"]) == len(part["moves"]) and abs(sum(part["parts"]) - part["end"]) < 1e-5
            times += list(times[-1] + np.cumsum(part["parts"]))
    single = parse_krl(*_files(big, "krl", "cut.src", motion=motion, max_points=len(idx)).values())
    assert moves == single["moves"] and len(moves) == len(idx)
    assert {k: list(v) for k, v in points.items()} == {k: list(v) for k, v in single["points"].items()}
    np.testing.assert_allclose(np.radians([points[m] for m in moves]), _ctrl(big)[idx], atol=POS_TOL_RAD)
    if motion == "spline":
        np.testing.assert_allclose(times, single["times"], atol=1e-9 * len(idx))
        np.testing.assert_allclose(times, big.t[idx], atol=1e-6 * len(idx))
    else:  # C_PTP on every point but the trajectory's last, across the parts
        last = files[f"{names[-1]}.src"].rstrip().splitlines()
        assert last[-2].strip() == f"PTP XP{len(idx) - 1}"
        assert sum(files[f"{p}.src"].count(" C_PTP") for p in names) == len(idx) - 2


def test_krl_and_rapid_at_the_limit_are_one_module_as_before():
    data = wave(400)
    for fmt, out, key, suffixes in (
        ("krl", "k.src", "max_points", [".dat", ".src"]),
        ("rapid", "r", "max_targets", [".mod"]),
    ):
        step = 0.1 if fmt == "krl" else 0.05
        m = len(data.decimated(step))
        one = _files(data, fmt, out, **{key: m})
        assert sorted(Path(f).suffix for f in one) == suffixes
        assert one == _files(data, fmt, out, **{key: 10**6})
        assert len(_files(data, fmt, out, **{key: m - 1})) > len(one)


def test_small_exports_equal_the_golden_files(monkeypatch):
    """Below every limit the files are exactly those of before this change (tests/golden/export)."""
    import planner.provenance as prov
    from tests.test_export import GOLDEN, GOLDEN_OPTIONS, small_data

    monkeypatch.setattr(prov, "version", lambda: "0.0.0-golden")

    for fmt in ("urscript", "urscript_movej", "ros2", "rapid", "krl"):
        for path, text in export_files(small_data(), fmt, Path(f"golden_{fmt}"), GOLDEN_OPTIONS.get(fmt)).items():
            assert isinstance(text, str) and text == (GOLDEN / path.name).read_text(encoding="utf-8"), path.name


# ------------------------------------------------------------------ rosbag2
def test_rosbag2_splits_the_trajectory_message(tmp_path):
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    data = wave(2500)
    files = export_files(data, "rosbag2", tmp_path / "bag", {"max_points": 1000, "start_time_s": 100})
    for p, content in files.items():
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(content)
    store = get_typestore(Stores.ROS2_HUMBLE)
    ns = 100 * 10**9 + np.round(data.t * 1e9).astype(np.int64)
    traj_t, traj_q, states, stamps = [], [], [], []
    with Reader(tmp_path / "bag") as reader:
        for con, stamp, raw in reader.messages():
            msg = store.deserialize_cdr(raw, con.msgtype)
            if con.topic == "/joint_trajectory":
                start = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
                assert stamp == start and len(msg.points) <= 1000
                for p in msg.points:
                    traj_t.append(start + p.time_from_start.sec * 10**9 + p.time_from_start.nanosec)
                    traj_q.append(p.positions)
            else:
                assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamp
                states.append(np.concatenate([msg.position, msg.velocity]))
                stamps.append(stamp)
    assert len(traj_q) == 2500 and len(states) == 2500
    np.testing.assert_array_equal(traj_t, ns)
    np.testing.assert_array_equal(stamps, ns)
    np.testing.assert_array_equal(np.array(traj_q), _ctrl(data))  # float64 throughout: exact
    np.testing.assert_array_equal(np.array(states), np.column_stack([_ctrl(data), data.qd * data.sign]))


# ------------------------------------------------------------------ from a run folder, whole or not at all
def _run_folder(base: Path, data: ExportData) -> Path:
    """A minimal plan run folder (summary.json + trajectory.csv) holding ``data``."""
    run = base / "run"
    run.mkdir()
    cols = np.column_stack([data.t, data.q, data.qd, data.qdd, data.qddd])
    with (run / "trajectory.csv").open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(TRAJECTORY_COLUMNS)
        w.writerows([[repr(v) for v in r] for r in cols.tolist()])
    summary = {
        "command": "plan",
        "plan_status": "ok",
        "problem": {"name": "big"},
        "controller_trajectory": "jerk_optimal",
        "timing": {"jerk_optimal": {"status": "ok", "file": "trajectory.csv", "dt": data.dt}},
        "robot_file": {  # the robot file a run records (summary.json is checked on reading)
            **load_robot("ur10").to_dict(),
            "joint_names": list(data.joint_names),
            "controller": {"joint_sign": [int(v) for v in data.sign], "joint_offset": list(data.offset)},
        },
        "limits": {
            "velocity": list(data.v_max),
            "acceleration": list(data.a_max),
            "jerk": list(data.j_max),
            "q_min": list(data.q_min),
            "q_max": list(data.q_max),
        },
    }
    (run / "summary.json").write_text(json.dumps(summary))
    return run


def test_export_command_writes_the_parts_whole_or_not_at_all(tmp_path, monkeypatch, capsys):
    import planner.output as output
    from planner.export.sources import _read_rows, _read_trajectory

    data = wave(3000)
    run = _run_folder(tmp_path, data)
    # the fast reader reads exactly what the row-by-row reader reads
    fast = _read_trajectory(run / "trajectory.csv")
    slow = _read_rows(
        run / "trajectory.csv", ["t"] + [f"{c}{i}" for c in ("q", "qd", "qdd", "qddd") for i in range(1, 7)]
    )
    np.testing.assert_array_equal(np.column_stack(fast[:5]), slow)
    np.testing.assert_array_equal(fast[1], data.q)
    out = tmp_path / "out"
    out.mkdir()
    real, calls = output._write_new_file, []

    def full_on_fifth(path, content):
        calls.append(path)
        if len(calls) == 5:
            raise OSError(28, "No space left on device", str(path))
        real(path, content)

    monkeypatch.setattr(output, "_write_new_file", full_on_fifth)
    argv = ["export", str(run), "--format", "krl", "--out", str(out / "cut.src"), "--set", "max_points=100"]
    assert main(argv) == 2
    assert "No space left" in capsys.readouterr().err and list(out.iterdir()) == []
    monkeypatch.setattr(output, "_write_new_file", real)
    assert main(argv) == 0
    written = sorted(p.name for p in out.iterdir())
    n = math.ceil((len(data.decimated(0.1)) - 1) / 100)
    assert len(written) == 2 + 2 * n and written[0] == "cut.dat" and written[-1] == f"cut_p{n:03d}.src"
    # the same files as the export of the trajectory in memory (the header line aside)
    mine = _files(data, "krl", "cut.src", max_points=100)
    for name in written:
        body = [ln for ln in (out / name).read_text().splitlines() if "generated by compplan" not in ln]
        assert body == [ln for ln in mine[name].splitlines() if "generated by compplan" not in ln], name
