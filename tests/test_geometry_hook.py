"""An effect changes the arm's geometry by implementing the ``geometry`` hook (issue 22):
:attr:`models.arm.ArmModel.geometry_is_nominal` asks the effects, it keeps no list of names,
so a joint error map and a plug-in with a geometry hook move the warm starts onto the model's
chain and get the plausibility caveat like the library's geometric effects."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import models.effects as fx
from models import load_robot
from models.arm import ArmModel

#: Library effects acting on the arm whose ``geometry`` hook changes the DH chain.
GEOMETRY_EFFECTS = {"joint_offset", "geometric", "thermal", "joint_error_map"}


def _model(*effects: str) -> ArmModel:
    r = load_robot("ur5")
    return ArmModel(nominal=r, theta=fx.make_layout(r).nominal.copy(), effects=list(effects))


def test_the_nominal_model_has_the_nominal_geometry():
    assert _model().geometry_is_nominal


@pytest.mark.parametrize("name", sorted(e.name for e in fx.registry() if e.acts_on == fx.ARM and not e.declared))
def test_an_effect_changes_the_geometry_when_it_implements_the_hook(name):
    assert _model(name).geometry_is_nominal is not (name in GEOMETRY_EFFECTS)
    assert fx.effect(name).overrides("geometry") is (name in GEOMETRY_EFFECTS)


PLUGINS = """
import casadi as ca
from .base import Effect, ParamGroup, register


@register
class WristShift(Effect):
    name = "wrist_shift"
    order = 51
    groups = (ParamGroup("wrist_shift.d", ("wrist_shift.d",), "m", scale=1e-3),)
    formula = "d_4 += d (test plug-in with a geometry hook)"

    def geometry(self, ctx, dh):
        return {**dh, "d": dh["d"] + ca.vertcat(0, 0, 0, ctx.p("wrist_shift.d"), 0, 0)}


@register
class ExtraTorque(Effect):
    name = "extra_torque"
    order = 52
    groups = (ParamGroup("extra_torque.t", ("extra_torque.t",), "N*m", scale=1.0),)
    formula = "tau_1 += t (test plug-in without one)"

    def joint_torque(self, ctx):
        return ca.vertcat(ctx.p("extra_torque.t"), 0, 0, 0, 0, 0)
"""


def test_a_plug_in_with_a_geometry_hook_changes_the_geometry(tmp_path):
    (tmp_path / "test_plugins.py").write_text(PLUGINS)
    code = """
import models.effects as fx
from models import load_robot
from models.arm import ArmModel
r = load_robot("ur5")
for name in ("wrist_shift", "extra_torque"):
    print(name, ArmModel(nominal=r, theta=fx.make_layout(r).nominal.copy(), effects=[name]).geometry_is_nominal)
"""
    env = {**os.environ, "COMPPLAN_EFFECT_PATH": str(tmp_path)}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env, check=False
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["wrist_shift", "False", "extra_torque", "True"]
