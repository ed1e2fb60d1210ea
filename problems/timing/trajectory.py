"""Data types of the time parametrisation: limits, status and the sampled trajectory.

Everything is in SI units and in joint space (no Cartesian frame is
involved): joint positions in rad, velocities in rad/s, accelerations in
rad/s^2, jerks in rad/s^3, times in s.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from dataclasses import dataclass, field

import numpy as np

from models.errors import InputError
from models.status import Status

__all__ = [
    "LIMIT_KEYS",
    "JointLimits",
    "TimingStatus",
    "Trajectory",
    "empty_trajectory",
]

#: Names of the limited quantities, in this order everywhere (also the keys
#: of :attr:`Trajectory.limit_ratio`).
LIMIT_KEYS: tuple[str, ...] = ("velocity", "acceleration", "jerk")


class TimingStatus(Status):
    """Outcome of :func:`problems.timing.time_parametrize`."""

    OK = "ok"
    LIMIT_EXCEEDED = "limit_exceeded"
    INFEASIBLE = "infeasible"
    FAILED = "failed"


def _limit_array(name: str, raw: object) -> np.ndarray:
    """Convert one limit to a float array of shape ``(n,)``.

    Raises
    ------
    InputError
        If it is not numeric or not a non-empty 1-D array.
    """
    try:
        arr = np.array(raw, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"JointLimits.{name} must be a numeric array, got {raw!r}") from exc
    if arr.ndim != 1 or arr.size == 0:
        raise InputError(f"JointLimits.{name} must be a non-empty 1-D array (n,), got shape {arr.shape}")
    return arr


@dataclass(frozen=True)
class JointLimits:
    """Symmetric per-joint kinematic limits (SI units, joint space).

    Parameters
    ----------
    velocity : np.ndarray
        Shape ``(n,)``, rad/s, finite and > 0.
    acceleration : np.ndarray
        Shape ``(n,)``, rad/s^2, finite and > 0.
    jerk : np.ndarray
        Shape ``(n,)``, rad/s^3, finite and > 0.

    Raises
    ------
    InputError
        If an array is not 1-D, is empty, the shapes differ, or a value is not
        finite or not > 0. The message names the quantity, the joint (1-based)
        and the value.

    Notes
    -----
    The arrays are stored as read-only float copies.
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    def __post_init__(self) -> None:
        shape: tuple[int, ...] | None = None
        for name in LIMIT_KEYS:
            arr = _limit_array(name, getattr(self, name))
            if shape is None:
                shape = arr.shape
            elif arr.shape != shape:
                raise InputError(
                    f"JointLimits.{name} has shape {arr.shape} but "
                    f"JointLimits.velocity has shape {shape}; all limits need "
                    "one value per joint"
                )
            bad = np.flatnonzero(~(np.isfinite(arr) & (arr > 0.0)))
            if bad.size:
                j = int(bad[0])
                raise InputError(
                    f"JointLimits.{name}: joint {j + 1} has value {float(arr[j])!r}; limits must be finite and > 0"
                )
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return int(self.velocity.shape[0])

    def as_dict(self) -> dict[str, np.ndarray]:
        """Limits keyed like :attr:`Trajectory.limit_ratio`, each shape ``(n,)``."""
        return {k: getattr(self, k) for k in LIMIT_KEYS}


@dataclass
class Trajectory:
    """A sampled, time-parametrised joint trajectory.

    Attributes
    ----------
    method : str
        Name of the registered method that produced it (e.g. ``"toppra"``).
    status : TimingStatus
        ``OK`` only if every checked ratio is ``<= 1 + LIMIT_RATIO_TOL``
        (velocity and acceleration for TOPP-RA; all three for Ruckig).
    reason : str
        Human-readable explanation, always non-empty (also for ``OK``); it does not
        repeat the status (show ``f"{status.value}: {reason}"``).
    t : np.ndarray
        Shape ``(M,)``, s. Uniform at ``dt`` from ``t[0] = 0``; ``t[-1]`` is
        the end time (a multiple of ``dt``) where the arm is at rest.
    q, qd, qdd, qddd : np.ndarray
        Shape ``(M, n)``: rad, rad/s, rad/s^2, rad/s^3 (joint space),
        evaluated from the analytic trajectory (not finite differences).
    duration_s : float
        ``t[-1]`` (s). ``0.0`` for a zero-length path, NaN when no trajectory
        could be computed (then ``M = 0``).
    limit_ratio : dict[str, np.ndarray]
        Keys ``"velocity"``, ``"acceleration"``, ``"jerk"``; each shape
        ``(n,)``, dimensionless: peak ``|value| / limit`` over the samples and
        the finer check grid (see :mod:`problems.timing.verification`). NaN if
        unavailable.
    dt : float
        Controller period (s).
    iterations : int
        Number of TOPP-RA / Ruckig runs of the limit-verification loop
        (0 if none ran).
    first_pass_limit_ratio : dict[str, np.ndarray]
        Ratios of the first run, before any grid refinement or limit
        shrinking, on the check grid (same keys and shapes; empty if no run
        produced a trajectory). ``first_pass_limit_ratio["acceleration"]``
        above 1 shows the raw TOPP-RA overshoot that was corrected.
    solver_code : str
        The solver's own code when a solver call failed and that failure
        decided the result: ``"ruckig.Result.<name>"`` when Ruckig returned a
        code other than ``Working``/``Finished``, ``"ruckig.RuckigError"``
        when the Ruckig binding raised instead. Empty when no solver call
        failed (and for TOPP-RA, whose code is quoted in :attr:`reason`).
    """

    method: str
    status: TimingStatus
    reason: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qddd: np.ndarray
    duration_s: float
    limit_ratio: dict[str, np.ndarray]
    dt: float
    iterations: int = 0
    first_pass_limit_ratio: dict[str, np.ndarray] = field(default_factory=dict)
    solver_code: str = ""

    @property
    def ok(self) -> bool:
        """``True`` if :attr:`status` is ``OK``."""
        return self.status is TimingStatus.OK

    def _csv_table(self) -> tuple[str, np.ndarray]:
        """Header line and data rows ``(M, 1 + 4 n)`` of :meth:`to_csv`: ``t, q, qd, qdd, qddd``
        (the columns of the product's ``trajectory.csv``)."""
        t = np.asarray(self.t)
        m = t.shape[0] if t.ndim == 1 else -1
        blocks = [np.asarray(self.q), np.asarray(self.qd), np.asarray(self.qdd), np.asarray(self.qddd)]
        if m < 0 or any(b.ndim != 2 or b.shape[0] != m for b in blocks):
            raise InputError(
                "inconsistent trajectory arrays: t "
                f"{t.shape}, q {blocks[0].shape}, qd {blocks[1].shape}, "
                f"qdd {blocks[2].shape}, qddd {blocks[3].shape}"
            )
        n = blocks[0].shape[1]
        if any(b.shape[1] != n for b in blocks):
            raise InputError(
                f"q, qd, qdd and qddd must have the same number of joints, got {[b.shape[1] for b in blocks]}"
            )
        header = ",".join(["t"] + [f"{p}{j}" for p in ("q", "qd", "qdd", "qddd") for j in range(1, n + 1)])
        data = np.column_stack([t] + blocks) if m else np.empty((0, 1 + 4 * n))
        return header, data

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write the samples as CSV, atomically.

        Columns: ``t, q1..qn, qd1..qdn, qdd1..qddn`` (s, rad, rad/s,
        rad/s^2), one header line, one row per sample, values in ``%.17g``
        (round-trip exact). The data are written to a temporary file in the
        destination directory and moved into place with :func:`os.replace`,
        so ``path`` is either fully written or left untouched.

        Parameters
        ----------
        path : str or os.PathLike
            Destination file.

        Raises
        ------
        InputError
            If the sample arrays have inconsistent shapes.
        OSError
            If the file cannot be written (nothing is left behind).
        """
        header, data = self._csv_table()
        dest = os.fspath(path)
        directory = os.path.dirname(os.path.abspath(dest))
        fd, tmp = tempfile.mkstemp(dir=directory, prefix="." + os.path.basename(dest) + ".", suffix=".tmp")
        try:
            with os.fdopen(fd, "w", newline="") as fh:
                fh.write(header + "\n")
                np.savetxt(fh, data, fmt="%.17g", delimiter=",")
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, dest)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise


def nan_ratios(n: int) -> dict[str, np.ndarray]:
    """Ratios marked unavailable: NaN, each shape ``(n,)``."""
    return {k: np.full(n, np.nan) for k in LIMIT_KEYS}


def empty_trajectory(
    method: str,
    status: TimingStatus,
    reason: str,
    n: int,
    dt: float,
    iterations: int = 0,
    solver_code: str = "",
) -> Trajectory:
    """A result without samples (``M = 0``, NaN duration and ratios) for ``n`` joints."""
    empty = np.empty((0, n))
    return Trajectory(
        method=method,
        status=status,
        reason=reason,
        t=np.empty(0),
        q=empty,
        qd=empty.copy(),
        qdd=empty.copy(),
        qddd=empty.copy(),
        duration_s=math.nan,
        limit_ratio=nan_ratios(n),
        dt=dt,
        iterations=iterations,
        solver_code=solver_code,
    )
