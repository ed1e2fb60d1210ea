"""Outputs of every shipped problem, the demo, a placement study, an identification and every export
format, written by the installed ``compplan`` (or the tree named by ``--tree``), and compared with
another snapshot file by file (issue 36: a redesign with the same behaviour).

    python benchmarks/output_snapshot.py run DIR [--tree PATH] [--only NAME ...]
    python benchmarks/output_snapshot.py compare DIR_A DIR_B

``compare`` reads both folders' files byte by byte after masking what is expected to differ between
two runs: the provenance (command line, date, version, input paths and hashes), wall-clock times and
the output folders' own paths. Every other difference is printed (file, first differing line) and the
exit status is 1.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

PROBLEMS = (
    "paper_4_4",
    "paper_5_2_points",
    "machining_offaxis",
    "drilling_cone",
    "measuring_position_only",
    "ur10_payload_tilt",
    "ur5_tool_thrust",
    "kr6_milling",
    "ur5_fast_payload",
    "placement_milling",
    "cell_table",
    "milling_pocket",
)
FORMATS = ("urscript", "urscript_movej", "ros2", "rosbag2", "rapid", "krl")
EXPORT_RUNS = ("paper_4_4", "kr6_milling")
PLACE_GRID = "x_m=0.0:0.4:3,y_m=-0.4:0.4:3,yaw_deg=0:90:2"
SIM_CONFIG = "problems/files/sim/ur5_gravity.toml"


def commands(out: Path) -> list[tuple[str, list[str]]]:
    runs: list[tuple[str, list[str]]] = [("demo", ["demo", "--out", str(out / "demo")])]
    for name in PROBLEMS:
        runs.append((f"plan_{name}", ["plan", name, "--out", str(out / f"plan_{name}")]))
    for name in EXPORT_RUNS:
        for fmt in FORMATS:
            runs.append(
                (
                    f"export_{name}_{fmt}",
                    ["export", str(out / f"plan_{name}"), "--format", fmt, "--out", str(out / f"export_{name}_{fmt}")],
                )
            )
    runs.append(("place", ["place", "placement_milling", "--grid", PLACE_GRID, "--out", str(out / "place")]))
    runs.append(
        (
            "simulate",
            ["simulate", "--robot", "ur5", "--config", SIM_CONFIG, "--seed", "3", "--out", str(out / "sim.csv")],
        )
    )
    runs.append(
        (
            "identify",
            [
                "identify",
                "--robot",
                "ur5",
                "--data",
                str(out / "sim.csv"),
                "--out",
                str(out / "identified.toml"),
                "--report",
                str(out / "identify_report"),
                "--no-progress",
            ],
        )
    )
    runs.append(
        (
            "predict",
            [
                "predict",
                "--model",
                str(out / "identified.toml"),
                "--input",
                str(out / "sim.csv"),
                "--out",
                str(out / "predicted.csv"),
            ],
        )
    )
    runs.append(("map", ["map", "--robot", "ur5", "--out", str(out / "map")]))
    return runs


def run(args: argparse.Namespace) -> int:
    out = Path(args.dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    cwd = Path.cwd()
    if args.tree:
        tree = Path(args.tree).resolve()
        env["PYTHONPATH"] = str(tree)
        cwd = tree
    (out / "tree.txt").write_text(str(cwd.resolve()) + "\n", encoding="utf-8")
    log = open(out / "commands.log", "w", encoding="utf-8")
    for name, argv in commands(out):
        if args.only and not any(name.startswith(o) for o in args.only):
            continue
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "planner.cli", *argv], cwd=cwd, env=env, capture_output=True, text=True
        )
        dt = time.perf_counter() - t0
        (out / f"{name}.stdout").write_text(proc.stdout, encoding="utf-8")
        (out / f"{name}.stderr").write_text(proc.stderr, encoding="utf-8")
        (out / f"{name}.rc").write_text(f"{proc.returncode}\n", encoding="utf-8")
        print(f"{name:40s} exit {proc.returncode} {dt:7.1f} s", file=log, flush=True)
        print(f"{name:40s} exit {proc.returncode} {dt:7.1f} s", flush=True)
    return 0


MASKS = [
    (re.compile(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d[\d.:+Z-]*"), b"<DATE>"),
    (re.compile(rb"\d{4}-\d\d-\d\d \d\d:\d\d(:\d\d)?( UTC)?"), b"<DATE>"),
    (re.compile(rb'"sha256": "[0-9a-f]{64}"'), b'"sha256": "<HASH>"'),
    (re.compile(rb"[0-9a-f]{64}"), b"<HASH>"),
    (re.compile(rb'("(wall|elapsed|cpu|time)[\w]*_s"\s*:\s*)[\d.eE+-]+'), rb"\1<T>"),
    (re.compile(rb"(in |took |after )[\d.]+ ?(s|min|ms)\b"), rb"\1<T>"),
    (re.compile(rb"[\d.]+ s (wall|CPU)"), b"<T>"),
    (re.compile(rb"/CreationDate \([^)]*\)"), b"/CreationDate ()"),
    (re.compile(rb'("\w*time\w*_s": )[\d.eE+-]+'), rb"\1<T>"),
    (re.compile(rb'("\w*_us_per_\w*": )[\d.eE+-]+'), rb"\1<T>"),
    (re.compile(rb'"check_time_s": \{[^}]*\}'), b'"check_time_s": {}'),
    (re.compile(rb'(data-key="[\w.]*(elapsed|time)\w*_s" data-value=")[\d.]+(">)[\d.,]+'), rb"\1<T>\3<T>"),
    (re.compile(rb'"stage_times_s": \{[^}]*\}'), b'"stage_times_s": {}'),
    (re.compile(rb'("poses_per_second": )[\d.]+'), rb"\1<RATE>"),
    (re.compile(rb'(poses_per_second" data-value=")[\d.]+(">)[\d,]+'), rb"\1<RATE>\2"),
    (re.compile(rb"[\d,]+ poses/s"), b"<RATE> poses/s"),
    # the branch table's last column: the branch's NLP time in ms
    (re.compile(rb"(?m)^(  \S+\s+\w+\s+[\d.]+ mm\s+[\d.]+ mm .*?)\s+[\d.]+( \*|  \(default\))?$"), rb"\1 <MS>\2"),
]


def masked(data: bytes, folder: Path, written: Path) -> bytes:
    """``data`` with the folder it was written into, the source tree's path (``folder/tree.txt``), dates,
    hashes and timings replaced by placeholders."""
    data = data.replace(str(written.resolve()).encode(), b"<ROOT>")
    tree = folder / "tree.txt"
    if tree.is_file():
        data = data.replace(tree.read_text(encoding="utf-8").strip().encode(), b"<TREE>")
    for pattern, repl in MASKS:
        data = pattern.sub(repl, data)
    return data


def canonical_json(data: bytes) -> bytes:
    try:
        return json.dumps(json.loads(data), indent=2, sort_keys=True).encode()
    except ValueError:
        return data


def compare(args: argparse.Namespace) -> int:
    a, b = Path(args.a), Path(args.b)
    files_a = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    files_b = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    bad = 0
    for rel in sorted(files_a ^ files_b):
        print(f"only in {'A' if rel in files_a else 'B'}: {rel}")
        bad += 1
    same = 0
    for rel in sorted(files_a & files_b):
        if rel.name in ("commands.log", "tree.txt"):
            continue
        da, db = (a / rel).read_bytes(), (b / rel).read_bytes()
        if da == db:
            same += 1
            continue
        if rel.suffix == ".json":
            # key order is not part of the format (a dictionary filled from a set can change it between runs)
            da, db = canonical_json(da), canonical_json(db)
        ma = masked(da, a, Path(args.written_a or a))
        mb = masked(db, b, Path(args.written_b or b))
        if ma == mb:
            same += 1
            continue
        la, lb = ma.splitlines(), mb.splitlines()
        line = next((i for i, (x, y) in enumerate(zip(la, lb)) if x != y), min(len(la), len(lb)))
        print(f"differs: {rel} (line {line + 1})")
        if args.verbose:
            print("  A:", la[line][:300] if line < len(la) else b"<end>")
            print("  B:", lb[line][:300] if line < len(lb) else b"<end>")
        bad += 1
    print(f"{same} files the same (after masking), {bad} differ or are missing")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("dir")
    r.add_argument("--tree", help="source tree to run (PYTHONPATH), default: the installed compplan")
    r.add_argument("--only", nargs="*", help="run only the commands whose names start with these")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("-v", "--verbose", action="store_true")
    c.add_argument("--written-a", help="the folder A was written into, if it was moved since")
    c.add_argument("--written-b", help="the folder B was written into, if it was moved since")
    args = parser.parse_args(argv)
    return run(args) if args.cmd == "run" else compare(args)


if __name__ == "__main__":
    raise SystemExit(main())
