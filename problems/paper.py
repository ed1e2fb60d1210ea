"""The seed paper's scenarios as data (Huang, Kong, Dong, Appl. Sci. 2021, 11, 10100).

Positions in the paper are in mm; here in m.  See docs/paper-reproduction.md.
"""

from __future__ import annotations

import numpy as np

#: Section 4.4: point-to-point path, 40 points, start and end TCP positions (m, base frame).
SECTION_4_4_START_M = np.array([0.207, 0.444, 0.631])
SECTION_4_4_END_M = np.array([-0.137, 0.069, 0.241])
SECTION_4_4_POINTS = 40
#: Section 4.4 wrench [fx, fy, fz, mx, my, mz] (N, N*m), base frame, on the TCP.
SECTION_4_4_WRENCH = np.array([5.0, 10.0, 20.0, 0.0, 0.0, 0.0])

#: Home configuration used to pick the default branch (rad): the UR "tool down" pose.
HOME_Q = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])

#: Section 4.3 compliance map: X = 0.3 m, Y and Z in (-0.3, 0.3) m, end attitude
#: (-1.57, 0, 1.57) rad read as roll-pitch-yaw, R = Rz(yaw) Ry(pitch) Rx(roll).
SECTION_4_3_X_M = 0.3
SECTION_4_3_RANGE_M = (-0.3, 0.3)
SECTION_4_3_RPY = np.array([-1.57, 0.0, 1.57])

#: Section 5.1 loads (N), applied downward.
SECTION_5_1_LOADS_N = np.array([0.0, 6.04, 10.63, 14.91, 18.64, 21.50])
