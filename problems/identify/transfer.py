"""Where a model holds: a validation file's errors and sigma coverage by each joint's distance beyond the
identified range.

A model identified on one campaign is used where the next task runs; a validation file from another
campaign (``identify --validation``, ``predict --input`` with measured points) says how far it holds.
:func:`where_it_holds` splits the validation rows, for every joint, by how far that joint's command lies
beyond the range the identification data covered (:attr:`models.arm.ArmModel.joint_range_rad`), in the
bins :data:`BEYOND_BINS_DEG`, and gives per bin the rows, the mean Euclidean error, the mean predicted
sigma and the share of per-axis errors within 2 sigma.  Errors and sigmas are in the measurement frame
(the validation file's), m inside; the dictionary is in mm (``_mm``) and degrees (``_deg``) for the report.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from models.arm import ArmModel

from .uncertainty import beyond_range, predicted_sigma

#: Bin edges of the distance beyond a joint's identified range, deg (0: inside the range).
BEYOND_BINS_DEG = (0.0, 15.0, 45.0, 90.0, 180.0, 360.0)
#: A bin "holds" while its mean error is at most this multiple of the error inside every range and
#: its 2-sigma coverage at least :data:`HOLDS_MIN_COVERAGE`.
HOLDS_ERROR_RATIO = 2.0
HOLDS_MIN_COVERAGE = 0.90


def _bin_rows(err: np.ndarray, sig: np.ndarray, sel: np.ndarray) -> dict[str, Any]:
    eu = np.linalg.norm(err[sel], axis=1)
    cover = np.abs(err[sel]) <= 2.0 * sig[sel] if np.isfinite(sig[sel]).all() else None
    return {
        "n_rows": int(sel.sum()),
        "mean_error_mm": float(eu.mean() * 1e3),
        "max_error_mm": float(eu.max() * 1e3),
        "mean_sigma_mm": float(np.mean(sig[sel]) * 1e3) if cover is not None else None,
        "coverage_2sigma": float(cover.mean()) if cover is not None else None,
    }


def where_it_holds(
    model: ArmModel, q: np.ndarray, wrench: np.ndarray | None, err: np.ndarray, sigma: np.ndarray | None = None
) -> dict[str, Any]:
    """The validation rows' errors and coverage by joint range (module docstring).

    Parameters
    ----------
    model : ArmModel
        The identified model (its :attr:`~models.arm.ArmModel.joint_range_rad` and sigma).
    q : ndarray, shape (N, 6)
        Commanded joints of the validation rows, rad.
    wrench : ndarray, shape (N, 6), or None
        Their base-frame TCP wrenches, N and N*m.
    err : ndarray, shape (N, 3)
        ``predicted - measured``, m, measurement frame.
    sigma : ndarray, shape (N, 3), optional
        The model's predicted sigma at those rows (measurement frame, m) when the caller has it
        (:func:`.uncertainty.predicted_sigma`); computed otherwise.

    Returns
    -------
    dict
        ``coverage_2sigma`` (all rows, per axis; None without a covariance), ``n_outside`` (rows with a
        joint beyond its range), ``inside`` (the bin of rows inside every range), ``joints`` (per joint with
        rows beyond its range: ``joint``, ``range_deg``, ``bins`` (each with ``beyond_deg`` [lo, hi] and
        :func:`_bin_rows`' figures) and ``holds_to_deg``, the farthest bin edge up to which every bin holds).
    """
    sig = predicted_sigma(model, q, wrench).sigma_m if sigma is None else np.asarray(sigma, dtype=float)
    available = bool(np.isfinite(sig).all())
    out: dict[str, Any] = {
        "coverage_2sigma": float(np.mean(np.abs(err) <= 2.0 * sig)) if available else None,
        "n_outside": 0,
        "inside": None,
        "joints": [],
    }
    if model.joint_range_rad is None:
        return out
    beyond = np.degrees(beyond_range(model, q))
    outside = beyond.any(axis=1)
    out["n_outside"] = int(outside.sum())
    ref = None
    if (~outside).any():
        out["inside"] = _bin_rows(err, sig, ~outside)
        ref = out["inside"]["mean_error_mm"]
    rng = np.degrees(np.asarray(model.joint_range_rad))
    for j in np.flatnonzero(beyond.any(axis=0)):
        bins, holds_to, holding = [], 0.0, True
        for lo, hi in zip(BEYOND_BINS_DEG[:-1], BEYOND_BINS_DEG[1:]):
            sel = (beyond[:, j] > lo) & (beyond[:, j] <= hi)
            if not sel.any():
                continue
            b = {"beyond_deg": [lo, hi], **_bin_rows(err, sig, sel)}
            ok = (ref is None or b["mean_error_mm"] <= HOLDS_ERROR_RATIO * ref) and (
                b["coverage_2sigma"] is None or b["coverage_2sigma"] >= HOLDS_MIN_COVERAGE
            )
            holding = holding and ok
            holds_to = hi if holding else holds_to
            bins.append(b)
        out["joints"].append(
            {
                "joint": int(j + 1),
                "range_deg": [float(rng[j, 0]), float(rng[j, 1])],
                "max_beyond_deg": float(beyond[:, j].max()),
                "bins": bins,
                "holds_to_deg": holds_to,
            }
        )
    return out


#: Joints named on the terminal line (the farthest beyond their ranges); the report's table has every one.
HOLDS_JOINTS_NAMED = 2


def holds_text(w: dict[str, Any]) -> str:
    """One line for the terminal: the coverage and, for the :data:`HOLDS_JOINTS_NAMED` joints farthest beyond
    their ranges, the error and coverage in the farthest bin and up to where the model holds."""
    cov = w.get("coverage_2sigma")
    head = f"2-sigma coverage {100 * cov:.1f} % per axis" if cov is not None else "no sigma (no covariance)"
    if not w.get("joints"):
        return f"{head}; every row inside the identified joint ranges"
    joints = sorted(w["joints"], key=lambda jt: -jt["max_beyond_deg"])
    parts = []
    for jt in joints[:HOLDS_JOINTS_NAMED]:
        far = jt["bins"][-1]
        holds = "holds" if jt["holds_to_deg"] >= far["beyond_deg"][1] else f"holds to {jt['holds_to_deg']:g} deg"
        cov_far = f", {100 * far['coverage_2sigma']:.0f} %" if far["coverage_2sigma"] is not None else ""
        parts.append(
            f"joint {jt['joint']} up to {jt['max_beyond_deg']:.0f} deg beyond: {far['mean_error_mm']:.3f} mm{cov_far} "
            f"({holds})"
        )
    more = (
        f"; {len(joints) - HOLDS_JOINTS_NAMED} more joint(s) in the report" if len(joints) > HOLDS_JOINTS_NAMED else ""
    )
    inside = w.get("inside")
    ins = f"inside every range {inside['mean_error_mm']:.3f} mm; " if inside else ""
    return f"{head}; {w['n_outside']} rows beyond a range: {ins}" + "; ".join(parts) + more
