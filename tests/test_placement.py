"""The base-placement study's library: grid, transforms, the per-pose kernel, scores, pickling and
``problem_at`` (``problems/placement``).

The kernel's numbers are checked against independent evaluations: the IK along the path in a base
frame built here from elementary rotations, the arm model's ``load_error`` evaluated on it, the
posture warm starts' programme, and the same task moved into the placed base frame
(``problem_at``) instead of moving the robot.  The Dask side is ``tests/test_placement_dask.py``.
"""

from __future__ import annotations

import functools
import math
import pickle
from dataclasses import replace

import numpy as np
import pytest

from models.errors import InputError
from models.ik import IKStatus, ik_solver
from models.load import Load
from problems.path import branch_paths
from problems.placement.grid import (
    GRID_AXES,
    PlacementGrid,
    PlacementGridError,
    base2cell,
    cell2base,
    grid_from_table,
    parse_grid_text,
)
from problems.placement.kernel import PlacementKernel
from problems.placement.placed import problem_at
from problems.placement.scores import RANK_RESOLUTION_M, RANK_RESOLUTION_SINGULAR, ChunkScores, PlacementStatus, ranking
from problems.posture import OrientationRule
from problems.posture.verification import guard_bounds
from problems.posture.warm_start import warm_starts
from problems.problem import ProblemFileError, load_problem

# --------------------------------------------------------------------------------------
# Named tolerances (why each is what it is)
# --------------------------------------------------------------------------------------

#: Grid values from ``linspace`` against values written here (a few ulps of metres / radians).
GRID_TOL = 1e-12
#: Homogeneous transforms built two ways from the same angles (round-off of a few products).
TRANSFORM_TOL = 1e-14
#: The kernel's load-induced errors against the same compiled ``load_error`` evaluated here on
#: the IK of independently built base-frame poses: the joint angles may differ by a 2 pi k
#: (unwrapping) and by round-off of the pose products, i.e. ~1e-15 rad -> ~1e-18 m of error.
ERROR_ATOL_M = 1e-12
#: The same for the singularity-margin ratio (dimensionless, of order 1..100).
RATIO_RTOL = 1e-10
#: Joint margins: angles accumulated over 30 wrapped steps (np.unwrap here, the kernel's own
#: wrap there): round-off of ~30 additions of numbers of order pi.
JOINT_MARGIN_ATOL_RAD = 1e-9
#: Moving the robot vs moving the task: the same IK of poses that differ only by the order of
#: the rotation products (R (R_nom Rz) vs (R R_nom) Rz), i.e. ~1e-16 relative -> ~1e-18 m.
EQUIVALENCE_ATOL_M = 1e-12
#: Warm starts (float64 dense programme) vs the kernel (float32 programme) at scan <= 36: when
#: both pick the same sequence the node-cost sums agree to the round-off of sqrt/mean.
WARM_COST_RTOL = 1e-12
#: Compiled C vs CasADi's virtual machine evaluating the same expression graph.
VM_ATOL_M = 1e-12
#: Scores of one chunk against the scores of the same placements split into two chunks.
CHUNK_SPLIT_ATOL = 1e-12

DEG = math.pi / 180.0


# --------------------------------------------------------------------------------------
# Helpers built here, independently of the library
# --------------------------------------------------------------------------------------


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def homog(R: np.ndarray | None = None, t: np.ndarray | None = None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def my_base2cell(p: np.ndarray) -> np.ndarray:
    """Trans(x, y, z) @ Rz(yaw) @ Rx(tilt), composed from elementary 4x4 transforms."""
    x, y, z, yaw, tilt = (float(v) for v in p)
    return homog(t=np.array([x, y, z])) @ homog(rot_z(yaw)) @ homog(rot_x(tilt))


def my_cell2base(p: np.ndarray) -> np.ndarray:
    return np.linalg.inv(my_base2cell(p))


@functools.cache
def shipped(name: str):
    return load_problem(name)


@functools.cache
def kernel_of(name: str) -> PlacementKernel:
    return PlacementKernel(shipped(name))


def small_grid(problem) -> PlacementGrid:
    return parse_grid_text("x_m=-0.4:0.4:3,y_m=-0.6:0.6:3,yaw_deg=0:90:2", base=problem.placement)


def _variant(name: str):
    if name == "milling_tool_wrench":
        return replace(shipped("placement_milling"), wrench_frame="tool")
    if name == "milling_base_moment":
        p = shipped("placement_milling")
        W = p.wrench.copy()
        W[:, 3:] = [2.0, -1.0, 3.0]  # N*m, cell frame
        return replace(p, wrench=W)
    if name == "milling_payload":
        return replace(shipped("placement_milling"), payload_mass_kg=4.0, payload_com_m=np.array([0.03, -0.02, 0.06]))
    return shipped(name)


# ======================================================================================
# 1. Grid
# ======================================================================================


def test_parse_grid_values_are_inclusive_ranges_in_si_units():
    g = parse_grid_text("x_m=-0.4:0.4:3, y_m=0.25, yaw_deg=0:270:4, tilt_deg=90, top=5")
    np.testing.assert_allclose(g.axes["x_m"], [-0.4, 0.0, 0.4], atol=GRID_TOL)
    np.testing.assert_allclose(g.axes["y_m"], [0.25], atol=GRID_TOL)
    np.testing.assert_allclose(g.axes["z_m"], [0.0], atol=GRID_TOL)  # not given: 0
    np.testing.assert_allclose(g.axes["yaw_deg"], np.array([0.0, 90.0, 180.0, 270.0]) * DEG, atol=GRID_TOL)
    np.testing.assert_allclose(g.axes["tilt_deg"], [math.pi / 2], atol=GRID_TOL)
    assert g.top == 5
    assert g.shape == (3, 1, 1, 4, 1) and g.size == 12
    # the same from a table (file form)
    t = grid_from_table({"x_m": [-0.4, 0.4, 3], "y_m": 0.25, "yaw_deg": [0, 270, 4], "tilt_deg": 90, "top": 5})
    for k in GRID_AXES:
        np.testing.assert_allclose(t.axes[k], g.axes[k], atol=GRID_TOL)
    assert t.top == 5


def test_parse_grid_keeps_the_base_grids_other_axes():
    base = grid_from_table({"x_m": [0, 1, 2], "z_m": 0.3, "yaw_deg": [0, 90, 2], "top": 2})
    g = parse_grid_text("x_m=0.5", base=base)
    np.testing.assert_allclose(g.axes["x_m"], [0.5], atol=GRID_TOL)
    np.testing.assert_allclose(g.axes["z_m"], [0.3], atol=GRID_TOL)
    np.testing.assert_allclose(g.axes["yaw_deg"], [0.0, math.pi / 2], atol=GRID_TOL)
    assert g.top == 2


def test_placements_order_is_x_fastest_and_indices_are_stable():
    text = "x_m=0:2:3, y_m=1:1.5:2, z_m=0.5, yaw_deg=0:90:2, tilt_deg=0:180:2"
    g = parse_grid_text(text)
    xs, ys, zs = [0.0, 1.0, 2.0], [1.0, 1.5], [0.5]
    yaws, tilts = [0.0, math.pi / 2], [0.0, math.pi]
    expected = [[x, y, z, yw, t] for t in tilts for yw in yaws for z in zs for y in ys for x in xs]
    P = g.placements()
    assert P.shape == (24, 5)
    np.testing.assert_allclose(P, expected, atol=GRID_TOL)
    # the same grid parsed again (and from a table) gives the same indices
    np.testing.assert_array_equal(parse_grid_text(text).placements(), P)
    t = grid_from_table(
        {"x_m": [0, 2, 3], "y_m": [1, 1.5, 2], "z_m": 0.5, "yaw_deg": [0, 90, 2], "tilt_deg": [0, 180, 2]}
    )
    np.testing.assert_array_equal(t.placements(), P)


def test_describe_gives_edge_units_and_round_trips():
    g = parse_grid_text("x_m=-0.6:1.0:17, y_m=0.2, yaw_deg=0:270:4, top=4")
    d = g.describe()
    assert d["x_m"] == pytest.approx([-0.6, 1.0, 17])
    assert d["y_m"] == pytest.approx(0.2)
    assert d["yaw_deg"] == pytest.approx([0.0, 270.0, 4])
    assert d["z_m"] == 0.0 and d["tilt_deg"] == 0.0
    assert d["placements"] == 17 * 4 and d["top"] == 4
    back = grid_from_table({k: v for k, v in d.items() if k != "placements"})
    for k in GRID_AXES:
        np.testing.assert_allclose(back.axes[k], g.axes[k], atol=GRID_TOL)


@pytest.mark.parametrize(
    "text, must_name",
    [
        ("w_m=1", ["w_m"]),  # unknown key
        ("x_m=0:1:0", ["x_m", "0"]),  # count 0
        ("x_m=0:1:2.5", ["x_m", "2.5"]),  # count not whole
        ("x_m=1:0:3", ["x_m", "1", "0"]),  # start > stop
        ("x_m=abc", ["x_m", "abc"]),  # not a number
        ("yaw_deg=0:90", ["yaw_deg", "0:90"]),  # two parts
        ("x_m=nan", ["x_m", "nan"]),  # not finite
        ("x_m", ["x_m"]),  # no '='
        ("x_m=", ["x_m"]),  # no value
        ("top=many", ["top", "many"]),  # top not an integer
        ("top=11", ["top", "11"]),  # top out of range
        ("x_m=0:1:1", ["x_m", "1"]),  # count 1 with start != stop
    ],
)
def test_bad_grid_text_names_the_key_and_the_value(text, must_name):
    with pytest.raises(PlacementGridError) as ei:
        parse_grid_text(text)
    assert isinstance(ei.value, InputError)
    msg = str(ei.value)
    assert "--grid" in msg
    for s in must_name:
        assert s in msg, (s, msg)


@pytest.mark.parametrize(
    "tab, must_name",
    [
        ({"x_m": [0.0, 1.0, 0]}, ["x_m", "0"]),
        ({"x_m": [0.0, 1.0]}, ["x_m"]),
        ({"y_m": "0.3"}, ["y_m", "'0.3'"]),
        ({"z_m": True}, ["z_m", "True"]),
        ({"yaw_deg": [0.0, "90", 2]}, ["yaw_deg", "'90'"]),
        ({"tilt_deg": [0.0, 90.0, True]}, ["tilt_deg", "True"]),
        ({"x_m": 0.0, "height": 1.0}, ["height"]),
        ({"top": -1}, ["top", "-1"]),
    ],
)
def test_bad_grid_table_names_the_key_and_the_value(tab, must_name):
    with pytest.raises(PlacementGridError) as ei:
        grid_from_table(tab)
    msg = str(ei.value)
    assert "[placement]" in msg
    for s in must_name:
        assert s in msg, (s, msg)


def _milling_toml_with(placement_table: str) -> str:
    from importlib import resources

    text = resources.files("problems").joinpath("files/placement_milling.toml").read_text(encoding="utf-8")
    head, sep, _ = text.partition("\n[placement]")
    assert sep, "placement_milling.toml has a [placement] table"
    return head + "\n[placement]\n" + placement_table + "\n"


def test_problem_file_placement_table_is_read(tmp_path):
    f = tmp_path / "grid_ok.toml"
    f.write_text(_milling_toml_with("x_m = [0.2, 0.6, 5]\ny_m = -0.1\nyaw_deg = [0, 180, 3]\ntop = 2\n"))
    p = load_problem(f)
    g = p.placement
    np.testing.assert_allclose(g.axes["x_m"], [0.2, 0.3, 0.4, 0.5, 0.6], atol=GRID_TOL)
    np.testing.assert_allclose(g.axes["y_m"], [-0.1], atol=GRID_TOL)
    np.testing.assert_allclose(g.axes["yaw_deg"], [0.0, math.pi / 2, math.pi], atol=GRID_TOL)
    assert g.top == 2 and g.size == 15
    # the shipped file's table, as its comments say: every 0.1 m, 4 yaws
    s = shipped("placement_milling").placement
    np.testing.assert_allclose(np.diff(s.axes["x_m"]), 0.1, atol=GRID_TOL)
    np.testing.assert_allclose(s.axes["yaw_deg"], np.array([0, 90, 180, 270]) * DEG, atol=GRID_TOL)


@pytest.mark.parametrize(
    "table, must_name",
    [
        ("x_m = [1.0, 0.0, 3]", ["x_m", "start"]),
        ("x_m = [0.0, 1.0, 0]", ["x_m", "0"]),
        ("depth_m = 0.3", ["depth_m"]),
        ('y_m = "left"', ["y_m", "left"]),
        ("top = 99", ["top", "99"]),
    ],
)
def test_problem_file_bad_placement_table(tmp_path, table, must_name):
    f = tmp_path / "grid_bad.toml"
    f.write_text(_milling_toml_with(table))
    with pytest.raises(ProblemFileError) as ei:
        load_problem(f)
    msg = str(ei.value)
    assert "[placement]" in msg and str(f) in msg
    for s in must_name:
        assert s in msg, (s, msg)


# ======================================================================================
# 2. Transforms
# ======================================================================================

PLACEMENTS_FOR_TRANSFORMS = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [0.3, -0.2, 0.1, 45 * DEG, 0.0],
        [-0.5, 0.7, 1.2, -120 * DEG, 90 * DEG],
        [0.1, 0.2, 2.0, 200 * DEG, 180 * DEG],
        [1.0, -1.0, 0.4, 33 * DEG, -37 * DEG],
    ]
)


def test_base2cell_is_trans_rz_rx():
    T = base2cell(PLACEMENTS_FOR_TRANSFORMS)
    assert T.shape == (len(PLACEMENTS_FOR_TRANSFORMS), 4, 4)
    for p, Tp in zip(PLACEMENTS_FOR_TRANSFORMS, T):
        np.testing.assert_allclose(Tp, my_base2cell(p), atol=TRANSFORM_TOL)
    # the physical meaning: tilt 90 deg (wall) turns the base z axis onto -y of the cell
    wall = base2cell(np.array([[0, 0, 0, 0, math.pi / 2]]))[0]
    np.testing.assert_allclose(wall[:3, 2], [0.0, -1.0, 0.0], atol=TRANSFORM_TOL)
    ceiling = base2cell(np.array([[0, 0, 0, 0, math.pi]]))[0]
    np.testing.assert_allclose(ceiling[:3, 2], [0.0, 0.0, -1.0], atol=TRANSFORM_TOL)


def test_cell2base_is_the_inverse():
    A, B = base2cell(PLACEMENTS_FOR_TRANSFORMS), cell2base(PLACEMENTS_FOR_TRANSFORMS)
    for a, b, p in zip(A, B, PLACEMENTS_FOR_TRANSFORMS):
        np.testing.assert_allclose(a @ b, np.eye(4), atol=TRANSFORM_TOL)
        np.testing.assert_allclose(b @ a, np.eye(4), atol=TRANSFORM_TOL)
        np.testing.assert_allclose(b, my_cell2base(p), atol=TRANSFORM_TOL)


# ======================================================================================
# 3. The kernel's numbers against an independent evaluation (fixed orientation)
# ======================================================================================


def _fixed(name: str):
    p = _variant(name)
    return p if p.rule is OrientationRule.FIXED else replace(p, rule=OrientationRule.FIXED)


def _base_frame_load(problem, c2b: np.ndarray) -> Load:
    """The problem's load in the placed base frame, built here from the problem's fields."""
    R = c2b[:3, :3]
    W = np.asarray(problem.wrench, dtype=float)
    if problem.wrench_frame == "base":
        wb, wt = np.hstack([W[:, :3] @ R.T, W[:, 3:] @ R.T]), np.zeros_like(W)
    else:
        wb, wt = np.zeros_like(W), W
    g = problem.robot.gravity if problem.gravity is None else problem.gravity
    return Load(
        wrench_base=wb,
        wrench_tool=wt,
        payload_mass_kg=problem.payload_mass_kg,
        payload_com_m=problem.payload_com_m,
        gravity=R @ np.asarray(g, dtype=float),
    )


def _independent_margin(
    q_raw_start: np.ndarray, q_path: np.ndarray, q_min: np.ndarray, q_max: np.ndarray
) -> float | None:
    """Joint margin of a continuous path after the documented shift: per joint the 2 pi k nearest
    zero (relative to the IK's own start value) that puts the whole path inside the limits."""
    # the same path, started at the IK's own value of waypoint 0
    q = q_path - 2 * np.pi * np.round((q_path[0] - q_raw_start) / (2 * np.pi))
    out = np.empty_like(q)
    for j in range(6):
        for k in sorted(range(-4, 5), key=abs):
            c = q[:, j] + 2 * np.pi * k
            if c.min() >= q_min[j] - 1e-12 and c.max() <= q_max[j] + 1e-12:
                out[:, j] = c
                break
        else:
            return None
    return float(np.minimum(out - q_min, q_max - out).min())


FIXED_CASES = [
    (
        "placement_milling",
        np.array(
            [
                [0.0, 0.0, 0.0, 0.0, 0.0],
                [0.1, -0.2, 0.05, 30 * DEG, 0.0],
                [0.2, 0.3, 0.0, -60 * DEG, 90 * DEG],
                [-0.2, 0.1, 0.3, 20 * DEG, 45 * DEG],
            ]
        ),
    ),
    (
        "ur10_payload_tilt",
        np.array([[0.0, 0.0, 0.0, 0.0, 0.0], [0.1, -0.2, 0.05, 30 * DEG, 0.0], [0.0, 0.0, 0.6, 45 * DEG, 180 * DEG]]),
    ),
    ("milling_base_moment", np.array([[0.1, -0.2, 0.05, 30 * DEG, 0.0], [-0.2, 0.1, 0.3, 20 * DEG, 45 * DEG]])),
]


@pytest.mark.parametrize("name, placements", FIXED_CASES, ids=[c[0] for c in FIXED_CASES])
def test_kernel_matches_independent_ik_and_load_error(name, placements):
    """Fixed orientation: one candidate, so the sequence is forced and every kernel number of a
    branch is the IK path's own, evaluated here through ``ArmModel.load_error``."""
    p = _fixed(name)
    arm = p.model
    assert "gravity" not in arm.active_effects  # the model's gravity constant plays no part
    kern = PlacementKernel(p)
    assert kern.n_candidates == 1
    sc = kern.evaluate(placements)
    ik = ik_solver(p.robot)
    bounds = guard_bounds(ik)
    checked = 0
    for i, pl in enumerate(placements):
        c2b = my_cell2base(pl)
        T_cell = np.zeros((p.n, 4, 4))
        T_cell[:, :3, :3], T_cell[:, :3, 3], T_cell[:, 3, 3] = p.rotations, p.positions, 1.0
        T_base = np.einsum("ij,njk->nik", c2b, T_cell)
        feasible, _ = branch_paths(ik, T_base, p.limits.max_joint_step)
        raw = ik.solve(T_base)
        load = _base_frame_load(p, c2b)
        assert sc.status[i] == PlacementStatus.OK.code, f"placement {i} should be feasible (test set-up)"
        for b in range(kern.n_branches):
            kern_ok = np.isfinite(sc.branch_rms_m[i, b])
            if b not in feasible:
                assert not kern_ok, f"placement {i}, branch {b}: kernel feasible, IK path not"
                continue
            q = feasible[b].q
            ratio = (np.abs(ik.guard_factors(q)) / bounds).min()
            margin = _independent_margin(raw.q[0, b], q, ik.q_min, ik.q_max)
            if ratio < 1.0 or margin is None:
                assert not kern_ok, f"placement {i}, branch {b}: inside a guard or limits, but kernel-feasible"
                continue
            assert kern_ok, f"placement {i}, branch {b}: feasible here (ratio {ratio:.3g}), not in the kernel"
            e = np.linalg.norm(arm.load_error(q, load)[:, :3], axis=1)
            assert sc.branch_rms_m[i, b] == pytest.approx(np.sqrt(np.mean(e**2)), rel=0, abs=ERROR_ATOL_M)
            assert sc.branch_max_m[i, b] == pytest.approx(e.max(), rel=0, abs=ERROR_ATOL_M)
            assert sc.branch_singular_margin[i, b] == pytest.approx(ratio, rel=RATIO_RTOL)
            assert sc.branch_joint_margin_rad[i, b] == pytest.approx(margin, abs=JOINT_MARGIN_ATOL_RAD)
            checked += 1
        # the best branch is the feasible one with the smallest RMS error
        b = int(sc.best_branch[i])
        assert sc.rms_error_m[i] == np.nanmin(sc.branch_rms_m[i]) == sc.branch_rms_m[i, b]
        assert sc.max_error_m[i] == sc.branch_max_m[i, b]
    assert checked >= 2 * len(placements)  # not vacuous


# ======================================================================================
# 4. Moving the robot == moving the task
# ======================================================================================

EQUIV_PLACEMENTS = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0],
        [0.1, -0.2, 0.05, 30 * DEG, 0.0],
        [0.2, 0.3, 0.0, -60 * DEG, 90 * DEG],  # wall
        [0.0, 0.0, 0.6, 45 * DEG, 180 * DEG],  # ceiling
        [-0.2, 0.1, 0.3, 20 * DEG, 45 * DEG],
        [5.0, 0.0, 0.0, 0.0, 0.0],  # out of reach
    ]
)


@pytest.mark.parametrize(
    "name",
    [
        "placement_milling",
        "milling_base_moment",
        "milling_tool_wrench",
        "milling_payload",
        "ur10_payload_tilt",
        "machining_offaxis",
    ],
)
def test_moving_the_robot_equals_moving_the_task(name):
    p = _variant(name)
    sc = PlacementKernel(p).evaluate(EQUIV_PLACEMENTS)
    n_ok = 0
    for i, pl in enumerate(EQUIV_PLACEMENTS):
        moved = PlacementKernel(problem_at(p, pl)).evaluate(np.zeros((1, 5)))
        one = ChunkScores.concatenate([sc_row(sc, i)])
        assert one.status[0] == moved.status[0] and one.best_branch[0] == moved.best_branch[0], i
        np.testing.assert_array_equal(np.isnan(one.branch_rms_m), np.isnan(moved.branch_rms_m))
        assert one.max_difference(moved) <= EQUIVALENCE_ATOL_M, (i, one.max_difference(moved))
        n_ok += int(one.status[0] == PlacementStatus.OK.code)
    assert n_ok >= 4  # the comparison is not vacuous
    assert sc.status[-1] != PlacementStatus.OK.code


def sc_row(sc: ChunkScores, i: int) -> ChunkScores:
    from dataclasses import fields

    return ChunkScores(**{f.name: getattr(sc, f.name)[i : i + 1] for f in fields(ChunkScores)})


def _self_weight(problem, gravity=None):
    """The problem on a model with the arm's self-weight (the ``gravity`` effect), optionally with
    a robot-file gravity other than vertical (e.g. a robot file written for a wall mount)."""
    g = problem.robot.gravity if gravity is None else np.asarray(gravity, dtype=float)
    robot = replace(problem.robot, gravity=g)
    arm = replace(
        problem.model, nominal=replace(problem.model.nominal, gravity=g), gravity_on=True, effects=["gravity"]
    )
    assert "gravity" in arm.active_effects and robot.has_masses
    return replace(problem, robot=robot, arm=arm)


def test_self_weight_turns_with_the_tilt():
    """With self-weight the arm's gravity turns into each placement's base frame (one kernel, every tilt)."""
    p = _self_weight(shipped("placement_milling").with_points(10))
    pls = np.array(
        [[0.0, 0.0, 0.0, 0.0, 0.0], [0.2, 0.3, 0.0, -60 * DEG, 90 * DEG], [0.0, 0.0, 0.6, 45 * DEG, 180 * DEG]]
    )
    kern = PlacementKernel(p)
    sc = kern.evaluate(pls)
    for i, pl in enumerate(pls):
        moved = PlacementKernel(problem_at(p, pl)).evaluate(np.zeros((1, 5)))
        assert sc.status[i] == PlacementStatus.OK.code == moved.status[0]
        assert sc_row(sc, i).max_difference(moved) <= EQUIVALENCE_ATOL_M
    # and the self-weight matters here (else the test above proves nothing about its rotation)
    flat = PlacementKernel(shipped("placement_milling").with_points(10)).evaluate(pls)
    assert np.nanmax(np.abs(flat.branch_rms_m - sc.branch_rms_m)) > 1e-6


def test_load_error_gravity_input_equals_the_model_with_that_gravity():
    """``load_error_g(q, L, g)`` (the kernel's model function) equals ``load_error`` of the same
    arm model built with robot gravity ``g``, for the robot's own gravity and for turned ones."""
    p = _self_weight(shipped("placement_milling").with_points(10))
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (20, 6))
    L = np.tile(p.task().load[0], (20, 1))
    f = p.model.kinematics.load_error_gravity
    assert f.name() == "load_error_g" and f.name_in() == ["q", "L", "g"]
    g0 = np.asarray(p.model.nominal.gravity, dtype=float)
    for g in (g0, np.array([0.0, -9.80665, 0.0]), np.array([3.0, -4.0, -8.0])):
        other = replace(p.model, nominal=replace(p.model.nominal, gravity=g))
        ref = other.load_error(q, L)
        got = np.array([np.asarray(f(qi, Li, g)).ravel() for qi, Li in zip(q, L)])
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-15)
    # the input matters (self-weight on): a turned gravity changes the error
    turned = np.array([np.asarray(f(qi, Li, [0.0, -9.80665, 0.0])).ravel() for qi, Li in zip(q, L)])
    assert np.abs(turned - p.model.load_error(q, L)).max() > 1e-6


def test_self_weight_with_non_vertical_robot_gravity_and_a_yaw():
    p = _self_weight(shipped("placement_milling").with_points(10), gravity=[0.0, -9.80665, 0.0])
    pl = np.array([[0.0, 0.0, 0.0, 90 * DEG, 0.0]])
    sc = PlacementKernel(p).evaluate(pl)
    moved = PlacementKernel(problem_at(p, pl[0])).evaluate(np.zeros((1, 5)))
    assert moved.status[0] == PlacementStatus.OK.code
    assert sc.max_difference(moved) <= EQUIVALENCE_ATOL_M


# ======================================================================================
# 5. Agreement with the posture warm starts
# ======================================================================================

WARM_PLACEMENTS = np.array(
    [[0.0, 0.0, 0.0, 0.0, 0.0], [0.1, -0.2, 0.05, 30 * DEG, 0.0], [-0.2, 0.1, 0.3, 20 * DEG, 45 * DEG]]
)


def _scan60():
    return replace(shipped("machining_offaxis"), scan=60)


@pytest.mark.parametrize("name", ["placement_milling", "machining_offaxis", "machining_offaxis_scan60"])
def test_kernel_agrees_with_the_warm_starts(name):
    """The warm starts' cost of a branch is the node-cost sum of its programme's sequence,
    sum_k ||e_k||^2 (m^2); the kernel reports the same sequence's RMS, so N * rms^2 must be it.
    placement_milling (scan 12) and machining_offaxis (scan 36) run the dense programme (as the
    warm starts do up to 48 candidates), scan 60 the neighbour-restricted one (both)."""
    p = _scan60() if name.endswith("scan60") else shipped(name)
    kern = PlacementKernel(p) if name.endswith("scan60") else kernel_of(name)
    assert kern.n_candidates == p.scan
    sc = kern.evaluate(WARM_PLACEMENTS)
    compared = 0
    for i, pl in enumerate(WARM_PLACEMENTS):
        pp = p if not pl.any() else problem_at(p, pl)
        ws = warm_starts(ik_solver(pp.robot), pp.model.kinematics, pp.task())
        feas = set(np.flatnonzero(np.isfinite(sc.branch_rms_m[i])).tolist())
        assert feas == set(ws.warm), (i, feas, sorted(ws.warm), ws.rejected)
        for b, (_, _, cost) in ws.warm.items():
            assert p.n * sc.branch_rms_m[i, b] ** 2 == pytest.approx(cost, rel=WARM_COST_RTOL), (i, b)
            compared += 1
        if ws.warm:
            assert int(sc.best_branch[i]) == min(ws.warm, key=lambda b: ws.warm[b][2])
    assert compared >= 8


YAW_JUMP = """
name = "yaw_jump"
[robot]
model = "ur10"
tool = { xyz = [0.0, 0.09, 0.16], rpy_deg = [0.0, 0.0, 0.0] }
[path]
kind = "waypoints"
positions = [[0.65, -0.10, 0.10], [0.65, -0.05, 0.10], [0.65, 0.0, 0.10], [0.65, 0.05, 0.10]]
rpy_deg = [[180.0, 0.0, 0.0], [180.0, 0.0, 0.0], [180.0, 0.0, 90.0], [180.0, 0.0, 90.0]]
[orientation]
rule = "free_tool_axis"
scan = 60
[wrench]
force = [40.0, -80.0, 60.0]
[limits]
max_joint_step = 0.3
"""


def test_a_blocked_restricted_programme_falls_back_to_the_dense_one():
    """The nominal orientation turns 90 deg between waypoints 1 and 2: with 60 candidates the
    neighbour-restricted programme (35 deg) has no flip-free sequence, the dense one has (the
    candidate 90 deg away keeps the tool still); as the warm starts, the kernel finds it."""
    import tomllib
    from problems.problem import problem_from_dict

    p = problem_from_dict(tomllib.loads(YAW_JUMP), "yaw_jump")
    kern = PlacementKernel(p)
    assert kern._nbr.shape[1] < kern.n_candidates == 60
    sc = kern.evaluate(np.zeros((1, 5)))
    ws = warm_starts(ik_solver(p.robot), p.model.kinematics, p.task())
    assert sc.status[0] == PlacementStatus.OK.code and len(ws.warm) >= 4
    assert set(np.flatnonzero(np.isfinite(sc.branch_rms_m[0])).tolist()) == set(ws.warm)
    for b, (_, _, cost) in ws.warm.items():
        assert p.n * sc.branch_rms_m[0, b] ** 2 <= cost * (1 + WARM_COST_RTOL)


def test_a_waypoint_excluded_only_by_joint_limits_is_joint_limit(tmp_path):
    """Joint 6 limited to +-40 deg: at (0.2, -1.0) a waypoint's IK solutions all lie outside the
    limits (JOINT_LIMIT, that waypoint named), where the +-360 deg arm is feasible; at (0.9, -0.2)
    the orientation scan still finds solutions inside them; far away it stays UNREACHABLE."""
    from importlib import resources

    text = resources.files("models").joinpath("robots/ur10.toml").read_text(encoding="utf-8")
    k = text.rfind("[[joints]]")
    old = "q_min_deg = -360.0\nq_max_deg = 360.0"
    assert old in text[k:]
    (tmp_path / "ur10_j6.toml").write_text(text[:k] + text[k:].replace(old, "q_min_deg = -40.0\nq_max_deg = 40.0", 1))
    p = shipped("placement_milling").with_robot(str(tmp_path / "ur10_j6.toml"))
    pls = np.array([[0.9, -0.2, 0.0, 0.0, 0.0], [0.2, -1.0, 0.0, 0.0, 0.0], [5.0, 0.0, 0.0, 0.0, 0.0]])
    sc = PlacementKernel(p).evaluate(pls)
    free = kernel_of("placement_milling").evaluate(pls)
    assert free.status.tolist() == [PlacementStatus.OK.code, PlacementStatus.OK.code, PlacementStatus.UNREACHABLE.code]
    assert [sc.status_of(i) for i in range(3)] == [
        PlacementStatus.OK,
        PlacementStatus.JOINT_LIMIT,
        PlacementStatus.UNREACHABLE,
    ]
    assert sc.blocked_waypoint[1] > 0 and free.blocked_waypoint[1] == -1


# ======================================================================================
# 6. Statuses, ranking, ChunkScores
# ======================================================================================


def test_far_placement_is_unreachable_at_waypoint_0():
    p = shipped("placement_milling")
    far = parse_grid_text("x_m=5, y_m=0, yaw_deg=0").placements()
    sc = kernel_of("placement_milling").evaluate(far)
    assert sc.status[0] == PlacementStatus.UNREACHABLE.code
    assert sc.blocked_waypoint[0] == 0
    assert sc.best_branch[0] == -1 and sc.feasible_branches[0] == 0
    assert np.isnan(sc.rms_error_m[0]) and np.isnan(sc.branch_rms_m[0]).all()
    # independently: the path's start is farther from the base than the arm's reach (sum of links)
    r = p.robot
    reach = float(np.sum(np.abs(r.a)) + np.sum(np.abs(r.d)) + np.linalg.norm(r.tcp2flange[:3, 3]))
    assert np.linalg.norm(p.positions[0] - far[0, :3]) > reach


@pytest.mark.slow
def test_partial_reach_names_the_first_unreachable_waypoint():
    """Placements across the shipped grid, some too far for part of the path: the kernel's blocked
    waypoint is the first one without an IK solution outside the singularity guards on any branch
    at any scanned orientation (checked here against the IK itself), and such a placement is
    UNREACHABLE."""
    from problems.posture.warm_start import candidates

    p = shipped("placement_milling")
    kern = kernel_of("placement_milling")
    ik = ik_solver(p.robot)
    grid = parse_grid_text("x_m=-0.6:1.0:17, y_m=-1.0:1.0:21", base=p.placement)
    pls = grid.placements()[::7]
    sc = kern.evaluate(pls)
    cands = candidates(p.task())
    T_cell = np.zeros((len(cands), p.n, 4, 4))
    for s, (_, R) in enumerate(cands):
        T_cell[s, :, :3, :3], T_cell[s, :, :3, 3], T_cell[s, :, 3, 3] = R, p.positions, 1.0
    partial = 0
    for i, pl in enumerate(pls):
        sol = ik.solve(np.einsum("ij,snjk->snik", my_cell2base(pl), T_cell).reshape(-1, 4, 4))
        ok = sol.status == IKStatus.OK.code  # (S*N, B)
        ratio = (np.abs(ik.guard_factors(np.where(ok[..., None], sol.q, 0.0))) / guard_bounds(ik)).min(-1)
        reach = (ok & (ratio >= 1.0)).reshape(len(cands), p.n, -1).any(axis=(0, 2))  # (N,)
        expected = -1 if reach.all() else int(np.argmin(reach))
        assert sc.blocked_waypoint[i] == expected, (i, pl)
        if expected >= 0:
            assert sc.status[i] == PlacementStatus.UNREACHABLE.code
            partial += int(reach.any())
    assert partial >= 1  # some placement reaches part of the path only
    assert (sc.blocked_waypoint >= 0).sum() >= 3 and (sc.status == PlacementStatus.OK.code).sum() >= 3


def test_flip_status_when_no_step_fits():
    p = shipped("placement_milling").with_points(8)
    p = replace(p, limits=replace(p.limits, max_joint_step=1e-4))  # 0.086 m between waypoints
    sc = PlacementKernel(p).evaluate(np.zeros((1, 5)))
    assert sc.status[0] == PlacementStatus.FLIP.code
    assert sc.blocked_waypoint[0] == -1 and sc.best_branch[0] == -1


def test_status_precedence_of_finish():
    """Synthetic rows: feasible; only limit failures; only flips; flips and limits; blocked waypoint."""
    sc = ChunkScores.empty(5, 2)
    sc.branch_rms_m[0] = [2e-3, 1e-3]
    sc.branch_max_m[0] = [3e-3, 4e-3]
    sc.branch_joint_margin_rad[0] = [0.5, 0.2]
    sc.branch_singular_margin[0] = [3.0, 2.0]
    sc.blocked_waypoint[4] = 7
    flip = np.array([[False, False], [False, False], [True, True], [True, False], [False, False]])
    limit = np.array([[False, False], [True, False], [False, False], [False, True], [False, False]])
    sc.finish(flip, limit)
    assert list(sc.status) == [
        PlacementStatus.OK.code,
        PlacementStatus.JOINT_LIMIT.code,
        PlacementStatus.FLIP.code,
        PlacementStatus.JOINT_LIMIT.code,
        PlacementStatus.UNREACHABLE.code,
    ]
    assert sc.best_branch[0] == 1 and sc.feasible_branches[0] == 2
    assert sc.rms_error_m[0] == 1e-3 and sc.max_error_m[0] == 4e-3
    assert sc.joint_margin_rad[0] == 0.2 and sc.singular_margin[0] == 2.0
    assert (sc.best_branch[1:] == -1).all() and np.isnan(sc.rms_error_m[1:]).all()


def test_ranking_is_feasible_only_and_sorted_by_rms():
    p = shipped("placement_milling")
    sc = kernel_of("placement_milling").evaluate(small_grid(p).placements())
    r = ranking(sc)
    assert set(r.tolist()) == set(np.flatnonzero(sc.status == PlacementStatus.OK.code).tolist())
    assert 0 < len(r) < len(sc)  # some feasible, some not (x = -0.4 m, y = +-0.6 m)
    q = np.round(sc.rms_error_m[r] / RANK_RESOLUTION_M)
    assert (np.diff(q) >= 0).all()
    # ties at the resolution (yaws that joint 1 absorbs): the larger singular margin first
    for a, b in zip(r[:-1], r[1:]):
        if q[list(r).index(a)] == q[list(r).index(b)] and round(sc.max_error_m[a] / RANK_RESOLUTION_M) == round(
            sc.max_error_m[b] / RANK_RESOLUTION_M
        ):
            assert round(sc.singular_margin[a] / RANK_RESOLUTION_SINGULAR) >= round(
                sc.singular_margin[b] / RANK_RESOLUTION_SINGULAR
            )


def test_ranking_ties_broken_by_margins_not_by_round_off():
    """Three placements with the same errors (one posture turned by yaws, round-off apart): the
    singularity margin counts only beyond RANK_RESOLUTION_SINGULAR, then the larger joint margin wins."""
    sc = ChunkScores.empty(4, 8)
    sc.status[:] = [PlacementStatus.OK.code] * 3 + [PlacementStatus.UNREACHABLE.code]
    sc.rms_error_m[:3] = [2.0e-4, 2.0e-4 + 1e-17, 2.0e-4 - 1e-17]
    sc.max_error_m[:3] = 3.0e-4
    sc.singular_margin[:3] = [7.63, 7.63 + 4e-15, 7.63 - 4e-15]
    sc.joint_margin_rad[:3] = [0.18, 0.77, 0.50]
    assert ranking(sc).tolist() == [1, 2, 0]
    sc.singular_margin[0] = 7.64  # a real difference in the margin decides first
    assert ranking(sc).tolist() == [0, 1, 2]


def test_chunk_scores_concatenate_equal_and_max_difference():
    p = shipped("placement_milling")
    kern = kernel_of("placement_milling")
    pls = small_grid(p).placements()
    whole = kern.evaluate(pls)
    parts = ChunkScores.concatenate([kern.evaluate(pls[:7]), kern.evaluate(pls[7:])])
    assert len(parts) == len(whole) == len(pls)
    assert parts.max_difference(whole) <= CHUNK_SPLIT_ATOL
    assert whole.equal(whole) and whole.max_difference(whole) == 0.0
    i = int(np.flatnonzero(whole.feasible)[0])
    other = ChunkScores.concatenate([whole])
    assert other.equal(whole)
    other.rms_error_m[i] += 1e-9
    assert not other.equal(whole)
    assert other.max_difference(whole) == pytest.approx(1e-9, rel=1e-6)
    other = ChunkScores.concatenate([whole])
    other.rms_error_m[i] = np.nan  # NaN where the other has a number
    assert not other.equal(whole) and other.max_difference(whole) == math.inf
    other = ChunkScores.concatenate([whole])
    other.status[i] = PlacementStatus.FLIP.code  # an integer array differs
    assert not other.equal(whole) and other.max_difference(whole) == math.inf


# ======================================================================================
# 7. Pickling (shipping the kernel to a worker)
# ======================================================================================


def test_pickled_kernel_gives_identical_scores():
    p = shipped("placement_milling")
    kern = kernel_of("placement_milling")
    pls = small_grid(p).placements()
    ref = kern.evaluate(pls)
    back = pickle.loads(pickle.dumps(kern))
    assert back.compiled == kern.compiled
    assert back.evaluate(pls).equal(ref)


def test_pickled_kernel_on_another_cpu_falls_back_to_the_vm():
    p = shipped("placement_milling")
    kern = kernel_of("placement_milling")
    if not kern.compiled:
        pytest.skip("no C compiler here: the kernel already runs on the virtual machine")
    pls = small_grid(p).placements()
    ref = kern.evaluate(pls)
    moved = pickle.loads(pickle.dumps(kern))  # a copy: the cached kernel stays as it is
    for st in (moved._model_state, moved._ik_state):
        assert st["library"] is not None
        st["host"] = "some other CPU"
    elsewhere = pickle.loads(pickle.dumps(moved))
    assert elsewhere.compiled is False
    got = elsewhere.evaluate(pls)
    np.testing.assert_array_equal(got.status, ref.status)
    np.testing.assert_array_equal(got.best_branch, ref.best_branch)
    assert got.max_difference(ref) <= VM_ATOL_M
    assert kern.compiled  # the original is untouched


_NO_COMPILER_WORKER = """
import os, pickle, sys
import numpy as np
from models.codegen import BatchFunction
from problems.placement.kernel import PlacementKernel
from problems.problem import load_problem
kernel, placements = pickle.loads(sys.stdin.buffer.read())
scores = kernel.evaluate(placements)
own = PlacementKernel(load_problem("placement_milling").with_points(5))   # built here: no compiler
sys.stdout.buffer.write(pickle.dumps((kernel.compiled, isinstance(kernel.ik.evaluator, BatchFunction),
                                     own.compiled, scores)))
"""


@pytest.mark.slow
def test_a_worker_without_a_compiler_runs_the_shipped_libraries(tmp_path):
    """A process with no C compiler and an empty compile cache (a bare Dask worker) unpickles the
    kernel and runs the model's and the IK's compiled libraries it carries: the same scores, bit for
    bit, while a kernel built in that process runs on CasADi's virtual machine."""
    import os
    import subprocess
    import sys

    kern = kernel_of("placement_milling")
    if not kern.compiled:
        pytest.skip("no C compiler here: nothing compiled to ship")
    pls = small_grid(shipped("placement_milling")).placements()
    ref = kern.evaluate(pls)
    env = dict(os.environ, CC=str(tmp_path / "no-such-cc"), PATH=str(tmp_path), COMPPLAN_CACHE=str(tmp_path / "cache"))
    env.pop("COMPPLAN_NO_COMPILER", None)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run(
        [sys.executable, "-c", _NO_COMPILER_WORKER],
        input=pickle.dumps((kern, pls)),
        capture_output=True,
        env=env,
        cwd=root,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr.decode()[-2000:]
    compiled, ik_compiled, own_compiled, scores = pickle.loads(out.stdout)
    assert compiled and ik_compiled
    assert not own_compiled  # the process really has no compiler
    assert scores.equal(ref)


def test_default_chunks_grow_with_the_sweep():
    """Small sweeps: CHUNK_POSES per chunk; large ones: at most DEFAULT_MAX_CHUNKS chunks, but no
    chunk above CHUNK_MAX_POSES."""
    from problems.placement.sweep import (
        CHUNK_MAX_POSES,
        CHUNK_POSES,
        DEFAULT_MAX_CHUNKS,
        chunk_placements_for,
        default_chunk_poses,
    )

    assert default_chunk_poses(10) == default_chunk_poses(CHUNK_POSES * DEFAULT_MAX_CHUNKS) == CHUNK_POSES
    assert default_chunk_poses(10**8) == 10**5
    assert default_chunk_poses(10**9) == default_chunk_poses(10**12) == CHUNK_MAX_POSES
    kern = kernel_of("placement_milling")
    ppp = kern.poses_per_placement
    assert chunk_placements_for(kern, 1428) == CHUNK_POSES // ppp
    assert chunk_placements_for(kern, 10**8 // ppp) == 10**5 // ppp
    assert chunk_placements_for(kern, 10, target_poses=5 * ppp) == 5


# ======================================================================================
# 8. problem_at
# ======================================================================================


def test_problem_at_maps_the_task_into_the_placed_base_frame():
    base_w = shipped("placement_milling")
    pl = np.array([0.3, -0.4, 0.2, 65 * DEG, 90 * DEG])
    c2b = my_cell2base(pl)
    R, t = c2b[:3, :3], c2b[:3, 3]
    q = problem_at(base_w, pl)
    np.testing.assert_allclose(q.positions, base_w.positions @ R.T + t, atol=TRANSFORM_TOL)
    np.testing.assert_allclose(q.rotations, np.einsum("ij,njk->nik", R, base_w.rotations), atol=TRANSFORM_TOL)
    # a base-frame wrench is fixed in the cell: force and moment turn with cell2base
    np.testing.assert_allclose(q.wrench[:, :3], base_w.wrench[:, :3] @ R.T, atol=1e-12)
    np.testing.assert_allclose(q.wrench[:, 3:], base_w.wrench[:, 3:] @ R.T, atol=1e-12)
    assert q.wrench_frame == "base"
    # the line's ends and the payload's and arm's gravity
    np.testing.assert_allclose(q.line[0], R @ base_w.line[0] + t, atol=TRANSFORM_TOL)
    np.testing.assert_allclose(q.line[1], R @ base_w.line[1] + t, atol=TRANSFORM_TOL)
    g_cell = np.array([0.0, 0.0, -9.80665])
    np.testing.assert_allclose(q.gravity, R @ g_cell, atol=1e-12)
    np.testing.assert_allclose(q.robot.gravity, R @ g_cell, atol=1e-12)
    np.testing.assert_allclose(q.model.nominal.gravity, R @ g_cell, atol=1e-12)
    # wall mount: gravity along the base's -y... R^T: cell -z -> base: Rx(90)^T (0,0,-1) = (0,-1,0)
    np.testing.assert_allclose(q.gravity, np.array([0.0, -9.80665, 0.0]), atol=1e-12)
    # the nominal orientation in the placed frame
    from models.transforms import rpy_to_matrix

    np.testing.assert_allclose(rpy_to_matrix(q.nominal_rpy), R @ rpy_to_matrix(base_w.nominal_rpy), atol=1e-12)
    # the load rows of its task say the same
    L = q.task().load
    np.testing.assert_allclose(L[:, 0:3], base_w.wrench[:, :3] @ R.T, atol=1e-12)
    np.testing.assert_allclose(L[:, 16:19], np.broadcast_to(R @ g_cell, (q.n, 3)), atol=1e-12)
    # with_points of the placed problem re-samples the placed line
    np.testing.assert_allclose(q.with_points(5).positions[[0, -1]], q.positions[[0, -1]], atol=1e-12)


def test_problem_at_keeps_a_tool_frame_wrench_and_the_payload_com():
    p = replace(
        shipped("placement_milling"),
        wrench_frame="tool",
        payload_mass_kg=3.0,
        payload_com_m=np.array([0.01, 0.02, 0.05]),
    )
    pl = np.array([0.3, -0.4, 0.2, 65 * DEG, 45 * DEG])
    q = problem_at(p, pl)
    np.testing.assert_array_equal(q.wrench, p.wrench)
    assert q.wrench_frame == "tool"
    np.testing.assert_array_equal(q.payload_com_m, p.payload_com_m)
    assert q.payload_mass_kg == p.payload_mass_kg
    R = my_cell2base(pl)[:3, :3]
    np.testing.assert_allclose(q.gravity, R @ np.array([0.0, 0.0, -9.80665]), atol=1e-12)


@pytest.mark.parametrize("name", ["placement_milling", "ur10_payload_tilt", "machining_offaxis"])
def test_problem_at_identity_is_the_problem(name):
    p = shipped(name)
    q = problem_at(p, np.zeros(5))
    a, b = p.task(), q.task()
    np.testing.assert_array_equal(b.positions, a.positions)
    np.testing.assert_array_equal(b.rotations, a.rotations)
    np.testing.assert_array_equal(b.load, a.load)
    assert b.rule is a.rule and b.scan == a.scan and b.smoothness == a.smoothness
    assert b.max_joint_step == a.max_joint_step and b.cone_half_angle == a.cone_half_angle
    np.testing.assert_allclose(q.nominal_rpy, p.nominal_rpy, atol=1e-12)
    np.testing.assert_array_equal(q.robot.gravity, p.robot.gravity)
    assert q.robot.tcp2flange.tolist() == p.robot.tcp2flange.tolist()
    # and the kernel scores it as the problem as written, bit for bit
    assert PlacementKernel(q).evaluate(np.zeros((1, 5))).equal(kernel_of(name).evaluate(np.zeros((1, 5))))


@pytest.mark.parametrize("text", ["x_m=-600:1000:17", "z_m=250", "y_m=-0.5:800:3"])
def test_a_grid_in_millimetres_is_refused(text):
    """Issue 24: bases 1000 m away ran with exit 0."""
    with pytest.raises(PlacementGridError, match=r"implausible for a robot base .*metres \(millimetres given\?\)"):
        parse_grid_text(text)
