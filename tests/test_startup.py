"""What a command imports and builds before its work: libraries are imported on demand
(``compplan --version`` imports none of them; a plan without its report does not import
pyplot) and the jerk-limited NLP's derivatives are built once per process.  Behaviour, not
timings: the import checks read ``sys.modules`` of a fresh interpreter."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: Libraries that cost start-up time and that ``compplan --version`` must not import.
HEAVY = ("numpy", "casadi", "scipy", "matplotlib", "toppra", "ruckig", "dask", "eaik")


def _modules_after(code: str) -> list[str]:
    """The modules of :data:`HEAVY` (and ``matplotlib.pyplot``, ``scipy.stats``) imported by ``code``
    in a fresh interpreter."""
    probe = code + (
        "\nimport json, sys\n"
        f"print(json.dumps([m for m in {list(HEAVY) + ['matplotlib.pyplot', 'scipy.stats']!r} "
        "if m in sys.modules]))\n"
    )
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=False)
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
