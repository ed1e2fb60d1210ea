"""Closed-form distances between segments and between capsules, vectorised in NumPy (no coal).

:func:`segment_distance` is the distance between segments (Ericson, *Real-Time Collision
Detection*, 5.1.9), vectorised over any leading shape, so N configurations times P capsule pairs
are one call; a capsule pair's distance is it minus both radii (:func:`capsule_distance`).

Units: m.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "capsule_distance",
    "segment_distance",
]

#: Squared segment length (m^2) below which a segment is treated as a point.
DEGENERATE_SEGMENT_M2 = 1e-24


def segment_distance(
    p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smallest distance between segments ``p0-p1`` and ``q0-q1``, with the closest points.

    Parameters
    ----------
    p0, p1, q0, q1 : ndarray, shape (..., 3)
        End points, m (broadcast against each other).

    Returns
    -------
    dist : ndarray, shape (...)
        Distance, m (>= 0).
    cp, cq : ndarray, shape (..., 3)
        Closest points on the first and on the second segment.
    """
    d1, d2 = p1 - p0, q1 - q0
    r = p0 - q0
    a = np.einsum("...i,...i->...", d1, d1)
    e = np.einsum("...i,...i->...", d2, d2)
    f = np.einsum("...i,...i->...", d2, r)
    c = np.einsum("...i,...i->...", d1, r)
    b = np.einsum("...i,...i->...", d1, d2)
    a_pt, e_pt = a <= DEGENERATE_SEGMENT_M2, e <= DEGENERATE_SEGMENT_M2
    a_s = np.where(a_pt, 1.0, a)
    e_s = np.where(e_pt, 1.0, e)
    denom = a * e - b * b
    # s on the first segment for the nearest point of the infinite lines (0 if parallel)
    s = np.where(
        denom > DEGENERATE_SEGMENT_M2 * (a + e + 1.0),
        np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0), 0, 1),
        0.0,
    )
    t = (b * s + f) / e_s
    # t outside [0, 1]: clamp it and recompute s
    s = np.where(t < 0.0, np.clip(-c / a_s, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a_s, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate segments (points)
    s = np.where(a_pt, 0.0, np.where(e_pt, np.clip(-c / a_s, 0.0, 1.0), s))
    t = np.where(e_pt, 0.0, np.where(a_pt, np.clip(f / e_s, 0.0, 1.0), t))
    cp = p0 + s[..., None] * d1
    cq = q0 + t[..., None] * d2
    return np.linalg.norm(cp - cq, axis=-1), cp, cq


def capsule_distance(
    seg_a: np.ndarray, r_a: np.ndarray | float, seg_b: np.ndarray, r_b: np.ndarray | float
) -> np.ndarray:
    """Signed distance between capsules (segment distance minus radii; negative: penetration).

    Parameters
    ----------
    seg_a, seg_b : ndarray, shape (..., 2, 3)
        Segment end points, m.
    r_a, r_b : float or ndarray broadcast to shape (...)
        Radii, m.

    Returns
    -------
    ndarray, shape (...), m.
    """
    dist, _, _ = segment_distance(seg_a[..., 0, :], seg_a[..., 1, :], seg_b[..., 0, :], seg_b[..., 1, :])
    return dist - r_a - r_b
