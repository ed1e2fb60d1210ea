"""Several campaigns select the model once: the re-fit rounds keep its structure.

Two campaigns of a virtual robot (geometric errors), the second measured by a moved tracker.  The
joint fit's rounds after the first re-fit the selected model (:func:`problems.identify.refit.refit_selection`)
and do not run the engine's effect selection again; the result is checked against what re-running the
whole engine on the table merged with the final transforms (the former rounds) finds.
"""

from __future__ import annotations

import numpy as np
import pytest

import problems.identify.engine as engine
from models import effects as fx
from models import load_robot
from models.transforms import invert, matrix_to_rotvec, rotvec_to_matrix, transform
from problems.identify import identify, identify_campaigns, merge_campaigns
from problems.identify.engine import select_model
from problems.identify.refit import refit_selection
from problems.measurements import Measurements
from problems.virtual import VirtualRobot

#: The virtual robot: geometric errors, 20 um noise.
CFG = {
    "seed": 7,
    "campaign": {"poses": 40, "loaded_rows": 0, "unloaded_rows": 1},
    "noise": {"sigma_m": 2e-5},
    "effects": {"geometric": {}},
}
NOISE_M = 2e-5
POSES = 40
#: Joint boxes (rad) of joints 2 and 3 of the two campaigns.
BOX_A = ((-2.0, 0.8), (-1.2, 1.6))
BOX_B = ((-1.0, -1.6), (-0.2, -0.8))
#: The moved tracker: campaign A's measurement frame -> campaign B's.
MOVE = transform(rotvec_to_matrix(np.array([0.05, -0.2, 0.4])), np.array([0.3, -0.5, 0.1]))
#: Engine selections of a two-campaign fit: the start transforms' fit of one campaign, and round 1.
SELECTIONS_PER_FIT = 2
#: The robot parameters (registration apart) agree with the engine's full run on the final table
#: to this many of their standard deviations (the Levenberg-Marquardt stop is 0.2 standard
#: deviations of a step).
OLD_WAY_MAX_Z = 0.5
#: ... the inlier RMS after to this relative difference ...
OLD_WAY_RMS_REL = 1e-3
#: ... and the reference registration to this translation (m) and rotation (rad), far below its
#: standard deviation (micrometres and microradians here).
OLD_WAY_REG_M, OLD_WAY_REG_RAD = 1e-6, 1e-6


def _campaign(vr, rng, box, source, T=None, t0=0.0) -> Measurements:
    lo, hi = -np.pi * np.ones(6), np.pi * np.ones(6)
    (lo[1], lo[2]), (hi[1], hi[2]) = box
    q = rng.uniform(lo, hi, (POSES, 6))
    F = np.zeros((POSES, 6))
    t = t0 + 10.0 * np.arange(POSES)
    p = vr.measure(q, F, t, None) + rng.normal(0.0, NOISE_M, (POSES, 3))
    if T is not None:
        p = p @ T[:3, :3].T + T[:3, 3]
    return Measurements(q=q, wrench=F, p=p, t=t, point=np.array([f"P{i}" for i in range(POSES)]), source=source)


@pytest.fixture(scope="module")
def case():
    robot = load_robot("ur5")
    vr = VirtualRobot(robot, CFG, seed=7)
    rng = np.random.default_rng(11)
    a = _campaign(vr, rng, BOX_A, "A.csv")
    b = _campaign(vr, rng, BOX_B, "B.csv", T=MOVE, t0=5000.0)
    return robot, a, b


def test_rounds_after_the_first_do_not_select_again(case, monkeypatch) -> None:
    robot, a, b = case
    calls = {"forward": 0, "backward": 0}

    def counted(name, fn):
        def wrapper(*args, **kwargs):
            calls[name] += 1
            return fn(*args, **kwargs)

        return wrapper

    monkeypatch.setattr(engine, "forward_selection", counted("forward", engine.forward_selection))
    monkeypatch.setattr(engine, "backward_pass", counted("backward", engine.backward_pass))
    res = identify_campaigns(robot, [a, b])
    fit = res.identifiability["campaign_fit"]
    assert fit["rounds"] >= 2 and fit["converged"]  # re-fit rounds did run ...
    assert calls == {"forward": SELECTIONS_PER_FIT, "backward": SELECTIONS_PER_FIT}  # ... without a selection


def test_result_matches_the_full_engine_on_the_final_table(case) -> None:
    robot, a, b = case
    res = identify_campaigns(robot, [a, b])
    frames = {c.name: c.base2meas for c in res.model.campaigns}
    A = [frames["B"] @ invert(frames["A"]), np.eye(4)]  # A -> B (the reference), B itself
    merged, _c = merge_campaigns([a, b], ["A", "B"], A)
    old = identify(robot, merged)  # what a former round ran: the whole selection again
    assert old.model.effects == res.model.effects
    assert abs(old.rms_after_m - res.rms_after_m) <= OLD_WAY_RMS_REL * res.rms_after_m
    std = np.sqrt(np.diag(res.model.covariance))
    z = [
        (old.model.theta[fx.PARAM_NAMES.index(n)] - res.model.theta[fx.PARAM_NAMES.index(n)]) / std[i]
        for i, n in enumerate(res.model.covariance_names)
        if not n.startswith("registration")  # a parametrisation around each fit's own start rotation
    ]
    assert len(z) > 10 and np.max(np.abs(z)) < OLD_WAY_MAX_Z
    D = old.model.base2meas() @ invert(res.model.base2meas())
    assert np.linalg.norm(D[:3, 3]) < OLD_WAY_REG_M
    assert np.linalg.norm(matrix_to_rotvec(D[:3, :3])) < OLD_WAY_REG_RAD


def test_refit_keeps_the_structure_and_refits_the_parameters(case) -> None:
    robot, a, _b = case
    sel = select_model(robot, a)
    first = sel.result()
    shift = transform(rotvec_to_matrix(np.array([0.0, 0.0, 1e-3])), np.array([1e-3, 0.0, 0.0]))
    moved = Measurements(q=a.q, wrench=a.wrench, p=a.p @ shift[:3, :3].T + shift[:3, 3], t=a.t, point=a.point,
                         source=a.source)  # fmt: skip
    again = refit_selection(sel, moved, first.model.theta).result()
    assert again.model.effects == first.model.effects
    assert again.model.held == first.model.held
    assert np.array_equal(again.inliers, first.inliers)
    # against the whole engine on the moved points (an independent fit): the same model, the
    # registration moved with the points, within the Levenberg-Marquardt stop (a 1 mm, 1 mrad start)
    full = identify(robot, moved)
    assert full.model.effects == again.model.effects
    assert abs(full.rms_after_m - again.rms_after_m) <= OLD_WAY_RMS_REL * full.rms_after_m
    std = again.model.std
    z = [(full.model.theta[fx.PARAM_NAMES.index(n)] - again.model.theta[fx.PARAM_NAMES.index(n)]) / sd
         for n, sd in std.items() if not n.startswith("registration")]  # fmt: skip
    assert len(z) > 10 and np.max(np.abs(z)) < OLD_WAY_MAX_Z
    D = full.model.base2meas() @ invert(again.model.base2meas())
    std_t = np.array([std[f"registration.t.{x}"] for x in "xyz"])
    std_w = max(std[f"registration.w.{x}"] for x in "xyz")
    assert np.all(np.abs(D[:3, 3]) < OLD_WAY_MAX_Z * std_t)
    assert np.linalg.norm(matrix_to_rotvec(D[:3, :3])) < OLD_WAY_MAX_Z * std_w
    assert np.linalg.norm(matrix_to_rotvec(full.model.base2meas()[:3, :3] @ first.model.base2meas()[:3, :3].T)) > 0.9e-3
    with pytest.raises(ValueError):
        refit_selection(sel, moved.subset(np.arange(moved.n - 1)), first.model.theta)
