"""Several campaigns in one table (:mod:`.campaigns`, step 2): their names and the merge.

:func:`merge_campaigns` maps every campaign's measured points by its transform into the reference
frame and concatenates them into one table (pose ids kept apart per campaign, time since each
campaign's start, weights from each campaign's ``sigma``); :func:`campaign_names` names the
campaigns after their files.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from models.errors import InputError

from ..measurements import Measurements

#: Separator of a campaign's name and a pose id in the merged table's ``point`` column.
POSE_SEPARATOR = "/"


def campaign_names(sources: Sequence[str]) -> list[str]:
    """Unique campaign names from data file names: the stems, ``-2``, ``-3`` ... appended to repeats
    (``campaign1`` ... for tables without a file name)."""
    out: list[str] = []
    for k, s in enumerate(sources):
        stem = Path(str(s)).stem if s and not str(s).startswith("<") else ""
        base = stem or f"campaign{k + 1}"
        name, n = base, 2
        while name in out:
            name, n = f"{base}-{n}", n + 1
        out.append(name)
    return out


def _all_or_none(campaigns: Sequence[Measurements], attr: str, names: Sequence[str], notes: list[str]) -> bool:
    """Whether every campaign has column ``attr``; a note names those without when only some have it."""
    have = [getattr(m, attr) is not None for m in campaigns]
    if any(have) and not all(have):
        missing = [n for n, h in zip(names, have) if not h]
        notes.append(
            f"campaigns: {attr} ignored in every campaign: {', '.join(missing)} give(s) none (a column is used "
            "only when every campaign gives it)"
        )
    return all(have)


def _check_orientation(campaigns: Sequence[Measurements], meas2ref: Sequence[np.ndarray]) -> None:
    """Raise :class:`InputError` when campaigns with orientation columns have registrations of their own."""
    rot = [m.rotation is not None for m in campaigns]
    if any(rot) and not all(np.allclose(T, np.eye(4)) for T in meas2ref):
        raise InputError(
            f"{', '.join(m.source for m, r in zip(campaigns, rot) if r)}: orientation columns (rx, ry, rz): "
            "several campaigns with their own registrations are fitted from positions only; give --shared "
            "registration (one frame for every campaign) or drop the rx, ry, rz columns"
        )


def _campaign_rows(
    campaigns: Sequence[Measurements],
    names: Sequence[str],
    meas2ref: Sequence[np.ndarray],
    use_t: bool,
    use_sigma: bool,
) -> tuple[list, list, list, list, list, bool]:
    """Per campaign: positions in the reference frame, times, point names, sigmas and per-axis sigmas.

    The last item: whether a re-registered campaign's anisotropic per-axis sigmas were made isotropic.
    """
    aniso = False
    P, T, PT, S, SX = [], [], [], [], []
    for m, name, A in zip(campaigns, names, meas2ref):
        P.append(m.p @ A[:3, :3].T + A[:3, 3])
        T.append((m.t - float(np.min(m.t))) if use_t else np.arange(m.n, dtype=float))
        ids = m.point if m.point is not None else m.pose_groups().astype(str)
        PT.append(np.array([f"{name}{POSE_SEPARATOR}{i}" for i in ids], dtype=object))
        if use_sigma:
            S.append(np.asarray(m.sigma, dtype=float))
            if np.allclose(A[:3, :3], np.eye(3)) and m.sigma_xyz is not None:
                SX.append(np.asarray(m.sigma_xyz, dtype=float))
            else:
                aniso |= m.sigma_xyz is not None and bool(np.ptp(m.sigma_xyz, axis=1).max() > 0)
                SX.append(np.repeat(np.asarray(m.sigma, dtype=float)[:, None], 3, axis=1))
    return P, T, PT, S, SX, aniso


def merge_campaigns(
    campaigns: Sequence[Measurements],
    names: Sequence[str],
    meas2ref: Sequence[np.ndarray] | None = None,
    notes: list[str] | None = None,
) -> tuple[Measurements, np.ndarray]:
    """One table of several campaigns, measured points in the reference frame.

    Parameters
    ----------
    campaigns : sequence of Measurements
        With positions ``p``, each in its own measurement frame, m.
    names : sequence of str
        Unique campaign names.
    meas2ref : sequence of ndarray, shape (4, 4), optional
        Per campaign: its measurement frame -> the reference frame (default identity: one frame).
    notes : list of str, optional
        Receives what the merge decided (columns some campaigns lack).

    Returns
    -------
    merged : Measurements
        ``p`` mapped into the reference frame; ``point`` = ``"<name>/<pose>"`` (a campaign's
        poses stay distinct from another's even with equal joints); ``t`` the time since the
        campaign's first row when every campaign has ``t``, else the row number within the
        campaign; ``sigma`` (isotropic: a rotated campaign's per-axis sigmas become their RMS),
        ``temperature`` and ``target`` only when every campaign gives them; ``line`` the file lines.
    campaign : ndarray of int, shape (N,)
        Campaign index of each row.
    """
    notes = [] if notes is None else notes
    C = len(campaigns)
    meas2ref = [np.eye(4)] * C if meas2ref is None else list(meas2ref)
    _check_orientation(campaigns, meas2ref)
    use_t = _all_or_none(campaigns, "t", names, notes)
    use_sigma = _all_or_none(campaigns, "sigma", names, notes)
    use_temp = _all_or_none(campaigns, "temperature", names, notes)
    use_target = all(m.target is not None for m in campaigns)
    use_rot = all(m.rotation is not None for m in campaigns)
    P, T, PT, S, SX, aniso = _campaign_rows(campaigns, names, meas2ref, use_t, use_sigma)
    if aniso:
        notes.append("campaigns: per-axis sigmas of a re-registered campaign are used as their RMS (isotropic)")
    cat = np.concatenate
    merged = Measurements(
        q=cat([m.q for m in campaigns]),
        wrench=cat([m.wrench for m in campaigns]),
        p=cat(P),
        t=cat(T),
        point=cat(PT).astype(str),
        rotation=cat([m.rotation for m in campaigns]) if use_rot else None,
        temperature=cat([m.temperature for m in campaigns]) if use_temp else None,
        sigma=cat(S) if use_sigma else None,
        line=cat([m.line for m in campaigns]),
        source=", ".join(m.source for m in campaigns),
        units=dict(campaigns[-1].units),
        sigma_xyz=cat(SX) if use_sigma else None,
        sigma_rot=(
            cat([m.sigma_rot for m in campaigns])
            if use_rot and all(m.sigma_rot is not None for m in campaigns)
            else None
        ),
        notes=[n for m in campaigns for n in m.notes],
        columns=dict(campaigns[-1].columns),
        target=cat([m.target for m in campaigns]) if use_target else None,
        file_format=campaigns[-1].file_format,
    )
    campaign = np.concatenate([np.full(m.n, k) for k, m in enumerate(campaigns)])
    return merged, campaign
