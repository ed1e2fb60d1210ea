"""Realising the simulated effects: the true parameters of each ``[effects.NAME]`` table.

:class:`_EffectRealisation` is a part of :class:`~problems.virtual.robot.VirtualRobot`:
its methods read ``self.robot``, ``self.where`` and ``self.effects`` (the checked
``[effects.NAME]`` tables) and set the realised parameters as attributes of the robot
(geometric errors, masses, hardening curve, dead band, beams, drift, thermal
expansion, periodic joint-error terms).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .config import (
    JOINT_ERROR_EFFECTS,
    SIM_JOINT_ERROR_MAX_AMPLITUDE_RAD,
    SIM_JOINT_ERROR_MAX_HARMONIC,
    SimConfigError,
    _at_least,
    _joint_list,
    _num,
    _vec,
)


class _EffectRealisation:
    """The realisation of every configured effect (a part of :class:`VirtualRobot`)."""

    def _realise(self, rng: np.random.Generator) -> None:
        """Realise the true parameters of every configured effect (in this fixed order).

        Only the geometric errors draw random numbers; the order below is the order of
        the checks (the first malformed effect is the one reported).
        """
        self.da = np.zeros(6)
        self.dalpha = np.zeros(6)
        self.dd = np.zeros(6)
        self.dtheta = np.zeros(6)
        self.dbeta = np.zeros(6)
        self._realise_joint_offset()
        self._realise_geometric(rng)
        self._realise_gravity()
        self._realise_lost_motion()
        self._realise_stiffness_hardening()
        self._realise_load_offset()
        self._realise_link_compliance()
        self._realise_drift()
        self._realise_thermal()
        self._realise_joint_error()

    def _realise_joint_offset(self) -> None:
        """Effect ``joint_offset``: add the zero offsets to :attr:`dtheta`, shape (6,), rad."""
        if "joint_offset" in self.effects:
            e = self.effects["joint_offset"]
            self.dtheta += _vec(f"{self.where}: [effects.joint_offset]", "dtheta_rad",
                                e.get("dtheta_rad", 1e-3), 6)

    def _realise_geometric(self, rng: np.random.Generator) -> None:
        """Effect ``geometric``: DH errors, given or drawn from ``rng``.

        Adds to :attr:`da`, :attr:`dd` (m), :attr:`dalpha`, :attr:`dtheta` and :attr:`dbeta`
        (rad), each shape (6,); ``dbeta`` (Hayati) only on joints with a parallel next axis
        (not joint 6).  Draws, in this order, da, dd, dalpha, dtheta, dbeta (6 normals each,
        for every one not given).
        """
        if "geometric" not in self.effects:
            return
        e = self.effects["geometric"]
        ew = f"{self.where}: [effects.geometric]"
        sl = _num(ew, "sigma_length_m", e.get("sigma_length_m", 5e-4))
        sa = _num(ew, "sigma_angle_rad", e.get("sigma_angle_rad", 1e-3))
        _at_least(ew, "sigma_length_m", sl, 0.0, what="(a standard deviation, m)")
        _at_least(ew, "sigma_angle_rad", sa, 0.0, what="(a standard deviation, rad)")
        self.da += _vec(ew, "da_m", e["da_m"], 6) if "da_m" in e else rng.normal(0, sl, 6)
        self.dd += _vec(ew, "dd_m", e["dd_m"], 6) if "dd_m" in e else rng.normal(0, sl, 6)
        self.dalpha += _vec(ew, "dalpha_rad", e["dalpha_rad"], 6) if "dalpha_rad" in e else rng.normal(0, sa, 6)
        self.dtheta += _vec(ew, "dtheta_rad", e["dtheta_rad"], 6) if "dtheta_rad" in e else rng.normal(0, sa, 6)
        par = np.abs(np.sin(self.robot.alpha)) < 1e-6
        par[5] = False
        beta = _vec(ew, "dbeta_rad", e["dbeta_rad"], 6) if "dbeta_rad" in e else rng.normal(0, sa, 6)
        self.dbeta += np.where(par, beta, 0.0)

    def _realise_gravity(self) -> None:
        """Effect ``gravity``: link masses and COMs (robot file, overrides, or a generic set).

        Sets :attr:`masses` (6,) kg, :attr:`coms` (6, 3) m in link frame i, :attr:`payload`
        kg and :attr:`payload_com` (3,) m in the flange frame; zeros without the effect.
        """
        r = self.robot
        self.masses = np.zeros(6)
        self.coms = np.zeros((6, 3))
        if "gravity" not in self.effects:
            self.payload, self.payload_com = 0.0, np.zeros(3)
            return
        e = self.effects["gravity"]
        ew = f"{self.where}: [effects.gravity]"
        if "masses_kg" in e:
            self.masses = _vec(ew, "masses_kg", e["masses_kg"], 6)
            _at_least(ew, "masses_kg", self.masses, 0.0)
        elif r.has_masses:
            self.masses = r.masses.copy()
        else:
            self.masses = 12.0 * np.hypot(r.a, r.d) + 0.5   # generic: 12 kg/m plus 0.5 kg per joint
        if "coms_m" in e:
            c = e["coms_m"]
            if not isinstance(c, list) or len(c) != 6:
                raise SimConfigError(f"{ew}: key 'coms_m' must be a list of 6 [x, y, z] lists")
            self.coms = np.array([_vec(ew, f"coms_m[{i}]", ci, 3, False) for i, ci in enumerate(c)])
        elif r.has_masses:
            self.coms = r.coms.copy()
        else:   # generic: half way back along the link (in link frame i, standard DH: -a/2 on x)
            self.coms = np.column_stack([-r.a / 2.0, np.zeros(6), np.zeros(6)])
        mass_scale = _num(ew, "mass_scale", e.get("mass_scale", 1.0))
        _at_least(ew, "mass_scale", mass_scale, 0.0)
        self.masses = self.masses * mass_scale
        self.payload = _num(ew, "payload_kg", e.get("payload_kg", 0.0))
        _at_least(ew, "payload_kg", self.payload, 0.0)
        self.payload_com = _vec(ew, "payload_com_m", e.get("payload_com_m", [0.0, 0.0, 0.05]), 3, False)

    def _realise_lost_motion(self) -> None:
        """Effect ``lost_motion``: :attr:`backlash` (6,) rad (half dead band) and
        :attr:`backlash_smoothing` N*m (0: a hard sign)."""
        if "lost_motion" in self.effects:
            e = self.effects["lost_motion"]
            ew = f"{self.where}: [effects.lost_motion]"
            self.backlash = _vec(ew, "backlash_rad", e.get("backlash_rad", 2e-4), 6)
            _at_least(ew, "backlash_rad", self.backlash, 0.0, what="(half the dead band)")
            self.backlash_smoothing = _num(ew, "smoothing_Nm", e.get("smoothing_Nm", 0.0))
            _at_least(ew, "smoothing_Nm", self.backlash_smoothing, 0.0)

    def _realise_stiffness_hardening(self) -> None:
        """Effect ``stiffness_hardening``: :attr:`hard_model`, :attr:`knee` (6,) N*m,
        :attr:`hard_ratio` (6,) and :attr:`hard_beta` (6,) 1/(N*m)."""
        if "stiffness_hardening" not in self.effects:
            return
        e = self.effects["stiffness_hardening"]
        ew = f"{self.where}: [effects.stiffness_hardening]"
        self.hard_model = e.get("model", "two_slope")
        if self.hard_model not in ("two_slope", "smooth"):
            raise SimConfigError(f"{ew}: key 'model' must be 'two_slope' or 'smooth', got {self.hard_model!r}")
        self.knee = _vec(ew, "knee_torque_Nm", e.get("knee_torque_Nm", 20.0), 6)
        self.hard_ratio = _vec(ew, "stiffness_ratio", e.get("stiffness_ratio", 2.0), 6)
        self.hard_beta = _vec(ew, "beta_per_Nm", e.get("beta_per_Nm", 0.01), 6)
        _at_least(ew, "knee_torque_Nm", self.knee, 0.0)
        _at_least(ew, "stiffness_ratio", self.hard_ratio, 0.0, strict=True)
        _at_least(ew, "beta_per_Nm", self.hard_beta, 0.0)

    def _realise_load_offset(self) -> None:
        """Effect ``load_offset``: :attr:`r_tool` (3,) m, TCP frame, where the wrench's force
        acts (zeros without the effect)."""
        self.r_tool = (_vec(self.where, "r_tool_m", self.effects["load_offset"].get("r_tool_m", [0.0, 0.03, 0.05]),
                            3, False)
                       if "load_offset" in self.effects else np.zeros(3))

    def _realise_link_compliance(self) -> None:
        """Effect ``link_compliance``: :attr:`beam_links` (0-based joints), :attr:`EI` and
        :attr:`GJ` (one per link), N*m^2."""
        if "link_compliance" not in self.effects:
            return
        e = self.effects["link_compliance"]
        ew = f"{self.where}: [effects.link_compliance]"
        links = _joint_list(ew, e.get("links", [2, 3]))
        self.beam_links = [x - 1 for x in links]
        self.EI = _vec(ew, "EI_Nm2", e.get("EI_Nm2", 2.0e5), len(links))
        self.GJ = _vec(ew, "GJ_Nm2", e.get("GJ_Nm2", 1.5e5), len(links))
        _at_least(ew, "EI_Nm2", self.EI, 0.0, strict=True)
        _at_least(ew, "GJ_Nm2", self.GJ, 0.0, strict=True)

    def _realise_drift(self) -> None:
        """Effect ``drift``: :attr:`drift_rate` (3,) m/s and :attr:`drift_acc` (3,) m/s^2,
        measurement frame."""
        if "drift" in self.effects:
            e = self.effects["drift"]
            w = self.where
            self.drift_rate = _vec(w, "rate_m_per_h", e.get("rate_m_per_h", [1e-4, -5e-5, 8e-5]), 3, False) / 3600.0
            self.drift_acc = _vec(w, "accel_m_per_h2", e.get("accel_m_per_h2", [0.0, 0.0, 0.0]), 3, False) / 3600.0 ** 2

    def _realise_thermal(self) -> None:
        """Effect ``thermal``: :attr:`th_alpha` 1/K, :attr:`th_links` (0-based joints whose
        a and d expand) and :attr:`th_ref` deg C."""
        if "thermal" not in self.effects:
            return
        e = self.effects["thermal"]
        ew = f"{self.where}: [effects.thermal]"
        self.th_alpha = _num(ew, "alpha_per_K", e.get("alpha_per_K", 2.3e-5))
        links = _joint_list(ew, e.get("links", [2, 3]))
        self.th_links = [x - 1 for x in links]
        self.th_ref = _num(ew, "reference_C", e.get("reference_C", 20.0))

    def _realise_joint_error(self) -> None:
        """Effect ``eccentricity`` (or its spelling ``joint_error_map``): periodic joint
        transmission errors, a sum of terms ``amplitude sin(harmonic q_c[joint] + phase)``.

        Sets, one entry per term (K terms; K = 0 without the effect): :attr:`ecc_joint`
        (K,) int, 0-based joint; :attr:`ecc_amp` (K,) rad; :attr:`ecc_harm` (K,) cycles per
        revolution; :attr:`ecc_phase` (K,) rad.  Each key is a number (applied to every term)
        or a list with one entry per term; lists must have equal lengths.
        """
        self.ecc_joint = np.zeros(0, dtype=int)
        self.ecc_amp = np.zeros(0)
        self.ecc_harm = np.zeros(0)
        self.ecc_phase = np.zeros(0)
        name = next((n for n in JOINT_ERROR_EFFECTS if n in self.effects), None)
        if name is None:
            return
        e = self.effects[name]
        ew = f"{self.where}: [effects.{name}]"
        raw = {"joint": e.get("joint", 1), "amplitude_rad": e.get("amplitude_rad", 1e-3),
               "harmonic": e.get("harmonic", 2), "phase_rad": e.get("phase_rad", 0.3)}
        for key, v in raw.items():
            if isinstance(v, list) and not v:
                raise SimConfigError(f"{ew}: key '{key}' must be a number or a non-empty list (one entry per "
                                     f"term), got {v!r}")
        lengths = {key: len(v) for key, v in raw.items() if isinstance(v, list)}
        if len(set(lengths.values())) > 1:
            shown = ", ".join(f"'{k}' has {n}" for k, n in lengths.items())
            raise SimConfigError(f"{ew}: the lists must have one entry per term, all of the same length; {shown} "
                                 "entries (a number applies to every term)")
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
        amp = np.array([_num(ew, k, v) for k, v in entries("amplitude_rad")])
        harm = np.array([_num(ew, k, v) for k, v in entries("harmonic")])
        phase = np.array([_num(ew, k, v) for k, v in entries("phase_rad")])
        amax, hmax = SIM_JOINT_ERROR_MAX_AMPLITUDE_RAD, SIM_JOINT_ERROR_MAX_HARMONIC
        for (k, _v), a in zip(entries("amplitude_rad"), amp):
            if abs(a) > amax:
                raise SimConfigError(f"{ew}: key '{k}' must be within [-{amax:g}, {amax:g}] rad (a transmission "
                                     f"error; a constant offset is [effects.joint_offset]), got {a:g}")
        for (k, _v), h in zip(entries("harmonic"), harm):
            if not 0.0 < h <= hmax:
                raise SimConfigError(f"{ew}: key '{k}' must be > 0 and <= {hmax:g} (cycles per revolution of the "
                                     f"joint), got {h:g}")
        self.ecc_joint = np.array(joints, dtype=int)
        self.ecc_amp, self.ecc_harm, self.ecc_phase = amp, harm, phase

    def joint_error_terms(self) -> list[dict[str, Any]]:
        """The periodic joint-error terms applied (empty without the effect).

        Returns
        -------
        list of dict
            One per term: ``joint`` (1..6), ``amplitude_rad`` (rad), ``harmonic`` (cycles
            per revolution) and ``phase_rad`` (rad); the error of ``joint`` is the sum of
            ``amplitude_rad * sin(harmonic * q_c + phase_rad)`` over its terms.
        """
        return [{"joint": int(j) + 1, "amplitude_rad": float(a), "harmonic": float(h), "phase_rad": float(ph)}
                for j, a, h, ph in zip(self.ecc_joint, self.ecc_amp, self.ecc_harm, self.ecc_phase)]
