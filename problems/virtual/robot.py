"""The :class:`VirtualRobot`: a robot with true parameters and effects, and a measurement system.

The class checks the configuration's top level and tables, realises the effects
(:mod:`~problems.virtual.effects`) and gathers its method groups from the parts:
the physics of the deflected arm (:mod:`~problems.virtual.physics`), poses and their
measurement (:mod:`~problems.virtual.measure`) and the campaign
(:mod:`~problems.virtual.campaign`); :meth:`VirtualRobot.truth` returns every
realised parameter.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

import numpy as np

from models.robot import Robot, load_robot
from models.transforms import matrix_to_rotvec, rotvec_to_matrix

from .campaign import _Campaign
from .config import (
    _EFFECT_KEYS,
    _TOP_KEYS,
    JOINT_ERROR_EFFECTS,
    SIM_EFFECTS,
    SimConfigError,
    _at_least,
    _bool,
    _int,
    _table,
    _vec,
)
from .effects import _EffectRealisation
from .measure import _Measuring
from .physics import _Physics


class VirtualRobot(_EffectRealisation, _Physics, _Measuring, _Campaign):
    """A robot with 'true' parameters and effects, and a measurement system.

    Parameters
    ----------
    robot : Robot
        The nominal (declared) description.
    config : mapping
        Parsed configuration (schema in ``docs/identification.md``).
    seed : int, optional
        Seed of the random parts (geometric errors, poses, loads, noise);
        overrides ``config['seed']``.
    where : str
        Name of the configuration source for error messages.
    """

    def __init__(self, robot: Robot, config: Mapping[str, Any], seed: int | None = None,
                 where: str = "simulation config") -> None:
        cfg = dict(config)
        unknown = sorted(set(cfg) - _TOP_KEYS)
        if unknown:
            raise SimConfigError(f"{where}: unknown top-level key(s) {unknown}; allowed: {sorted(_TOP_KEYS)}")
        self.robot = robot
        self.where = where
        self.config = copy.deepcopy(cfg)
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
                raise SimConfigError(f"{where}: seed {seed!r}: expected an integer >= 0")
            self.seed = int(seed)
        else:
            self.seed = _int(where, "seed", cfg.get("seed", 0), 0)
        units = cfg.get("units", "SI")
        if units not in ("SI", "mm"):
            raise SimConfigError(f"{where}: key 'units' must be 'SI' or 'mm', got {units!r}")
        rng = np.random.default_rng(self.seed)
        self.convention = robot.convention
        # --- stiffness (true joint stiffness of the "declared" model)
        st = _table(where, cfg, "stiffness", {"scale"})
        scale = _vec(f"{where}: [stiffness]", "scale", st.get("scale", 1.0), 6)
        _at_least(f"{where}: [stiffness]", "scale", scale if isinstance(st.get("scale"), list) else scale[0],
                  0.0, strict=True)
        self.k_true = robot.stiffness * scale
        # --- registration and measured point
        reg = _table(where, cfg, "registration", {"registered", "base2meas_xyz_m", "base2meas_rotvec_rad",
                                                  "measured_point_m"})
        self.registered = _bool(f"{where}: [registration]", "registered", reg.get("registered", False))
        if self.registered:
            self.R_reg, self.t_reg = np.eye(3), np.zeros(3)
            self.p_tool = robot.tcp2flange[:3, 3].copy()
        else:
            self.R_reg = rotvec_to_matrix(_vec(where, "base2meas_rotvec_rad",
                                               reg.get("base2meas_rotvec_rad", [0.02, -0.01, 0.6]), 3, False))
            self.t_reg = _vec(where, "base2meas_xyz_m", reg.get("base2meas_xyz_m", [1.5, -0.5, 0.2]), 3, False)
            self.p_tool = _vec(where, "measured_point_m", reg.get("measured_point_m", [0.02, -0.015, 0.06]),
                               3, False)
        # --- effects
        eff = cfg.get("effects", {})
        if not isinstance(eff, Mapping):
            raise SimConfigError(f"{where}: 'effects' must be a table of [effects.NAME] tables")
        unknown = sorted(set(eff) - set(SIM_EFFECTS))
        if unknown:
            raise SimConfigError(f"{where}: unknown effect(s) {unknown}; known: {list(SIM_EFFECTS)}")
        self.effects: dict[str, dict[str, Any]] = {}
        for name, t in eff.items():
            if not isinstance(t, Mapping):
                raise SimConfigError(f"{where}: [effects.{name}] must be a table")
            bad = sorted(set(t) - _EFFECT_KEYS[name])
            if bad:
                raise SimConfigError(f"{where}: [effects.{name}]: unknown key(s) {bad}; "
                                     f"allowed: {sorted(_EFFECT_KEYS[name])}")
            self.effects[name] = dict(t)
        both = [name for name in JOINT_ERROR_EFFECTS if name in self.effects]
        if len(both) > 1:
            raise SimConfigError(f"{where}: [effects.eccentricity] and [effects.joint_error_map] are two spellings "
                                 "of the same effect (periodic joint errors); give one of them, with all its "
                                 "terms as lists")
        self._realise(rng)

    def truth(self) -> dict[str, Any]:
        """Every realised parameter (SI), TOML-serialisable; rebuild with :func:`from_truth`."""
        out: dict[str, Any] = {
            "robot": self.robot.to_dict(), "config": self.config, "seed": self.seed,
            "realised": {
                "stiffness_Nm_per_rad": self.k_true.tolist(),
                "base2meas_rotvec_rad": matrix_to_rotvec(self.R_reg).tolist(),
                "base2meas_xyz_m": self.t_reg.tolist(),
                "measured_point_m": self.p_tool.tolist(),
                "da_m": self.da.tolist(), "dalpha_rad": self.dalpha.tolist(), "dd_m": self.dd.tolist(),
                "dtheta_rad": self.dtheta.tolist(), "dbeta_rad": self.dbeta.tolist(),
                "joint_error_terms": self.joint_error_terms(),
                "effects": sorted(self.effects),
            },
        }
        if getattr(self, "outlier_rows", None) is not None:
            out["realised"]["outlier_rows"] = [int(i) for i in self.outlier_rows]
        return out


def simulator(robot: str | Robot, config: Mapping[str, Any], seed: int | None = None,
              where: str = "simulation config") -> VirtualRobot:
    """Convenience: a :class:`VirtualRobot` from a robot name/file and a config mapping."""
    r = robot if isinstance(robot, Robot) else load_robot(robot)
    return VirtualRobot(r, config, seed=seed, where=where)
