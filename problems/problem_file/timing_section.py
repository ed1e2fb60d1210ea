"""The ``[timing]`` section of a problem file, validated against the timing registry.

Holds :class:`TimingSettings` (methods, controller period, method options), the older flat keys
of method options (:data:`TIMING_OPTION_KEYS`), :func:`check_timing` (settings against the
registry of :mod:`problems.timing`) and :func:`parse_timing` (the ``[timing]`` table and its
``[timing.<method>]`` tables). The error type and the value validators are
:mod:`problems.problem_file.values`; the package :mod:`problems.problem_file` re-exports the names
here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Mapping

from models.errors import InputError
from problems.problem_file.values import VALUES, ProblemFileError, err, flag, integer, positive, table
from problems.timing import (
    DT_DEFAULT_S,
    available_methods,
    controller_methods,
    default_methods,
    get_method,
    program_default_methods,
)
from problems.timing.registry import validate_options

# The timing methods a problem may name, those run when it names none, the default and largest
# controller period and each method's options are the registry's (problems.timing.registry).

#: ``[timing]`` keys that set a method's option (kept from before the ``[timing.<method>]``
#: tables): key -> (method, option).
TIMING_OPTION_KEYS: dict[str, tuple[str, str]] = {
    "toppra_gridpoints": ("toppra", "gridpoints"),
    "toppra_max_iterations": ("toppra", "max_iterations"),
    "ruckig_max_iterations": ("ruckig", "max_iterations"),
}


@dataclass(frozen=True)
class TimingSettings:
    """Time parametrisation: methods by name (registered in :mod:`problems.timing`), controller
    period (s) and method options.

    ``method_options`` holds the ``[timing.<method>]`` tables (option name -> value, as the
    method's ``options`` name them); ``toppra_gridpoints``, ``toppra_max_iterations`` and
    ``ruckig_max_iterations`` are the older flat keys of two of them (0: the method's default).
    """

    methods: tuple[str, ...] = field(default_factory=default_methods)
    dt: float = DT_DEFAULT_S
    toppra_gridpoints: int = 0  # 0: the timing module's default
    toppra_max_iterations: int = 0  # 0: default
    ruckig_max_iterations: int = 0  # 0: default
    dynamic: bool = False  # motor-side commands for the inertial torques (problems/dynamic.py)
    method_options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def options(self, method: str) -> dict[str, Any]:
        """Keyword options of ``method`` for ``problems.timing.time_parametrize``."""
        out: dict[str, Any] = {
            opt: getattr(self, key)
            for key, (m, opt) in TIMING_OPTION_KEYS.items()
            if m == method and getattr(self, key)
        }
        out.update(self.method_options.get(method, {}))
        return out


def check_timing(where: str, t: TimingSettings) -> None:
    """Validate timing settings against the registry of timing methods: methods registered and
    non-empty, one the controller can run among them, ``dt`` in (0, the smallest ``dt_max_s`` of
    the methods] s, each method's options known to it and valid.

    Parameters
    ----------
    where : str
        The source, used in error messages.
    t : TimingSettings

    Raises
    ------
    ProblemFileError
        Naming ``timing.methods``, ``timing.dt`` or the option's key; an unknown method's message
        lists the registered ones.
    """
    valid = list(available_methods())
    if not t.methods:
        raise err(where, "timing.methods", f"must name at least one of {valid}")
    for m in t.methods:
        if m not in valid:
            raise err(where, "timing.methods", f"has unknown method {m!r}; valid: {valid}")
    if not controller_methods(t.methods):
        raise err(
            where,
            "timing.methods",
            f"= {list(t.methods)} has no method whose trajectory the controller "
            f"can run; add one of {list(controller_methods())}",
        )
    dt_max = min(get_method(m).dt_max_s for m in t.methods)
    if not (0.0 < t.dt <= dt_max) or not math.isfinite(t.dt):
        raise err(where, "timing.dt", f"must be in (0, {dt_max}] s, got {t.dt!r}")
    for m in dict.fromkeys([*t.methods, *t.method_options]):
        if m not in valid:
            raise ProblemFileError(f"{where}: [timing.{m}]: unknown method {m!r}; valid: {valid}")
        try:
            validate_options(get_method(m), t.options(m))
        except InputError as exc:  # name the flat [timing] key when the bad option came from one
            flat = [k for k, (mm, opt) in TIMING_OPTION_KEYS.items() if mm == m and getattr(t, k) and opt in str(exc)]
            key = f"timing.{flat[0]}" if flat else f"[timing.{m}]"
            raise ProblemFileError(f"{where}: {key}: {exc}") from None


def _method_tables(where: str, tt: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The ``[timing.<method>]`` tables of ``[timing]``: method -> option -> value, each name
    known to the method (values are checked by :func:`check_timing`)."""
    out: dict[str, dict[str, Any]] = {}
    for m in available_methods():
        if m not in tt:
            continue
        tab, spec = tt[m], get_method(m)
        if not isinstance(tab, Mapping):
            raise err(where, f"timing.{m}", f"must be a table of {m}'s options {list(spec.options)}, got {tab!r}")
        VALUES.unknown_keys(f"{where}: [timing.{m}]", tab, spec.options)
        for key, (method, opt) in TIMING_OPTION_KEYS.items():
            if method == m and opt in tab and tt.get(key):
                raise ProblemFileError(f"{where}: give either 'timing.{key}' or 'timing.{m}.{opt}', not both")
        out[m] = dict(tab)
    return out


def parse_timing(where: str, data: Mapping[str, Any], program: bool = False) -> TimingSettings:
    """The ``[timing]`` section: methods (registered in :mod:`problems.timing`), controller period
    (s), method options (``[timing.<method>]`` tables and the older flat keys). ``program``: the path
    is a CAM program (the default methods are then :func:`~problems.timing.program_default_methods`)."""
    tt = table(where, data, "timing")
    methods = tt.get("methods", list(program_default_methods() if program else default_methods()))
    if not isinstance(methods, list) or not all(isinstance(m, str) for m in methods):
        raise err(
            where, "timing.methods", f"must be a list of method names {list(available_methods())}, got {methods!r}"
        )
    timing = TimingSettings(
        methods=tuple(methods),
        dt=positive(where, "timing.dt", tt.get("dt", DT_DEFAULT_S)),
        toppra_gridpoints=integer(where, "timing.toppra_gridpoints", tt.get("toppra_gridpoints", 0), 0),
        toppra_max_iterations=integer(where, "timing.toppra_max_iterations", tt.get("toppra_max_iterations", 0), 0),
        ruckig_max_iterations=integer(where, "timing.ruckig_max_iterations", tt.get("ruckig_max_iterations", 0), 0),
        dynamic=tt.get("dynamic", False),
        method_options=_method_tables(where, tt),
    )
    flag(where, "timing.dynamic", timing.dynamic)
    check_timing(where, timing)
    return timing
