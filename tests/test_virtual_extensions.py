"""Virtual robot: which effects it simulates, periodic joint errors with several terms, and 6-D
(orientation) campaigns.

The references are computed here by hand (the old single-term formula, a sum of sines, the
nominal forward kinematics of :class:`models.symbolic.KinematicModel`), not by the
simulator's own code paths.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from scipy.spatial.transform import Rotation

import models.effects as fx
from models import load_robot
from models.robot import robot_from_dict
from models.symbolic import KinematicModel
from models.transforms import rpy_to_matrix, transform
from problems.measurements import measurements_to_csv, parse_measurements
from problems.virtual import (
    SIM_EFFECTS,
    SimConfigError,
    VirtualRobot,
    effect_tables,
    from_truth,
    load_config,
    not_simulated,
    realisation,
    realisations,
    rotvecs,
)
from problems.virtual.registry import top_level_tables
from tests.conftest import as_modified_dh

#: Default registration of an unregistered simulated campaign (docs/identification.md, section 9).
REG_ROTVEC = [0.02, -0.01, 0.6]
#: A tool with a rotation, so that R_tcp2flange matters.
TOOL = transform(rpy_to_matrix([0.3, -0.2, 1.1]), np.array([0.01, 0.02, 0.15]))
NO_NOISE = {"sigma_m": 0.0, "sigma_rad": 0.0}


def _rng() -> np.random.Generator:
    return np.random.default_rng(20240611)


def _q(n: int = 40) -> np.ndarray:
    return _rng().uniform(-math.pi, math.pi, (n, 6))


def _angle_between(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Rotation angle of Ra^T Rb per row, rad."""
    return np.linalg.norm(Rotation.from_matrix(np.swapaxes(Ra, -1, -2) @ Rb).as_rotvec(), axis=-1)


# ----------------------------------------------------------------------------------
# Which effects the virtual robot simulates
# ----------------------------------------------------------------------------------

#: Smallest change of the measured point (m) a table's physics must make in
#: test_each_effect_table_changes_the_measurement (its defaults give 1e-5 m and more).
EFFECT_VISIBLE_M = 1e-6

#: A plug-in module of two effects the virtual robot does not simulate: one declares no table,
#: the other a table with no realisation.
UNSIMULATED_PLUGIN = """
from .base import Effect, ParamGroup, register


@register
class WristOffset(Effect):
    name = "wrist_offset"
    order = 50
    groups = (ParamGroup("wrist_offset.d", ("wrist_offset.d",), "m", scale=1e-3),)
    formula = "d_4 += d (test plug-in, no simulation)"


@register
class Wobble(Effect):
    name = "wobble"
    order = 51
    groups = (ParamGroup("wobble.a", ("wobble.a",), "m", scale=1e-3),)
    formula = "test plug-in, a table the virtual robot does not realise"
    simulation = "wobble_sim"
"""


def test_the_effects_and_the_virtual_robot_agree_on_what_is_simulated() -> None:
    """Every effect that declares a table (``simulation``) has a realisation under its name, and every
    realisation realises effects that declare its table; the valid tables follow from the declarations."""
    for e in fx.registry():
        r = realisation(e.name)
        assert (r is not None) == bool(e.simulation), e.name
        if r is not None:
            assert r.table == e.simulation and r.top_level == e.declared, e.name
    for r in realisations():
        assert all(fx.effect(n).simulation == r.table for n in r.effects), r
        assert r.effects or r.table == "outliers"  # the one table of no model term
    assert not_simulated() == {}  # every built-in effect is simulated
    library = [e for e in fx.registry() if e.simulation and not e.declared]
    assert set(effect_tables()) == {n for e in library for n in (e.simulation, e.name)} | {"outliers"}
    assert set(SIM_EFFECTS) == set(effect_tables())
    assert set(top_level_tables()) == {e.simulation for e in fx.registry() if e.declared}
    assert set(top_level_tables()) == {"stiffness", "registration"}
    # a table may be named by the declaration or by the effect (joint_error_map: [effects.eccentricity])
    assert effect_tables()["eccentricity"] is effect_tables()["joint_error_map"] is realisation("joint_error_map")


@pytest.mark.parametrize("name", [n for n in SIM_EFFECTS if n != "outliers"])
def test_each_effect_table_changes_the_measurement(name: str) -> None:
    """Each ``[effects.NAME]`` table, with its defaults, reaches the physics: the robot says it simulates
    the effects of that table and the noise-free measurement moves."""
    robot = load_robot("ur5")
    rng = _rng()
    q = rng.uniform(-2.0, 2.0, (12, 6))
    F = np.hstack([rng.normal(0.0, 120.0, (12, 3)), rng.normal(0.0, 5.0, (12, 3))])
    t, temp = np.linspace(0.0, 7200.0, 12), np.linspace(15.0, 35.0, 12)
    plain = VirtualRobot(robot, {})
    vr = VirtualRobot(robot, {"effects": {name: {}}})
    assert all(vr.simulated(n) for n in effect_tables()[name].effects)
    assert not any(plain.simulated(n) for n in effect_tables()[name].effects)
    moved = np.linalg.norm(vr.measure(q, F, t, temp) - plain.measure(q, F, t, temp), axis=1).max()
    assert moved > EFFECT_VISIBLE_M, (name, moved)


def test_outliers_are_a_simulated_table_of_no_model_effect() -> None:
    cfg = {"campaign": {"poses": 10}, "noise": {"sigma_m": 0.0}}
    vr = VirtualRobot(load_robot("ur5"), {**cfg, "effects": {"outliers": {"fraction": 0.1}}})
    assert vr.simulated("outliers") and realisation("outliers") is None
    m, m0 = vr.campaign(), VirtualRobot(load_robot("ur5"), cfg).campaign()
    moved = np.flatnonzero(np.linalg.norm(m.p - m0.p, axis=1) > 0)
    assert moved.tolist() == vr.outlier_rows.tolist() and len(moved) == 4  # 10 % of 40 rows


@pytest.mark.parametrize(
    "name, words",
    [
        ("wobble", ["'wobble'", "known: ['joint_offset'", "'eccentricity', 'joint_error_map', 'outliers']"]),
        ("stiffness", ["'stiffness'", "[stiffness] is a top-level table"]),
        ("joint_springs", ["'joint_springs'", "declared model", "top-level table [stiffness]"]),
        ("measured_point", ["'measured_point'", "declared model", "top-level table [registration]"]),
    ],
)
def test_an_unknown_effect_table_lists_the_known_ones(name: str, words: list[str]) -> None:
    with pytest.raises(SimConfigError) as exc:
        VirtualRobot(load_robot("ur5"), {"effects": {name: {}}}, where="s.toml")
    msg = str(exc.value)
    assert msg.startswith("s.toml: unknown effect(s)"), msg
    for w in words:
        assert w in msg, (w, msg)


def test_a_plug_in_effect_the_virtual_robot_does_not_simulate_is_reported(tmp_path) -> None:
    """A plug-in effect (``$COMPPLAN_EFFECT_PATH``) that declares no table, or one the virtual robot
    does not realise, is listed by ``not_simulated`` with the reason, a configuration naming it is an
    error saying so, and the virtual robot simulates everything else as before."""
    (tmp_path / "unsimulated.py").write_text(UNSIMULATED_PLUGIN)
    code = """
from models import load_robot
from problems.virtual import SIM_EFFECTS, SimConfigError, VirtualRobot, not_simulated
ns = not_simulated()
assert sorted(ns) == ["wobble", "wrist_offset"], ns
assert "wobble_sim" not in SIM_EFFECTS and "wrist_offset" not in SIM_EFFECTS, SIM_EFFECTS
print(ns["wrist_offset"])
print(ns["wobble"])
for name in ("wrist_offset", "wobble_sim", "wobble"):
    try:
        VirtualRobot(load_robot("ur5"), {"effects": {name: {}}}, where="s.toml")
    except SimConfigError as exc:
        print(exc)
    else:
        raise AssertionError(name)
vr = VirtualRobot(load_robot("ur5"), {"campaign": {"poses": 3}, "effects": {"gravity": {}}}, seed=2)
print(vr.campaign().n)
"""
    env = {**os.environ, "COMPPLAN_EFFECT_PATH": str(tmp_path)}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env, check=False
    )
    assert out.returncode == 0, out.stderr[-2000:]
    why_none, why_table, plug_in, table, effect, rows = out.stdout.strip().splitlines()[-6:]
    assert "declares no table of the virtual robot" in why_none
    assert "[effects.wobble_sim]" in why_table and "does not realise" in why_table
    assert "unknown effect(s) ['wrist_offset']" in plug_in and why_none in plug_in
    assert "unknown effect(s) ['wobble_sim']" in table and "known: ['joint_offset'" in table
    assert "[effects.wobble_sim] is the table of effect(s) wobble" in table and "does not realise" in table
    assert "unknown effect(s) ['wobble']" in effect and why_table in effect
    assert rows == "12"


# ----------------------------------------------------------------------------------
# Periodic joint errors
# ----------------------------------------------------------------------------------


def test_single_term_form_is_bit_identical_to_the_old_formula() -> None:
    """``joint = 1, amplitude_rad, harmonic, phase_rad`` as before: the term
    ``amplitude sin(harmonic q_c[:, j] + phase)`` added to the commanded joint before the
    equilibrium (the loads act on the pose with the error), applied by hand to a robot without
    the effect, gives the same campaign to the last bit."""
    robot = load_robot("ur5")
    base = {"seed": 5, "campaign": {"poses": 15}, "noise": {"sigma_m": 2e-5}}
    ecc = {"joint": 1, "amplitude_rad": 1e-3, "harmonic": 2, "phase_rad": 0.3}
    vr = VirtualRobot(robot, {**base, "effects": {"eccentricity": ecc}})
    ref = VirtualRobot(robot, base)
    plain_eq = ref.equilibrium

    def old_equilibrium(q_c, F, temperature=None):
        qc = np.atleast_2d(q_c).copy()
        qc[:, 0] += 1e-3 * np.sin(2.0 * qc[:, 0] + 0.3)
        return plain_eq(qc, F, temperature)

    ref.equilibrium = old_equilibrium  # the reference: the old formula, by hand
    m, m_ref = vr.campaign(), ref.campaign()
    for k in ("q", "wrench", "p", "t"):
        assert np.array_equal(getattr(m, k), getattr(m_ref, k)), k
    assert np.array_equal(vr.equilibrium(m.q, m.wrench), old_equilibrium(m.q, m.wrench))
    # the truth lists the one term
    assert vr.truth()["realised"]["joint_error_terms"] == [
        {"joint": 1, "amplitude_rad": 1e-3, "harmonic": 2.0, "phase_rad": 0.3}
    ]
    # defaults of an empty table are the old ones
    d = VirtualRobot(robot, {"effects": {"eccentricity": {}}})
    assert d.joint_error_terms() == [{"joint": 1, "amplitude_rad": 1e-3, "harmonic": 2.0, "phase_rad": 0.3}]


def test_multi_term_joint_errors_are_the_hand_computed_sum() -> None:
    robot = load_robot("ur10")
    terms = {
        "joint": [1, 1, 4, 6],
        "amplitude_rad": [1e-3, -4e-4, 2e-4, 3e-4],
        "harmonic": [2, 13.4, 1, 3.5],
        "phase_rad": [0.3, -1.0, 2.0, 0.0],
    }
    q = _q()
    expect = np.zeros_like(q)
    expect[:, 0] = 1e-3 * np.sin(2 * q[:, 0] + 0.3) - 4e-4 * np.sin(13.4 * q[:, 0] - 1.0)
    expect[:, 3] = 2e-4 * np.sin(q[:, 3] + 2.0)
    expect[:, 5] = 3e-4 * np.sin(3.5 * q[:, 5])
    vr = VirtualRobot(robot, {"effects": {"joint_error_map": terms}})
    np.testing.assert_allclose(vr.joint_error(q), expect, rtol=0, atol=1e-17)
    # both spellings are the same effect
    vr_e = VirtualRobot(robot, {"effects": {"eccentricity": terms}})
    assert np.array_equal(vr_e.joint_error(q), vr.joint_error(q))
    # the error is added to the commanded joints before the equilibrium: the loads act on that pose
    F = _rng().normal(0.0, 80.0, (len(q), 6))
    plain = VirtualRobot(robot, {})
    np.testing.assert_allclose(vr.equilibrium(q, F), plain.equilibrium(q + expect, F), rtol=0, atol=1e-15)
    # scalars apply to every term; a single joint number to all of them
    vr_b = VirtualRobot(
        robot,
        {
            "effects": {
                "joint_error_map": {"joint": 2, "amplitude_rad": [1e-3, 2e-4], "harmonic": [1, 7.5], "phase_rad": 0.5}
            }
        },
    )
    e2 = 1e-3 * np.sin(q[:, 1] + 0.5) + 2e-4 * np.sin(7.5 * q[:, 1] + 0.5)
    np.testing.assert_allclose(vr_b.joint_error(q)[:, 1], e2, rtol=0, atol=1e-17)
    assert not np.any(vr_b.joint_error(q)[:, [0, 2, 3, 4, 5]])
    # absent effect: zeros
    assert np.array_equal(plain.joint_error(q), np.zeros_like(q))
    assert plain.truth()["realised"]["joint_error_terms"] == []


def test_joint_error_truth_round_trips_through_toml() -> None:
    cfg = {
        "seed": 3,
        "effects": {
            "joint_error_map": {
                "joint": [2, 5],
                "amplitude_rad": [5e-4, 1e-4],
                "harmonic": [1.5, 40],
                "phase_rad": [0.1, 0.2],
            }
        },
    }
    vr = VirtualRobot(load_robot("ur5"), cfg)
    truth = tomllib.loads(tomli_w.dumps(vr.truth()))
    assert truth["realised"]["joint_error_terms"] == [
        {"joint": 2, "amplitude_rad": 5e-4, "harmonic": 1.5, "phase_rad": 0.1},
        {"joint": 5, "amplitude_rad": 1e-4, "harmonic": 40.0, "phase_rad": 0.2},
    ]
    q = _q(10)
    assert np.array_equal(from_truth(truth).joint_error(q), vr.joint_error(q))


BAD_JOINT_ERRORS = [
    ({"joint": 7}, ["'joint'", "7"]),
    ({"joint": [1, 0], "amplitude_rad": [1e-3, 1e-3]}, ["'joint[1]'", "0"]),
    ({"joint": "1"}, ["'joint'", "'1'"]),
    ({"joint": True}, ["'joint'", "True"]),
    ({"joint": []}, ["'joint'", "non-empty"]),
    ({"joint": [1, 2], "amplitude_rad": [1e-3, 1e-3, 1e-3]}, ["'joint' has 2", "'amplitude_rad' has 3"]),
    ({"harmonic": 0}, ["'harmonic'", "0"]),
    ({"harmonic": 250.0}, ["'harmonic'", "250"]),
    ({"harmonic": [2, -1], "joint": [1, 2]}, ["'harmonic[1]'", "-1"]),
    ({"amplitude_rad": 0.1}, ["'amplitude_rad'", "0.1"]),
    ({"amplitude_rad": [1e-3, -0.06]}, ["'amplitude_rad[1]'", "-0.06"]),
    ({"amplitude_rad": float("nan")}, ["'amplitude_rad'", "finite"]),
    ({"phase_rad": "x"}, ["'phase_rad'", "'x'"]),
    ({"period": 2}, ["unknown key", "period"]),
]


@pytest.mark.parametrize("name", ["eccentricity", "joint_error_map"])
@pytest.mark.parametrize("table, words", BAD_JOINT_ERRORS)
def test_joint_error_config_errors_name_the_key_and_value(name: str, table: dict, words: list[str]) -> None:
    with pytest.raises(SimConfigError) as exc:
        VirtualRobot(load_robot("ur5"), {"effects": {name: table}}, where="s.toml")
    msg = str(exc.value)
    assert "s.toml" in msg and f"[effects.{name}]" in msg
    for w in words:
        assert w in msg, (w, msg)


def test_both_spellings_of_the_joint_error_effect_are_refused() -> None:
    with pytest.raises(SimConfigError, match=r"eccentricity.*joint_error_map"):
        VirtualRobot(load_robot("ur5"), {"effects": {"eccentricity": {}, "joint_error_map": {}}})


# ----------------------------------------------------------------------------------
# Orientation
# ----------------------------------------------------------------------------------


def _robot(kind: str):
    r = load_robot("ur5")
    if kind == "modified_dh":
        r = robot_from_dict(as_modified_dh(r.to_dict()), "mdh")
    return r.with_tool(TOOL)


@pytest.mark.parametrize("kind, registered", [("standard_dh", False), ("standard_dh", True), ("modified_dh", False)])
def test_noise_free_orientation_is_the_nominal_fk_with_the_registration(kind: str, registered: bool) -> None:
    robot = _robot(kind)
    cfg = {
        "campaign": {"poses": 20, "loaded_rows": 2, "orientation": True},
        "noise": NO_NOISE,
        "registration": {"registered": registered},
    }
    vr = VirtualRobot(robot, cfg)
    m = vr.campaign()
    assert m.rotation is not None and m.rotation.shape == (m.n, 3)
    R_reg = np.eye(3) if registered else Rotation.from_rotvec(REG_ROTVEC).as_matrix()
    km = KinematicModel(robot)
    R_meas = Rotation.from_rotvec(m.rotation).as_matrix()
    # loaded rows: the arm's joints are deflected; the orientation is the FK at those joints
    R_expect = R_reg @ km.tcp(vr.equilibrium(m.q, m.wrench))[:, :3, :3]
    np.testing.assert_allclose(R_meas, R_expect, rtol=0, atol=1e-12)
    # unloaded rows: no deflection, the FK of the commands
    un = ~np.any(m.wrench, axis=1)
    assert un.sum() == 20
    np.testing.assert_allclose(R_meas[un], R_reg @ km.tcp(m.q[un])[:, :3, :3], rtol=0, atol=1e-12)
    # the loads did turn the frame (by the stiffness), by far more than the tolerance
    assert _angle_between(R_meas[~un], R_reg @ km.tcp(m.q[~un])[:, :3, :3]).max() > 1e-5
    # rotation vectors: angle in [0, pi], equal to the expected ones away from pi
    ang = np.linalg.norm(m.rotation, axis=1)
    assert ang.max() <= math.pi + 1e-12
    rv = Rotation.from_matrix(R_expect).as_rotvec()
    far = np.linalg.norm(rv, axis=1) < math.pi - 1e-3
    np.testing.assert_allclose(m.rotation[far], rv[far], rtol=0, atol=1e-12)


def test_orientation_noise_has_the_declared_std_and_leaves_positions_alone() -> None:
    sigma = 1e-3
    cfg = {
        "campaign": {"poses": 700, "unloaded_rows": 3, "loaded_rows": 0, "orientation": True},
        "noise": {"sigma_m": 2e-5, "sigma_rad": sigma},
    }
    vr = VirtualRobot(load_robot("ur10"), cfg)
    m = vr.campaign()
    assert m.n == 2100
    R_true = vr.measure_orientation(m.q, m.wrench)
    # noise in the measured frame: R_noisy = R_true exp([w]x)
    w = rotvecs(np.swapaxes(R_true, 1, 2) @ Rotation.from_rotvec(m.rotation).as_matrix())
    std = w.std(axis=0)
    assert np.all(np.abs(std / sigma - 1.0) < 0.1), std
    assert np.all(np.abs(w.mean(axis=0)) < 5 * sigma / math.sqrt(m.n))
    corr = np.corrcoef(w.T)
    assert np.abs(corr - np.eye(3)).max() < 0.1
    # the documented form (right-multiplied, in the measured frame), checked with the draws replayed
    R = R_true[:50]
    w50 = np.random.default_rng(9).normal(0.0, sigma, (50, 3))
    np.testing.assert_allclose(
        VirtualRobot.campaign_rotation_noise(R, sigma, np.random.default_rng(9)),
        R @ Rotation.from_rotvec(w50).as_matrix(),
        rtol=0,
        atol=1e-15,
    )
    # the orientation noise is drawn last: positions, times, loads are those of a 3-D campaign
    m3 = VirtualRobot(load_robot("ur10"), {**cfg, "campaign": {**cfg["campaign"], "orientation": False}}).campaign()
    assert m3.rotation is None
    for k in ("q", "wrench", "p", "t"):
        assert np.array_equal(getattr(m, k), getattr(m3, k)), k


def test_a_joint_6_offset_turns_the_frame_about_the_flange_axis_by_that_angle() -> None:
    robot = _robot("standard_dh")
    delta = 2e-3
    q = _q(30)
    F = np.zeros((len(q), 6))
    for registered in (True, False):
        reg = {"registered": registered}
        R0 = VirtualRobot(robot, {"registration": reg}).measure_orientation(q, F)
        vr1 = VirtualRobot(
            robot, {"registration": reg, "effects": {"joint_offset": {"dtheta_rad": [0, 0, 0, 0, 0, delta]}}}
        )
        R1 = vr1.measure_orientation(q, F)
        R_reg = np.eye(3) if registered else Rotation.from_rotvec(REG_ROTVEC).as_matrix()
        z_flange = (R_reg.T @ R0 @ TOOL[:3, :3].T)[:, :, 2]  # joint-6 axis (alpha6 = 0), base frame
        np.testing.assert_allclose(rotvecs(R1 @ np.swapaxes(R0, 1, 2)), delta * z_flange @ R_reg.T, rtol=0, atol=1e-13)
        # in the measured frame: about the flange z axis seen from the tool
        np.testing.assert_allclose(
            rotvecs(np.swapaxes(R0, 1, 2) @ R1),
            np.broadcast_to(delta * TOOL[:3, :3].T[:, 2], (len(q), 3)),
            rtol=0,
            atol=1e-13,
        )
    # a periodic joint-6 error turns it by the error of each row
    terms = {"joint": 6, "amplitude_rad": 1e-3, "harmonic": 3.5, "phase_rad": 0.2}
    vr_e = VirtualRobot(robot, {"registration": {"registered": True}, "effects": {"joint_error_map": terms}})
    R0 = VirtualRobot(robot, {"registration": {"registered": True}}).measure_orientation(q, F)
    e6 = 1e-3 * np.sin(3.5 * q[:, 5] + 0.2)
    z_flange = (R0 @ TOOL[:3, :3].T)[:, :, 2]
    np.testing.assert_allclose(
        rotvecs(vr_e.measure_orientation(q, F) @ np.swapaxes(R0, 1, 2)), e6[:, None] * z_flange, rtol=0, atol=1e-13
    )


def test_a_moment_turns_the_frame_by_the_joint_compliance() -> None:
    """A pure moment deflects the joints; the frame turns by ``J_w K^-1 J_w^T m`` (first order)."""
    robot = load_robot("ur10")
    q = _q(20)
    km = KinematicModel(robot)
    z_flange = km.tcp(q)[:, :3, 2]
    m_vec = 50.0 * z_flange  # 50 N*m about the flange axis
    F = np.hstack([np.zeros_like(m_vec), m_vec])
    vr = VirtualRobot(robot, {"registration": {"registered": True}})
    turn = rotvecs(vr.measure_orientation(q, F) @ np.swapaxes(vr.measure_orientation(q, 0 * F), 1, 2))
    expect = km.D(q, F)[:, 3:]
    np.testing.assert_allclose(turn, expect, rtol=0, atol=1e-3 * np.abs(expect).max())
    assert np.all(np.sum(turn * m_vec, axis=1) > 0)  # it yields in the direction of the moment


def test_link_compliance_turns_the_frame_as_it_moves_the_points() -> None:
    """The beams move every distal point by ``delta + phi x (x - tip)``: the frame turns by
    the summed ``phi``, the same rotation that separates two points' displacements."""
    robot = load_robot("ur10").with_tool(TOOL)
    cfg = {"registration": {"registered": True}}
    vr = VirtualRobot(robot, {**cfg, "effects": {"link_compliance": {"EI_Nm2": 1e5, "GJ_Nm2": 8e4}}})
    rigid = VirtualRobot(robot, cfg)
    q = _q(25)
    F = _rng().normal(0.0, 100.0, (len(q), 6))
    phi = rotvecs(vr.orientations(q, F) @ np.swapaxes(rigid.orientations(q, F), 1, 2))
    assert np.abs(phi).max() > 1e-5
    a, b = np.array([0.0, 0.0, 0.0]), np.array([0.1, -0.05, 0.2])
    pa, _ = vr.positions(q, F, point=a)
    pb, _ = vr.positions(q, F, point=b)
    ra, _ = rigid.positions(q, F, point=a)
    rb, _ = rigid.positions(q, F, point=b)
    np.testing.assert_allclose((pa - ra) - (pb - rb), np.cross(phi, ra - rb), rtol=0, atol=1e-13)


def test_orientation_columns_round_trip_through_csv() -> None:
    vr = VirtualRobot(load_robot("ur5"), {"campaign": {"poses": 5, "orientation": True}})
    m = vr.campaign()
    back = parse_measurements(measurements_to_csv(m), "sim.csv")
    np.testing.assert_array_equal(back.rotation, m.rotation)


BAD_ORIENTATION = [
    ({"campaign": {"orientation": "yes"}}, ["[campaign]", "'orientation'", "yes"]),
    ({"campaign": {"orientation": True}, "noise": {"sigma_rad": -1e-4}}, ["[noise]", "'sigma_rad'", "-0.0001"]),
    ({"noise": {"sigma_rot_column": True}}, ["'sigma_rot_column'", "orientation = true"]),
    ({"campaign": {"orientation": True}, "noise": {"sigma_rad": 0.0, "sigma_rot_column": True}}, ["'sigma_rad'", "0"]),
    ({"noise": {"sigma_deg": 1.0}}, ["unknown key", "sigma_deg"]),
]


@pytest.mark.parametrize("cfg, words", BAD_ORIENTATION)
def test_orientation_config_errors_name_the_key_and_value(cfg: dict, words: list[str]) -> None:
    vr = VirtualRobot(load_robot("ur5"), {**cfg, "campaign": {"poses": 3, **cfg.get("campaign", {})}}, where="s.toml")
    with pytest.raises(SimConfigError) as exc:
        vr.campaign()
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))


def test_sigma_rot_column_fills_the_orientation_sigma() -> None:
    cfg = {"campaign": {"poses": 4, "orientation": True}, "noise": {"sigma_rad": 3e-5, "sigma_rot_column": True}}
    m = VirtualRobot(load_robot("ur5"), cfg).campaign()
    np.testing.assert_array_equal(m.sigma_rot, np.full((m.n, 3), 3e-5))
    assert m.sigma is None
    back = parse_measurements(measurements_to_csv(m), "sim.csv")
    np.testing.assert_array_equal(back.sigma_rot, m.sigma_rot)


def test_example_config_with_joint_errors_and_orientation_runs() -> None:
    cfg = load_config(Path(__file__).resolve().parents[1] / "problems/files/sim/ur5_joint_errors_6d.toml")
    cfg["campaign"]["poses"] = 5
    vr = VirtualRobot(load_robot("ur5"), cfg)
    m = vr.campaign()
    assert m.rotation is not None and m.rotation.shape == (m.n, 3)
    assert len(vr.joint_error_terms()) >= 2
