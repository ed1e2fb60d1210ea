"""Clearance of an arm's capsules: self-collision and cell objects over N configurations.

The result is a :class:`Clearance` (status, reason, the smallest signed distance, the pair, the
sample index), never a bare ``None``.  Units: m.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING
from collections.abc import Sequence

import numpy as np

from ..status import Status
from .capsules import CapsuleModel, self_collision_pairs
from .distance import capsule_shape_distance
from .segments import capsule_distance

if TYPE_CHECKING:
    from .scene import SceneObject

__all__ = [
    "DEFAULT_CLEARANCE_M",
    "Clearance",
    "ClearanceStatus",
    "clearance_from_distances",
    "object_distances",
    "self_distances",
]

#: Smallest allowed distance (m) when a problem sets none: robot body to objects, link to link
#: (the issue's default, 5 mm).
DEFAULT_CLEARANCE_M = 0.005


class ClearanceStatus(Status):
    """How close the arm comes: ``ok`` (every pair keeps the clearance), ``too_close`` (no contact
    but closer than the clearance), ``collision`` (contact or penetration)."""

    OK = "ok"
    TOO_CLOSE = "too_close"
    COLLISION = "collision"


@dataclass(frozen=True)
class Clearance:
    """The smallest clearance over samples and pairs.

    Attributes
    ----------
    status : ClearanceStatus
    reason : str
        One line (does not repeat the status): the pair, the sample, the distance in mm.
    distance : float
        Smallest signed distance, m (negative: penetration depth); ``inf`` with no pair.
    pair : str
        The pair at the smallest distance, ``"link 3 – table"`` (empty with no pair).
    index : int
        The sample (waypoint, configuration) index of the smallest distance (-1 with no pair).
    clearance : float
        The required clearance, m.
    """

    status: ClearanceStatus
    reason: str
    distance: float
    pair: str
    index: int
    clearance: float


def clearance_from_distances(
    distances: np.ndarray, pair_names: Sequence[str], clearance: float = DEFAULT_CLEARANCE_M, what: str = "sample"
) -> Clearance:
    """The :class:`Clearance` of a table of signed distances.

    Parameters
    ----------
    distances : ndarray, shape (N, P)
        Signed distance of pair p at sample n, m.
    pair_names : sequence of str, length P
    clearance : float
        Required clearance, m.
    what : str
        What a sample is in the reason (``waypoint``, ``sample``, ``configuration``).
    """
    d = np.asarray(distances, dtype=float)
    if d.size == 0:
        return Clearance(ClearanceStatus.OK, "no pair to check", float("inf"), "", -1, clearance)
    n, p = np.unravel_index(int(np.argmin(d)), d.shape)
    dmin, pair = float(d[n, p]), pair_names[p]
    if dmin <= 0.0:
        status, text = ClearanceStatus.COLLISION, f"{pair} overlap by {-dmin * 1e3:.1f} mm at {what} {n}"
    elif dmin < clearance:
        status = ClearanceStatus.TOO_CLOSE
        text = f"{pair} {dmin * 1e3:.1f} mm apart at {what} {n} (clearance {clearance * 1e3:.1f} mm)"
    else:
        status, text = ClearanceStatus.OK, f"smallest distance {dmin * 1e3:.1f} mm: {pair} at {what} {n}"
    return Clearance(status, text, dmin, pair, int(n), clearance)


def self_distances(
    model: CapsuleModel, segments: np.ndarray, pairs: np.ndarray | None = None
) -> tuple[np.ndarray, list[str]]:
    """Signed self-collision distances of N configurations, vectorised (closed form).

    Parameters
    ----------
    model : CapsuleModel
    segments : ndarray, shape (N, M, 2, 3)
        From :func:`~models.collision.capsules.capsule_segments`.
    pairs : ndarray of int, shape (P, 2), optional
        Capsule index pairs; default :func:`~models.collision.capsules.self_collision_pairs`.

    Returns
    -------
    distances : ndarray, shape (N, P), m
    names : list of str, length P (``"link 1 – link 4"``)
    """
    pr = self_collision_pairs(model) if pairs is None else np.asarray(pairs, dtype=int).reshape(-1, 2)
    names = model.names
    d = capsule_distance(segments[:, pr[:, 0]], model.radius[pr[:, 0]], segments[:, pr[:, 1]], model.radius[pr[:, 1]])
    return d, [f"{names[i]} – {names[j]}" for i, j in pr]


def object_distances(
    model: CapsuleModel, segments: np.ndarray, objects: Sequence[SceneObject]
) -> tuple[np.ndarray, list[str]]:
    """Signed distances between every capsule and every object at N configurations (coal, a loop).

    Returns
    -------
    distances : ndarray, shape (N, M * K), m (capsule-major: pair ``m * K + k``)
    names : list of str, length M * K (``"link 3 – table"``)
    """
    n, m = segments.shape[:2]
    out = np.empty((n, m, len(objects)))
    for i in range(n):
        for c in range(m):
            for k, obj in enumerate(objects):
                out[i, c, k] = capsule_shape_distance(
                    segments[i, c, 0], segments[i, c, 1], model.radius[c], obj
                ).distance
    names = [f"{cn} – {o.name}" for cn in model.names for o in objects]
    return out.reshape(n, m * len(objects)), names
