"""A timing method is one module: a plug-in from a folder of ``$COMPPLAN_TIMING_PATH`` goes from
a problem file through ``compplan plan`` to the summary, the report and an export, with no other edit.

The plug-in (:data:`PLUGIN`) is a simple but real method: the rest-to-rest septic polynomial
``s(u) = 35u^4 - 84u^5 + 70u^6 - 20u^7`` (zero velocity, acceleration and jerk at both ends),
stretched in time until the chain rule bounds every joint's velocity, acceleration and jerk by its
limit; it ends in :func:`problems.timing.verification.finish_trajectory` like the built-in methods.
Registration happens at import, so the plan runs in a fresh interpreter (a subprocess).
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from models.errors import InputError
from problems.problem import ProblemFileError, problem_from_dict
from problems.timing import available_methods

#: The plug-in's method name, module file and display name.
NAME = "septic"
MODULE = "septic_law.py"
DISPLAY = "Septic law"
#: Its controller rank: preferred to TOPP-RA's (so the controller runs it when the problem names
#: both) and to every built-in method's.
RANK = 5
#: Slack on the limit checks of the trajectory file (the CSV holds %.17g values).
LIMIT_TOL = 1e-9
#: A subprocess that plans (posture, compensation, timing, report) gets this long, s.
TIMEOUT_S = 600

PLUGIN = (
    '''
"""Septic rest-to-rest law stretched to the slowest joint (a timing plug-in for a test)."""
import numpy as np

from models.errors import InputError
from problems.timing.registry import TimingMethod, register_method
from problems.timing.verification import check_times, finish_trajectory, format_ratios, limit_ratios

_U = np.linspace(0.0, 1.0, 200001)
#: Peaks of the septic's first three derivatives |ds/du|, |d2s/du2|, |d3s/du3| over u in [0, 1]
#: (fine grid) and the relative margin
#: that covers the grid's error.
C1 = float(np.max(140 * _U**3 * (1 - _U)**3))
C2 = float(np.max(np.abs(420 * _U**2 * (1 - _U)**2 * (1 - 2 * _U))))
C3 = float(np.max(np.abs(840 * _U * (1 - _U) * (5 * _U**2 - 5 * _U + 1))))
MARGIN = 1e-6


def septic(duration):
    def law(t):
        u = np.clip(np.asarray(t, float) / duration, 0.0, 1.0)
        s = u**4 * (35 - 84 * u + 70 * u**2 - 20 * u**3)
        s1 = 140 * u**3 * (1 - u)**3
        s2 = 420 * u**2 * (1 - u)**2 * (1 - 2 * u)
        s3 = 840 * u * (1 - u) * (5 * u**2 - 5 * u + 1)
        return s, s1 / duration, s2 / duration**2, s3 / duration**3
    return law


def run(path, limits, dt, opts):
    a1, a2, a3 = path.abs_max
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.vstack([a1 * C1 / limits.velocity,
                          np.sqrt((a2 * C1**2 + a1 * C2) / limits.acceleration),
                          np.cbrt((a3 * C1**3 + 3 * a2 * C1 * C2 + a1 * C3) / limits.jerk)])
    duration = float(np.nanmax(need)) * (1 + MARGIN) * opts.get("stretch", 1.0)
    law = septic(duration)
    tc = check_times(duration, dt)
    s, sd, sdd, sddd = law(tc)
    _, qd, qdd, qddd = path.evaluate(s, sd, sdd, sddd)
    ratio = limit_ratios(qd, qdd, qddd, limits)
    summary = f"septic law stretched to {duration:.4f} s; {format_ratios(ratio)}"
    return finish_trajectory("@NAME@", path, limits, dt, law, duration, ratio, summary,
                             check_sd=sd, sd_scale=float(sd.max()), iterations=1)


def validate(opts):
    if "stretch" in opts:
        v = opts["stretch"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (1.0 <= v <= 10.0):
            raise InputError(f"option stretch must be a number in [1, 10], got {v!r}")
        opts["stretch"] = float(v)
    return opts


register_method(TimingMethod(
    name="@NAME@", run=run, options=("stretch",), validate_options=validate,
    checked_limits=("velocity", "acceleration", "jerk"),
    description="septic rest-to-rest law stretched to the slowest joint (test plug-in)",
    display_name="@DISPLAY@", controller_rank=@RANK@))
'''.replace("@NAME@", NAME)
    .replace("@DISPLAY@", DISPLAY)
    .replace("@RANK@", str(RANK))
)


def _problem_text(methods: str, extra: str = "") -> str:
    """The shipped paper_4_4 problem with other ``[timing] methods`` (and ``extra`` appended)."""
    text = (Path(__file__).resolve().parents[1] / "problems" / "files" / "paper_4_4.toml").read_text()
    old = 'methods = ["toppra", "jerk_optimal"]'
    assert old in text
    return text.replace(old, f"methods = {methods}") + extra


def _compplan(args: list[str], plugins: Path) -> subprocess.CompletedProcess:
    """``compplan ARGS`` in a fresh interpreter with ``$COMPPLAN_TIMING_PATH`` = ``plugins``."""
    env = {**os.environ, "COMPPLAN_TIMING_PATH": str(plugins)}
    return subprocess.run(
        [sys.executable, "-m", "planner", *args],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        env=env,
        check=False,
    )


@pytest.fixture(scope="module")
def plugin_run(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The plug-in's folder, and ``compplan plan`` of paper_4_4 timed by TOPP-RA and the plug-in."""
    tmp = tmp_path_factory.mktemp("timing_plugin")
    plugins = tmp / "plugins"
    plugins.mkdir()
    (plugins / MODULE).write_text(PLUGIN)
    problem = tmp / "p44_plugin.toml"
    problem.write_text(_problem_text(f'["toppra", "{NAME}"]', f"\n[timing.{NAME}]\nstretch = 1.05\n"))
    out = tmp / "run"
    done = _compplan(["plan", str(problem), "--out", str(out)], plugins)
    assert done.returncode == 0, done.stderr[-3000:]
    return {"tmp": tmp, "plugins": plugins, "out": out, "stdout": done.stdout}


def test_the_plugin_plans_and_its_trajectory_is_in_the_summary(plugin_run):
    out = plugin_run["out"]
    s = json.loads((out / "summary.json").read_text())
    assert s["plan_status"] == "ok"
    t = s["timing"][NAME]
    assert t["status"] == "ok" and t["display_name"] == DISPLAY
    assert t["limits_enforced"] == ["velocity", "acceleration", "jerk"] and t["within_all_limits"]
    assert not t["reason"].startswith("ok") and t["reason"].startswith("velocity, acceleration and jerk within")
    assert s["problem"]["timing"][NAME] == {"stretch": 1.05}  # its [timing.septic] table
    # its rank puts it before TOPP-RA: the controller runs it, and the headline says so
    assert s["controller_trajectory"] == NAME and t["file"] == "trajectory.csv"
    assert s["headline"]["duration_method"] == NAME
    assert s["headline"]["duration_note"] == f"{DISPLAY}: the trajectory the controller runs (trajectory.csv)"
    assert set(s["timing"]) == {"toppra", NAME} and s["timing"]["toppra"]["file"] == "trajectory_toppra.csv"
    assert s["duration_s"][NAME] > s["duration_s"]["toppra"]  # TOPP-RA is time-optimal


def test_the_plugin_trajectory_file_is_within_every_limit(plugin_run):
    out = plugin_run["out"]
    s = json.loads((out / "summary.json").read_text())
    with (out / "trajectory.csv").open() as fh:
        rows = list(csv.reader(fh))
    header, data = rows[0], np.array(rows[1:], float)
    assert data.shape[0] > 10 and data[0, 0] == 0.0
    assert data[-1, 0] == pytest.approx(s["duration_s"][NAME])
    cols = {h: data[:, i] for i, h in enumerate(header)}
    used = []
    for prefix, key in (("qd", "velocity"), ("qdd", "acceleration"), ("qddd", "jerk")):
        lim = np.asarray(s["limits"][key])
        peak = np.max(np.abs(np.column_stack([cols[f"{prefix}{j}"] for j in range(1, 7)])), axis=0)
        assert np.all(peak <= lim * (1 + LIMIT_TOL)), (key, peak / lim)
        used.append(float(np.max(peak / lim)))
    assert max(used) > 0.5, used  # it uses its limits (not stretched to nothing)
    # rest to rest
    for prefix in ("qd", "qdd"):
        assert np.all(np.abs([cols[f"{prefix}{j}"][[0, -1]] for j in range(1, 7)]) < 1e-12)


def test_the_report_names_the_plugin(plugin_run):
    out = plugin_run["out"]
    html = (out / "report.html").read_text()
    assert f"{DISPLAY} (controller)" in html  # its row of the timing table
    assert "TOPP-RA" in html
    assert f"  {NAME}" in plugin_run["stdout"] and "-> trajectory.csv" in plugin_run["stdout"]


def test_the_plugin_trajectory_exports_for_ros2(plugin_run):
    target = plugin_run["tmp"] / "septic_ros2.yaml"
    done = _compplan(
        ["export", str(plugin_run["out"]), "--format", "ros2", "--out", str(target)], plugin_run["plugins"]
    )
    assert done.returncode == 0, done.stderr[-3000:]
    msg = yaml.safe_load(target.read_text())
    rows = (plugin_run["out"] / "trajectory.csv").read_text().splitlines()
    assert len(msg["points"]) == len(rows) - 1


def test_an_unknown_method_lists_the_plugin_too(plugin_run):
    problem = plugin_run["tmp"] / "unknown.toml"
    problem.write_text(_problem_text('["toppra", "nope"]'))
    done = _compplan(["plan", str(problem), "--out", str(plugin_run["tmp"] / "never")], plugin_run["plugins"])
    assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
    assert "timing.methods" in done.stderr and "'nope'" in done.stderr
    assert f"'{NAME}'" in done.stderr and "'toppra'" in done.stderr and "'jerk_optimal'" in done.stderr
    assert not (plugin_run["tmp"] / "never").exists()


def test_an_unknown_method_is_an_input_error_listing_the_registered_ones():
    import tomllib

    data = tomllib.loads(_problem_text('["toppra", "spline"]'))
    with pytest.raises(ProblemFileError) as err:
        problem_from_dict(data, "p.toml")
    assert isinstance(err.value, InputError)
    msg = str(err.value)
    assert msg.startswith("p.toml: key 'timing.methods'") and "'spline'" in msg
    assert all(repr(m) in msg for m in available_methods())


def test_method_option_tables_are_checked_against_the_method():
    import tomllib

    bad = tomllib.loads(_problem_text('["toppra", "jerk_optimal"]', "\n[timing.toppra]\ngridpoints = 1\n"))
    with pytest.raises(ProblemFileError, match=r"\[timing.toppra\]: option gridpoints must be an integer >= 2"):
        problem_from_dict(bad, "p.toml")
    unknown = tomllib.loads(_problem_text('["toppra", "jerk_optimal"]', "\n[timing.toppra]\nstretch = 2\n"))
    with pytest.raises(ProblemFileError, match=r"\[timing.toppra\]: unknown key\(s\) \['stretch'\]"):
        problem_from_dict(unknown, "p.toml")
    ok = tomllib.loads(_problem_text('["toppra", "jerk_optimal"]', '\n[timing.toppra]\ntime_law = "spline"\n'))
    pr = problem_from_dict(ok, "p.toml")
    assert pr.timing.options("toppra") == {"time_law": "spline"} and pr.timing.options("jerk_optimal") == {}
    no_controller = tomllib.loads(_problem_text("[]"))
    with pytest.raises(ProblemFileError, match="timing.methods"):
        problem_from_dict(no_controller, "p.toml")
