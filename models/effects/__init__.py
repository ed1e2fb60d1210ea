"""The effect library: one module per effect, each registering an :class:`Effect` plug-in.

Every module of this package other than ``base`` and ``graph`` (and every module in the
folders named by ``$COMPPLAN_EFFECT_PATH``) is imported here, so adding an effect is
adding a module that defines and registers it (see ``docs/architecture.md``).  The layouts below are built
from the registry once all
built-in modules are imported.
"""

from __future__ import annotations


from models.plugins import import_plugins

from . import base
from .base import (
    ARM,
    TORQUE_SCALE_FLOOR_NM,
    Effect,
    ModelLayout,
    default_constants,
    effect,
    get_const,
    layouts,
    make_layout,
    registry,
    set_const,
)

#: Extra folders searched for effect modules (``os.pathsep``-separated), so an installed
#: product can be extended without editing it: each ``*.py`` there is imported as
#: ``models.effects.<name>`` and registers its effect (relative imports such as
#: ``from .base import Effect`` work as for the built-in modules).
EFFECT_PATH_VARIABLE = "COMPPLAN_EFFECT_PATH"
import_plugins(__name__, __path__, EFFECT_PATH_VARIABLE, skip=("base", "graph"))

from .graph import LOAD_SIZE, ROW_SIZE, identification_functions  # noqa: E402 - the layouts need every effect registered first
from .link_compliance import beam_frames  # noqa: E402 - after the registration above
from .registration import cayley_np, cayley_vector  # noqa: E402 - after the registration above
from .stiffness_hardening import HARDENING_KNOT_QUANTILES, N_KNOTS  # noqa: E402 - after the registration above
from .thermal import THERMAL_REFERENCE_C  # noqa: E402 - after the registration above

_L = layouts()
#: Parameter groups ``(key, effect, labels, unit)`` in the order of ``theta``.
PARAMETER_GROUPS: tuple[tuple[str, str, list[str], str], ...] = tuple(
    (g.key, e.name, list(g.labels), g.unit if isinstance(g.unit, str) else "varies") for g, e in _L.groups
)
GROUP_SLICES: dict[str, slice] = dict(_L.slices)
N_PARAMS: int = _L.n_params
PARAM_NAMES: tuple[str, ...] = _L.names
CONST_SIZE: int = _L.const_size
CONST_SLICES: dict[str, slice] = dict(_L.const_slices)
#: Effects of the identification library (candidates), in registry order, plus ``outliers``
#: (robust fitting: not a model term).
LIBRARY: tuple[str, ...] = tuple(e.name for e in registry() if not e.declared) + ("outliers",)
#: Names of the declared (always present) parameter groups.
BASE_GROUPS: tuple[str, ...] = tuple(g.key for e in registry() if e.declared for g in e.groups)
#: Names of the registration's parameters (base frame -> measurement frame): translation ``reg.t``,
#: then rotation ``reg.w`` (Cayley vector).
REGISTRATION_NAMES: tuple[str, ...] = PARAM_NAMES[GROUP_SLICES["reg.t"]] + PARAM_NAMES[GROUP_SLICES["reg.w"]]
#: Effect plug-ins by name.
EFFECTS: dict[str, Effect] = {e.name: e for e in registry()}


def make_const(robot, R0=None, tau_scale=None, gravity_on: bool = False, beams=None, knots=None, extra=None):
    """The constant vector of ``robot`` (defaults from the declarations), with the
    data-dependent blocks given: registration ``R0`` (3x3), joint torque scales
    ``tau_scale`` (6, N*m, floored at :data:`TORQUE_SCALE_FLOOR_NM`), ``gravity_on``,
    beam frames (6, 3, 3), hardening knots (6, N_KNOTS, N*m; default: torque-scale
    quantiles) and ``extra``: any other blocks by key (e.g. ``error_map.freq``)."""
    import numpy as np

    c = default_constants(robot)
    if R0 is not None:
        c = set_const(c, "registration.R0", np.asarray(R0, dtype=float))
    ts = np.ones(6) if tau_scale is None else np.maximum(np.asarray(tau_scale, dtype=float), TORQUE_SCALE_FLOOR_NM)
    c = set_const(c, "tau_scale", ts)
    c = set_const(c, "gravity.on", [1.0 if gravity_on else 0.0])
    if beams is not None:
        c = set_const(
            c,
            "link_compliance.beams",
            np.concatenate([np.asarray(b, dtype=float).reshape(-1, order="F") for b in beams]),
        )
    kn = np.outer(ts, HARDENING_KNOT_QUANTILES) if knots is None else np.asarray(knots, dtype=float)
    c = set_const(c, "hardening.knots", kn.reshape(-1))
    for key, value in (extra or {}).items():
        c = set_const(c, key, np.asarray(value, dtype=float).reshape(-1))
    return c


__all__ = [
    "ARM",
    "CONST_SIZE",
    "CONST_SLICES",
    "EFFECTS",
    "GROUP_SLICES",
    "HARDENING_KNOT_QUANTILES",
    "LIBRARY",
    "LOAD_SIZE",
    "ModelLayout",
    "N_KNOTS",
    "N_PARAMS",
    "PARAMETER_GROUPS",
    "PARAM_NAMES",
    "ROW_SIZE",
    "THERMAL_REFERENCE_C",
    "TORQUE_SCALE_FLOOR_NM",
    "base",
    "beam_frames",
    "REGISTRATION_NAMES",
    "cayley_np",
    "cayley_vector",
    "effect",
    "get_const",
    "identification_functions",
    "layouts",
    "make_const",
    "make_layout",
    "registry",
    "set_const",
]
