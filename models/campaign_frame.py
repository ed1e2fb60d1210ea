"""One measurement campaign of a model identified from several: its registration and how the model's
covariance reads in its frame.

A campaign is one measurement file with the instrument set up once; each has its own registration
(base frame -> its measurement frame), the robot is shared (:mod:`problems.identify.campaigns`).  The
model's own registration is its reference campaign's; :func:`campaign_covariance` gives the model's
covariance with the registration's rows and columns those of another campaign, its cross-covariance
with the robot's parameters included when the model file holds it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import effects as fx


@dataclass
class CampaignFrame:
    """One measurement campaign of a model identified from several.

    Attributes
    ----------
    name : str
        The campaign's name (by default its data file's stem), unique within the model.
    base2meas : ndarray, shape (4, 4)
        Its registration: base-frame coordinates -> that campaign's measurement-frame coordinates, m.
    n_rows : int
        Rows of the campaign used in the fit.
    data : str
        The data file it was read from.
    registration_cov : ndarray, shape (6, 6), or None
        Covariance of its registration in the model's registration parameters ``reg.t`` (m) then
        ``reg.w`` (Cayley vector of the rotation correction applied on the measurement side,
        around the rotation of ``base2meas``), SI.
    registration_cross_cov : ndarray, shape (6, k), or None
        Covariance of those six parameters with the model's free parameters (the rows of
        :attr:`~models.arm.ArmModel.covariance`, in the order of its ``covariance_names``), SI; None:
        not known (older files), taken as zero.
    """

    name: str
    base2meas: np.ndarray
    n_rows: int = 0
    data: str = ""
    registration_cov: np.ndarray | None = None
    registration_cross_cov: np.ndarray | None = None


def campaign_covariance(cov: np.ndarray, names: list[str], frame: CampaignFrame) -> np.ndarray:
    """The model's covariance ``cov`` (k, k; rows ``names``) in campaign ``frame``'s measurement frame:
    the registration's rows and columns replaced by the campaign's registration covariance and its
    cross-covariance with the other parameters (zero when the file does not hold it)."""
    out = np.array(cov, dtype=float, copy=True)
    if frame.registration_cov is None:
        return out
    idx = [names.index(n) if n in names else -1 for n in fx.REGISTRATION_NAMES]
    cross = frame.registration_cross_cov
    for a, ia in enumerate(idx):
        if ia < 0:
            continue
        out[ia, :] = 0.0 if cross is None else cross[a]
        out[:, ia] = out[ia, :]
    for a, ia in enumerate(idx):
        for b, ib in enumerate(idx):
            if ia >= 0 and ib >= 0:
                out[ia, ib] = frame.registration_cov[a, b]
    return out
