"""Truth records: rebuilding a :class:`VirtualRobot` from :meth:`VirtualRobot.truth`.

A truth record (written by ``compplan simulate`` next to the simulated data as
``.truth.toml``) holds the robot, the configuration and the seed, from which every
realised parameter follows; ``realised`` is for reading only.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .config import SimConfigError
from .robot import VirtualRobot


def from_truth(truth: Mapping[str, Any]) -> VirtualRobot:
    """Rebuild a :class:`VirtualRobot` from :meth:`VirtualRobot.truth`."""
    from models.robot import robot_from_dict

    try:
        robot = robot_from_dict(truth["robot"], "truth: robot")
        return VirtualRobot(robot, truth["config"], seed=int(truth["seed"]), where="truth: config")
    except KeyError as exc:
        raise SimConfigError(f"truth: missing key {exc}") from None


def load_truth(path: str | Path) -> VirtualRobot:
    """Load a truth file written by ``compplan simulate``."""
    from models.robot import read_text_file

    p = Path(path)
    text = read_text_file(p, "truth file (TOML, written by compplan simulate)", SimConfigError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SimConfigError(f"{p}: not valid TOML: {exc}") from None
    missing = [k for k in ("robot", "config", "seed") if k not in data]
    if missing:
        raise SimConfigError(
            f"{p}: not a truth file of compplan simulate (missing key(s) "
            f"{', '.join(missing)}); give the .truth.toml written next to the simulated data"
        )
    return from_truth(data)
