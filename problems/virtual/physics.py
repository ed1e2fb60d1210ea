"""The physics of the true arm: joint errors, torques, joint deflection, equilibrium, link beams, joint tilts.

:class:`PhysicsPart` is a part of :class:`~problems.virtual.robot.VirtualRobot`: its
methods read the realised parameters (set by ``__init__`` and
:class:`~problems.virtual.effects.EffectPart`) and give the deflected arm:
the fixed point ``q = q_c + e(q_c) + dq(q)`` of the joints, the Euler-Bernoulli
beams of the links and the tilts of the joints.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from models.errors import InputError

from .geometry import ArmGeometry, joint_axes, link_frames, tau_point

#: Fixed-point tolerance of the simulator's deflected equilibrium (rad).
SIM_EQUILIBRIUM_TOL = 1e-13
#: Maximum fixed-point iterations of the simulator.
SIM_EQUILIBRIUM_MAX_ITER = 200


class PhysicsPart:
    """The deflected arm of the true parameters (a part of :class:`VirtualRobot`)."""

    def joint_error(self, q_c: np.ndarray) -> np.ndarray:
        """Periodic joint error the simulator adds to each joint (effect ``eccentricity`` /
        ``joint_error_map``), a function of the commanded angle.

        Parameters
        ----------
        q_c : ndarray, shape (N, 6) or (6,)
            Commanded joint angles, rad.

        Returns
        -------
        ndarray, shape (N, 6)
            Error added to each joint angle of the arm before the kinematics, rad
            (``sum_k amplitude_k sin(harmonic_k q_c[joint_k] + phase_k)``; zeros without
            the effect).
        """
        q_c = np.atleast_2d(np.asarray(q_c, dtype=float))
        if q_c.ndim != 2 or q_c.shape[1] != 6:
            raise InputError(f"joint_error: q_c: expected shape (N, 6), got {q_c.shape}")
        err = np.zeros(q_c.shape)
        for j, a, h, ph in zip(self.ecc_joint, self.ecc_amp, self.ecc_harm, self.ecc_phase):
            err[:, j] += float(a) * np.sin(float(h) * q_c[:, j] + float(ph))
        return err

    def _geometry(self, temperature: np.ndarray) -> ArmGeometry:
        r = self.robot
        n = len(temperature)
        a = np.tile(r.a + self.da, (n, 1))
        d = np.tile(r.d + self.dd, (n, 1))
        if self.simulated("thermal"):
            s = 1.0 + self.th_alpha * (temperature - self.th_ref)
            for i in self.th_links:
                a[:, i] *= s
                d[:, i] *= s
        return ArmGeometry(
            a=a,
            alpha=np.tile(r.alpha + self.dalpha, (n, 1)),
            d=d,
            toff=np.tile(r.theta_offset + self.dtheta, (n, 1)),
            beta=np.tile(self.dbeta, (n, 1)),
            frame02base=np.asarray(r.frame02base, dtype=float),
        )

    def _tool(self) -> np.ndarray:
        return self.robot.tcp2flange

    def _flange(self, fr: np.ndarray) -> np.ndarray:
        """flange2base (N, 4, 4) from the frames: DH frame 6 and the chain's ``flange2frame6``."""
        return fr[:, 5] @ np.asarray(self.robot.flange2frame6, dtype=float)

    def _torques(self, q: np.ndarray, F: np.ndarray, geo: ArmGeometry) -> np.ndarray:
        fr = link_frames(q, geo, self.convention)
        z, p = joint_axes(fr, self.convention, geo.frame02base)
        fl = self._flange(fr)
        tcp = fl @ self._tool()
        f, m = F[:, :3], F[:, 3:]
        point = tcp[:, :3, 3] + np.einsum("nij,j->ni", tcp[:, :3, :3], self.r_tool)
        tau = tau_point(z, p, point, f, m)
        if self.simulated("gravity"):
            g = self.robot.gravity
            for j in range(6):
                c = fr[:, j, :3, 3] + np.einsum("nij,j->ni", fr[:, j, :3, :3], self.coms[j])
                tau += (
                    tau_point(z, p, c, np.broadcast_to(self.masses[j] * g, c.shape), np.zeros_like(c))
                    * (np.arange(6) <= j)[None, :]
                )
            if self.payload > 0:
                c = fl[:, :3, 3] + np.einsum("nij,j->ni", fl[:, :3, :3], self.payload_com)
                tau += tau_point(z, p, c, np.broadcast_to(self.payload * g, c.shape), np.zeros_like(c))
        return tau

    def _deflection(self, tau: np.ndarray) -> np.ndarray:
        k = self.k_true
        if self.simulated("stiffness_hardening"):
            if self.hard_model == "two_slope":
                a = np.abs(tau)
                lo = np.minimum(a, self.knee) / k
                hi = np.maximum(a - self.knee, 0.0) / (k * self.hard_ratio)
                dq = np.sign(tau) * (lo + hi)
            else:
                dq = tau / (k * (1.0 + self.hard_beta * np.abs(tau)))
        else:
            dq = tau / k
        if self.simulated("lost_motion"):
            if self.backlash_smoothing > 0:
                dq = dq + self.backlash * np.tanh(tau / self.backlash_smoothing)
            else:
                dq = dq + self.backlash * np.sign(tau)
        return dq

    def equilibrium(self, q_c: np.ndarray, F: np.ndarray, temperature: np.ndarray | None = None) -> np.ndarray:
        """Deflected joint angles ``q = q_c + dq(q)`` (rad), shape (N, 6).

        Periodic joint errors (:meth:`joint_error` of the commanded angles) are part of the
        pose the loads act on: ``q = q_c + e(q_c) + dq(q)``.
        """
        q_c = np.atleast_2d(q_c)
        n = len(q_c)
        F = np.broadcast_to(np.asarray(F, dtype=float), (n, 6))
        T = np.full(n, 20.0) if temperature is None else np.asarray(temperature, dtype=float)
        geo = self._geometry(T)
        q0 = q_c + self.joint_error(q_c) if self.ecc_joint.size else q_c
        q = q0.copy()
        for _ in range(SIM_EQUILIBRIUM_MAX_ITER):
            q_new = q0 + self._deflection(self._torques(q, F, geo))
            step = np.max(np.abs(q_new - q))
            q = q_new
            if step < SIM_EQUILIBRIUM_TOL:
                break
        return q

    def _beams(self, fr: np.ndarray, F: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Euler-Bernoulli beams of effect ``link_compliance``, one per link: yields the tip
        displacement ``delta`` (N, 3) m, the tip rotation ``phi`` (N, 3) rad (a small rotation
        vector) and the tip position (N, 3) m, base frame; everything distal to the tip moves
        by ``delta + phi x (x - tip)`` and turns by ``phi``."""
        _z, p = joint_axes(fr, self.convention, self.robot.frame02base)
        tcp = self._flange(fr) @ self._tool()
        p_app = tcp[:, :3, 3] + np.einsum("nij,j->ni", tcp[:, :3, :3], self.r_tool)
        f, m = F[:, :3], F[:, 3:]
        for k, i in enumerate(self.beam_links):
            base = p[:, i]
            tip = p[:, i + 1] if i < 5 else fr[:, 5, :3, 3]
            seg = tip - base
            L = np.linalg.norm(seg, axis=1, keepdims=True)
            e = seg / L
            m_tip = m + np.cross(p_app - tip, f)
            f_perp = f - np.sum(f * e, axis=1, keepdims=True) * e
            m_ax = np.sum(m_tip * e, axis=1, keepdims=True) * e
            m_perp = m_tip - m_ax
            EI, GJ = self.EI[k], self.GJ[k]
            delta = f_perp * L**3 / (3 * EI) + np.cross(m_perp, e) * L**2 / (2 * EI)
            phi = np.cross(e, f_perp) * L**2 / (2 * EI) + m_perp * L / EI + m_ax * L / GJ
            yield delta, phi, tip

    def _beam_displacement(self, fr: np.ndarray, F: np.ndarray, point: np.ndarray) -> np.ndarray:
        """Displacement of ``point`` (N, 3), base frame, m, by the link beams."""
        dp = np.zeros_like(point)
        for delta, phi, tip in self._beams(fr, F):
            dp += delta + np.cross(phi, point - tip)
        return dp

    def _beam_rotation(self, fr: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Rotation of the flange by the link beams: the sum of their tip rotations, a
        rotation vector (N, 3), rad, base frame (small: the beams are linear)."""
        phi_sum = np.zeros((fr.shape[0], 3))
        for _delta, phi, _tip in self._beams(fr, F):
            phi_sum += phi
        return phi_sum

    def _tilts(self, fr: np.ndarray, F: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Tilts of effect ``joint_tilt``, one per tilted joint: yields the rotation ``phi`` (N, 3)
        rad (a small rotation vector) of everything distal to the joint, and the joint's point
        (N, 3) m, base frame.

        The moment through joint i about its point: each distal link's weight at its centre of
        mass, the payload's (with ``[effects.gravity]``), the wrench's moment and its force at
        the load point; its components about x and y of the joint's DH frame times the tilt
        compliances."""
        n = fr.shape[0]
        g = np.asarray(self.robot.gravity, dtype=float)
        _z, p = joint_axes(fr, self.convention, self.robot.frame02base)
        f0 = np.broadcast_to(np.asarray(self.robot.frame02base, dtype=float), (n, 4, 4))
        axes = np.concatenate([f0[:, None], fr[:, :5]], axis=1) if self.convention == "standard_dh" else fr
        fl = self._flange(fr)
        tcp = fl @ self._tool()
        p_app = tcp[:, :3, 3] + np.einsum("nij,j->ni", tcp[:, :3, :3], self.r_tool)
        weights = [
            (fr[:, j, :3, 3] + np.einsum("nij,j->ni", fr[:, j, :3, :3], self.tilt_coms[j]), self.tilt_masses[j], j)
            for j in range(6)
        ]
        if self.simulated("gravity") and self.payload > 0:
            weights.append((fl[:, :3, 3] + np.einsum("nij,j->ni", fl[:, :3, :3], self.payload_com), self.payload, 5))
        for k, i in enumerate(self.tilt_joints):
            mom = F[:, 3:] + np.cross(p_app - p[:, i], F[:, :3])
            for c, mass, j in weights:
                if j >= i:
                    mom = mom + np.cross(c - p[:, i], mass * g)
            x, y = axes[:, i, :3, 0], axes[:, i, :3, 1]
            mx, my = np.sum(mom * x, axis=1, keepdims=True), np.sum(mom * y, axis=1, keepdims=True)
            yield self.tilt_cx[k] * mx * x + self.tilt_cy[k] * my * y, p[:, i]

    def _tilt_displacement(self, fr: np.ndarray, F: np.ndarray, point: np.ndarray) -> np.ndarray:
        """Displacement of ``point`` (N, 3), base frame, m, by the joint tilts."""
        dp = np.zeros_like(point)
        for phi, pivot in self._tilts(fr, F):
            dp += np.cross(phi, point - pivot)
        return dp

    def _tilt_rotation(self, fr: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Rotation of the flange by the joint tilts: the sum of their rotations, a rotation
        vector (N, 3), rad, base frame (small: the tilts are linear)."""
        phi_sum = np.zeros((fr.shape[0], 3))
        for phi, _pivot in self._tilts(fr, F):
            phi_sum += phi
        return phi_sum

    def _deflected_frames(
        self, q_c: np.ndarray, F: np.ndarray, temperature: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Frames frame_i2base of the deflected arm (N, 6, 4, 4) and the wrench broadcast
        to (N, 6): equilibrium joints (plus periodic joint errors) on the true geometry."""
        q_c = np.atleast_2d(np.asarray(q_c, dtype=float))
        n = len(q_c)
        F = np.broadcast_to(np.asarray(F, dtype=float), (n, 6))
        T = np.full(n, 20.0) if temperature is None else np.asarray(temperature, dtype=float)
        q = self.equilibrium(q_c, F, T)
        return link_frames(q, self._geometry(T), self.convention), F
