"""Shared fixtures.  Tests run from a checkout with ``pip install .[test]``."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from models import AnalyticIK, KinematicModel, load_robot

ROBOTS = ("ar5", "ur5", "ur10")


@functools.lru_cache(maxsize=None)
def _model(name: str) -> tuple:
    robot = load_robot(name)
    return robot, KinematicModel(robot), AnalyticIK(robot)


@pytest.fixture(params=ROBOTS)
def robot_model_ik(request):
    """(robot, KinematicModel, AnalyticIK) for each built-in robot."""
    return _model(request.param)


def get_model(name: str) -> tuple:
    return _model(name)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


def as_modified_dh(robot_dict: dict) -> dict:
    """The same UR-type chain rewritten in modified DH (row i holds a_{i-1}, alpha_{i-1});
    valid because a6 = alpha6 = 0 for these arms (see docs/conventions.md)."""
    rows = robot_dict["joints"]
    mdh = []
    for i in range(6):
        row = dict(rows[i])
        row["a"] = rows[i - 1]["a"] if i > 0 else 0.0
        row["alpha"] = rows[i - 1]["alpha"] if i > 0 else 0.0
        mdh.append(row)
    return {**robot_dict, "convention": "modified_dh", "joints": mdh}
