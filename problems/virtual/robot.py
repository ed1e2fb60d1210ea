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
from models.transforms import matrix_to_rotvec

from .campaign import CampaignPart
from .config import TOP_KEYS, SimConfigError, integer
from .effects import EffectPart
from .measure import MeasuringPart
from .physics import PhysicsPart
from .registry import checked_effect_tables, top_level_tables


class VirtualRobot(EffectPart, PhysicsPart, MeasuringPart, CampaignPart):
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

    def __init__(
        self, robot: Robot, config: Mapping[str, Any], seed: int | None = None, where: str = "simulation config"
    ) -> None:
        cfg = dict(config)
        top_keys = TOP_KEYS | set(top_level_tables())
        unknown = sorted(set(cfg) - top_keys)
        if unknown:
            raise SimConfigError(f"{where}: unknown top-level key(s) {unknown}; allowed: {sorted(top_keys)}")
        self.robot = robot
        self.where = where
        self.config = copy.deepcopy(cfg)
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
                raise SimConfigError(f"{where}: seed {seed!r}: expected an integer >= 0")
            self.seed = int(seed)
        else:
            self.seed = integer(where, "seed", cfg.get("seed", 0), 0)
        units = cfg.get("units", "SI")
        if units not in ("SI", "mm"):
            raise SimConfigError(f"{where}: key 'units' must be 'SI' or 'mm', got {units!r}")
        rng = np.random.default_rng(self.seed)
        self.convention = robot.convention
        # the declared model (true stiffness, registration and measured point), then the effects
        self._realise_declared(cfg, rng)
        #: The ``[effects.NAME]`` tables as given (checked), by the name given.
        self.effects: dict[str, dict[str, Any]] = checked_effect_tables(where, cfg)
        self._realise(rng)

    def truth(self) -> dict[str, Any]:
        """Every realised parameter (SI), TOML-serialisable; rebuild with :func:`from_truth`."""
        out: dict[str, Any] = {
            "robot": self.robot.to_dict(),
            "config": self.config,
            "seed": self.seed,
            "realised": {
                "stiffness_Nm_per_rad": self.k_true.tolist(),
                "base2meas_rotvec_rad": matrix_to_rotvec(self.R_reg).tolist(),
                "base2meas_xyz_m": self.t_reg.tolist(),
                "measured_point_m": self.p_tool.tolist(),
                "da_m": self.da.tolist(),
                "dalpha_rad": self.dalpha.tolist(),
                "dd_m": self.dd.tolist(),
                "dtheta_rad": self.dtheta.tolist(),
                "dbeta_rad": self.dbeta.tolist(),
                "joint_error_terms": self.joint_error_terms(),
                "effects": sorted(self.effects),
            },
        }
        if getattr(self, "outlier_rows", None) is not None:
            out["realised"]["outlier_rows"] = [int(i) for i in self.outlier_rows]
        return out


def simulator(
    robot: str | Robot, config: Mapping[str, Any], seed: int | None = None, where: str = "simulation config"
) -> VirtualRobot:
    """Convenience: a :class:`VirtualRobot` from a robot name/file and a config mapping."""
    r = robot if isinstance(robot, Robot) else load_robot(robot)
    return VirtualRobot(r, config, seed=seed, where=where)
