"""Identifiability: which parameters the data can tell apart, in which priority.

:func:`select_identifiable` runs a pivoted Gram-Schmidt on the scaled Jacobian
columns in priority order (:func:`priority_order`: registration, measured point,
stiffness, then the effects in the order added); a parameter whose column is
(numerically) a combination of earlier ones is *held* at its nominal value and
reported with the parameters it aliases, one the data do not excite or determine is
held too.  :func:`structural_held` runs the same test on a rich synthetic design to
tell structural redundancy (e.g. a joint-1 offset and the registration) from too
few data.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from models.effects import PARAM_NAMES, ModelLayout, make_const, make_layout
from models.robot import Robot

from ..measurements import Measurements
from .evaluation import evaluator_for, make_rows, time_reference, torque_scale

#: A parameter whose scaled Jacobian column keeps less than this fraction of its
#: norm after projection on the columns of higher priority is redundant (held):
#: its variance would be inflated by more than ``1/IDENT_REL_TOL^2`` and its
#: estimate would rest on second-order effects of the model.
IDENT_REL_TOL = 1e-2
#: A parameter whose predicted standard deviation exceeds this many typical
#: magnitudes (``ModelLayout.scale``) is not determined by the data (held).
IDENT_MAX_STD_RATIO = 10.0
#: The parameter of a rotation about the last joint axis (held first when aliased).
LAST_AXIS_ROTATION = "dtheta[6]"
#: Rows of the synthetic design used to tell structural from data-caused
#: unidentifiability.
STRUCTURAL_DESIGN_ROWS = 240
#: A held parameter whose reason names one of these aliases with the registration or the
#: measured point (unregistered data): unobservable in the base frame.
REGISTRATION_ALIAS_MARKERS = ("registration.", "measured_point")


def select_identifiable(
    Js: np.ndarray, order: Sequence[int], sigma: float, names: Sequence[str] = PARAM_NAMES
) -> tuple[list[int], dict[int, str]]:
    """Pivoted Gram-Schmidt on scaled Jacobian columns in priority order.

    Parameters
    ----------
    Js : ndarray, shape (n, len(order))
        Columns of the weighted residual Jacobian times the parameter scales, in
        the order of ``order`` (weighted residual units per typical magnitude).
    order : sequence of int
        Parameter indices (priority order: earlier ones are kept first).
    sigma : float
        Current residual RMS (weighted units), for the excitation test (0: no test).
    names : sequence of str
        Parameter names (for the reasons).

    Returns
    -------
    kept : list of int
        Identifiable parameter indices.
    held : dict
        Held parameter index -> reason (names the parameters it cannot be told
        apart from, or states that the data do not excite it).
    """
    n = Js.shape[0]
    Q = np.zeros((n, 0))
    kept: list[int] = []
    held: dict[int, str] = {}
    for k, idx in enumerate(order):
        c = Js[:, k]
        nrm = float(np.linalg.norm(c))
        if nrm == 0.0 or not np.isfinite(nrm):
            held[idx] = "not excited by the data (no sensitivity)"
            continue
        res = c - Q @ (Q.T @ c)
        res = res - Q @ (Q.T @ res)
        rn = float(np.linalg.norm(res))
        if rn < IDENT_REL_TOL * nrm:
            held[idx] = _alias_reason(Q, c, kept, names)
            continue
        if sigma > 0 and sigma / rn > IDENT_MAX_STD_RATIO:
            held[idx] = (
                f"not determined by the data (predicted std {sigma / rn:.3g} typical magnitudes > "
                f"{IDENT_MAX_STD_RATIO:g})"
            )
            continue
        Q = np.column_stack([Q, res / rn])
        kept.append(idx)
    return kept, held


def _alias_reason(Q: np.ndarray, c: np.ndarray, kept: Sequence[int], names: Sequence[str]) -> str:
    """Reason of a redundant column ``c``: the kept parameters whose (orthogonalised)
    directions ``Q`` carry it (at most four, the largest first)."""
    if not kept:
        return "not excited by the data"
    contrib = np.abs(Q.T @ c)
    top = np.argsort(contrib)[::-1][:4]
    alias = [names[kept[j]] for j in top if contrib[j] > 0.05 * contrib.max()]
    return "cannot be told apart from " + ", ".join(alias)


@dataclass(frozen=True)
class Known:
    """Parts of the measurement set-up declared known (held) rather than identified.

    ``registration``: the measurement frame is the robot base frame (a tracker base calibration);
    ``measured_point``: the measured point (and, with orientation data, the measured frame) is the
    robot file's TCP (a tool calibration).  ``bool(known)`` is True when both are: the data are
    *registered*.
    """

    registration: bool = False
    measured_point: bool = False

    def __bool__(self) -> bool:
        return self.registration and self.measured_point

    @classmethod
    def of(cls, registered: bool | Known) -> Known:
        return registered if isinstance(registered, Known) else cls(bool(registered), bool(registered))

    def describe(self) -> str:
        parts = [w for w, k in (("registration", self.registration), ("measured point", self.measured_point)) if k]
        return " and ".join(parts) if parts else "nothing"


def priority_order(layout: ModelLayout, effects: Sequence[str], registered: bool | Known) -> list[int]:
    """Parameter indices in priority order: registration, point, stiffness, effects
    (registration and point only where not known, see :class:`Known`)."""
    known = Known.of(registered)
    order: list[int] = []
    if not known.registration:
        order += list(layout.indices(("reg.t", "reg.w")))
    if not known.measured_point:
        order += list(layout.indices(("tool.p", "tool.r")))
    order += list(layout.indices(("stiffness.s",)))
    for e in effects:
        for i in layout.effect_indices(e):
            if i not in order:
                order.append(int(i))
    # The rotation of the flange about the last joint axis is what position data of a point
    # near that axis cannot see: its sensitivity is the point's distance from the axis, and it
    # then aliases with dalpha[6] and da[6], which move the point the same way.  Last in
    # priority, it is the one held, so the identified flange is not turned about the tool axis
    # (which would turn the tool frame, and every tool-frame load and payload with it).
    last = [i for i in order if PARAM_NAMES[i] == LAST_AXIS_ROTATION]
    return [i for i in order if i not in last] + last


def structural_held(robot: Robot, effects: Sequence[str], registered: bool) -> set[int]:
    """Parameters held on a rich synthetic design (structural redundancy).

    The design: :data:`STRUCTURAL_DESIGN_ROWS` random configurations within the joint
    limits, random 50 N forces (every third row unloaded), temperature 15..35 deg C.
    """
    rng = np.random.default_rng(7)
    n = STRUCTURAL_DESIGN_ROWS
    lo, hi = np.maximum(robot.q_min, -np.pi), np.minimum(robot.q_max, np.pi)
    q = rng.uniform(lo, hi, (n, 6))
    F = np.zeros((n, 6))
    F[:, :3] = rng.normal(0, 50.0, (n, 3))
    F[::3] = 0.0
    m = Measurements(q=q, wrench=F, p=np.zeros((n, 3)), t=np.linspace(0, 1, n), temperature=np.linspace(15, 35, n))
    layout = make_layout(robot)
    tau_s, knots = torque_scale(robot, m)
    const = make_const(robot, np.eye(3), tau_s, True, knots=knots)
    ev = evaluator_for(robot)
    theta = layout.nominal.copy()
    rows = make_rows(m, time_reference(m), 20.0)
    _pred, qe = ev.measure(rows, theta, const)
    _p, J = ev.jacobian(rows, qe, theta, const)
    order = priority_order(layout, effects, registered)
    Js = J[:, order] * layout.scale[order][None, :]
    _kept, held = select_identifiable(Js, order, 0.0)
    return set(held)


def aliases_registration(reason: str) -> bool:
    """Whether a held parameter's reason makes it an alias of the registration or the
    measured point: it names one of them (:data:`REGISTRATION_ALIAS_MARKERS`) first, as the
    parameter that carries most of its column.  A parameter whose column is mostly that of
    another arm parameter (e.g. ``dd[3]`` of parallel joints, carried by ``dd[2]``) is
    compensated through that one."""
    if not any(k in reason for k in REGISTRATION_ALIAS_MARKERS):
        return False
    _head, sep, tail = reason.partition("cannot be told apart from ")
    if not sep:
        return True
    first = tail.split(",")[0].strip()
    return any(first.startswith(k) for k in REGISTRATION_ALIAS_MARKERS)
