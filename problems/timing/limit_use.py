"""How much of its limits a trajectory uses, and which constraint binds (``summary.json`` ``timing``).

A time-optimal trajectory rides at least one limit at every instant; which one, on which
joint, and for how much of the motion, is what an engineer needs to shorten a cycle (raise
that limit, change that joint's path).  A trajectory that stays under half of every limit
is slower than it needs to be, and :func:`limit_use` says why (the method's registered
``underuse_cause``).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Mapping

import numpy as np

from models.errors import InputError
from problems.timing.registry import get_method
from problems.timing.trajectory import Trajectory

__all__ = [
    "ACTIVE_RATIO",
    "describe_binding",
    "limit_use",
]

#: A sample rides a limit when its ratio |value| / limit is at least this.
ACTIVE_RATIO: float = 0.98
#: Below this peak ratio on every enforced limit, the trajectory "uses under half of every limit".
UNDERUSE_RATIO: float = 0.5
#: Binding constraints listed (the most often active first).
BINDING_SHOWN: int = 3

_QUANTITIES = (("velocity", "qd"), ("acceleration", "qdd"), ("jerk", "qddd"))


def limit_use(tr: Trajectory, limits: Any, enforced: tuple[str, ...]) -> dict[str, Any]:
    """Peak ratio, the binding constraints and (when under half of every limit) why.

    Parameters
    ----------
    tr : Trajectory
        A timed trajectory (samples at ``tr.dt``).
    limits : JointLimits or any object with ``velocity``, ``acceleration``, ``jerk`` arrays (6,)
        The limits it was timed under (rad/s, rad/s^2, rad/s^3).
    enforced : tuple of str
        The quantities the method enforces (the others are not counted).

    Returns
    -------
    dict
        ``peak_ratio`` (the largest enforced ratio), ``peak`` ("acceleration of joint 3"),
        ``binding``: list of ``{"limit", "joint" (1-based), "fraction_of_time"}`` for the
        constraints riding their limit (ratio >= :data:`ACTIVE_RATIO`) in the most samples,
        ``under_half`` (bool) and ``why`` (a sentence, or ``None``).
    """
    if tr.t.size == 0:
        return {"peak_ratio": None, "peak": None, "binding": [], "under_half": False, "why": None}
    ratios: dict[str, np.ndarray] = {}
    for name, attr in _QUANTITIES:
        if name in enforced:
            ratios[name] = np.abs(getattr(tr, attr)) / np.asarray(getattr(limits, name))[None, :]
    peak_name, peak_joint, peak = "", 0, -1.0
    for name, r in ratios.items():
        j = int(np.argmax(r.max(axis=0)))
        if float(r[:, j].max()) > peak:
            peak_name, peak_joint, peak = name, j, float(r[:, j].max())
    binding = [
        {"limit": name, "joint": j + 1, "fraction_of_time": float(np.mean(r[:, j] >= ACTIVE_RATIO))}
        for name, r in ratios.items()
        for j in range(r.shape[1])
        if np.any(r[:, j] >= ACTIVE_RATIO)
    ]
    binding.sort(key=lambda b: -b["fraction_of_time"])
    under = peak < UNDERUSE_RATIO
    why = None
    if under:
        try:
            cause = get_method(tr.method).underuse_cause
        except InputError:  # a method not registered here (a plug-in not loaded)
            cause = ""
        why = f"uses under half of every limit (peak {peak:.2f}: {peak_name} of joint {peak_joint + 1}); " + (
            cause or "no limit binds; see the method's reason"
        )
    return {
        "peak_ratio": peak,
        "peak": f"{peak_name} of joint {peak_joint + 1}",
        "binding": binding[:BINDING_SHOWN],
        "under_half": bool(under),
        "why": why,
    }


def describe_binding(use: Mapping[str, Any]) -> str:
    """One line: ``binds: acceleration of joint 2 (41 % of the time), ...`` or the underuse sentence."""
    if use.get("why"):
        return str(use["why"])

    def share(f: float) -> str:  # "0 %" read as "never", though the limit is reached
        return f"{100 * f:.0f} %" if f >= 0.005 else "under 0.5 %"

    parts = [
        f"{b['limit']} of joint {b['joint']} ({share(b['fraction_of_time'])} of the time)"
        for b in use.get("binding", [])
    ]
    return "binds: " + ", ".join(parts) if parts else f"peak {use.get('peak')} ({use.get('peak_ratio', 0):.2f})"
