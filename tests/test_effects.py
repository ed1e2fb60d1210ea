"""Every effect plug-in: its symbolic term against the virtual robot's simulation of the same
physics (an independent NumPy implementation, problems/virtual/), and its derivatives
against finite differences.

For each effect the simulator is configured with that effect alone (its table, which the effect
names: ``Effect.simulation``); its realised physical parameters are mapped to the plug-in's
parameters (``SIMULATION_MAP``, by hand from the physics: beam formulas, dead band, barycentre,
...), and the model's noise-free prediction
of the measured point must equal the simulator's measurement.  Stiffness hardening has no
exact mapping (the simulator's two-slope and smooth curves are not splines): its spline is
fitted to the simulated curve and must match it to a few % of the curve's nonlinear part.
"""

from __future__ import annotations

import pkgutil

import casadi as ca
import numpy as np
import pytest

import models.effects as fx
from models import load_robot
from models.arm import ArmModel
from models.load import Load
from problems.virtual import VirtualRobot

#: Model prediction vs simulator measurement, m.
SIMULATION_MATCH_TOL_M = 1e-9
#: Hardening spline vs simulated curve: max error over the nonlinear part of the curve.
HARDENING_FIT_REL_TOL = 0.05
#: Relative tolerance of the analytic derivatives against central differences.
FD_REL_TOL = 1e-6
#: Derivatives through the unrolled equilibrium (identification graph): the implicit-function
#: factor is carried to first order only (JACOBIAN_UNROLL = 1), a relative error of about
#: |d dq/dq| (<= 1e-2 for the loads here), which Levenberg-Marquardt tolerates.
FD_EQUILIBRIUM_REL_TOL = 1e-2
#: Absolute floor of that comparison, relative to the largest derivative of the row
#: (central differences of a FD_PARAM_STEP-scaled step).
FD_EQUILIBRIUM_ABS_REL = 1e-7
#: Central-difference step of a parameter, in its typical magnitudes: large enough that the rounding of
#: the measured point (~1e-15 m) stays far below the difference for the smallest magnitudes (a map
#: coefficient's 1e-5 rad: a 1e-11 rad step left 1e-4 relative noise), small enough that the truncation
#: of a nonlinear parameter's difference (relative ~step^2) does not matter.
FD_PARAM_STEP = 1e-4


def _vr(robot_name: str, effect: str, table: dict, registered: bool = True) -> VirtualRobot:
    """The virtual robot with the physics of ``effect`` alone, given by ``table``: its table of the
    configuration is the one the effect declares (``[effects.<simulation>]``, or the top-level
    ``[<simulation>]`` of a declared effect)."""
    e = fx.effect(effect)
    cfg = {"campaign": {"poses": 20}, "noise": {"sigma_m": 0.0}, "registration": {"registered": registered}}
    if e.declared:
        cfg[e.simulation] = {**cfg.get(e.simulation, {}), **table}
    else:
        cfg["effects"] = {e.simulation: table}
    return VirtualRobot(load_robot(robot_name), cfg, seed=5)


def _map_geometric(vr: VirtualRobot, th: dict, c: dict) -> None:
    th["geometric.da"], th["geometric.dd"] = vr.da, vr.dd
    th["geometric.dalpha"], th["joint_offset.dtheta"], th["geometric.dbeta"] = vr.dalpha, vr.dtheta, vr.dbeta


def _map_gravity(vr: VirtualRobot, th: dict, c: dict) -> None:
    m, h = vr.masses.copy(), vr.masses[:, None] * vr.coms
    m[5] += vr.payload  # the payload rides on link 6 (flange frame)
    h[5] += vr.payload * vr.payload_com
    th["gravity.m"], th["gravity.h"] = m, h.reshape(-1)
    c["gravity.on"] = [1.0]


def _map_lost_motion(vr: VirtualRobot, th: dict, c: dict) -> None:
    th["lost_motion.b"] = vr.backlash
    c["tau_scale"] = np.ones(6)
    th["lost_motion.rho"] = [np.log(vr.backlash_smoothing)]  # tau_0 = exp(rho) * 1 N*m


def _map_link_compliance(vr: VirtualRobot, th: dict, c: dict) -> None:
    """Euler-Bernoulli beam of length L along the beam axis x: delta_v = L^3/3EI f_v
    + L^2/2EI (m x e)_v, phi = L^2/2EI (e x f) + L/EI m_perp + L/GJ m_axial."""
    robot = vr.robot
    fr = ArmModel.from_robot(robot).kinematics.fk_frames(np.zeros(6))
    pts = [np.zeros(3)] + [np.asarray(T)[:3, 3] for T in fr[:5]]
    lc = np.zeros((6, 12))
    for k, i in enumerate(vr.beam_links):
        L = np.linalg.norm(pts[i + 1] - pts[i])
        EI, GJ = vr.EI[k], vr.GJ[k]
        lc[i, 0:6] = [0.0, L**3 / (3 * EI), L**3 / (3 * EI), L / GJ, L / EI, L / EI]
        lc[i, 9], lc[i, 11] = L**2 / (2 * EI), -(L**2) / (2 * EI)  # tr_yz, tr_zy
    th["link_compliance.link"] = lc.reshape(-1)


def _map_joint_tilt(vr: VirtualRobot, th: dict, c: dict) -> None:
    """The tilt compliances of the joints listed; the weight is the robot file's links (no
    ``[effects.gravity]``), the model's ``gravity`` parameters at their nominal values."""
    cx, cy = np.zeros(6), np.zeros(6)
    cx[vr.tilt_joints], cy[vr.tilt_joints] = vr.tilt_cx, vr.tilt_cy
    th["joint_tilt.cx"], th["joint_tilt.cy"] = cx, cy


#: Campaign span of the rows (s): tn = t / span.
SPAN_S = 7200.0


def _map_drift(vr: VirtualRobot, th: dict, c: dict) -> None:
    th["drift.v"], th["drift.a"] = vr.drift_rate * SPAN_S, vr.drift_acc * SPAN_S**2  # at tn = 1


def _map_thermal(vr: VirtualRobot, th: dict, c: dict) -> None:
    a = np.zeros(6)
    a[vr.th_links] = vr.th_alpha
    th["thermal.alpha"] = a


def _map_registration(vr: VirtualRobot, th: dict, c: dict) -> None:
    c["registration.R0"] = vr.R_reg
    th["reg.t"], th["tool.p"] = vr.t_reg, vr.p_tool


def _map_error_map(vr: VirtualRobot, th: dict, c: dict) -> None:
    """Each simulated term ``A sin(h q + phi)`` of joint j is a theta-component slot with frequency
    h: ``a cos(h q) + b sin(h q)``, a = A sin(phi), b = A cos(phi); the range is left open."""
    from models.effects.joint_error_map import COEF_SHAPE, FREQ_SHAPE

    coef, freq = np.zeros(COEF_SHAPE), np.zeros(FREQ_SHAPE)
    used = np.zeros(6, dtype=int)
    for t in vr.joint_error_terms():
        j, s = t["joint"] - 1, used[t["joint"] - 1]
        freq[j, 0, s] = t["harmonic"]
        coef[j, 0, s] = [t["amplitude_rad"] * np.sin(t["phase_rad"]), t["amplitude_rad"] * np.cos(t["phase_rad"])]
        used[j] += 1
    th["error_map.c"] = coef.reshape(-1)
    c["error_map.freq"] = freq.reshape(-1)


def _map_springs(vr: VirtualRobot, th: dict, c: dict) -> None:
    th["stiffness.s"] = vr.robot.stiffness / vr.k_true - 1.0


#: effect -> (robot, its simulator table, registered, mapping).  The table's name is the effect's
#: declaration (``Effect.simulation``), not repeated here: only the test's own knowledge is (which
#: values excite the physics, and how the realised physics maps onto the effect's parameters).
SIMULATION_MAP = {
    "joint_springs": ("ur5", {"scale": [1.3, 0.8, 1.1, 0.7, 1.2, 0.9]}, True, _map_springs),
    "registration": ("ur10", {}, False, _map_registration),
    "measured_point": ("ur10", {}, False, _map_registration),
    "joint_offset": ("ur5", {"dtheta_rad": [1e-3, -2e-3, 5e-4, 1e-3, -1e-3, 2e-3]}, True, _map_geometric),
    "geometric": ("ur10", {}, True, _map_geometric),
    "gravity": ("ur10", {"payload_kg": 3.0, "payload_com_m": [0.01, 0.02, 0.05]}, True, _map_gravity),
    # ur5, not the paper's ar5: the ar5's joints are so compliant that 60 N loads leave the
    # identification graph's EQUILIBRIUM_UNROLL-times unrolled fixed point ~1e-7 m short of
    # convergence, which would hide the term under the truncation (the planning model iterates)
    "lost_motion": ("ur5", {"backlash_rad": 3e-4, "smoothing_Nm": 2.0}, True, _map_lost_motion),
    "load_offset": (
        "ur5",
        {"r_tool_m": [0.01, 0.04, 0.07]},
        True,
        lambda vr, th, c: th.__setitem__("load_offset.r_tool", vr.r_tool),
    ),
    "link_compliance": ("ur10", {"EI_Nm2": 1.5e5, "GJ_Nm2": 1.0e5}, True, _map_link_compliance),
    "joint_tilt": (
        "ur10",
        {
            "joints": [1, 2, 3],
            "compliance_x_rad_per_Nm": [2e-6, 5e-6, 8e-6],
            "compliance_y_rad_per_Nm": [3e-6, 1e-6, 6e-6],
        },
        True,
        _map_joint_tilt,
    ),
    "drift": ("ur5", {"rate_m_per_h": [2e-4, -1e-4, 1.5e-4], "accel_m_per_h2": [1e-4, 0, -2e-4]}, True, _map_drift),
    "thermal": ("ur5", {"alpha_per_K": 2.3e-5, "links": [2, 3]}, True, _map_thermal),
    "stiffness_hardening": None,  # no exact mapping: see test_hardening_spline_fits_the_simulated_curves
    "joint_error_map": (
        "ur5",
        {
            "joint": [1, 1, 3],
            "amplitude_rad": [1e-3, 2e-4, 4e-4],
            "harmonic": [2, 13.4, 5.5],
            "phase_rad": [0.3, -1.2, 1.1],
        },
        True,
        _map_error_map,
    ),
}


def test_every_module_of_the_package_registers_an_effect():
    names = {m.name for m in pkgutil.iter_modules(fx.__path__)} - {"base", "graph"}
    registered = {type(e).__module__.rsplit(".", 1)[1] for e in fx.registry()}
    assert names == registered
    for e in fx.registry():
        assert e.formula and (e.declared or e.name in fx.LIBRARY)
        for g in e.groups:
            assert len(g.units()) == g.size and all(g.units())
    # the layouts are built from the declarations alone
    assert fx.N_PARAMS == sum(g.size for e in fx.registry() for g in e.groups)
    assert fx.CONST_SIZE == fx.layouts().const_size


def test_every_effect_has_a_simulation_check():
    assert set(SIMULATION_MAP) == {e.name for e in fx.registry()}
    # ... and the virtual robot simulates each (the agreement itself: test_virtual_extensions.py)
    from problems.virtual import realisation

    assert all(realisation(name) is not None for name in SIMULATION_MAP)


def _rows(vr: VirtualRobot, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    q = vr.sample_poses(n, rng)
    F = np.zeros((n, 6))
    F[:, :3] = rng.normal(0, 60.0, (n, 3))
    F[:, 3:] = rng.normal(0, 3.0, (n, 3))
    F[::4] = 0.0
    t = np.linspace(0.0, SPAN_S, n)
    temp = np.linspace(15.0, 35.0, n)
    return q, F, t, temp


@pytest.mark.parametrize("name", sorted(k for k, v in SIMULATION_MAP.items() if v is not None))
def test_symbolic_term_equals_the_virtual_robot(name, rng):
    robot_name, table, registered, mapping = SIMULATION_MAP[name]
    vr = _vr(robot_name, name, table, registered)
    assert vr.simulated(name)
    robot = vr.robot
    th: dict = {}
    c: dict = {}
    mapping(vr, th, c)
    const = fx.make_const(robot)
    for k, v in c.items():
        const = fx.set_const(const, k, np.asarray(v, dtype=float))
    lay = fx.make_layout(robot, const)
    theta = lay.nominal.copy()
    if registered:
        theta[fx.GROUP_SLICES["tool.p"]] = vr.p_tool
    for k, v in th.items():
        theta[fx.GROUP_SLICES[k]] = np.asarray(v, dtype=float).reshape(-1)
    n = 24
    q, F, t, temp = _rows(vr, n, rng)
    rows = np.column_stack([q, F, t / SPAN_S, temp - fx.THERMAL_REFERENCE_C, np.zeros((n, 4))])
    f = fx.identification_functions(robot.convention, tuple(bool(x) for x in lay.eligible))["measure"]
    pred = np.array([np.asarray(f(rows[i], theta, const)[0]).reshape(3) for i in range(n)])
    meas = vr.measure(q, F, t, temp)
    err = np.linalg.norm(pred - meas, axis=1).max()
    assert err < SIMULATION_MATCH_TOL_M, err
    # the effect is not trivially absent: the nominal model differs
    nominal = np.array([np.asarray(f(rows[i], lay.nominal, fx.make_const(robot))[0]).reshape(3) for i in range(n)])
    assert np.linalg.norm(nominal - meas, axis=1).max() > 1e-6


@pytest.mark.parametrize("model", ["two_slope", "smooth"])
def test_hardening_spline_fits_the_simulated_curves(model):
    vr = _vr(
        "ur5",
        "stiffness_hardening",
        {"model": model, "knee_torque_Nm": 30.0, "stiffness_ratio": 2.0, "beta_per_Nm": 0.01},
    )
    from models.effects.stiffness_hardening import HARDENING_KNOT_QUANTILES, N_HARDENING, StiffnessHardening

    k0 = vr.robot.stiffness
    tau_max = 120.0
    tau = np.linspace(-tau_max, tau_max, 241)
    truth = vr._deflection(np.tile(tau[:, None], (1, 6)))  # (M, 6) rad
    ts = np.full(6, tau_max)
    knots = np.outer(ts, HARDENING_KNOT_QUANTILES)
    eff = StiffnessHardening()
    # the plug-in's term is linear in (s, b): fit per joint by least squares through its own graph
    b_sym, s_sym, t_sym = ca.SX.sym("b", 6 * N_HARDENING), ca.SX.sym("s", 6), ca.SX.sym("t", 6)

    class Ctx:
        def p(self, key):
            return b_sym if key == "hardening.b" else s_sym

        def c(self, key):
            return {
                "tau_scale": ca.DM(ts),
                "hardening.knots": ca.DM(knots.reshape(-1)),
                "compliance0": ca.DM(1.0 / k0),
            }[key]

    ctx = Ctx()
    dq = eff.joint_deflection(ctx, t_sym) + ctx.c("compliance0") * (1 + s_sym) * t_sym
    fn = ca.Function("h", [t_sym, b_sym, s_sym], [dq, ca.jacobian(dq, ca.vertcat(b_sym, s_sym))])
    for j in range(6):
        A, y = [], []
        for ti, yi in zip(tau, truth[:, j]):
            v, J = fn(np.full(6, ti), np.zeros(6 * N_HARDENING), np.zeros(6))
            A.append(np.asarray(J)[j])
            y.append(yi)
        A, y = np.array(A), np.array(y)
        x = np.linalg.lstsq(A, y, rcond=None)[0]
        nonlinear = np.abs(y - tau / k0[j]).max()
        assert nonlinear > 1e-5
        assert np.abs(A @ x - y).max() < HARDENING_FIT_REL_TOL * nonlinear, (j, np.abs(A @ x - y).max(), nonlinear)


def _random_model(robot_name: str, rng: np.random.Generator) -> tuple[ArmModel, np.ndarray]:
    robot = load_robot(robot_name)
    lay = fx.make_layout(robot)
    theta = lay.nominal + rng.normal(0, 0.5, fx.N_PARAMS) * lay.scale * lay.eligible
    theta[fx.GROUP_SLICES["lost_motion.rho"]] = np.log(0.2)  # smooth enough for differences
    effects = [e for e in fx.LIBRARY if e not in ("outliers",)]
    arm = ArmModel(
        nominal=robot, theta=theta, tau_scale=np.full(6, 40.0), gravity_on=True, effects=effects, temperature_ref=27.0
    )
    return arm, theta


@pytest.mark.parametrize("fname", ["load_deflection", "joint_torques", "load_error", "tcp_wrench"])
def test_planning_functions_with_every_effect_match_finite_differences(fname, rng):
    arm, _ = _random_model("ur10", rng)
    f = arm.kinematics.fn[fname]
    q = ca.SX.sym("q", 6)
    L = ca.SX.sym("L", fx.LOAD_SIZE)
    jf = ca.Function("j", [q, L], [ca.jacobian(f(q, L), q)])
    load = Load(
        wrench_base=[30, -20, -60, 1, 2, 0],
        wrench_tool=[0, 5, -20, 0, 0, 1],
        payload_mass_kg=3.0,
        payload_com_m=[0.02, 0.0, 0.08],
    ).rows(1)[0]
    for _ in range(4):
        q0 = rng.uniform(-2.5, 2.5, 6)
        J = np.asarray(jf(q0, load))
        h = 1e-6
        fd = np.column_stack(
            [
                (np.asarray(f(q0 + h * e, load)) - np.asarray(f(q0 - h * e, load))).reshape(-1) / (2 * h)
                for e in np.eye(6)
            ]
        )
        scale = max(np.abs(J).max(), 1e-12)
        assert np.abs(J - fd).max() < FD_REL_TOL * scale * 10, (fname, np.abs(J - fd).max(), scale)


@pytest.mark.parametrize("effect", [e.name for e in fx.registry() if e.groups])
def test_identification_derivatives_of_each_effect_match_finite_differences(effect, rng):
    robot = load_robot("ur10")
    const = fx.make_const(robot, np.eye(3), np.full(6, 40.0), True)
    if effect == "joint_error_map":  # two slots of every joint and component in use
        from models.effects.joint_error_map import FREQ_SHAPE

        freq = np.zeros(FREQ_SHAPE)
        freq[:, :, 0], freq[:, :, 1] = 3.0, 7.5
        const = fx.set_const(const, "error_map.freq", freq.reshape(-1))
        const = fx.set_const(const, "error_map.range", np.tile([-2.0, 2.0], 6))
    lay = fx.make_layout(robot, const)
    theta = lay.nominal + rng.normal(0, 0.3, fx.N_PARAMS) * lay.scale * lay.eligible
    theta[fx.GROUP_SLICES["lost_motion.rho"]] = np.log(0.2)
    fns = fx.identification_functions(robot.convention, tuple(bool(x) for x in lay.eligible))
    idx = (
        lay.effect_indices(effect)
        if not fx.effect(effect).declared
        else lay.indices([g.key for g in fx.effect(effect).groups])
    )
    assert len(idx)
    for _ in range(3):
        row = np.r_[rng.uniform(-2.5, 2.5, 6), rng.normal(0, 15.0, 3), rng.normal(0, 1.0, 3), 0.4, 6.0, 0, 0, 0, 0]
        _p, q_eq = fns["measure"](row, theta, const)
        _p, J = fns["measure_jac"](row, q_eq, theta, const)
        J = np.asarray(J)
        el = np.flatnonzero(lay.eligible)
        Jfull = np.zeros((3, fx.N_PARAMS))
        Jfull[:, el] = J
        for i in idx:
            h = FD_PARAM_STEP * lay.scale[i]
            tp, tm = theta.copy(), theta.copy()
            tp[i] += h
            tm[i] -= h
            fd = np.asarray(fns["measure"](row, tp, const)[0]) - np.asarray(fns["measure"](row, tm, const)[0])
            fd = fd.reshape(3) / (2 * h)
            scale = max(np.abs(fd).max(), np.abs(Jfull[:, i]).max(), 1e-15)
            floor = FD_EQUILIBRIUM_ABS_REL * np.abs(Jfull * lay.scale[None, :]).max() / lay.scale[i]
            assert np.abs(Jfull[:, i] - fd).max() <= FD_EQUILIBRIUM_REL_TOL * scale + floor, (
                fx.PARAM_NAMES[i],
                Jfull[:, i],
                fd,
            )


def test_arm_model_with_every_effect_equals_the_identification_graph(rng):
    """Planning and identification evaluate one graph: the loaded TCP of the planning functions at
    the equilibrium equals the identification graph's measured point for a TCP measurement."""
    arm, theta = _random_model("ur10", rng)
    robot = arm.nominal
    theta = theta.copy()
    theta[fx.GROUP_SLICES["tool.p"]] = robot.tcp2flange[:3, 3]
    for g in ("reg.w", "reg.t", "drift.v", "drift.a"):
        theta[fx.GROUP_SLICES[g]] = 0.0
    arm = ArmModel(
        nominal=robot, theta=theta, tau_scale=arm.tau_scale, gravity_on=True, effects=arm.effects, temperature_ref=27.0
    )
    lay = fx.make_layout(robot)
    f = fx.identification_functions(robot.convention, tuple(bool(x) for x in lay.eligible))["measure"]
    for _ in range(5):
        q = rng.uniform(-2.5, 2.5, 6)
        F = np.r_[rng.normal(0, 40.0, 3), rng.normal(0, 2.0, 3)]
        row = np.r_[q, F, 0.0, 27.0 - fx.THERMAL_REFERENCE_C, 0, 0, 0, 0]
        p_id = np.asarray(f(row, theta, arm.const)[0]).reshape(3)
        eq = arm.equilibrium(q[None], F)
        p_plan, _R = arm.loaded_tcp(eq.q, F)
        assert np.linalg.norm(p_plan[0] - p_id) < 1e-9


def test_a_new_effect_module_is_all_it_takes(tmp_path):
    """Adding an effect is adding one module that registers itself: a module in a folder on
    $COMPPLAN_EFFECT_PATH is discovered, gets parameters in the layout, and acts in planning."""
    import os
    import subprocess
    import sys

    plugin = """
import casadi as ca
from .base import Effect, ParamGroup, register


@register
class WristOffset(Effect):
    name = "wrist_offset"
    order = 50
    groups = (ParamGroup("wrist_offset.d", ("wrist_offset.d",), "m", scale=1e-3),)
    formula = "d_4 += d (test plug-in)"

    def geometry(self, ctx, dh):
        return {**dh, "d": dh["d"] + ca.vertcat(0, 0, 0, ctx.p("wrist_offset.d"), 0, 0)}
"""
    (tmp_path / "wrist_offset.py").write_text(plugin)
    code = """
import numpy as np
import models.effects as fx
from models import load_robot
from models.arm import ArmModel
assert "wrist_offset" in fx.LIBRARY, fx.LIBRARY
r = load_robot("ur5")
th = fx.make_layout(r).nominal.copy()
th[fx.GROUP_SLICES["wrist_offset.d"]] = 0.01
a = ArmModel(nominal=r, theta=th, effects=["wrist_offset"])
n = ArmModel.from_robot(r)
q = np.array([0.1, -1.0, 1.2, -1.5, -1.4, 0.3])
print(float(np.linalg.norm(a.kinematics.tcp(q)[:3, 3] - n.kinematics.tcp(q)[:3, 3])))
"""
    env = {**os.environ, "COMPPLAN_EFFECT_PATH": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert abs(float(out.stdout.strip().splitlines()[-1]) - 0.01) < 1e-9
