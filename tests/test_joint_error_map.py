"""Per-joint angle error maps, the nonparametric diagnostics, 6-D measurements and known set-up parts.

* the map is not added where there is no periodic joint error (false attribution: 0 of
  :data:`FALSE_ATTRIBUTION_SEEDS` virtual robots with other effects);
* an identified map travels with the model (file round trip, predict) and continues beyond its range;
* "no unexplained structure" holds against an independent nonparametric fit of the residual
  (a kernel smoother on each joint angle, written here, not the product's P-splines);
* orientation data identify the measured frame and parameters position data cannot; a campaign
  with one tool orientation (an ISO 9283 cube) is refused unregistered and identified with the
  measured point declared known.

The found / held-out / compensation checks of a virtual robot with periodic errors are in
``tests/test_identify.py`` (case ``joint_error_map``).
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from models import load_robot
from models.arm_file import load_model, model_toml
from models.ik import AnalyticIK
from problems.identify import DataError, IdentifyStatus, ParameterStatus, identify, predict
from problems.measurements import Measurements
from problems.virtual import VirtualRobot

SIGMA = 2e-5  # per-axis position noise of the campaigns, m
SIGMA_RAD = 2e-5  # per-component orientation noise, rad
#: Virtual robots without a periodic joint error on which the map must not be added.
FALSE_ATTRIBUTION_SEEDS = 20
#: An independent smoother may explain at most this share of a residual called structure-free.
INDEPENDENT_SMOOTHER_MAX_SHARE = 0.05
#: Prediction of a reloaded model vs the in-memory one, m.
ROUND_TRIP_TOL_M = 1e-9

#: Effects of the no-map campaigns, cycled over the seeds (robot, effects, registered).
NO_MAP_CASES = [
    ("ur5", {}, False),
    ("ur10", {"geometric": {}}, True),
    ("ur10", {"gravity": {"payload_kg": 2.0}}, False),
    ("ur5", {"stiffness_hardening": {"knee_torque_Nm": 30.0, "stiffness_ratio": 2.0}}, False),
    ("ur5", {"joint_offset": {"dtheta_rad": [1e-3, -1.5e-3, 2e-3, -1e-3, 1.5e-3, 1e-3]}}, True),
]


def _config(effects: dict, registered: bool, poses: int = 60, **campaign) -> dict:
    return {
        "campaign": {"poses": poses, **campaign},
        "noise": {"sigma_m": SIGMA},
        "registration": {"registered": registered},
        "effects": copy.deepcopy(effects),
    }


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(FALSE_ATTRIBUTION_SEEDS))
def test_no_map_is_added_without_a_periodic_joint_error(seed: int) -> None:
    robot, effects, registered = NO_MAP_CASES[seed % len(NO_MAP_CASES)]
    vr = VirtualRobot(load_robot(robot), _config(effects, registered), seed=100 + seed)
    res = identify(load_robot(robot), vr.campaign(), registered=registered)
    assert "joint_error_map" not in res.effects_added, (
        seed,
        res.effects_added,
        [c.detail for h in res.history for c in h.candidates],
    )


# ----------------------------------------------------------------------------------
# A model with a map
# ----------------------------------------------------------------------------------

MAP_EFFECTS = {
    "joint_error_map": {"joint": [1, 4], "amplitude_rad": [5e-4, 2e-4], "harmonic": [3, 6], "phase_rad": [0.4, -0.7]}
}


@pytest.fixture(scope="module")
def map_case():
    vr = VirtualRobot(load_robot("ur5"), _config(MAP_EFFECTS, True, poses=120), seed=21)
    m = vr.campaign()
    res = identify(load_robot("ur5"), m, registered=True)
    return vr, m, res


def test_map_is_found_with_its_harmonics(map_case) -> None:
    _vr, _m, res = map_case
    assert res.effects_added == ["joint_error_map"], res.effects_added
    found = {(e.joint, e.component): e for e in res.error_maps}
    assert set(found) == {(1, "theta"), (4, "theta")}
    for (j, _c), f, amp in (((1, "theta"), 3.0, 5e-4), ((4, "theta"), 6.0, 2e-4)):
        h = found[(j, "theta")].harmonics[0]
        assert h.freq_cpr == pytest.approx(f, abs=0.02)
        assert h.amplitude == pytest.approx(amp, rel=0.05)
        assert h.amplitude_std < 0.1 * amp
        assert h.amplitude_tcp_m > 0
    e1 = found[(1, "theta")]
    assert len(e1.q_rad) == len(e1.value) == len(e1.band) and np.all(e1.band > 0)


def test_map_model_file_round_trip_predicts_the_same(map_case, tmp_path) -> None:
    _vr, m, res = map_case
    path = tmp_path / "model.toml"
    path.write_text(model_toml(res.model))
    loaded = load_model(path)
    assert "joint_error_map" in loaded.effects
    assert np.abs(predict(loaded, m) - predict(res.model, m)).max() < ROUND_TRIP_TOL_M
    # the map is part of the prediction: without it the prediction changes by its size
    bare = copy.deepcopy(res.model)
    bare.effect_const = {}
    assert np.abs(predict(bare, m) - predict(res.model, m)).max() > 10 * SIGMA


def test_planning_model_applies_the_map(map_case) -> None:
    """The planning functions (commanded angle = the FK input) carry the map: the TCP differs from
    the same model without it by the map's angle error times the lever."""
    _vr, m, res = map_case
    bare = copy.deepcopy(res.model)
    bare.effect_const = {}
    q = m.q[:5]
    p_map = np.array([np.asarray(res.model.kinematics.fk_position(qi)).reshape(3) for qi in q])
    p_bare = np.array([np.asarray(bare.kinematics.fk_position(qi)).reshape(3) for qi in q])
    assert np.linalg.norm(p_map - p_bare, axis=1).max() > 10 * SIGMA


def test_map_continues_beyond_its_angle_range(map_case) -> None:
    """A map is a function of its joint's angle everywhere: beyond the covered range the planning model's TCP
    moves by the map's own series at that angle (written out here from its constants and coefficients), not
    by its value at the end of the range; and no caveat says otherwise."""
    from models.effects import GROUP_SLICES
    from models.effects.joint_error_map import COEF_SHAPE, FREQ_SHAPE

    _vr, m, res = map_case
    model = res.model
    bare = dataclasses.replace(model, effect_const={})  # a new object: no kinematics cached with the maps
    emap = res.error_maps[0]
    j = emap.joint - 1
    lo, hi = emap.range_rad
    f = np.asarray(model.effect_const["error_map.freq"]).reshape(FREQ_SHAPE)[:, 0]  # theta maps, every joint
    c = np.asarray(model.theta[GROUP_SLICES["error_map.c"]]).reshape(COEF_SHAPE)[:, 0]
    assert not np.any(np.asarray(model.effect_const["error_map.freq"]).reshape(FREQ_SHAPE)[:, 1:])
    q = np.tile(m.q[0], (2, 1))
    q[:, j] = [hi + 0.6, hi]

    def series(i: int, x: float) -> float:
        return float(np.sum(c[i, :, 0] * np.cos(f[i] * x) + c[i, :, 1] * np.sin(f[i] * x)))

    # the maps' effect at the TCP, by the joint offsets they add: the same as a bare model with those offsets
    for qi in q:
        p_map = np.asarray(model.kinematics.fk_position(qi)).reshape(3)
        shifted = qi + np.array([series(i, qi[i]) for i in range(6)])
        p_ref = np.asarray(bare.kinematics.fk_position(shifted)).reshape(3)
        assert np.abs(p_map - p_ref).max() < 1e-3 * SIGMA
    assert abs(series(j, hi + 0.6) - series(j, hi)) > 1e-6  # continued, not held at the end value
    assert not [x for x in model.caveats(q, np.zeros(6)) if "error map" in x]


def _kernel_cv_share(x: np.ndarray, y: np.ndarray, bandwidths: tuple[float, ...] = (0.02, 0.05, 0.1, 0.2)) -> float:
    """Leave-one-out explained share of ``y`` (n, 3) by a Gaussian kernel (Nadaraya-Watson)
    smoother on ``x`` (n,): the best over a few bandwidths (rad)."""
    yc = y - y.mean(axis=0)
    tot = float(np.sum(yc**2))
    best = -np.inf
    d = x[:, None] - x[None, :]
    for h in bandwidths:
        K = np.exp(-0.5 * (d / h) ** 2)
        np.fill_diagonal(K, 0.0)
        w = K.sum(axis=1, keepdims=True)
        ok = w[:, 0] > 1e-9
        fit = (K @ yc)[ok] / w[ok]
        best = max(best, 1.0 - float(np.sum((yc[ok] - fit) ** 2)) / float(np.sum(yc[ok] ** 2)))
    return best if tot > 0 else 0.0


def test_no_structure_claim_holds_against_an_independent_smoother(map_case) -> None:
    _vr, m, res = map_case
    assert not res.unexplained["present"], res.unexplained
    r = res.residual_after[res.inliers]
    q = m.q[res.inliers]
    shares = [_kernel_cv_share(q[:, j], r) for j in range(6)]
    assert max(shares) < INDEPENDENT_SMOOTHER_MAX_SHARE, shares


@pytest.mark.slow
def test_structure_the_fourier_order_3_diagnostic_missed_is_reported() -> None:
    """A smooth, non-periodic error of the TCP along x that depends on joint 1 alone (not a joint
    error motion: no map describes it): the per-axis smoother sees it."""
    vr = VirtualRobot(load_robot("ur10"), _config({}, True, poses=150), seed=8)
    m = vr.campaign()
    m.p = m.p + 6e-5 * np.tanh(4.0 * m.q[:, [0]]) * np.array([[1.0, 0.0, 0.0]])
    res = identify(load_robot("ur10"), m, registered=True)
    assert res.unexplained["present"], res.unexplained
    assert res.unexplained["variable"].startswith("q1"), res.unexplained
    assert _kernel_cv_share(m.q[res.inliers, 0], res.residual_after[res.inliers]) > INDEPENDENT_SMOOTHER_MAX_SHARE


# ----------------------------------------------------------------------------------
# 6-D data and known parts of the set-up
# ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_orientation_data_identify_more_parameters() -> None:
    cfg = _config({"geometric": {}}, True, poses=80, orientation=True)
    cfg["noise"].update({"sigma_rad": SIGMA_RAD, "sigma_rot_column": True, "sigma_column": True})
    vr = VirtualRobot(load_robot("ur10"), cfg, seed=4)
    m = vr.campaign()
    assert m.rotation is not None and m.sigma_rot is not None
    res6 = identify(load_robot("ur10"), m, registered=True)
    m3 = Measurements(q=m.q, wrench=m.wrench, p=m.p, t=m.t, point=m.point, sigma=m.sigma)
    res3 = identify(load_robot("ur10"), m3, registered=True)
    assert res6.orientation is not None and res3.orientation is None
    assert res6.orientation["rms_after_rad"] < 1.5 * SIGMA_RAD
    gained = set(res6.orientation["identifiable_thanks_to_orientation"])
    held3 = {h["name"] for h in res3.identifiability["held"]}
    held6 = {h["name"] for h in res6.identifiability["held"]}
    assert gained and gained <= held3 - held6, (gained, held3, held6)
    assert "dtheta[6]" in gained


def _cube_campaign(vr: VirtualRobot, n_side: int = 4) -> Measurements:
    """An ISO 9283-like cube: TCP positions on a grid, one tool orientation (pointing down)."""
    R = np.diag([1.0, -1.0, -1.0])
    g = np.linspace(-0.15, 0.15, n_side)
    T = np.tile(np.eye(4), (n_side**3, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = np.array([[0.45 + x, 0.1 + y, 0.35 + z] for x in g for y in g for z in g])
    sol = AnalyticIK(vr.robot).solve(T)
    branch = int(np.argmax(sol.valid.sum(axis=0)))
    ok = sol.valid[:, branch]
    q = sol.q[ok, branch]
    F = np.zeros((len(q), 6))
    rng = np.random.default_rng(3)
    p = vr.measure(q, F) + rng.normal(0, SIGMA, (len(q), 3))
    return Measurements(q=q, wrench=F, p=p)


def test_single_tool_orientation_needs_the_measured_point_declared() -> None:
    vr = VirtualRobot(load_robot("ur5"), _config({}, False), seed=6)
    m = _cube_campaign(vr)
    assert m.n >= 40
    with pytest.raises(DataError, match="measured"):
        identify(load_robot("ur5"), m)
    res = identify(load_robot("ur5"), m, known=["measured_point"], candidates=[])
    assert res.identifiability["known"] == "measured point"
    assert res.status in (IdentifyStatus.OK, IdentifyStatus.UNEXPLAINED)
    held = {p.name for p in res.parameters if p.status is ParameterStatus.HELD}
    assert {"measured_point.x", "measured_point.y", "measured_point.z"} <= held
    free = {p.name for p in res.parameters if p.status is ParameterStatus.FREE}
    assert {"registration.t.x", "registration.t.y", "registration.t.z"} <= free


def test_unknown_known_part_is_refused() -> None:
    vr = VirtualRobot(load_robot("ur5"), _config({}, False), seed=6)
    with pytest.raises(Exception, match="known part"):
        identify(load_robot("ur5"), vr.campaign(), known=["tool"])


def test_map_components_are_checked_and_runout_is_searched_on_request() -> None:
    vr = VirtualRobot(load_robot("ur5"), _config(MAP_EFFECTS, True, poses=60), seed=21)
    m = vr.campaign()
    with pytest.raises(Exception, match="map component"):
        identify(load_robot("ur5"), m, registered=True, map_components=["wobble"])
    res = identify(
        load_robot("ur5"), m, registered=True, map_components=["theta", "d", "a"], candidates=["joint_error_map"]
    )
    assert res.effects_added == ["joint_error_map"]
    assert {(e.joint, e.component) for e in res.error_maps} >= {(1, "theta")}


def test_per_axis_sigmas_weight_each_residual_component() -> None:
    """Position rows weigh each axis by 1/sigma_x, 1/sigma_y, 1/sigma_z; orientation rows by
    1/sigma_rx.. (rad); without orientation sigmas, by the balancing weight given."""
    from problems.identify.evaluation import row_weights, with_orientation_rows

    n = 4
    q = np.zeros((n, 6))
    sx = np.tile([1e-5, 2e-5, 4e-5], (n, 1))
    sr = np.tile([1e-5, 1e-5, 5e-5], (n, 1))
    m = Measurements(
        q=q, wrench=np.zeros((n, 6)), p=np.zeros((n, 3)), rotation=np.zeros((n, 3)), sigma_xyz=sx, sigma_rot=sr
    )
    mx, is_pos = with_orientation_rows(m)
    w = row_weights(mx, is_pos)
    assert w.shape == (2 * n, 3) and is_pos.sum() == n
    np.testing.assert_array_equal(w[is_pos], 1.0 / sx)
    np.testing.assert_array_equal(w[~is_pos], 1.0 / sr)
    m2 = Measurements(q=q, wrench=np.zeros((n, 6)), p=np.zeros((n, 3)), rotation=np.zeros((n, 3)), sigma_xyz=sx)
    mx2, is_pos2 = with_orientation_rows(m2)
    w2 = row_weights(mx2, is_pos2, rot_weight=0.7)
    np.testing.assert_array_equal(w2[~is_pos2], np.full((n, 3), 0.7))
