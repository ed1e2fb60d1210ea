"""Identify a material's mechanistic cutting coefficients from measured mean cutting forces.

Method (Altintas, *Manufacturing Automation*, 2nd ed., 2012, section 2.3, identification of the
cutting constants, generalised): the mean wrench of a steady cut over a spindle revolution is linear
in the six coefficients ``k = [Ktc, Krc, Kac, Kte, Kre, Kae]`` for any engagement,
``mean = D(test) @ k`` (:func:`models.cutting.force.mean_force_design`).  The textbook's slot tests at
several feeds per tooth give straight lines in the feed (slope: the cutting coefficients, intercept:
the edge coefficients); here every measured component of every test is one row of a design matrix
and ``k`` is its linear least-squares solution, so slots, up and down milling at any widths and depths,
and any end-mill shape, mix in one fit.

* Rows: ``Fx, Fy`` of every test, ``Fz`` where measured, ``Mx, My, Mz`` where measured (divided by
  the cutter radius, so that a moment row weighs as a force at the cutter's edge).
* The columns are scaled to unit length before the solution (the coefficients differ by about
  five orders of magnitude between N/m^2 and N/m); the **condition number** is the scaled matrix's.
* A coefficient is **identified** when the tests fix it: the null space of the design has no
  component along it.  With fewer than six independent rows some coefficients are not (one feed
  per tooth only: the cutting and edge terms are proportional; no ``Fz``: ``Kac`` and ``Kae``).
* Standard errors: ``sigma^2 (D^T D)^-1`` with ``sigma^2`` the residual variance
  ``RSS / (rows - 6)`` (no redundancy: not available).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from models.cutting.cutter import CutterShape, EndMill
from models.cutting.engagement import SLICE_HEIGHT_M
from models.errors import InputError
from models.status import Status
from problems.cutting.force_data import ForceTable, ForceTest, Spindle, engagement_of_test

__all__ = [
    "AXES",
    "COEFFICIENT_NAMES",
    "COEFFICIENT_UNITS",
    "CoefficientFit",
    "FitStatus",
    "design_of_tests",
    "fit_coefficients",
]

#: The six coefficients in the order of the design's columns.
COEFFICIENT_NAMES = ("Ktc", "Krc", "Kac", "Kte", "Kre", "Kae")
#: Their SI units.
COEFFICIENT_UNITS = ("N/m^2", "N/m^2", "N/m^2", "N/m", "N/m", "N/m")
#: The wrench components, in the order of the design's rows.
AXES = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: Angle bins of a revolution in a test's engagement: a flat end mill (one slice per test) and
#: other shapes (slices of ``SLICE_HEIGHT_M``).  Fine bins put the entry/exit angle of a partial
#: immersion within 0.025 deg (flat) / 0.125 deg of the exact one.
FIT_ANGLE_BINS_FLAT = 7200
FIT_ANGLE_BINS = 1440
#: Mirror of a wrench between a counter-clockwise spindle's frame and the feed frame (y -> -y).
MIRROR = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
#: Singular values of the column-scaled design below this fraction of the largest count as zero.
RANK_RTOL = 1e-9
#: A coefficient is identified when the null space's component along it is below this.
IDENTIFIED_TOL = 1e-6
#: Column-scaled condition number above which the tests hardly separate the coefficients.
COND_LIMIT = 100.0
#: Coefficient of determination of an axis below which the fit is called poor.
R2_MIN = 0.9


class FitStatus(Status):
    """Outcome of a fit (the worst that applies); ``usable``: all six coefficients identified."""

    OK = "ok"
    #: Some coefficients are not fixed by the tests (the reason names them and what to add).
    UNDERDETERMINED = "underdetermined"
    #: A cutting coefficient Ktc or Krc <= 0: force signs or frame wrong (forces on the workpiece?).
    IMPLAUSIBLE = "implausible"
    #: The tests separate the coefficients poorly (condition number above COND_LIMIT).
    ILL_CONDITIONED = "ill_conditioned"
    #: The model explains a measured axis poorly (R^2 below R2_MIN).
    POOR_FIT = "poor_fit"

    @property
    def usable(self) -> bool:
        """Every status but ``underdetermined`` gives all six coefficients (with a caveat unless ok)."""
        return self is not FitStatus.UNDERDETERMINED


@dataclass(frozen=True)
class CoefficientFit:
    """The identified coefficients and how well the tests fix them.

    Attributes
    ----------
    status : FitStatus
    reason : str
        Why the status (empty when ok).
    values : ndarray, shape (6,)
        ``[Ktc, Krc, Kac (N/m^2), Kte, Kre, Kae (N/m)]``; NaN where not identified.
    std_errors : ndarray, shape (6,)
        One standard error of each, same units; NaN where not identified or no redundancy.
    identified : ndarray of bool, shape (6,)
    r_squared : ndarray, shape (6,)
        Coefficient of determination per axis ``[Fx, Fy, Fz, Mx, My, Mz]`` over the tests; NaN for an
        axis not measured (or with fewer than 2 values, or no spread).
    measured, fitted, residuals : ndarray, shape (n, 6)
        Per test: the measured wrench, the model's (N, N·m; NaN where not measured, for residuals),
        and measured minus fitted.  With coefficients not identified, ``fitted`` is NaN where not
        measured (the measured components' fit is unique, the others are not).
    condition_number : float
        Of the column-scaled design (inf when rank-deficient).
    rank, n_rows, dof : int
        Rank of the design, its rows (measured components), rows minus rank.
    notes : tuple of str
    table : ForceTable
        The tests fitted.
    """

    status: FitStatus
    reason: str
    values: np.ndarray
    std_errors: np.ndarray
    identified: np.ndarray
    r_squared: np.ndarray
    measured: np.ndarray
    fitted: np.ndarray
    residuals: np.ndarray
    condition_number: float
    rank: int
    n_rows: int
    dof: int
    table: ForceTable
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def complete(self) -> bool:
        """Whether all six coefficients are identified."""
        return bool(self.identified.all())

    def coefficient_dict(self) -> dict[str, float]:
        """Name -> value (NaN where not identified)."""
        return {n: float(v) for n, v in zip(COEFFICIENT_NAMES, self.values)}

    def rms(self) -> np.ndarray:
        """RMS residual per axis, shape (6,), NaN for an axis not measured."""
        r = self.residuals
        n = np.sum(np.isfinite(r), axis=0)
        with np.errstate(invalid="ignore"):
            return np.where(n > 0, np.sqrt(np.nansum(r * r, axis=0) / np.maximum(n, 1)), np.nan)

    def coefficients(self, name: str, source: str):  # -> models.cutting.material.CuttingCoefficients
        """The identified coefficients as the force model takes them.

        Raises
        ------
        InputError
            Not all six are identified (the reason says which and why).
        """
        if not self.complete:
            raise InputError(f"{self.table.where}: the cutting coefficients are not identified: {self.reason}")
        from models.cutting.material import CuttingCoefficients

        return CuttingCoefficients(*map(float, self.values), name=name, source=source)


def design_of_tests(mill: EndMill, table: ForceTable | Sequence[ForceTest], where: str = "") -> np.ndarray:
    """The design of each test, ``mean wrench = D @ [Ktc, Krc, Kac, Kte, Kre, Kae]``.

    Parameters
    ----------
    mill : EndMill
    table : ForceTable or sequence of ForceTest
    where : str
        The file, for messages (default: the table's).

    Returns
    -------
    ndarray, shape (n, 6, 6)
        Rows ``[Fx, Fy, Fz, Mx, My, Mz]`` on the tool in the feed frame (moments about the tool tip),
        columns the coefficients (N per N/m^2, N per N/m; N·m likewise).

    Raises
    ------
    InputError
        A test the cutter cannot make (deeper than its flutes, wider than its diameter).
    """
    from models.cutting.force import mean_force_design

    tests = table.tests if isinstance(table, ForceTable) else tuple(table)
    where = where or (table.where if isinstance(table, ForceTable) else "tests")
    flat = mill.shape is CutterShape.FLAT
    bins = FIT_ANGLE_BINS_FLAT if flat else FIT_ANGLE_BINS
    out = np.zeros((len(tests), 6, 6))
    for i, t in enumerate(tests):
        batch = engagement_of_test(mill, where, t, bins, None if flat else SLICE_HEIGHT_M)
        D = mean_force_design(mill, batch, t.feed_per_tooth_m)[0]
        out[i] = MIRROR[:, None] * D if t.spindle is Spindle.CCW else D
    return out


def fit_coefficients(mill: EndMill, tests: ForceTable | Sequence[ForceTest]) -> CoefficientFit:
    """Fit the six cutting coefficients to measured mean forces (module docstring: the method).

    Parameters
    ----------
    mill : EndMill
        The cutter of the tests.
    tests : ForceTable or sequence of ForceTest
        The tests (:func:`problems.cutting.force_data.read_force_csv`).

    Returns
    -------
    CoefficientFit
        With status ``underdetermined`` when the tests do not fix every coefficient (the
        identified ones are still given).

    Raises
    ------
    InputError
        No tests, or a test the cutter cannot make.
    """
    table = tests if isinstance(tests, ForceTable) else ForceTable("tests", tuple(tests))
    if table.n == 0:
        raise InputError(f"{table.where}: no tests; expected cuts at two or more feeds per tooth")
    designs = design_of_tests(mill, table)
    measured = table.wrenches()
    weight = np.array([1.0, 1.0, 1.0] + [1.0 / mill.radius_m] * 3)
    have = np.isfinite(measured)
    A = (designs * weight[None, :, None])[have]  # (rows, 6)
    b = (measured * weight[None, :])[have]
    sol = _solve(A, b)
    values = np.where(sol.identified, sol.x, np.nan)
    fitted = designs @ sol.x  # unique where measured (the projection), whatever the null space
    residuals = np.where(have, measured - fitted, np.nan)
    r2 = _r_squared(measured, fitted, have)
    if not sol.identified.all():
        fitted = np.where(have, fitted, np.nan)
    status, reason, notes = _judge(table, sol, values, r2, have)
    return CoefficientFit(
        status=status,
        reason=reason,
        values=values,
        std_errors=np.where(sol.identified, sol.std, np.nan),
        identified=sol.identified,
        r_squared=r2,
        measured=measured,
        fitted=fitted,
        residuals=residuals,
        condition_number=sol.cond,
        rank=sol.rank,
        n_rows=int(A.shape[0]),
        dof=int(A.shape[0]) - sol.rank,
        table=table,
        notes=tuple(notes),
    )


@dataclass(frozen=True)
class _Solution:
    x: np.ndarray  # (6,) minimum-norm solution (scaled back)
    std: np.ndarray  # (6,) standard errors (NaN without redundancy)
    identified: np.ndarray  # (6,) bool
    rank: int
    cond: float


def _solve(A: np.ndarray, b: np.ndarray) -> _Solution:
    """Least squares on the column-scaled design: the minimum-norm solution, which coefficients the
    null space leaves free, the condition number and the standard errors."""
    scale = np.linalg.norm(A, axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    As = A / scale
    U, s, Vt = np.linalg.svd(As, full_matrices=True)
    tol = RANK_RTOL * (s[0] if s.size else 0.0)
    rank = int(np.sum(s > tol)) if s.size else 0
    null = Vt[rank:]  # (6 - rank, 6)
    identified = np.linalg.norm(null, axis=0) < IDENTIFIED_TOL if null.size else np.ones(6, bool)
    identified &= np.linalg.norm(A, axis=0) > 0.0
    Vr, sr = Vt[:rank].T, s[:rank]
    xs = Vr @ ((U[:, :rank].T @ b) / sr) if rank else np.zeros(6)
    dof = A.shape[0] - rank
    std = np.full(6, np.nan)
    if dof > 0 and rank:
        rss = float(np.sum((b - As @ xs) ** 2))
        cov = (rss / dof) * (Vr / sr**2) @ Vr.T
        std = np.sqrt(np.maximum(np.diag(cov), 0.0)) / scale
    cond = float(s[0] / s[-1]) if rank == 6 and s.size >= 6 else math.inf
    return _Solution(xs / scale, std, identified, rank, cond)


def _r_squared(measured: np.ndarray, fitted: np.ndarray, have: np.ndarray) -> np.ndarray:
    """R^2 per axis over the tests that measured it (NaN: under 2 values or no spread)."""
    out = np.full(6, np.nan)
    for k in range(6):
        y, f = measured[have[:, k], k], fitted[have[:, k], k]
        if y.size < 2:
            continue
        tot = float(np.sum((y - y.mean()) ** 2))
        if tot > 0.0:
            out[k] = 1.0 - float(np.sum((y - f) ** 2)) / tot
    return out


def _judge(
    table: ForceTable, sol: _Solution, values: np.ndarray, r2: np.ndarray, have: np.ndarray
) -> tuple[FitStatus, str, list[str]]:
    """The status, its reason and notes (the worst status that applies)."""
    notes: list[str] = []
    if sol.rank < 6 or not sol.identified.all():
        return FitStatus.UNDERDETERMINED, _underdetermined_reason(table, sol, have), notes
    if not np.isfinite(sol.std).any():
        notes.append(
            "as many measured components as coefficients: the fit is exact and has no standard errors; "
            "add tests (e.g. a third feed per tooth) for an estimate of the scatter"
        )
    bad = [f"{n} = {v:.4g} N/m^2" for n, v in zip(COEFFICIENT_NAMES[:2], values[:2]) if not v > 0.0]
    if bad:
        reason = (
            f"{' and '.join(bad)} is not positive: check the force signs and frame (forces on the tool, not on "
            "the workpiece: negate a table dynamometer's; x along the feed, z up the tool axis)"
        )
        return FitStatus.IMPLAUSIBLE, reason, notes
    if sol.cond > COND_LIMIT:
        reason = (
            f"condition number {sol.cond:.3g} > {COND_LIMIT:g}: the tests hardly separate the cutting from the "
            "edge coefficients; spread the feeds per tooth (e.g. a factor 3 between the smallest and largest)"
        )
        return FitStatus.ILL_CONDITIONED, reason, notes
    poor = [f"{AXES[k]} R^2 = {r2[k]:.3f}" for k in range(6) if np.isfinite(r2[k]) and r2[k] < R2_MIN]
    if poor:
        reason = (
            f"{', '.join(poor)} (< {R2_MIN:g}): the linear model explains the measured forces poorly (outliers, "
            "run-out, chatter, a size effect at small feeds, or wrong milling/width columns)"
        )
        return FitStatus.POOR_FIT, reason, notes
    return FitStatus.OK, "", notes


def _underdetermined_reason(table: ForceTable, sol: _Solution, have: np.ndarray) -> str:
    """Which coefficients the tests leave free, and what to add."""
    free = [n for n, ok in zip(COEFFICIENT_NAMES, sol.identified) if not ok]
    parts = []
    feeds = np.unique(np.round(table.feeds_m(), 12))
    if not have[:, 2].any() and {"Kac", "Kae"} & set(free):
        parts.append("no axial force (column Fz_N absent or empty): Kac and Kae are not identified")
    if feeds.size == 1:
        parts.append(
            f"one feed per tooth only ({feeds[0] * 1e3:g} mm): the cutting (Ktc, Krc, Kac) and edge (Kte, Kre, Kae) "
            "terms cannot be separated; add tests at two or more feeds per tooth (the textbook uses four or more)"
        )
    if not parts:
        parts.append(
            f"the tests fix {6 - len(free)} of the 6 coefficients (design rank {sol.rank}); add tests at other "
            "feeds per tooth or engagements"
        )
    return f"{'; '.join(parts)} (not identified: {', '.join(free) or 'none'})"
