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
