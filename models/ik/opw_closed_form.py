"""Closed-form inverse kinematics of ortho-parallel 6R arms with a spherical wrist (OPW).

The OPW family (Brandstötter, Angerer & Hofbaur 2014: KUKA KR, ABB IRB, Fanuc, ...) is
described here by a *canonical* arm standing upright in its own base frame, all
canonical angles ``phi = 0``:

* axis 1 = +z through the origin; axes 2 and 3 along +y through ``(a1, *, c1)`` and
  ``(a1, *, c1 + c2)``;
* wrist centre ``C = (a1 + a2, b, c1 + c2 + c3)``; axes 4 and 6 along +z, axis 5 along
  +y, all three through ``C``; flange origin at ``C + c4 z`` with the base orientation.

Canonical forward kinematics (checked against ``py_opw_kinematics``, which implements
the same model): ``R = Rz(phi1) Ry(phi2 + phi3) Rz(phi4) Ry(phi5) Rz(phi6)``, the wrist
centre in the arm plane ``x = a1 + c2 sin phi2 + c3 sin phi23 + a2 cos phi23``,
``y = b``, ``z = c1 + c2 cos phi2 + c3 cos phi23 - a2 sin phi23``, rotated by
``Rz(phi1)``; the flange origin is ``C + c4 R e_z``.

A robot given in product-of-exponentials form (axes ``w``, points ``p``, zero pose
``M0``) is mapped onto it by :func:`models.ik.opw_detect.opw_from_axes`; joint ``i`` relates to its canonical
angle by ``phi_i = s_i q_i + o_i`` and, for every ``q``::

    flange2base(q) = canon2base @ FK_canon(phi(q)) @ flange2canon_flange

(``canon2base`` maps canonical-base coordinates to robot-base coordinates,
``flange2canon_flange`` maps robot-flange coordinates to canonical-flange coordinates).
Note that ``offsets`` follow ``phi = s q + o``; the opw_kinematics / rs-opw-kinematics
convention is ``phi = s q - offset``, see :meth:`OPWGeometry.opw_parameters`.

Branches (index ``4*shoulder + 2*elbow + wrist``, :data:`OPW_BRANCH_LABELS`):

* shoulder "front": the arm plane points at the wrist centre (the wrist centre's
  arm-plane x coordinate is positive), "back": it points away (reaching over axis 1);
* elbow: with ``gamma = atan2(a2, c3)``, ``sin(phi3 + gamma)`` is the sine of the signed
  angle of the triangle shoulder-elbow-wrist, ``cross(W - S, E - S) = c2 K sin(phi3 +
  gamma)`` in the arm plane (x, z), ``K = hypot(a2, c3)``.  For "front" (wrist centre
  ahead of the shoulder) ``sin(phi3 + gamma) > 0`` puts the elbow above the
  shoulder-wrist line: "up"; for "back" the wrist centre lies behind the shoulder, the
  line points the other way and "up" is ``sin(phi3 + gamma) < 0``;
* wrist "noflip": ``sin(phi5) > 0``, "flip": ``sin(phi5) < 0`` (``phi4 + pi, -phi5,
  phi6 + pi``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from ..errors import InputError
from ..status import CodedStatus
from ..transforms import rotations_about

#: Structure checks: largest distance between axes that should meet, relative to the arm
#: size (m per m of arm size, see :attr:`OPWGeometry.scale`).
OPW_DIST_TOL_REL = 1e-9
#: :meth:`OPWGeometry.opw_parameters` reports lengths below this (relative to the arm size)
#: and offsets below this (rad) as exact zeros: rounding residue of the extraction.
OPW_PRINT_ZERO = 1e-12
#: acos/sqrt arguments beyond their domain by at most this (relative) are clipped;
#: beyond it the branch is unreachable.
OPW_CLIP_TOL = 1e-12
#: |sin(phi5)| below this: wrist singular, phi4 and phi6 not separable (dimensionless).
OPW_WRIST_SINGULAR_TOL = 1e-10
#: Wrist centre closer to axis 1 than this (relative to the arm size) with b = 0:
#: shoulder singular, phi1 undetermined.
OPW_SHOULDER_SINGULAR_TOL_REL = 1e-9

OPW_BRANCH_LABELS: tuple[str, ...] = tuple(
    f"{sh}-{el}-{wr}" for sh in ("front", "back") for el in ("up", "down") for wr in ("noflip", "flip")
)

#: A full turn, rad.
TWO_PI = 2.0 * np.pi


class OPWStatus(CodedStatus):
    """Why a branch has (or has no) solution; values and codes shared with :class:`models.ik.IKStatus`
    (the OPW family stores these codes as IK codes)."""

    OK = "ok", 0
    SHOULDER_UNREACHABLE = "shoulder_unreachable", 1  # wrist centre closer to axis 1 than |b|
    WRIST_SINGULAR = "wrist_singular", 3  # sin(phi5) ~ 0: phi4 and phi6 not separable
    ELBOW_UNREACHABLE = "elbow_unreachable", 4  # wrist centre beyond the reach of links 2-3
    SHOULDER_SINGULAR = "shoulder_singular", 6  # wrist centre on axis 1 with b = 0: phi1 undetermined


class NotOPW(InputError):
    """The chain is not ortho-parallel with a spherical wrist; the message names the joints."""


@dataclass(frozen=True)
class OPWGeometry:
    """Canonical OPW parameters of a chain and the map between both descriptions.

    Attributes
    ----------
    a1, a2, b, c1, c2, c3, c4 : float
        Canonical lengths (m), see the module docstring.
    signs : ndarray, shape (6,)
        ``s_i`` = +1 or -1: ``phi_i = s_i q_i + o_i``.
    offsets : ndarray, shape (6,)
        ``o_i`` (rad).
    canon2base : ndarray, shape (4, 4)
        Canonical base frame -> robot base frame.
    flange2canon_flange : ndarray, shape (4, 4)
        Robot flange coordinates -> canonical flange coordinates, so that
        ``flange2base(q) = canon2base @ FK_canon(phi(q)) @ flange2canon_flange``.
    scale : float
        Arm size used for relative tolerances (m): largest distance of the zero-pose
        flange origin from a joint axis.
    """

    a1: float
    a2: float
    b: float
    c1: float
    c2: float
    c3: float
    c4: float
    signs: np.ndarray
    offsets: np.ndarray
    canon2base: np.ndarray
    flange2canon_flange: np.ndarray
    scale: float

    def phi(self, q: np.ndarray) -> np.ndarray:
        """Canonical angles ``s q + o`` (rad) of joint values ``q`` (rad), shape (..., 6)."""
        return np.asarray(q, dtype=float) * self.signs + self.offsets

    def q_from_phi(self, phi: np.ndarray) -> np.ndarray:
        """Joint values ``s (phi - o)`` (rad) of canonical angles, shape (..., 6), not wrapped."""
        return (np.asarray(phi, dtype=float) - self.offsets) * self.signs

    def fk(self, q: np.ndarray) -> np.ndarray:
        """Flange pose ``flange2base`` (m) through the canonical model, q (N, 6) -> (N, 4, 4)."""
        Tc = opw_canonical_fk(self, self.phi(np.atleast_2d(q)))
        return self.canon2base @ Tc @ self.flange2canon_flange

    def opw_parameters(self) -> dict[str, Any]:
        """Parameters in the opw_kinematics convention ``phi = sign * q - offset``.

        Returns
        -------
        dict
            ``a1 .. c4`` (m), ``offsets`` (6 floats, rad, ``= -o``) and
            ``sign_corrections`` (6 ints).  ``py_opw_kinematics.KinematicModel`` takes
            the same offsets (radians with ``Robot(..., degrees=False)``) and
            ``flip_axes = sign_corrections < 0``; its FK is the canonical flange pose.
            Rounding residue (below OPW_PRINT_ZERO) is reported as exact zeros.
        """
        off = -self.offsets
        off = np.where(np.abs(off) < OPW_PRINT_ZERO, 0.0, off)
        lengths = {k: getattr(self, k) for k in ("a1", "a2", "b", "c1", "c2", "c3", "c4")}
        lengths = {k: (0.0 if abs(v) < OPW_PRINT_ZERO * self.scale else v) for k, v in lengths.items()}
        return {
            **lengths,
            "offsets": tuple(float(v) for v in off),
            "sign_corrections": tuple(int(s) for s in self.signs),
        }


# --------------------------------------------------------------------------- canonical FK

_rodrigues = rotations_about


def opw_canonical_fk(geom: OPWGeometry, phi: Any) -> np.ndarray:
    """Canonical flange pose in the canonical base frame, phi (N, 6) rad -> (N, 4, 4)."""
    phi = np.atleast_2d(np.asarray(phi, dtype=float))
    p1, p2, p4, p5, p6 = phi[:, 0], phi[:, 1], phi[:, 3], phi[:, 4], phi[:, 5]
    p23 = p2 + phi[:, 2]
    ez, ey = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])
    R = _rodrigues(ez, p1) @ _rodrigues(ey, p23) @ _rodrigues(ez, p4) @ _rodrigues(ey, p5) @ _rodrigues(ez, p6)
    x = geom.a1 + geom.c2 * np.sin(p2) + geom.c3 * np.sin(p23) + geom.a2 * np.cos(p23)
    z = geom.c1 + geom.c2 * np.cos(p2) + geom.c3 * np.cos(p23) - geom.a2 * np.sin(p23)
    C = np.stack([x * np.cos(p1) - geom.b * np.sin(p1), x * np.sin(p1) + geom.b * np.cos(p1), z], axis=-1)
    T = np.broadcast_to(np.eye(4), (phi.shape[0], 4, 4)).copy()
    T[:, :3, :3] = R
    T[:, :3, 3] = C + geom.c4 * R[:, :, 2]
    return T


# --------------------------------------------------------------------------- closed form


def _rz_sx(c: ca.SX, s: ca.SX) -> ca.SX:
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def _ry_sx(c: ca.SX, s: ca.SX) -> ca.SX:
    return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))


def _ik_arm(g: OPWGeometry, Cw: ca.SX) -> tuple[list[tuple[ca.SX, ...]], list[ca.SX], ca.SX, ca.SX]:
    """Shoulder and elbow for the wrist centre ``Cw`` (canonical base, m).

    Returns the four (phi1, phi2, phi3) in the order front-up, front-down, back-up,
    back-down, the unclipped elbow cosines per shoulder, and the shoulder-unreachable /
    shoulder-singular flags.
    """
    r = ca.sqrt(Cw[0] ** 2 + Cw[1] ** 2)
    rho = ca.sqrt(ca.fmax(r**2 - g.b**2, 0.0))
    tol = OPW_SHOULDER_SINGULAR_TOL_REL * g.scale
    b_zero = abs(g.b) <= OPW_DIST_TOL_REL * g.scale
    sh_unreach = ca.SX(0) if b_zero else r < abs(g.b) * (1.0 - OPW_CLIP_TOL)
    sh_sing = r < tol if b_zero else ca.SX(0)
    psi, beta = ca.atan2(Cw[1], Cw[0]), ca.atan2(g.b, rho)
    K = float(np.hypot(g.a2, g.c3))
    gamma = float(np.arctan2(g.a2, g.c3))
    dz = Cw[2] - g.c1
    sols, cosines = [], []
    for front in (True, False):
        phi1 = psi - beta if front else psi + beta - np.pi
        dx = (rho if front else -rho) - g.a1
        c3e = (dx**2 + dz**2 - g.c2**2 - K**2) / (2.0 * g.c2 * K)
        cosines.append(c3e)
        cc = ca.fmin(ca.fmax(c3e, -1.0), 1.0)
        sn = ca.sqrt(1.0 - cc**2)
        # "up" is sin(phi3 + gamma) > 0 in front, < 0 at the back (module docstring).
        for sgn in (1.0, -1.0) if front else (-1.0, 1.0):
            phi2 = ca.atan2(dx, dz) - ca.atan2(K * sgn * sn, g.c2 + K * cc)
            phi3 = ca.atan2(sgn * sn, cc) - gamma
            sols.append((phi1, phi2, phi3))
    return sols, cosines, sh_unreach, sh_sing


def _ik_wrist(g: OPWGeometry, R: ca.SX, phi123: tuple[ca.SX, ...]) -> tuple[list[ca.SX], ca.SX]:
    """Both wrist solutions (phi4, phi5, phi6) for the orientation ``R`` (canonical), and |sin phi5|."""
    phi1, phi2, phi3 = phi123
    R03 = ca.mtimes(_rz_sx(ca.cos(phi1), ca.sin(phi1)), _ry_sx(ca.cos(phi2 + phi3), ca.sin(phi2 + phi3)))
    R36 = ca.mtimes(R03.T, R)
    s5 = ca.sqrt(R36[0, 2] ** 2 + R36[1, 2] ** 2)
    singular = s5 < OPW_WRIST_SINGULAR_TOL
    out = []
    for sgn in (1.0, -1.0):
        # Singular: joint 4 held at q4 = 0 (noflip) or its flip partner; phi6 takes the rest.
        phi4 = ca.if_else(
            singular, g.offsets[3] + (0.0 if sgn > 0 else np.pi), ca.atan2(sgn * R36[1, 2], sgn * R36[0, 2])
        )
        phi5 = ca.atan2(sgn * s5, R36[2, 2])
        Rr = ca.mtimes([_ry_sx(ca.cos(phi5), ca.sin(phi5)).T, _rz_sx(ca.cos(phi4), ca.sin(phi4)).T, R36])
        phi6 = ca.atan2(Rr[1, 0], Rr[0, 0])
        out.append(ca.vertcat(phi4, phi5, phi6))
    return out, s5


def opw_ik_function(geom: OPWGeometry) -> ca.Function:
    """The closed-form IK as a CasADi SX Function "opw_ik" (mappable, code-generable).

    Parameters
    ----------
    geom : OPWGeometry
        From :func:`opw_from_axes`.

    Returns
    -------
    casadi.Function
        ``flange2base`` (4x4, m) -> ``q`` (6 x 8, rad, column = branch in
        :data:`OPW_BRANCH_LABELS` order, joint values wrapped to (-pi, pi]) and
        ``status`` (8,, :attr:`OPWStatus.code` values).  ``q`` is finite for finite input;
        mask it by status.  Precedence: SHOULDER_UNREACHABLE, ELBOW_UNREACHABLE,
        SHOULDER_SINGULAR, WRIST_SINGULAR.  Singular branches still carry a solution that
        reproduces the pose (shoulder: phi1 = polar angle of the wrist centre; wrist:
        joint 4 held at q4 = 0 on "noflip", phi4 + pi on "flip", phi6 takes the rest).
    """
    T = ca.SX.sym("flange2base", 4, 4)
    Tc = ca.mtimes([ca.DM(np.linalg.inv(geom.canon2base)), T, ca.DM(np.linalg.inv(geom.flange2canon_flange))])
    R, P = Tc[:3, :3], Tc[:3, 3]
    Cw = P - geom.c4 * R[:, 2]
    arms, cosines, sh_unreach, sh_sing = _ik_arm(geom, Cw)
    qs, codes = [], []
    for k, phi123 in enumerate(arms):
        wrists, s5 = _ik_wrist(geom, R, phi123)
        for phi456 in wrists:
            phi = ca.vertcat(*phi123, phi456)
            q = (phi - ca.DM(geom.offsets)) * ca.DM(geom.signs)
            qs.append(q - TWO_PI * ca.ceil((q - np.pi) / TWO_PI))
            code = ca.if_else(
                s5 < OPW_WRIST_SINGULAR_TOL, float(OPWStatus.WRIST_SINGULAR.code), float(OPWStatus.OK.code)
            )
            code = ca.if_else(sh_sing, float(OPWStatus.SHOULDER_SINGULAR.code), code)
            code = ca.if_else(
                ca.fabs(cosines[k // 2]) > 1.0 + OPW_CLIP_TOL, float(OPWStatus.ELBOW_UNREACHABLE.code), code
            )
            code = ca.if_else(sh_unreach, float(OPWStatus.SHOULDER_UNREACHABLE.code), code)
            codes.append(code)
    return ca.Function("opw_ik", [T], [ca.horzcat(*qs), ca.vertcat(*codes)], ["flange2base"], ["q", "status"])


def opw_ik(fun: ca.Function, flange2base: Any) -> tuple[np.ndarray, np.ndarray]:
    """Evaluate :func:`opw_ik_function` over a batch of poses (CasADi ``map``).

    Parameters
    ----------
    fun : casadi.Function
        From :func:`opw_ik_function`.
    flange2base : array_like, shape (N, 4, 4) or (4, 4)
        Target flange poses, base frame (m).

    Returns
    -------
    q : ndarray, shape (N, 8, 6)
        Joint values (rad) per branch; not masked (see ``status``).
    status : ndarray of int, shape (N, 8)
        :attr:`OPWStatus.code` values.
    """
    T = np.asarray(flange2base, dtype=float).reshape(-1, 4, 4)
    n = T.shape[0]
    q, st = fun.map(n)(np.hstack(list(T)))
    q = np.asarray(q).reshape(6, n, 8).transpose(1, 2, 0)
    status = np.rint(np.asarray(st)).astype(int).T.reshape(n, 8)
    return q, status


# --------------------------------------------------------------------------- branch guards


def opw_guard_factors(geom: OPWGeometry, q: Any) -> Any:
    """Three smooth functions of q whose signs identify the branch.

    Parameters
    ----------
    geom : OPWGeometry
    q : casadi.SX, shape (6,) or ndarray, shape (..., 6)
        Joint values (rad).

    Returns
    -------
    casadi.SX, shape (3,) or ndarray, shape (..., 3)
        ``[shoulder, elbow, wrist]``: the signed horizontal distance (m) of the wrist
        centre from axis 1 along the arm-plane x direction (zero where the wrist centre
        is at distance |b| from axis 1); ``sin(phi3 + atan2(a2, c3))`` (zero with the arm
        stretched or folded); ``sin(phi5)`` (zero at the wrist singularity).  Expected
        signs per branch: :func:`opw_branch_signs`.
    """
    gamma = float(np.arctan2(geom.a2, geom.c3))
    if isinstance(q, (ca.SX, ca.MX)):
        phi = [geom.signs[i] * q[i] + geom.offsets[i] for i in range(6)]
        sin, cos = ca.sin, ca.cos
    else:
        qa = np.asarray(q, dtype=float)
        qa = qa.ravel() if isinstance(q, ca.DM) else qa
        phi = [geom.signs[i] * qa[..., i] + geom.offsets[i] for i in range(6)]
        sin, cos = np.sin, np.cos
    p23 = phi[1] + phi[2]
    shoulder = geom.a1 + geom.c2 * sin(phi[1]) + geom.c3 * sin(p23) + geom.a2 * cos(p23)
    elbow = sin(phi[2] + gamma)
    wrist = sin(phi[4])
    if isinstance(q, (ca.SX, ca.MX)):
        return ca.vertcat(shoulder, elbow, wrist)
    return np.stack([shoulder, elbow, wrist], axis=-1)


def opw_branch_signs() -> np.ndarray:
    """Expected signs of :func:`opw_guard_factors` per branch, shape (8, 3), entries +-1.

    Row ``4*shoulder + 2*elbow + wrist``: shoulder +1 front / -1 back; elbow factor +1
    for front-up and back-down, -1 for front-down and back-up; wrist +1 noflip / -1 flip.
    """
    out = np.empty((8, 3))
    for k in range(8):
        sh, el, wr = k // 4, (k // 2) % 2, k % 2
        out[k] = (1 - 2 * sh, (1 - 2 * el) * (1 - 2 * sh), 1 - 2 * wr)
    return out
