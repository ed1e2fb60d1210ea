"""Realising the simulated effects: the true parameters of each simulated table.

:class:`EffectPart` is a part of :class:`~problems.virtual.robot.VirtualRobot`.
Each of its ``_realise_*`` methods realises the physics of the model effects it names in its
:func:`~problems.virtual.registry.simulates` decorator, from that table of the configuration
(which table is the effects' declaration, ``Effect.simulation``; the decorator lists the
table's keys).  A method receives the checked table (``None`` when an ``[effects.NAME]``
table is not given), the source and table for messages and the realisation's random
generator, and sets the realised parameters as attributes of the robot (stiffness,
registration and measured point, geometric errors, masses, hardening curve, dead band,
beams, joint tilts, drift, thermal expansion, periodic joint-error terms, outliers).  The tables are
realised in the order of the methods below (the order of the checks and the random draws).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from models.transforms import rotvec_to_matrix

from .config import (
    SIM_JOINT_ERROR_MAX_AMPLITUDE_RAD,
    SIM_JOINT_ERROR_MAX_HARMONIC,
    SimConfigError,
    at_least,
    flag,
    joint_list,
    number,
    table,
    vector,
)
from .registry import realisations, simulates

#: A table as a realisation receives it (None: an ``[effects.NAME]`` table not given).
Table = Mapping[str, Any] | None


class EffectPart:
    """The realisation of every configured effect (a part of :class:`VirtualRobot`)."""

    def _realise_declared(self, cfg: Mapping[str, Any], rng: np.random.Generator) -> None:
        """Realise the declared model from its top-level tables (always; defaults when absent)."""
        for r in realisations(top_level=True):
            t = table(self.where, cfg, r.table, set(r.keys))
            getattr(self, r.method)(t, f"{self.where}: [{r.table}]", rng)
        self._simulated = {name for r in realisations(top_level=True) for name in r.effects}

    def _realise(self, rng: np.random.Generator) -> None:
        """Realise the true parameters of every ``[effects.NAME]`` table (in the registry's order).

        Only the geometric errors draw random numbers; the order is the order of the checks
        (the first malformed effect is the one reported).
        """
        self.da = np.zeros(6)
        self.dalpha = np.zeros(6)
        self.dd = np.zeros(6)
        self.dtheta = np.zeros(6)
        self.dbeta = np.zeros(6)
        for r in realisations(top_level=False):
            name = next((s for s in r.spellings if s in self.effects), None)
            if name is not None:
                self._simulated |= set(r.effects or (r.table,))
            getattr(self, r.method)(
                None if name is None else self.effects[name], f"{self.where}: [effects.{name or r.table}]", rng
            )

    def simulated(self, name: str) -> bool:
        """Whether the physics of model effect ``name`` (or the disturbance ``outliers``) is simulated:
        its table is configured (the declared model's always is)."""
        return name in self._simulated

    @simulates("joint_springs", keys={"scale"})
    def _realise_stiffness(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """The declared joint springs: :attr:`k_true` (6,) N*m/rad, the robot file's stiffness times
        ``scale`` (a number or 6)."""
        scale = vector(ew, "scale", e.get("scale", 1.0), 6)
        at_least(ew, "scale", scale if isinstance(e.get("scale"), list) else scale[0], 0.0, strict=True)
        self.k_true = self.robot.stiffness * scale

    @simulates(
        "registration",
        "measured_point",
        keys={"registered", "base2meas_xyz_m", "base2meas_rotvec_rad", "measured_point_m"},
    )
    def _realise_registration(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """The declared registration and measured point: :attr:`registered`, :attr:`R_reg` (3, 3) and
        :attr:`t_reg` (3,) m (base frame -> measurement frame), :attr:`p_tool` (3,) m, flange frame
        (registered data: identity, zero and the robot file's TCP)."""
        robot = self.robot
        self.registered = flag(ew, "registered", e.get("registered", False))
        if self.registered:
            self.R_reg, self.t_reg = np.eye(3), np.zeros(3)
            self.p_tool = robot.tcp2flange[:3, 3].copy()
        else:
            self.R_reg = rotvec_to_matrix(
                vector(ew, "base2meas_rotvec_rad", e.get("base2meas_rotvec_rad", [0.02, -0.01, 0.6]), 3, False)
            )
            self.t_reg = vector(ew, "base2meas_xyz_m", e.get("base2meas_xyz_m", [1.5, -0.5, 0.2]), 3, False)
            self.p_tool = vector(ew, "measured_point_m", e.get("measured_point_m", [0.02, -0.015, 0.06]), 3, False)

    @simulates("joint_offset", keys={"dtheta_rad"})
    def _realise_joint_offset(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Joint offsets: add the zero offsets to :attr:`dtheta`, shape (6,), rad."""
        if e is not None:
            self.dtheta += vector(ew, "dtheta_rad", e.get("dtheta_rad", 1e-3), 6)

    @simulates(
        "geometric", keys={"sigma_length_m", "sigma_angle_rad", "da_m", "dalpha_rad", "dd_m", "dtheta_rad", "dbeta_rad"}
    )
    def _realise_geometric(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Geometric errors: DH errors, given or drawn from ``rng``.

        Adds to :attr:`da`, :attr:`dd` (m), :attr:`dalpha`, :attr:`dtheta` and :attr:`dbeta`
        (rad), each shape (6,); ``dbeta`` (Hayati) only on joints with a parallel next axis
        (not joint 6).  Draws, in this order, da, dd, dalpha, dtheta, dbeta (6 normals each,
        for every one not given).
        """
        if e is None:
            return
        sl = number(ew, "sigma_length_m", e.get("sigma_length_m", 5e-4))
        sa = number(ew, "sigma_angle_rad", e.get("sigma_angle_rad", 1e-3))
        at_least(ew, "sigma_length_m", sl, 0.0, what="(a standard deviation, m)")
        at_least(ew, "sigma_angle_rad", sa, 0.0, what="(a standard deviation, rad)")
        self.da += vector(ew, "da_m", e["da_m"], 6) if "da_m" in e else rng.normal(0, sl, 6)
        self.dd += vector(ew, "dd_m", e["dd_m"], 6) if "dd_m" in e else rng.normal(0, sl, 6)
        self.dalpha += vector(ew, "dalpha_rad", e["dalpha_rad"], 6) if "dalpha_rad" in e else rng.normal(0, sa, 6)
        self.dtheta += vector(ew, "dtheta_rad", e["dtheta_rad"], 6) if "dtheta_rad" in e else rng.normal(0, sa, 6)
        par = np.abs(np.sin(self.robot.alpha)) < 1e-6
        par[5] = False
        beta = vector(ew, "dbeta_rad", e["dbeta_rad"], 6) if "dbeta_rad" in e else rng.normal(0, sa, 6)
        self.dbeta += np.where(par, beta, 0.0)

    @simulates("gravity", keys={"masses_kg", "coms_m", "mass_scale", "payload_kg", "payload_com_m"})
    def _realise_gravity(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Self-weight: link masses and COMs (robot file, overrides, or a generic set).

        Sets :attr:`masses` (6,) kg, :attr:`coms` (6, 3) m in link frame i, :attr:`payload`
        kg and :attr:`payload_com` (3,) m in the flange frame; zeros without the effect.
        """
        r = self.robot
        self.masses = np.zeros(6)
        self.coms = np.zeros((6, 3))
        if e is None:
            self.payload, self.payload_com = 0.0, np.zeros(3)
            return
        if "masses_kg" in e:
            self.masses = vector(ew, "masses_kg", e["masses_kg"], 6)
            at_least(ew, "masses_kg", self.masses, 0.0)
        elif r.has_masses:
            self.masses = r.masses.copy()
        else:
            self.masses = 12.0 * np.hypot(r.a, r.d) + 0.5  # generic: 12 kg/m plus 0.5 kg per joint
        if "coms_m" in e:
            c = e["coms_m"]
            if not isinstance(c, list) or len(c) != 6:
                raise SimConfigError(f"{ew}: key 'coms_m' must be a list of 6 [x, y, z] lists")
            self.coms = np.array([vector(ew, f"coms_m[{i}]", ci, 3, False) for i, ci in enumerate(c)])
        elif r.has_masses:
            self.coms = r.coms.copy()
        else:  # generic: half way back along the link (in link frame i, standard DH: -a/2 on x)
            self.coms = np.column_stack([-r.a / 2.0, np.zeros(6), np.zeros(6)])
        mass_scale = number(ew, "mass_scale", e.get("mass_scale", 1.0))
        at_least(ew, "mass_scale", mass_scale, 0.0)
        self.masses = self.masses * mass_scale
        self.payload = number(ew, "payload_kg", e.get("payload_kg", 0.0))
        at_least(ew, "payload_kg", self.payload, 0.0)
        self.payload_com = vector(ew, "payload_com_m", e.get("payload_com_m", [0.0, 0.0, 0.05]), 3, False)

    @simulates("lost_motion", keys={"backlash_rad", "smoothing_Nm"})
    def _realise_lost_motion(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Lost motion: :attr:`backlash` (6,) rad (half dead band) and
        :attr:`backlash_smoothing` N*m (0: a hard sign)."""
        if e is not None:
            self.backlash = vector(ew, "backlash_rad", e.get("backlash_rad", 2e-4), 6)
            at_least(ew, "backlash_rad", self.backlash, 0.0, what="(half the dead band)")
            self.backlash_smoothing = number(ew, "smoothing_Nm", e.get("smoothing_Nm", 0.0))
            at_least(ew, "smoothing_Nm", self.backlash_smoothing, 0.0)

    @simulates("stiffness_hardening", keys={"model", "knee_torque_Nm", "stiffness_ratio", "beta_per_Nm"})
    def _realise_stiffness_hardening(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Stiffness hardening: :attr:`hard_model`, :attr:`knee` (6,) N*m,
        :attr:`hard_ratio` (6,) and :attr:`hard_beta` (6,) 1/(N*m)."""
        if e is None:
            return
        self.hard_model = e.get("model", "two_slope")
        if self.hard_model not in ("two_slope", "smooth"):
            raise SimConfigError(f"{ew}: key 'model' must be 'two_slope' or 'smooth', got {self.hard_model!r}")
        self.knee = vector(ew, "knee_torque_Nm", e.get("knee_torque_Nm", 20.0), 6)
        self.hard_ratio = vector(ew, "stiffness_ratio", e.get("stiffness_ratio", 2.0), 6)
        self.hard_beta = vector(ew, "beta_per_Nm", e.get("beta_per_Nm", 0.01), 6)
        at_least(ew, "knee_torque_Nm", self.knee, 0.0)
        at_least(ew, "stiffness_ratio", self.hard_ratio, 0.0, strict=True)
        at_least(ew, "beta_per_Nm", self.hard_beta, 0.0)

    @simulates("load_offset", keys={"r_tool_m"})
    def _realise_load_offset(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Load offset: :attr:`r_tool` (3,) m, TCP frame, where the wrench's force acts (zeros
        without the effect)."""
        self.r_tool = (
            np.zeros(3) if e is None else vector(ew, "r_tool_m", e.get("r_tool_m", [0.0, 0.03, 0.05]), 3, False)
        )

    @simulates("link_compliance", keys={"links", "EI_Nm2", "GJ_Nm2"})
    def _realise_link_compliance(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Link compliance: :attr:`beam_links` (0-based joints), :attr:`EI` and :attr:`GJ` (one per
        link), N*m^2."""
        if e is None:
            return
        links = joint_list(ew, e.get("links", [2, 3]))
        self.beam_links = [x - 1 for x in links]
        self.EI = vector(ew, "EI_Nm2", e.get("EI_Nm2", 2.0e5), len(links))
        self.GJ = vector(ew, "GJ_Nm2", e.get("GJ_Nm2", 1.5e5), len(links))
        at_least(ew, "EI_Nm2", self.EI, 0.0, strict=True)
        at_least(ew, "GJ_Nm2", self.GJ, 0.0, strict=True)

    @simulates("joint_tilt", keys={"joints", "compliance_x_rad_per_Nm", "compliance_y_rad_per_Nm"})
    def _realise_joint_tilt(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Joint tilt: :attr:`tilt_joints` (0-based), :attr:`tilt_cx` and :attr:`tilt_cy` (one per
        joint listed), rad/(N*m), about x and y of the joint's DH frame (the one whose z is its
        axis); :attr:`tilt_masses` (6,) kg and :attr:`tilt_coms` (6, 3) m, link frame j, the
        weight the joints carry: the ``[effects.gravity]`` links when that table is given (its
        payload too), else the robot file's (zeros without masses)."""
        if e is None:
            return
        joints = joint_list(ew, e.get("joints", [2, 3]), "joints")
        self.tilt_joints = [x - 1 for x in joints]
        self.tilt_cx = vector(ew, "compliance_x_rad_per_Nm", e.get("compliance_x_rad_per_Nm", 5e-6), len(joints))
        self.tilt_cy = vector(ew, "compliance_y_rad_per_Nm", e.get("compliance_y_rad_per_Nm", 5e-6), len(joints))
        at_least(ew, "compliance_x_rad_per_Nm", self.tilt_cx, 0.0)
        at_least(ew, "compliance_y_rad_per_Nm", self.tilt_cy, 0.0)
        r = self.robot
        if self.simulated("gravity"):
            self.tilt_masses, self.tilt_coms = self.masses.copy(), self.coms.copy()
        elif r.has_masses:
            self.tilt_masses, self.tilt_coms = r.masses.copy(), r.coms.copy()
        else:
            self.tilt_masses, self.tilt_coms = np.zeros(6), np.zeros((6, 3))

    @simulates("drift", keys={"rate_m_per_h", "accel_m_per_h2"})
    def _realise_drift(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Drift of the instrument: :attr:`drift_rate` (3,) m/s and :attr:`drift_acc` (3,) m/s^2,
        measurement frame."""
        if e is not None:
            self.drift_rate = vector(ew, "rate_m_per_h", e.get("rate_m_per_h", [1e-4, -5e-5, 8e-5]), 3, False) / 3600.0
            self.drift_acc = (
                vector(ew, "accel_m_per_h2", e.get("accel_m_per_h2", [0.0, 0.0, 0.0]), 3, False) / 3600.0**2
            )

    @simulates("thermal", keys={"alpha_per_K", "links", "reference_C"})
    def _realise_thermal(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Thermal expansion: :attr:`th_alpha` 1/K, :attr:`th_links` (0-based joints whose a and d
        expand) and :attr:`th_ref` deg C."""
        if e is None:
            return
        self.th_alpha = number(ew, "alpha_per_K", e.get("alpha_per_K", 2.3e-5))
        links = joint_list(ew, e.get("links", [2, 3]))
        self.th_links = [x - 1 for x in links]
        self.th_ref = number(ew, "reference_C", e.get("reference_C", 20.0))

    @simulates("joint_error_map", keys={"joint", "amplitude_rad", "harmonic", "phase_rad"})
    def _realise_joint_error(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Periodic joint transmission errors (``[effects.eccentricity]``, or its spelling
        ``[effects.joint_error_map]``), a sum of terms ``amplitude sin(harmonic q_c[joint] + phase)``.

        Sets, one entry per term (K terms; K = 0 without the effect): :attr:`ecc_joint`
        (K,) int, 0-based joint; :attr:`ecc_amp` (K,) rad; :attr:`ecc_harm` (K,) cycles per
        revolution; :attr:`ecc_phase` (K,) rad.  Each key is a number (applied to every term)
        or a list with one entry per term; lists must have equal lengths.
        """
        self.ecc_joint = np.zeros(0, dtype=int)
        self.ecc_amp = np.zeros(0)
        self.ecc_harm = np.zeros(0)
        self.ecc_phase = np.zeros(0)
        if e is None:
            return
        raw = {
            "joint": e.get("joint", 1),
            "amplitude_rad": e.get("amplitude_rad", 1e-3),
            "harmonic": e.get("harmonic", 2),
            "phase_rad": e.get("phase_rad", 0.3),
        }
        for key, v in raw.items():
            if isinstance(v, list) and not v:
                raise SimConfigError(
                    f"{ew}: key '{key}' must be a number or a non-empty list (one entry per term), got {v!r}"
                )
        lengths = {key: len(v) for key, v in raw.items() if isinstance(v, list)}
        if len(set(lengths.values())) > 1:
            shown = ", ".join(f"'{k}' has {n}" for k, n in lengths.items())
            raise SimConfigError(
                f"{ew}: the lists must have one entry per term, all of the same length; {shown} "
                "entries (a number applies to every term)"
            )
        k_terms = next(iter(lengths.values()), 1)

        def entries(key: str) -> list[tuple[str, Any]]:
            v = raw[key]
            if isinstance(v, list):
                return [(f"{key}[{i}]", x) for i, x in enumerate(v)]
            return [(key, v)] * k_terms

        joints = []
        for k, j in entries("joint"):
            if isinstance(j, bool) or not isinstance(j, int) or not 1 <= j <= 6:
                raise SimConfigError(f"{ew}: key '{k}' must be a joint number 1..6, got {j!r}")
            joints.append(j - 1)
        amp = np.array([number(ew, k, v) for k, v in entries("amplitude_rad")])
        harm = np.array([number(ew, k, v) for k, v in entries("harmonic")])
        phase = np.array([number(ew, k, v) for k, v in entries("phase_rad")])
        amax, hmax = SIM_JOINT_ERROR_MAX_AMPLITUDE_RAD, SIM_JOINT_ERROR_MAX_HARMONIC
        for (k, _v), a in zip(entries("amplitude_rad"), amp):
            if abs(a) > amax:
                raise SimConfigError(
                    f"{ew}: key '{k}' must be within [-{amax:g}, {amax:g}] rad (a transmission "
                    f"error; a constant offset is [effects.joint_offset]), got {a:g}"
                )
        for (k, _v), h in zip(entries("harmonic"), harm):
            if not 0.0 < h <= hmax:
                raise SimConfigError(
                    f"{ew}: key '{k}' must be > 0 and <= {hmax:g} (cycles per revolution of the joint), got {h:g}"
                )
        self.ecc_joint = np.array(joints, dtype=int)
        self.ecc_amp, self.ecc_harm, self.ecc_phase = amp, harm, phase

    @simulates(keys={"fraction", "magnitude_m"}, disturbance="outliers")
    def _realise_outliers(self, e: Table, ew: str, rng: np.random.Generator) -> None:
        """Gross measurement errors (no model term: the identification's robust fit): :attr:`outlier_fraction`
        (a fraction of the rows) and :attr:`outlier_magnitude` m; the campaign draws them."""
        self.outlier_fraction, self.outlier_magnitude = 0.0, 0.0
        if e is None:
            return
        self.outlier_fraction = number(ew, "fraction", e.get("fraction", 0.03))
        self.outlier_magnitude = number(ew, "magnitude_m", e.get("magnitude_m", 2e-3))
        if not 0.0 <= self.outlier_fraction <= 1.0:
            raise SimConfigError(
                f"{ew}: key 'fraction' must be in [0, 1] (a fraction of the rows), got {self.outlier_fraction:g}"
            )
        at_least(ew, "magnitude_m", self.outlier_magnitude, 0.0)

    def joint_error_terms(self) -> list[dict[str, Any]]:
        """The periodic joint-error terms applied (empty without the effect).

        Returns
        -------
        list of dict
            One per term: ``joint`` (1..6), ``amplitude_rad`` (rad), ``harmonic`` (cycles
            per revolution) and ``phase_rad`` (rad); the error of ``joint`` is the sum of
            ``amplitude_rad * sin(harmonic * q_c + phase_rad)`` over its terms.
        """
        return [
            {"joint": int(j) + 1, "amplitude_rad": float(a), "harmonic": float(h), "phase_rad": float(ph)}
            for j, a, h, ph in zip(self.ecc_joint, self.ecc_amp, self.ecc_harm, self.ecc_phase)
        ]
