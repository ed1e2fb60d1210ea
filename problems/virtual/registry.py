"""Which physics the virtual robot simulates: its realisations, keyed by the effects' declarations.

Each model effect declares, once, the table of the virtual robot's configuration that simulates
its physics (:attr:`models.effects.Effect.simulation`): ``[effects.<simulation>]`` for a library
effect, the top-level ``[<simulation>]`` table for a declared one (``[stiffness]``,
``[registration]``).  The virtual robot registers its NumPy realisation of that physics with
:func:`simulates`, naming the effects it realises; the table's name, whether it is top-level and
the valid ``[effects.NAME]`` names are looked up in the effect registry, never written here a
second time.  A library effect's table may also be named as the effect
(``[effects.joint_error_map]`` for ``[effects.eccentricity]``).  ``[effects.outliers]`` is the
one table that simulates no model term (gross measurement errors, which the identification
handles by robust fitting): it names its table itself.

Only the declarations are read (names, ``simulation``, ``declared``), never the effects'
formulas: the realisations (:mod:`~problems.virtual.effects`) and the physics
(:mod:`~problems.virtual.physics`) stay an independent implementation, the bench the model is
tested against.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import models.effects as fx
from models.errors import PluginError

from .config import SimConfigError

_F = TypeVar("_F", bound=Callable[..., None])


@dataclass(frozen=True)
class Realisation:
    """The virtual robot's realisation of the physics of one or more model effects.

    Attributes
    ----------
    effects : tuple of str
        The model effects (registry names) whose physics it realises; they declare its table
        (``simulation``).  Empty for a disturbance that is no model term (``outliers``).
    keys : frozenset of str
        The keys its table accepts.
    method : str
        The method of :class:`~problems.virtual.effects.EffectPart` that realises it,
        called as ``method(table, where, rng)``: ``table`` the checked table (``None`` when an
        ``[effects.NAME]`` table is not given; a top-level table is always realised, ``{}`` when
        absent), ``where`` the source and table for messages, ``rng`` the realisation's generator.
    disturbance : str
        The ``[effects.NAME]`` table of a realisation with no model effect (else empty).
    """

    effects: tuple[str, ...]
    keys: frozenset[str]
    method: str
    disturbance: str = ""

    @property
    def table(self) -> str:
        """Its table's name: the effects' ``simulation`` declaration."""
        return fx.effect(self.effects[0]).simulation if self.effects else self.disturbance

    @property
    def top_level(self) -> bool:
        """Whether its table is a top-level one (the declared model's), not an ``[effects.NAME]``."""
        return bool(self.effects) and fx.effect(self.effects[0]).declared

    @property
    def spellings(self) -> tuple[str, ...]:
        """The names its table may be given: the declared one, then each effect's name where it
        differs (``[effects.NAME]`` tables only)."""
        if self.top_level:
            return (self.table,)
        return tuple(dict.fromkeys((self.table, *self.effects)))


_REALISATIONS: list[Realisation] = []


def _declared_table(effects: tuple[str, ...]) -> None:
    """Refuse a realisation of effects that are not registered or declare no (or different) tables."""
    for name in effects:
        try:
            e = fx.effect(name)
        except KeyError:
            raise PluginError(f"the virtual robot realises effect '{name}', which is not registered") from None
        if not e.simulation:
            raise PluginError(f"the virtual robot realises effect '{name}', which declares no `simulation` table")
    kinds = {(fx.effect(n).simulation, fx.effect(n).declared) for n in effects}
    if len(kinds) > 1:
        raise PluginError(
            f"one realisation of effects {list(effects)}, which declare different tables: {sorted(kinds)}"
        )


def simulates(*effects: str, keys: Iterable[str], disturbance: str = "") -> Callable[[_F], _F]:
    """Method decorator: register a method of :class:`~problems.virtual.effects.EffectPart`
    as the virtual robot's realisation of the physics of ``effects`` (model effect names).

    Realisations run in the order they are registered (the order of the checks, and of the random
    draws).  ``keys``: the keys of the table.  ``disturbance``: the ``[effects.NAME]`` table of a
    realisation of no model effect (then ``effects`` is empty).
    """
    if bool(effects) == bool(disturbance):
        raise PluginError("simulates: give the model effects realised, or the table of a disturbance, not both")
    _declared_table(effects)

    def deco(fn: _F) -> _F:
        r = Realisation(tuple(effects), frozenset(keys), fn.__name__, disturbance)
        taken = {s for q in _REALISATIONS for s in q.spellings} | {q.method for q in _REALISATIONS}
        clash = sorted(taken & {*r.spellings, r.method})
        if clash:
            raise PluginError(f"simulates: {clash} already realised")
        _REALISATIONS.append(r)
        return fn

    return deco


def realisations(top_level: bool | None = None) -> tuple[Realisation, ...]:
    """The registered realisations in their order (only the top-level or ``[effects.NAME]`` ones
    when ``top_level`` is given)."""
    return tuple(r for r in _REALISATIONS if top_level is None or r.top_level == top_level)


def realisation(effect: str) -> Realisation | None:
    """The realisation of model effect ``effect`` (None: the virtual robot does not simulate it)."""
    return next((r for r in _REALISATIONS if effect in r.effects), None)


def effect_tables() -> dict[str, Realisation]:
    """Every valid ``[effects.NAME]`` name -> its realisation, in realisation order."""
    return {s: r for r in realisations(top_level=False) for s in r.spellings}


def top_level_tables() -> tuple[str, ...]:
    """The top-level tables of the declared model's simulation (``stiffness``, ``registration``)."""
    return tuple(r.table for r in realisations(top_level=True))


def not_simulated() -> dict[str, str]:
    """Registered model effects the virtual robot does not simulate -> why (one line each)."""
    out = {}
    for e in fx.registry():
        if realisation(e.name) is not None:
            continue
        table = f"[{'' if e.declared else 'effects.'}{e.simulation}]"
        other = next((r for r in _REALISATIONS if r.table == e.simulation and r.top_level == e.declared), None)
        if not e.simulation:
            out[e.name] = "declares no table of the virtual robot (its `simulation` is empty)"
        elif other is not None:
            out[e.name] = (
                f"declares the table {table}, which the virtual robot realises as effect(s) "
                f"{', '.join(other.effects) or other.table} only"
            )
        else:
            out[e.name] = (
                f"declares the table {table}, which the virtual robot does not realise "
                "(problems/virtual/effects.py, @simulates)"
            )
    return out


def _unknown_effect_hint(name: str) -> str:
    """Why ``[effects.name]`` is not a table, when ``name`` is a model effect or a top-level table."""
    missing = not_simulated()
    if name in missing:
        return f"Effect '{name}' is not simulated by the virtual robot: it {missing[name]}."
    declaring = [e.name for e in fx.registry() if e.simulation == name and e.name in missing]
    if declaring:
        return (
            f"[effects.{name}] is the table of effect(s) {', '.join(declaring)} (Effect.simulation), which the "
            "virtual robot does not realise (problems/virtual/effects.py, @simulates)."
        )
    r = realisation(name)
    if r is not None and r.top_level:
        return f"Effect '{name}' is part of the declared model, simulated by the top-level table [{r.table}]."
    if name in top_level_tables():
        return f"[{name}] is a top-level table, not an [effects.NAME] table."
    return ""


def checked_effect_tables(where: str, cfg: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The ``[effects.NAME]`` tables of a configuration, checked: known names, tables, known keys,
    one spelling per table.  Raises :class:`SimConfigError` naming the source, table and key."""
    eff = cfg.get("effects", {})
    if not isinstance(eff, Mapping):
        raise SimConfigError(f"{where}: 'effects' must be a table of [effects.NAME] tables")
    tables = effect_tables()
    unknown = sorted(set(eff) - set(tables))
    if unknown:
        hints = " ".join(h for h in map(_unknown_effect_hint, unknown) if h)
        raise SimConfigError(
            f"{where}: unknown effect(s) {unknown}; known: {list(tables)}" + (f". {hints}" if hints else "")
        )
    out: dict[str, dict[str, Any]] = {}
    for name, t in eff.items():
        if not isinstance(t, Mapping):
            raise SimConfigError(f"{where}: [effects.{name}] must be a table")
        allowed = tables[name].keys
        bad = sorted(set(t) - allowed)
        if bad:
            raise SimConfigError(f"{where}: [effects.{name}]: unknown key(s) {bad}; allowed: {sorted(allowed)}")
        out[name] = dict(t)
    for r in realisations(top_level=False):
        given = [s for s in r.spellings if s in out]
        if len(given) > 1:
            raise SimConfigError(
                f"{where}: {' and '.join(f'[effects.{s}]' for s in given)} are two spellings of "
                f"the same effect ({', '.join(r.effects)}); give one of them, with all its entries"
            )
    return out
