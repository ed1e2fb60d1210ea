"""Loads in a campaign design (:mod:`.design`): which parameters act through the region's load,
how much of the region's predicted variance they carry, and what the design says about it.

A parameter *acts through the load* where the evaluation poses' wrenches change its sensitivity by
more than :data:`~.uncertainty.LOAD_EXCITED_FRACTION` of its sensitivity unloaded
(:func:`~.uncertainty.through_load`: joint stiffness, a load offset, ...): loaded measurements
tell it apart from what unloaded data see.  When such
parameters carry more than :data:`DESIGN_LOAD_DOMINANT_SHARE` of the region's variance after the
campaign and the pool has no loaded row, no campaign from that pool can reduce it: the design
says so (status ``needs_loads``).  With loaded rows in the pool the design chooses them where
they help, and says how many it chose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.arm import ArmModel

from .uncertainty import LOAD_TEST_MAX_POSES, frame_jacobian, held_covariance, through_load

#: The region's variance after the campaign is *dominated* by the parameters that act through the
#: load when they carry more than this share of it (the variance holding them would remove).
DESIGN_LOAD_DOMINANT_SHARE = 0.5
#: Parameters named in the design's sentence about loads (the rest counted).
LOAD_PARAMETERS_NAMED = 6


@dataclass
class LoadCheck:
    """What the design says about loads.

    Attributes
    ----------
    parameters : list of str
        The model's parameters that act through the region's load.
    share_before, share_after : float
        Their share of the region's variance before and after the campaign (0 without them).
    pool_loaded : int
        Usable pool rows with a load.
    chosen_loaded : int
        Chosen rows with a load.
    """

    parameters: list[str]
    share_before: float
    share_after: float
    pool_loaded: int
    chosen_loaded: int

    @property
    def needs_loads(self) -> bool:
        """The region's sigma after the campaign is dominated by parameters only loads determine and
        the pool has no loaded row."""
        return bool(self.parameters) and self.share_after > DESIGN_LOAD_DOMINANT_SHARE and not self.pool_loaded

    def names_text(self) -> str:
        more = len(self.parameters) - LOAD_PARAMETERS_NAMED
        return ", ".join(self.parameters[:LOAD_PARAMETERS_NAMED]) + (f" and {more} more" if more > 0 else "")

    def note(self, n_chosen: int) -> str | None:
        """The design's note about loads (None when no parameter acts through the load)."""
        if not self.parameters:
            return None
        if self.needs_loads:
            return None  # the status's reason says it
        return (
            f"loads: {self.chosen_loaded} of the {n_chosen} chosen poses are loaded ({self.pool_loaded} loaded pool "
            f"poses); parameters that act through the region's load ({self.names_text()}) carry "
            f"{self.share_before:.0%} of the region's variance before and {self.share_after:.0%} after"
        )

    def reason(self, sigma_after_mm: float) -> str:
        """The ``needs_loads`` status's reason."""
        return (
            f"the region's predicted sigma after this campaign, {sigma_after_mm:.4g} mm, is {self.share_after:.0%} "
            f"from parameters that act through the region's load ({self.names_text()}), and the pool has no loaded "
            "pose: no campaign from it can determine them; measure under load (a pool with load columns fx..mz, or "
            "--problem of a task with its load)"
        )

    def to_dict(self) -> dict[str, object]:
        return {
            "parameters": list(self.parameters),
            "share_before": float(self.share_before),
            "share_after": float(self.share_after),
            "pool_loaded": int(self.pool_loaded),
            "chosen_loaded": int(self.chosen_loaded),
            "needs_loads": self.needs_loads,
        }


def load_parameters(model: ArmModel, eq: np.ndarray, ew: np.ndarray | None, names: list[str], frame: str) -> np.ndarray:
    """Which of ``names`` act through the load at the evaluation poses ``eq`` (N, 6), rad, under
    ``ew`` (N, 6) or (6,) (bool (k,); all False without a load)."""
    k = len(names)
    if ew is None or not np.any(np.asarray(ew, dtype=float)):
        return np.zeros(k, dtype=bool)
    eq = np.atleast_2d(np.asarray(eq, dtype=float))
    n = len(eq)
    idx = np.unique(np.linspace(0, n - 1, min(n, LOAD_TEST_MAX_POSES)).round().astype(int))
    w = np.broadcast_to(np.asarray(ew, dtype=float), (n, 6))[idx]
    return through_load(
        frame_jacobian(model, eq[idx], w, names, frame), frame_jacobian(model, eq[idx], None, names, frame)
    )


def load_share(Jev: np.ndarray, P: np.ndarray, mask: np.ndarray) -> float:
    """The share of the region's variance ``mean trace(J_e P J_e^T)`` that holding the parameters of
    ``mask`` (bool over P's columns) would remove."""
    if not mask.any():
        return 0.0
    total = float(np.einsum("nik,kl,nil->", Jev, P, Jev))
    if total <= 0:
        return 0.0
    Pc = held_covariance(P, mask)
    Jk = Jev[:, :, ~mask]
    rest = float(np.einsum("nik,kl,nil->", Jk, Pc, Jk))
    return float(min(max(1.0 - rest / total, 0.0), 1.0))
