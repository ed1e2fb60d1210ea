"""Time parametrisation of a joint-space path (TOPP-RA or Ruckig).

The input is a geometric path given as joint waypoints ``q_path`` (shape
``(N, n)``, rad, joint space). Every method times the *same* geometric path,
a natural cubic chord-length spline ``P(s)`` through the waypoints, with a
monotone scalar time law ``s(t)`` from rest to rest, so ``q(t) = P(s(t))``
follows the path exactly; the result is sampled every ``dt`` s and its peak
velocity, acceleration and jerk ratios are checked on a finer grid.

Modules, one job each:

:mod:`~problems.timing.trajectory`
    The data types: :class:`JointLimits`, :class:`TimingStatus`,
    :class:`Trajectory` (with CSV export).
:mod:`~problems.timing.path`
    The geometric path: waypoint checks, the spline, its derivatives and the
    path parameter.
:mod:`~problems.timing.verification`
    Sampling on the controller grid and the limit checks (peak ratios).
:mod:`~problems.timing.registry`
    The method registry, the shared tolerances (``LIMIT_RATIO_TOL``...), the
    dt bounds (``DT_MAX_S``) and :func:`time_parametrize`, which dispatches
    by method name.
:mod:`~problems.timing.toppra_method` (with :mod:`~problems.timing.toppra_law`)
    ``method="toppra"``: time-optimal under velocity and acceleration limits.
:mod:`~problems.timing.ruckig_method`
    ``method="ruckig"``: jerk-limited.

Each backend registers itself when imported (this package imports the
built-in ones), so adding a method means adding a module that builds a
:class:`TimingMethod` and calls :func:`register_method`, and importing it
here. The package prints nothing.
"""

from __future__ import annotations

from problems.timing.path import SplinePath
from problems.timing.registry import (
    DT_DEFAULT_S,
    DT_MAX_S,
    LIMIT_RATIO_TOL,
    MONOTONE_TOL,
    SHRINK_MARGIN_MAX,
    TimingMethod,
    available_methods,
    get_method,
    register_method,
    time_parametrize,
    unregister_method,
)
from problems.timing.trajectory import JointLimits, TimingStatus, Trajectory
from problems.timing.verification import VERIFY_OVERSAMPLE

# Built-in backends: importing them registers "toppra" and then "ruckig"; the
# order is the order of VALID_METHODS and of the error messages.
from problems.timing import toppra_method  # isort: skip
from problems.timing import ruckig_method  # isort: skip
from problems.timing import jerk_optimal  # isort: skip
from problems.timing.ruckig_method import (
    RUCKIG_BUDGET_FRACTIONS,
    RUCKIG_CONSISTENCY_TOL,
    RUCKIG_MAX_ITERATIONS,
    RUCKIG_SHRINK_MARGIN,
)
from problems.timing.toppra_method import (
    SHRINK_MARGIN_FLOOR,
    TOPPRA_GRIDPOINTS_PER_WAYPOINT,
    TOPPRA_MAX_GRIDPOINTS,
    TOPPRA_MAX_ITERATIONS,
    TOPPRA_MAX_REFINEMENTS,
    TOPPRA_MIN_GRIDPOINTS,
    TOPPRA_REFINE_FACTOR,
    TOPPRA_REFINE_MIN_EXCESS,
    TOPPRA_SHRINK_MARGIN,
    TOPPRA_SMOOTHING_S,
    TOPPRA_TIME_LAW,
    TOPPRA_TIME_LAWS,
)

#: Names of the built-in methods, in registration order (a snapshot taken at
#: import; :func:`available_methods` also lists methods registered later).
VALID_METHODS: tuple[str, ...] = available_methods()

__all__ = [
    # public API (as exported by the former problems/timing.py)
    "LIMIT_RATIO_TOL",
    "JointLimits",
    "Trajectory",
    "TimingStatus",
    "VALID_METHODS",
    "time_parametrize",
    # registry and dt bounds
    "DT_DEFAULT_S",
    "DT_MAX_S",
    "TimingMethod",
    "available_methods",
    "get_method",
    "register_method",
    "unregister_method",
    "SplinePath",
    # named constants (tolerances and defaults) kept importable from here
    "MONOTONE_TOL",
    "SHRINK_MARGIN_MAX",
    "SHRINK_MARGIN_FLOOR",
    "VERIFY_OVERSAMPLE",
    "TOPPRA_MIN_GRIDPOINTS",
    "TOPPRA_GRIDPOINTS_PER_WAYPOINT",
    "TOPPRA_TIME_LAWS",
    "TOPPRA_TIME_LAW",
    "TOPPRA_SMOOTHING_S",
    "TOPPRA_MAX_REFINEMENTS",
    "TOPPRA_REFINE_FACTOR",
    "TOPPRA_MAX_GRIDPOINTS",
    "TOPPRA_REFINE_MIN_EXCESS",
    "TOPPRA_MAX_ITERATIONS",
    "TOPPRA_SHRINK_MARGIN",
    "RUCKIG_MAX_ITERATIONS",
    "RUCKIG_SHRINK_MARGIN",
    "RUCKIG_BUDGET_FRACTIONS",
    "RUCKIG_CONSISTENCY_TOL",
    # backend modules
    "ruckig_method",
    "toppra_method",
]
