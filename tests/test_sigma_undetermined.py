"""A sigma that means something (issue 34): the parameters the identification data do not determine
are left out of the predicted sigma and named; model files with an implausible covariance are refused
naming the entry; a design proposes loads, or says it cannot, and a design from scratch starts from the
nominal model (problems/identify/uncertainty.py, models/arm_file.py, problems/identify/design*.py)."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
import tomli_w

from models import effects as fx
from models.arm_file import COVARIANCE_MAX_STD_RATIO, load_model, model_from_robot, model_toml
from models.robot import RobotFileError, robot_from_dict
from planner.cli import main as cli_main
from problems.identify.design import SETUP_NAMES, design_campaign
from problems.identify.design_loads import DESIGN_LOAD_DOMINANT_SHARE
from problems.identify.design_result import DesignStatus
from problems.identify.uncertainty import (
    UNDETERMINED_STD_RATIO,
    at_tcp,
    parameter_jacobian,
    path_sigma,
    predicted_sigma,
    to_base_frame,
    undetermined,
)
from problems.measurements import Measurements

#: The load of the "used with load" poses: a base-frame force on the TCP, N.
LOAD_N = (0.0, 0.0, -200.0)
#: Poses of the tests.
N_POSES = 40


@pytest.fixture(scope="module")
def unloaded_model():
    """Identified on unloaded virtual data with self-weight (the real UR5 grid's case, in ~2 s): joint
    stiffness is seen only through the self-weight it multiplies, so stiffness and the link masses are
    not determined, only their product."""
    from models import load_robot
    from problems.identify import identify
    from problems.virtual import VirtualRobot

    robot = load_robot("ur5")
    cfg = {
        "seed": 3,
        "campaign": {"poses": 80, "loaded_rows": 0, "unloaded_rows": 1},
        "noise": {"sigma_m": 2e-5},
        "effects": {"geometric": {}, "gravity": {}},
    }
    vr = VirtualRobot(robot, cfg)
    data = vr.campaign()
    model = identify(robot, data, candidates=["geometric", "gravity"]).model
    return robot, vr, data, model


def _loaded(n: int) -> np.ndarray:
    w = np.zeros((n, 6))
    w[:, :3] = LOAD_N
    return w


def test_unloaded_identification_leaves_stiffness_out_of_the_sigma(unloaded_model):
    _robot, vr, _data, model = unloaded_model
    und = {u.name: u for u in undetermined(model)}
    stiff = [n for n in model.covariance_names if n.startswith("stiffness.s")]
    assert stiff and set(stiff) <= set(und)  # kept by the fit, but not determined by its data
    assert all(u.std_ratio > UNDETERMINED_STD_RATIO for u in und.values())
    q = vr.sample_poses(N_POSES, np.random.default_rng(1))
    ps = predicted_sigma(model, q, _loaded(N_POSES), frame="base")
    # the full covariance's sigma under load: dominated by the stiffness (what the user saw, in metres)
    names = list(model.covariance_names)
    J = to_base_frame(model, parameter_jacobian(at_tcp(model), q, _loaded(N_POSES), names)[1], names)
    full = np.sqrt(np.einsum("nik,kl,nil->ni", J, np.asarray(model.covariance), J).max())
    assert ps.available and np.isfinite(ps.sigma_m).all()
    assert ps.sigma_m.max() < 1e-3 < full  # below a millimetre, the full one above
    got = {u.name: u for u in ps.excluded}
    assert set(got) == set(und)
    assert all(got[n].through_load for n in stiff)  # the load changes their effect: loaded data determine them
    assert all(got[n].effect == "joint_springs" for n in stiff)
    text = ps.excluded_text()
    assert text.startswith("sigma excludes") and "stiffness.s[2]" in text and "no loaded measurements" in text
    # unloaded, the same parameters are left out but nothing is said to act through a load
    ps0 = predicted_sigma(model, q, None, frame="base", include_residual=False)
    assert {u.name for u in ps0.excluded} == set(und) and not any(u.through_load for u in ps0.excluded)
    # holding parameters never makes the sigma larger than the full covariance's (conditioning; the
    # data determine the product of stiffness and mass, which the held block must keep)
    J0 = to_base_frame(model, parameter_jacobian(at_tcp(model), q, None, names)[1], names)
    full0 = np.einsum("nik,kl,nil->ni", J0, np.asarray(model.covariance), J0)
    assert (ps0.sigma_m**2 <= full0 * (1 + 1e-6) + 1e-20).all()


def test_path_sigma_carries_what_it_leaves_out(unloaded_model):
    _robot, vr, _data, model = unloaded_model
    q = vr.sample_poses(10, np.random.default_rng(2))
    d = path_sigma(model, q, _loaded(10)).to_dict()
    assert d["available"] and d["max_m"] < 1e-3
    names = {e["name"] for e in d["excluded"]}
    assert "stiffness.s[2]" in names and "sigma excludes" in d["text"]
    assert all(set(e) == {"name", "effect", "std_ratio", "through_load"} for e in d["excluded"])
    # the plan says that the compensation of its load rests on them; unloaded, it has nothing to say
    warn = path_sigma(model, q, _loaded(10)).load_warning()
    assert warn is not None and "stiffness.s[2]" in warn and "not in the sigma" in warn
    assert path_sigma(model, q, np.zeros((10, 6))).load_warning() is None


def test_a_determined_model_leaves_nothing_out(small_virtual_model):
    _robot, vr, _data, model = small_virtual_model
    assert undetermined(model) == []
    ps = predicted_sigma(model, vr.sample_poses(5, np.random.default_rng(0)), _loaded(5), frame="base")
    assert ps.excluded == [] and ps.excluded_text() == ""


# ------------------------------------------------------------------------------ tampered covariances
def _tampered(model, edit):
    d = tomllib.loads(model_toml(model))
    cov = d["identified"]["covariance"]
    edit(cov["matrix"], cov["names"])
    return d


def _set(i: int, j: int, v: float):
    def edit(M, _names):
        M[i][j] = v

    return edit


def _negative(M, _names):
    M[0][0] = -abs(M[0][0]) - 1e-12


def _correlation_beyond_one(M, _names):
    v = 2.0 * math.sqrt(M[0][0] * M[1][1])
    M[0][1] = M[1][0] = v


@pytest.mark.parametrize(
    ("edit", "words", "entry"),
    [
        (_set(0, 0, 1e30), "variance of", "0"),
        (_negative, "variance of", "0"),
        (_set(1, 1, float("nan")), "is nan: expected a finite number", "1"),
        (_set(0, 2, float("inf")), "expected a finite number", "0,2"),
        (_set(0, 1, 1.0), "not symmetric", "0,1"),
        (_correlation_beyond_one, "beyond 1 (not positive semi-definite)", "0,1"),
    ],
)
def test_tampered_covariance_is_refused_naming_the_entry(small_virtual_model, edit, words, entry):
    _robot, _vr, _data, model = small_virtual_model
    d = _tampered(model, edit)
    names = d["identified"]["covariance"]["names"]
    with pytest.raises(RobotFileError) as e:
        model_from_robot(robot_from_dict(d, "m.toml"), "m.toml")
    msg = str(e.value)
    assert msg.startswith("m.toml: [identified.covariance] matrix") and words in msg and "\n" not in msg
    for k in entry.split(","):
        assert names[int(k)] in msg


def test_non_psd_covariance_names_its_direction(small_virtual_model):
    _robot, _vr, _data, model = small_virtual_model

    def three(M, _names):  # correlations of 0.9, 0.9 and -0.9: each pair fine, the three together not PSD
        s = [math.sqrt(M[i][i]) for i in range(3)]
        for i, j, r in ((0, 1, 0.9), (0, 2, 0.9), (1, 2, -0.9)):
            M[i][j] = M[j][i] = r * s[i] * s[j]

    d = _tampered(model, three)
    with pytest.raises(RobotFileError, match="not positive semi-definite") as e:
        model_from_robot(robot_from_dict(d, "m.toml"), "m.toml")
    assert any(n in str(e.value) for n in d["identified"]["covariance"]["names"][:3])


def test_absurd_variance_limit_is_relative_to_the_typical_magnitude(small_virtual_model):
    _robot, _vr, _data, model = small_virtual_model
    d = tomllib.loads(model_toml(model))
    names = d["identified"]["covariance"]["names"]
    typical = fx.make_layout(model.nominal).scale[fx.PARAM_NAMES.index(names[0])]
    M = d["identified"]["covariance"]["matrix"]
    for j in range(1, len(names)):  # decorrelate parameter 0, then give it just below / above the limit
        M[0][j] = M[j][0] = 0.0
    M[0][0] = (0.99 * COVARIANCE_MAX_STD_RATIO * typical) ** 2
    ok = model_from_robot(robot_from_dict(d, "m.toml"), "m.toml")
    assert names[0] in {u.name for u in undetermined(ok)}  # read, and left out of the sigma
    M[0][0] = (1.01 * COVARIANCE_MAX_STD_RATIO * typical) ** 2
    with pytest.raises(RobotFileError, match="typical magnitude"):
        model_from_robot(robot_from_dict(d, "m.toml"), "m.toml")


def test_cli_refuses_a_tampered_model_in_one_line(small_virtual_model, tmp_path, capsys):
    _robot, vr, _data, model = small_virtual_model
    d = _tampered(model, _set(0, 0, 1e30))
    path = tmp_path / "tampered.toml"
    path.write_text(tomli_w.dumps(d))
    inp = tmp_path / "in.csv"
    q = vr.sample_poses(2, np.random.default_rng(0))
    inp.write_text(
        "q1,q2,q3,q4,q5,q6,fx,fy,fz,mx,my,mz\n" + "".join(",".join(map(repr, r)) + ",0,0,0,0,0,0\n" for r in q)
    )
    code = cli_main(["predict", "--model", str(path), "--input", str(inp), "--out", str(tmp_path / "p.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("compplan: error:")
    assert "tampered.toml" in err[0] and d["identified"]["covariance"]["names"][0] in err[0]
    assert not (tmp_path / "p.csv").exists()


# ------------------------------------------------------------------------------ design
def test_design_from_scratch_starts_from_the_nominal_model(small_virtual_model):
    _robot, vr, _data, model = small_virtual_model
    q = vr.sample_poses(120, np.random.default_rng(11))
    pool = Measurements(q=q, wrench=np.zeros((len(q), 6)), source="pool")
    des = design_campaign(model, pool, 10)
    names = list(model.covariance_names)
    _p, J = parameter_jacobian(model, q, None, names)
    typical = fx.make_layout(model.nominal).scale[[fx.PARAM_NAMES.index(n) for n in names]]
    J[:, :, [n in SETUP_NAMES for n in names]] = 0.0
    nominal = np.sqrt(np.einsum("nik,k,nik->n", J, typical**2, J) / 3.0)
    np.testing.assert_allclose(des.sigma_before_m, nominal, rtol=1e-9)
    assert des.region_sigma_m(des.sigma_after_m) < des.region_sigma_m(des.sigma_before_m)  # it goes down
    assert any(n.startswith("before: the nominal model") for n in des.notes)


def test_design_needs_loads_or_chooses_them(unloaded_model):
    _robot, vr, data, model = unloaded_model
    q = vr.sample_poses(150, np.random.default_rng(4))
    eval_q = vr.sample_poses(20, np.random.default_rng(5))
    kw = dict(eval_q=eval_q, eval_wrench=_loaded(len(eval_q)), eval_frame="base", earlier=[data])
    unloaded = Measurements(q=q, wrench=np.zeros((len(q), 6)), source="pool")
    des = design_campaign(model, unloaded, 12, **kw)
    assert des.status is DesignStatus.NEEDS_LOADS
    assert des.loads.share_after > DESIGN_LOAD_DOMINANT_SHARE and des.loads.pool_loaded == 0
    assert "stiffness.s[2]" in des.loads.parameters and "measure under load" in des.reason
    w = np.zeros((len(q), 6))
    w[1::2] = _loaded(len(q))[1::2]
    loaded = Measurements(q=q, wrench=w, source="pool")
    des2 = design_campaign(model, loaded, 12, **kw)
    assert des2.status is not DesignStatus.NEEDS_LOADS and des2.loads.chosen_loaded > 0
    assert des2.region_sigma_m(des2.sigma_after_m) < 0.5 * des.region_sigma_m(des.sigma_after_m)
    assert any(n.startswith("loads:") for n in des2.notes) and des2.to_dict()["loads"]["chosen_loaded"] > 0


def test_task_pool_carries_the_tasks_load(small_virtual_model):
    from problems.identify.design_region import task_region

    _robot, _vr, _data, model = small_virtual_model
    region = task_region("ur5_tool_thrust", model, n_pool=40, seed=2)
    loaded = np.any(region.pool.wrench != 0, axis=1)
    assert loaded[1::2].all() and not loaded[0::2].any()
    # the tool-frame thrust, turned with each pose's tool: |F| as the task's
    assert np.allclose(np.linalg.norm(region.pool.wrench[1::2, :3], axis=1), np.linalg.norm(region.eval_wrench[0, :3]))


def test_loaded_identification_is_accepted_by_load_model(unloaded_model, tmp_path):
    """The model file an identification writes reads back, stiffness and all (its variances far below
    the refusal limit)."""
    _robot, _vr, _data, model = unloaded_model
    path = tmp_path / "m.toml"
    path.write_text(model_toml(model))
    back = load_model(path)
    assert [u.name for u in undetermined(back)] == [u.name for u in undetermined(model)]
