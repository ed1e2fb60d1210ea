"""Per-joint angle error maps: the error motion of each joint as a function of its own angle.

Joint j's DH row gets, per component ``c`` of :data:`MAP_COMPONENTS` (``theta``: angular
positioning error; ``d``: axial; ``a``: radial along the link's x axis; ``alpha``, ``beta``:
tilts about the link's x and y axes -- the error motions of ISO 230-7 expressed in DH terms),

``p_c,j += e_cj(q_c,j)``,  ``e_cj(q) = sum_s a_cjs cos(f_cjs q) + b_cjs sin(f_cjs q)``

a Fourier series of the *commanded* angle ``q_c,j`` (the transmission error of a strain-wave
or cycloidal gear, a bearing's runout and wobble, an output encoder's error: functions of the
joint's own angle, what machine tools compensate with axis error tables).

* ``f_js`` (constants ``error_map.freq``, cycles per revolution; 0: slot unused) are chosen
  from the residual by :mod:`problems.identify.error_map` (a cross-validated spectrum search
  with a significance test), up to :data:`MAP_SLOTS` per joint;
* ``a_js, b_js`` (parameters ``error_map.c``, rad) are fitted like every other parameter;
* ``[lo_j, hi_j]`` (constants ``error_map.range``, rad) is the angle range the data covered.
  The map is a function of the joint's angle everywhere, beyond that range too: a gear's error
  follows the gear's angle, which turns with the joint's (a whole number of cycles per revolution
  repeats every turn; another frequency, an intermediate stage's, continues as the same sinusoid).
  What it says beyond the range is as good as the data that determined it: the model's sigma grows
  there (:mod:`problems.identify.sigma_calibration`).  (Model files written before issue 37 held a
  map at its end value beyond the range.)

The parameters of unused slots are not in use (:meth:`JointErrorMap.in_use`: not eligible, no
Jacobian column), so a model without a map costs nothing.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from .base import ConstGroup, Effect, ParamGroup, register

#: Components of a joint's error motion (DH row entries) and their SI units.
MAP_COMPONENTS = ("theta", "d", "a", "alpha", "beta")
MAP_UNITS = ("rad", "m", "m", "rad", "rad")
N_COMP = len(MAP_COMPONENTS)
#: Fourier terms (slots) per joint and component.
MAP_SLOTS = 6
#: Default range bound (no clipping), rad.
MAP_RANGE_OPEN_RAD = 1.0e3
#: The constant blocks an identified model carries for its maps.
MAP_CONST_KEYS = ("error_map.freq", "error_map.range")
#: Typical magnitude of a map coefficient, rad or m (10 urad, 10 um).
MAP_COEF_SCALE = 1e-5
#: Shape of the coefficient block ``error_map.c`` and of ``error_map.freq`` (joint, component, slot).
COEF_SHAPE = (6, N_COMP, MAP_SLOTS, 2)
FREQ_SHAPE = (6, N_COMP, MAP_SLOTS)


def _labels() -> tuple[str, ...]:
    return tuple(
        f"error_map.q{j + 1}.{c}.s{s + 1}.{f}"
        for j in range(6)
        for c in MAP_COMPONENTS
        for s in range(MAP_SLOTS)
        for f in ("cos", "sin")
    )


def slot_index(j: int, c: int, s: int) -> tuple[int, int]:
    """Offsets of the cos and sin coefficients of joint ``j``, component ``c``, slot ``s`` (0-based)
    in ``error_map.c``."""
    k = 2 * ((N_COMP * j + c) * MAP_SLOTS + s)
    return k, k + 1


@register
class JointErrorMap(Effect):
    name = "joint_error_map"
    order = 12
    groups = (
        ParamGroup(
            "error_map.c",
            _labels(),
            tuple(u for _j in range(6) for u in MAP_UNITS for _s in range(2 * MAP_SLOTS)),
            scale=MAP_COEF_SCALE,
        ),
    )
    constants = (
        ConstGroup(
            "error_map.freq",
            int(np.prod(FREQ_SHAPE)),
            0.0,
            "frequency of each slot (joint, component, slot; row-major), cycles per revolution; 0: unused",
        ),
        ConstGroup(
            "error_map.range",
            12,
            lambda r: np.tile([-MAP_RANGE_OPEN_RAD, MAP_RANGE_OPEN_RAD], 6),
            "angle range of each joint's map (6 x [lo, hi]), rad: the data's range (the map continues beyond it)",
        ),
    )
    formula = (
        "per-joint angle error maps: DH entry c of joint j (theta, d, a, alpha, beta) += sum_s a cos(f q_c,j) "
        "+ b sin(f q_c,j), harmonics f (cycles/rev) chosen by a cross-validated spectrum search with a "
        "family-wise test, a function of q_c,j everywhere (continued beyond the range the data covered)"
    )
    simulation = "eccentricity"

    def in_use(self, const: Any) -> dict[str, np.ndarray]:
        """The coefficients of slots with a frequency."""
        return {"error_map.c": np.repeat(np.asarray(const("error_map.freq")).reshape(-1) != 0, 2)}

    @staticmethod
    def joints_with_map(param: Any) -> np.ndarray:
        """Joints (bool, (6,)) whose map has a nonzero term (not ``joints_acting``: the map does not
        depend on torque, so the torque range of the data does not limit it; its angle range does)."""
        return np.any(np.asarray(param("error_map.c")).reshape(6, -1) != 0.0, axis=1)

    def geometry(self, ctx: Any, dh: dict[str, Any]) -> dict[str, Any]:
        if ctx.qc is None:
            return dh
        c, f = ctx.p("error_map.c"), ctx.c("error_map.freq")
        used = self._slots_used(ctx, c, f)
        if not used.any():
            return dh
        out = dict(dh)
        for k, comp in enumerate(MAP_COMPONENTS):
            if not used[:, k].any():
                continue
            terms = []
            for j in range(6):
                acc: Any = 0
                if used[j, k].any():
                    qj = ctx.qc[j]  # the map is a function of the joint's angle everywhere (not held)
                    for s in np.flatnonzero(used[j, k]):
                        kc, ks = slot_index(j, k, int(s))
                        fs = f[(N_COMP * j + k) * MAP_SLOTS + int(s)]
                        acc = acc + c[kc] * ca.cos(fs * qj) + c[ks] * ca.sin(fs * qj)
                terms.append(acc)
            key = "theta_offset" if comp == "theta" else comp
            out[key] = dh[key] + ca.vertcat(*terms)
        return out

    @staticmethod
    def _slots_used(ctx: Any, c: Any, f: Any) -> np.ndarray:
        """Slots (6, N_COMP, MAP_SLOTS) that enter the graph: with fixed numbers (planning) those with a
        frequency and a nonzero coefficient; with symbols (identification) the eligible ones."""
        cs, fsx = ca.SX(c), ca.SX(f)
        if cs.is_constant() and fsx.is_constant():
            cv = np.asarray(ca.DM(cs)).reshape(COEF_SHAPE)
            fv = np.asarray(ca.DM(fsx)).reshape(FREQ_SHAPE)
            return (fv != 0) & np.any(cv != 0, axis=3)
        el = np.asarray(ctx.eligible_of("error_map.c"), dtype=bool).reshape(COEF_SHAPE)
        return np.any(el, axis=3)
