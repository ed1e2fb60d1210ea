"""The arm model: one object from measurement to motion.

An :class:`ArmModel` is the kinematic chain of a robot description plus its
deflection model, a set of effect plug-ins (:mod:`models.effects`) with their
parameter values.  A plain robot file gives the nominal model (DH table and
linear joint springs); a robot file with an ``[identified]`` table (written by
``compplan identify``, see :mod:`models.arm_file`) gives the identified one.
Planning, compensation, maps, prediction and reports all evaluate this object:

* :attr:`ArmModel.kinematics` -- named CasADi functions with the parameters fixed
  (:class:`KinematicModel`, here because the two build each other), compiled for batches;
* :meth:`ArmModel.equilibrium` -- the deflected equilibrium ``q = q_c + dq(q, L)``,
  the one place the product decides where a loaded arm settles (the deflection is
  evaluated at the deflected pose).

Frames: the base frame of the robot (``tcp2base`` maps TCP-frame coordinates to
base-frame coordinates); the measurement frame and the measured point matter only
for identification and prediction (:meth:`base2meas`, :attr:`measured_point`).
Callers import them from :mod:`models.arm` (with :func:`~models.arm.load_arm`) and :mod:`models.symbolic`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from . import effects as fx
from .constants import EQUILIBRIUM_MAX_ITER, EQUILIBRIUM_STEP_TOL
from .load import Load, load_rows
from .campaign_frame import CampaignFrame, campaign_covariance
from .codegen import BatchFunction, VMBatchFunction, batch_function
from .errors import InputError
from .effects.graph import arm_functions, load_error_gravity_function
from .robot import Robot

if TYPE_CHECKING:  # pragma: no cover
    from .ik import IKSolver


#: Threads used by batch evaluation (OpenMP, or ``Function.map(..., "thread", N)`` without a compiler).
BATCH_THREADS = 2
#: Joint torques up to this fraction above the identification data's range count as inside it.
TORQUE_RANGE_SLACK = 0.05


@dataclass
class EquilibriumResult:
    """Deflected equilibrium ``q = q_c + dq(q, L)`` for N commands.

    Attributes
    ----------
    q : ndarray, shape (N, 6)
        Deflected joint angles, rad.
    converged : ndarray of bool, shape (N,)
    iterations : int
    """

    q: np.ndarray
    converged: np.ndarray
    iterations: int


@dataclass
class ArmModel:
    """A robot's kinematic chain and deflection model (SI units).

    Attributes
    ----------
    nominal : Robot
        The description the parameters refer to (nominal DH, stiffness, limits, tool).
    theta : ndarray, shape (N_PARAMS,)
        Every effect parameter (effects not active sit at their defaults, where they vanish).
    R0 : ndarray, shape (3, 3)
        Rotation the registration correction is applied to (measurement frame).
    tau_scale : ndarray, shape (6,)
        Joint torque scales of the hardening and lost-motion terms, N*m.
    gravity_on : bool
        Self-weight torques included (the ``gravity`` effect).
    beams : ndarray, shape (6, 3, 3)
        Beam frames of ``link_compliance``.
    knots : ndarray, shape (6, N_KNOTS) or None
        Hardening knots, N*m.
    time_ref : (float, float)
        ``(t_start, t_span)`` of the identification campaign, s (drift).
    temperature_ref : float
        Temperature the model is evaluated at when none is given, deg C.
    effects : list of str
        Active library effects.
    registered : bool
        Whether the identification data were registered: measurement frame = base frame *and*
        measured point = TCP (with only one of them known, the parameters aliased with the other
        are held and named, and base-frame plans say so).
    std, held : dict
        Standard deviations and held parameters of the identification.
    noise_sigma_m : float or None
    tcp_correction_m : ndarray, shape (3,)
        Correction of the TCP in the flange frame, m, applied when planning.  With data
        declared registered, the measured point *is* the TCP; position data cannot tell the
        flange-side geometric errors (``da, dalpha, dd, dtheta`` of joint 6) from it, so the
        fit puts them into the measured point, and its difference from the robot file's TCP
        is this correction.  Zero for unregistered data (there the registration absorbs them:
        see ``docs/identification.md``, section 8).
    torque_range_Nm : ndarray, shape (6,), or None
        Largest joint torque magnitude of the identification data (external plus self-weight),
        N*m: beyond it the torque-nonlinear effects are extrapolated (see :meth:`extrapolation`).
    effect_const : dict of str to ndarray
        Data-dependent constant blocks of effects by key (e.g. ``error_map.freq``, cycles/rev, and
        ``error_map.range``, rad, of :mod:`models.effects.joint_error_map`); others keep their defaults.
    covariance : ndarray, shape (k, k), or None
        Covariance of the free parameters of the identification, SI (units of :data:`theta`'s
        entries), in the order of :attr:`covariance_names`; None for a nominal model or a model
        file written before the covariance was stored (format 1).
    covariance_names : list of str
        The parameter names (``models.effects.PARAM_NAMES``) of the rows of :attr:`covariance`.
    residual_sigma_m : float or None
        Standard deviation per axis of the identification's residual (inlier position rows,
        corrected for the free parameters: ``sqrt(sum r^2 / (3 n - k))``), m: the part of a
        prediction's error no parameter explains (noise and what the model lacks).
    joint_range_rad : ndarray, shape (6, 2), or None
        Smallest and largest commanded joint angle of the identification data, rad (every
        campaign): beyond them the model is extrapolated (:func:`problems.identify.uncertainty`).
    sigma_scale, sigma_growth_rad_per_rad : float
        The sigma's calibration on held-out rows (:mod:`problems.identify.sigma_calibration`): the
        factor on the linearised sigma, and the joint angle error per rad beyond ``joint_range_rad``.
    campaigns : list of CampaignFrame
        The measurement campaigns the model was identified from, each with its own registration
        (base frame -> that campaign's measurement frame); the model's own registration
        (:meth:`base2meas`) is the reference campaign's (default: the most rows); empty for one campaign.
    source, sha256 : str
        Where the model was read from and the file's hash (empty when built in memory).
    """

    nominal: Robot
    theta: np.ndarray
    R0: np.ndarray = field(default_factory=lambda: np.eye(3))
    tau_scale: np.ndarray = field(default_factory=lambda: np.ones(6))
    gravity_on: bool = False
    beams: np.ndarray | None = None
    knots: np.ndarray | None = None
    time_ref: tuple[float, float] = (0.0, 1.0)
    temperature_ref: float = fx.THERMAL_REFERENCE_C
    effects: list[str] = field(default_factory=list)
    registered: bool = True
    std: dict[str, float] = field(default_factory=dict)
    noise_sigma_m: float | None = None
    held: dict[str, str] = field(default_factory=dict)
    tcp_correction_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    torque_range_Nm: np.ndarray | None = None
    effect_const: dict[str, np.ndarray] = field(default_factory=dict)
    covariance: np.ndarray | None = None
    covariance_names: list[str] = field(default_factory=list)
    residual_sigma_m: float | None = None
    joint_range_rad: np.ndarray | None = None
    sigma_scale: float = 1.0
    sigma_growth_rad_per_rad: float = 0.0
    campaigns: list[CampaignFrame] = field(default_factory=list)
    source: str = ""
    sha256: str = ""

    def __post_init__(self) -> None:
        if self.beams is None:
            self.beams = fx.beam_frames(self.nominal)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_robot(cls, robot: Robot) -> ArmModel:
        """The nominal model of a description: its DH chain and linear joint springs."""
        return cls(nominal=robot, theta=fx.make_layout(robot).nominal.copy())

    def robot(self) -> Robot:
        """The identified robot: DH errors and stiffness folded into the ordinary fields,
        everything else in the ``[identified]`` table (see :mod:`models.arm_file`)."""
        from .arm_dict import model_to_dict
        from .robot import robot_from_dict

        return robot_from_dict(model_to_dict(self), "identified model")

    @property
    def name(self) -> str:
        return self.nominal.name

    def with_tool(self, tcp2flange: np.ndarray) -> ArmModel:
        """The same model with another TCP (4x4, TCP -> flange)."""
        return replace(self, nominal=self.nominal.with_tool(tcp2flange))

    # ------------------------------------------------------------------ parameters
    @property
    def const(self) -> np.ndarray:
        """The constant vector of the model graph (identification, prediction)."""
        return fx.make_const(
            self.nominal, self.R0, self.tau_scale, self.gravity_on, self.beams, self.knots, self.effect_const
        )

    @property
    def planning_const(self) -> np.ndarray:
        """The constant vector for planning: the TCP carries :attr:`tcp_correction_m`."""
        T = np.array(self.nominal.tcp2flange, dtype=float)
        T[:3, 3] += np.asarray(self.tcp_correction_m, dtype=float)
        return fx.set_const(self.const, "tool", T.reshape(-1, order="F"))

    def parameter(self, group: str) -> np.ndarray:
        """Values of a parameter group (e.g. ``"geometric.da"``), SI."""
        return self.theta[fx.GROUP_SLICES[group]].copy()

    @property
    def active_effects(self) -> tuple[str, ...]:
        """Active library effects, with those they subsume (``geometric`` -> ``joint_offset``)."""
        out: list[str] = []
        for e in self.effects:
            if e not in fx.EFFECTS:
                continue
            out += [e] + [s for s in fx.EFFECTS[e].subsumes]
        if self.gravity_on and "gravity" not in out:
            out.append("gravity")
        return tuple(e.name for e in fx.registry() if e.name in out)

    @property
    def arm_effects(self) -> tuple[str, ...]:
        """Effects that act on the arm (planning): declared ones and active library ones."""
        return tuple(
            e.name for e in fx.registry() if e.acts_on == fx.ARM and (e.declared or e.name in self.active_effects)
        )

    @property
    def geometry_is_nominal(self) -> bool:
        """The chain is the robot file's DH table: no effect acting on the arm implements the
        ``geometry`` hook (:meth:`models.effects.Effect.overrides`; in the library joint offsets,
        DH errors, thermal expansion and joint error maps, and any plug-in that changes the chain)."""
        return not any(fx.effect(e).overrides("geometry") for e in self.arm_effects)

    @property
    def is_nominal(self) -> bool:
        """Nothing but the robot file's chain and springs."""
        return not self.active_effects and np.allclose(self.theta[fx.GROUP_SLICES["stiffness.s"]], 0.0)

    def joint_compliance(self) -> np.ndarray:
        """Linear joint-spring compliances ``c0 (1 + s)``, rad/(N*m), (6,)."""
        return (1.0 / self.nominal.stiffness) * (1.0 + self.theta[fx.GROUP_SLICES["stiffness.s"]])

    def campaign_names(self) -> list[str]:
        """Names of the campaigns the model was identified from (empty for one campaign)."""
        return [c.name for c in self.campaigns]

    def for_campaign(self, name: str | None) -> ArmModel:
        """The model with campaign ``name``'s registration (None: the model as it is, i.e. the
        reference campaign's).  Raises ``KeyError`` naming the campaigns for an unknown name."""
        if name is None:
            return self
        for c in self.campaigns:
            if c.name == name:
                theta = self.theta.copy()
                theta[fx.GROUP_SLICES["reg.t"]] = c.base2meas[:3, 3]
                theta[fx.GROUP_SLICES["reg.w"]] = 0.0
                cov = self.covariance
                if cov is not None:
                    cov = campaign_covariance(cov, list(self.covariance_names), c)
                return replace(self, theta=theta, R0=np.array(c.base2meas[:3, :3], dtype=float), covariance=cov)
        raise KeyError(name)

    def base2meas(self) -> np.ndarray:
        """Identified measurement-frame registration (4, 4): base-frame -> measurement-frame coordinates."""
        T = np.eye(4)
        T[:3, :3] = fx.cayley_np(self.theta[fx.GROUP_SLICES["reg.w"]]) @ self.R0
        T[:3, 3] = self.theta[fx.GROUP_SLICES["reg.t"]]
        return T

    @property
    def measured_point(self) -> np.ndarray:
        """Measured point in the flange frame, m, (3,)."""
        return self.theta[fx.GROUP_SLICES["tool.p"]].copy()

    def describe(self) -> dict[str, Any]:
        """What the summaries record about the model used."""
        return {
            "robot": self.nominal.name,
            "file": self.source or None,
            "sha256": self.sha256 or None,
            "identified": bool(self.effects) or not self.is_nominal,
            "effects": ["joint_springs"] + list(self.active_effects),
            "registered": bool(self.registered),
            "tcp_correction_m": [float(v) for v in self.tcp_correction_m],
            "temperature_C": float(self.temperature_ref),
        }

    def extrapolation(self, q: np.ndarray, load: Load | np.ndarray) -> list[str]:
        """Where joint torques at the poses ``q`` (N, 6) exceed the identification data's range
        on a joint where an effect's term acts (:meth:`models.effects.Effect.joints_acting`:
        the torque-nonlinear ones, hardening and lost motion): one line per joint, empty when none."""
        acting: dict[str, np.ndarray] = {}
        for name in self.active_effects:
            where = fx.effect(name).joints_acting(self.parameter)
            if where is not None and where.any():
                acting[name] = where
        if not acting or self.torque_range_Nm is None:
            return []
        q = np.atleast_2d(np.asarray(q, dtype=float))
        km = self.kinematics
        tau = np.abs(km.batch(km.fn["joint_torques"], q, load_rows(load, len(q)))[0])
        out = []
        for j in range(6):
            names = [n for n, w in acting.items() if w[j]]
            k = int(np.argmax(tau[:, j]))
            lim = float(self.torque_range_Nm[j])
            if names and tau[k, j] > lim * (1.0 + TORQUE_RANGE_SLACK):
                out.append(
                    f"joint {j + 1}: torque {tau[k, j]:.4g} N*m at waypoint {k} exceeds the identification "
                    f"data's range ({lim:.4g} N*m): the identified {', '.join(names)} "
                    "is extrapolated there"
                )
        return out

    def caveats(self, q: np.ndarray, load: Load | np.ndarray) -> list[str]:
        """Everything that limits the model's trust along the poses ``q`` (N, 6): torques beyond the
        identification data (:meth:`extrapolation`), geometry corrections too large for the robot
        file (:func:`models.plausibility.implausible_geometry`), and each active effect's own caveats
        (:meth:`models.effects.Effect.caveats`, e.g. a joint left inside its dead band)."""
        out = self.extrapolation(q, load)
        if not self.geometry_is_nominal:
            from .plausibility import implausible_geometry

            held = [fx.PARAM_NAMES.index(n) for n in self.held if n in fx.PARAM_NAMES]
            msg = implausible_geometry(self.nominal, self.theta, held)
            if msg:
                out.append(msg)
        q = np.atleast_2d(np.asarray(q, dtype=float))
        km = self.kinematics
        tau = km.batch(km.fn["joint_torques"], q, load_rows(load, len(q)))[0]
        lever = np.linalg.norm(km.J(q).reshape(-1, 6, 6)[:, :3, :], axis=1)
        const = self.const

        def c(key: str) -> np.ndarray:
            return fx.get_const(const, key)

        for name in self.active_effects:
            out += fx.effect(name).caveats(self.parameter, c, tau, lever)
            out += fx.effect(name).angle_caveats(self.parameter, c, q)
        return out

    # ------------------------------------------------------------------ evaluation
    @cached_property
    def kinematics(self) -> KinematicModel:
        """Named CasADi functions of this model with its parameters fixed (compiled batches)."""
        return KinematicModel(self)

    @cached_property
    def ik(self) -> IKSolver:
        """The all-branch IK of the nominal chain with this model's tool (built once per model;
        :func:`models.ik.ik_solver`)."""
        from .ik import ik_solver

        return ik_solver(self.nominal)

    def load_deflection(self, q: np.ndarray, load: Load | np.ndarray) -> np.ndarray:
        """Joint deflection ``dq(q, L)`` of the arm whose joints sit at ``q`` (N, 6), rad."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        km = self.kinematics
        return km.batch(km.fn["load_deflection"], q, load_rows(load, len(q)))[0]

    def joint_torques(self, q: np.ndarray, load: Load | np.ndarray) -> np.ndarray:
        """Joint torques the load (and, with ``gravity``, the arm's weight) applies at the pose
        ``q`` (N, 6), N*m: a joint yields in the direction of its torque."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        km = self.kinematics
        return km.batch(km.fn["joint_torques"], q, load_rows(load, len(q)))[0]

    def torque_deflection(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Joint deflection under the applied joint torques ``tau`` (N, 6) N*m at the pose ``q``
        (N, 6) rad: the model's deflection law (springs, hardening, lost motion), rad."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        tau = np.broadcast_to(np.asarray(tau, dtype=float), q.shape)
        km = self.kinematics
        return km.batch(km.fn["torque_deflection"], q, np.ascontiguousarray(tau))[0]

    def loaded_tcp(self, q: np.ndarray, load: Load | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """TCP of the loaded arm whose joints sit at ``q``: positions (N, 3) m and rotations
        (N, 3, 3), base frame (link compliance included)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        km = self.kinematics
        p, R = km.batch(km.fn["loaded_tcp"], q, load_rows(load, len(q)))
        return p, R

    def tcp_wrench(self, q: np.ndarray, load: Load | np.ndarray) -> np.ndarray:
        """Wrench on the TCP at the pose ``q``, base frame, (N, 6) [N; N*m]."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        km = self.kinematics
        return km.batch(km.fn["tcp_wrench"], q, load_rows(load, len(q)))[0]

    def load_error(self, q: np.ndarray, load: Load | np.ndarray) -> np.ndarray:
        """First-order load-induced TCP error at the pose ``q`` (N, 6) [m; rad], base frame:
        ``[J_v dq(q, L) + dp_link(q, L); J_w dq(q, L)]`` (the posture NLP's objective)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        km = self.kinematics
        return km.batch(km.fn["load_error"], q, load_rows(load, len(q)))[0]

    def equilibrium(
        self,
        q_command: np.ndarray,
        load: Load | np.ndarray,
        max_iter: int = EQUILIBRIUM_MAX_ITER,
        tol: float = EQUILIBRIUM_STEP_TOL,
    ) -> EquilibriumResult:
        """Solve ``q = q_c + dq(q, L)`` by fixed-point iteration (vectorised over N).

        The map contracts by about ``|d dq / dq|`` (1e-3 .. 1e-1 for real arms and loads),
        so a few iterations reach machine precision; rows that do not converge within
        ``max_iter`` are flagged.

        Parameters
        ----------
        q_command : ndarray, shape (N, 6), rad
        load : Load, load rows (N, 19), or a base-frame wrench (6,) / (N, 6)
        """
        qc = np.atleast_2d(np.asarray(q_command, dtype=float))
        L = load_rows(load, len(qc))
        q = qc + self.load_deflection(qc, L)
        converged = np.zeros(len(qc), dtype=bool)
        it = 0
        for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported after the loop
            q_new = qc + self.load_deflection(q, L)
            step = np.max(np.abs(q_new - q), axis=1)
            q = q_new
            converged = step <= tol
            if converged.all():
                break
        return EquilibriumResult(q=q, converged=converged, iterations=it)


class KinematicModel:
    """Named CasADi functions of one arm model, parameters fixed (working data).

    Parameters
    ----------
    source : Robot or ArmModel
        A description (its nominal model: DH chain and linear joint springs) or an arm
        model (identified geometry, springs and effects); baked in as constants.

    Attributes
    ----------
    fk_frames : casadi.Function
        ``q (6) -> frame12base ... frame62base`` (4x4 each).
    fk_tcp : casadi.Function
        ``q (6) -> tcp2base`` (4x4).
    jacobian : casadi.Function
        ``q (6) -> J`` (6x6), geometric, TCP point, base frame.
    compliance : casadi.Function
        ``q (6) -> C`` (6x6), ``C = J K^-1 J^T`` (m/N, rad/N, m/(N*m), rad/(N*m) blocks).
    deflection : casadi.Function
        ``(q (6), F (6)) -> D (6)``, ``D = C F``: TCP displacement [m; rad] under wrench F.
    joint_deflection : casadi.Function
        ``(q (6), F (6)) -> dq (6)``, ``dq = K^-1 J^T F`` (rad).
    kinetostatics : casadi.Function
        ``q (6) -> p (3), R (3x3), J (6x6), C (6x6)`` in one pass (batch workhorse).
    fn : dict of casadi.Function
        All of the above plus the load functions of the model (``L``: load vector,
        :mod:`models.load`): ``tcp_wrench(q, L) -> W``, ``joint_torques(q, L) -> tau``,
        ``load_deflection(q, L) -> dq``, ``loaded_tcp(q, L) -> p, R``,
        ``load_error(q, L) -> e`` (see :class:`models.arm.ArmModel`).

    ``C`` and ``joint_deflection`` are those of the linear joint springs (with the model's
    identified spring compliances); the load functions include every active effect.
    """

    def __init__(self, source: Robot | ArmModel) -> None:
        arm = source if isinstance(source, ArmModel) else ArmModel.from_robot(source)
        self.arm = arm
        self.robot = arm.nominal
        el = fx.make_layout(arm.nominal, arm.const).eligible
        dT = arm.temperature_ref - fx.THERMAL_REFERENCE_C
        # what builds the model graph: convention, effects, parameters, constants, eligibility, dT
        self._graph_args = (arm.nominal.convention, arm.active_effects, arm.theta, arm.planning_const, el, dT)
        #: Every named function of the model (see :func:`models.effects.graph.arm_functions`).
        self.fn: dict[str, ca.Function] = arm_functions(*self._graph_args)
        self.fk_frames = self.fn["fk_frames"]
        self.fk_tcp = self.fn["fk_tcp"]
        self.fk_position = self.fn["fk_position"]
        self.jacobian = self.fn["jacobian"]
        self.compliance = self.fn["compliance"]
        self.deflection = self.fn["deflection"]
        self.joint_deflection = self.fn["joint_deflection"]
        self.kinetostatics = self.fn["kinetostatics"]
        self._evaluators: dict[str, BatchFunction | VMBatchFunction] = {}
        self._load_error_g: ca.Function | None = None

    @property
    def load_error_gravity(self) -> ca.Function:
        """``load_error_g(q (6), L (LOAD_SIZE), g (3)) -> e (6)``: ``fn["load_error"]`` with the
        robot's gravity constant (m/s^2, base frame; the arm's self-weight) as the input ``g``,
        for the same arm mounted another way (placement studies).  Built on first use."""
        if self._load_error_g is None:
            self._load_error_g = load_error_gravity_function(*self._graph_args)
        return self._load_error_g

    # ------------------------------------------------------------------ batch helpers
    def batch(self, f: ca.Function, *args: np.ndarray) -> list[np.ndarray]:
        """Evaluate ``f`` over a batch without a Python loop.

        Compiled C when a compiler (or a cached library) is available, else CasADi's
        virtual machine with the same results to rounding (see :mod:`models.codegen`).

        Parameters
        ----------
        f : casadi.Function
            One of this model's functions.
        *args : ndarray, shape (N, n_in_k) or (n_in_k,)
            One row per pose; a 1-D argument is broadcast to every pose.

        Returns
        -------
        list of ndarray
            One per output, shape (N, rows, cols) (or (N, rows) for vectors).
        """
        arrs = [np.atleast_2d(np.asarray(a, dtype=float)) for a in args]
        n = max(a.shape[0] for a in arrs)
        for a in arrs:
            if a.shape[0] not in (1, n):
                raise InputError(
                    f"{f.name()}: batch arguments have {a.shape[0]} and {n} rows; expected 1 or {n} rows each"
                )
        return self.evaluator(f)(*[a if a.shape[0] == n else a.reshape(-1) for a in arrs])

    def evaluator(self, f: ca.Function) -> BatchFunction | VMBatchFunction:
        """The batch evaluator of ``f``, built once: compiled (cached on disk) or, without a
        C compiler, CasADi's virtual machine (its ``compiled`` attribute says which)."""
        name = f.name()
        ev = self._evaluators.get(name)
        if ev is None:
            ev = self._evaluators[name] = batch_function(f, BATCH_THREADS)
        return ev

    def compiled(self, f: ca.Function) -> BatchFunction | None:
        """The compiled batch evaluator of ``f`` (built once, cached on disk), or
        None if there is no compiled code (then ``batch`` uses CasADi's virtual machine)."""
        ev = self.evaluator(f)
        return ev if isinstance(ev, BatchFunction) else None

    # ------------------------------------------------------------- numeric conveniences
    def tcp(self, q: np.ndarray) -> np.ndarray:
        """``tcp2base`` for one pose (6,) -> (4, 4), or a batch (N, 6) -> (N, 4, 4)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.fk_tcp(q))
        return self.batch(self.fk_tcp, q)[0]

    def J(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian, (6,) -> (6, 6) or (N, 6) -> (N, 6, 6)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.jacobian(q))
        return self.batch(self.jacobian, q)[0]

    def C(self, q: np.ndarray) -> np.ndarray:
        """Compliance, (6,) -> (6, 6) or (N, 6) -> (N, 6, 6)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.compliance(q))
        return self.batch(self.compliance, q)[0]

    def D(self, q: np.ndarray, F: np.ndarray) -> np.ndarray:
        """TCP deflection [m; rad] under wrench F (base frame), (N, 6) -> (N, 6)."""
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.asarray(self.deflection(q, F)).reshape(6)
        return self.batch(self.deflection, q, F)[0]
