"""Time parametrisation of a joint-space path (TOPP-RA, jerk-optimal, Ruckig, plug-ins).

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
    Sampling on the controller grid, the limit checks (peak ratios) and
    :func:`~problems.timing.verification.finish_trajectory`, the status and
    reason every method ends with.
:mod:`~problems.timing.registry`
    The method registry (:class:`TimingMethod`: name, options, checked limits,
    dt bound, default, controller preference, display name and texts), the
    shared tolerances (``LIMIT_RATIO_TOL``...), the dt bounds (``DT_MAX_S``,
    ``DT_DEFAULT_S``) and :func:`time_parametrize`, which dispatches by
    method name.
:mod:`~problems.timing.limit_use`
    Which limit binds, and why a trajectory stays under half of every limit.
:mod:`~problems.timing.toppra_method` (with :mod:`~problems.timing.toppra_law`)
    ``method="toppra"``: time-optimal under velocity and acceleration limits.
:mod:`~problems.timing.ruckig_method`
    ``method="ruckig"``: jerk-limited.
:mod:`~problems.timing.jerk_optimal`
    ``method="jerk_optimal"``: time-optimal under velocity, acceleration and
    jerk limits.

Each backend registers itself when imported. This package imports every
module it contains and every ``*.py`` module in the folders named by
``$COMPPLAN_TIMING_PATH`` (as ``problems.timing.<name>``, through
:func:`models.plugins.import_plugins`), so adding a method is adding one
module that builds a :class:`TimingMethod` and calls
:func:`register_method`: problem files, plans, summaries, reports and exports
pick it up. The package prints nothing.
"""

from __future__ import annotations

from models.plugins import import_plugins
from problems.timing.path import SplinePath
from problems.timing.registry import (
    DT_DEFAULT_S,
    DT_MAX_S,
    LIMIT_RATIO_TOL,
    MONOTONE_TOL,
    SHRINK_MARGIN_MAX,
    TimingMethod,
    available_methods,
    controller_methods,
    default_methods,
    program_default_methods,
    display_name,
    get_method,
    register_method,
    time_parametrize,
    unregister_method,
)
from problems.timing.trajectory import JointLimits, TimingStatus, Trajectory
from problems.timing.verification import VERIFY_OVERSAMPLE

#: The environment variable naming folders of timing-method plug-in modules.
TIMING_PATH_VARIABLE = "COMPPLAN_TIMING_PATH"

# Backends and plug-ins: importing them registers them; the built-in ones first, in this order
# (the order of available_methods() and of the error messages).
import_plugins(
    __name__,
    __path__,
    TIMING_PATH_VARIABLE,
    skip=("path", "registry", "trajectory", "verification", "limit_use", "toppra_law", "toppra_import", "jerk_law"),
    first=("toppra_method", "ruckig_method", "jerk_optimal", "lookahead"),
)

__all__ = [
    "LIMIT_RATIO_TOL",
    "JointLimits",
    "Trajectory",
    "TimingStatus",
    "time_parametrize",
    "DT_DEFAULT_S",
    "DT_MAX_S",
    "TimingMethod",
    "available_methods",
    "controller_methods",
    "default_methods",
    "program_default_methods",
    "display_name",
    "get_method",
    "register_method",
    "unregister_method",
    "SplinePath",
    "MONOTONE_TOL",
    "SHRINK_MARGIN_MAX",
    "VERIFY_OVERSAMPLE",
]
