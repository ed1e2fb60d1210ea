"""The result of a campaign design (:mod:`.design`): its status, the rows set aside, the
parameters no pool row identifies, and :class:`CampaignDesign`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from models.status import Status


class DesignStatus(Status):
    """Outcome of a campaign design (``.value`` is the ``report.json`` string)."""

    OK = "ok"
    #: chosen, but some parameters no pool row identifies and the earlier data do not determine
    UNIDENTIFIABLE = "unidentifiable_parameters"
    #: chosen, but the region's sigma after it is dominated by parameters that act through the load
    #: and the pool has no loaded row (``design_loads``)
    NEEDS_LOADS = "needs_loads"

    @property
    def usable(self) -> bool:
        return True


@dataclass
class SetAside:
    """Pool rows set aside by a guard: how many, and the file lines of the first ones."""

    reason: str
    count: int
    lines: list[int]

    def to_dict(self) -> dict[str, Any]:
        return {"reason": self.reason, "count": self.count, "lines": list(self.lines)}


@dataclass
class Unidentifiable:
    """A parameter no usable pool row can identify (not excited, or a combination of others)."""

    name: str
    reason: str
    determined_by_earlier: bool

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "reason": self.reason, "determined_by_earlier": self.determined_by_earlier}


@dataclass
class CampaignDesign:
    """A designed measurement campaign.

    Attributes
    ----------
    status : DesignStatus
    reason : str
        One sentence on the status.
    chosen : ndarray of int, shape (n,)
        Pool row indices (0-based), in travel order.
    criterion : str
        ``"task"`` or ``"d"``.
    eval_frame : str
        Frame of the evaluation poses' positions (``"measurement"`` or ``"base"``).
    sigma_before_m, sigma_after_m, sigma_random_m : ndarray, shape (N_e,)
        Per evaluation pose: the RMS over the three axes of the parameters' part of the predicted
        sigma, m, before the campaign, after it, and after ``n`` random usable pool rows (mean
        over the random subsets).
    variance_before_m2, variance_after_m2, variance_random_m2 : float
        The task criterion: mean over the evaluation poses of ``trace(J_e P J_e^T)``, m^2 (the
        random one: mean over the subsets).
    logdet_gain_after, logdet_gain_random : float
        The D criterion: ``log det`` of the information after minus before (dimensionless; the
        random one: mean over the subsets).
    unidentifiable : list of Unidentifiable
    guards : dict of str to SetAside
        ``"outside_limits"`` and ``"near_singularity"``.
    travel_s : float
        Estimated travel time of the ordered visit at the joint velocity limits, s (sum over
        moves of ``max_j |dq_j| / v_max_j``; no acceleration).
    n_pool, n_usable, n_eval : int
        Pool rows, rows left after the guards, evaluation poses.
    random_trials : int
    notes : list of str
        What the design assumed (e.g. the source of the "before" sigma).
    loads : LoadCheck or None
        The parameters that act through the region's load, their share of its variance, the loaded
        pool and chosen rows (:mod:`.design_loads`).
    """

    status: DesignStatus
    reason: str
    chosen: np.ndarray
    criterion: str
    eval_frame: str
    sigma_before_m: np.ndarray
    sigma_after_m: np.ndarray
    sigma_random_m: np.ndarray
    variance_before_m2: float
    variance_after_m2: float
    variance_random_m2: float
    logdet_gain_after: float
    logdet_gain_random: float
    unidentifiable: list[Unidentifiable]
    guards: dict[str, SetAside]
    travel_s: float
    n_pool: int
    n_usable: int
    n_eval: int
    random_trials: int
    notes: list[str] = field(default_factory=list)
    loads: Any = None

    @staticmethod
    def region_sigma_m(sigma: np.ndarray) -> float:
        """One figure for the region: the RMS over the evaluation poses of a per-pose sigma, m."""
        return float(np.sqrt(np.mean(np.asarray(sigma) ** 2)))

    def to_dict(self) -> dict[str, Any]:
        """Everything, JSON-ready (SI units)."""
        return {
            "status": self.status.value,
            "reason": self.reason,
            "criterion": self.criterion,
            "eval_frame": self.eval_frame,
            "chosen": [int(i) for i in self.chosen],
            "n_pool": self.n_pool,
            "n_usable": self.n_usable,
            "n_eval": self.n_eval,
            "random_trials": self.random_trials,
            "region_sigma_before_m": self.region_sigma_m(self.sigma_before_m),
            "region_sigma_after_m": self.region_sigma_m(self.sigma_after_m),
            "region_sigma_random_m": self.region_sigma_m(self.sigma_random_m),
            "sigma_before_m": self.sigma_before_m.tolist(),
            "sigma_after_m": self.sigma_after_m.tolist(),
            "sigma_random_m": self.sigma_random_m.tolist(),
            "variance_before_m2": self.variance_before_m2,
            "variance_after_m2": self.variance_after_m2,
            "variance_random_m2": self.variance_random_m2,
            "logdet_gain_after": self.logdet_gain_after,
            "logdet_gain_random": self.logdet_gain_random,
            "unidentifiable": [u.to_dict() for u in self.unidentifiable],
            "guards": {k: g.to_dict() for k, g in self.guards.items()},
            "travel_s": self.travel_s,
            "notes": list(self.notes),
            "loads": None if self.loads is None else self.loads.to_dict(),
        }
