"""Named numerical tolerances and physical constants (SI units throughout).

Every tolerance used by the library or its tests is defined here, so the
contract stated in the README can be checked against one place.
"""

from __future__ import annotations

from typing import Any

#: Standard gravity, m/s^2.
STANDARD_GRAVITY = 9.80665

#: Cosine arguments of the analytic IK that exceed 1 in magnitude by at most
#: this much are treated as rounding and clipped to +-1 (dimensionless).
IK_CLIP_TOL = 1e-10

#: |sin(theta5)| below this: wrist singular, theta6 undetermined (dimensionless).
#: sin(theta5) is formed as sqrt(1 - cos^2), whose rounding floor is ~sqrt(eps) = 1.5e-8, so an
#: exactly singular pose evaluates to about 1e-8; and the closed form's rotation error grows like
#: eps / |sin(theta5)| (measured: 1.2e-10 rad at |sin(theta5)| = 4.8e-6), so below this threshold
#: the round-trip contract IK_ROUNDTRIP_TOL cannot be met and the pose is reported singular.
IK_WRIST_SINGULAR_TOL = 1e-5

#: Wrist-centre radius margin relative to the lateral offset below which the
#: shoulder solution is degenerate (m).
IK_SHOULDER_SINGULAR_TOL = 1e-9

#: Contract: FK(IK(T)) reproduces T to this (m for positions, rad for rotations).
IK_ROUNDTRIP_TOL = 1e-10

#: Contract: exact compensation puts the deflected TCP on the target to this (m).
EXACT_COMPENSATION_TOL = 1e-9

#: Fixed-point iterations allowed for the deflected equilibrium q = q_c + dq(q, F).
EQUILIBRIUM_MAX_ITER = 50

#: Step size below which the deflected-equilibrium iteration stops (rad).
EQUILIBRIUM_STEP_TOL = 1e-14

#: Jacobian condition number above which the closed-form compensation switches
#: to damped least squares and reports a warning (dimensionless).
JACOBIAN_COND_WARN = 1e6

#: Damping factor of the damped-least-squares inverse (same unit as J's entries).
DLS_DAMPING = 1e-4

#: A position beyond this distance from the base is implausible in metres (m);
#: the loaders suggest a unit mistake (probably millimetres).
PLAUSIBLE_POSITION_MAX_M = 5.0
#: A joint speed limit above this (rad/s, about 2300 deg/s; the fastest 6R wrists run about
#: 1000 deg/s) is implausible in rad/s: the loaders suggest degrees per second.
PLAUSIBLE_JOINT_SPEED_MAX_RAD_S = 40.0
#: A link mass above this (kg) is implausible: the loaders suggest grams.
PLAUSIBLE_LINK_MASS_MAX_KG = 5000.0
#: The arm's total link mass over the cube of its reach (sum of |a| and |d|), kg/m^3, above which
#: the masses are implausible in kg: real 6R arms lie near 5 (cobots, 0.8-1.7 m) to 150 (heavy industrial
#: arms); masses in grams give about 1000 times that.
PLAUSIBLE_MASS_PER_REACH3_MAX_KG_M3 = 3000.0
#: Gravity vectors whose magnitude is above this (m/s^2) are implausible: 1.5 standard gravities
#: covers every place an arm stands on Earth and a tilted base; 10 g or 981 is a unit slip
#: (cm/s^2, or g given as a multiple).
PLAUSIBLE_GRAVITY_MAX_M_S2 = 1.5 * STANDARD_GRAVITY


def gravity_problem(g: Any) -> str:
    """Why a gravity vector (m/s^2) is implausible, or empty: its magnitude above
    :data:`PLAUSIBLE_GRAVITY_MAX_M_S2`, with the likely slip."""
    import numpy as np

    mag = float(np.linalg.norm(g))
    if mag <= PLAUSIBLE_GRAVITY_MAX_M_S2:
        return ""
    hint = "cm/s^2 given?" if abs(mag / 100.0 - STANDARD_GRAVITY) < 1.0 else "a multiple of g given, or another unit?"
    return (
        f"has magnitude {mag:.6g} m/s^2, implausible for gravity on Earth (at most {PLAUSIBLE_GRAVITY_MAX_M_S2:.4g}; "
        f"standard gravity is {STANDARD_GRAVITY} m/s^2): {hint}"
    )
