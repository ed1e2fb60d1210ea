"""The model's sigma calibrated on held-out rows and grown beyond the identified ranges
(problems/identify/sigma_calibration.py; the formula in problems/identify/uncertainty.py).

* the linearised refit of a hold-out against an independent least-squares refit;
* on a virtual UR5 whose truth holds periodic joint errors the model may not add (an effect left out), identified
  in one joint-1 range: the calibrated sigma covers held-out errors inside the range and beyond it in the
  band, where the linearised sigma does not (the growth is what covers beyond it);
* the model file keeps the calibration; a bad value is refused naming the key.
"""

from __future__ import annotations

import tomllib
from dataclasses import replace

import numpy as np
import pytest

from models.arm_file import model_from_robot, model_toml
from models.robot import RobotFileError, robot_from_dict
from problems.identify import identify, predict
from problems.identify.sigma_calibration import refit_without
from problems.identify.uncertainty import predicted_sigma

#: Agreement of the linearised refit with an independent least-squares refit (relative).
REFIT_REL_TOL = 1e-8
#: The issue's coverage band of the 2-sigma interval (per axis).
COVERAGE_BAND = (0.90, 0.99)
#: Measurement noise of the virtual campaigns, m.
NOISE_M = 2e-5
#: Joint-1 range of the identification campaign and of the region beyond it, deg.
REGION_DEG, BEYOND_DEG = (-60.0, 20.0), (35.0, 80.0)


def test_linearised_refit_is_the_least_squares_refit() -> None:
    rng = np.random.default_rng(4)
    n, k = 120, 7
    J = rng.normal(size=(3 * n, k))
    r = rng.normal(size=3 * n)
    train = np.repeat(rng.random(n) < 0.7, 3)
    delta, C, s2 = refit_without(J, r, train)
    # independent: refit the training rows' residual model r + J d = min by lstsq
    d_ref = np.linalg.lstsq(J[train], -r[train], rcond=None)[0]
    e = r[train] + J[train] @ d_ref
    s2_ref = float(e @ e) / (train.sum() - k)
    assert np.allclose(delta, d_ref, rtol=REFIT_REL_TOL, atol=0)
    assert s2 == pytest.approx(s2_ref, rel=REFIT_REL_TOL)
    assert np.allclose(C, s2_ref * np.linalg.inv(J[train].T @ J[train]), rtol=1e-6)


@pytest.fixture(scope="module")
def transfer_case():
    """A virtual UR5 with DH errors and slow periodic errors of joints 1 and 2 (a bearing's 2 and 3 cycles per
    revolution); identified without `joint_error_map` (left out) from poses with joint 1 in REGION_DEG;
    held-out poses inside that range and beyond it."""
    from models import load_robot
    from problems.virtual import VirtualRobot

    robot = load_robot("ur5")
    ecc = {"joint": [1, 2], "amplitude_rad": [3e-4, 2e-4], "harmonic": [2.0, 3.0], "phase_rad": [0.4, 1.1]}
    cfg = {"seed": 5, "noise": {"sigma_m": NOISE_M}, "effects": {"geometric": {}, "eccentricity": ecc}}
    vr = VirtualRobot(robot, cfg)
    rng = np.random.default_rng(5)

    def campaign(deg: tuple[float, float], n: int, name: str):
        q = vr.sample_poses(4 * n, rng)
        q = q[(q[:, 0] >= np.radians(deg[0])) & (q[:, 0] <= np.radians(deg[1]))][:n]
        while len(q) < n:
            extra = vr.sample_poses(8 * n, rng)
            extra = extra[(extra[:, 0] >= np.radians(deg[0])) & (extra[:, 0] <= np.radians(deg[1]))]
            q = np.vstack([q, extra])[:n]
        from problems.measurements import Measurements

        F = np.zeros((n, 6))
        t = np.arange(n, dtype=float)
        p = vr.measure(q, F, t, None) + rng.normal(0, NOISE_M, (n, 3))
        return Measurements(q=q, wrench=F, p=p, t=t, point=np.array([f"{name}{i}" for i in range(n)]), source=name)

    data = campaign(REGION_DEG, 150, "A")
    res = identify(robot, data, candidates=["geometric", "joint_offset"])
    return res, campaign(REGION_DEG, 150, "in"), campaign(BEYOND_DEG, 150, "out")


def _coverage(model, m) -> float:
    e = predict(model, m) - m.p
    s = predicted_sigma(model, m.q, m.wrench).sigma_m
    return float(np.mean(np.abs(e) <= 2 * s))


def test_calibrated_sigma_covers_inside_and_beyond_the_identified_range(transfer_case) -> None:
    res, inside, beyond = transfer_case
    model = res.model
    cal = res.identifiability["sigma_calibration"]
    assert cal is not None and cal["n_cv_rows"] == 150 and cal["n_range_rows"] > 0
    assert (
        model.sigma_growth_rad_per_rad == pytest.approx(cal["growth_rad_per_rad"])
        and model.sigma_growth_rad_per_rad > 0
    )
    linear = replace(model, sigma_scale=1.0, sigma_growth_rad_per_rad=0.0)
    cov_in, cov_out = _coverage(model, inside), _coverage(model, beyond)
    lin_out = _coverage(linear, beyond)
    assert COVERAGE_BAND[0] <= cov_in <= COVERAGE_BAND[1], cov_in
    assert COVERAGE_BAND[0] <= cov_out <= COVERAGE_BAND[1], (cov_out, lin_out)
    # the left-out periodic errors make the linearised sigma too small beyond the range: the growth covers it
    assert lin_out < COVERAGE_BAND[0], lin_out
    assert any("sigma calibrated on held-out rows" in n for n in res.notes)


def _reload(model):
    return model_from_robot(robot_from_dict(tomllib.loads(model_toml(model)), "m.toml"), "m.toml")


def test_model_file_keeps_the_calibration(small_virtual_model) -> None:
    model = replace(small_virtual_model[3], sigma_scale=1.25, sigma_growth_rad_per_rad=3e-4)
    back = _reload(model)
    assert back.sigma_scale == 1.25 and back.sigma_growth_rad_per_rad == 3e-4


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        ({"sigma_scale": -1.0}, "expected a positive scale"),
        ({"sigma_growth_rad_per_rad": -1e-3}, "growth >= 0"),
        ({"sigma_scale": "big"}, "'sigma_scale' must be a list of 1 numbers"),
    ],
)
def test_bad_calibration_is_refused(small_virtual_model, edit, words) -> None:
    model = replace(small_virtual_model[3], sigma_scale=1.25, sigma_growth_rad_per_rad=3e-4)
    d = tomllib.loads(model_toml(model))
    d["identified"].update(edit)
    with pytest.raises(RobotFileError, match=words.replace("(", r"\(").replace(")", r"\)")):
        model_from_robot(robot_from_dict(d, "m.toml"), "m.toml")


def test_only_one_calibration_key_is_refused(small_virtual_model) -> None:
    model = replace(small_virtual_model[3], sigma_scale=1.25, sigma_growth_rad_per_rad=3e-4)
    d = tomllib.loads(model_toml(model))
    del d["identified"]["sigma_growth_rad_per_rad"]
    with pytest.raises(RobotFileError, match="needs 'sigma_growth_rad_per_rad' beside it"):
        model_from_robot(robot_from_dict(d, "m.toml"), "m.toml")
