"""The virtual robot: a measurement-campaign simulator with optional effects.

It is the project's own test bench for ``compplan identify``.  It is written
independently of the identification model (:mod:`models.effects`): NumPy
kinematics, physical forms of the effects (a two-slope hardening curve, a hard
dead band, Euler-Bernoulli beams, COM Jacobians for gravity), so that a test
passes only if the identification's parametrisation covers the physics rather
than reproduces its own formulas.

The configuration is a TOML table (schema in ``docs/identification.md``, examples
in ``problems/files/sim/``).  :meth:`VirtualRobot.truth` returns every realised
parameter, so a campaign can be re-measured after compensation.

A campaign measures the position of the measured point and, with ``[campaign]
orientation = true``, the orientation of the measured frame (the TCP's orientation,
carried to the measured point) as a rotation vector in the measurement frame.

Conventions as everywhere: SI units, wrench ``[f; m]`` in the base frame acting
on the TCP, a joint yields in the direction of the torque applied to it.
"""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from models.errors import InputError
from models.robot import Robot, load_robot
from models.transforms import matrix_to_rotvec, rotvec_to_matrix  # noqa: F401 - re-exported

from .measurements import Measurements

#: Fixed-point tolerance of the simulator's deflected equilibrium (rad).
SIM_EQUILIBRIUM_TOL = 1e-13
#: Maximum fixed-point iterations of the simulator.
SIM_EQUILIBRIUM_MAX_ITER = 200
#: Candidate poses drawn per requested pose when sampling the workspace.
SIM_POSE_OVERSAMPLING = 40
#: Jacobian condition number above which a sampled pose is rejected (too close to
#: a singularity to be a sensible measurement pose).
SIM_MAX_JACOBIAN_COND = 200.0

#: Largest amplitude of one periodic joint-error term (rad): a transmission error, not an offset.
SIM_JOINT_ERROR_MAX_AMPLITUDE_RAD = 0.05
#: Largest harmonic (cycles per revolution of the joint) of a periodic joint-error term.
SIM_JOINT_ERROR_MAX_HARMONIC = 200.0

#: Effects the simulator knows: the library ones and some outside the library.
#: ``joint_error_map`` is the same simulated physics as ``eccentricity`` (periodic joint
#: transmission errors), spelled as the library effect that models it; give one of the two.
SIM_EFFECTS = ("gravity", "stiffness_hardening", "lost_motion", "joint_offset", "geometric",
               "load_offset", "link_compliance", "drift", "thermal", "eccentricity", "joint_error_map",
               "outliers")
#: Effects the identification library does not contain (for negative tests).
OUT_OF_LIBRARY = ("eccentricity",)
#: The two spellings of the periodic joint-error effect (``[effects.NAME]``).
JOINT_ERROR_EFFECTS = ("eccentricity", "joint_error_map")

_TOP_KEYS = {"seed", "campaign", "noise", "registration", "temperature", "stiffness", "effects", "units"}
#: Largest number of rows a simulated campaign may have (poses x rows per pose).
SIM_MAX_ROWS = 1_000_000


class SimConfigError(InputError):
    """A simulation configuration is malformed; the message names the key."""


# ----------------------------------------------------------------------------------
# NumPy kinematics (vectorised over rows, per-row DH parameters allowed)
# ----------------------------------------------------------------------------------

def _link(theta: np.ndarray, d: np.ndarray, a: np.ndarray, alpha: np.ndarray, beta: np.ndarray,
          convention: str) -> np.ndarray:
    n = theta.shape[0]
    ct, st = np.cos(theta), np.sin(theta)
    ca_, sa = np.cos(alpha), np.sin(alpha)
    A = np.zeros((n, 4, 4))
    if convention == "standard_dh":
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = ct, -st * ca_, st * sa, a * ct
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st, ct * ca_, -ct * sa, a * st
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca_, d
    else:
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 3] = ct, -st, a
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st * ca_, ct * ca_, -sa, -sa * d
        A[:, 2, 0], A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = st * sa, ct * sa, ca_, ca_ * d
    A[:, 3, 3] = 1.0
    if np.any(beta != 0):
        cb, sb = np.cos(beta), np.sin(beta)
        Ry = np.zeros((n, 4, 4))
        Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2], Ry[:, 3, 3] = cb, sb, 1, -sb, cb, 1
        A = A @ Ry
    return A


@dataclass
class _Geometry:
    """Per-row DH parameters, shape (N, 6) each."""

    a: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    toff: np.ndarray
    beta: np.ndarray


def _frames(q: np.ndarray, g: _Geometry, convention: str) -> np.ndarray:
    """Frames frame_i2base (i = 1..6), shape (N, 6, 4, 4)."""
    n = q.shape[0]
    out = np.zeros((n, 6, 4, 4))
    T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for i in range(6):
        T = T @ _link(q[:, i] + g.toff[:, i], g.d[:, i], g.a[:, i], g.alpha[:, i], g.beta[:, i], convention)
        out[:, i] = T
    return out


def _axes(frames: np.ndarray, convention: str) -> tuple[np.ndarray, np.ndarray]:
    """Joint axes z_i and points p_i, shape (N, 6, 3) each."""
    n = frames.shape[0]
    if convention == "standard_dh":
        z = np.concatenate([np.broadcast_to([0.0, 0.0, 1.0], (n, 1, 3)), frames[:, :5, :3, 2]], axis=1)
        p = np.concatenate([np.zeros((n, 1, 3)), frames[:, :5, :3, 3]], axis=1)
    else:
        z, p = frames[:, :, :3, 2], frames[:, :, :3, 3]
    return z, p


def _tau_point(z: np.ndarray, p: np.ndarray, point: np.ndarray, f: np.ndarray, m: np.ndarray,
               first: int = 0) -> np.ndarray:
    """Joint torques of force f at ``point`` and moment m: z_i . ((point - p_i) x f + m)."""
    lever = point[:, None, :] - p
    tau = np.einsum("nij,nij->ni", z, np.cross(lever, f[:, None, :]) + m[:, None, :])
    tau[:, :first] = 0.0
    return tau


def rotvecs(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis x angle, rad, angle in [0, pi]) of rotations (N, 3, 3) -> (N, 3)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(np.asarray(R, dtype=float).reshape(-1, 3, 3)).as_rotvec()


# ----------------------------------------------------------------------------------
# Configuration
# ----------------------------------------------------------------------------------

def _num(where: str, key: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise SimConfigError(f"{where}: key '{key}' must be a finite number, got {v!r}")
    return float(v)


def _vec(where: str, key: str, v: Any, n: int, broadcast: bool = True) -> np.ndarray:
    if broadcast and isinstance(v, (int, float)) and not isinstance(v, bool):
        return np.full(n, _num(where, key, v))
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise SimConfigError(f"{where}: key '{key}' must be {'a number or ' if broadcast else ''}"
                             f"a list of {n} numbers, got {v!r}")
    return np.array([_num(where, f"{key}[{i}]", x) for i, x in enumerate(v)])


def _at_least(where: str, key: str, v: float | np.ndarray, lo: float, strict: bool = False,
              what: str = "") -> None:
    """Refuse values below ``lo`` (or equal to it when ``strict``), naming the key and the value."""
    arr = np.atleast_1d(np.asarray(v, dtype=float))
    bad = np.flatnonzero(arr <= lo) if strict else np.flatnonzero(arr < lo)
    if bad.size:
        i = int(bad[0])
        k = key if arr.size == 1 and np.ndim(v) == 0 else f"{key}[{i}]"
        raise SimConfigError(f"{where}: key '{k}' must be {'>' if strict else '>='} {lo:g}"
                             f"{' ' + what if what else ''}, got {float(arr[i]):g}")


def _int(where: str, key: str, v: Any, lo: int) -> int:
    """An integer >= ``lo`` (a float such as 20.5 or a string is refused)."""
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise SimConfigError(f"{where}: key '{key}' must be an integer >= {lo}, got {v!r}")
    return int(v)


def _bool(where: str, key: str, v: Any) -> bool:
    if not isinstance(v, bool):
        raise SimConfigError(f"{where}: key '{key}' must be true or false, got {v!r}")
    return v


def _magnitudes(where: str, key: str, v: Any) -> np.ndarray:
    """A number or a non-empty list of finite numbers >= 0 (force or moment magnitudes)."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        out = np.array([_num(where, key, v)])
    elif isinstance(v, list) and v:
        out = np.array([_num(where, f"{key}[{i}]", x) for i, x in enumerate(v)])
    else:
        raise SimConfigError(f"{where}: key '{key}' must be a number or a non-empty list of numbers, got {v!r}")
    _at_least(where, key, out if isinstance(v, list) else out[0], 0.0)
    return out


def _table(where: str, cfg: Mapping[str, Any], key: str, allowed: set[str]) -> dict[str, Any]:
    t = cfg.get(key, {})
    if not isinstance(t, Mapping):
        raise SimConfigError(f"{where}: '{key}' must be a table")
    unknown = sorted(set(t) - allowed)
    if unknown:
        raise SimConfigError(f"{where}: [{key}]: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    return dict(t)


def _joint_list(where: str, links: Any) -> list[int]:
    """``links``, checked to be a list of joint numbers 1..6 (``where``: the table, for messages)."""
    if not isinstance(links, list) or not all(isinstance(x, int) and 1 <= x <= 6 for x in links):
        raise SimConfigError(f"{where}: key 'links' must be a list of joint numbers 1..6, got {links!r}")
    return links


_EFFECT_KEYS: dict[str, set[str]] = {
    "gravity": {"masses_kg", "coms_m", "mass_scale", "payload_kg", "payload_com_m"},
    "stiffness_hardening": {"model", "knee_torque_Nm", "stiffness_ratio", "beta_per_Nm"},
    "lost_motion": {"backlash_rad", "smoothing_Nm"},
    "joint_offset": {"dtheta_rad"},
    "geometric": {"sigma_length_m", "sigma_angle_rad", "da_m", "dalpha_rad", "dd_m", "dtheta_rad", "dbeta_rad"},
    "load_offset": {"r_tool_m"},
    "link_compliance": {"links", "EI_Nm2", "GJ_Nm2"},
    "drift": {"rate_m_per_h", "accel_m_per_h2"},
    "thermal": {"alpha_per_K", "links", "reference_C"},
    "eccentricity": {"joint", "amplitude_rad", "harmonic", "phase_rad"},
    "joint_error_map": {"joint", "amplitude_rad", "harmonic", "phase_rad"},
    "outliers": {"fraction", "magnitude_m"},
}

DEFAULT_CAMPAIGN = {
    "poses": 100, "unloaded_rows": 1, "loaded_rows": 3, "force_magnitudes_N": [50.0, 100.0, 150.0],
    "moment_magnitudes_Nm": [0.0], "directions": "random", "dt_s": 20.0, "r_min_m": 0.25,
    "z_min_m": -0.2, "repeats": 0, "orientation": False,
}
#: Keys of the ``[noise]`` table and their defaults.
DEFAULT_NOISE = {"sigma_m": 2e-5, "sigma_column": False, "sigma_rad": 2e-5, "sigma_rot_column": False}


def load_config(path: str | Path) -> dict[str, Any]:
    """Read a simulation configuration TOML file."""
    from models.robot import read_text_file

    p = Path(path)
    text = read_text_file(p, "simulation configuration file (TOML)", SimConfigError)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SimConfigError(f"{p}: not valid TOML: {exc}") from None


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



# ----------------------------------------------------------------------------------
# The virtual robot
# ----------------------------------------------------------------------------------

class VirtualRobot:
    """A robot with 'true' parameters and effects, and a measurement system.

    Parameters
    ----------
    robot : Robot
        The nominal (declared) description.
    config : mapping
        Parsed configuration (schema in ``docs/identification.md``).
    seed : int, optional
        Seed of the random parts (geometric errors, poses, loads, noise);
        overrides ``config['seed']``.
    where : str
        Name of the configuration source for error messages.
    """

    def __init__(self, robot: Robot, config: Mapping[str, Any], seed: int | None = None,
                 where: str = "simulation config") -> None:
        cfg = dict(config)
        unknown = sorted(set(cfg) - _TOP_KEYS)
        if unknown:
            raise SimConfigError(f"{where}: unknown top-level key(s) {unknown}; allowed: {sorted(_TOP_KEYS)}")
        self.robot = robot
        self.where = where
        self.config = copy.deepcopy(cfg)
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
                raise SimConfigError(f"{where}: seed {seed!r}: expected an integer >= 0")
            self.seed = int(seed)
        else:
            self.seed = _int(where, "seed", cfg.get("seed", 0), 0)
        units = cfg.get("units", "SI")
        if units not in ("SI", "mm"):
            raise SimConfigError(f"{where}: key 'units' must be 'SI' or 'mm', got {units!r}")
        rng = np.random.default_rng(self.seed)
        self.convention = robot.convention
        # --- stiffness (true joint stiffness of the "declared" model)
        st = _table(where, cfg, "stiffness", {"scale"})
        scale = _vec(f"{where}: [stiffness]", "scale", st.get("scale", 1.0), 6)
        _at_least(f"{where}: [stiffness]", "scale", scale if isinstance(st.get("scale"), list) else scale[0],
                  0.0, strict=True)
        self.k_true = robot.stiffness * scale
        # --- registration and measured point
        reg = _table(where, cfg, "registration", {"registered", "base2meas_xyz_m", "base2meas_rotvec_rad",
                                                  "measured_point_m"})
        self.registered = _bool(f"{where}: [registration]", "registered", reg.get("registered", False))
        if self.registered:
            self.R_reg, self.t_reg = np.eye(3), np.zeros(3)
            self.p_tool = robot.tcp2flange[:3, 3].copy()
        else:
            self.R_reg = rotvec_to_matrix(_vec(where, "base2meas_rotvec_rad",
                                               reg.get("base2meas_rotvec_rad", [0.02, -0.01, 0.6]), 3, False))
            self.t_reg = _vec(where, "base2meas_xyz_m", reg.get("base2meas_xyz_m", [1.5, -0.5, 0.2]), 3, False)
            self.p_tool = _vec(where, "measured_point_m", reg.get("measured_point_m", [0.02, -0.015, 0.06]),
                               3, False)
        # --- effects
        eff = cfg.get("effects", {})
        if not isinstance(eff, Mapping):
            raise SimConfigError(f"{where}: 'effects' must be a table of [effects.NAME] tables")
        unknown = sorted(set(eff) - set(SIM_EFFECTS))
        if unknown:
            raise SimConfigError(f"{where}: unknown effect(s) {unknown}; known: {list(SIM_EFFECTS)}")
        self.effects: dict[str, dict[str, Any]] = {}
        for name, t in eff.items():
            if not isinstance(t, Mapping):
                raise SimConfigError(f"{where}: [effects.{name}] must be a table")
            bad = sorted(set(t) - _EFFECT_KEYS[name])
            if bad:
                raise SimConfigError(f"{where}: [effects.{name}]: unknown key(s) {bad}; "
                                     f"allowed: {sorted(_EFFECT_KEYS[name])}")
            self.effects[name] = dict(t)
        both = [name for name in JOINT_ERROR_EFFECTS if name in self.effects]
        if len(both) > 1:
            raise SimConfigError(f"{where}: [effects.eccentricity] and [effects.joint_error_map] are two spellings "
                                 "of the same effect (periodic joint errors); give one of them, with all its "
                                 "terms as lists")
        self._realise(rng)

    # ------------------------------------------------------------------ realisation
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
            raise ValueError(f"joint_error: q_c must have shape (N, 6), got {q_c.shape}")
        err = np.zeros(q_c.shape)
        for j, a, h, ph in zip(self.ecc_joint, self.ecc_amp, self.ecc_harm, self.ecc_phase):
            err[:, j] += float(a) * np.sin(float(h) * q_c[:, j] + float(ph))
        return err

    # ------------------------------------------------------------------ physics
    def _geometry(self, temperature: np.ndarray) -> _Geometry:
        r = self.robot
        n = len(temperature)
        a = np.tile(r.a + self.da, (n, 1))
        d = np.tile(r.d + self.dd, (n, 1))
        if "thermal" in self.effects:
            s = 1.0 + self.th_alpha * (temperature - self.th_ref)
            for i in self.th_links:
                a[:, i] *= s
                d[:, i] *= s
        return _Geometry(a=a, alpha=np.tile(r.alpha + self.dalpha, (n, 1)), d=d,
                         toff=np.tile(r.theta_offset + self.dtheta, (n, 1)),
                         beta=np.tile(self.dbeta, (n, 1)))

    def _tool(self) -> np.ndarray:
        return self.robot.tcp2flange

    def _torques(self, q: np.ndarray, F: np.ndarray, geo: _Geometry) -> np.ndarray:
        fr = _frames(q, geo, self.convention)
        z, p = _axes(fr, self.convention)
        tcp = fr[:, 5] @ self._tool()
        f, m = F[:, :3], F[:, 3:]
        point = tcp[:, :3, 3] + np.einsum("nij,j->ni", tcp[:, :3, :3], self.r_tool)
        tau = _tau_point(z, p, point, f, m)
        if "gravity" in self.effects:
            g = self.robot.gravity
            for j in range(6):
                c = fr[:, j, :3, 3] + np.einsum("nij,j->ni", fr[:, j, :3, :3], self.coms[j])
                tau += _tau_point(z, p, c, np.broadcast_to(self.masses[j] * g, c.shape), np.zeros_like(c)) \
                    * (np.arange(6) <= j)[None, :]
            if self.payload > 0:
                c = fr[:, 5, :3, 3] + np.einsum("nij,j->ni", fr[:, 5, :3, :3], self.payload_com)
                tau += _tau_point(z, p, c, np.broadcast_to(self.payload * g, c.shape), np.zeros_like(c))
        return tau

    def _deflection(self, tau: np.ndarray) -> np.ndarray:
        k = self.k_true
        if "stiffness_hardening" in self.effects:
            if self.hard_model == "two_slope":
                a = np.abs(tau)
                lo = np.minimum(a, self.knee) / k
                hi = np.maximum(a - self.knee, 0.0) / (k * self.hard_ratio)
                dq = np.sign(tau) * (lo + hi)
            else:
                dq = tau / (k * (1.0 + self.hard_beta * np.abs(tau)))
        else:
            dq = tau / k
        if "lost_motion" in self.effects:
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
        _z, p = _axes(fr, self.convention)
        tcp = fr[:, 5] @ self._tool()
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
            delta = f_perp * L ** 3 / (3 * EI) + np.cross(m_perp, e) * L ** 2 / (2 * EI)
            phi = np.cross(e, f_perp) * L ** 2 / (2 * EI) + m_perp * L / EI + m_ax * L / GJ
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

    def _deflected_frames(self, q_c: np.ndarray, F: np.ndarray,
                          temperature: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Frames frame_i2base of the deflected arm (N, 6, 4, 4) and the wrench broadcast
        to (N, 6): equilibrium joints (plus periodic joint errors) on the true geometry."""
        q_c = np.atleast_2d(np.asarray(q_c, dtype=float))
        n = len(q_c)
        F = np.broadcast_to(np.asarray(F, dtype=float), (n, 6))
        T = np.full(n, 20.0) if temperature is None else np.asarray(temperature, dtype=float)
        q = self.equilibrium(q_c, F, T)
        return _frames(q, self._geometry(T), self.convention), F

    def positions(self, q_c: np.ndarray, F: np.ndarray, temperature: np.ndarray | None = None,
                  point: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """True position of a flange point and the TCP pose, base frame.

        Returns
        -------
        p_point : ndarray, shape (N, 3)
            Position of ``point`` (flange frame, m; default the measured point), m.
        tcp2base : ndarray, shape (N, 4, 4)
            TCP frame of the deflected arm (link compliance applied to the position only;
            :meth:`orientations` also turns the frame by the beams).
        """
        fr, F = self._deflected_frames(q_c, F, temperature)
        return self._positions_from_frames(fr, F, point)

    def _positions_from_frames(self, fr: np.ndarray, F: np.ndarray,
                               point: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`positions` from the deflected frames of :meth:`_deflected_frames`."""
        pt = self.p_tool if point is None else np.asarray(point, dtype=float)
        p_point = fr[:, 5, :3, 3] + np.einsum("nij,j->ni", fr[:, 5, :3, :3], pt)
        tcp = fr[:, 5] @ self._tool()
        if "link_compliance" in self.effects:
            p_point = p_point + self._beam_displacement(fr, F, p_point)
            tcp = tcp.copy()
            tcp[:, :3, 3] += self._beam_displacement(fr, F, tcp[:, :3, 3].copy())
        return p_point, tcp

    def orientations(self, q_c: np.ndarray, F: np.ndarray,
                     temperature: np.ndarray | None = None) -> np.ndarray:
        """True orientation of the measured frame, base frame, shape (N, 3, 3).

        The measured frame sits at the measured point with the TCP's orientation:
        ``R = exp([phi]) R_flange2base(q) R_tcp2flange``, ``q`` the deflected joints plus
        periodic joint errors on the true geometry (DH errors, joint offsets, thermal
        lengths), ``phi`` the summed tip rotations of the link beams (effect
        ``link_compliance``; zero without it).
        """
        fr, F = self._deflected_frames(q_c, F, temperature)
        return self._orientations_from_frames(fr, F)

    def _orientations_from_frames(self, fr: np.ndarray, F: np.ndarray) -> np.ndarray:
        """:meth:`orientations` from the deflected frames of :meth:`_deflected_frames`."""
        R = fr[:, 5, :3, :3] @ self._tool()[:3, :3]
        if "link_compliance" in self.effects:
            from scipy.spatial.transform import Rotation
            R = Rotation.from_rotvec(self._beam_rotation(fr, F)).as_matrix() @ R
        return R

    def _to_measurement_frame(self, p: np.ndarray, t: np.ndarray | None) -> np.ndarray:
        """Base-frame positions (N, 3) to the measurement frame, with drift at times ``t``, m."""
        pm = p @ self.R_reg.T + self.t_reg
        if "drift" in self.effects and t is not None:
            tt = np.asarray(t, dtype=float)[:, None]
            pm = pm + self.drift_rate * tt + self.drift_acc * tt ** 2
        return pm

    def measure(self, q_c: np.ndarray, F: np.ndarray, t: np.ndarray | None = None,
                temperature: np.ndarray | None = None) -> np.ndarray:
        """Noise-free measurement of the measured point, measurement frame, m, (N, 3)."""
        p, _tcp = self.positions(q_c, F, temperature)
        return self._to_measurement_frame(p, t)

    def measure_orientation(self, q_c: np.ndarray, F: np.ndarray,
                            temperature: np.ndarray | None = None) -> np.ndarray:
        """Noise-free orientation of the measured frame in the measurement frame,
        ``R_base2meas @ orientations(...)``, shape (N, 3, 3).  Drift (a translation of the
        instrument) does not turn it."""
        return self.R_reg @ self.orientations(q_c, F, temperature)

    def measure_rotvec(self, q_c: np.ndarray, F: np.ndarray,
                       temperature: np.ndarray | None = None) -> np.ndarray:
        """:meth:`measure_orientation` as rotation vectors (axis x angle, angle in [0, pi]),
        rad, shape (N, 3): the ``rx, ry, rz`` columns of a noise-free campaign."""
        return rotvecs(self.measure_orientation(q_c, F, temperature))

    def _measure_pose(self, q_c: np.ndarray, F: np.ndarray, t: np.ndarray | None,
                      temperature: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`measure` and :meth:`measure_orientation` from one equilibrium."""
        fr, F = self._deflected_frames(q_c, F, temperature)
        p, _tcp = self._positions_from_frames(fr, F)
        return self._to_measurement_frame(p, t), self.R_reg @ self._orientations_from_frames(fr, F)

    def tcp_error(self, q_command: np.ndarray, F: np.ndarray, target2base: np.ndarray,
                  temperature: np.ndarray | None = None) -> np.ndarray:
        """True TCP position minus target position, base frame, m, shape (N, 3)."""
        _p, tcp = self.positions(q_command, F, temperature)
        return tcp[:, :3, 3] - target2base[:, :3, 3]

    # ------------------------------------------------------------------ campaign
    def sample_poses(self, n: int, rng: np.random.Generator, r_min: float = 0.25,
                     z_min: float = -0.2, max_cond: float = SIM_MAX_JACOBIAN_COND) -> np.ndarray:
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
                raise SimConfigError(f"{self.where}: cannot find {n} poses in the workspace "
                                     f"(r >= {r_min} m, z >= {z_min} m); relax r_min_m/z_min_m")
        return np.vstack(kept)[:n]

    def campaign(self, progress: Callable[[int, int], None] | None = None,
                 seed: int | None = None) -> Measurements:
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
        camp = {**DEFAULT_CAMPAIGN, **_table(self.where, self.config, "campaign", set(DEFAULT_CAMPAIGN))}
        plan = self._campaign_plan(camp)
        orientation = _bool(f"{self.where}: [campaign]", "orientation", camp["orientation"])
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
            extra["rotation"] = rotvecs(self._campaign_rotation_noise(R, sigma_rad, rng))
            if rot_column:
                extra["sigma_rot"] = np.full((n, 3), sigma_rad)
        if progress is not None:
            progress(n, n)
        return Measurements(q=q, wrench=F, p=p, t=t, point=np.array(pts), temperature=temperature,
                            sigma=sig_col, source="virtual robot", **extra)

    def _rotation_noise_config(self, orientation: bool) -> tuple[float, bool]:
        """The orientation keys of ``[noise]``: ``sigma_rad`` (rad, >= 0; > 0 with the column)
        and ``sigma_rot_column`` (needs ``[campaign] orientation = true``)."""
        ncfg = _table(self.where, self.config, "noise", set(DEFAULT_NOISE))
        nw = f"{self.where}: [noise]"
        sigma = _num(nw, "sigma_rad", ncfg.get("sigma_rad", DEFAULT_NOISE["sigma_rad"]))
        column = _bool(nw, "sigma_rot_column", ncfg.get("sigma_rot_column", DEFAULT_NOISE["sigma_rot_column"]))
        _at_least(nw, "sigma_rad", sigma, 0.0, strict=column,
                  what="(a standard deviation, rad" + ("; the sigma_rot column needs it > 0)" if column else ")"))
        if column and not orientation:
            raise SimConfigError(f"{nw}: key 'sigma_rot_column' = true needs [campaign] orientation = true "
                                 "(there is no orientation to give a sigma for)")
        return sigma, column

    @staticmethod
    def _campaign_rotation_noise(R: np.ndarray, sigma_rad: float, rng: np.random.Generator) -> np.ndarray:
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
        n_poses = _int(cw, "poses", camp["poses"], 1)
        n_un = _int(cw, "unloaded_rows", camp["unloaded_rows"], 0)
        n_ld = _int(cw, "loaded_rows", camp["loaded_rows"], 0)
        n_rep = _int(cw, "repeats", camp["repeats"], 0)
        if n_un + n_ld == 0:
            raise SimConfigError(f"{cw}: keys 'unloaded_rows' and 'loaded_rows' are both 0; a pose needs at "
                                 "least one row")
        n_rows = n_poses * (n_un + n_ld + n_rep)
        if n_rows > SIM_MAX_ROWS:
            raise SimConfigError(f"{cw}: {n_poses} poses x {n_un + n_ld + n_rep} rows = {n_rows} rows, more than "
                                 f"the cap of {SIM_MAX_ROWS} rows (SIM_MAX_ROWS)")
        mags = _magnitudes(cw, "force_magnitudes_N", camp["force_magnitudes_N"])
        mmags = _magnitudes(cw, "moment_magnitudes_Nm", camp["moment_magnitudes_Nm"])
        dirs = camp["directions"]
        if dirs not in ("random", "axes", "down"):
            raise SimConfigError(f"{cw}: key 'directions' must be 'random', 'axes' or 'down', got {dirs!r}")
        dt = _num(cw, "dt_s", camp["dt_s"])
        _at_least(cw, "dt_s", dt, 0.0, strict=True, what="s (the time between rows)")
        r_min = _num(cw, "r_min_m", camp["r_min_m"])
        _at_least(cw, "r_min_m", r_min, 0.0)
        return _CampaignPlan(n_poses, n_un, n_ld, n_rep, mags, mmags, dirs, r_min, _num(cw, "z_min_m", camp["z_min_m"]))

    def _campaign_loads(self, q_poses: np.ndarray, plan: _CampaignPlan,
                        rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, list[str]]:
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

    def _campaign_times(self, camp: Mapping[str, Any], n: int,
                        rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray | None]:
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
        dt = _num(f"{self.where}: [campaign]", "dt_s", camp["dt_s"])
        t = np.arange(n) * dt
        tcfg = _table(self.where, self.config, "temperature", {"start_C", "end_C", "time_constant_s", "noise_C"})
        if not tcfg:
            return t, None
        tw = f"{self.where}: [temperature]"
        t0 = _num(tw, "start_C", tcfg.get("start_C", 20.0))
        t1 = _num(tw, "end_C", tcfg.get("end_C", t0))
        tau = _num(tw, "time_constant_s", tcfg.get("time_constant_s", max(t[-1], 1.0) / 2))
        _at_least(tw, "time_constant_s", tau, 0.0, strict=True, what="s")
        noise_c = _num(tw, "noise_C", tcfg.get("noise_C", 0.0))
        _at_least(tw, "noise_C", noise_c, 0.0, what="(a standard deviation, deg C)")
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
        ncfg = _table(self.where, self.config, "noise", set(DEFAULT_NOISE))
        nw = f"{self.where}: [noise]"
        sigma = _num(nw, "sigma_m", ncfg.get("sigma_m", DEFAULT_NOISE["sigma_m"]))
        column = _bool(nw, "sigma_column", ncfg.get("sigma_column", DEFAULT_NOISE["sigma_column"]))
        _at_least(nw, "sigma_m", sigma, 0.0, strict=column,
                  what="(a standard deviation, m" + ("; the sigma column needs it > 0)" if column else ")"))
        p = p + rng.normal(0, sigma, p.shape)
        sig_col = np.full(len(p), sigma) if column else None
        return p, sig_col

    def _campaign_outliers(self, p: np.ndarray, rng: np.random.Generator) -> None:
        """Effect ``outliers``: add gross errors to some rows of ``p`` in place.

        Sets :attr:`outlier_rows` (sorted row indices; empty without the effect).  Each
        outlier is a random direction times ``magnitude_m`` times a factor in [1, 2).

        Parameters
        ----------
        p : ndarray, shape (N, 3)
            Measured positions, measurement frame, m; modified in place.
        rng : Generator
            Draws the rows, then K x 3 normals (directions), then K uniforms (factors).
        """
        self.outlier_rows = np.zeros(0, dtype=int)
        if "outliers" not in self.effects:
            return
        n = len(p)
        e = self.effects["outliers"]
        ow = f"{self.where}: [effects.outliers]"
        frac = _num(ow, "fraction", e.get("fraction", 0.03))
        mag = _num(ow, "magnitude_m", e.get("magnitude_m", 2e-3))
        if not 0.0 <= frac <= 1.0:
            raise SimConfigError(f"{ow}: key 'fraction' must be in [0, 1] (a fraction of the rows), got {frac:g}")
        _at_least(ow, "magnitude_m", mag, 0.0)
        k = max(1, round(frac * n))
        idx = np.sort(rng.choice(n, size=k, replace=False))
        u = rng.normal(size=(k, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        p[idx] += u * mag * rng.uniform(1.0, 2.0, (k, 1))
        self.outlier_rows = idx

    # ------------------------------------------------------------------ truth
    def truth(self) -> dict[str, Any]:
        """Every realised parameter (SI), TOML-serialisable; rebuild with :func:`from_truth`."""
        out: dict[str, Any] = {
            "robot": self.robot.to_dict(), "config": self.config, "seed": self.seed,
            "realised": {
                "stiffness_Nm_per_rad": self.k_true.tolist(),
                "base2meas_rotvec_rad": matrix_to_rotvec(self.R_reg).tolist(),
                "base2meas_xyz_m": self.t_reg.tolist(),
                "measured_point_m": self.p_tool.tolist(),
                "da_m": self.da.tolist(), "dalpha_rad": self.dalpha.tolist(), "dd_m": self.dd.tolist(),
                "dtheta_rad": self.dtheta.tolist(), "dbeta_rad": self.dbeta.tolist(),
                "joint_error_terms": self.joint_error_terms(),
                "effects": sorted(self.effects),
            },
        }
        if getattr(self, "outlier_rows", None) is not None:
            out["realised"]["outlier_rows"] = [int(i) for i in self.outlier_rows]
        return out


def from_truth(truth: Mapping[str, Any]) -> VirtualRobot:
    """Rebuild a :class:`VirtualRobot` from :meth:`VirtualRobot.truth`."""
    from models.robot import robot_from_dict
    try:
        robot = robot_from_dict(truth["robot"], "truth: robot")
        return VirtualRobot(robot, truth["config"], seed=int(truth["seed"]), where="truth: config")
    except KeyError as exc:
        raise SimConfigError(f"truth: missing key {exc}") from None


def load_truth(path: str | Path) -> VirtualRobot:
    """Load a truth file written by ``compplan simulate``."""
    from models.robot import read_text_file

    p = Path(path)
    text = read_text_file(p, "truth file (TOML, written by compplan simulate)", SimConfigError)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SimConfigError(f"{p}: not valid TOML: {exc}") from None
    missing = [k for k in ("robot", "config", "seed") if k not in data]
    if missing:
        raise SimConfigError(f"{p}: not a truth file of compplan simulate (missing key(s) "
                             f"{', '.join(missing)}); give the .truth.toml written next to the simulated data")
    return from_truth(data)


def simulator(robot: str | Robot, config: Mapping[str, Any], seed: int | None = None,
              where: str = "simulation config") -> VirtualRobot:
    """Convenience: a :class:`VirtualRobot` from a robot name/file and a config mapping."""
    r = robot if isinstance(robot, Robot) else load_robot(robot)
    return VirtualRobot(r, config, seed=seed, where=where)


__all__ = [
    "JOINT_ERROR_EFFECTS",
    "OUT_OF_LIBRARY",
    "SIM_EFFECTS",
    "SimConfigError",
    "VirtualRobot",
    "from_truth",
    "load_config",
    "load_truth",
    "matrix_to_rotvec",
    "rotvec_to_matrix",
    "rotvecs",
    "simulator",
]
