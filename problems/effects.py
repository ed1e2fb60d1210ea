"""The effect library: documented, parametrised additions to the declared model.

The *declared model* of a measurement is the paper's joint-compliance model plus,
for absolute data, the registration of the measurement frame and the position of
the measured point on the flange.  Each library effect adds named parameters to
one forward function, built once per DH convention as a CasADi graph::

    q  = q_c + dq(q, F)                     (unrolled fixed point, EQUILIBRIUM_UNROLL times)
    dq = c*tau + c*(b1*tau|tau|/tau_s + b2*tau^3/tau_s^2) + b_lm*tanh(tau/tau_0)
    tau = J_v(q)^T f + J_w(q)^T (m + r x f) + tau_g(q; pi)
    p_base = base2flange(q; DH + errors, thermal) * p_tool + dp_link(q, F)
    p_meas = base2meas * p_base + v*tn + a*tn^2

Every parameter of every effect lives in one flat vector ``theta`` whose layout
(:data:`PARAMETER_GROUPS`) does not depend on the robot, so the compiled function
serves every arm of a convention.  An effect that is not active keeps its
parameters at their nominal value, which makes it vanish (for ``gravity``: link
masses from the robot file are the nominal values, and the gravity torque is
switched by the ``gravity_on`` entry of the constant vector).

Units (SI) and frames:

* ``q``, ``dq``: rad; ``F = [f (N); m (N*m)]``: base frame, acting on the TCP;
* ``tau``: N*m, joint torques, positive where the joint yields positively;
* ``tn``: time since the first measurement, normalised to [0, 1] over the campaign; ``dT``: temperature minus
  :data:`THERMAL_REFERENCE_C`, K;
* ``p_tool``: measured point in the flange frame, m; ``p_meas``: measurement frame, m.

See ``docs/identification.md`` for the formulas and the parameter tables.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from models.robot import Robot
from models.symbolic import joint_axes, link_transform

# ----------------------------------------------------------------------------------
# Named constants
# ----------------------------------------------------------------------------------

#: Fixed-point iterations of the deflected equilibrium unrolled in the CasADi graph.
#: The map contracts by about ``|dq|`` (rad) per iteration, so 5 iterations leave
#: ``|dq|^6`` (below 1e-9 rad for deflections up to 0.03 rad).
EQUILIBRIUM_UNROLL = 5

#: Fixed-point iterations restarted from the converged equilibrium to differentiate
#: it: the derivative error is of order ``|dq|^JACOBIAN_UNROLL`` (relative).
JACOBIAN_UNROLL = 1

#: Reference temperature of the nominal link lengths (ISO 1), deg C.
THERMAL_REFERENCE_C = 20.0

#: A link takes part in ``link_compliance`` (beam springs) when its length is at
#: least this fraction of the longest link (dimensionless).
LINK_BEAM_MIN_FRACTION = 0.3

#: A link takes part in ``thermal`` when its length exceeds this (m).
THERMAL_MIN_LINK_LENGTH_M = 0.01

#: Two consecutive joint axes count as parallel (Hayati parameter ``beta`` added)
#: when ``|sin(alpha)|`` is below this (dimensionless).
PARALLEL_AXIS_TOL = 1e-6

#: Bounds of the lost-motion shape parameter ``rho = ln(tau_0 / tau_s)``: a dead
#: band is sharp (its transition torque at most 5 % of the joint's torque scale); a
#: gradual change of compliance with torque is ``stiffness_hardening``.
LOST_MOTION_RHO_BOUNDS = (np.log(1e-3), np.log(0.05))

#: Initial lost-motion shape: ``tau_0 = exp(rho) * tau_s``.
LOST_MOTION_RHO_INIT = np.log(0.01)

#: Hardening: knots of the quadratic-spline compliance curve, as quantiles of the
#: nonzero joint torques of the data (per joint).
HARDENING_KNOT_QUANTILES = (0.1, 0.3, 0.55, 0.8, 0.95)
#: Number of hardening knots per joint.
N_KNOTS = len(HARDENING_KNOT_QUANTILES)
#: Hardening terms per joint: ``tau|tau|`` and one quadratic hinge per knot.
N_HARDENING = 1 + N_KNOTS

#: Joint torque scale floor (N*m) used when a joint sees no torque in the data.
TORQUE_SCALE_FLOOR_NM = 1.0

#: Names of the library effects, in the order they are documented.
LIBRARY = ("gravity", "stiffness_hardening", "lost_motion", "joint_offset", "geometric",
           "load_offset", "link_compliance", "drift", "thermal", "outliers")

#: Names of the declared (always present) parameter groups.
BASE_GROUPS = ("reg.w", "reg.t", "tool.p", "stiffness.s")

# (group, count, unit, label-maker) in the order of ``theta``.
_LINK_COMPLIANCE_KEYS = ("tt_xx", "tt_yy", "tt_zz", "rr_xx", "rr_yy", "rr_zz",
                         "tr_xy", "tr_xz", "tr_yx", "tr_yz", "tr_zx", "tr_zy")
_SYM_KEYS = ("xx", "yy", "zz", "xy", "xz", "yz")


def _joint_labels(prefix: str) -> list[str]:
    return [f"{prefix}[{i + 1}]" for i in range(6)]


def _xyz_labels(prefix: str) -> list[str]:
    return [f"{prefix}.{c}" for c in "xyz"]


PARAMETER_GROUPS: tuple[tuple[str, str, list[str], str], ...] = (
    # (group, effect, parameter names, unit)
    ("reg.w", "registration", _xyz_labels("registration.w"), "1"),
    ("reg.t", "registration", _xyz_labels("registration.t"), "m"),
    ("tool.p", "measured_point", _xyz_labels("measured_point"), "m"),
    ("stiffness.s", "stiffness", _joint_labels("stiffness.s"), "1"),
    ("joint_offset.dtheta", "joint_offset", _joint_labels("dtheta"), "rad"),
    ("geometric.da", "geometric", _joint_labels("da"), "m"),
    ("geometric.dalpha", "geometric", _joint_labels("dalpha"), "rad"),
    ("geometric.dd", "geometric", _joint_labels("dd"), "m"),
    ("geometric.dbeta", "geometric", _joint_labels("dbeta"), "rad"),
    ("gravity.m", "gravity", _joint_labels("gravity.mass"), "kg"),
    ("gravity.h", "gravity", [f"gravity.first_moment[{i + 1}].{c}" for i in range(6) for c in "xyz"], "kg*m"),
    ("hardening.b", "stiffness_hardening",
     [f"hardening.b[{i + 1}].{'quad' if k == 0 else f'knot{k}'}" for i in range(6)
      for k in range(N_HARDENING)], "1"),
    ("lost_motion.b", "lost_motion", _joint_labels("lost_motion.b"), "rad"),
    ("lost_motion.rho", "lost_motion", ["lost_motion.rho"], "1"),
    ("load_offset.r_tool", "load_offset", _xyz_labels("load_offset.r_tool"), "m"),
    ("load_offset.r_base", "load_offset", _xyz_labels("load_offset.r_base"), "m"),
    ("link_compliance.link", "link_compliance",
     [f"link_compliance.link{i + 1}.{k}" for i in range(6) for k in _LINK_COMPLIANCE_KEYS], "varies"),
    ("link_compliance.tool", "link_compliance", [f"link_compliance.tool.{k}" for k in _SYM_KEYS], "m/N"),
    ("link_compliance.base", "link_compliance", [f"link_compliance.base.{k}" for k in _SYM_KEYS], "m/N"),
    ("drift.v", "drift", _xyz_labels("drift.v"), "m"),
    ("drift.a", "drift", _xyz_labels("drift.a"), "m"),
    ("thermal.alpha", "thermal", _joint_labels("thermal.alpha"), "1/K"),
)


def _group_slices() -> dict[str, slice]:
    out, k = {}, 0
    for g, _e, names, _u in PARAMETER_GROUPS:
        out[g] = slice(k, k + len(names))
        k += len(names)
    return out


GROUP_SLICES: dict[str, slice] = _group_slices()
N_PARAMS: int = sum(len(n) for _g, _e, n, _u in PARAMETER_GROUPS)
PARAM_NAMES: tuple[str, ...] = tuple(n for _g, _e, names, _u in PARAMETER_GROUPS for n in names)

#: Per-row inputs: q_c (6, rad), F (6, N and N*m), tn (1), dT (1, K).
ROW_SIZE = 14
#: Constants: a, alpha, d, theta_offset (4x6), c0 (6), R0 (9, column-major),
#: flange2tcp (16, column-major), gravity (3), tau_s (6), gravity_on (1),
#: beam frames (6 x 9, column-major: link frame -> beam frame axes), hardening
#: knots (6 x N_KNOTS, N*m, joint-major).
CONST_SIZE = 24 + 6 + 9 + 16 + 3 + 6 + 1 + 54 + 6 * N_KNOTS


# ----------------------------------------------------------------------------------
# Effect descriptions
# ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class EffectSpec:
    """One library effect.

    Attributes
    ----------
    name : str
        Library name (``report.json``'s ``effects_added`` uses it).
    groups : tuple of str
        Parameter groups of ``theta`` it frees (see :data:`PARAMETER_GROUPS`).
    formula : str
        One-line statement of the addition to the model.
    needs : tuple of str
        Data it needs to be testable: ``"load"`` (a varying wrench), ``"time"``,
        ``"temperature"``.
    """

    name: str
    groups: tuple[str, ...]
    formula: str
    needs: tuple[str, ...] = ()
    subsumes: tuple[str, ...] = field(default=())


EFFECTS: dict[str, EffectSpec] = {e.name: e for e in (
    EffectSpec("gravity", ("gravity.m", "gravity.h"),
               "self-weight joint deflection dq += C tau_g(q; m_j, m_j r_j), tau_g from link masses and "
               "first moments (barycentric, linear), C the joint compliance"),
    EffectSpec("stiffness_hardening", ("hardening.b",),
               "torque-dependent compliance, an odd quadratic spline: dq_i = c_i tau_i + c0_i (b_i0 tau_i|tau_i| "
               "+ sum_k b_ik sign(tau_i) (|tau_i| - kappa_ik)_+^2) / tau_s,i, knots kappa_ik at torque quantiles",
               needs=("load",)),
    EffectSpec("lost_motion", ("lost_motion.b", "lost_motion.rho"),
               "smooth dead band dq_i += b_i tanh(tau_i / (exp(rho) tau_s,i)), b = half the lost motion",
               needs=("load",)),
    EffectSpec("joint_offset", ("joint_offset.dtheta",), "theta_i = q_i + theta_offset_i + dtheta_i"),
    EffectSpec("geometric", ("joint_offset.dtheta", "geometric.da", "geometric.dalpha", "geometric.dd",
                             "geometric.dbeta"),
               "full DH error set (da, dalpha, dd, dtheta per joint; Hayati dbeta about y for parallel axes)",
               subsumes=("joint_offset",)),
    EffectSpec("load_offset", ("load_offset.r_tool", "load_offset.r_base"),
               "the force acts at TCP + R_tcp r_tool + r_base: extra moment r x f", needs=("load",)),
    EffectSpec("link_compliance", ("link_compliance.link", "link_compliance.tool", "link_compliance.base"),
               "beam springs (6x6 compliance, 12 terms) at the distal end of each long link, plus translational "
               "3x3 compliances at the measured point in the tool and base frames", needs=("load",)),
    EffectSpec("drift", ("drift.v", "drift.a"),
               "measurement drift p_meas += v tn + a tn^2, tn = time since the first row over the campaign span",
               needs=("time",)),
    EffectSpec("thermal", ("thermal.alpha",),
               "link lengths a_i, d_i scaled by (1 + alpha_i (T - 20 C))", needs=("temperature",)),
    EffectSpec("outliers", (),
               "robust fit: rows whose standardised residual exceeds the chi-square bound are excluded and listed"),
)}


# ----------------------------------------------------------------------------------
# Robot-specific layout: nominal values, scales, eligibility
# ----------------------------------------------------------------------------------

@dataclass
class ModelLayout:
    """Robot-specific view of the parameter vector.

    Attributes
    ----------
    nominal : ndarray, shape (N_PARAMS,)
        Value of each parameter when its effect is not active (and when held).
    scale : ndarray, shape (N_PARAMS,)
        Typical magnitude, in the parameter's unit (scaling and identifiability).
    eligible : ndarray of bool, shape (N_PARAMS,)
        Whether the parameter exists for this robot (e.g. ``dbeta`` only for
        parallel consecutive axes, beam springs only for long links).
    units : list of str
    const : ndarray, shape (CONST_SIZE,)
        Constant input of the CasADi functions (nominal DH, compliance, R0, tool,
        gravity, torque scales, gravity switch).
    """

    robot: Robot
    nominal: np.ndarray
    scale: np.ndarray
    eligible: np.ndarray
    units: list[str]
    beam_links: list[int]
    thermal_links: list[int]
    parallel_joints: list[int]

    @property
    def names(self) -> tuple[str, ...]:
        return PARAM_NAMES

    def indices(self, groups: tuple[str, ...] | list[str]) -> np.ndarray:
        """Indices of the eligible parameters of the given groups."""
        idx = [np.arange(GROUP_SLICES[g].start, GROUP_SLICES[g].stop) for g in groups]
        if not idx:
            return np.zeros(0, dtype=int)
        allidx = np.concatenate(idx)
        return allidx[self.eligible[allidx]]

    def effect_indices(self, effect: str) -> np.ndarray:
        if effect == "base":
            return self.indices(BASE_GROUPS)
        return self.indices(EFFECTS[effect].groups)


def link_lengths(robot: Robot) -> np.ndarray:
    """Length of each DH link (row), ``sqrt(a^2 + d^2)``, m, shape (6,)."""
    return np.hypot(robot.a, robot.d)


def make_layout(robot: Robot) -> ModelLayout:
    """Nominal values, scales and eligibility of every parameter for ``robot``."""
    n = N_PARAMS
    nominal = np.zeros(n)
    scale = np.ones(n)
    eligible = np.ones(n, dtype=bool)
    units: list[str] = []
    for _g, _e, names, unit in PARAMETER_GROUPS:
        units.extend([unit] * len(names))

    def sl(g: str) -> slice:
        return GROUP_SLICES[g]

    lengths = link_lengths(robot)
    reach = float(max(np.sum(lengths), 0.1))
    c_mean = float(np.mean(1.0 / robot.stiffness))
    scale[sl("reg.w")] = 1e-3
    scale[sl("reg.t")] = 1e-3
    scale[sl("tool.p")] = 1e-3
    nominal[sl("tool.p")] = robot.flange2tcp[:3, 3]
    scale[sl("stiffness.s")] = 0.1
    scale[sl("joint_offset.dtheta")] = 1e-3
    for g in ("geometric.da", "geometric.dd"):
        scale[sl(g)] = 1e-3
    for g in ("geometric.dalpha", "geometric.dbeta"):
        scale[sl(g)] = 1e-3
    par = [i for i in range(6) if abs(np.sin(robot.alpha[i])) < PARALLEL_AXIS_TOL]
    # beta of row i is meaningful when axes z_{i-1}, z_i are parallel (alpha_i ~ 0), and only
    # where a following joint exists to tell it from the tool.
    par = [i for i in par if i < 5]
    beta_el = np.zeros(6, dtype=bool)
    beta_el[par] = True
    eligible[sl("geometric.dbeta")] = beta_el
    # gravity: nominal masses/first moments from the robot file (zero without masses)
    if robot.has_masses:
        m = robot.masses
        nominal[sl("gravity.m")] = m
        nominal[sl("gravity.h")] = (m[:, None] * robot.coms).reshape(-1)
    scale[sl("gravity.m")] = max(1.0, float(np.mean(robot.masses)) if robot.has_masses else 1.0)
    scale[sl("gravity.h")] = 0.1
    scale[sl("hardening.b")] = 0.1
    scale[sl("lost_motion.b")] = 1e-4
    nominal[sl("lost_motion.rho")] = LOST_MOTION_RHO_INIT
    scale[sl("lost_motion.rho")] = 1.0
    scale[sl("load_offset.r_tool")] = 1e-2
    scale[sl("load_offset.r_base")] = 1e-2
    # link compliance: beam springs on long links
    beam_links = [i for i in range(6) if lengths[i] >= LINK_BEAM_MIN_FRACTION * lengths.max()]
    lc = np.zeros((6, 12))
    lc_scale = np.zeros(12)
    lmax = float(lengths.max())
    lc_scale[0:3] = 0.1 * c_mean * lmax ** 2
    lc_scale[3:6] = 0.1 * c_mean
    lc_scale[6:12] = 0.1 * c_mean * lmax
    lc_units = ["m/N"] * 3 + ["rad/(N*m)"] * 3 + ["m/(N*m)"] * 6
    s_link = sl("link_compliance.link")
    scale[s_link] = np.tile(lc_scale, 6)
    el = np.zeros((6, 12), dtype=bool)
    el[beam_links, :] = True
    eligible[s_link] = el.reshape(-1)
    for k in range(s_link.start, s_link.stop):
        units[k] = lc_units[(k - s_link.start) % 12]
    del lc
    scale[sl("link_compliance.tool")] = 0.1 * c_mean * lmax ** 2
    scale[sl("link_compliance.base")] = 0.1 * c_mean * lmax ** 2
    scale[sl("drift.v")] = 1e-4
    scale[sl("drift.a")] = 1e-4
    thermal_links = [i for i in range(6) if lengths[i] > THERMAL_MIN_LINK_LENGTH_M]
    el = np.zeros(6, dtype=bool)
    el[thermal_links] = True
    eligible[sl("thermal.alpha")] = el
    scale[sl("thermal.alpha")] = 1e-5
    del reach
    return ModelLayout(robot=robot, nominal=nominal, scale=scale, eligible=eligible, units=units,
                       beam_links=beam_links, thermal_links=thermal_links, parallel_joints=par)


def beam_frames(robot: Robot) -> np.ndarray:
    """Axes of the beam of each link in its DH link frame, shape (6, 3, 3).

    Column 0 is the unit vector from joint *i* to joint *i+1* (to the flange for
    link 6) expressed in link frame *i*; columns 1, 2 complete a right-handed frame
    (column 1 is the part of the link frame's z axis normal to the beam, or of x).
    Computed from the nominal geometry at ``q = 0`` (the direction is independent of q).
    """
    from models.symbolic import KinematicModel
    km = KinematicModel(robot)
    fr = [np.asarray(T) for T in km.fk_frames(np.zeros(6))]
    if robot.convention == "standard_dh":
        pts = [np.zeros(3)] + [T[:3, 3] for T in fr[:5]]
    else:
        pts = [T[:3, 3] for T in fr]
    out = np.zeros((6, 3, 3))
    for i in range(6):
        tip = pts[i + 1] if i < 5 else fr[5][:3, 3]
        R = fr[i][:3, :3]
        seg = R.T @ (tip - pts[i])
        if np.linalg.norm(seg) < 1e-9:
            seg = np.array([1.0, 0.0, 0.0])
        e1 = seg / np.linalg.norm(seg)
        ref = np.array([0.0, 0.0, 1.0]) if abs(e1[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        e2 = ref - (ref @ e1) * e1
        e2 /= np.linalg.norm(e2)
        out[i] = np.column_stack([e1, e2, np.cross(e1, e2)])
    return out


def make_const(robot: Robot, R0: np.ndarray, tau_scale: np.ndarray, gravity_on: bool,
               beams: np.ndarray | None = None, knots: np.ndarray | None = None) -> np.ndarray:
    """The constant input vector (see :data:`CONST_SIZE`)."""
    bf = beam_frames(robot) if beams is None else np.asarray(beams, dtype=float)
    ts = np.maximum(np.asarray(tau_scale, dtype=float), TORQUE_SCALE_FLOOR_NM)
    kn = (np.outer(ts, HARDENING_KNOT_QUANTILES) if knots is None
          else np.asarray(knots, dtype=float).reshape(6, N_KNOTS))
    c = np.concatenate([
        robot.a, robot.alpha, robot.d, robot.theta_offset, 1.0 / robot.stiffness,
        np.asarray(R0, dtype=float).reshape(-1, order="F"),
        np.asarray(robot.flange2tcp, dtype=float).reshape(-1, order="F"),
        robot.gravity, np.maximum(np.asarray(tau_scale, dtype=float), TORQUE_SCALE_FLOOR_NM),
        [1.0 if gravity_on else 0.0],
        np.concatenate([bf[i].reshape(-1, order="F") for i in range(6)]),
        kn.reshape(-1),
    ])
    assert c.shape == (CONST_SIZE,)
    return c


# ----------------------------------------------------------------------------------
# Symbolic model
# ----------------------------------------------------------------------------------

def _ry4(b: Any) -> Any:
    c, s = ca.cos(b), ca.sin(b)
    return ca.vertcat(ca.horzcat(c, 0, s, 0), ca.horzcat(0, 1, 0, 0),
                      ca.horzcat(-s, 0, c, 0), ca.horzcat(0, 0, 0, 1))


def cayley(w: Any) -> Any:
    """Rotation matrix of the Cayley vector ``w`` (exactly orthogonal; ~ rotation by 2w).

    ``R = I + 2/(1+|w|^2) ([w]x + [w]x^2)``.
    """
    W = ca.skew(w)
    return ca.SX.eye(3) + 2.0 / (1.0 + ca.dot(w, w)) * (W + ca.mtimes(W, W))


def cayley_np(w: np.ndarray) -> np.ndarray:
    """NumPy version of :func:`cayley`, shape (3, 3)."""
    w = np.asarray(w, dtype=float)
    W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    return np.eye(3) + 2.0 / (1.0 + w @ w) * (W + W @ W)


def _sym3(v: Any) -> Any:
    return ca.vertcat(ca.horzcat(v[0], v[3], v[4]), ca.horzcat(v[3], v[1], v[5]),
                      ca.horzcat(v[4], v[5], v[2]))


class _Unpacked:
    """Named views of theta and const (CasADi expressions)."""

    def __init__(self, theta: Any, const: Any) -> None:
        def g(name: str) -> Any:
            s = GROUP_SLICES[name]
            return theta[s.start:s.stop]
        self.g = g
        self.a0 = const[0:6]
        self.alpha0 = const[6:12]
        self.d0 = const[12:18]
        self.toff0 = const[18:24]
        self.c0 = const[24:30]
        self.R0 = ca.reshape(const[30:39], 3, 3)
        self.tool = ca.reshape(const[39:55], 4, 4)
        self.grav = const[55:58]
        self.tau_s = const[58:64]
        self.grav_on = const[64]
        self.beams = [ca.reshape(const[65 + 9 * i:74 + 9 * i], 3, 3) for i in range(6)]
        self.knots = const[119:119 + 6 * N_KNOTS]


def _geometry(u: _Unpacked, dT: Any) -> tuple[Any, Any, Any, Any, Any]:
    """DH parameters with geometric errors and thermal scaling."""
    scale = 1.0 + u.g("thermal.alpha") * dT
    a = (u.a0 + u.g("geometric.da")) * scale
    d = (u.d0 + u.g("geometric.dd")) * scale
    alpha = u.alpha0 + u.g("geometric.dalpha")
    toff = u.toff0 + u.g("joint_offset.dtheta")
    beta = u.g("geometric.dbeta")
    return a, alpha, d, toff, beta


def _chain(q: Any, a: Any, alpha: Any, d: Any, toff: Any, beta: Any, convention: str) -> list[Any]:
    frames = []
    T = ca.SX.eye(4)
    for i in range(6):
        A = link_transform(q[i] + toff[i], d[i], a[i], alpha[i], convention)
        T = ca.mtimes(T, ca.mtimes(A, _ry4(beta[i])))
        frames.append(T)
    return frames


def _torques(frames: list[Any], F: Any, u: _Unpacked, convention: str) -> tuple[Any, Any]:
    """External and gravity joint torques at the pose of ``frames`` (N*m, (6,) each)."""
    zs, ps = joint_axes(frames, convention)
    tcp = ca.mtimes(frames[-1], u.tool)
    p_tcp, R_tcp = tcp[:3, 3], tcp[:3, :3]
    f, m = F[0:3], F[3:6]
    r = ca.mtimes(R_tcp, u.g("load_offset.r_tool")) + u.g("load_offset.r_base")
    m_eff = m + ca.cross(r, f)
    tau_ext = ca.vertcat(*[ca.dot(zs[i], ca.cross(p_tcp - ps[i], f) + m_eff) for i in range(6)])
    mass = u.g("gravity.m")
    h = u.g("gravity.h")
    S = ca.SX.zeros(3)
    M = 0
    tau_g = [None] * 6
    for j in range(5, -1, -1):
        Rj, pj = frames[j][:3, :3], frames[j][:3, 3]
        S = S + mass[j] * pj + ca.mtimes(Rj, h[3 * j:3 * j + 3])
        M = M + mass[j]
        tau_g[j] = ca.dot(zs[j], ca.cross(S - M * ps[j], u.grav))
    return tau_ext, u.grav_on * ca.vertcat(*tau_g)


def _joint_deflection(tau: Any, u: _Unpacked) -> Any:
    c = u.c0 * (1.0 + u.g("stiffness.s"))
    ts = u.tau_s
    b = u.g("hardening.b")
    hinge = []
    for i in range(6):
        # odd quadratic spline of the torque (C1): tau|tau| plus sign(tau) (|tau| - kappa_k)_+^2
        a = ca.fabs(tau[i])
        acc = b[N_HARDENING * i] * tau[i] * a
        for k in range(N_KNOTS):
            kap = u.knots[N_KNOTS * i + k]
            acc = acc + b[N_HARDENING * i + 1 + k] * ca.sign(tau[i]) * ca.fmax(a - kap, 0) ** 2
        hinge.append(acc / ts[i])
    # hinge terms scale with the nominal compliance, so the model is linear in (s, b)
    elastic = c * tau + u.c0 * ca.vertcat(*hinge)
    tau0 = ca.exp(u.g("lost_motion.rho")) * ts
    lost = u.g("lost_motion.b") * ca.tanh(tau / tau0)
    return elastic + lost


def _link_displacement(frames: list[Any], F: Any, point: Any, u: _Unpacked, convention: str,
                       links: tuple[int, ...] = tuple(range(6))) -> Any:
    """Translation of ``point`` (base frame) caused by link and Cartesian compliance, m.

    Link *i* carries a 6x6 compliance at its distal joint, in its beam frame
    (:func:`beam_frames`; axis 0 along the link): translational and rotational
    diagonals plus the six translation-rotation couplings, which contain the
    Euler-Bernoulli beam (``delta_v = L^3/3EI f_v + L^2/2EI m_w`` ...) and lumped
    ("virtual joint") springs as special cases.  The wrench it transmits is the
    applied force and its moment about the link tip.
    """
    _zs, ps = joint_axes(frames, convention)
    tcp = ca.mtimes(frames[-1], u.tool)
    p_tcp, R_tcp = tcp[:3, 3], tcp[:3, :3]
    f, m = F[0:3], F[3:6]
    r = ca.mtimes(R_tcp, u.g("load_offset.r_tool")) + u.g("load_offset.r_base")
    p_app = p_tcp + r
    lc = u.g("link_compliance.link")
    dp = ca.SX.zeros(3)
    for i in links:
        R = ca.mtimes(frames[i][:3, :3], u.beams[i])
        p_tip = ps[i + 1] if i < 5 else frames[5][:3, 3]
        m_tip = m + ca.cross(p_app - p_tip, f)
        fl = ca.mtimes(R.T, f)
        ml = ca.mtimes(R.T, m_tip)
        k = lc[12 * i:12 * i + 12]
        Ctr = ca.vertcat(ca.horzcat(0, k[6], k[7]), ca.horzcat(k[8], 0, k[9]), ca.horzcat(k[10], k[11], 0))
        delta = k[0:3] * fl + ca.mtimes(Ctr, ml)
        phi = ca.mtimes(Ctr.T, fl) + k[3:6] * ml
        dp = dp + ca.mtimes(R, delta + ca.cross(phi, ca.mtimes(R.T, point - p_tip)))
    Ct = _sym3(u.g("link_compliance.tool"))
    dp = dp + ca.mtimes(R_tcp, ca.mtimes(Ct, ca.mtimes(R_tcp.T, f)))
    dp = dp + ca.mtimes(_sym3(u.g("link_compliance.base")), f)
    return dp


def _equilibrium(qc: Any, F: Any, dT: Any, u: _Unpacked, convention: str,
                 q_start: Any = None, n_iter: int = EQUILIBRIUM_UNROLL) -> tuple[Any, list[Any]]:
    geo = _geometry(u, dT)
    q = qc if q_start is None else q_start
    for _ in range(n_iter):
        frames = _chain(q, *geo, convention)
        te, tg = _torques(frames, F, u, convention)
        q = qc + _joint_deflection(te + tg, u)
    return q, _chain(q, *geo, convention)


def _measured_point(frames: list[Any], F: Any, tn: Any, u: _Unpacked, convention: str,
                    links: tuple[int, ...]) -> Any:
    p_flange = ca.mtimes(frames[-1], ca.vertcat(u.g("tool.p"), 1))[:3]
    p_base = p_flange + _link_displacement(frames, F, p_flange, u, convention, links)
    R = ca.mtimes(cayley(u.g("reg.w")), u.R0)
    return ca.mtimes(R, p_base) + u.g("reg.t") + u.g("drift.v") * tn + u.g("drift.a") * tn * tn


@lru_cache(maxsize=8)
def model_functions(convention: str, eligible: tuple[bool, ...] | None = None) -> dict[str, ca.Function]:
    """CasADi functions of the identification model for one DH convention.

    ``eligible`` (length :data:`N_PARAMS`) marks the parameters that exist for the
    robot (:attr:`ModelLayout.eligible`): the Jacobian is taken with respect to them
    only (``measure_jac`` returns ``3 x n_eligible``), and links without beam
    springs are left out of the graph.  ``None``: all parameters.

    Returns
    -------
    dict
        ``measure(row (14), theta (P), const (C)) -> p_meas (3)``;
        ``measure_jac(row, theta, const) -> p_meas (3), dp/dtheta (3 x P)``;
        ``tcp_pose(q (6), F (6), dT (1), theta, const) -> p_tcp (3), R_tcp (3x3)``: the
        TCP of the *deflected* joint angles ``q`` (geometry, thermal and link compliance
        applied; base frame); ``joint_deflection(q, F, dT, theta, const) -> dq (6)``:
        the joint deflection at the equilibrium ``q``;
        ``torques(q_c, F, dT, theta, const) -> tau_ext (6), tau_g (6), q_eq (6)``;
        ``point_jacobian(q, dT, theta, const) -> p (3), Jp (3x6)``: the measured point of
        the undeflected arm and its positional Jacobian, measurement frame.
    """
    el = np.ones(N_PARAMS, dtype=bool) if eligible is None else np.asarray(eligible, dtype=bool)
    s_link = GROUP_SLICES["link_compliance.link"]
    link_el = el[s_link].reshape(6, 12).any(axis=1)
    links = tuple(i for i in range(6) if link_el[i])
    theta_el = ca.SX.sym("theta_el", int(el.sum()))
    # theta with the ineligible entries as their own symbols (kept as inputs, not differentiated)
    theta_fixed = ca.SX.sym("theta_fixed", int((~el).sum()))
    parts = []
    ie = iff = 0
    for k in range(N_PARAMS):
        if el[k]:
            parts.append(theta_el[ie])
            ie += 1
        else:
            parts.append(theta_fixed[iff])
            iff += 1
    theta_v = ca.vertcat(*parts)
    theta = ca.SX.sym("theta", N_PARAMS)
    row = ca.SX.sym("row", ROW_SIZE)
    const = ca.SX.sym("const", CONST_SIZE)
    u = _Unpacked(theta, const)
    qc, F, tn, dT = row[0:6], row[6:12], row[12], row[13]
    q, frames = _equilibrium(qc, F, dT, u, convention)
    p_meas = _measured_point(frames, F, tn, u, convention, links)
    measure = ca.Function("ident_measure", [row, theta, const], [p_meas, q],
                          ["row", "theta", "const"], ["p", "q_eq"])
    # Jacobian: restart the fixed point from the converged q_eq (a constant input), so the
    # value is exact and the derivative carries the implicit-function factor to
    # O(|dq/dq|^JACOBIAN_UNROLL) (relative).
    q_in = ca.SX.sym("q_eq", 6)
    u_v = _Unpacked(theta_v, const)
    _q2, frames2 = _equilibrium(qc, F, dT, u_v, convention, q_start=q_in, n_iter=JACOBIAN_UNROLL)
    p_meas2 = _measured_point(frames2, F, tn, u_v, convention, links)
    jac = ca.jacobian(p_meas2, theta_el)
    jac_fun = ca.Function("ident_measure_jac_el", [row, q_in, theta_el, theta_fixed, const], [p_meas2, jac])
    idx_el = [k for k in range(N_PARAMS) if el[k]]
    idx_fx = [k for k in range(N_PARAMS) if not el[k]]
    th_el = theta[idx_el] if idx_el else ca.SX(0, 1)
    th_fx = theta[idx_fx] if idx_fx else ca.SX(0, 1)
    pj, Jj = jac_fun(row, q_in, th_el, th_fx, const)
    measure_jac = ca.Function("ident_measure_jac", [row, q_in, theta, const], [pj, Jj],
                              ["row", "q_eq", "theta", "const"], ["p", "J"])
    # Torques at the command and equilibrium (diagnostics)
    qe = ca.SX.sym("q", 6)
    Fs = ca.SX.sym("F", 6)
    dTs = ca.SX.sym("dT", 1)
    q_eq, fr_eq = _equilibrium(qe, Fs, dTs, u, convention)
    te, tg = _torques(fr_eq, Fs, u, convention)
    torques = ca.Function("ident_torques", [qe, Fs, dTs, theta, const], [te, tg, q_eq],
                          ["q_c", "F", "dT", "theta", "const"], ["tau_ext", "tau_g", "q_eq"])
    # Pose and deflection at a given (deflected) configuration
    F, dT = Fs, dTs
    geo = _geometry(u, dT)
    fr = _chain(qe, *geo, convention)
    tcp = ca.mtimes(fr[-1], u.tool)
    p_tcp = tcp[:3, 3] + _link_displacement(fr, F, tcp[:3, 3], u, convention, links)
    tcp_pose = ca.Function("ident_tcp_pose", [qe, F, dT, theta, const], [p_tcp, tcp[:3, :3]],
                           ["q", "F", "dT", "theta", "const"], ["p_tcp", "R_tcp"])
    te2, tg2 = _torques(fr, F, u, convention)
    jd = ca.Function("ident_joint_deflection", [qe, F, dT, theta, const], [_joint_deflection(te2 + tg2, u)],
                     ["q", "F", "dT", "theta", "const"], ["dq"])
    # Positional Jacobian of the measured point (undeflected geometry), measurement frame
    fr0 = _chain(qe, *geo, convention)
    p0 = ca.mtimes(fr0[-1], ca.vertcat(u.g("tool.p"), 1))[:3]
    p0m = ca.mtimes(ca.mtimes(cayley(u.g("reg.w")), u.R0), p0) + u.g("reg.t")
    point_jac = ca.Function("ident_point_jacobian", [qe, dT, theta, const], [p0m, ca.jacobian(p0m, qe)],
                            ["q", "dT", "theta", "const"], ["p", "Jp"])
    return {"measure": measure, "measure_jac": measure_jac, "tcp_pose": tcp_pose,
            "joint_deflection": jd, "torques": torques, "point_jacobian": point_jac}
