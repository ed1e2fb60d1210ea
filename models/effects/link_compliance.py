"""Link (and Cartesian) compliance: displacement of a point that does not pass through the joints.

Every link at least :data:`LINK_BEAM_MIN_FRACTION` as long as the longest carries a 6x6
compliance at its distal joint, in its beam frame (axis 1 along the link,
:func:`beam_frames`): translational and rotational diagonals and the six
translation-rotation couplings (``delta = C_tt f + C_tr m_tip``, ``phi = C_tr^T f + C_rr m_tip``),
which contain the Euler-Bernoulli beam and lumped ("virtual joint") springs.  Plus 3x3 symmetric
translational compliances at the point in the tool and the base frame.  The point moves by
``delta + phi x (point - p_tip)`` per link.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from models.robot import Robot

from .base import ConstGroup, Effect, ParamGroup, link_lengths, mean_compliance, register

#: A link takes part when its length is at least this fraction of the longest link (dimensionless).
LINK_BEAM_MIN_FRACTION = 0.3

_KEYS = ("tt_xx", "tt_yy", "tt_zz", "rr_xx", "rr_yy", "rr_zz", "tr_xy", "tr_xz", "tr_yx", "tr_yz", "tr_zx", "tr_zy")
_SYM = ("xx", "yy", "zz", "xy", "xz", "yz")
_UNITS = ("m/N",) * 3 + ("rad/(N*m)",) * 3 + ("m/(N*m)",) * 6


def beam_links(robot: Robot) -> list[int]:
    lengths = link_lengths(robot)
    return [i for i in range(6) if lengths[i] >= LINK_BEAM_MIN_FRACTION * lengths.max()]


def _link_scale(robot: Robot) -> np.ndarray:
    c, lmax = mean_compliance(robot), float(link_lengths(robot).max())
    s = np.r_[np.full(3, 0.1 * c * lmax**2), np.full(3, 0.1 * c), np.full(6, 0.1 * c * lmax)]
    return np.tile(s, 6)


def _link_eligible(robot: Robot) -> np.ndarray:
    el = np.zeros((6, 12), dtype=bool)
    el[beam_links(robot), :] = True
    return el.reshape(-1)


def _point_scale(robot: Robot) -> float:
    return 0.1 * mean_compliance(robot) * float(link_lengths(robot).max()) ** 2


def beam_frames(robot: Robot) -> np.ndarray:
    """Axes of the beam of each link in its DH link frame, shape (6, 3, 3).

    Column 0 is the unit vector from joint i to joint i+1 (to the flange for link 6) in link
    frame i; columns 1, 2 complete a right-handed frame.  From the nominal geometry at q = 0.
    """
    from .graph import chain

    dh = {k: ca.DM(v) for k, v in robot.nominal_dh().items() if v is not None}
    fr = [np.asarray(ca.DM(T)) for T in chain(ca.DM.zeros(6), dh, robot.convention)]
    pts = ([np.zeros(3)] + [T[:3, 3] for T in fr[:5]]) if robot.convention == "standard_dh" else [T[:3, 3] for T in fr]
    out = np.zeros((6, 3, 3))
    for i in range(6):
        tip = pts[i + 1] if i < 5 else fr[5][:3, 3]
        seg = fr[i][:3, :3].T @ (tip - pts[i])
        if np.linalg.norm(seg) < 1e-9:
            seg = np.array([1.0, 0.0, 0.0])
        e1 = seg / np.linalg.norm(seg)
        ref = np.array([0.0, 0.0, 1.0]) if abs(e1[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        e2 = ref - (ref @ e1) * e1
        e2 /= np.linalg.norm(e2)
        out[i] = np.column_stack([e1, e2, np.cross(e1, e2)])
    return out


def _sym3(v: Any) -> Any:
    return ca.vertcat(ca.horzcat(v[0], v[3], v[4]), ca.horzcat(v[3], v[1], v[5]), ca.horzcat(v[4], v[5], v[2]))


@register
class LinkCompliance(Effect):
    name = "link_compliance"
    order = 9
    groups = (
        ParamGroup(
            "link_compliance.link",
            tuple(f"link_compliance.link{i + 1}.{k}" for i in range(6) for k in _KEYS),
            _UNITS * 6,
            scale=_link_scale,
            eligible=_link_eligible,
        ),
        ParamGroup("link_compliance.tool", tuple(f"link_compliance.tool.{k}" for k in _SYM), "m/N", scale=_point_scale),
        ParamGroup("link_compliance.base", tuple(f"link_compliance.base.{k}" for k in _SYM), "m/N", scale=_point_scale),
    )
    constants = (
        ConstGroup(
            "link_compliance.beams",
            54,
            lambda r: np.concatenate([b.reshape(-1, order="F") for b in beam_frames(r)]),
            "beam frame of each link in its DH frame (6 x 3x3, column-major)",
        ),
    )
    needs = ("load",)
    formula = (
        "beam springs (6x6 compliance, 12 terms) at the distal end of each long link, plus translational "
        "3x3 compliances at the point in the tool and base frames"
    )
    simulation = "link_compliance"

    def point_displacement(self, ctx: Any, point: Any) -> Any:
        f, m = ctx.wrench[0:3], ctx.wrench[3:6]
        p_app = ctx.load_point()
        lc = ctx.p("link_compliance.link")
        beams = ctx.c("link_compliance.beams")
        links = ctx.eligible_of("link_compliance.link").reshape(6, 12).any(axis=1)
        dp = ca.DM.zeros(3)
        for i in range(6):
            if not links[i]:
                continue
            R = ca.mtimes(ctx.frames[i][:3, :3], ca.reshape(beams[9 * i : 9 * i + 9], 3, 3))
            p_tip = ctx.ps[i + 1] if i < 5 else ctx.frames[5][:3, 3]
            m_tip = m + ca.cross(p_app - p_tip, f)
            fl, ml = ca.mtimes(R.T, f), ca.mtimes(R.T, m_tip)
            k = lc[12 * i : 12 * i + 12]
            Ctr = ca.vertcat(ca.horzcat(0, k[6], k[7]), ca.horzcat(k[8], 0, k[9]), ca.horzcat(k[10], k[11], 0))
            delta = k[0:3] * fl + ca.mtimes(Ctr, ml)
            phi = ca.mtimes(Ctr.T, fl) + k[3:6] * ml
            dp = dp + ca.mtimes(R, delta + ca.cross(phi, ca.mtimes(R.T, point - p_tip)))
        Rt = ctx.R_tcp
        dp = dp + ca.mtimes(Rt, ca.mtimes(_sym3(ctx.p("link_compliance.tool")), ca.mtimes(Rt.T, f)))
        return dp + ca.mtimes(_sym3(ctx.p("link_compliance.base")), f)
