"""Compliance maps: the diagonal of ``C(q) = J K^-1 J^T`` over a plane of TCP positions.

The paper's section-4.3 map (Fig. 5) fixes ``X = 0.3 m``, sweeps ``Y`` and ``Z``
over ``(-0.3, 0.3) m`` and holds the end attitude at ``(-1.57, 0, 1.57) rad``.
This module computes that map, or the same kind of map over any axis-aligned
plane, for any robot and attitude.

Conventions
-----------
* The plane is normal to one base axis (``plane="x"``, ``"y"`` or ``"z"``) at
  ``offset_m``; the two in-plane coordinates are the other two base axes in
  the order ``x, y, z`` (``x``-plane: ``u = y``, ``v = z``; ``y``-plane:
  ``u = x``, ``v = z``; ``z``-plane: ``u = x``, ``v = y``).
* The attitude is read as roll, pitch, yaw (rad) with
  ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (:func:`models.transforms.rpy_to_matrix`),
  the same convention as the robot file's tool rotation.  The paper's
  ``(-1.57, 0, 1.57)`` thus points the tool z axis along base ``-x``.
* Branch rule ``"home"``: at every grid point, the IK branch whose solution is
  nearest :data:`problems.paper.HOME_Q` (Euclidean distance in joint space,
  each angle shifted by ``2 pi k`` towards the home angle within the limits).
  A branch label such as ``"s+w-e+"`` fixes the branch everywhere; points it
  does not reach are unreachable.  Points without a valid branch are NaN.
* ``C`` is evaluated in batch at the chosen configurations (no Python loop per
  point).  Its diagonal is returned in SI: ``C11..C33`` in m/N, ``C44..C66``
  in rad/(N*m).  ``C`` stays finite at singular poses (it is the stiffness
  ``C^-1`` that blows up there).

Nothing here prints; long computations report progress through a callback.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Callable

import numpy as np

from models import Robot
from models.arm import ArmModel
from models.constants import PLAUSIBLE_POSITION_MAX_M
from models.errors import InputError
from models.ik import IK_REASONS, IKStatus
from models.transforms import rpy_to_matrix
from problems import paper

#: ``progress(stage, done, total)``: called after each chunk (the CLI drives tqdm with it).
ProgressFn = Callable[[str, int, int], None]

#: Valid plane names and their in-plane axes (indices into x, y, z).
PLANE_AXES: dict[str, tuple[int, int, int]] = {"x": (0, 1, 2), "y": (1, 0, 2), "z": (2, 0, 1)}
AXIS_NAMES = ("x", "y", "z")

#: Default grid resolution per in-plane axis (the paper does not give one).
DEFAULT_POINTS = 61
#: Grid points per IK/compliance batch (one progress step per chunk).
CHUNK_POINTS = 20_000
#: Largest accepted grid (points per axis), to keep memory bounded.
MAX_POINTS_PER_AXIS = 2000


#: Names and SI units of the six diagonal elements.
ELEMENT_NAMES = ("C11", "C22", "C33", "C44", "C55", "C66")


class GridCounts:
    """Point counts of a map whose ``branch`` array holds -1 where no IK branch reaches."""

    branch: np.ndarray

    @property
    def n_points(self) -> int:
        return int(self.branch.size)

    @property
    def n_unreachable(self) -> int:
        return int(np.count_nonzero(self.branch < 0))


@dataclass
class ComplianceMap(GridCounts):
    """Diagonal compliance over a plane grid.

    Attributes
    ----------
    robot : str
        Robot name.
    plane : str
        Normal axis of the plane, ``"x"``, ``"y"`` or ``"z"``.
    offset_m : float
        Plane position along its normal, m.
    u_m, v_m : ndarray, shapes (nu,), (nv,)
        In-plane grid coordinates, m (axes :attr:`u_axis`, :attr:`v_axis`).
    rpy_rad : ndarray, shape (3,)
        End attitude (roll, pitch, yaw), rad.
    branch_rule : str
        ``"home"`` or a branch label.
    branch : ndarray of int, shape (nu, nv)
        Branch index used at each point (-1: unreachable).
    q : ndarray, shape (nu, nv, 6)
        Configuration used at each point, rad (NaN where unreachable).
    diag : ndarray, shape (nu, nv, 6)
        ``C11..C66`` (m/N for 1-3, rad/(N*m) for 4-6); NaN where unreachable.
    unreachable_reasons : dict of str to int
        For unreachable points, how many fail for each IK reason (of the fixed
        branch; for rule ``"home"``, the reason of branch 0).
    labels : tuple of str
        The IK family's branch labels (index -> label).
    """

    robot: str
    plane: str
    offset_m: float
    u_m: np.ndarray
    v_m: np.ndarray
    rpy_rad: np.ndarray
    branch_rule: str
    branch: np.ndarray
    q: np.ndarray
    diag: np.ndarray
    unreachable_reasons: dict[str, int] = field(default_factory=dict)
    labels: tuple[str, ...] = ()

    @property
    def u_axis(self) -> str:
        return AXIS_NAMES[PLANE_AXES[self.plane][1]]

    @property
    def v_axis(self) -> str:
        return AXIS_NAMES[PLANE_AXES[self.plane][2]]

    def branches_used(self) -> dict[str, int]:
        """Branch label -> number of grid points that use it."""
        idx, counts = np.unique(self.branch[self.branch >= 0], return_counts=True)
        return {self.labels[int(i)]: int(c) for i, c in zip(idx, counts)}

    def table(self) -> tuple[list[str], np.ndarray]:
        """Rows of ``compliance_map.csv``: u, v (m), branch index (-1 none), C11..C66 (SI)."""
        U, V = np.meshgrid(self.u_m, self.v_m, indexing="ij")
        cols = [f"{self.u_axis}_m", f"{self.v_axis}_m", "branch"] + [
            f"{n}_{'m_per_N' if i < 3 else 'rad_per_Nm'}" for i, n in enumerate(ELEMENT_NAMES)
        ]
        rows = np.column_stack([U.ravel(), V.ravel(), self.branch.ravel(), self.diag.reshape(-1, 6)])
        return cols, rows

    def csv_bytes(self) -> bytes:
        """``compliance_map.csv`` as bytes (17 significant digits, ``nan`` where unreachable).

        Formatted by NumPy in one pass: a million-point map would take many seconds
        through a per-value Python formatter.
        """
        cols, rows = self.table()
        buf = io.StringIO()
        buf.write(",".join(cols) + "\n")
        np.savetxt(buf, rows, fmt="%.17g", delimiter=",")
        return buf.getvalue().encode()

    def summary(self) -> dict:
        """JSON-ready description (ranges in SI)."""
        finite = np.isfinite(self.diag).all(axis=-1)
        rng = {}
        for i, n in enumerate(ELEMENT_NAMES):
            vals = self.diag[..., i][finite]
            rng[n] = [float(vals.min()), float(vals.max())] if vals.size else [None, None]
        return {
            "robot": self.robot,
            "plane": f"{self.plane} = {self.offset_m:g} m",
            f"{self.u_axis}_range_m": [float(self.u_m[0]), float(self.u_m[-1])],
            f"{self.v_axis}_range_m": [float(self.v_m[0]), float(self.v_m[-1])],
            "points": [int(self.u_m.size), int(self.v_m.size)],
            "rpy_rad": [float(v) for v in self.rpy_rad],
            "rpy_convention": "R = Rz(yaw) Ry(pitch) Rx(roll)",
            "branch_rule": self.branch_rule,
            "branches_used": self.branches_used(),
            "n_unreachable": self.n_unreachable,
            "unreachable_reasons": dict(self.unreachable_reasons),
            "diag_range_SI": rng,
            "units": {"C11..C33": "m/N", "C44..C66": "rad/(N*m)"},
        }


def _check_range(key: str, rng: tuple[float, float]) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in rng)
    except (TypeError, ValueError):
        raise InputError(f"compliance map: {key} = {rng!r}; expected two numbers (m)") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise InputError(f"compliance map: {key} = ({lo:g}, {hi:g}); expected finite lo < hi (m)")
    if max(abs(lo), abs(hi)) > PLAUSIBLE_POSITION_MAX_M:
        raise InputError(
            f"compliance map: {key} = ({lo:g}, {hi:g}) m is implausibly large; expected metres (millimetres given?)"
        )
    return lo, hi


def branch_index(rule: str, labels: tuple[str, ...] | None = None) -> int | None:
    """The branch index of ``rule`` among ``labels`` (None for ``"home"``); without labels (the
    robot not known yet) only the type is checked."""
    if not isinstance(rule, str) or not rule:
        raise InputError(f"compliance map: branch = {rule!r}; expected 'home' or a branch label")
    if rule == "home" or labels is None:
        return None
    if rule in labels:
        return labels.index(rule)
    raise InputError(
        f"compliance map: branch = {rule!r}; expected 'home' or one of the robot's branch labels {', '.join(labels)}"
    )


def validate_map_options(
    plane: str,
    offset_m: float,
    u_range_m: tuple[float, float],
    v_range_m: tuple[float, float],
    points: int | tuple[int, int],
    rpy_rad: np.ndarray,
    branch: str,
) -> tuple:
    """Check the options of :func:`compliance_map` (same meaning) and return them normalised:
    ``(offset, (u_lo, u_hi), (v_lo, v_hi), (nu, nv), rpy (3,), branch index or None)``.

    Raises
    ------
    InputError
        Naming the option, its value and what was expected.
    """
    if plane not in PLANE_AXES:
        raise InputError(f"compliance map: plane = {plane!r}; expected one of x, y, z")
    try:
        off = float(offset_m)
    except (TypeError, ValueError):
        raise InputError(f"compliance map: offset = {offset_m!r}; expected a number (m)") from None
    if not np.isfinite(off) or abs(off) > PLAUSIBLE_POSITION_MAX_M:
        raise InputError(f"compliance map: offset = {off!r} m; expected a finite value in metres")
    u_lo, u_hi = _check_range("u range", u_range_m)
    v_lo, v_hi = _check_range("v range", v_range_m)
    nu, nv = (points, points) if np.isscalar(points) else tuple(points)  # type: ignore[misc]
    for name, n in (("points (u)", nu), ("points (v)", nv)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 2 <= n <= MAX_POINTS_PER_AXIS:
            raise InputError(f"compliance map: {name} = {n!r}; expected an integer in [2, {MAX_POINTS_PER_AXIS}]")
    rpy = np.asarray(rpy_rad, dtype=float).reshape(-1)
    if rpy.shape != (3,) or not np.all(np.isfinite(rpy)):
        raise InputError(f"compliance map: rpy = {rpy_rad!r}; expected three finite angles (rad)")
    b_fixed = branch_index(branch)
    return off, (u_lo, u_hi), (v_lo, v_hi), (nu, nv), rpy, b_fixed


def evaluate_grid(
    arm: ArmModel, P: np.ndarray, R: np.ndarray, b_fixed: int | None, chunk: int, progress: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """IK branch and compliance diagonal at every TCP position of ``P`` (N, 3), base frame, at the
    attitude ``R`` (TCP -> base rotation), in batches of ``chunk`` points.

    Returns q (N, 6) rad, the chosen branch (N,) (-1: none), diag C (N, 6) SI, and the IK status
    of the reference branch (N,)."""
    ik = arm.ik
    model = arm.kinematics
    n = len(P)
    q = np.full((n, 6), np.nan)
    chosen = np.full(n, -1, dtype=int)
    diag = np.full((n, 6), np.nan)
    status_ref = np.zeros(n, dtype=int)
    step = max(1, int(chunk))
    for start in range(0, n, step):  # one batch per chunk, not per point
        sl = slice(start, min(n, start + step))
        T = np.zeros((sl.stop - sl.start, 4, 4))
        T[:, :3, :3] = R
        T[:, :3, 3] = P[sl]
        T[:, 3, 3] = 1.0
        qc, ch, sol = ik.nearest(T, paper.HOME_Q, branch=b_fixed)
        if not arm.geometry_is_nominal and (ch >= 0).any():
            # the closed form solves the nominal chain: move onto the model's (identified) geometry
            from problems.compensation import rigid_pose_solve

            qc = qc.copy()
            qc[ch >= 0] = rigid_pose_solve(arm, qc[ch >= 0], T[ch >= 0])
        q[sl], chosen[sl] = qc, ch
        status_ref[sl] = sol.status[:, 0 if b_fixed is None else b_fixed]
        ok = ch >= 0
        if ok.any():
            C = model.C(qc[ok])
            diag[np.arange(sl.start, sl.stop)[ok]] = np.einsum("nii->ni", C.reshape(-1, 6, 6))
        if progress is not None:
            progress("compliance map", sl.stop, n)
    return q, chosen, diag, status_ref


def compliance_map(
    robot: Robot | ArmModel,
    *,
    plane: str = "x",
    offset_m: float = paper.SECTION_4_3_X_M,
    u_range_m: tuple[float, float] = paper.SECTION_4_3_RANGE_M,
    v_range_m: tuple[float, float] = paper.SECTION_4_3_RANGE_M,
    points: int | tuple[int, int] = DEFAULT_POINTS,
    rpy_rad: np.ndarray = paper.SECTION_4_3_RPY,
    branch: str = "home",
    progress: ProgressFn | None = None,
    chunk: int = CHUNK_POINTS,
) -> ComplianceMap:
    """Diagonal compliance ``C11..C66`` over a plane of TCP positions (paper section 4.3).

    Parameters
    ----------
    robot : Robot or ArmModel
        Any arm with an IK family (:func:`models.ik.ik_solver`).
    plane : {"x", "y", "z"}
        Base axis normal to the plane.
    offset_m : float
        Plane position along its normal, m (paper: X = 0.3 m).
    u_range_m, v_range_m : (float, float)
        In-plane ranges, m, both ends included (see module docstring for axes).
    points : int or (int, int)
        Grid points per in-plane axis.
    rpy_rad : array_like, shape (3,)
        End attitude roll, pitch, yaw (rad), ``R = Rz(yaw) Ry(pitch) Rx(roll)``.
    branch : str
        ``"home"`` (per point, nearest :data:`problems.paper.HOME_Q`) or a label.
    progress : callable, optional
        ``progress("compliance map", done_points, total_points)`` after each chunk.
    chunk : int
        Points per batch.

    Returns
    -------
    ComplianceMap

    Raises
    ------
    InputError
        Bad plane, range, grid size, attitude or branch (the message names the key).
    """
    off, (u_lo, u_hi), (v_lo, v_hi), (nu, nv), rpy, b_fixed = validate_map_options(
        plane, offset_m, u_range_m, v_range_m, points, rpy_rad, branch
    )

    from models.arm import load_arm

    arm = load_arm(robot)  # a Robot (nominal model) or an ArmModel (identified)
    robot = arm.nominal
    labels = arm.ik.labels
    b_fixed = branch_index(branch, labels)
    u = np.linspace(u_lo, u_hi, int(nu))
    v = np.linspace(v_lo, v_hi, int(nv))
    shape = (u.size, v.size)
    P = _plane_points(plane, off, u, v)
    q, chosen, diag, status_ref = evaluate_grid(arm, P, rpy_to_matrix(rpy), b_fixed, chunk, progress)
    return ComplianceMap(
        robot=robot.name,
        plane=plane,
        offset_m=off,
        u_m=u,
        v_m=v,
        rpy_rad=rpy,
        branch_rule=branch,
        branch=chosen.reshape(shape),
        q=q.reshape(shape + (6,)),
        diag=diag.reshape(shape + (6,)),
        unreachable_reasons=_unreachable_reasons(chosen, status_ref),
        labels=labels,
    )


def _plane_points(plane: str, off: float, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The grid's TCP positions (U * V, 3), base frame, m: ``u`` (U,) and ``v`` (V,) along the
    plane's in-plane axes (``u`` slowest), ``off`` along its normal."""
    U, V = np.meshgrid(u, v, indexing="ij")
    n_axis, u_axis, v_axis = PLANE_AXES[plane]
    P = np.empty((U.size, 3))
    P[:, n_axis] = off
    P[:, u_axis] = U.ravel()
    P[:, v_axis] = V.ravel()
    return P


def _unreachable_reasons(chosen: np.ndarray, status_ref: np.ndarray) -> dict[str, int]:
    """IK reason -> the number of grid points without a solution (``chosen`` < 0), from the IK
    status codes ``status_ref`` (both shape (P,))."""
    reasons: dict[str, int] = {}
    bad = chosen < 0
    if bad.any():
        codes, counts = np.unique(status_ref[bad], return_counts=True)
        for c, k in zip(codes, counts):
            reasons[IK_REASONS[IKStatus.from_code(c)]] = int(k)
    return reasons
