"""The one model graph: kinematic chain plus effect hooks, as CasADi expressions.

The forward model of the loaded arm (all frames and vectors in the base frame
unless stated; SI units)::

    dh      = geometry hooks applied to the nominal DH table (offsets, errors, thermal)
    frames  = chain(q; dh)                       frame_i2base, i = 1..6 (frame 6: flange)
    W       = wrench on the TCP, [f (N); m (N*m)], base frame (the load, see models.load)
    tau     = J_v^T f + J_w^T (m + r x f) + joint-torque hooks (self-weight)
    dq      = sum of joint-deflection hooks(tau)  (linear springs, hardening, lost motion)
    q       = q_c + dq(q)                         deflected equilibrium (deflection at the deflected pose)
    p       = flange2base(q) * point + point-displacement hooks (link compliance)
    p_meas  = measurement hooks(p)                (registration, drift; identification only)

This module builds that graph once for every use: identification (parameters
symbolic, :func:`identification_functions`) and planning (parameters fixed,
:func:`arm_functions`), so there is one FK chain, one torque model and one
deflection model in the product.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any
from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

from models.errors import InputError

from . import base
from .base import Effect, layouts, registry
from .registration import cayley

#: Fixed-point iterations of the deflected equilibrium unrolled in the identification graph.
#: The map contracts by about ``|d dq / dq|`` per iteration (1e-3 .. 1e-1), so 5 iterations
#: leave far less than the measurement noise.
EQUILIBRIUM_UNROLL = 5

#: Fixed-point iterations restarted from the converged equilibrium to differentiate it:
#: the derivative error is of order ``|d dq/dq|^JACOBIAN_UNROLL`` (relative).
JACOBIAN_UNROLL = 1

#: Per-row inputs of the identification functions: q_c (6, rad), F (6, N and N*m, base
#: frame, on the TCP), tn (1), dT (1, K), kind (1: 0 position row, 1 orientation row), the
#: measured orientation of an orientation row (3, rotation vector of the measured frame in the
#: measurement frame, rad).
ROW_SIZE = 18

#: Load vector of the planning functions (see :mod:`models.load`):
#: ``[f_base (3) N, m_base (3) N*m, f_tool (3) N, m_tool (3) N*m, payload mass (1) kg,
#: payload centre of mass (3) m in the TCP frame, gravity (3) m/s^2 in the base frame]``.
LOAD_SIZE = 19


def link_transform(theta: Any, d: Any, a: Any, alpha: Any, convention: str) -> Any:
    """DH link transform A_i as a 4x4 CasADi expression.

    ``standard_dh``: ``Rz(theta) Tz(d) Tx(a) Rx(alpha)``;
    ``modified_dh``: ``Rx(alpha) Tx(a) Rz(theta) Tz(d)`` (a, alpha of the previous link).
    """
    ct, st = ca.cos(theta), ca.sin(theta)
    ca_, sa = ca.cos(alpha), ca.sin(alpha)
    if convention == "standard_dh":
        return ca.vertcat(
            ca.horzcat(ct, -st * ca_, st * sa, a * ct),
            ca.horzcat(st, ct * ca_, -ct * sa, a * st),
            ca.horzcat(0, sa, ca_, d),
            ca.horzcat(0, 0, 0, 1),
        )
    if convention == "modified_dh":
        return ca.vertcat(
            ca.horzcat(ct, -st, 0, a),
            ca.horzcat(st * ca_, ct * ca_, -sa, -sa * d),
            ca.horzcat(st * sa, ct * sa, ca_, ca_ * d),
            ca.horzcat(0, 0, 0, 1),
        )
    raise InputError(f"DH convention {convention!r}: expected 'standard_dh' or 'modified_dh'")


def _ry4(b: Any) -> Any:
    c, s = ca.cos(b), ca.sin(b)
    return ca.vertcat(ca.horzcat(c, 0, s, 0), ca.horzcat(0, 1, 0, 0), ca.horzcat(-s, 0, c, 0), ca.horzcat(0, 0, 0, 1))


def _is_zero(x: Any) -> bool:
    try:
        return bool(ca.DM(x).is_zero()) if not isinstance(x, (ca.SX, ca.MX)) else bool(x.is_zero())
    except Exception:
        return False


def chain(q: Any, dh: dict[str, Any], convention: str) -> list[Any]:
    """Frames ``frame_i2base`` (i = 1..6) of the chain ``frame02base A_i(q_i + theta_offset_i) Ry(beta_i)``.

    ``dh`` holds length-6 vectors ``a, alpha, d, theta_offset, beta`` (symbolic or numeric);
    ``beta`` is the Hayati angle of nominally parallel consecutive axes (0 elsewhere); and,
    for a chain whose DH frame 0 is not the base frame (a URDF chain), ``frame02base`` (4x4).
    """
    frames = []
    T = ca.SX.eye(4) if not isinstance(q, ca.MX) else ca.MX.eye(4)
    if dh.get("frame02base") is not None:
        T = dh["frame02base"]
    for i in range(6):
        A = link_transform(q[i] + dh["theta_offset"][i], dh["d"][i], dh["a"][i], dh["alpha"][i], convention)
        b = dh["beta"][i]
        if not _is_zero(b):
            A = ca.mtimes(A, _ry4(b))
        T = ca.mtimes(T, A)
        frames.append(T)
    return frames


def joint_axes(frames: Sequence[Any], convention: str, frame02base: Any = None) -> tuple[list[Any], list[Any]]:
    """Unit axis ``z`` and a point ``p`` of each joint, base frame (3-vectors); ``frame02base``
    is DH frame 0 in the base frame (None: the base frame itself)."""
    if convention == "standard_dh":
        first = ca.DM.eye(4) if frame02base is None else frame02base
        origin = [first] + list(frames[:-1])  # joint i turns about z_{i-1}
    else:
        origin = list(frames)  # joint i turns about z_i
    return [T[:3, 2] for T in origin], [T[:3, 3] for T in origin]


def geometric_jacobian(frames: Sequence[Any], p_tcp: Any, convention: str, frame02base: Any = None) -> Any:
    """Geometric Jacobian at point ``p_tcp`` by the vector-product method (paper eq. 10).

    Column i is ``[z_i x (p_tcp - p_i); z_i]`` (base frame), rows ``[v; w]``.
    """
    zs, ps = joint_axes(frames, convention, frame02base)
    return ca.horzcat(*[ca.vertcat(ca.cross(z, p_tcp - p), z) for z, p in zip(zs, ps)])


def load_wrench(R_tcp: Any, L: Any) -> Any:
    """Wrench on the TCP, base frame, from a load vector (see :data:`LOAD_SIZE`).

    ``f = f_base + R f_tool + m g``, ``m = m_base + R m_tool + (R c) x (m g)`` with ``R`` the
    TCP rotation (base <- TCP), ``c`` the payload's centre of mass in the TCP frame.
    """
    fb, mb, ft, mt = L[0:3], L[3:6], L[6:9], L[9:12]
    mass, com, g = L[12], L[13:16], L[16:19]
    fw = mass * g
    f = fb + ca.mtimes(R_tcp, ft) + fw
    m = mb + ca.mtimes(R_tcp, mt) + ca.cross(ca.mtimes(R_tcp, com), fw)
    return ca.vertcat(f, m)


class Context:
    """What a hook sees: parameters, constants, and the state of the arm being evaluated.

    Attributes
    ----------
    convention : str
    theta, const : CasADi vectors (symbolic or numeric)
    dT, tn : CasADi scalars
        Temperature minus the reference (K) and normalised campaign time (1).
    qc : CasADi vector (6,)
        The commanded joint angles, rad (what the controller was told; angle-dependent
        transmission errors are functions of it).
    eligible : ndarray of bool, shape (N_PARAMS,)
        Parameters that exist for this robot (hooks may skip what does not).
    frames, zs, ps, tcp, p_tcp, R_tcp, wrench
        Set by :meth:`at` for the current joint angles (base frame).
    """

    def __init__(
        self,
        convention: str,
        theta: Any,
        const: Any,
        eligible: np.ndarray,
        dT: Any = 0.0,
        tn: Any = 0.0,
        qc: Any = None,
    ) -> None:
        self.convention = convention
        self.theta, self.const = theta, const
        self.eligible = eligible
        self.dT, self.tn = dT, tn
        self.qc = qc
        self._lay = layouts()
        self.frames: list[Any] = []
        self.graph: Graph | None = None

    def p(self, key: str) -> Any:
        """Parameter group ``key`` of theta."""
        s = self._lay.slices[key]
        return self.theta[s.start : s.stop]

    def c(self, key: str) -> Any:
        """Constant block ``key``."""
        s = self._lay.const_slices[key]
        return self.const[s.start : s.stop]

    def load_arm(self) -> Any | None:
        """Sum of the active effects' moment arms (base frame, m), None when there is none."""
        arm = None
        for e in self.graph.effects if self.graph is not None else ():
            r = e.moment_arm(self)
            if r is not None:
                arm = r if arm is None else arm + r
        return arm

    def load_point(self) -> Any:
        """Where the external force acts: the TCP plus the moment arms (base frame, m)."""
        arm = self.load_arm()
        return self.p_tcp if arm is None else self.p_tcp + arm

    def eligible_of(self, key: str) -> np.ndarray:
        return self.eligible[self._lay.slices[key]]

    @property
    def tool(self) -> Any:
        return ca.reshape(self.c("tool"), 4, 4)

    @property
    def general(self) -> bool:
        """Whether the chain has end transforms (DH frame 0 != base, flange != DH frame 6)."""
        return self.graph is not None and self.graph.general

    def frame02base(self) -> Any:
        """DH frame 0 in the base frame (4x4), None for a plain DH chain."""
        return ca.reshape(self.c("chain.frame02base"), 4, 4) if self.general else None

    def at(self, frames: list[Any], wrench_fn: Callable[[Context], Any]) -> Context:
        """Set the arm state (frames of the current joint angles) and the wrench on the TCP."""
        self.frames = frames
        self.zs, self.ps = joint_axes(frames, self.convention, self.frame02base())
        #: flange2base of the current joint angles
        self.flange = (
            ca.mtimes(frames[-1], ca.reshape(self.c("chain.flange2frame6"), 4, 4)) if self.general else frames[-1]
        )
        self.tcp = ca.mtimes(self.flange, self.tool)
        self.p_tcp, self.R_tcp = self.tcp[:3, 3], self.tcp[:3, :3]
        self.wrench = wrench_fn(self)
        return self


class Graph:
    """The model graph of one set of active effects (hooks called in registry order)."""

    def __init__(self, convention: str, active: Sequence[Effect], eligible: np.ndarray, general: bool = False) -> None:
        self.convention = convention
        self.effects = [e for e in registry() if e in active]
        self.eligible = eligible
        #: the chain has end transforms (``chain.frame02base``, ``chain.flange2frame6``)
        self.general = general

    def context(self, theta: Any, const: Any, dT: Any = 0.0, tn: Any = 0.0, qc: Any = None) -> Context:
        ctx = Context(self.convention, theta, const, self.eligible, dT, tn, qc)
        ctx.graph = self
        return ctx

    def geometry(self, ctx: Context) -> dict[str, Any]:
        dh = {
            "a": ctx.c("dh.a"),
            "alpha": ctx.c("dh.alpha"),
            "d": ctx.c("dh.d"),
            "theta_offset": ctx.c("dh.theta_offset"),
            "beta": ca.DM.zeros(6),
            "frame02base": ctx.frame02base(),
        }
        for e in self.effects:
            dh = e.geometry(ctx, dh)
        return dh

    def torques(self, ctx: Context) -> tuple[Any, Any]:
        """External joint torques (of the wrench on the TCP) and the other joint torques."""
        f, m = ctx.wrench[0:3], ctx.wrench[3:6]
        arm = ctx.load_arm()
        if arm is not None:
            m = m + ca.cross(arm, f)
        tau_ext = ca.vertcat(*[ca.dot(ctx.zs[i], ca.cross(ctx.p_tcp - ctx.ps[i], f) + m) for i in range(6)])
        return tau_ext, self._sum("joint_torque", 6, ctx)

    def _sum(self, hook: str, size: int, ctx: Context, *args: Any) -> Any:
        """Sum of the effects' ``hook`` terms (those that return None add nothing)."""
        total = ca.DM.zeros(size)
        for e in self.effects:
            term = getattr(e, hook)(ctx, *args)
            if term is not None:
                total = total + term
        return total

    def joint_deflection(self, ctx: Context, tau: Any) -> Any:
        return self._sum("joint_deflection", 6, ctx, tau)

    def point_displacement(self, ctx: Context, point: Any) -> Any:
        return self._sum("point_displacement", 3, ctx, point)

    def measurement(self, ctx: Context, p: Any) -> Any:
        for e in self.effects:
            p = e.measurement(ctx, p)
        return p

    def deflection_at(self, ctx: Context) -> Any:
        """Joint deflection of the state set in ``ctx`` (torques at that pose)."""
        te, to = self.torques(ctx)
        return self.joint_deflection(ctx, te + to)

    def equilibrium(
        self,
        ctx: Context,
        dh: dict[str, Any],
        qc: Any,
        wrench_fn: Callable[[Context], Any],
        q_start: Any = None,
        n_iter: int = EQUILIBRIUM_UNROLL,
    ) -> Any:
        """Unrolled fixed point ``q = q_c + dq(q)``; leaves ``ctx`` at the final state."""
        q = qc if q_start is None else q_start
        for _ in range(n_iter):
            ctx.at(chain(q, dh, self.convention), wrench_fn)
            q = qc + self.deflection_at(ctx)
        ctx.at(chain(q, dh, self.convention), wrench_fn)
        return q


# --------------------------------------------------------------------------------------
# Identification: parameters symbolic
# --------------------------------------------------------------------------------------


def measured_point(graph: Graph, ctx: Context) -> Any:
    """The measured point (``measured_point`` parameters, flange frame) in the base frame,
    with point displacements, then through the measurement hooks."""
    p_flange = ca.mtimes(ctx.flange, ca.vertcat(ctx.p("tool.p"), 1))[:3]
    p_base = p_flange + graph.point_displacement(ctx, p_flange)
    return graph.measurement(ctx, p_base)


def rotvec_matrix(w: Any) -> Any:
    """Rotation matrix of a rotation vector ``w`` (axis x angle, rad), Rodrigues (exact at 0)."""
    th2 = ca.dot(w, w)
    th = ca.sqrt(th2 + 1e-300)
    W = ca.skew(w)
    a = ca.if_else(th2 > 1e-12, ca.sin(th) / th, 1 - th2 / 6)
    b = ca.if_else(th2 > 1e-12, (1 - ca.cos(th)) / (th2 + 1e-300), 0.5 - th2 / 24)
    return ca.SX.eye(3) + a * W + b * ca.mtimes(W, W)


def orientation_error(graph: Graph, ctx: Context, rv_meas: Any) -> Any:
    """Orientation error of the measured frame: ``vee(skew(R_m^T R))`` with ``R`` the model's
    frame and ``R_m`` the measured one (``rv_meas``, rotation vector), both in the measurement
    frame; components in the measured frame, rad (the rotation vector of ``R_m^T R`` to first
    order).  The frame's rotation into the measurement frame is the linear part of the
    measurement hooks (affine maps), taken from the images of three points."""
    R_tool = ca.mtimes(ca.reshape(ctx.c("measured_frame.R0"), 3, 3), cayley(ctx.p("tool.r")))
    R_base = ca.mtimes(ctx.flange[:3, :3], R_tool)
    p_flange = ca.mtimes(ctx.flange, ca.vertcat(ctx.p("tool.p"), 1))[:3]
    cols = [graph.measurement(ctx, p_flange + R_base[:, k]) - graph.measurement(ctx, p_flange) for k in range(3)]
    R = ca.horzcat(*cols)
    E = ca.mtimes(rotvec_matrix(rv_meas).T, R)
    return 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])


def _measure_jacobian(
    graph: Graph,
    observed: Callable[[Graph, Context], Any],
    el: np.ndarray,
    row: ca.SX,
    theta: ca.SX,
    const: ca.SX,
    const_F: Callable[[Context], Any],
) -> ca.Function:
    """``ident_measure_jac(row, q_eq, theta, const) -> p, J``: the measurement and its Jacobian in the eligible
    parameters ``el`` (others' columns zero).

    The fixed point restarted from the converged q_eq (an input), so the value is exact and the
    derivative carries the implicit-function factor to first order.
    """
    n = len(el)
    qc, tn, dT = row[0:6], row[12], row[13]
    idx_el = np.flatnonzero(el)
    idx_fx = np.flatnonzero(~el)
    th_el = ca.SX.sym("theta_el", len(idx_el))
    th_fx = ca.SX.sym("theta_fixed", len(idx_fx))
    parts: list[Any] = [None] * n
    for k, i in enumerate(idx_el):
        parts[i] = th_el[k]
    for k, i in enumerate(idx_fx):
        parts[i] = th_fx[k]
    theta_v = ca.vertcat(*parts)
    q_in = ca.SX.sym("q_eq", 6)
    ctx2 = graph.context(theta_v, const, dT, tn, qc)
    dh2 = graph.geometry(ctx2)
    graph.equilibrium(ctx2, dh2, qc, const_F, q_start=q_in, n_iter=JACOBIAN_UNROLL)
    p2 = observed(graph, ctx2)
    jac = ca.jacobian(p2, th_el)
    jf = ca.Function("ident_measure_jac_el", [row, q_in, th_el, th_fx, const], [p2, jac])
    pj, Jj = jf(
        row,
        q_in,
        theta[idx_el.tolist()] if len(idx_el) else ca.SX(0, 1),
        theta[idx_fx.tolist()] if len(idx_fx) else ca.SX(0, 1),
        const,
    )
    return ca.Function(
        "ident_measure_jac", [row, q_in, theta, const], [pj, Jj], ["row", "q_eq", "theta", "const"], ["p", "J"]
    )


def _torques_function(graph: Graph, theta: ca.SX, const: ca.SX, qs: ca.SX, Fs: ca.SX, dTs: ca.SX) -> ca.Function:
    """``ident_torques(q_c, F, dT, theta, const) -> tau_ext, tau_g, q_eq`` (no time drift)."""
    ctx3 = graph.context(theta, const, dTs, 0.0, qs)
    dh3 = graph.geometry(ctx3)
    q_eq = graph.equilibrium(ctx3, dh3, qs, lambda _c: Fs)
    te, to = graph.torques(ctx3)
    return ca.Function(
        "ident_torques",
        [qs, Fs, dTs, theta, const],
        [te, to, q_eq],
        ["q_c", "F", "dT", "theta", "const"],
        ["tau_ext", "tau_g", "q_eq"],
    )


def _point_jacobian_function(
    graph: Graph, convention: str, theta: ca.SX, const: ca.SX, qs: ca.SX, dTs: ca.SX
) -> ca.Function:
    """``ident_point_jacobian(q, dT, theta, const) -> p, Jp``: the undeflected arm's measured point and its
    positional Jacobian, measurement frame."""
    ctx4 = graph.context(theta, const, dTs, 0.0, qs)
    dh4 = graph.geometry(ctx4)
    ctx4.at(chain(qs, dh4, convention), lambda _c: ca.DM.zeros(6))
    p0 = ca.mtimes(ctx4.flange, ca.vertcat(ctx4.p("tool.p"), 1))[:3]
    p0m = graph.measurement(ctx4, p0)
    return ca.Function(
        "ident_point_jacobian",
        [qs, dTs, theta, const],
        [p0m, ca.jacobian(p0m, qs)],
        ["q", "dT", "theta", "const"],
        ["p", "Jp"],
    )


@lru_cache(maxsize=8)
def identification_functions(
    convention: str, eligible: tuple[bool, ...] | None = None, orientation: bool = False, general: bool = False
) -> dict[str, ca.Function]:
    """CasADi functions of the identification model (every registered effect in the graph).

    ``eligible`` (length N_PARAMS) marks the parameters that exist for the robot: the
    Jacobian is taken with respect to them only.  ``None``: all parameters.
    ``orientation``: rows may be orientation rows (``kind`` = 1), whose output is the
    orientation error of the measured frame (:func:`orientation_error`, rad) instead of the
    measured point; without it every row is a position row (and cheaper).

    Returns
    -------
    dict
        ``measure(row (14), theta, const) -> p_meas (3), q_eq (6)``;
        ``measure_jac(row, q_eq, theta, const) -> p (3), dp/dtheta (3 x N_PARAMS, ineligible
        columns zero)``; ``torques(q_c, F, dT, theta, const) -> tau_ext, tau_other, q_eq``;
        ``point_jacobian(q, dT, theta, const) -> p (3), Jp (3x6)``: the measured point of the
        undeflected arm and its positional Jacobian, measurement frame (drift excluded).
    """
    lay = layouts()
    n = lay.n_params
    el = np.ones(n, dtype=bool) if eligible is None else np.asarray(eligible, dtype=bool)
    graph = Graph(convention, registry(), el, general)
    theta = ca.SX.sym("theta", n)
    row = ca.SX.sym("row", ROW_SIZE)
    const = ca.SX.sym("const", lay.const_size)
    qc, F, tn, dT = row[0:6], row[6:12], row[12], row[13]
    kind, rv = row[14], row[15:18]
    const_F: Callable[[Context], Any] = lambda _ctx: F  # noqa: E731 - base-frame wrench of the row

    def observed(g: Graph, c: Context) -> Any:
        """Position (position rows) or orientation error (orientation rows) of the row."""
        if not orientation:
            return measured_point(g, c)
        return ca.if_else(kind > 0.5, orientation_error(g, c, rv), measured_point(g, c))

    ctx = graph.context(theta, const, dT, tn, qc)
    dh = graph.geometry(ctx)
    q = graph.equilibrium(ctx, dh, qc, const_F)
    p_meas = observed(graph, ctx)
    measure = ca.Function("ident_measure", [row, theta, const], [p_meas, q], ["row", "theta", "const"], ["p", "q_eq"])

    measure_jac = _measure_jacobian(graph, observed, el, row, theta, const, const_F)
    qs, Fs, dTs = ca.SX.sym("q", 6), ca.SX.sym("F", 6), ca.SX.sym("dT", 1)
    torques = _torques_function(graph, theta, const, qs, Fs, dTs)
    point_jac = _point_jacobian_function(graph, convention, theta, const, qs, dTs)
    return {"measure": measure, "measure_jac": measure_jac, "torques": torques, "point_jacobian": point_jac}


# --------------------------------------------------------------------------------------
# Planning: parameters fixed
# --------------------------------------------------------------------------------------


def _planning_graph(convention: str, active: Sequence[str], const: np.ndarray, eligible: np.ndarray) -> Graph:
    """The graph of a planning model: the effects that act on the arm and are active (the
    measurement effects, registration and drift, do not)."""
    effs = [e for e in registry() if e.acts_on == base.ARM and (e.declared or e.name in active)]
    lay = layouts()
    general = any(
        not np.array_equal(np.asarray(const)[lay.const_slices[k]], np.eye(4).reshape(-1))
        for k in ("chain.frame02base", "chain.flange2frame6")
    )
    return Graph(convention, effs, np.asarray(eligible, dtype=bool), general)


def _loaded_arm(graph: Graph, theta: np.ndarray, const: Any, dT: float, q: Any, L: Any) -> dict[str, Any]:
    """The loaded arm at ``q`` under the load vector ``L``: context, Jacobian, torques, joint
    deflection and the load-induced TCP error ``err`` = [position (3) m; rotation (3) rad]."""
    ctx = graph.context(ca.SX(ca.DM(theta)), const, float(dT), 0.0, q)
    dh = graph.geometry(ctx)
    ctx.at(chain(q, dh, graph.convention), lambda c: load_wrench(c.R_tcp, L))
    J = geometric_jacobian(ctx.frames, ctx.p_tcp, graph.convention, ctx.frame02base())
    te, to = graph.torques(ctx)
    tau = te + to
    dq = graph.joint_deflection(ctx, tau)
    dp = graph.point_displacement(ctx, ctx.p_tcp)
    err = ca.vertcat(ca.mtimes(J[:3, :], dq) + dp, ca.mtimes(J[3:, :], dq))
    return {"ctx": ctx, "J": J, "tau": tau, "dq": dq, "dp": dp, "err": err}


def arm_functions(
    convention: str, active: Sequence[str], theta: np.ndarray, const: np.ndarray, eligible: np.ndarray, dT: float = 0.0
) -> dict[str, ca.Function]:
    """Named CasADi functions of an arm model with fixed parameters (see :class:`models.arm.ArmModel`).

    Only the effects that act on the arm and are active enter the graph (the
    measurement effects, registration and drift, do not).  Inputs: ``q`` (6, rad) and,
    for the load functions, the load vector ``L`` (:data:`LOAD_SIZE`).
    """
    graph = _planning_graph(convention, active, const, eligible)
    q = ca.SX.sym("q", 6)
    L = ca.SX.sym("L", LOAD_SIZE)
    F = ca.SX.sym("F", 6)
    arm = _loaded_arm(graph, theta, ca.SX(ca.DM(const)), dT, q, L)
    ctx, J, tau, dq, dp, err = arm["ctx"], arm["J"], arm["tau"], arm["dq"], arm["dp"], arm["err"]
    frames, tcp = ctx.frames, ctx.tcp
    tau_in = ca.SX.sym("tau", 6)
    dq_of_tau = graph.joint_deflection(ctx, tau_in)
    # the linear-spring compliance C = J diag(c) J^T with the model's spring compliances
    springs = base.effect("joint_springs")
    c = springs.compliance(ctx)
    C = compliance_from_jacobian(J, c)
    names = [f"frame{i + 1}2base" for i in range(6)]
    out = {
        "fk_frames": ca.Function("fk_frames", [q], frames, ["q"], names),
        "fk_tcp": ca.Function("fk_tcp", [q], [tcp], ["q"], ["tcp2base"]),
        "fk_position": ca.Function("fk_position", [q], [tcp[:3, 3]], ["q"], ["p_tcp"]),
        "jacobian": ca.Function("jacobian", [q], [J], ["q"], ["J"]),
        "compliance": ca.Function("compliance", [q], [C], ["q"], ["C"]),
        "deflection": ca.Function("deflection", [q, F], [ca.mtimes(C, F)], ["q", "F"], ["D"]),
        "joint_deflection": ca.Function("joint_deflection", [q, F], [c * ca.mtimes(J.T, F)], ["q", "F"], ["dq"]),
        "kinetostatics": ca.Function(
            "kinetostatics", [q], [tcp[:3, 3], tcp[:3, :3], J, C], ["q"], ["p_tcp", "R_tcp", "J", "C"]
        ),
        "tcp_wrench": ca.Function("tcp_wrench", [q, L], [ctx.wrench], ["q", "L"], ["W"]),
        "joint_torques": ca.Function("joint_torques", [q, L], [tau], ["q", "L"], ["tau"]),
        "load_deflection": ca.Function("load_deflection", [q, L], [dq], ["q", "L"], ["dq"]),
        "torque_deflection": ca.Function("torque_deflection", [q, tau_in], [dq_of_tau], ["q", "tau"], ["dq"]),
        "loaded_tcp": ca.Function("loaded_tcp", [q, L], [tcp[:3, 3] + dp, tcp[:3, :3]], ["q", "L"], ["p_tcp", "R_tcp"]),
        "load_error": ca.Function("load_error", [q, L], [err], ["q", "L"], ["e"]),
    }
    # pose error of the loaded TCP against a target (position m; rotation vector of R_t^T R, rad)
    p_t, R_t = ca.SX.sym("p_t", 3), ca.SX.sym("R_t", 3, 3)
    E = ca.mtimes(R_t.T, tcp[:3, :3])
    e = ca.vertcat(tcp[:3, 3] + dp - p_t, 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]))
    out["loaded_pose_error"] = ca.Function(
        "loaded_pose_error", [q, L, p_t, R_t], [e, ca.jacobian(e, q)], ["q", "L", "p_t", "R_t"], ["e", "de_dq"]
    )
    return out


def load_error_gravity_function(
    convention: str, active: Sequence[str], theta: np.ndarray, const: np.ndarray, eligible: np.ndarray, dT: float = 0.0
) -> ca.Function:
    """``load_error_g(q, L, g) -> e``: the model's ``load_error`` with its gravity constant as an
    input.

    ``g`` (3, m/s^2, base frame) replaces the robot's ``gravity`` (the arm's self-weight, when
    the model has the ``gravity`` effect); ``L`` carries the payload's own gravity as always.  The
    same arm on a base mounted another way (a placement study's tilts and yaws) is one function
    with ``g`` turned into its base frame, instead of one model per mounting.  With
    ``g = robot.gravity`` it equals ``load_error``.
    """
    graph = _planning_graph(convention, active, const, eligible)
    q, L, g = ca.SX.sym("q", 6), ca.SX.sym("L", LOAD_SIZE), ca.SX.sym("g", 3)
    cs = ca.SX(ca.DM(const))
    s = layouts().const_slices["gravity"]
    cs[s.start : s.stop] = g
    err = _loaded_arm(graph, theta, cs, dT, q, L)["err"]
    return ca.Function("load_error_g", [q, L, g], [err], ["q", "L", "g"], ["e"])


def compliance_from_jacobian(J: Any, kinv: Any) -> Any:
    """``C = J diag(kinv) J^T`` built on the upper triangle and mirrored (exactly symmetric)."""
    n = J.shape[0]
    entries = {}
    for i in range(n):
        for j in range(i, n):
            entries[i, j] = sum(J[i, k] * kinv[k] * J[j, k] for k in range(J.shape[1]))
    return ca.vertcat(*[ca.horzcat(*[entries[min(i, j), max(i, j)] for j in range(n)]) for i in range(n)])
