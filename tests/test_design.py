"""Campaign design (problems/identify/design.py, design_region.py) and ``compplan design``
(planner/commands/design.py): the greedy gains against brute-force inverses, the design against
random subsets, the guards, the unidentifiable parameters, the travel order, the task region and
the command line."""

from __future__ import annotations

import csv
import json

from dataclasses import replace

import numpy as np
import pytest

from models.arm_file import load_model, model_toml
from models.symbolic import KinematicModel
from problems.identify.design import DESIGN_MAX_JACOBIAN_COND, design_campaign
from problems.identify.design_greedy import greedy_gains, select_greedy
from problems.identify.design_region import TASK_MAX_EVAL_POSES, task_region
from problems.identify.design_result import DesignStatus
from problems.identify.travel import path_time, travel_order
from problems.identify.uncertainty import parameter_jacobian, predicted_sigma, to_base_frame
from problems.measurements import Measurements, measurements_to_csv, read_measurements

#: Relative tolerance of a Woodbury gain against the brute-force inverse.
GAIN_REL_TOL = 1e-7
#: Relative tolerance of the design's figures against an independent computation in raw units
#: (the ridge of a design from scratch, 1e-6 poses' worth, is below it).
INDEPENDENT_REL_TOL = 1e-4
#: Random subsets of the baseline drawn by the test itself.
TEST_RANDOM_SUBSETS = 20
#: Pool poses of the tests.
N_POOL = 300
#: Tolerance of the task path's TCP against its waypoints, m.
PATH_TOL_M = 1e-6


@pytest.fixture(scope="module")
def fitted(small_virtual_model):
    robot, vr, data, model = small_virtual_model
    qp = vr.sample_poses(N_POOL, np.random.default_rng(11))
    pool = Measurements(q=qp, wrench=np.zeros((len(qp), 6)), source="pool")
    return robot, model, data, pool


def _scaled(J: np.ndarray) -> np.ndarray:
    """Columns of a stacked Jacobian (N, 3, k) scaled to unit RMS (well-conditioned inverses)."""
    rms = np.sqrt(np.mean(J**2, axis=(0, 1)))
    return J / np.where(rms > 0, rms, 1.0)


def _info(J: np.ndarray, s2: float) -> np.ndarray:
    return np.einsum("nik,nil->kl", J, J) / s2


# ------------------------------------------------------------------------------ gains
def test_task_gain_equals_bruteforce_trace_reduction(fitted):
    _robot, model, data, pool = fitted
    s2 = model.residual_sigma_m**2
    _p, J = parameter_jacobian(model, np.vstack([data.q, pool.q]))
    J = _scaled(J)
    Je, Jc = J[: data.n], J[data.n :]
    I0 = _info(Je, s2) + 1e-9 * np.eye(J.shape[2])
    P0 = np.linalg.inv(I0)
    M = np.einsum("nik,nil->kl", Jc, Jc) / len(Jc)
    gain, _A, _S = greedy_gains(P0, Jc, s2, "task", M)
    for i in (0, 7, 123, N_POOL - 1):
        P1 = np.linalg.inv(I0 + _info(Jc[i : i + 1], s2))
        brute = np.trace(M @ P0) - np.trace(M @ P1)
        assert brute > 0
        assert gain[i] == pytest.approx(brute, rel=GAIN_REL_TOL)


def test_d_gain_equals_bruteforce_logdet_change(fitted):
    _robot, model, data, pool = fitted
    s2 = model.residual_sigma_m**2
    _p, J = parameter_jacobian(model, np.vstack([data.q, pool.q]))
    J = _scaled(J)
    Je, Jc = J[: data.n], J[data.n :]
    I0 = _info(Je, s2) + 1e-9 * np.eye(J.shape[2])
    gain, _A, _S = greedy_gains(np.linalg.inv(I0), Jc, s2, "d")
    for i in (1, 50, 222):
        brute = np.linalg.slogdet(I0 + _info(Jc[i : i + 1], s2))[1] - np.linalg.slogdet(I0)[1]
        assert gain[i] == pytest.approx(brute, rel=GAIN_REL_TOL)


def test_greedy_posterior_equals_bruteforce_inverse(fitted):
    """The Woodbury-updated posterior of the chosen rows (exchange included) is the inverse of
    the information of those rows."""
    _robot, model, data, pool = fitted
    s2 = model.residual_sigma_m**2
    _p, J = parameter_jacobian(model, np.vstack([data.q, pool.q]))
    J = _scaled(J)
    Je, Jc = J[: data.n], J[data.n :]
    I0 = _info(Je, s2) + 1e-9 * np.eye(J.shape[2])
    M = np.einsum("nik,nil->kl", Jc, Jc) / len(Jc)
    sel, P = select_greedy(np.linalg.inv(I0), Jc, 12, s2, "task", M)
    assert len(set(sel.tolist())) == 12
    brute = np.linalg.inv(I0 + _info(Jc[sel], s2))
    assert np.trace(M @ P) == pytest.approx(np.trace(M @ brute), rel=1e-6)


# ------------------------------------------------------------------------------ the design
def _independent_variance(model, data, pool, rows, s2) -> float:
    """Mean over the pool of trace(J_e P J_e^T), base frame, shared registration, raw units."""
    _p, Je = parameter_jacobian(model, data.q)
    _p, Jp = parameter_jacobian(model, pool.q)
    names = list(model.covariance_names)
    Jb = to_base_frame(model, Jp, names)
    P = np.linalg.inv(_info(Je, s2) + _info(Jp[rows], s2))
    return float(np.mean(np.einsum("nik,kl,nil->n", Jb, P, Jb)))


@pytest.mark.parametrize("criterion", ["task", "d"])
def test_design_beats_random_subsets(fitted, criterion):
    _robot, model, data, pool = fitted
    s2 = model.residual_sigma_m**2
    n = 15
    des = design_campaign(
        model,
        pool,
        n,
        earlier=[data],
        criterion=criterion,
        new_registration=False,
        eval_frame="base",
        potential_knots=0,  # the criterion itself, no potential terms
    )
    assert des.status is DesignStatus.OK and len(des.chosen) == n == len(set(des.chosen.tolist()))
    # the design's figures against an independent computation (raw units, np.linalg.inv)
    v_des = _independent_variance(model, data, pool, des.chosen, s2)
    assert des.variance_after_m2 == pytest.approx(v_des, rel=INDEPENDENT_REL_TOL)
    rng = np.random.default_rng(5)
    v_rand = [
        _independent_variance(model, data, pool, rng.choice(pool.n, n, replace=False), s2)
        for _ in range(TEST_RANDOM_SUBSETS)
    ]
    if criterion == "task":
        assert v_des < np.mean(v_rand)
        assert des.region_sigma_m(des.sigma_after_m) < des.region_sigma_m(des.sigma_random_m)
    else:
        assert des.logdet_gain_after > des.logdet_gain_random
    assert des.region_sigma_m(des.sigma_after_m) < des.region_sigma_m(des.sigma_before_m)


def test_sigma_before_is_the_models_own(fitted):
    """With the identification data as the earlier data, the prior's predicted sigma is the
    model's covariance's (the identification's covariance is the inverse of that information)."""
    _robot, model, data, pool = fitted
    des = design_campaign(model, pool, 5, earlier=[data])
    # the design's sigmas are the parameters' linearised posterior, before the calibration on held-out rows
    linear = replace(model, sigma_scale=1.0, sigma_growth_rad_per_rad=0.0)
    own = predicted_sigma(linear, pool.q, include_residual=False)
    rms = np.sqrt(np.mean(own.sigma_m**2, axis=1))
    np.testing.assert_allclose(des.sigma_before_m, rms, rtol=1e-2)
    scratch = design_campaign(model, pool, 5)  # no earlier data: the nominal model (tests/test_sigma_undetermined.py)
    assert (scratch.sigma_before_m > 10 * rms).all()


def test_guards_set_aside_singular_and_out_of_limit_rows(fitted):
    robot, model, _data, pool = fitted
    q = pool.q[:40].copy()
    q[3, 0] = robot.q_max[0] + 0.1  # beyond joint 1's limit
    q[7, 4] = 0.0  # wrist singularity of a UR arm (q5 = 0)
    cond = np.linalg.cond(np.asarray(KinematicModel(robot).fn["jacobian"](q[7])))
    assert cond > DESIGN_MAX_JACOBIAN_COND
    p = Measurements(q=q, wrench=np.zeros((40, 6)))
    des = design_campaign(model, p, 39 - 1)
    assert des.guards["outside_limits"].count == 1 and des.guards["outside_limits"].lines == [int(p.line[3])]
    assert des.guards["near_singularity"].count == 1 and des.guards["near_singularity"].lines == [int(p.line[7])]
    assert des.n_usable == 38 and 3 not in des.chosen and 7 not in des.chosen
    from models.errors import InputError

    with pytest.raises(InputError, match="usable rows"):
        design_campaign(model, p, 39)


def test_fixed_joint_6_names_the_parameters_it_cannot_separate(fitted):
    _robot, model, data, pool = fitted
    assert design_campaign(model, pool, 5).unidentifiable == []
    q = pool.q.copy()
    q[:, 5] = 0.3
    p = Measurements(q=q, wrench=np.zeros_like(q))
    des = design_campaign(model, p, 5)
    names = {u.name for u in des.unidentifiable}
    # with joint 6 still, the joint-5 distal geometry is a constant offset, as the measured point
    assert names == {"dtheta[5]", "da[5]", "dalpha[5]", "dd[5]"}
    assert des.status is DesignStatus.UNIDENTIFIABLE and not any(u.determined_by_earlier for u in des.unidentifiable)
    seq = design_campaign(model, p, 5, earlier=[data])
    assert seq.status is DesignStatus.OK and all(u.determined_by_earlier for u in seq.unidentifiable)


def test_travel_order_is_a_shorter_permutation(fitted):
    robot, _model, _data, pool = fitted
    q = pool.q[:40]
    order, t = travel_order(q, robot.v_max)
    assert sorted(order.tolist()) == list(range(40))

    # independent time of a sequence: the slowest joint of each move at its velocity limit
    def seq_time(o):
        return sum(float(np.max(np.abs(q[b] - q[a]) / robot.v_max)) for a, b in zip(o[:-1], o[1:]))

    assert t == pytest.approx(seq_time(order), rel=1e-12)
    assert t <= seq_time(np.arange(40)) + 1e-12
    D = np.max(np.abs(q[:, None] - q[None]) / robot.v_max, axis=2)
    assert path_time(np.arange(40), D) == pytest.approx(seq_time(np.arange(40)))
    assert t < 0.7 * seq_time(np.arange(40))  # random poses: ordering matters


def test_task_region_follows_the_path(fitted):
    _robot, model, data, _pool = fitted
    from problems.problem import load_problem

    prob = load_problem("ur5_tool_thrust")
    reg = task_region(prob, model, 200, 1)
    eval_q, pool = reg  # unpacks as (eval_q, pool)
    assert 2 <= len(eval_q) <= TASK_MAX_EVAL_POSES and pool.n == 200
    assert np.all(pool.q >= model.nominal.q_min) and np.all(pool.q <= model.nominal.q_max)
    # the path configurations put the problem's TCP on its waypoints (the model's chain, the problem's tool)
    km = prob.with_robot(model).model.kinematics
    tcp = np.array([np.asarray(km.fn["fk_position"](q)).ravel() for q in eval_q])
    d = np.min(np.linalg.norm(tcp[:, None] - prob.positions[None], axis=2), axis=1)
    assert np.max(d) < PATH_TOL_M
    # the load: the tool-frame thrust turned into the base frame has the thrust's magnitude
    assert np.allclose(np.linalg.norm(reg.eval_wrench[:, :3], axis=1), 40.0)
    des = design_campaign(
        model, pool, 10, eval_q=eval_q, eval_wrench=reg.eval_wrench, eval_frame="base", earlier=[data]
    )
    assert des.n_eval == len(eval_q) and des.variance_after_m2 < des.variance_random_m2


# ------------------------------------------------------------------------------ command line
def _main(argv: list[str]) -> int:
    from planner import cli

    if "design" not in cli.COMMAND_MODULES:  # until the command is listed in planner/cli.py
        cli.COMMAND_MODULES = (*cli.COMMAND_MODULES, "design")
    return cli.main(argv)


@pytest.fixture(scope="module")
def files(fitted, tmp_path_factory):
    _robot, model, data, pool = fitted
    d = tmp_path_factory.mktemp("design")
    (d / "model.toml").write_text(model_toml(model))
    (d / "A.csv").write_text(measurements_to_csv(data))
    with (d / "pool.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["# a comment line"])
        w.writerow([f"q{j}" for j in range(1, 7)] + ["fx", "fy", "fz", "mx", "my", "mz"])
        for i, q in enumerate(pool.q):
            w.writerow([repr(float(v)) for v in q] + [0.0, 0.0, -float(i % 3) * 10.0, 0.0, 0.0, 0.0])
    return d


def test_cli_end_to_end(files, capsys):
    d = files
    out, rep = d / "campaign.csv", d / "report"
    code = _main(
        ["design", "--model", str(d / "model.toml"), "--data", str(d / "A.csv"), "--pool", str(d / "pool.csv"),
         "--n", "12", "--out", str(out), "--report", str(rep), "--no-progress"]
    )  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    assert printed.startswith("design: 12 of 300 pool poses (criterion task") and "wrote" in printed
    with out.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["point", "extra_pool_line"] + [f"q{j}" for j in range(1, 7)] + [
        "fx", "fy", "fz", "mx", "my", "mz", "x", "y", "z"
    ]  # fmt: skip
    assert [r["point"] for r in rows] == [f"design-{k:03d}" for k in range(1, 13)]
    assert all(r["x"] == r["y"] == r["z"] == "" for r in rows)
    lines = (d / "pool.csv").read_text().splitlines()
    for r in rows:  # each row is the pool file's line it names (line 1: the comment, 2: the header)
        src = lines[int(r["extra_pool_line"]) - 1].split(",")
        assert [float(r[f"q{j}"]) for j in range(1, 7)] == [float(v) for v in src[:6]]
        assert float(r["fz"]) == float(src[8])
    assert len({r["extra_pool_line"] for r in rows}) == 12
    # filled in with the measured points, the campaign is a measurement file identify reads
    filled = d / "filled.csv"
    with out.open() as f:
        text = f.read().replace(",,,\n", ",0.4,0.1,0.3\n")
    filled.write_text(text)
    m = read_measurements(str(filled))
    assert m.n == 12 and np.allclose(m.p, [0.4, 0.1, 0.3]) and list(m.point[:2]) == ["design-001", "design-002"]
    j = json.loads((rep / "report.json").read_text())
    assert j["command"] == "design" and len(j["design"]["chosen"]) == 12
    assert len(j["design"]["sigma_after_m"]) == 300 and j["design"]["guards"]["near_singularity"]["count"] == 0
    assert "data:image/png;base64," in (rep / "report.html").read_text()
    assert (rep / "report.md").read_text().startswith("# compplan campaign design")


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["--n", "5"], "--pool"),  # neither --pool nor --problem
        (["--pool", "POOL", "--problem", "ur5_tool_thrust", "--n", "5"], "--problem"),
        (["--pool", "POOL", "--n", "0"], "--n"),
        (["--pool", "POOL", "--n", "301"], "--n 301"),
        (["--pool", "BAD", "--n", "5"], "bad.csv"),
        (["--pool", "POOL", "--n", "5", "--criterion", "e"], "--criterion"),
        (["--pool", "POOL", "--n", "5", "--model", "ur5"], "re-identify"),
        (["--pool", "POOL", "--n", "5", "--shared", "frame"], "--shared"),
    ],
)
def test_cli_bad_inputs(files, capsys, args, names):
    d = files
    (d / "bad.csv").write_text("q1,q2,q3,q4,q5\n0,0,0,0,0\n")
    out = d / "never.csv"
    argv = ["design", "--model", str(d / "model.toml"), "--out", str(out)]
    argv += [str(d / "pool.csv") if a == "POOL" else str(d / "bad.csv") if a == "BAD" else a for a in args]
    with pytest.raises(SystemExit) as exc:
        code = _main(argv)
        raise SystemExit(code)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("compplan: error:") and names in err[0]
    assert not out.exists()


def test_cli_task_region(files, capsys):
    d = files
    out = d / "task_campaign.csv"
    code = _main(
        ["design", "--model", str(d / "model.toml"), "--data", str(d / "A.csv"), "--problem", "ur5_tool_thrust",
         "--n", "8", "--criterion", "d", "--seed", "2", "--out", str(out)]
    )  # fmt: skip
    assert code == 0
    assert "(criterion d; base frame" in capsys.readouterr().out
    with out.open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 8
    # extra_pool_line is the task pool's row (1-based): the same seed gives the same pool, its loaded rows
    # (the task's load) written with their load
    model = load_model(d / "model.toml")
    _eq, pool = task_region("ur5_tool_thrust", model, seed=2)
    for r in rows:
        i = int(r["extra_pool_line"]) - 1
        np.testing.assert_allclose([float(r[f"q{j}"]) for j in range(1, 7)], pool.q[i], rtol=0, atol=1e-15)
        np.testing.assert_allclose([float(r[c]) for c in ("fx", "fy", "fz", "mx", "my", "mz")], pool.wrench[i])


def test_potential_terms_change_the_choice_not_the_reported_sigma(fitted):
    """The model-robust selection (potential terms: unmodelled periodic joint errors) chooses other
    rows; the sigmas reported stay the model's own posterior after the chosen rows."""
    _robot, model, data, pool = fitted
    s2 = model.residual_sigma_m**2
    kw = dict(earlier=[data], new_registration=False, eval_frame="base")
    plain = design_campaign(model, pool, 15, potential_knots=0, **kw)
    robust = design_campaign(model, pool, 15, potential_knots=4, **kw)
    assert set(plain.chosen.tolist()) != set(robust.chosen.tolist())
    v = _independent_variance(model, data, pool, robust.chosen, s2)
    assert robust.variance_after_m2 == pytest.approx(v, rel=INDEPENDENT_REL_TOL)
    np.testing.assert_allclose(robust.sigma_before_m, plain.sigma_before_m, rtol=1e-9)


def test_cli_shared_registration_needs_no_new_frame(files, capsys):
    """With --shared registration the new campaign adds no registration to determine: the predicted
    sigma after it is below the one with a frame of its own (same pool, same N)."""
    d = files
    after = {}
    for label, extra in (("own", []), ("shared", ["--shared", "registration"])):
        rep = d / f"rep_{label}"
        argv = ["design", "--model", str(d / "model.toml"), "--data", str(d / "A.csv"), "--pool", str(d / "pool.csv"),
                "--n", "10", "--out", str(d / f"c_{label}.csv"), "--report", str(rep), *extra]  # fmt: skip
        assert _main(argv) == 0
        j = json.loads((rep / "report.json").read_text())
        after[label] = float(np.sqrt(np.mean(np.square(j["design"]["sigma_after_m"]))))
    capsys.readouterr()
    assert after["shared"] < after["own"]
