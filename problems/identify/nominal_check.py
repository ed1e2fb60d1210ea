"""Do the measured points fit the declared robot at all?  Checked before any effect is fitted.

After the "before" fit (the robot file's nominal model with only the registration and the
measured point fitted), the measured points of the arm the robot file describes lie millimetres
from their prediction.  A median miss beyond
:data:`~problems.measurements.PLAUSIBLE_NOMINAL_DEVIATION_M` means one of:

* positions in another unit than their columns declare (metres under ``x_mm`` ...): the measured
  points spread over a thousandth (or a thousand times) of what the nominal forward kinematics
  of the same joints spreads over (:func:`unit_mismatch`);
* another arm (or other joint conventions): when even every DH parameter fitted (the
  ``geometric`` effect) leaves the points that far, nothing can fit and identification stops
  (:func:`check_nominal_fit`); when DH corrections do fit, the run goes on and its verdict names
  the implausible geometry (:mod:`models.plausibility`).

A file that gives the acquisition software's targets (the tracker-dif formats) is also compared
with the robot's nominal forward kinematics (:func:`target_note`).  Everything is SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.robot import Robot

from ..measurements import (
    PLAUSIBLE_NOMINAL_DEVIATION_M,
    POSITION_COLUMNS,
    TRACKER_COLUMNS,
    TRACKER_FORMATS,
    Measurements,
)
from ..measurements.columns import TRACKER_LENGTH_FACTOR, TRACKER_TARGET_COLUMNS
from .evaluation import FitProblem
from .identifiability import Known
from .lsq import ModelFit, evaluate, fit_model
from .results import DataError

#: Measured points whose spread differs from the nominal forward kinematics' by more than this
#: factor (either way) are not a robot's error: arms differ in size by a few times at most.
UNIT_SCALE_MISMATCH = 30.0
#: A unit whose factor brings the two spreads within this factor of each other is the suspect.
UNIT_SCALE_MATCH = 3.0
#: The spread comparison needs the nominal points to spread at least this much (m, RMS about
#: their centroid): poses all alike say nothing of the scale.
UNIT_CHECK_MIN_SPREAD_M = 0.05
#: Targets within this RMS of the nominal forward kinematics (m) are that model's: software
#: computes them to micrometres; more means the acquisition used another model of the arm.
TARGET_AGREE_RMS_M = 1e-4
#: Length units a position column may be in: SI factor -> (name, suffix).
_LENGTH_UNITS = {1.0: ("metres", "_m"), 1e-3: ("millimetres", "_mm"), 1e-6: ("micrometres", "_um")}


def _spread(P: np.ndarray) -> float:
    """RMS distance of the points (N, 3) from their centroid, in their unit."""
    return float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1)))) if len(P) else 0.0


def _position_factor(m: Measurements) -> float:
    """SI factor of the file's position columns (the format's for a tracker file)."""
    if m.file_format in TRACKER_FORMATS:
        return TRACKER_LENGTH_FACTOR
    return float(m.units.get(m.columns.get("x", "x"), 1.0))


def unit_mismatch(robot: Robot, m: Measurements, measured: np.ndarray, nominal: np.ndarray) -> str | None:
    """The message for positions in another unit than declared, or None.

    Parameters
    ----------
    robot : Robot
        The declared robot (named in the message).
    m : Measurements
        The table (its columns and units name the suspect columns).
    measured, nominal : ndarray, shape (N, 3)
        Measured points (m, as read) and the nominal model's prediction of them (m, any frame:
        only the spreads are compared).
    """
    s_nom = _spread(nominal)
    if s_nom < UNIT_CHECK_MIN_SPREAD_M:
        return None
    ratio = _spread(measured) / s_nom
    if 1.0 / UNIT_SCALE_MISMATCH < ratio < UNIT_SCALE_MISMATCH:
        return None
    factor = _position_factor(m)
    written = _spread(measured) / factor  # the spread in the file's numbers
    cols = [m.columns.get(c, c) for c in POSITION_COLUMNS]
    tracker = m.file_format in TRACKER_FORMATS
    shown = ", ".join(TRACKER_COLUMNS[1:7]) if tracker else ", ".join(cols)
    for f, (word, suffix) in _LENGTH_UNITS.items():
        if f != factor and 1.0 / UNIT_SCALE_MATCH < ratio * f / factor < UNIT_SCALE_MATCH:
            current = _LENGTH_UNITS.get(factor, ("their declared unit", ""))[0]
            if tracker:
                fix = f"the {m.file_format} format's positions are millimetres: write millimetres"
            else:
                renamed = ", ".join(f"{c}{suffix}" for c in POSITION_COLUMNS)
                fix = f"write {current} or name the columns {renamed}"
            return (
                f"{m.source}: columns {shown} look like {word}: the measured points spread over ~{written:.3g} "
                f"(file units) where the nominal forward kinematics of robot '{robot.name}' at the same joints "
                f"spreads over ~{s_nom * 1e3:.0f} mm; {fix}"
            )
    return (
        f"{m.source}: the measured points ({shown}) spread over {_spread(measured) * 1e3:.3g} mm where the nominal "
        f"forward kinematics of robot '{robot.name}' at the same joints spreads over {s_nom * 1e3:.0f} mm; "
        "are the positions in the unit their columns declare, and is --robot right?"
    )


def _median_miss(prob: FitProblem, fit: ModelFit) -> float:
    """Median distance (m) of the measured points from the fit's prediction (position rows)."""
    return float(np.median(np.linalg.norm(fit.residual(prob)[prob.pos], axis=1)))


@dataclass
class NominalFit:
    """How far the measured points are from the declared robot's nominal model.

    Attributes
    ----------
    source : str
        The data file, for messages.
    robot : str
        The robot's name.
    fitted : str
        What the "before" fit fitted (for messages).
    miss_m : float
        Median distance of the measured points from the nominal model's prediction, m.
    miss_dh_m : float or None
        The same with every DH parameter fitted too (``geometric``), m; None when not tried
        (the nominal model fits, or the selection may not add ``geometric``).
    """

    source: str
    robot: str
    fitted: str
    miss_m: float
    miss_dh_m: float | None = None

    @property
    def plausible(self) -> bool:
        """The nominal model fits within :data:`PLAUSIBLE_NOMINAL_DEVIATION_M`."""
        return self.miss_m <= PLAUSIBLE_NOMINAL_DEVIATION_M

    def refusal(self) -> str:
        """The one-line error: the measured points do not fit this robot."""
        head = (
            f"{self.source}: the measured points do not fit robot '{self.robot}': median distance "
            f"{self.miss_m * 1e3:.0f} mm from its nominal forward kinematics ({self.fitted}; expected < "
            f"{PLAUSIBLE_NOMINAL_DEVIATION_M * 1e3:g} mm)"
        )
        if self.miss_dh_m is None:
            why = "the effects allowed (--candidates) cannot change its geometry"
        elif self.miss_dh_m > PLAUSIBLE_NOMINAL_DEVIATION_M:
            why = f"{self.miss_dh_m * 1e3:.0f} mm even with every DH parameter fitted"
        else:
            why = (
                f"they fit only with DH corrections of another arm's size ({self.miss_dh_m * 1e3:.2g} mm with "
                "every DH parameter fitted)"
            )
        return f"{head}, {why}; is --robot right?"

    def notes(self) -> list[str]:
        """The note of a run that goes on although the nominal model misses (empty when it fits)."""
        if self.plausible or self.miss_dh_m is None or self.miss_dh_m > PLAUSIBLE_NOMINAL_DEVIATION_M:
            return []
        return [
            f"the measured points are a median {self.miss_m * 1e3:.0f} mm from the nominal forward kinematics "
            f"of robot '{self.robot}' (expected < {PLAUSIBLE_NOMINAL_DEVIATION_M * 1e3:g} mm); only DH "
            f"corrections bring them within {self.miss_dh_m * 1e3:.2g} mm: check --robot"
        ]


def check_nominal_fit(
    robot: Robot, prob: FitProblem, fit_b: ModelFit, theta: np.ndarray, known: Known, can_fit_geometry: bool
) -> NominalFit:
    """Refuse data that do not fit the declared robot in any way; measure how far they are from it.

    Parameters
    ----------
    robot : Robot
    prob : FitProblem
        The identification problem (rows, measured points).
    fit_b : ModelFit
        The "before" fit: nominal model, registration and measured point fitted (as ``known`` allows).
    theta : ndarray, shape (N_PARAMS,)
        Its parameters (the start of a fit with DH corrections).
    known : Known
        Parts of the set-up declared known.
    can_fit_geometry : bool
        Whether the selection may add the ``geometric`` effect (else nothing can bring the points
        nearer than the before fit).

    Returns
    -------
    NominalFit
        Not :attr:`~NominalFit.plausible` only when DH corrections fit the data (the run may go on:
        its verdict names the implausible geometry; a declared model that cannot be fitted against
        such a miss is then refused with :meth:`NominalFit.refusal`).

    Raises
    ------
    DataError
        Positions in another unit than declared; or the measured points a median beyond
        :data:`PLAUSIBLE_NOMINAL_DEVIATION_M` from the nominal model, and from the best fit with
        every DH parameter free (or ``geometric`` not allowed).
    """
    m = prob.m
    if known.registration and known.measured_point:
        fitted = "data declared registered"
    else:
        fitted = ("measured point" if known.registration else "registration and measured point") + " fitted"
    out = NominalFit(m.source, robot.name, fitted, _median_miss(prob, fit_b))
    if out.plausible:
        return out
    pos = prob.pos
    nominal, _q = evaluate(prob, prob.layout.nominal)
    msg = unit_mismatch(robot, m, m.p[pos], nominal[pos])
    if msg is not None:
        raise DataError(msg)
    if not can_fit_geometry:
        raise DataError(out.refusal())
    fit_g = fit_model(prob, theta, ["geometric"], known, np.ones(m.n, dtype=bool), robust=False)
    out.miss_dh_m = _median_miss(prob, fit_g)
    if out.miss_dh_m > PLAUSIBLE_NOMINAL_DEVIATION_M:
        raise DataError(out.refusal())
    return out


def target_note(robot: Robot, m: Measurements) -> str | None:
    """How the file's targets (``Measurements.target``, base frame) compare with the robot's
    nominal forward kinematics of the commanded joints, the measured point fitted in the TCP
    frame by linear least squares; None when the file has no targets."""
    if m.target is None:
        return None
    from models import KinematicModel

    T = KinematicModel(robot).tcp(m.q)  # (N, 4, 4) nominal TCP poses, base frame
    A = T[:, :3, :3].reshape(-1, 3)
    b = (m.target - T[:, :3, 3]).reshape(-1)
    point, *_ = np.linalg.lstsq(A, b, rcond=None)
    rms = float(np.sqrt(np.mean(np.sum((A @ point - b).reshape(-1, 3) ** 2, axis=1))))
    cols = ", ".join(TRACKER_TARGET_COLUMNS)
    at = ", ".join(f"{v * 1e3:.3f}" for v in point)
    if rms <= TARGET_AGREE_RMS_M:
        return (
            f"the file's targets ({cols}) are the nominal forward kinematics of robot '{robot.name}' at the "
            f"commanded joints ({rms * 1e3:.3f} mm RMS, with the measured point at ({at}) mm in its TCP frame)"
        )
    return (
        f"the file's targets ({cols}) differ from the nominal forward kinematics of robot '{robot.name}' at "
        f"the commanded joints by {rms * 1e3:.3g} mm RMS (measured point fitted at ({at}) mm in its TCP frame): the "
        "acquisition software used another model of the arm; check --robot"
    )
