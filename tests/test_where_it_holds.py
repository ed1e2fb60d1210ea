"""Validation across joint ranges (problems/identify/transfer.py): the validation rows binned by each
joint's distance beyond its identified range, against a direct computation written here, and the
report's and terminal's words."""

from __future__ import annotations

import numpy as np
import pytest

from problems.identify.transfer import BEYOND_BINS_DEG, holds_text, where_it_holds
from problems.identify.uncertainty import predicted_sigma


@pytest.fixture(scope="module")
def rows(small_virtual_model):
    """Poses inside every identified range and with joint 1 5, 30 and 100 deg beyond its upper end;
    errors growing with that distance (m)."""
    _robot, vr, _data, model = small_virtual_model
    rng = model.joint_range_rad
    q = np.tile(0.5 * (rng[:, 0] + rng[:, 1]), (40, 1))
    beyond_deg = np.repeat([0.0, 5.0, 30.0, 100.0], 10)
    q[:, 0] = np.where(beyond_deg > 0, rng[0, 1] + np.radians(beyond_deg), q[:, 0])
    gen = np.random.default_rng(1)
    err = gen.normal(0.0, 2e-5, (40, 3)) * (1.0 + beyond_deg[:, None] / 10.0)
    return model, q, err, beyond_deg


def test_bins_match_a_direct_count(rows) -> None:
    model, q, err, beyond_deg = rows
    w = where_it_holds(model, q, None, err)
    sig = predicted_sigma(model, q).sigma_m
    assert w["n_outside"] == 30 and w["inside"]["n_rows"] == 10
    assert w["coverage_2sigma"] == pytest.approx(np.mean(np.abs(err) <= 2 * sig))
    (j1,) = [jt for jt in w["joints"] if jt["joint"] == 1]
    assert j1["max_beyond_deg"] == pytest.approx(100.0)
    for b in j1["bins"]:
        lo, hi = b["beyond_deg"]
        assert (lo, hi) in zip(BEYOND_BINS_DEG[:-1], BEYOND_BINS_DEG[1:])
        sel = (beyond_deg > lo) & (beyond_deg <= hi)
        assert b["n_rows"] == sel.sum() == 10
        assert b["mean_error_mm"] == pytest.approx(np.linalg.norm(err[sel], axis=1).mean() * 1e3)
        assert b["coverage_2sigma"] == pytest.approx(np.mean(np.abs(err[sel]) <= 2 * sig[sel]))
    # the error grows ten-fold by 100 deg: the model does not hold to the farthest bin
    assert j1["holds_to_deg"] < 180.0
    text = holds_text(w)
    assert "joint 1 up to 100 deg beyond" in text and "inside every range" in text and len(text) < 300


def test_inside_every_range_has_no_joint_rows(rows) -> None:
    model, q, err, beyond_deg = rows
    inside = beyond_deg == 0
    w = where_it_holds(model, q[inside], None, err[inside])
    assert w["joints"] == [] and w["n_outside"] == 0
    assert "every row inside the identified joint ranges" in holds_text(w)
