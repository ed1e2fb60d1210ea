"""What the report says about identified joint error maps: harmonics, sizes and the map with its band.

Built from the final fit (:mod:`.engine`): for each joint and component of
:mod:`models.effects.joint_error_map` that has a term, the harmonics (cycles per revolution)
with their amplitudes (SI and at the TCP) and the map over the angle range the data covered,
with a band of :data:`MAP_BAND_SIGMAS` standard deviations from the fit's covariance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from models.effects import GROUP_SLICES
from models.effects.joint_error_map import COEF_SHAPE, FREQ_SHAPE, MAP_COMPONENTS, MAP_UNITS, slot_index

#: Width of the uncertainty band of a drawn map, standard deviations.
MAP_BAND_SIGMAS = 2.0
#: Points of a drawn map.
MAP_CURVE_POINTS = 240
#: A drawn map extends beyond its covered range by this share of the range on each side (at least
#: MAP_CURVE_EXTEND_MIN_RAD): the map continues there (it is a function of the angle everywhere).
MAP_CURVE_EXTEND = 0.25
MAP_CURVE_EXTEND_MIN_RAD = float(np.radians(10.0))


@dataclass
class Harmonic:
    """One term of a map: frequency (cycles/rev), amplitude ``sqrt(a^2 + b^2)`` and its standard
    deviation (SI: rad or m), and the amplitude at the TCP (m: times the median lever of the
    component over the data)."""

    freq_cpr: float
    amplitude: float
    amplitude_std: float
    amplitude_tcp_m: float


@dataclass
class ErrorMapSummary:
    """The identified map of one joint and component.

    Attributes
    ----------
    joint : int
        1-based.
    component : str
        ``theta`` (angular positioning), ``d`` (axial), ``a`` (radial), ``alpha``, ``beta`` (tilts).
    unit : str
        SI unit of the map (``rad`` or ``m``).
    range_rad : (float, float)
        Commanded angle range the map was identified on.
    harmonics : list of Harmonic
        Largest amplitude first.
    q_rad, value, band : ndarray, shape (MAP_CURVE_POINTS,)
        (The curve spans the range and :data:`MAP_CURVE_EXTEND` of it beyond each end.)
        The map over its range and :data:`MAP_CURVE_EXTEND` of it beyond each end (SI), and the
        half-width of its band (MAP_BAND_SIGMAS std, the coefficients' covariance).
    rms_tcp_m : float
        RMS of the map's effect at the TCP over the data, m.
    """

    joint: int
    component: str
    unit: str
    range_rad: tuple[float, float]
    harmonics: list[Harmonic] = field(default_factory=list)
    q_rad: np.ndarray = field(default_factory=lambda: np.zeros(0))
    value: np.ndarray = field(default_factory=lambda: np.zeros(0))
    band: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rms_tcp_m: float = 0.0

    def to_dict(self) -> dict:
        """JSON form (SI plus the report's units: deg, urad or um)."""
        k = 1e6
        u = "urad" if self.unit == "rad" else "um"
        return {
            "joint": self.joint,
            "component": self.component,
            "unit": self.unit,
            "range_deg": [float(np.degrees(v)) for v in self.range_rad],
            "rms_tcp_um": self.rms_tcp_m * 1e6,
            "harmonics": [
                {
                    "freq_cpr": h.freq_cpr,
                    f"amplitude_{u}": h.amplitude * k,
                    f"amplitude_std_{u}": h.amplitude_std * k,
                    "amplitude_tcp_um": h.amplitude_tcp_m * 1e6,
                }
                for h in self.harmonics
            ],
        }


def summarise_maps(
    theta: np.ndarray,
    cov: np.ndarray | None,
    const_freq: np.ndarray,
    const_range: np.ndarray,
    lever: np.ndarray,
    q: np.ndarray,
) -> list[ErrorMapSummary]:
    """Summaries of every map with a term.

    Parameters
    ----------
    theta : ndarray, shape (N_PARAMS,)
        Identified parameters.
    cov : ndarray, shape (N_PARAMS, N_PARAMS) or None
        Their covariance (SI), NaN/zero where not free.
    const_freq, const_range : ndarray
        The model's ``error_map.freq`` (FREQ_SHAPE, cycles/rev) and ``error_map.range`` (6, 2) rad.
    lever : ndarray, shape (n, 6, N_COMP)
        TCP displacement per unit of each joint's component over the data (norm of the Jacobian
        column of that DH entry), m/rad or m/m.
    q : ndarray, shape (n, 6)
        Commanded joint angles of the data, rad.
    """
    f = np.asarray(const_freq, dtype=float).reshape(FREQ_SHAPE)
    rng = np.asarray(const_range, dtype=float).reshape(6, 2)
    s0 = GROUP_SLICES["error_map.c"].start
    c = np.asarray(theta, dtype=float)[GROUP_SLICES["error_map.c"]].reshape(COEF_SHAPE)
    out = []
    for j in range(6):
        for k, comp in enumerate(MAP_COMPONENTS):
            slots = [s for s in range(f.shape[2]) if f[j, k, s] > 0 and np.any(c[j, k, s] != 0)]
            if not slots:
                continue
            lo, hi = float(rng[j, 0]), float(rng[j, 1])
            med_lever = float(np.median(lever[:, j, k])) if len(lever) else 0.0
            ext = max(MAP_CURVE_EXTEND * (hi - lo), MAP_CURVE_EXTEND_MIN_RAD)
            grid = np.linspace(lo - ext, hi + ext, MAP_CURVE_POINTS)
            idx, cols = [], []
            harm = []
            for s in slots:
                ic, is_ = slot_index(j, k, s)
                a, b = c[j, k, s]
                amp = float(np.hypot(a, b))
                std = float("nan")
                if cov is not None and amp > 0:
                    g = np.array([a, b]) / amp
                    sub = cov[np.ix_([s0 + ic, s0 + is_], [s0 + ic, s0 + is_])]
                    std = float(np.sqrt(max(g @ sub @ g, 0.0)))
                harm.append(Harmonic(float(f[j, k, s]), amp, std, amp * med_lever))
                idx += [s0 + ic, s0 + is_]
                cols += [np.cos(f[j, k, s] * grid), np.sin(f[j, k, s] * grid)]
            B = np.column_stack(cols)
            coef = np.asarray(theta, dtype=float)[idx]
            value = B @ coef
            band = np.zeros_like(value)
            if cov is not None:
                sub = np.nan_to_num(cov[np.ix_(idx, idx)])
                band = MAP_BAND_SIGMAS * np.sqrt(np.maximum(np.einsum("ni,ij,nj->n", B, sub, B), 0.0))
            qd = np.clip(q[:, j], lo, hi)
            Bd = np.column_stack([fn(f[j, k, s] * qd) for s in slots for fn in (np.cos, np.sin)])
            rms_tcp = float(np.sqrt(np.mean((Bd @ coef * lever[:, j, k]) ** 2))) if len(q) else 0.0
            harm.sort(key=lambda h: -h.amplitude)
            out.append(ErrorMapSummary(j + 1, comp, MAP_UNITS[k], (lo, hi), harm, grid, value, band, rms_tcp))
    return out
