"""Several measurement campaigns in one fit (issue 26, "Fit several campaigns").

Two campaigns of the same virtual robot in different joint regions; the second measured by a
re-positioned tracker (its points moved by a known rigid transform).  The truth is known, so the
identified transforms, the shared robot and the covariance are checked against it or against an
independent computation.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from models import effects as fx
from models import load_robot
from models.arm_file import load_model, model_toml
from models.errors import InputError
from models.transforms import matrix_to_rotvec, rotvec_to_matrix
from planner.cli import main as cli_main
from problems.identify import DataError, identify, identify_campaigns, merge_campaigns, predict
from problems.identify.campaign_joint import JointFit, joint_covariance
from problems.identify.uncertainty import beyond_range, parameter_jacobian, predicted_sigma
from problems.measurements import Measurements, measurements_to_csv
from problems.virtual import VirtualRobot

#: The virtual robot: geometric errors, 20 um noise.
CFG = {
    "seed": 3,
    "campaign": {"poses": 60, "loaded_rows": 0, "unloaded_rows": 1},
    "noise": {"sigma_m": 2e-5},
    "effects": {"geometric": {}},
}
NOISE_M = 2e-5
POSES = 60
#: Joint boxes (rad) of the two campaigns: joints 2 and 3 restricted, the others free.
BOX_A = ((-2.0, 0.8), (-1.2, 1.6))
BOX_B = ((-1.0, -1.6), (-0.2, -0.8))
#: The re-positioned tracker: campaign A's measurement frame -> campaign B's.
MOVE_ROTVEC = np.array([0.05, -0.2, 0.4])
MOVE_T_M = np.array([0.3, -0.5, 0.1])
#: The identified A -> B transform moves A's points to within this RMS of the truth, m.
TRANSFORM_TOL_M = 2e-5
#: Chi-square quantile the transform's error (6 components, in its own covariance) stays under.
TRANSFORM_CHI2_Q = 0.999
#: The robot parameters of the per-campaign fit differ from the one-frame fit's (same data, the
#: tracker not moved) by at most this many of their standard deviations.
SAME_ROBOT_MAX_Z = 3.0
#: The joint model predicts campaign B's region at most this fraction of campaign A alone's error.
JOINT_GAIN = 0.5
#: Relative agreement of two computations of the same covariance.
COV_REL_TOL = 1e-3
#: The sigma in a campaign's frame against the one of the independent joint covariance (relative).
SIGMA_REL_TOL = 1e-3
#: Finite-difference agreement of the joint Jacobian (relative to the column's norm).
FD_REL_TOL = 1e-4
FD_STEP = 1e-6


def _box(rng: np.random.Generator, n: int, box: tuple) -> np.ndarray:
    lo, hi = -np.pi * np.ones(6), np.pi * np.ones(6)
    (lo[1], lo[2]), (hi[1], hi[2]) = box
    return rng.uniform(lo, hi, (n, 6))


def _move() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotvec_to_matrix(MOVE_ROTVEC)
    T[:3, 3] = MOVE_T_M
    return T


def _campaign(vr, rng, q, source, T=None, noise=NOISE_M, t0=0.0) -> Measurements:
    n = len(q)
    F = np.zeros((n, 6))
    t = t0 + 10.0 * np.arange(n)
    p = vr.measure(q, F, t, None) + rng.normal(0.0, noise, (n, 3))
    if T is not None:
        p = p @ T[:3, :3].T + T[:3, 3]
    return Measurements(q=q, wrench=F, p=p, t=t, point=np.array([f"P{i}" for i in range(n)]), source=source)


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("ur5")
    vr = VirtualRobot(robot, CFG, seed=3)
    rng = np.random.default_rng(5)
    T = _move()
    a = _campaign(vr, rng, _box(rng, POSES, BOX_A), "A.csv")
    qb = _box(rng, POSES, BOX_B)
    b_same = _campaign(vr, rng, qb, "B.csv", t0=5000.0)  # the tracker not moved
    b = Measurements(q=b_same.q, wrench=b_same.wrench, p=b_same.p @ T[:3, :3].T + T[:3, 3], t=b_same.t,
                     point=b_same.point, source="B.csv")  # fmt: skip
    qh = _box(rng, POSES, BOX_B)  # held out, campaign B's region, noise-free
    held_a = _campaign(vr, rng, qh, "held", noise=0.0)
    held_b = _campaign(vr, rng, qh, "held", T=T, noise=0.0)
    res = identify_campaigns(robot, [a, b])
    return {"robot": robot, "vr": vr, "a": a, "b": b, "b_same": b_same, "T": T, "res": res, "held_a": held_a,
            "held_b": held_b}  # fmt: skip


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _frames(res) -> dict:
    return {c.name: c for c in res.model.campaigns}


def test_campaign_registrations_match_the_moved_tracker(setup) -> None:
    res, a, T = setup["res"], setup["a"], setup["T"]
    fr = _frames(res)
    assert list(fr) == ["A", "B"]
    assert np.allclose(res.model.base2meas(), fr["B"].base2meas, atol=1e-12)  # equally large: the last given
    a2b = fr["B"].base2meas @ np.linalg.inv(fr["A"].base2meas)
    err = a.p @ (a2b[:3, :3] - T[:3, :3]).T + (a2b[:3, 3] - T[:3, 3])
    assert _rms(err) < TRANSFORM_TOL_M
    assert fr["A"].n_rows == fr["B"].n_rows == POSES
    assert res.identifiability["campaign_fit"]["converged"]
    assert any("fitted jointly" in n for n in res.notes)


def test_transform_error_is_within_its_covariance(setup) -> None:
    """A one-shot statistical check: the error of the identified A -> B transform (reference-frame
    motion ``dt``, ``dphi``) against the truth, in the joint covariance, is chi-square with 6 dof."""
    res, a, b, T = setup["res"], setup["a"], setup["b"], setup["T"]
    fr = _frames(res)
    A = [fr["B"].base2meas @ np.linalg.inv(fr["A"].base2meas), np.eye(4)]
    merged, campaign = merge_campaigns([a, b], ["A", "B"], A)
    joint = JointFit(res.model, list(res.model.covariance_names), [a, b], campaign, merged, res.inliers)
    cov, _s2, _dof = joint_covariance(joint, res.model.theta, A)
    k = len(res.model.covariance_names)
    D = A[0] @ np.linalg.inv(T)  # the identified transform = exp(dphi) truth + dt
    e = np.concatenate([D[:3, 3], matrix_to_rotvec(D[:3, :3])])
    chi2 = float(e @ np.linalg.solve(cov[k : k + 6, k : k + 6], e))
    assert chi2 < stats.chi2.ppf(TRANSFORM_CHI2_Q, 6)


def test_robot_matches_a_fit_in_one_frame(setup) -> None:
    robot, a, b_same, held_a = setup["robot"], setup["a"], setup["b_same"], setup["held_a"]
    one = identify_campaigns(robot, [a, b_same], shared=("registration",))
    per = setup["res"].model
    assert one.model.effects == per.effects
    reg = set(fx.PARAM_NAMES[fx.GROUP_SLICES["reg.t"]]) | set(fx.PARAM_NAMES[fx.GROUP_SLICES["reg.w"]])
    std = np.sqrt(np.diag(per.covariance))
    z = [
        (per.theta[fx.PARAM_NAMES.index(n)] - one.model.theta[fx.PARAM_NAMES.index(n)]) / std[i]
        for i, n in enumerate(per.covariance_names)
        if n not in reg
    ]
    assert len(z) > 10 and np.max(np.abs(z)) < SAME_ROBOT_MAX_Z
    assert _rms(predict(one.model, held_a) - held_a.p) < 2 * NOISE_M  # the one-frame fit is a good one


def test_joint_model_beats_campaign_a_alone_in_b_region(setup) -> None:
    robot, a, res = setup["robot"], setup["a"], setup["res"]
    alone = identify(robot, a)
    err_alone = _rms(predict(alone.model, setup["held_a"]) - setup["held_a"].p)
    err_joint = _rms(predict(res.model.for_campaign("B"), setup["held_b"]) - setup["held_b"].p)
    assert err_joint < JOINT_GAIN * err_alone


def test_covariance_equals_an_independent_block_computation(setup) -> None:
    """The joint covariance in each campaign's own registration parameters, computed independently:
    one Jacobian over the shared robot parameters and 6 registration columns per campaign, each
    campaign's block from ``parameter_jacobian`` of ``model.for_campaign(name)`` (the parametrisation
    a campaign's registration_cov is in), residuals in each campaign's own frame."""
    res, a, b = setup["res"], setup["a"], setup["b"]
    model = res.model
    reg = list(fx.PARAM_NAMES[fx.GROUP_SLICES["reg.t"]]) + list(fx.PARAM_NAMES[fx.GROUP_SLICES["reg.w"]])
    rob = [n for n in model.covariance_names if n not in reg]
    k = len(rob)
    blocks, rs = [], []
    for c, (name, m) in enumerate((("A", a), ("B", b))):
        mc = model.for_campaign(name)
        _p, J = parameter_jacobian(mc, m.q, m.wrench, rob + reg)
        Jf = np.zeros((m.n, 3, k + 12))
        Jf[:, :, :k] = J[:, :, :k]
        Jf[:, :, k + 6 * c : k + 6 * c + 6] = J[:, :, k:]
        blocks.append(Jf.reshape(-1, k + 12))
        rs.append((predict(mc, m) - m.p).reshape(-1))
    J, r = np.vstack(blocks), np.concatenate(rs)
    cov = np.linalg.inv(J.T @ J) * float(r @ r) / (r.size - J.shape[1])
    fr = _frames(res)
    rob_cols = [model.covariance_names.index(n) for n in rob]
    for c, name in enumerate(("A", "B")):
        blk = cov[k + 6 * c : k + 6 * c + 6, k + 6 * c : k + 6 * c + 6]
        assert np.abs(fr[name].registration_cov - blk).max() < COV_REL_TOL * np.abs(blk).max()
        # and its cross-covariance with the robot's parameters
        cross = cov[k + 6 * c : k + 6 * c + 6, :k]
        mine_x = fr[name].registration_cross_cov[:, rob_cols]
        assert np.abs(mine_x - cross).max() < COV_REL_TOL * np.sqrt(np.abs(blk).max() * np.abs(cov[:k, :k]).max())
        # the sigma in the campaign's frame is the joint covariance's: J_c C J_c^T with the cross terms
        held = setup["held_a"] if name == "A" else setup["held_b"]
        mc = model.for_campaign(name)
        _p, Jh = parameter_jacobian(mc, held.q, held.wrench, rob + reg)
        sub = np.r_[0:k, k + 6 * c : k + 6 * c + 6]
        P = np.einsum("nik,kl,nil->ni", Jh, cov[np.ix_(sub, sub)], Jh)  # rows: robot, then this campaign's 6
        mine_s = predicted_sigma(mc, held.q, held.wrench, include_residual=False).sigma_m / mc.sigma_scale
        inside = ~beyond_range(mc, held.q).any(axis=1)
        assert inside.any()
        assert np.allclose(mine_s[inside], np.sqrt(P[inside]), rtol=SIGMA_REL_TOL)
    idx = [model.covariance_names.index(n) for n in rob]
    mine = model.covariance[np.ix_(idx, idx)]
    assert np.abs(mine - cov[:k, :k]).max() < COV_REL_TOL * np.abs(cov[:k, :k]).max()
    # the correction matters: treating A's transform as known understates the robot's variance
    engine = identify(setup["robot"], res.data)
    n_idx = [engine.model.covariance_names.index(n) for n in rob]
    ratio = np.diag(cov[:k, :k]) / np.diag(engine.model.covariance[np.ix_(n_idx, n_idx)])
    assert ratio.min() > 1 - COV_REL_TOL and ratio.max() > 1.1


def test_joint_jacobian_by_finite_differences(setup) -> None:
    res, a, b = setup["res"], setup["a"], setup["b"]
    fr = _frames(res)
    A = [fr["B"].base2meas @ np.linalg.inv(fr["A"].base2meas), np.eye(4)]
    merged, campaign = merge_campaigns([a, b], ["A", "B"], A)
    joint = JointFit(res.model, list(res.model.covariance_names), [a, b], campaign, merged, res.inliers)
    theta = res.model.theta
    _r, J = joint.jacobian(theta, A)
    k = len(joint.idx)
    from problems.identify.campaign_joint import perturbed

    def res_vec(th, AA):
        return (joint.residual(th, AA) * joint.w)[joint.mask].reshape(-1)

    for col in list(range(0, k, max(k // 6, 1))) + list(range(k, k + 6)):
        e = np.zeros(6)
        if col < k:
            hi, lo = theta.copy(), theta.copy()
            hi[joint.idx[col]] += FD_STEP
            lo[joint.idx[col]] -= FD_STEP
            fd = (res_vec(hi, A) - res_vec(lo, A)) / (2 * FD_STEP)
        else:
            e[col - k] = FD_STEP
            up = [perturbed(A[0], e[:3], e[3:]), A[1]]
            dn = [perturbed(A[0], -e[:3], -e[3:]), A[1]]
            fd = (res_vec(theta, up) - res_vec(theta, dn)) / (2 * FD_STEP)
        assert np.linalg.norm(fd - J[:, col]) < FD_REL_TOL * np.linalg.norm(J[:, col]), col


def test_model_file_keeps_the_campaigns(setup, tmp_path) -> None:
    model = setup["res"].model
    path = tmp_path / "m.toml"
    path.write_text(model_toml(model))
    back = load_model(path)
    assert back.campaign_names() == ["A", "B"]
    for c0, c1 in zip(model.campaigns, back.campaigns):
        assert c0.n_rows == c1.n_rows and c0.data == c1.data
        assert np.allclose(c0.base2meas, c1.base2meas, atol=1e-12)
        assert np.allclose(c0.registration_cov, c1.registration_cov, rtol=1e-9, atol=0)
    held = setup["held_a"]
    assert np.allclose(predict(back.for_campaign("A"), held), predict(model.for_campaign("A"), held), atol=1e-10)


def test_shared_registration_is_the_concatenation(setup) -> None:
    robot, a, b = setup["robot"], setup["a"], setup["b_same"]
    res = identify_campaigns(robot, [a, b], shared=("registration",))
    cat = Measurements(
        q=np.vstack([a.q, b.q]),
        wrench=np.vstack([a.wrench, b.wrench]),
        p=np.vstack([a.p, b.p]),
        t=np.concatenate([a.t - a.t[0], b.t - b.t[0]]),
        point=np.array([f"a{i}" for i in range(a.n)] + [f"b{i}" for i in range(b.n)]),
        source="cat",
    )
    ref = identify(robot, cat)
    assert res.model.effects == ref.model.effects
    assert np.allclose(res.model.theta, ref.model.theta, rtol=0, atol=1e-10)
    assert [c.name for c in res.model.campaigns] == ["A", "B"]
    assert all(np.allclose(c.base2meas, res.model.base2meas()) for c in res.model.campaigns)


def test_one_campaign_is_identify(setup) -> None:
    robot, a = setup["robot"], setup["a"]
    res = identify_campaigns(robot, [a])
    ref = identify(robot, a)
    assert res.model.campaigns == []
    assert np.allclose(res.model.theta, ref.model.theta, rtol=0, atol=0)


def test_campaign_with_too_few_poses_is_refused(setup) -> None:
    robot, a, b = setup["robot"], setup["a"], setup["b"]
    few = b.subset(np.array([0, 0, 1, 1]))
    with pytest.raises(DataError, match=r"B\.csv.*2 distinct pose.*--shared registration"):
        identify_campaigns(robot, [a, few])
    with pytest.raises(InputError, match="shared part"):
        identify_campaigns(robot, [a, b], shared=("tool",))


def test_merge_keeps_poses_times_and_frames_apart(setup) -> None:
    a, b = setup["a"], setup["b_same"]
    twin = b.subset(np.arange(b.n))
    twin.q = a.q.copy()  # the same joints as campaign A, another campaign
    T = setup["T"]
    merged, campaign = merge_campaigns([a, twin], ["A", "B"], [T, np.eye(4)])
    assert len(np.unique(merged.pose_groups())) == 2 * POSES
    assert merged.t[campaign == 0][0] == 0.0 and merged.t[campaign == 1][0] == 0.0 and b.t[0] > 0.0
    assert np.allclose(merged.p[campaign == 0], a.p @ T[:3, :3].T + T[:3, 3])
    assert np.array_equal(merged.p[campaign == 1], twin.p)


def test_orientation_with_own_registrations_is_refused(setup) -> None:
    a, b = setup["a"], setup["b"]
    rot = b.subset(np.arange(b.n))
    rot.rotation = np.zeros((b.n, 3))
    A = np.eye(4)
    A[:3, 3] = [0.1, 0.0, 0.0]
    with pytest.raises(InputError, match="rx, ry, rz.*--shared"):
        merge_campaigns([a, rot], ["A", "B"], [A, np.eye(4)])


def test_cli_two_data_files(setup, tmp_path, capsys) -> None:
    a, b = setup["a"], setup["b"]
    pa, pb = tmp_path / "left.csv", tmp_path / "right.csv"
    pa.write_text(measurements_to_csv(a))
    pb.write_text(measurements_to_csv(b))
    out, rep = tmp_path / "m.toml", tmp_path / "rep"
    args = ["identify", "--robot", "ur5", "--data", str(pa), "--data", str(pb), "--out", str(out)]
    assert cli_main(args + ["--report", str(rep), "--no-progress", "--candidates", "geometric"]) == 0
    text = capsys.readouterr().out
    assert "campaign left" in text and "from the reference campaign's" in text
    assert "campaign right" in text and "reference" in text
    model = load_model(out)
    assert model.campaign_names() == ["left", "right"]
    a2b = model.campaigns[1].base2meas @ np.linalg.inv(model.campaigns[0].base2meas)
    err = a.p @ (a2b[:3, :3] - setup["T"][:3, :3]).T + (a2b[:3, 3] - setup["T"][:3, 3])
    assert _rms(err) < TRANSFORM_TOL_M
    report = json.loads((rep / "report.json").read_text())
    assert [c["name"] for c in report["campaigns"]] == ["left", "right"]
    assert "- campaigns: left (60 rows" in (rep / "report.md").read_text()
    assert "reference campaign: right (the campaign with the most rows, 60 rows)" in text  # equally large: the last
