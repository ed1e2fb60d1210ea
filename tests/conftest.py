"""Shared fixtures, the ``slow`` marker and the settings of the test session.

Tests run from a checkout with ``pip install .[test]``: ``python -m pytest -q`` runs every
test (the README's command, the one CI runs); ``python -m pytest -q -m "not slow"`` leaves out
the expensive ones for the inner loop (README, "Tests"; the marker is registered in
``pyproject.toml``).

What several modules read is computed once per session: the plans of shipped problems (in
memory and written into a session folder), the CLI runs several modules read.  A shared
folder is read-only by contract: a test that changes files copies it first
(``shutil.copytree(shared, tmp_path / ...)``); the session checks at its end that no shared
folder changed (:class:`SharedFolders`) and fails naming the files if one did.

numpy, CasADi and the packages under test are imported inside the fixtures, after the BLAS
setting below.
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import hashlib
import io
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    import numpy as np

#: BLAS threads per test process (and the processes it starts), unless the environment sets
#: them: the suite's matrices are small, and on a shared 2-core machine OpenBLAS's threads spin
#: for work that never comes (measured on a loaded 2-core machine: the false-attribution
#: identifications of tests/test_joint_error_map.py took 2.7x the CPU time with its default).
BLAS_THREADS = "1"
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
for _var in BLAS_THREAD_VARIABLES:
    os.environ.setdefault(_var, BLAS_THREADS)

#: The report figure cache of this test session (and the processes it starts): a fresh folder,
#: so no test reads a figure the user's runs cached, and the user's cache is left alone.
os.environ["COMPPLAN_FIGURE_CACHE"] = tempfile.mkdtemp(prefix="compplan-figures-")
atexit.register(shutil.rmtree, os.environ["COMPPLAN_FIGURE_CACHE"], True)

ROBOTS = ("ar5", "ur5", "ur10")

#: The output folder placeholder of the shared CLI runs' argument lists.
OUT = "{out}"


# ------------------------------------------------------------------------------ the slow marker
#: A test that reads one of these fixtures is slow (each costs seconds: a plan with its report,
#: identification campaigns, the shipped placement study).
SLOW_FIXTURES = frozenset(
    {
        "paper_report",
        "fast_payload_run",
        "effect_case",
        "map_case",
        "identified_ur10",
        "shipped_run",
        "maps_run",
        "plain_run",
    }
)

#: Slow tests of modules that carry no ``@pytest.mark.slow`` of their own: module file name ->
#: test function names (each measured above about one CPU-second).  The other modules mark
#: their slow tests where they are defined.
SLOW_TESTS: dict[str, frozenset[str]] = {
    "test_report.py": frozenset(
        {
            "test_trajectory_file_without_jerk_columns_is_stated",
            "test_run_without_trajectory_says_so",
            "test_other_timing_shapes_are_rendered",
            "test_serial_and_parallel_rendering_give_the_same_files",
            "test_compliance_map_is_cached_per_robot_and_options",
            "test_stale_figures_of_an_earlier_report_are_removed",
            "test_cli_report_and_map",
            "test_payload_and_tool_frame_loads_are_named_not_a_zero_base_force",
            "test_command_outputs_record_their_command_line",
            "test_identification_report_is_styled_and_explains_itself",
        }
    ),
    "test_one_model.py": frozenset(
        {
            "test_tool_frame_wrench_plan_lands_on_the_truth_robot",
            "test_plan_with_a_model_from_unregistered_data_says_the_base_frame_is_not_exact",
        }
    ),
    "test_plan.py": frozenset(
        {
            "test_machining_gain_and_figures",
        }
    ),
}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark slow the tests that read a :data:`SLOW_FIXTURES` fixture or that :data:`SLOW_TESTS`
    names; a name there that its module does not define is an error (the table cannot go stale)."""
    checked: set[str] = set()
    for item in items:
        if SLOW_FIXTURES.intersection(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
        module = getattr(item, "module", None)
        names = SLOW_TESTS.get(item.path.name)
        if module is None or names is None:
            continue
        if module.__name__ not in checked:
            checked.add(module.__name__)
            missing = sorted(n for n in names if not callable(getattr(module, n, None)))
            if missing:
                raise pytest.UsageError(
                    f"tests/conftest.py SLOW_TESTS names tests {module.__name__} does not define: {', '.join(missing)}"
                )
        if getattr(item, "originalname", item.name) in names:
            item.add_marker(pytest.mark.slow)


# ------------------------------------------------------------------------------ built-in arms
@functools.cache
def _model(name: str) -> tuple:
    from models import AnalyticIK, KinematicModel, load_robot

    robot = load_robot(name)
    return robot, KinematicModel(robot), AnalyticIK(robot)


@pytest.fixture(params=ROBOTS)
def robot_model_ik(request):
    """(robot, KinematicModel, AnalyticIK) for each built-in robot."""
    return _model(request.param)


def get_model(name: str) -> tuple:
    return _model(name)


@pytest.fixture
def rng() -> np.random.Generator:
    import numpy as np

    return np.random.default_rng(20261121)


def as_modified_dh(robot_dict: dict) -> dict:
    """The same UR-type chain rewritten in modified DH (row i holds a_{i-1}, alpha_{i-1});
    valid because a6 = alpha6 = 0 for these arms (see docs/conventions.md)."""
    rows = robot_dict["joints"]
    mdh = []
    for i in range(6):
        row = dict(rows[i])
        row["a"] = rows[i - 1]["a"] if i > 0 else 0.0
        row["alpha"] = rows[i - 1]["alpha"] if i > 0 else 0.0
        mdh.append(row)
    out = {**robot_dict, "convention": "modified_dh", "joints": mdh}
    out.pop("collision", None)  # its segments are given in the standard-DH frames
    return out


# ------------------------------------------------------------------------------ shared folders
def _digest(folder: Path) -> dict[str, str]:
    """SHA-256 of every file below ``folder`` (relative name -> hex digest)."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


class SharedFolders:
    """The session's shared output folders and their contents when written."""

    def __init__(self) -> None:
        self._digests: dict[Path, dict[str, str]] = {}

    def add(self, folder: Path) -> Path:
        self._digests[folder] = _digest(folder)
        return folder

    def changed(self) -> list[str]:
        """One line per shared folder whose files changed since it was written."""
        lines = []
        for folder, before in self._digests.items():
            after = _digest(folder) if folder.is_dir() else {}
            diff = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
            if diff:
                lines.append(f"{folder}: {', '.join(diff)}")
        return lines


@pytest.fixture(scope="session")
def shared_folders():
    """Registry of the shared folders; at the session's end, an error if a test changed one."""
    reg = SharedFolders()
    yield reg
    changed = reg.changed()
    if changed:
        pytest.fail("a test changed a shared folder (copy it first):\n" + "\n".join(changed), pytrace=False)


@dataclass(frozen=True)
class CliRun:
    """A ``compplan`` command run in this process: its output folder, exit status and output."""

    folder: Path
    code: int
    out: str
    err: str


class SharedCli:
    """``compplan`` commands run once per session, each into its own folder."""

    def __init__(self, factory: pytest.TempPathFactory, folders: SharedFolders) -> None:
        self._factory, self._folders = factory, folders
        self._runs: dict[tuple[str, ...], CliRun] = {}

    def run(self, *argv: str) -> CliRun:
        """``compplan ARGV`` with :data:`OUT` replaced by a new session folder (run once per
        ``argv``); fails the test that asked if the command fails."""
        if argv not in self._runs:
            from planner.cli import main

            folder = self._factory.mktemp("shared_" + "_".join(a for a in argv[:2] if a.isidentifier())) / "out"
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main([str(folder) if a == OUT else a for a in argv])
            assert code == 0, f"compplan {' '.join(argv)}: exit {code}\n{err.getvalue()}"
            self._runs[argv] = CliRun(self._folders.add(folder), code, out.getvalue(), err.getvalue())
        return self._runs[argv]


@pytest.fixture(scope="session")
def shared_cli(tmp_path_factory, shared_folders) -> SharedCli:
    return SharedCli(tmp_path_factory, shared_folders)


# ------------------------------------------------------------------------------ shipped problems
#: ``compplan plan paper_4_4`` without figures and report, as tests/test_plan.py checks it.
PAPER_RUN_ARGV = ("plan", "paper_4_4", "--out", OUT, "--no-figures", "--no-report")
#: ``compplan plan ur5_fast_payload``: dynamic compensation, with the report.
FAST_PAYLOAD_ARGV = ("plan", "ur5_fast_payload", "--out", OUT)


@pytest.fixture(scope="session")
def paper_result() -> Any:
    """The demo's plan (paper section 4.4 on ar5, ``run_demo``) in memory.  Read-only."""
    from models import load_robot
    from planner.demo import run_demo

    return run_demo(load_robot("ar5"))


@pytest.fixture(scope="session")
def paper_folder(paper_result, tmp_path_factory, shared_folders) -> Path:
    """``paper_result``'s files (``planner.demo.write_outputs``: no figures, no report)."""
    from planner.demo import write_outputs

    folder = tmp_path_factory.mktemp("paper_folder") / "run"
    write_outputs(paper_result, folder)
    return shared_folders.add(folder)


@pytest.fixture(scope="session")
def paper_report(paper_result, tmp_path_factory, shared_folders) -> Path:
    """``paper_result``'s files and report, the report built from the result with the report
    defaults (as ``compplan demo``)."""
    from planner.demo import write_outputs

    folder = tmp_path_factory.mktemp("paper_report") / "run"
    write_outputs(paper_result, folder, report=True)
    return shared_folders.add(folder)


@pytest.fixture(scope="session")
def paper_run(shared_cli) -> Path:
    """The folder of ``compplan plan paper_4_4 --out DIR --no-figures --no-report``."""
    return shared_cli.run(*PAPER_RUN_ARGV).folder


@pytest.fixture(scope="session")
def paper_run_output(shared_cli) -> str:
    """What ``compplan plan paper_4_4 ...`` (:data:`PAPER_RUN_ARGV`) printed on stdout."""
    return shared_cli.run(*PAPER_RUN_ARGV).out


@pytest.fixture(scope="session")
def fast_payload_run(shared_cli) -> Path:
    """The folder of ``compplan plan ur5_fast_payload --out DIR`` (with its report)."""
    return shared_cli.run(*FAST_PAYLOAD_ARGV).folder


@pytest.fixture(scope="session")
def small_virtual_model() -> tuple:
    """A small identification on the virtual UR5 (DH errors, 60 unloaded poses, 20 um noise; under a
    second): ``(robot, virtual_robot, data, model)``, the model with its covariance (format 2).
    Shared by the tests of the sigma, the design and the outputs: do not modify it."""
    from models import load_robot
    from problems.identify import identify
    from problems.virtual import VirtualRobot

    robot = load_robot("ur5")
    cfg = {
        "seed": 3,
        "campaign": {"poses": 60, "loaded_rows": 0, "unloaded_rows": 1},
        "noise": {"sigma_m": 2e-5},
        "effects": {"geometric": {}},
    }
    vr = VirtualRobot(robot, cfg)
    data = vr.campaign()
    return robot, vr, data, identify(robot, data, candidates=["geometric"]).model
