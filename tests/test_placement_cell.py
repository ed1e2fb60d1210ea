"""The cell in the placement sweep: closed-form capsule distances against coal, the base-footprint
status, and a study whose best placement without the cell stands inside the workpiece's table."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from models.collision import capsule_shape_distance
from models.collision.distance import box_shape, cylinder_shape, sphere_shape
from models.collision.vectorised import capsule_object_distance, vec_object
from models.transforms import rpy_to_matrix
from problems.cell import Cell, CellObject
from problems.placement.grid import PlacementGrid
from problems.placement.kernel import PlacementKernel
from problems.placement.scores import PlacementStatus, ranking
from problems.problem import load_problem

TOL_M = 1e-6


def _random_case(rng: np.random.Generator, kind: str):
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(rng.uniform(-3, 3, 3))
    T[:3, 3] = rng.uniform(-0.2, 0.2, 3)
    if kind == "box":
        size = rng.uniform(0.05, 0.5, 3)
        shape = box_shape("o", size, T)
    elif kind == "sphere":
        size = rng.uniform(0.05, 0.3, 1)
        shape = sphere_shape("o", size[0], T)
    else:
        size = rng.uniform(0.05, 0.3, 2)
        shape = cylinder_shape("o", size[0], size[1], T)
    p0 = rng.uniform(-0.5, 0.5, 3)
    p1 = p0 + rng.uniform(-0.4, 0.4, 3)
    return vec_object("o", kind, size, T), shape, p0, p1, rng.uniform(0.01, 0.1)


@pytest.mark.parametrize("kind", ["box", "sphere"])
def test_exact_shapes_match_coal(kind):
    rng = np.random.default_rng(7)
    got, ref = [], []
    for _ in range(300):
        obj, shape, p0, p1, r = _random_case(rng, kind)
        got.append(capsule_object_distance(np.array([[p0, p1]]), r, obj)[0])
        ref.append(capsule_shape_distance(p0, p1, r, shape).distance)
    got, ref = np.array(got), np.array(ref)
    assert (ref < 0).sum() > 30 and (ref > 0).sum() > 30  # both signs exercised
    np.testing.assert_allclose(got, ref, atol=TOL_M)  # distance and penetration depth


def test_a_segment_through_a_thin_slab_is_measured_as_coal_measures_it():
    """A link crossing a table top: the closed form's squared distance is zero only up to
    rounding (1e-34 m^2 was seen); it must still report the penetration depth, not 0."""
    T = np.eye(4)
    T[:3, 3] = [0.5, 0.0, -0.04]
    size = np.array([2.4, 1.6, 0.04])
    obj, shape = vec_object("table", "box", size, T), box_shape("table", size, T)
    rng = np.random.default_rng(9)
    for _ in range(200):
        top = np.r_[rng.uniform(-0.6, 0.6, 2), rng.uniform(0.05, 0.4)]  # the slab: z -0.06 .. -0.02
        bottom = np.r_[top[:2] + rng.uniform(-0.02, 0.02, 2), -0.06 - rng.uniform(0.05, 0.3)]
        got = capsule_object_distance(np.array([[top, bottom]]), 0.07, obj)[0]
        ref = capsule_shape_distance(top, bottom, 0.07, shape).distance
        assert ref < -0.07
        np.testing.assert_allclose(got, ref, atol=TOL_M)


def test_cylinder_bound_is_conservative():
    rng = np.random.default_rng(8)
    for _ in range(300):
        obj, shape, p0, p1, r = _random_case(rng, "cylinder")
        got = capsule_object_distance(np.array([[p0, p1]]), r, obj)[0]
        ref = capsule_shape_distance(p0, p1, r, shape).distance
        if ref > 0:  # apart: never more clearance than coal
            assert got <= ref + TOL_M
        else:  # penetrating (coal's EPA depth on cylinders is unreliable): the sign
            assert got <= TOL_M


@pytest.fixture(scope="module")
def milling():
    return load_problem("placement_milling")


def test_base_footprint_status(milling):
    table = CellObject("table", "box", np.array([0.4, 0.4, 0.3]), _at([1.0, 0.0, 0.1]))
    k = PlacementKernel(replace(milling, cell=Cell((table,))))
    pl = np.array([[1.0, 0.0, 0, 0, 0], [1.25, 0.0, 0, 0, 0], [0.0, 0.0, 0, 0, 0]])
    sc = k.evaluate(pl)
    assert sc.status_of(0) is PlacementStatus.COLLISION and sc.status_of(1) is PlacementStatus.COLLISION
    assert sc.status_of(2) is not PlacementStatus.COLLISION


def _at(xyz):
    T = np.eye(4)
    T[:3, 3] = xyz
    return T


def test_study_avoids_the_table(milling):
    grid = PlacementGrid(
        {
            "x_m": np.linspace(-0.2, 1.0, 7),
            "y_m": np.linspace(-0.6, 0.6, 7),
            "z_m": np.zeros(1),
            "yaw_deg": np.zeros(1),
            "tilt_deg": np.zeros(1),
        }
    )
    pl = grid.placements()
    plain = PlacementKernel(milling).evaluate(pl)
    best = pl[ranking(plain)[0]]
    # the workpiece's table, built around the no-cell optimum: its top 5 cm above the mounting plane
    lo = np.array([min(best[0], 0.55) - 0.1, min(best[1], -0.35) - 0.1, -0.5])
    hi = np.array([max(best[0], 0.75) + 0.1, max(best[1], 0.35) + 0.1, 0.03])
    table = CellObject("table", "box", hi - lo, _at(0.5 * (lo + hi)))
    part = CellObject("part", "box", np.array([0.12, 0.68, 0.07]), _at([0.65, 0.0, 0.065]), role="workpiece")
    cell = Cell((table, part))
    kernel = PlacementKernel(replace(milling, cell=cell))
    sc = kernel.evaluate(pl)
    i_best = int(ranking(plain)[0])
    assert sc.status_of(i_best) is PlacementStatus.COLLISION
    chosen = int(ranking(sc)[0])
    assert sc.status_of(chosen) is PlacementStatus.OK


@pytest.mark.parametrize("kind", ["box", "sphere", "cylinder"])
def test_the_kernels_shortcut_decides_as_the_exact_distance(kind):
    """KernelCell._object_distance (slab test, probe points, exact distances only where undecided)
    says "closer than the clearance" exactly when the closed-form distance of every pair does;
    capsules drawn around the object's surface so that many lie within a few clearances of it."""
    from problems.placement.collide import KernelCell

    rng = np.random.default_rng(7)
    clearance = 0.005
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(rng.uniform(-np.pi, np.pi, 3))
    T[:3, 3] = rng.uniform(-0.2, 0.2, 3)
    size = {"box": np.array([0.3, 0.2, 0.1]), "sphere": np.array([0.12]), "cylinder": np.array([0.1, 0.3])}[kind]
    obj = vec_object("o", kind, size, T)
    K, m = 400, 3
    centre = T[:3, 3] + rng.normal(0.0, 0.15, (K, m, 1, 3))
    seg = centre + rng.normal(0.0, 0.08, (K, m, 2, 3))
    radius = rng.uniform(0.01, 0.05, m)
    cell = object.__new__(KernelCell)
    cell.clearance = clearance  # the method reads only the clearance of its instance
    fast = KernelCell._object_distance(cell, seg, radius, obj)
    exact = capsule_object_distance(seg.reshape(-1, 2, 3), np.tile(radius, K), obj).reshape(K, m).min(axis=1)
    assert np.array_equal(fast < clearance, exact < clearance)
    near = np.abs(exact - clearance) < 0.02
    assert near.sum() > 10  # the draw puts cases near the threshold, where a shortcut could err


def test_the_maps_outline_each_object_seen_from_above():
    """The placement maps draw each cell object's x-y footprint (cell frame): a box turned 90 deg
    about z swaps its x and y extents; a cylinder lying along x shows its length along x."""
    from planner.report.placement import _object_outlines

    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(np.array([0.0, 0.0, np.pi / 2]))
    T[:3, 3] = [0.5, 0.1, 0.2]
    C = np.eye(4)
    C[:3, :3] = rpy_to_matrix(np.array([0.0, np.pi / 2, 0.0]))  # the cylinder's z axis along base x
    cell = Cell(
        (
            CellObject("plate", "box", np.array([0.4, 0.2, 0.05]), T),
            CellObject("roller", "cylinder", np.array([0.05, 0.6]), C, role="workpiece"),
        ),
        0.005,
    )
    (n1, r1, box), (n2, r2, cyl) = _object_outlines(cell)
    assert (n1, r1, n2, r2) == ("plate", "obstacle", "roller", "workpiece")
    assert np.allclose(box[0], box[-1]) and np.allclose(cyl[0], cyl[-1])  # closed outlines
    assert np.allclose(box.min(axis=0), [0.4, -0.1]) and np.allclose(box.max(axis=0), [0.6, 0.3])
    assert np.allclose(cyl.min(axis=0), [-0.3, -0.05], atol=1e-9) and np.allclose(cyl.max(axis=0), [0.3, 0.05])
