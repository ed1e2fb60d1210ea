"""The real-data run: a UR5 measured by a laser tracker (shared/data/ur5-laser-tracker).

Reads the dataset as it is (the measurement-file format ``tracker-dif``), identifies on ``grid.csv`` with
``compplan identify`` (full effect library, residual-driven selection), and reports on
``random.csv`` only (held out): mean, RMS and max Euclidean error, beside the published
figures (2.566 mm uncalibrated, 0.155 mm mean after hybrid calibration + neural network).

Run::

    python benchmarks/real_ur5_tracker.py [--data ../shared/data/ur5-laser-tracker] [--out out/real]

The dataset's files are read as they are by the installed commands, in the measurement-file
format ``tracker-dif`` (``docs/measurement-file.md``, "Tracker exports"); conventions (see
docs/real-data.md):

* ``x_t, y_t, z_t`` are the nominal-FK targets (mm, base frame) of the commanded joints
  ``joint_1..6`` (deg) with the measured point 31 mm along the flange z axis;
* the measured position is ``target + dif`` (the format ``tracker-dif``; the sign that makes the
  identified self-weight compliance of joint 2 positive, i.e. physical; the other sign,
  ``tracker-dif-reversed``, gives a negative stiffness);
* no external load: the wrench is zero, self-weight acts through the ``gravity`` and
  ``joint_tilt`` effects (UR5 link masses from the robot file).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

#: The measured point in the flange frame assumed by the dataset's targets, m.
TRACKER_TCP_M = (0.0, 0.0, 0.031)
#: The measurement-file format of the dataset: measured = target + dif (docs/real-data.md).
DATA_FORMAT = "tracker-dif"
#: The dataset's files: identification and held-out.
GRID_FILE, RANDOM_FILE = "grid.csv", "random.csv"
PUBLISHED_UNCALIBRATED_MEAN_MM = 2.566
PUBLISHED_BEST_MEAN_MM = 0.155
#: Issue 10's acceptance: held-out mean Euclidean error, mm.
TARGET_MEAN_MM = 0.08
#: Exit status of a bad argument (as compplan's).
EXIT_USER_ERROR = 2


def robot_file(dst: Path) -> None:
    from models import load_robot
    from models.robot import robot_to_toml
    from models.transforms import transform

    r = load_robot("ur5").with_tool(transform(np.eye(3), np.array(TRACKER_TCP_M)))
    dst.write_text(robot_to_toml(r))


def _error(message: str) -> int:
    """One line on stderr, as compplan's errors; the exit status of a bad argument."""
    print(f"real_ur5_tracker.py: error: {message}", file=sys.stderr)
    return EXIT_USER_ERROR


def _row(name: str, e: np.ndarray) -> str:
    return f"  {name:<34}{e.mean():>10.4f}{np.sqrt(np.mean(e**2)):>10.4f}{e.max():>10.4f}"


def _print_results(e_before: np.ndarray, e_after: np.ndarray, report: dict, elapsed: float) -> None:
    """The held-out table beside the published figures, the issue-10 target, and the maps."""
    print(f"\nrandom.csv (held out, {len(e_after)} poses): Euclidean error [mm]")
    print(f"  {'model':<34}{'mean':>10}{'RMS':>10}{'max':>10}")
    print(_row("nominal (uncalibrated)", e_before))
    print(_row("identified (" + ", ".join(report.get("effects_added", [])) + ")", e_after))
    print(
        f"  published: uncalibrated {PUBLISHED_UNCALIBRATED_MEAN_MM} mm mean, "
        f"hybrid MDH + neural network {PUBLISHED_BEST_MEAN_MM} mm mean"
    )
    verdict = "below" if e_after.mean() < PUBLISHED_BEST_MEAN_MM else "NOT below"
    print(f"  -> {verdict} the published best; identification took {elapsed:.1f} s")
    print(
        f"  target of issue 10: held-out mean <= {TARGET_MEAN_MM} mm: "
        f"{'met' if e_after.mean() <= TARGET_MEAN_MM else 'NOT met'}"
    )
    maps = report.get("error_maps") or []
    if maps:
        print("\njoint error maps (harmonic cycles/rev: amplitude, at the TCP):")
        for e in maps:
            unit = "urad" if e["unit"] == "rad" else "um"
            terms = ", ".join(
                f"{h['freq_cpr']:.2f}: {h['amplitude_' + unit]:.0f} {unit} ({h['amplitude_tcp_um']:.0f} um)"
                for h in e["harmonics"]
            )
            print(
                f"  joint {e['joint']} {e['component']:<5} range {e['range_deg'][0]:.0f}..{e['range_deg'][1]:.0f} deg, "
                f"RMS at TCP {e['rms_tcp_um']:.0f} um: {terms}"
            )


def _identify_argv(out: Path, grid_csv: Path, rand_csv: Path, candidates: str | None) -> list[str]:
    """The ``compplan identify`` command of the benchmark (full library unless ``candidates``)."""
    argv = ["identify", "--robot", str(out / "ur5_tracker.toml"), "--data", str(grid_csv), "--format", DATA_FORMAT]
    argv += ["--out", str(out / "ur5_identified.toml"), "--report", str(out / "report"), "--validation", str(rand_csv)]
    return argv + (["--candidates", candidates] if candidates else [])


def main() -> int:
    here = Path(__file__).resolve().parents[1]
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--data",
        default=str(here.parent / "shared" / "data" / "ur5-laser-tracker"),
        help=f"folder of the dataset ({GRID_FILE}, {RANDOM_FILE})",
    )
    ap.add_argument("--out", default=str(here / "out" / "real_ur5"))
    ap.add_argument("--candidates", default=None, help="comma-separated effect names (default: all)")
    args = ap.parse_args()
    sys.path.insert(0, str(here))

    from planner.cli import main as cli
    from models.arm_file import load_model
    from models.errors import InputError
    from problems.identify import predict
    from problems.measurements import read_measurements

    data, out = Path(args.data), Path(args.out)
    grid_csv, rand_csv = data / GRID_FILE, data / RANDOM_FILE
    for f in (grid_csv, rand_csv):
        if not f.is_file():
            return _error(
                f"--data {data}: no file {f.name} there; expected the folder of the UR5 laser-tracker data "
                f"({GRID_FILE}, {RANDOM_FILE})"
            )
    try:
        out.mkdir(parents=True, exist_ok=True)
        robot_file(out / "ur5_tracker.toml")
    except OSError as exc:
        return _error(f"--out {out}: cannot write there ({exc.strerror or exc})")
    try:
        m = read_measurements(rand_csv, file_format=DATA_FORMAT)
    except InputError as exc:
        return _error(str(exc))
    p_rand_mm = m.p * 1e3

    t0 = time.perf_counter()
    argv = _identify_argv(out, grid_csv, rand_csv, args.candidates)
    rc = cli(argv)
    elapsed = time.perf_counter() - t0
    if rc != 0:
        print(f"identify failed (exit {rc})")
        return rc

    model = load_model(str(out / "ur5_identified.toml"))
    e_after = np.linalg.norm(predict(model, m) * 1e3 - p_rand_mm, axis=1)
    from models import KinematicModel, load_robot

    km = KinematicModel(load_robot(str(out / "ur5_tracker.toml")))
    e_before = np.linalg.norm(km.tcp(m.q)[:, :3, 3] * 1e3 - p_rand_mm, axis=1)
    report = json.loads((out / "report" / "report.json").read_text())

    _print_results(e_before, e_after, report, elapsed)
    summary = {
        "random_mean_mm_before": float(e_before.mean()),
        "random_mean_mm_after": float(e_after.mean()),
        "random_rms_mm_after": float(np.sqrt(np.mean(e_after**2))),
        "random_max_mm_after": float(e_after.max()),
        "effects_added": report.get("effects_added"),
        "unexplained": report.get("unexplained"),
        "identify_seconds": elapsed,
        "error_maps": report.get("error_maps"),
    }
    (out / "real_summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
