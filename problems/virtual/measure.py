"""True poses of the deflected arm and their noise-free measurement.

:class:`MeasuringPart` is a part of :class:`~problems.virtual.robot.VirtualRobot`: the
measured point and the TCP (link beams and joint tilts applied), the orientation of the measured frame,
and what the instrument sees of them (registration ``base2meas`` and drift).
"""

from __future__ import annotations

import numpy as np

from .geometry import rotvecs


class MeasuringPart:
    """Positions, orientations and their measurement (a part of :class:`VirtualRobot`)."""

    def positions(
        self, q_c: np.ndarray, F: np.ndarray, temperature: np.ndarray | None = None, point: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """True position of a flange point and the TCP pose, base frame.

        Returns
        -------
        p_point : ndarray, shape (N, 3)
            Position of ``point`` (flange frame, m; default the measured point), m.
        tcp2base : ndarray, shape (N, 4, 4)
            TCP frame of the deflected arm (link compliance and joint tilts applied to the position
            only; :meth:`orientations` also turns the frame by the beams and tilts).
        """
        fr, F = self._deflected_frames(q_c, F, temperature)
        return self._positions_from_frames(fr, F, point)

    def _positions_from_frames(
        self, fr: np.ndarray, F: np.ndarray, point: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`positions` from the deflected frames of :meth:`_deflected_frames`."""
        pt = self.p_tool if point is None else np.asarray(point, dtype=float)
        fl = self._flange(fr)
        p_point = fl[:, :3, 3] + np.einsum("nij,j->ni", fl[:, :3, :3], pt)
        tcp = fl @ self._tool()
        p0, p_tcp = p_point.copy(), tcp[:, :3, 3].copy()
        tcp = tcp.copy()
        for name, displacement in (
            ("link_compliance", self._beam_displacement),
            ("joint_tilt", self._tilt_displacement),
        ):
            if self.simulated(name):  # each at the undisplaced points (linear, first order)
                p_point = p_point + displacement(fr, F, p0)
                tcp[:, :3, 3] += displacement(fr, F, p_tcp)
        return p_point, tcp

    def orientations(self, q_c: np.ndarray, F: np.ndarray, temperature: np.ndarray | None = None) -> np.ndarray:
        """True orientation of the measured frame, base frame, shape (N, 3, 3).

        The measured frame sits at the measured point with the TCP's orientation:
        ``R = exp([phi]) R_flange2base(q) R_tcp2flange``, ``q`` the deflected joints plus
        periodic joint errors on the true geometry (DH errors, joint offsets, thermal
        lengths), ``phi`` the summed tip rotations of the link beams (effect
        ``link_compliance``) and the joint tilts (effect ``joint_tilt``); zero without them.
        """
        fr, F = self._deflected_frames(q_c, F, temperature)
        return self._orientations_from_frames(fr, F)

    def _orientations_from_frames(self, fr: np.ndarray, F: np.ndarray) -> np.ndarray:
        """:meth:`orientations` from the deflected frames of :meth:`_deflected_frames`."""
        R = self._flange(fr)[:, :3, :3] @ self._tool()[:3, :3]
        phi = np.zeros((fr.shape[0], 3))
        if self.simulated("link_compliance"):
            phi += self._beam_rotation(fr, F)
        if self.simulated("joint_tilt"):
            phi += self._tilt_rotation(fr, F)
        if self.simulated("link_compliance") or self.simulated("joint_tilt"):
            from scipy.spatial.transform import Rotation

            R = Rotation.from_rotvec(phi).as_matrix() @ R
        return R

    def _to_measurement_frame(self, p: np.ndarray, t: np.ndarray | None) -> np.ndarray:
        """Base-frame positions (N, 3) to the measurement frame, with drift at times ``t``, m."""
        pm = p @ self.R_reg.T + self.t_reg
        if self.simulated("drift") and t is not None:
            tt = np.asarray(t, dtype=float)[:, None]
            pm = pm + self.drift_rate * tt + self.drift_acc * tt**2
        return pm

    def measure(
        self, q_c: np.ndarray, F: np.ndarray, t: np.ndarray | None = None, temperature: np.ndarray | None = None
    ) -> np.ndarray:
        """Noise-free measurement of the measured point, measurement frame, m, (N, 3)."""
        p, _tcp = self.positions(q_c, F, temperature)
        return self._to_measurement_frame(p, t)

    def measure_orientation(self, q_c: np.ndarray, F: np.ndarray, temperature: np.ndarray | None = None) -> np.ndarray:
        """Noise-free orientation of the measured frame in the measurement frame,
        ``R_base2meas @ orientations(...)``, shape (N, 3, 3).  Drift (a translation of the
        instrument) does not turn it."""
        return self.R_reg @ self.orientations(q_c, F, temperature)

    def measure_rotvec(self, q_c: np.ndarray, F: np.ndarray, temperature: np.ndarray | None = None) -> np.ndarray:
        """:meth:`measure_orientation` as rotation vectors (axis x angle, angle in [0, pi]),
        rad, shape (N, 3): the ``rx, ry, rz`` columns of a noise-free campaign."""
        return rotvecs(self.measure_orientation(q_c, F, temperature))

    def _measure_pose(
        self, q_c: np.ndarray, F: np.ndarray, t: np.ndarray | None, temperature: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`measure` and :meth:`measure_orientation` from one equilibrium."""
        fr, F = self._deflected_frames(q_c, F, temperature)
        p, _tcp = self._positions_from_frames(fr, F)
        return self._to_measurement_frame(p, t), self.R_reg @ self._orientations_from_frames(fr, F)

    def tcp_error(
        self, q_command: np.ndarray, F: np.ndarray, target2base: np.ndarray, temperature: np.ndarray | None = None
    ) -> np.ndarray:
        """True TCP position minus target position, base frame, m, shape (N, 3)."""
        _p, tcp = self.positions(q_command, F, temperature)
        return tcp[:, :3, 3] - target2base[:, :3, 3]
