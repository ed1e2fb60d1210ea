"""Simulating a measurement campaign: poses, loads, times and temperatures, noise, outliers.

:class:`CampaignPart` is a part of :class:`~problems.virtual.robot.VirtualRobot`: it reads
the ``[campaign]``, ``[noise]`` and ``[temperature]`` tables, draws the outliers of ``[effects.outliers]``,
measures the rows with the robot's noise-free measurement and returns them as
:class:`~problems.measurements.Measurements`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import numpy as np

from ..measurements import Measurements
from .config import (
    DEFAULT_CAMPAIGN,
    DEFAULT_NOISE,
    SIM_MAX_ROWS,
    SimConfigError,
    at_least,
    flag,
    integer,
    magnitudes,
    number,
    table,
)
from .geometry import rotvecs

#: Candidate poses drawn per requested pose when sampling the workspace.
SIM_POSE_OVERSAMPLING = 40
#: Jacobian condition number above which a sampled pose is rejected (too close to
#: a singularity to be a sensible measurement pose).
SIM_MAX_JACOBIAN_COND = 200.0


class _CampaignPlan(NamedTuple):
    """The validated ``[campaign]`` settings that shape the rows.

    Attributes
    ----------
    poses : int
        Number of measurement poses (>= 1).
    unloaded_rows, loaded_rows, repeats : int
        Rows per pose: with zero wrench, with a random load, and repeated rows.
    force_magnitudes_N : ndarray, shape (M,)
        Force magnitudes to draw from, N.
    moment_magnitudes_Nm : ndarray, shape (K,)
        Moment magnitudes to draw from, N*m.
    directions : {"random", "axes", "down"}
        How force directions are drawn (base frame).
    r_min_m, z_min_m : float
        Workspace of the sampled poses: flange at least ``r_min_m`` from the base z axis
        and above ``z_min_m``, m, base frame.
    """

    poses: int
    unloaded_rows: int
    loaded_rows: int
    repeats: int
    force_magnitudes_N: np.ndarray
    moment_magnitudes_Nm: np.ndarray
    directions: str
    r_min_m: float
    z_min_m: float


class CampaignPart:
    """The measurement campaign of the configuration (a part of :class:`VirtualRobot`)."""

    def sample_poses(
        self,
        n: int,
        rng: np.random.Generator,
        r_min: float = 0.25,
        z_min: float = -0.2,
        max_cond: float = SIM_MAX_JACOBIAN_COND,
    ) -> np.ndarray:
        """Random joint configurations with the TCP in a sensible workspace, (n, 6) rad.

        Joints are drawn uniformly in [-pi, pi] (within the limits); a pose is kept when
        the flange is at least ``r_min`` from the base axis, above ``z_min``, and the
        nominal Jacobian condition number is below :data:`SIM_MAX_JACOBIAN_COND`.
        """
        from models.symbolic import KinematicModel

        km = KinematicModel(self.robot)
        fk = km.kinetostatics
        lo = np.maximum(self.robot.q_min, -np.pi)
        hi = np.minimum(self.robot.q_max, np.pi)
        kept: list[np.ndarray] = []
        total = 0
        while sum(len(k) for k in kept) < n:
            m = max(n * SIM_POSE_OVERSAMPLING, 200)
            q = rng.uniform(lo, hi, (m, 6))
            p, _R, J, _C = fk.map(m, "thread", 2)(q.T)
            p = np.asarray(p).T
            J = np.asarray(J).reshape(6, m, 6).transpose(1, 0, 2)
            ok = (np.hypot(p[:, 0], p[:, 1]) >= r_min) & (p[:, 2] >= z_min)
            ok &= np.linalg.cond(J) < max_cond
            q = q[ok]
            kept.append(q)
            total += m
            if total > 200 * max(n, 10) * SIM_POSE_OVERSAMPLING:
                raise SimConfigError(
                    f"{self.where}: cannot find {n} poses in the workspace "
                    f"(r >= {r_min} m, z >= {z_min} m); relax r_min_m/z_min_m"
                )
        return np.vstack(kept)[:n]

    def campaign(self, progress: Callable[[int, int], None] | None = None, seed: int | None = None) -> Measurements:
        """Simulate the measurement campaign of the configuration.

        ``seed`` overrides the seed of the campaign's random parts (poses, loads,
        noise, outliers) -- a second campaign of the same robot (held-out data) --
        while the robot's realised parameters stay those of the configuration's seed.

        Returns
        -------
        Measurements
            Rows in measurement order, with ``point``, ``t`` and (if configured)
            ``temperature`` and ``sigma``; positions in the measurement frame.  With
            ``[campaign] orientation = true`` also ``rotation`` (N, 3): the orientation
            of the measured frame in the measurement frame as a rotation vector, rad
            (noise ``[noise] sigma_rad``; with ``sigma_rot_column`` also ``sigma_rot``).
            :attr:`outlier_rows` holds the indices of the rows given gross errors (positions
            only; the orientation of those rows is not corrupted).
        """
        # One generator, drawn in this order: poses, loads, temperature noise,
        # measurement noise, outliers, orientation noise (last, so that switching the
        # orientation on leaves every other column of the campaign unchanged).
        rng = np.random.default_rng(self.seed + 1 if seed is None else seed)
        camp = {**DEFAULT_CAMPAIGN, **table(self.where, self.config, "campaign", set(DEFAULT_CAMPAIGN))}
        plan = self._campaign_plan(camp)
        orientation = flag(f"{self.where}: [campaign]", "orientation", camp["orientation"])
        sigma_rad, rot_column = self._rotation_noise_config(orientation)
        q_poses = self.sample_poses(plan.poses, rng, plan.r_min_m, plan.z_min_m)
        q, F, pts = self._campaign_loads(q_poses, plan, rng)
        n = len(q)
        t, temperature = self._campaign_times(camp, n, rng)
        if orientation:
            p, R = self._measure_pose(q, F, t, temperature)
        else:
            p, R = self.measure(q, F, t, temperature), None
        p, sig_col = self._campaign_noise(p, rng)
        self._campaign_outliers(p, rng)
        extra: dict[str, Any] = {}
        if R is not None:
            extra["rotation"] = rotvecs(self.campaign_rotation_noise(R, sigma_rad, rng))
            if rot_column:
                extra["sigma_rot"] = np.full((n, 3), sigma_rad)
        if progress is not None:
            progress(n, n)
        return Measurements(
            q=q,
            wrench=F,
            p=p,
            t=t,
            point=np.array(pts),
            temperature=temperature,
            sigma=sig_col,
            source="virtual robot",
            **extra,
        )

    def _rotation_noise_config(self, orientation: bool) -> tuple[float, bool]:
        """The orientation keys of ``[noise]``: ``sigma_rad`` (rad, >= 0; > 0 with the column)
        and ``sigma_rot_column`` (needs ``[campaign] orientation = true``)."""
        ncfg = table(self.where, self.config, "noise", set(DEFAULT_NOISE))
        nw = f"{self.where}: [noise]"
        sigma = number(nw, "sigma_rad", ncfg.get("sigma_rad", DEFAULT_NOISE["sigma_rad"]))
        column = flag(nw, "sigma_rot_column", ncfg.get("sigma_rot_column", DEFAULT_NOISE["sigma_rot_column"]))
        at_least(
            nw,
            "sigma_rad",
            sigma,
            0.0,
            strict=column,
            what="(a standard deviation, rad" + ("; the sigma_rot column needs it > 0)" if column else ")"),
        )
        if column and not orientation:
            raise SimConfigError(
                f"{nw}: key 'sigma_rot_column' = true needs [campaign] orientation = true "
                "(there is no orientation to give a sigma for)"
            )
        return sigma, column

    @staticmethod
    def campaign_rotation_noise(R: np.ndarray, sigma_rad: float, rng: np.random.Generator) -> np.ndarray:
        """Orientation noise: ``R exp([w]x)``, ``w ~ N(0, sigma_rad^2 I)`` (measured frame).

        Parameters
        ----------
        R : ndarray, shape (N, 3, 3)
            Noise-free orientations, measurement frame.
        sigma_rad : float
            Standard deviation of each rotation-vector component, rad.
        rng : Generator
            Draws N x 3 normals.
        """
        from scipy.spatial.transform import Rotation

        w = rng.normal(0.0, sigma_rad, (len(R), 3))
        return R @ Rotation.from_rotvec(w).as_matrix()

    def _campaign_plan(self, camp: Mapping[str, Any]) -> _CampaignPlan:
        """Validate the row-shaping keys of ``camp``, the ``[campaign]`` table merged over
        :data:`DEFAULT_CAMPAIGN` (``dt_s`` is read later, by :meth:`_campaign_times`)."""
        cw = f"{self.where}: [campaign]"
        n_poses = integer(cw, "poses", camp["poses"], 1)
        n_un = integer(cw, "unloaded_rows", camp["unloaded_rows"], 0)
        n_ld = integer(cw, "loaded_rows", camp["loaded_rows"], 0)
        n_rep = integer(cw, "repeats", camp["repeats"], 0)
        if n_un + n_ld == 0:
            raise SimConfigError(
                f"{cw}: keys 'unloaded_rows' and 'loaded_rows' are both 0; a pose needs at least one row"
            )
        n_rows = n_poses * (n_un + n_ld + n_rep)
        if n_rows > SIM_MAX_ROWS:
            raise SimConfigError(
                f"{cw}: {n_poses} poses x {n_un + n_ld + n_rep} rows = {n_rows} rows, more than "
                f"the cap of {SIM_MAX_ROWS} rows (SIM_MAX_ROWS)"
            )
        mags = magnitudes(cw, "force_magnitudes_N", camp["force_magnitudes_N"])
        mmags = magnitudes(cw, "moment_magnitudes_Nm", camp["moment_magnitudes_Nm"])
        dirs = camp["directions"]
        if dirs not in ("random", "axes", "down"):
            raise SimConfigError(f"{cw}: key 'directions' must be 'random', 'axes' or 'down', got {dirs!r}")
        dt = number(cw, "dt_s", camp["dt_s"])
        at_least(cw, "dt_s", dt, 0.0, strict=True, what="s (the time between rows)")
        r_min = number(cw, "r_min_m", camp["r_min_m"])
        at_least(cw, "r_min_m", r_min, 0.0)
        return _CampaignPlan(
            n_poses, n_un, n_ld, n_rep, mags, mmags, dirs, r_min, number(cw, "z_min_m", camp["z_min_m"])
        )

    def _campaign_loads(
        self, q_poses: np.ndarray, plan: _CampaignPlan, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """The rows of the campaign: per pose, unloaded rows, random loads, then repeats.

        Parameters
        ----------
        q_poses : ndarray, shape (P, 6)
            Commanded joint angles of the poses, rad.
        plan : _CampaignPlan
        rng : Generator
            Draws the loads pose by pose (see :meth:`_random_load`).

        Returns
        -------
        q : ndarray, shape (N, 6)
            Commanded joint angles of each row, rad.
        F : ndarray, shape (N, 6)
            Wrench ``[f; m]`` on the TCP of each row, N and N*m, base frame.
        points : list of str
            Pose label of each row (``P0001``, ...).
        """
        qs, Fs, pts = [], [], []
        for k in range(plan.poses):
            rows_F = [np.zeros(6)] * plan.unloaded_rows
            for _ in range(plan.loaded_rows):
                rows_F.append(self._random_load(plan, rng))
            rows_F = rows_F + [rows_F[i % len(rows_F)] for i in range(plan.repeats)]
            for Fk in rows_F:
                qs.append(q_poses[k])
                Fs.append(Fk)
                pts.append(f"P{k + 1:04d}")
        return np.array(qs), np.array(Fs), pts

    @staticmethod
    def _random_load(plan: _CampaignPlan, rng: np.random.Generator) -> np.ndarray:
        """One random load ``[f; m]``, shape (6,), N and N*m, base frame.

        Draws, in order: the force magnitude, the force direction (3 normals for
        ``random``, an axis and a sign for ``axes``, nothing for ``down``), the moment
        magnitude and the moment direction (3 normals).
        """
        mag = rng.choice(plan.force_magnitudes_N)
        if plan.directions == "random":
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
        elif plan.directions == "axes":
            u = np.zeros(3)
            u[rng.integers(3)] = rng.choice([-1.0, 1.0])
        else:
            u = np.array([0.0, 0.0, -1.0])
        mm = rng.choice(plan.moment_magnitudes_Nm)
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        return np.concatenate([mag * u, mm * v])

    def _campaign_times(
        self, camp: Mapping[str, Any], n: int, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Measurement times and, with a ``[temperature]`` table, temperatures of the rows.

        Parameters
        ----------
        camp : mapping
            The ``[campaign]`` table merged over :data:`DEFAULT_CAMPAIGN` (``dt_s`` is read).
        n : int
            Number of rows N.
        rng : Generator
            Draws N temperature-noise normals (only with a ``[temperature]`` table).

        Returns
        -------
        t : ndarray, shape (N,)
            Time of each row, s (``dt_s`` apart, from 0).
        temperature : ndarray, shape (N,) or None
            Warm-up curve ``start + (end - start)(1 - exp(-t/tau))`` plus noise, deg C.
        """
        dt = number(f"{self.where}: [campaign]", "dt_s", camp["dt_s"])
        t = np.arange(n) * dt
        tcfg = table(self.where, self.config, "temperature", {"start_C", "end_C", "time_constant_s", "noise_C"})
        if not tcfg:
            return t, None
        tw = f"{self.where}: [temperature]"
        t0 = number(tw, "start_C", tcfg.get("start_C", 20.0))
        t1 = number(tw, "end_C", tcfg.get("end_C", t0))
        tau = number(tw, "time_constant_s", tcfg.get("time_constant_s", max(t[-1], 1.0) / 2))
        at_least(tw, "time_constant_s", tau, 0.0, strict=True, what="s")
        noise_c = number(tw, "noise_C", tcfg.get("noise_C", 0.0))
        at_least(tw, "noise_C", noise_c, 0.0, what="(a standard deviation, deg C)")
        temperature = t0 + (t1 - t0) * (1 - np.exp(-t / tau))
        temperature = temperature + rng.normal(0, noise_c, n)
        return t, temperature

    def _campaign_noise(self, p: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
        """Add the ``[noise]`` Gaussian measurement noise.

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Noise-free measured positions, measurement frame, m.
        rng : Generator
            Draws N x 3 normals.

        Returns
        -------
        p : ndarray, shape (N, 3)
            Noisy positions (a new array), measurement frame, m.
        sigma : ndarray, shape (N,) or None
            The per-axis noise sigma of each row, m, if ``sigma_column`` is set.
        """
        ncfg = table(self.where, self.config, "noise", set(DEFAULT_NOISE))
        nw = f"{self.where}: [noise]"
        sigma = number(nw, "sigma_m", ncfg.get("sigma_m", DEFAULT_NOISE["sigma_m"]))
        column = flag(nw, "sigma_column", ncfg.get("sigma_column", DEFAULT_NOISE["sigma_column"]))
        at_least(
            nw,
            "sigma_m",
            sigma,
            0.0,
            strict=column,
            what="(a standard deviation, m" + ("; the sigma column needs it > 0)" if column else ")"),
        )
        p = p + rng.normal(0, sigma, p.shape)
        sig_col = np.full(len(p), sigma) if column else None
        return p, sig_col

    def _campaign_outliers(self, p: np.ndarray, rng: np.random.Generator) -> None:
        """``[effects.outliers]``: add gross errors to some rows of ``p`` in place.

        Sets :attr:`outlier_rows` (sorted row indices; empty without the table).  Each
        outlier is a random direction times ``magnitude_m`` times a factor in [1, 2)
        (:attr:`outlier_fraction` and :attr:`outlier_magnitude`, realised and checked with the robot).

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Measured positions, measurement frame, m; modified in place.
        rng : Generator
            Draws the rows, then K x 3 normals (directions), then K uniforms (factors).
        """
        self.outlier_rows = np.zeros(0, dtype=int)
        if not self.simulated("outliers"):
            return
        n = len(p)
        frac, mag = self.outlier_fraction, self.outlier_magnitude
        k = max(1, round(frac * n))
        idx = np.sort(rng.choice(n, size=k, replace=False))
        u = rng.normal(size=(k, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        p[idx] += u * mag * rng.uniform(1.0, 2.0, (k, 1))
        self.outlier_rows = idx
