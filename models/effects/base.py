"""The effect plug-in interface: parameter and constant declarations, the registry, the layout.

An *effect* is one module of :mod:`models.effects` that defines a subclass of
:class:`Effect` and registers it with :func:`register`.  It declares

* its parameters (:class:`ParamGroup`: name, unit, typical scale, default
  value, bounds, which exist for a given robot),
* the constants its formula needs (:class:`ConstGroup`),
* its symbolic CasADi term, as one or more *hooks* called by the model graph
  (:mod:`models.effects.graph`) in a fixed order of phases:

  1. ``geometry(ctx, dh)``       -- changes the DH parameters (offsets, errors, thermal);
  2. ``moment_arm(ctx)``         -- where the external force acts relative to the TCP;
  3. ``joint_torque(ctx)``       -- joint torques beyond those of the external wrench;
  4. ``joint_deflection(ctx, tau)`` -- joint deflection as a function of the joint torques;
  5. ``point_displacement(ctx, point)`` -- displacement of a point not through the joints;
  6. ``measurement(ctx, p)``     -- from the base frame to the measuring instrument;

* which data excite it (``needs``: ``"load"``, ``"time"``, ``"temperature"``),
* which table of the virtual robot's configuration simulates its physics
  (``simulation``: the one place that names it; the virtual robot,
  :mod:`problems.virtual`, registers its realisation under the effect's name and reads
  only this declaration, never the formulas, so that a test compares two implementations).

Every parameter of every registered effect lives in one flat vector ``theta``
whose layout (:data:`PARAMETER_GROUPS`, built from the registry) does not depend
on the robot; an effect that is not active keeps its parameters at their default
value, where it vanishes.  Constants live in one flat vector ``const`` whose
layout (:data:`CONST_GROUPS`) is likewise built from the declarations, so no
code indexes it by hand.

Units are SI throughout (see ``docs/conventions.md``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
from collections.abc import Callable

import numpy as np

from models.errors import InputError, PluginError
from models.robot import Robot

if TYPE_CHECKING:  # pragma: no cover
    from .graph import Context

#: A value given per robot: a constant, or a function of the robot description.
PerRobot = Callable[[Robot], Any] | float | None

#: Two consecutive joint axes count as parallel (Hayati parameter ``beta`` added)
#: when ``|sin(alpha)|`` is below this (dimensionless).
PARALLEL_AXIS_TOL = 1e-6

#: Joint torque scale floor (N*m) used when a joint sees no torque in the data.
TORQUE_SCALE_FLOOR_NM = 1.0

#: Phases (hook names) in the order the graph calls them.
PHASES = ("geometry", "moment_arm", "joint_torque", "joint_deflection", "point_displacement", "measurement")

#: Where an effect acts: on the arm (planning and measurement) or on the measurement only
#: (registration, drift of the instrument).
ARM, MEASUREMENT = "arm", "measurement"


def _resolve(v: PerRobot, robot: Robot, n: int, default: float) -> np.ndarray:
    if v is None:
        return np.full(n, default, dtype=float)
    if callable(v):
        out = np.asarray(v(robot), dtype=float).reshape(-1)
    else:
        out = np.asarray(v, dtype=float).reshape(-1)
    return np.broadcast_to(out, (n,)).astype(float) if out.size in (1, n) else out


@dataclass(frozen=True)
class ParamGroup:
    """A group of parameters of one effect.

    Attributes
    ----------
    key : str
        Group name, e.g. ``"geometric.da"`` (used in model files).
    labels : tuple of str
        One name per parameter, e.g. ``"da[1]"`` (reports).
    unit : str or tuple of str
        SI unit, one for the group or one per parameter.
    scale : float or callable(robot) -> array
        Typical magnitude in the parameter's unit (scaling, identifiability).
    default : float or callable(robot) -> array
        Value when the effect is not active (where it vanishes), also the
        identification's start and the value of held parameters.
    bounds : (float, float) or None
        Box bounds of every parameter of the group (projected LM steps).
    eligible : callable(robot) -> bool array, or None
        Which parameters exist for the robot (``None``: all).
    """

    key: str
    labels: tuple[str, ...]
    unit: str | tuple[str, ...]
    scale: PerRobot = 1.0
    default: PerRobot = 0.0
    bounds: tuple[float, float] | None = None
    eligible: Callable[[Robot], np.ndarray] | None = None

    @property
    def size(self) -> int:
        return len(self.labels)

    def units(self) -> list[str]:
        return [self.unit] * self.size if isinstance(self.unit, str) else list(self.unit)


@dataclass(frozen=True)
class ConstGroup:
    """A named block of the constant vector (not identified; fixed per model).

    ``default(robot)`` gives its value when a model is built from a robot file alone.
    """

    key: str
    size: int
    default: PerRobot = 0.0
    doc: str = ""


def joint_labels(prefix: str) -> tuple[str, ...]:
    """``prefix[1] .. prefix[6]``."""
    return tuple(f"{prefix}[{i + 1}]" for i in range(6))


def xyz_labels(prefix: str) -> tuple[str, ...]:
    """``prefix.x, prefix.y, prefix.z``."""
    return tuple(f"{prefix}.{c}" for c in "xyz")


def link_lengths(robot: Robot) -> np.ndarray:
    """Length of each DH link (row), ``sqrt(a^2 + d^2)``, m, shape (6,)."""
    return np.hypot(robot.a, robot.d)


def mean_compliance(robot: Robot) -> float:
    """Mean joint compliance ``mean(1/k)``, rad/(N*m)."""
    return float(np.mean(1.0 / robot.stiffness))


class Effect:
    """Base class of an effect plug-in (see the module docstring).

    Class attributes
    ----------------
    name : str
        Library name (``effects`` in model files, ``--include`` on the command line).
    order : int
        Position in the registry (parameter layout, identification priority and hook order).
    acts_on : {"arm", "measurement"}
        ``"measurement"`` effects (registration, drift) are left out of planning.
    declared : bool
        Part of the declared model (always fitted), not a library candidate.
    groups : tuple of ParamGroup
        Parameters owned by this effect.
    frees : tuple of str
        Parameter groups (of any effect) it frees when added in identification
        (defaults to its own groups).
    subsumes : tuple of str
        Effects it contains (``geometric`` contains ``joint_offset``).
    constants : tuple of ConstGroup
    needs : tuple of str
        Data it needs to be testable: ``"load"`` (a varying wrench), ``"time"``,
        ``"temperature"``.
    formula : str
        One line stating the addition to the model (reports, docs).
    simulation : str
        The table of the virtual robot's configuration that simulates the physics it models:
        ``[effects.<simulation>]`` for a library effect (which may also be named as the effect),
        the top-level ``[<simulation>]`` table for a declared one.  The virtual robot's NumPy
        realisation of it is registered under the effect's name
        (``problems/virtual/effects.py``, ``@simulates``; ``problems.virtual.not_simulated()``
        lists the effects without one).  Empty: the virtual robot does not simulate it.
    """

    name: str = ""
    order: int = 100
    acts_on: str = ARM
    declared: bool = False
    groups: tuple[ParamGroup, ...] = ()
    frees: tuple[str, ...] = ()
    subsumes: tuple[str, ...] = ()
    constants: tuple[ConstGroup, ...] = ()
    needs: tuple[str, ...] = ()
    formula: str = ""
    simulation: str = ""

    # ---- hooks (override those the effect uses; see the module docstring) --------------
    def geometry(self, ctx: Context, dh: dict[str, Any]) -> dict[str, Any]:
        return dh

    def moment_arm(self, ctx: Context) -> Any | None:
        return None

    def joint_torque(self, ctx: Context) -> Any | None:
        return None

    def joint_deflection(self, ctx: Context, tau: Any) -> Any | None:
        return None

    def point_displacement(self, ctx: Context, point: Any) -> Any | None:
        return None

    def measurement(self, ctx: Context, p: Any) -> Any:
        return p

    def joints_acting(self, param: Callable[[str], np.ndarray]) -> np.ndarray | None:
        """Which joints (bool, (6,)) the effect's term acts on with the given parameter values
        (``param(group_key)`` returns a group's values), or None when it is not per joint.
        Used to say where a torque-nonlinear term is extrapolated beyond its data."""
        return None

    def caveats(
        self,
        param: Callable[[str], np.ndarray],
        const: Callable[[str], np.ndarray],
        tau: np.ndarray,
        lever_m: np.ndarray,
    ) -> list[str]:
        """Where this effect's prediction cannot be trusted along a path (one line each).

        Parameters
        ----------
        param, const : callable
            ``param(group_key)`` / ``const(block_key)``: the model's values.
        tau : ndarray, shape (N, 6)
            Joint torques at the planned (deflected) poses, N*m.
        lever_m : ndarray, shape (N, 6)
            TCP displacement per radian of each joint, m/rad (norm of the Jacobian's columns).
        """
        return []

    def in_use(self, const: Callable[[str], np.ndarray]) -> dict[str, np.ndarray] | None:
        """Which parameters of the effect's groups enter the model with these constants
        (``const(block_key)``): group key -> bool array; None when all do.  A parameter not in
        use is not eligible (no Jacobian column; see :func:`make_layout`)."""
        return None

    def angle_caveats(
        self, param: Callable[[str], np.ndarray], const: Callable[[str], np.ndarray], q: np.ndarray
    ) -> list[str]:
        """Where this effect's prediction cannot be trusted at the joint angles ``q`` (N, 6) rad
        (e.g. beyond the angle range it was identified on), one line each."""
        return []

    # ---- helpers -------------------------------------------------------------------
    @property
    def freed_groups(self) -> tuple[str, ...]:
        return self.frees or tuple(g.key for g in self.groups)

    def overrides(self, phase: str) -> bool:
        """Whether the effect implements hook ``phase``."""
        return getattr(type(self), phase) is not getattr(Effect, phase)


_REGISTRY: dict[str, Effect] = {}


def register(cls: type[Effect]) -> type[Effect]:
    """Class decorator: register an effect plug-in (one instance per class)."""
    inst = cls()
    if not inst.name:
        raise PluginError(f"effect class {cls.__name__}: no name (expected a non-empty class attribute 'name')")
    if inst.name in _REGISTRY and type(_REGISTRY[inst.name]) is not cls:
        raise PluginError(
            f"effect '{inst.name}' is registered twice (by {type(_REGISTRY[inst.name]).__name__} "
            f"and {cls.__name__}); expected one class per effect name"
        )
    keys = {g.key for e in _REGISTRY.values() if e.name != inst.name for g in e.groups}
    clash = keys & {g.key for g in inst.groups}
    if clash:
        raise PluginError(
            f"effect '{inst.name}': parameter group(s) {sorted(clash)} already declared by another "
            "effect; expected keys of its own"
        )
    _REGISTRY[inst.name] = inst
    _invalidate()
    return cls


def registry() -> list[Effect]:
    """Registered effects in registry order."""
    return sorted(_REGISTRY.values(), key=lambda e: (e.order, e.name))


def effect(name: str) -> Effect:
    """The registered effect ``name`` (KeyError if unknown)."""
    return _REGISTRY[name]


# ---- layouts (rebuilt when the registry changes) ----------------------------------------


@dataclass
class _Layouts:
    groups: tuple[tuple[ParamGroup, Effect], ...]
    slices: dict[str, slice]
    names: tuple[str, ...]
    n_params: int
    consts: tuple[ConstGroup, ...]
    const_slices: dict[str, slice]
    const_size: int
    base_consts: tuple[ConstGroup, ...] = field(default=())


_CACHE: dict[str, _Layouts] = {}


def _invalidate() -> None:
    _CACHE.clear()


#: Constants of the model graph itself (not of an effect).
def _base_consts() -> tuple[ConstGroup, ...]:
    return (
        ConstGroup("dh.a", 6, lambda r: r.a, "nominal DH a, m"),
        ConstGroup("dh.alpha", 6, lambda r: r.alpha, "nominal DH alpha, rad"),
        ConstGroup("dh.d", 6, lambda r: r.d, "nominal DH d, m"),
        ConstGroup("dh.theta_offset", 6, lambda r: r.theta_offset, "nominal joint-angle offsets, rad"),
        ConstGroup(
            "tool",
            16,
            lambda r: np.asarray(r.tcp2flange).reshape(-1, order="F"),
            "tcp2flange (4x4, column-major): TCP frame -> flange frame",
        ),
        ConstGroup(
            "chain.frame02base",
            16,
            lambda r: np.asarray(r.frame02base).reshape(-1, order="F"),
            "frame02base (4x4, column-major): DH frame 0 -> base frame",
        ),
        ConstGroup(
            "chain.flange2frame6",
            16,
            lambda r: np.asarray(r.flange2frame6).reshape(-1, order="F"),
            "flange2frame6 (4x4, column-major): flange frame -> DH frame 6",
        ),
        ConstGroup("gravity", 3, lambda r: r.gravity, "gravity acceleration, base frame, m/s^2"),
        ConstGroup(
            "compliance0", 6, lambda r: 1.0 / r.stiffness, "nominal joint compliances 1/k of the robot file, rad/(N*m)"
        ),
        ConstGroup("tau_scale", 6, 1.0, "joint torque scale of the load-dependent effects, N*m"),
    )


def layouts() -> _Layouts:
    """The parameter and constant layouts of the current registry."""
    lay = _CACHE.get("x")
    if lay is not None:
        return lay
    groups: list[tuple[ParamGroup, Effect]] = []
    consts = list(_base_consts())
    for e in registry():
        groups += [(g, e) for g in e.groups]
        consts += list(e.constants)
    slices, names, k = {}, [], 0
    for g, _e in groups:
        slices[g.key] = slice(k, k + g.size)
        names += list(g.labels)
        k += g.size
    cslices, kc = {}, 0
    for c in consts:
        if c.key in cslices:
            raise PluginError(f"constant '{c.key}' declared twice (by two effects); expected keys of its own")
        cslices[c.key] = slice(kc, kc + c.size)
        kc += c.size
    lay = _Layouts(tuple(groups), slices, tuple(names), k, tuple(consts), cslices, kc)
    _CACHE["x"] = lay
    return lay


def default_constants(robot: Robot) -> np.ndarray:
    """The constant vector of ``robot`` with every block at its declared default."""
    lay = layouts()
    c = np.zeros(lay.const_size)
    for g in lay.consts:
        c[lay.const_slices[g.key]] = _resolve(g.default, robot, g.size, 0.0)
    return c


def set_const(const: np.ndarray, key: str, value: Any) -> np.ndarray:
    """Copy of ``const`` with block ``key`` set to ``value``.

    ``value`` is flat (the block's own layout, see its :class:`ConstGroup` doc) or a 3x3
    or 4x4 matrix, which is stored column-major (CasADi's ``reshape``); any other 2-D
    shape is refused, since its flattening order would be a guess.
    """
    s = layouts().const_slices[key]
    out = np.array(const, dtype=float, copy=True)
    v = np.asarray(value, dtype=float)
    if v.ndim > 1 and v.shape not in ((3, 3), (4, 4)):
        raise InputError(
            f"constant '{key}': expected a flat array of {s.stop - s.start} values or a 3x3 or 4x4 "
            f"matrix, got shape {v.shape}"
        )
    flat = v.reshape(-1, order="F") if v.ndim > 1 else v.reshape(-1)
    if flat.size != s.stop - s.start:
        raise InputError(f"constant '{key}': expected {s.stop - s.start} values, got {flat.size}")
    out[s] = flat
    return out


def get_const(const: np.ndarray, key: str) -> np.ndarray:
    """Block ``key`` of a constant vector (flat)."""
    return np.asarray(const, dtype=float)[layouts().const_slices[key]]


@dataclass
class ModelLayout:
    """Robot-specific view of the parameter vector.

    Attributes
    ----------
    nominal : ndarray, shape (N_PARAMS,)
        Default of each parameter (the effect vanishes there; held parameters sit there).
    scale : ndarray, shape (N_PARAMS,)
        Typical magnitude, in the parameter's unit.
    eligible : ndarray of bool, shape (N_PARAMS,)
        Whether the parameter exists for this robot.
    lower, upper : ndarray, shape (N_PARAMS,)
        Box bounds (``-inf``/``inf`` where none).
    units : list of str
    """

    robot: Robot
    nominal: np.ndarray
    scale: np.ndarray
    eligible: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    units: list[str]

    @property
    def names(self) -> tuple[str, ...]:
        return layouts().names

    def indices(self, groups: tuple[str, ...] | list[str]) -> np.ndarray:
        """Indices of the eligible parameters of the given groups."""
        sl = layouts().slices
        idx = [np.arange(sl[g].start, sl[g].stop) for g in groups]
        if not idx:
            return np.zeros(0, dtype=int)
        allidx = np.concatenate(idx)
        return allidx[self.eligible[allidx]]

    def effect_indices(self, name: str) -> np.ndarray:
        """Indices of the eligible parameters an effect frees (``"base"``: the declared model)."""
        if name == "base":
            return self.indices([g.key for e in registry() if e.declared for g in e.groups])
        return self.indices(list(effect(name).freed_groups))


def make_layout(robot: Robot, const: np.ndarray | None = None) -> ModelLayout:
    """Defaults, scales, bounds and eligibility of every parameter for ``robot``.

    ``const`` (the constant vector of a model; default the robot's defaults) decides which
    parameters of effects with data-dependent terms are in use (:meth:`Effect.in_use`, e.g.
    the slots of a joint error map that have a frequency); the others are not eligible."""
    lay = layouts()
    n = lay.n_params
    nominal, scale = np.zeros(n), np.ones(n)
    eligible = np.ones(n, dtype=bool)
    lower, upper = np.full(n, -np.inf), np.full(n, np.inf)
    units: list[str] = []
    for g, _e in lay.groups:
        s = lay.slices[g.key]
        nominal[s] = _resolve(g.default, robot, g.size, 0.0)
        scale[s] = _resolve(g.scale, robot, g.size, 1.0)
        if g.eligible is not None:
            eligible[s] = np.asarray(g.eligible(robot), dtype=bool).reshape(-1)
        if g.bounds is not None:
            lower[s], upper[s] = g.bounds
        units += g.units()
    cv = default_constants(robot) if const is None else np.asarray(const, dtype=float)
    for e in registry():
        use = e.in_use(lambda key: get_const(cv, key))
        for key, mask in (use or {}).items():
            eligible[lay.slices[key]] &= np.asarray(mask, dtype=bool).reshape(-1)
    return ModelLayout(
        robot=robot, nominal=nominal, scale=scale, eligible=eligible, lower=lower, upper=upper, units=units
    )
