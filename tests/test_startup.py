"""What a command imports and builds before its work: libraries are imported on demand
(``compplan --version`` imports none of them; ``--help`` no SciPy and no export format module; a
plan without its report neither pyplot nor SciPy's statistics) and the jerk-limited NLP's
derivatives are built once per process.  Behaviour, not
timings: the import checks read ``sys.modules`` of a fresh interpreter."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

#: Libraries that cost start-up time and that ``compplan --version`` must not import.
HEAVY = ("numpy", "casadi", "scipy", "matplotlib", "toppra", "ruckig", "dask", "eaik")


def _modules_after(code: str, also: tuple[str, ...] = ()) -> list[str]:
    """The modules of :data:`HEAVY` (and ``matplotlib.pyplot``, ``scipy.stats``, and ``also``) imported
    by ``code`` in a fresh interpreter (without plug-in folders of export formats)."""
    names = list(HEAVY) + ["matplotlib.pyplot", "scipy.stats", *also]
    probe = code + f"\nimport json, sys\nprint(json.dumps([m for m in {names!r} if m in sys.modules]))\n"
    env = {k: v for k, v in os.environ.items() if k != "COMPPLAN_EXPORT_PATH"}
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=False, env=env)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_version_imports_no_library():
    out = _modules_after(
        "from planner.cli import main\ntry:\n    main(['--version'])\n"
        "except SystemExit as exc:\n    assert exc.code == 0\n"
    )
    assert out == []


@pytest.mark.parametrize("argv", [["-v", "--version"], ["--bogus", "--version"], ["--version", "plan"]])
def test_version_fast_path_answers_as_the_parser_does(argv):
    from planner.cli import _asks_version

    assert _asks_version(argv)


@pytest.mark.parametrize("argv", [["-h", "--version"], ["plan", "--version"], ["--", "--version"], []])
def test_version_fast_path_leaves_other_lines_to_the_parser(argv):
    from planner.cli import _asks_version

    assert not _asks_version(argv)


def test_version_prints_what_the_parser_prints(capsys):
    from planner.cli import build_parser, main, version_line

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    fast = capsys.readouterr().out
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--version"])
    assert fast == capsys.readouterr().out == version_line() + "\n"


#: What the help of the command line must not import (the parser is built without them).
NOT_FOR_HELP = ("scipy", "matplotlib", "toppra", "ruckig", "dask", "eaik")
#: The export package's format modules (and the ROS 2 check's quintic): the parser offers the
#: formats' names without importing them.
FORMAT_MODULES = tuple(f"planner.export.{m}" for m in ("krl", "rapid", "ros2", "rosbag2", "urscript", "quintic"))


@pytest.mark.parametrize("argv", [["--help"], ["plan", "--help"], ["export", "--help"]])
def test_help_imports_no_scipy(argv):
    """``compplan --help`` and a command's help build the whole parser (every command, the export
    formats' names) without SciPy, matplotlib or the timing libraries, and without a format module."""
    code = (
        f"from planner.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit as exc:\n    assert exc.code == 0\n"
    )
    out = _modules_after(code, also=("problems.dynamic", *FORMAT_MODULES))
    assert [m for m in out if m.split(".")[0] in NOT_FOR_HELP or m.startswith("planner.export.")] == []
    assert "problems.dynamic" not in out


def test_the_parser_offers_every_format_without_importing_them():
    """The ``--format`` / ``--export`` choices are the registered formats' names."""
    code = (
        "from planner.cli import build_parser\nimport sys\n"
        "p = build_parser()\n"
        "sub = next(a for a in p._actions if a.dest == 'command').choices\n"
        "offered = [next(a.choices for a in sub[c]._actions if a.dest == d) for c, d in "
        "(('export', 'format'), ('plan', 'export'), ('demo', 'export'))]\n"
        f"imported = [m for m in {FORMAT_MODULES!r} if m in sys.modules]\n"
        "from planner.export import EXPORT_FORMATS\n"
        "assert all(list(o) == list(EXPORT_FORMATS) for o in offered), (offered, EXPORT_FORMATS)\n"
        "print(imported)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "COMPPLAN_EXPORT_PATH"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_builtin_formats_are_what_the_modules_register():
    """:data:`planner.export.BUILTIN_FORMATS` names the formats the package's modules register, in the
    order they register (a new built-in format adds its name there)."""
    code = (
        "import planner.export.registry as e\ne.load_formats()\n"
        "print(list(e._FORMATS) == list(e.BUILTIN_FORMATS) == list(e.formats()), list(e._FORMATS))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "COMPPLAN_EXPORT_PATH"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("True"), r.stdout


def test_formats_are_listed_in_one_order_whatever_was_imported_first():
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            "import planner.export.urscript, planner.export.ros2\nfrom planner.export import formats, BUILTIN_FORMATS\n"
            "print(list(formats()) == list(BUILTIN_FORMATS))",
        ],
        capture_output=True,
        text=True,
        check=False,
        env={k: v for k, v in os.environ.items() if k != "COMPPLAN_EXPORT_PATH"},
    )
    assert out.stdout.strip() == "True", out.stderr


def test_a_plan_without_its_report_imports_no_scipy_statistics(tmp_path):
    """A bare plan (``--no-report --no-figures``) reads the uncertainty module without the
    identification engine, and the export package without the dynamic compensation: neither SciPy's
    statistics nor its signal processing, and no pyplot."""
    argv = ["plan", "paper_4_4", "--out", str(tmp_path / "run"), "--no-report", "--no-figures"]
    out = _modules_after(
        f"from planner.cli import main\nassert main({argv!r}) == 0\n",
        also=("scipy.signal", "problems.dynamic", "problems.identify.engine"),
    )
    assert not {"scipy.stats", "scipy.signal", "matplotlib.pyplot", "problems.dynamic"} & set(out), out
    assert "problems.identify.engine" not in out


def test_light_modules_import_no_numerical_library():
    """The error classes and the report's tables come without CasADi / SciPy / matplotlib."""
    assert _modules_after("import models.errors, models.status") == []
    out = _modules_after("import planner.report.tables")
    assert "matplotlib" not in out and "scipy.stats" not in out


def test_lazy_package_names_are_the_modules_names():
    import models
    from models.robot import load_robot
    from planner import report
    from planner.report.writer import write_report

    assert models.load_robot is load_robot and report.write_report is write_report
    assert set(models.__all__) <= set(dir(models)) and set(report.__all__) <= set(dir(report))
    with pytest.raises(AttributeError):
        models.no_such_name


def test_general_ik_solver_imports_scipy_on_demand():
    out = _modules_after("import models.ik")
    assert "scipy.stats" not in out


def test_toppra_is_imported_without_pyplot():
    out = _modules_after(
        "from problems.timing.toppra_import import import_toppra\n"
        "tp = import_toppra()\nassert tp.algorithm.TOPPRA and tp.constraint\n"
    )
    assert "toppra" in out and "matplotlib.pyplot" not in out


def test_toppras_plotting_still_reaches_pyplot():
    out = _modules_after(
        "from problems.timing.toppra_import import import_toppra\n"
        "import_toppra()\nimport toppra.algorithm.algorithm as a\nassert callable(a.plt.plot)\n"
    )
    assert "matplotlib.pyplot" in out


def test_jerk_optimal_solvers_of_one_nlp_share_its_derivatives():
    """The warm-start variant (and another iteration limit) reuses the first solver's gradient,
    Jacobian and Hessian functions instead of differentiating the NLP again."""
    from problems.timing import jerk_optimal as jo

    n_grid = min(jo.JERK_GRIDPOINTS)
    cold = jo._solver(n_grid, 2, jo.JERK_MAX_ITER)
    others = [jo._solver(n_grid, 2, jo.JERK_MAX_ITER, warm=True), jo._solver(n_grid, 2, 7)]
    for name, _option in jo._DERIVATIVE_OPTIONS:
        assert {hash(s.get_function(name)) for s in others} == {hash(cold.get_function(name))}, name
    other_nlp = jo._solver(n_grid, 1, jo.JERK_MAX_ITER)  # another NLP: its own functions
    assert hash(other_nlp.get_function("nlp_hess_l")) != hash(cold.get_function("nlp_hess_l"))
