"""Symbolic CasADi model of a 6R arm: FK, geometric Jacobian, compliance.

:class:`KinematicModel` is the working data built from a :class:`~models.robot.Robot`
description.  Every quantity is a named :class:`casadi.Function`; batch helpers
evaluate them over many poses in one call (compiled C from :mod:`models.codegen`, or,
without a C compiler, ``Function.map`` with threads on CasADi's virtual machine), so
NumPy arrays are converted once per batch, not once per pose.

Frames and signs (see ``docs/conventions.md``):

* ``frame_i2base`` (i = 1..6): DH frame *i* in the base frame; frame 6 is the flange.
* ``tcp2base = flange2base @ tcp2flange``.
* Jacobian ``J`` (6, 6): geometric, at the TCP point, base frame, rows
  ``[v_x, v_y, v_z, w_x, w_y, w_z]`` (linear velocity first), ``twist = J qdot``.
* A wrench ``F = [f; m]`` (N, N*m), base frame, acts on the TCP; joint torques
  ``tau = J^T F``; joint deflection ``dq = K^-1 tau`` (a joint yields in the
  direction of the torque applied to it); TCP deflection ``D = J dq = C F`` with
  ``C = J K^-1 J^T`` (eq. 15 of the paper), ``D = [dp (m); dphi (rad)]``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from . import effects as fx
from .errors import InputError
from .codegen import BatchFunction, VMBatchFunction, batch_function
from .effects.graph import (
    arm_functions,
    compliance_from_jacobian,
    geometric_jacobian,
    joint_axes,
    link_transform,
    load_error_gravity_function,
)
from .robot import Robot

if TYPE_CHECKING:  # pragma: no cover
    from .arm import ArmModel

#: Threads used by batch evaluation (OpenMP, or ``Function.map(..., "thread", N)`` without a compiler).
BATCH_THREADS = 2


# The chain, its joint axes and the Jacobian are the model graph's (one FK chain in the product).
__all__ = [
    "KinematicModel",
    "cartesian_stiffness",
    "compliance_from_jacobian",
    "directional_stiffness",
    "geometric_jacobian",
    "joint_axes",
    "link_transform",
]


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
        from .arm import ArmModel

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


def directional_stiffness(C: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Translational stiffness along unit direction(s) ``u``: ``1 / (u^T C_tt u)`` (N/m).

    Parameters
    ----------
    C : ndarray, shape (..., 6, 6)
        Compliance matrices.
    u : ndarray, shape (3,) or (..., 3)
        Direction in the base frame (normalised here).
    """
    u = np.asarray(u, dtype=float)
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    ctt = C[..., :3, :3]
    return 1.0 / np.einsum("...i,...ij,...j->...", u, ctt, u)


def cartesian_stiffness(C: np.ndarray, max_cond: float = 1e12) -> np.ndarray:
    """Cartesian stiffness ``K_x = C^-1`` (paper eq. 20) where it exists.

    Raises
    ------
    np.linalg.LinAlgError
        If C is singular (condition number above ``max_cond``): at a singular
        pose the arm is infinitely compliant in some direction and K_x does not exist.
    """
    cond = np.linalg.cond(C)
    if np.any(~np.isfinite(cond)) or np.any(cond > max_cond):
        raise np.linalg.LinAlgError(
            f"compliance is singular (condition number {np.max(cond):.3g} > {max_cond:.1g}): "
            "the Cartesian stiffness does not exist at this pose"
        )
    return np.linalg.inv(C)
