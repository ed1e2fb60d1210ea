"""The cell checked in the plan: the arm's capsules against the cell's objects and themselves.

What is checked (``docs/cell.md``, "What is checked where"):

* **which pose**: joint configurations as the controller runs them (a branch's exact compensated
  command at the waypoints, the controller's trajectory at every sample); the planned, deflected
  posture is compared with the command and the largest displacement of a capsule end point
  between them is reported (:attr:`CellCheck.deflection_m`): the clearance must cover it;
* **the arm** as the capsules of :func:`models.collision.capsule_model` (the robot file's
  ``[collision]`` geometry, the built-in radii or the generic ones), plus the **tool**
  (:func:`models.collision.tool.with_tool_geometry`): the bounding capsules of its declared body
  elements and its cutter, else one capsule from the flange to the TCP;
* **objects**: every capsule against every object of the cell, except the cutter (else the capsule
  that ends at the TCP), which may touch the workpiece (its pair is not checked), and capsules
  fixed to the base (they do not move: the problem file's base-footprint check covers the base,
  :func:`problems.cell.footprint_overlaps`); distances through coal
  (:func:`models.collision.capsule_shape_distance`) only where the closed form
  (:mod:`models.collision.vectorised`, vectorised over the samples) is not exact and its lower
  bound can be the nearest of its sample;
* **self-collision**: the arm's self pairs (:func:`models.collision.self_collision_pairs`) and the
  tool's capsules against links 0..4, closed form, vectorised over the samples.

Before this check, the posture NLP itself keeps the clearance of the pairs that come near
(:mod:`problems.posture.clearance`, constraints with gradients); this module checks every pair
exactly afterwards and sets aside the branches the NLP could not clear.

The result of a check is a :class:`models.collision.Clearance` (status ok / too_close /
collision, the pair, the sample, the smallest signed distance). Units: m, base frame. Prints nothing.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from models.collision import (
    TOOL_BODY,
    TOOL_MIN_LENGTH_M,
    CapsuleModel,
    Clearance,
    ClearanceStatus,
    capsule_distance,
    capsule_shape_distance,
)
from models.collision.scene import Scene
from models.collision.segments import segment_distance
from models.collision.vectorised import capsule_object_distance
from models.robot import Robot
from problems.compensation import exact
from problems.posture import BranchStatus, PostureResult, PostureStatus
from problems.posture.solve import rechoose

__all__ = [
    "TOOL_BODY",
    "TOOL_MIN_LENGTH_M",
    "cell_geometry",
    "cell_summary",
    "check_command",
    "check_poses",
    "check_trajectory",
    "choose_collision_free",
    "segments",
]


#: Samples measured at once by :func:`distance_table` (its temporaries hold about 15 candidate
#: points per capsule, object and sample: some 100 MB for a UR10 with a tool in a five-object cell).
CHECK_BLOCK = 4096


def cell_geometry(robot: Robot, cell: Any, model: CapsuleModel | None = None) -> Scene:
    """The collision scene to check for a robot in a cell (:meth:`problems.cell.Cell.scene`).

    Parameters
    ----------
    robot : Robot
        With its tool (``tcp2flange``).
    cell : problems.cell.Cell
        Its objects, its declared tool geometry and ``clearance`` (m).
    model : CapsuleModel, optional
        The arm's capsules (default :func:`models.collision.capsule_model`).

    The tool's capsules and the pairs checked come from :mod:`models.collision.tool`, as in the
    placement kernel and the posture NLP (:class:`models.collision.scene.Scene`): the declared body
    elements and the cutter (named as declared, ``cutter``), else one capsule flange -> TCP
    (``tool``); only the cutter (else the capsule ending at the TCP) may touch the workpiece.
    """
    return cell.scene(robot, model)


def segments(geom: Scene, q: np.ndarray) -> np.ndarray:
    """Capsule end points at configurations ``q`` (N, 6) rad: shape (N, M, 2, 3), m, base frame."""
    return geom.segments(q)


def distance_table(geom: Scene, q: np.ndarray) -> np.ndarray:
    """Signed distances (m) of the pairs at configurations ``q`` (N, 6) rad, shape (N, M * K + P),
    such that each row's smallest entry is exact, with its pair, where it is below the clearance
    or is the smallest of its block of :data:`CHECK_BLOCK` rows (elsewhere it is at least the
    larger of the two): so are the table's smallest and its first row below the clearance.

    Object pairs not checked are ``+inf``. Every pair is first bounded from its capsules' mid
    points (a shape's signed distance is 1-Lipschitz): an object pair by ``sd(mid) - r`` from
    above (where the object's closed form is exact) and ``sd(mid) - half length - r`` from below;
    a self pair by the mid points' distance less both radii from above and less both half
    lengths and radii from below. A pair is measured only where its lower bound is below both its
    sample's least upper bound and ``max(clearance, the block's least upper bound)`` (else it can
    be neither the nearest pair of its sample nor matter to the check): self pairs in closed
    form, object pairs in closed form too (:func:`models.collision.vectorised.capsule_object_distance`
    on the object's kernel proxy, vectorised), exact for boxes and spheres; where that is only a
    bound (cylinder, mesh) and can be the nearest of its sample, by coal, nearest first. A pair
    not measured holds its lower bound.
    """
    q = np.atleast_2d(q)
    return np.vstack([_table_block(geom, q[i : i + CHECK_BLOCK]) for i in range(0, max(q.shape[0], 1), CHECK_BLOCK)])


def _table_block(geom: Scene, q: np.ndarray) -> np.ndarray:
    """:func:`distance_table` of one block of at most :data:`CHECK_BLOCK` samples."""
    seg, self_lower, lower, least = _bounds(geom, q)
    return _measure(geom, seg, self_lower, lower, least, max(geom.clearance, float(least.min(initial=np.inf))))


def _bounds(geom: Scene, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Segments (N, M, 2, 3), the self pairs' lower bounds (N, P), the object pairs' (N, M, K) and
    each sample's least upper bound (N,) (:func:`distance_table`)."""
    seg = segments(geom, q)
    n, m = seg.shape[:2]
    k = len(geom.shapes)
    r = geom.model.radius
    ci, cj = geom.self_pairs[:, 0], geom.self_pairs[:, 1]
    mid = 0.5 * (seg[:, :, 0] + seg[:, :, 1])
    half = 0.5 * np.linalg.norm(seg[:, :, 1] - seg[:, :, 0], axis=-1) + r  # (N, M)
    gap = np.linalg.norm(mid[:, ci] - mid[:, cj], axis=-1)  # (N, P)
    self_lower = gap - half[:, ci] - half[:, cj]
    least = (gap - r[ci] - r[cj]).min(axis=1, initial=np.inf)
    lower = np.full((n, m, k), np.inf)
    for j in range(k):
        sd, exact = _mid_distance(geom, j, mid)
        lower[:, :, j] = np.where(geom.checked[:, j], sd - half, np.inf)
        if exact:
            least = np.minimum(least, np.where(geom.checked[:, j], sd - r, np.inf).min(axis=1))
    return seg, self_lower, lower, np.broadcast_to(least, (n,)).copy()


def _mid_distance(geom: Scene, j: int, mid: np.ndarray) -> tuple[np.ndarray, bool]:
    """Object ``j``'s signed distance (m) from points ``mid`` (N, M, 3), and whether it is exact
    (else a lower bound: measured on its kernel proxy, or from its bounding sphere)."""
    o = geom.shapes[j]
    proxy = o.proxy(nlp=False)
    exact = proxy.shape is o.shape and o.shape.exact_in_kernel
    try:
        return proxy.shape.signed_distance(proxy.to_local(mid.reshape(-1, 3))).reshape(mid.shape[:2]), exact
    except NotImplementedError:
        return np.linalg.norm(mid - geom.centre[j], axis=-1) - geom.bound[j], False


def _measure(
    geom: Scene,
    seg: np.ndarray,
    self_lower: np.ndarray,
    lower: np.ndarray,
    least: np.ndarray,
    theta: float,
) -> np.ndarray:
    """The rows of :func:`distance_table` of one block, from its bounds (:func:`_bounds`)."""
    n, m, k = lower.shape
    r = geom.model.radius
    self_d = self_lower.copy()
    i, s = np.nonzero((self_lower < least[:, None]) & (self_lower < theta))
    if i.size:
        ci, cj = geom.self_pairs[s, 0], geom.self_pairs[s, 1]
        self_d[i, s] = capsule_distance(seg[i, ci], r[ci], seg[i, cj], r[cj])
    obj = lower.copy()
    exact = np.zeros(k, dtype=bool)
    need = (lower < least[:, None, None]) & (lower < theta)
    for j in range(k):
        i, c = np.nonzero(need[:, :, j])
        if i.size:
            obj[i, c, j], exact[j] = _closed_form(geom, j, seg[i, c], r[c])
    best = np.minimum(least, np.where(need & exact[None, None], obj, np.inf).min(axis=(1, 2), initial=np.inf))
    bound = np.where(need & ~exact[None, None], obj, np.inf)  # measured bounds coal may have to tighten
    for i in np.flatnonzero((bound < np.minimum(best, theta)[:, None, None]).any(axis=(1, 2))):
        for flat in np.argsort(bound[i], axis=None):
            c, j = divmod(int(flat), k)
            if not bound[i, c, j] < min(best[i], theta):
                break  # every remaining pair is at least this far
            d = capsule_shape_distance(seg[i, c, 0], seg[i, c, 1], r[c], geom.shapes[j]).distance
            obj[i, c, j] = d
            best[i] = min(best[i], d)
    return np.hstack([obj.reshape(n, m * k), self_d])


def _closed_form(geom: Scene, j: int, seg: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, bool]:
    """Object ``j``'s signed distances from capsules ``seg`` (..., 2, 3), ``radii`` (...), m, in
    closed form, and whether they are exact: its kernel proxy's closed form
    (:meth:`~models.collision.shapes.Shape.capsule_distance`), else (a shape kind without one) the
    distance from its bounding sphere, a lower bound."""
    o = geom.shapes[j]
    proxy = o.proxy(nlp=False)
    try:
        return capsule_object_distance(seg, radii, proxy), proxy.shape is o.shape and o.shape.exact_in_kernel
    except NotImplementedError:
        c = geom.centre[j]
        d_c, _, _ = segment_distance(seg[..., 0, :], seg[..., 1, :], c, c)
        return d_c - radii - geom.bound[j], False


def _clearance(d_row_min: float, pair: str, clearance: float, where: str, index: int) -> Clearance:
    if d_row_min <= 0.0:
        status, text = ClearanceStatus.COLLISION, f"{pair} overlap by {-d_row_min * 1e3:.1f} mm at {where}"
    elif d_row_min < clearance:
        status = ClearanceStatus.TOO_CLOSE
        text = f"{pair} {d_row_min * 1e3:.1f} mm apart at {where} (clearance {clearance * 1e3:.1f} mm)"
    else:
        status, text = ClearanceStatus.OK, f"smallest distance {d_row_min * 1e3:.1f} mm: {pair} at {where}"
    return Clearance(status, text, d_row_min, pair, index, clearance)


def first_violation(geom: Scene, d: np.ndarray, label: str = "waypoint", times: np.ndarray | None = None) -> Clearance:
    """The :class:`Clearance` of a distance table (:func:`distance_table`): at the *first* sample
    closer than the clearance (its nearest pair), else at the smallest distance of all.

    ``label``: what a sample is in the reason; ``times`` (N,) s: name samples by their time.
    """
    if d.size == 0 or not np.isfinite(d).any():
        return Clearance(ClearanceStatus.OK, "no pair to check", float("inf"), "", -1, geom.clearance)
    row_min = d.min(axis=1)
    bad = np.flatnonzero(row_min < geom.clearance)
    i = int(bad[0]) if bad.size else int(np.argmin(row_min))
    return _at_row(geom, d, i, 0, label, times)


def _at_row(geom: Scene, d: np.ndarray, i: int, start: int, label: str, times: np.ndarray | None) -> Clearance:
    """The :class:`Clearance` of row ``i`` of a table whose first row is sample ``start``."""
    p, k = int(np.argmin(d[i])), start + i
    where = f"{label} {k}" if times is None else f"t = {times[k]:.3f} s ({label} {k})"
    return _clearance(float(d[i, p]), geom.pair_names[p], geom.clearance, where, k)


def _first_violation_of(
    geom: Scene, qs: list[np.ndarray], label: str = "waypoint", times: np.ndarray | None = None
) -> Clearance:
    """:func:`first_violation` of the elementwise smaller of the tables of ``qs`` (each (N, 6)
    rad), block by block: a block with a sample closer than the clearance ends the check."""
    n = qs[0].shape[0]
    best: tuple[float, np.ndarray, int, int] | None = None  # value, block, row, start
    for start in range(0, n, CHECK_BLOCK):
        d = _table_block(geom, qs[0][start : start + CHECK_BLOCK])
        for q in qs[1:]:
            d = np.minimum(d, _table_block(geom, q[start : start + CHECK_BLOCK]))
        if d.size == 0 or not np.isfinite(d).any():
            continue
        row_min = d.min(axis=1)
        bad = np.flatnonzero(row_min < geom.clearance)
        if bad.size:
            return _at_row(geom, d, int(bad[0]), start, label, times)
        i = int(np.argmin(row_min))
        if best is None or row_min[i] < best[0]:
            best = (float(row_min[i]), d[i : i + 1], 0, start + i)
    if best is None:
        return Clearance(ClearanceStatus.OK, "no pair to check", float("inf"), "", -1, geom.clearance)
    return _at_row(geom, best[1], best[2], best[3], label, times)


def check_poses(geom: Scene, q: np.ndarray, label: str = "waypoint", times: np.ndarray | None = None) -> Clearance:
    """Clearance of configurations ``q`` (N, 6) rad against the cell and themselves
    (:func:`first_violation` of :func:`distance_table`, block by block: the first block with a
    sample closer than the clearance ends the check)."""
    return _first_violation_of(geom, [np.atleast_2d(q)], label, times)


def largest_displacement(geom: Scene, q_a: np.ndarray, q_b: np.ndarray) -> tuple[float, str, int]:
    """Largest displacement (m) of a capsule end point between configurations ``q_a`` and ``q_b``
    (N, 6) rad, with the capsule's name and the sample."""
    a, b = segments(geom, q_a), segments(geom, q_b)
    dist = np.linalg.norm(a - b, axis=-1).max(axis=-1)  # (N, M)
    i, c = np.unravel_index(int(np.argmax(dist)), dist.shape)
    return float(dist[i, c]), geom.names[c], int(i)


@dataclass
class CellCheck:
    """What the plan's cell check found (``summary.json`` ``cell``).

    Attributes
    ----------
    geometry : Scene
    branches : dict branch -> Clearance
        Each usable branch's command at the waypoints (with its planned posture).
    waypoints : Clearance or None
        The chosen branch's command at the waypoints.
    trajectory : Clearance or None
        The controller's trajectory at every sample (``index`` the sample).
    trajectory_method : str or None
    trajectory_time_s : float or None
        Time of the trajectory's nearest sample, s.
    deflection_m : float
        Largest capsule end-point displacement between the chosen branch's command and its planned
        (deflected) posture at the waypoints, m; ``deflection_where``: capsule and waypoint.
    stiffness_best : int or None
        The branch the plan would choose without the cell.
    choice_note : str
        When the stiffness-best branch collides: what the collision-free choice pays (one line).
    check_time_s : dict
        Wall time of each check, s, and ``poses``: the number of poses checked.
    checked : dict branch -> (command, posture)
        The joints (N, 6) rad each entry of ``branches`` was checked at (:func:`check_command`
        does not measure them again).
    """

    geometry: Scene
    branches: dict[int, Clearance] = field(default_factory=dict)
    waypoints: Clearance | None = None
    trajectory: Clearance | None = None
    trajectory_method: str | None = None
    trajectory_time_s: float | None = None
    deflection_m: float = 0.0
    deflection_where: str = ""
    stiffness_best: int | None = None
    choice_note: str = ""
    check_time_s: dict[str, float] = field(default_factory=dict)
    checked: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, repr=False)


def check_branches(
    geom: Scene, postures: dict[int, np.ndarray], commands: dict[int, np.ndarray]
) -> dict[int, Clearance]:
    """Each branch's clearance at the waypoints: its command and its planned posture (the smaller).

    Parameters
    ----------
    postures, commands : dict branch -> ndarray, shape (N, 6)
        Planned (deflected) posture and exact command, rad (a command with non-finite values is
        left out: its planned posture alone is checked).
    """
    out = {}
    for b, q in postures.items():
        qc = commands.get(b)
        out[b] = _first_violation_of(geom, [q] if qc is None or not np.all(np.isfinite(qc)) else [q, qc])
    return out


# --------------------------------------------------------------------------------------
# The plan's stages
# --------------------------------------------------------------------------------------


#: Branch statuses whose kept (analytic) posture is checked too: the NLP with the cell's
#: clearance constraints failed on them, typically because no posture of the branch keeps it.
_KEPT = (BranchStatus.SOLVER_FAILED, BranchStatus.CONSTRAINT_VIOLATED)


def choose_collision_free(
    problem: Any, ps: PostureResult, geom: Scene | None = None, free: PostureResult | None = None
) -> tuple[PostureResult, CellCheck]:
    """Every usable branch checked at every waypoint, colliding ones set aside, the choice made
    again (:func:`problems.posture.solve.rechoose`).

    A branch whose exact command or planned posture comes closer than the clearance to an object
    or to itself gets status ``collision`` and the reason of its :class:`Clearance` (first
    waypoint, pair, penetration or distance in mm). When the stiffness-best posture in empty
    space (``free``, else ``ps``'s own choice) collides, the new choice's reason says what the
    collision-free posture pays in load-induced error.

    Parameters
    ----------
    problem : problems.problem.Problem
        With its ``cell``, arm model and load.
    ps : PostureResult
        The posture stage's result (status OK), solved with the cell's clearance constraints.
    geom : Scene, optional
        The geometry to check (default :func:`cell_geometry` of the problem).
    free : PostureResult, optional
        The same stage in empty space (no clearance constraints): what the cell costs.

    Returns
    -------
    PostureResult
        New (the branches replaced where they collide); status COLLISION if no branch is free.
    CellCheck
    """
    t0 = time.perf_counter()
    geom = geom or cell_geometry(problem.robot, problem.cell)
    arm, L = problem.model, problem.load.rows(problem.n)
    usable = {b: r for b, r in ps.branches.items() if r.status.usable}
    failed = {b: r for b, r in ps.branches.items() if r.status in _KEPT and np.all(np.isfinite(r.q))}
    commands = {b: exact(arm, r.q, L).q_command for b, r in usable.items()}
    found = check_branches(geom, {b: r.q for b, r in usable.items()}, commands)
    kept = check_branches(geom, {b: r.q for b, r in failed.items()}, {})
    ref = free if free is not None and free.ok else ps
    check = CellCheck(geom, found, stiffness_best=ref.chosen)
    check.checked = {b: (commands[b], usable[b].q) for b in found}
    branches = dict(ps.branches)
    for b, c in found.items():
        if c.status is not ClearanceStatus.OK:
            branches[b] = replace(branches[b], status=BranchStatus.COLLISION, reason=c.reason)
    for b, c in kept.items():  # the NLP found no posture that keeps the clearance
        if c.status is not ClearanceStatus.OK:
            why = f"{c.reason} (posture NLP: {branches[b].reason})"
            branches[b] = replace(branches[b], status=BranchStatus.COLLISION, reason=why)
            check.branches[b] = c
    out = rechoose(replace(ps, branches=branches))
    if out.ok and ref.chosen is not None:
        was = ref.branches[ref.chosen]
        was_c = (
            found[ref.chosen] if ref is ps else check_branches(geom, {0: was.q}, {0: exact(arm, was.q, L).q_command})[0]
        )
        if was_c.status is not ClearanceStatus.OK:
            now = out.best
            check.choice_note = (
                f"in empty space the stiffness-best posture ({was.label}) collides ({was_c.reason}): the "
                f"collision-free {now.label} pays RMS load-induced error {now.rms_error_m * 1e3:.4g} mm vs "
                f"{was.rms_error_m * 1e3:.4g} mm (x{now.rms_error_m / was.rms_error_m:.3g}, first order)"
            )
            out.reason += f"; {check.choice_note}"
    if out.ok:
        check.waypoints = found[out.chosen]
    elif out.status is PostureStatus.COLLISION:
        pairs = Counter(c.pair for c in found.values() if c.status is not ClearanceStatus.OK)
        out.reason += "; the pair at each branch's first violation: " + ", ".join(
            f"{p} ({n} branch(es))" for p, n in pairs.most_common()
        )
    check.check_time_s = {"branches_s": time.perf_counter() - t0, "poses": 2 * problem.n * len(usable)}
    return out, check


def check_command(check: CellCheck, q_command: np.ndarray, q_planned: np.ndarray, branch: int | None = None) -> None:
    """The chosen branch's command at the waypoints again (unless ``branch`` was checked at these
    very joints: :attr:`CellCheck.checked`), and the deflection between it and the planned posture
    (:attr:`CellCheck.deflection_m`)."""
    g = check.geometry
    seen = check.checked.get(branch) if branch is not None else None
    if seen is not None and np.array_equal(seen[0], q_command) and np.array_equal(seen[1], q_planned):
        check.waypoints = check.branches[branch]
    else:
        check.waypoints = _first_violation_of(g, [q_command, q_planned])
    size, capsule, k = largest_displacement(g, q_command, q_planned)
    check.deflection_m, check.deflection_where = size, f"{capsule} at waypoint {k}"


def check_trajectory(check: CellCheck, method: str, t: np.ndarray, q: np.ndarray) -> Clearance:
    """The controller's trajectory ``q`` (S, 6) rad at its samples ``t`` (S,) s against the cell;
    kept in ``check`` and returned."""
    t0 = time.perf_counter()
    c = check_poses(check.geometry, q, "sample", t)
    check.trajectory, check.trajectory_method = c, method
    check.trajectory_time_s = float(t[c.index]) if c.index >= 0 else None
    check.check_time_s["trajectory_s"] = time.perf_counter() - t0
    check.check_time_s["trajectory_poses"] = int(len(q))
    return c


def _block(c: Clearance | None) -> dict[str, Any] | None:
    if c is None:
        return None
    return {
        "status": c.status.value,
        "min_clearance_mm": c.distance * 1e3 if np.isfinite(c.distance) else None,
        "pair": c.pair or None,
        "index": c.index,
        "reason": c.reason,
    }


def cell_summary(check: CellCheck, labels: tuple[str, ...]) -> dict[str, Any]:
    """The ``cell`` block of ``summary.json`` (mm where the key says so, else SI)."""
    g = check.geometry
    traj = _block(check.trajectory)
    if traj is not None:
        traj["method"] = check.trajectory_method
        traj["time_s"] = check.trajectory_time_s
    per_pose = (
        check.check_time_s["trajectory_s"] / check.check_time_s["trajectory_poses"] * 1e6
        if check.check_time_s.get("trajectory_poses")
        else None
    )
    return {
        "clearance_mm": g.clearance * 1e3,
        "objects": [{"name": s.name, "shape": s.kind, "role": role} for s, role in zip(g.shapes, g.roles)],
        "capsules": {n: float(r) for n, r in zip(g.names, g.model.radius)},
        "radii_source": g.model.radii_source,
        "waypoints": _block(check.waypoints),
        "trajectory": traj,
        "branches": {labels[b]: _block(c) for b, c in check.branches.items()},
        "stiffness_best_branch": labels[check.stiffness_best] if check.stiffness_best is not None else None,
        "choice_note": check.choice_note or None,
        "deflection_margin_mm": check.deflection_m * 1e3,
        "deflection_where": check.deflection_where,
        "deflection_note": (
            "largest displacement of a capsule end point between the commanded joints and the planned "
            "(deflected) posture at the waypoints: the clearance must cover it"
        ),
        "what": (
            "commanded joints (path.csv) and planned postures at the waypoints, the controller's trajectory at "
            "every sample; capsules along the links and the tool (flange to TCP) against every object (the tool "
            "may touch the workpiece) and non-adjacent links against each other"
        ),
        "check_time_s": dict(check.check_time_s),
        "trajectory_us_per_pose": per_pose,
    }
