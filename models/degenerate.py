"""Degenerate 6R chains: joint axes that cannot move the tool in all 6 directions anywhere.

The class (``docs/robot-file.md``, "Degenerate chains"): a 6R chain is **degenerate** when its
Jacobian has rank < 6 at *every* configuration within the joint limits.  The Jacobian's columns
are the joint screws (the Plücker lines of the joint axes), so this is a property of the axes'
geometry alone: two joints turning about one axis line (the second is redundant), four or more
parallel axes (parallel axes span at most 3 DOF: turning about their direction and moving across
it), four or more axes through one point (zero-length links: they only turn the tool about that
point), three parallel axes in one plane, and any other always-dependent set of axes.

The Jacobian is an analytic function of ``q``: if its rank is 6 at one configuration it is 6
almost everywhere (the configurations where it drops are a set of measure zero), so the largest
rank at a few random configurations decides, with probability one.  The samples are seeded (a
load is deterministic) and stop at the first configuration of full rank, so a sound chain costs
one forward kinematics.  Only a degenerate chain is examined further, for the reason: which joints
are coaxial, parallel, concurrent or otherwise dependent at every sample.

Both robot-file readers call :func:`check_chain` (the DH table in :mod:`models.robot_file.dh_table`, the URDF
chain in :mod:`models.robot_file.urdf_file`): one definition, one message.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import combinations

import numpy as np

from .description import Robot, RobotFileError
from .transforms import dh_chain_frames, rotations_about

#: Random configurations (within the joint limits) at which the Jacobian's rank is tested; the
#: largest rank over them is the chain's.  A sound chain stops at the first (full rank).
RANK_SAMPLES = 8
#: Seed of those samples: a robot file loads (or is refused) the same way every time.
RANK_SEED = 20240611
#: Relative tolerance of the rank: a singular value of the scaled Jacobian (unit axes, moments
#: divided by the chain's size) below this fraction of the largest counts as zero.  An exactly
#: degenerate chain gives ~1e-16 (rounding); a sound arm at a random configuration gives
#: 1e-3 .. 1 (a 1 um offset on a 1 m arm still gives ~1e-6).
RANK_RTOL = 1e-9
#: Relative tolerance of the geometric relations named in the reason (sine of the angle between
#: parallel axes; distances divided by the chain's size): as strict as the rank's.
GEOMETRY_RTOL = 1e-9
#: Smallest length scale of a chain (m): keeps the moments' scaling finite when every axis passes
#: through one point (all links of zero length); no arm is smaller than a micrometre.
LENGTH_FLOOR_M = 1e-6

#: What to check in a DH robot file.
DH_HINT = "check a, alpha and d of those joints (docs/robot-file.md, 'Degenerate chains')"
#: What to check in a URDF.
URDF_HINT = "check the <axis> and <origin> of those joints in the URDF (docs/robot-file.md, 'Degenerate chains')"

#: ``axes_at(q)`` -> unit joint axes ``w`` (6, 3) and a point on each ``p`` (6, 3), m, base frame.
AxesAt = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


# --------------------------------------------------------------------------------------
# The joint axes of a chain at a configuration
# --------------------------------------------------------------------------------------


def dh_axes(convention: str, a: np.ndarray, alpha: np.ndarray, d: np.ndarray, theta_offset: np.ndarray) -> AxesAt:
    """``axes_at(q)`` of a DH table: joint *i* turns about z of DH frame *i - 1* (``standard_dh``)
    or *i* (``modified_dh``), through that frame's origin; the frames' base is DH frame 0.

    Parameters
    ----------
    convention : {"standard_dh", "modified_dh"}
    a, d : ndarray, shape (6,)
        DH lengths, m.
    alpha, theta_offset : ndarray, shape (6,)
        DH twists and joint offsets, rad.
    """
    rows = slice(0, 6) if convention == "standard_dh" else slice(1, 7)

    def axes(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        F = dh_chain_frames(convention, a, alpha, d, theta_offset, q)[rows]
        return F[:, :3, 2], F[:, :3, 3]

    return axes


def robot_axes(robot: Robot) -> AxesAt:
    """``axes_at(q)`` of a robot's DH chain (DH frame 0 as the base: a rigid motion changes no rank)."""
    return dh_axes(robot.convention, robot.a, robot.alpha, robot.d, robot.theta_offset)


def poe_axes(w0: np.ndarray, p0: np.ndarray) -> AxesAt:
    """``axes_at(q)`` of a chain given by its axes at q = 0 (product of exponentials, as a URDF).

    Parameters
    ----------
    w0, p0 : ndarray, shape (6, 3)
        Unit joint axes and a point on each (m), base frame, at q = 0.
    """
    w0, p0 = np.asarray(w0, dtype=float), np.asarray(p0, dtype=float)

    def axes(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R, t = np.eye(3), np.zeros(3)
        w, p = np.empty((6, 3)), np.empty((6, 3))
        for i in range(6):
            w[i], p[i] = R @ w0[i], R @ p0[i] + t
            Ri = rotations_about(w0[i], np.array([q[i]]))[0]  # exp([S_i] q_i): rotation about line i at q = 0
            R, t = R @ Ri, R @ (p0[i] - Ri @ p0[i]) + t
        return w, p

    return axes


# --------------------------------------------------------------------------------------
# The rank test
# --------------------------------------------------------------------------------------


def _screws(w: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, float]:
    """Joint screws, one a row, shape (6, 6): ``[w_i, (p_i - c) x w_i / L]`` with ``c`` the
    points' centroid and ``L`` the chain's size (m), so the rank tolerance is unit-free; and ``L``."""
    c = p.mean(axis=0)
    size = max(float(np.max(np.linalg.norm(p - c, axis=1))), LENGTH_FLOOR_M)
    return np.hstack([w, np.cross(p - c, w) / size]), size


def _ranks(S: np.ndarray) -> np.ndarray:
    """Numerical ranks of a stack of screw sets ``S`` (K, m, 6) (:data:`RANK_RTOL`), shape (K,)."""
    s = np.linalg.svd(S, compute_uv=False)
    return np.sum(s > RANK_RTOL * s[..., :1], axis=-1)


def degenerate_reason(
    axes_at: AxesAt,
    q_min: np.ndarray,
    q_max: np.ndarray,
    names: Sequence[str] | None = None,
    hint: str = DH_HINT,
) -> str | None:
    """Why a 6R chain is degenerate (its Jacobian has rank < 6 at every configuration within the
    limits), or None for a sound chain.

    Parameters
    ----------
    axes_at : callable
        ``axes_at(q)`` -> joint axes ``w`` (6, 3) and points ``p`` (6, 3) at ``q`` (6,), rad
        (:func:`dh_axes`, :func:`robot_axes`, :func:`poe_axes`).
    q_min, q_max : ndarray, shape (6,)
        Joint limits, rad: the samples lie within them.
    names : sequence of 6 str, optional
        Joint names, quoted after the joint numbers.
    hint : str
        What to check, appended to the reason.

    Returns
    -------
    str or None
        One line: the dependent joints (coaxial, parallel, concurrent, otherwise dependent), the
        largest rank over :data:`RANK_SAMPLES` configurations, the hint.
    """
    rng = np.random.default_rng(RANK_SEED)
    Q = rng.uniform(np.asarray(q_min, dtype=float), np.asarray(q_max, dtype=float), (RANK_SAMPLES, 6))
    W, P, S, sizes = [], [], [], []
    for q in Q:
        w, p = axes_at(q)
        s, size = _screws(np.asarray(w, dtype=float), np.asarray(p, dtype=float))
        if int(_ranks(s[None])[0]) == 6:
            return None
        W.append(w)
        P.append(p)
        S.append(s)
        sizes.append(size)
    W_, P_, S_, L_ = np.array(W), np.array(P), np.array(S), np.array(sizes)
    rank = int(np.max(_ranks(S_)))
    reasons = _explain(W_, P_, S_, L_, names) or ["the joint axes are linearly dependent at every configuration"]
    return (
        f"degenerate chain: {'; '.join(reasons)}; the Jacobian has rank {rank} < 6 at every configuration "
        f"({RANK_SAMPLES} sampled within the joint limits): the tool cannot move in all 6 directions "
        f"anywhere; {hint}"
    )


def check_chain(
    where: str,
    axes_at: AxesAt,
    q_min: np.ndarray,
    q_max: np.ndarray,
    names: Sequence[str] | None = None,
    hint: str = DH_HINT,
) -> None:
    """Raise :class:`~models.robot.RobotFileError` (``"{where}: degenerate chain: ..."``) if the
    chain is degenerate (:func:`degenerate_reason`)."""
    why = degenerate_reason(axes_at, q_min, q_max, names, hint)
    if why:
        raise RobotFileError(f"{where}: {why}")


# --------------------------------------------------------------------------------------
# The reason: which joints, and how
# --------------------------------------------------------------------------------------


def _joints_text(idx: Sequence[int], names: Sequence[str] | None) -> str:
    """``"joints 2 (elbow) and 3 (wrist_1)"``, ``"joints 1, 2, 3 and 4"`` (1-based numbers) or ``"all 6 joints"``."""
    if len(idx) == 6:
        return "all 6 joints"
    items = [f"{i + 1} ({names[i]})" if names else str(i + 1) for i in idx]
    return "joints " + (", ".join(items[:-1]) + " and " + items[-1] if len(items) > 1 else items[0])


def _parallel(W: np.ndarray, i: int, k: int) -> bool:
    """Axes i and k parallel (either sense) at every sample (``W``: (K, 6, 3))."""
    return bool(np.all(np.linalg.norm(np.cross(W[:, i], W[:, k]), axis=-1) < GEOMETRY_RTOL))


def _coaxial(W: np.ndarray, P: np.ndarray, L: np.ndarray, i: int, k: int) -> bool:
    """Axes i and k one and the same line at every sample."""
    off = np.linalg.norm(np.cross(P[:, k] - P[:, i], W[:, i]), axis=-1) / L
    return _parallel(W, i, k) and bool(np.all(off < GEOMETRY_RTOL))


def _concurrent(W: np.ndarray, P: np.ndarray, L: np.ndarray, group: Sequence[int]) -> bool:
    """The axes of ``group`` pass through one point at every sample (least-squares point; its
    distance to every axis below :data:`GEOMETRY_RTOL` times the chain's size)."""
    for w, p, size in zip(W[:, list(group)], P[:, list(group)], L):
        proj = np.eye(3)[None] - w[:, :, None] * w[:, None, :]  # projectors across each axis
        A, b = proj.sum(axis=0), np.einsum("nij,nj->i", proj, p)
        x = np.linalg.lstsq(A, b, rcond=None)[0]
        dist = np.linalg.norm(np.einsum("nij,nj->ni", proj, x[None] - p), axis=-1)
        if np.any(dist > GEOMETRY_RTOL * size):
            return False
    return True


def _kind(W: np.ndarray, P: np.ndarray, L: np.ndarray, group: Sequence[int]) -> str:
    """``"parallel"``, ``"concurrent"`` or ``"dependent"``: how the axes of ``group`` relate."""
    if all(_parallel(W, i, k) for i, k in combinations(group, 2)):
        return "parallel"
    if _concurrent(W, P, L, group):
        return "concurrent"
    return "dependent"


def _explain(W: np.ndarray, P: np.ndarray, S: np.ndarray, L: np.ndarray, names: Sequence[str] | None) -> list[str]:
    """The reasons of a degenerate chain (samples ``W``, ``P`` (K, 6, 3), screws ``S`` (K, 6, 6),
    sizes ``L`` (K,)): coaxial joints, then the minimal sets of distinct axes dependent at every
    sample, merged into the largest parallel / concurrent groups."""
    reasons = []
    line_of = list(range(6))  # the first joint of each axis line
    for i, k in combinations(range(6), 2):
        if line_of[k] == k and _coaxial(W, P, L, i, k):
            line_of[k] = line_of[i]
    for first in sorted(set(line_of)):
        same = [j for j in range(6) if line_of[j] == first]
        if len(same) > 1:
            redundant = "redundant joints" if len(same) == 2 else f"{len(same) - 1} of them redundant"
            reasons.append(f"{_joints_text(same, names)} turn about one and the same axis line ({redundant})")
    lines = sorted(set(line_of))
    minimal: list[tuple[int, ...]] = []
    for m in range(3, len(lines) + 1):  # two distinct lines are always independent
        for group in combinations(lines, m):
            if any(set(g) <= set(group) for g in minimal):
                continue
            if np.all(_ranks(S[:, list(group)]) < m):
                minimal.append(group)
    groups = [(set(g), _kind(W, P, L, g)) for g in minimal]
    merged = True
    while merged:  # grow each group by others of its kind while the union keeps the kind
        merged = False
        for a, b in combinations(range(len(groups)), 2):
            (ga, ka), (gb, kb) = groups[a], groups[b]
            union = sorted(ga | gb)
            if ka == kb != "dependent" and _kind(W, P, L, union) == ka:
                groups[a] = (set(union), ka)
                del groups[b]
                merged = True
                break
    for group, kind in groups:
        g = sorted(group)
        dof = int(np.max(_ranks(S[:, g])))
        g = [j for j in range(6) if line_of[j] in group]  # with the joints coaxial with them
        what = {
            "parallel": "have parallel axes" + (" in one plane" if dof == 2 else ""),
            "concurrent": "have axes through one point (zero-length links)" + (" in one plane" if dof == 2 else ""),
            "dependent": "have axes that are linearly dependent at every configuration",
        }[kind]
        reasons.append(f"{_joints_text(g, names)} {what}, which span only {dof} DOF")
    return reasons
