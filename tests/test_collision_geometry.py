"""The arm's collision geometry (models/collision): capsules, distances against coal, pairs."""

from __future__ import annotations

import coal
import numpy as np
import pytest
import trimesh

from models.collision import (
    BUILTIN_ALLOWED_PAIRS,
    BUILTIN_RADII_M,
    ClearanceStatus,
    box_shape,
    capsule_distance,
    capsule_model,
    capsule_segments,
    capsule_shape_distance,
    chain_frames,
    clearance_from_distances,
    cylinder_shape,
    mesh_shape,
    segment_distance,
    self_collision_body_pairs,
    self_collision_pairs,
    self_distances,
    sphere_shape,
)
from models.collision.capsules import BUILTIN_OVERLAPPING_ALLOWED, LINE_RADIUS_M
from models.ik.base import dh_frames
from models.robot import BUILTIN_ROBOTS, load_robot
from models.transforms import rpy_to_matrix, transform

#: Agreement with coal required of every distance, m.
AGREE_M = 1e-6


def _random_pose(rng: np.random.Generator, spread: float = 0.3) -> np.ndarray:
    return transform(rpy_to_matrix(rng.uniform(-np.pi, np.pi, 3)), rng.uniform(-spread, spread, 3))


def _coal_capsule_pair(p0, p1, r0, q0, q1, r1) -> float:
    from models.collision.distance import CellShape, _capsule_frame, shape_pair_distance

    Ta, la = _capsule_frame(p0, p1)
    Tb, lb = _capsule_frame(q0, q1)
    a = CellShape("a", coal.Capsule(r0, la), Ta, "capsule")
    b = CellShape("b", coal.Capsule(r1, lb), Tb, "capsule")
    return shape_pair_distance(a, b).distance


def test_segment_distance_matches_coal_on_random_capsules():
    rng = np.random.default_rng(7)
    n = 300
    P = rng.uniform(-0.4, 0.4, (n, 4, 3))
    # include parallel and crossing cases: some second segments parallel to the first
    par = rng.random(n) < 0.2
    P[par, 3] = P[par, 2] + (P[par, 1] - P[par, 0]) * rng.uniform(0.2, 1.5, (par.sum(), 1))
    r = rng.uniform(0.01, 0.08, (n, 2))
    mine = capsule_distance(P[:, 0:2], r[:, 0], P[:, 2:4], r[:, 1])
    ref = np.array([_coal_capsule_pair(P[i, 0], P[i, 1], r[i, 0], P[i, 2], P[i, 3], r[i, 1]) for i in range(n)])
    sep = ref > 0  # coal's penetration depth of capsules is EPA's, compared on separated pairs
    assert sep.sum() > n // 3 and (~sep).sum() > 10
    np.testing.assert_allclose(mine[sep], ref[sep], atol=AGREE_M)
    np.testing.assert_array_less(mine[~sep], AGREE_M)


def test_segment_distance_closest_points_and_degenerate_segments():
    rng = np.random.default_rng(3)
    p0, p1, q0 = rng.normal(size=(3, 50, 3))
    d, cp, cq = segment_distance(p0, p1, q0, q0)  # second segment a point
    # brute force on the first segment
    s = np.linspace(0, 1, 20001)[:, None, None]
    brute = np.min(np.linalg.norm(p0 + s * (p1 - p0) - q0, axis=-1), axis=0)
    np.testing.assert_allclose(d, brute, atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(cp - cq, axis=-1), d, atol=1e-12)
    d2, _, _ = segment_distance(q0, q0, p0, p0)
    np.testing.assert_allclose(d2, np.linalg.norm(p0 - q0, axis=-1))


def _shapes(rng):
    T = _random_pose(rng, 0.1)
    size = rng.uniform(0.1, 0.4, 3)
    mesh = trimesh.creation.box(extents=size)
    return [
        (box_shape("box", size, T), mesh_shape("mesh", mesh, T)),
        (sphere_shape("sphere", 0.12, T), None),
        (cylinder_shape("cylinder", 0.1, 0.3, T), None),
    ]


@pytest.mark.parametrize("kind", ["box", "sphere", "cylinder"])
def test_capsule_primitive_distance_matches_closed_form_or_mesh(kind):
    """Box vs the same box as a mesh (coal BVH); sphere and cylinder vs closed forms."""
    rng = np.random.default_rng({"box": 1, "sphere": 2, "cylinder": 3}[kind])
    checked = 0
    for _ in range(60):
        shapes = dict((s.kind, (s, m)) for s, m in _shapes(rng))
        obj, mesh = shapes[kind]
        p0, p1 = rng.uniform(-0.6, 0.6, (2, 3))
        r = rng.uniform(0.01, 0.05)
        got = capsule_shape_distance(p0, p1, r, obj)
        inv = np.linalg.inv(obj.shape2base)
        a, b = (inv @ np.append(p0, 1))[:3], (inv @ np.append(p1, 1))[:3]
        if kind == "box":
            if got.distance <= 0:
                continue
            ref = capsule_shape_distance(p0, p1, r, mesh).distance
        elif kind == "sphere":
            ref = segment_distance(a, b, np.zeros(3), np.zeros(3))[0] - 0.12 - r
        else:  # cylinder: dense sampling of the segment, exact point-cylinder distance
            s = np.linspace(0, 1, 200001)[:, None]
            x = a + s * (b - a)
            rad, ax = np.linalg.norm(x[:, :2], axis=1) - 0.1, np.abs(x[:, 2]) - 0.15
            outside = np.hypot(np.maximum(rad, 0), np.maximum(ax, 0)) + np.minimum(np.maximum(rad, ax), 0)
            ref = outside.min() - r
            if ref <= 0:
                continue
            ref_tol = 1e-6  # sampling step 1e-5 of a < 1.2 m segment, curvature term negligible
            assert abs(got.distance - ref) < AGREE_M + ref_tol
            checked += 1
            continue
        assert abs(got.distance - ref) < AGREE_M, (got, ref)
        np.testing.assert_allclose(np.linalg.norm(got.point_a - got.point_b), abs(got.distance), atol=AGREE_M)
        checked += 1
    assert checked >= 20


@pytest.mark.parametrize("kind", ["box", "sphere", "cylinder", "mesh"])
def test_penetration_is_negative(kind):
    T = _random_pose(np.random.default_rng(5), 0.1)
    mesh = trimesh.creation.box(extents=[0.3, 0.2, 0.4])
    obj = {
        "box": box_shape("o", [0.3, 0.2, 0.4], T),
        "sphere": sphere_shape("o", 0.15, T),
        "cylinder": cylinder_shape("o", 0.1, 0.4, T),
        "mesh": mesh_shape("o", mesh, T),
    }[kind]
    c = T[:3, 3]
    got = capsule_shape_distance(c - 0.02 * T[:3, 2], c + 0.02 * T[:3, 2], 0.01, obj)  # wholly inside
    assert got.distance < 0
    edge = T[:3, :3] @ np.array([0.0, 0.0, 0.2 if kind != "sphere" else 0.15]) + c  # top face centre
    cross = capsule_shape_distance(edge - 0.05 * T[:3, 2], edge + 0.1 * T[:3, 2], 0.02, obj)
    # 0.05 m past the face plus the radius; a mesh's depth is per triangle (docs/cell.md): < 0 only
    assert cross.distance < (-0.04 if kind != "mesh" else 0.0)
    assert "o" in got.pair


def test_mesh_file_and_errors(tmp_path):
    from models.errors import InputError

    path = tmp_path / "part.stl"
    trimesh.creation.box(extents=[300.0, 200.0, 400.0]).export(path)  # mm
    obj = mesh_shape("part", path, np.eye(4), scale=0.001)
    ref = box_shape("part", [0.3, 0.2, 0.4], np.eye(4))
    p0, p1 = np.array([0.5, 0.1, 0.0]), np.array([0.5, -0.3, 0.6])
    assert (
        abs(capsule_shape_distance(p0, p1, 0.02, obj).distance - capsule_shape_distance(p0, p1, 0.02, ref).distance)
        < AGREE_M
    )
    with pytest.raises(InputError, match="no such mesh file"):
        mesh_shape("part", tmp_path / "missing.stl", np.eye(4))


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_capsules_follow_forward_kinematics(name):
    """Capsule end points lie on the joint-frame origins of FK, and the capsules form one chain."""
    robot = load_robot(name)
    model = capsule_model(robot)
    rng = np.random.default_rng(11)
    q = rng.uniform(robot.q_min, robot.q_max, (4, 6))
    F = chain_frames(robot, q)
    S = capsule_segments(model, F)
    for i in range(q.shape[0]):
        ref = dh_frames(robot, q[i])
        np.testing.assert_allclose(F[i], ref, atol=1e-12)
        origins = ref[:, :3, 3]
        ends = S[i].reshape(-1, 3)
        for o in origins[1:]:  # every joint-frame origin is a capsule end (within the chain)
            assert np.min(np.linalg.norm(ends - o, axis=1)) < 1e-12
        flange = (ref[6] @ robot.flange2frame6)[:3, 3]
        assert np.min(np.linalg.norm(ends - flange, axis=1)) < 1e-12
    assert np.all(model.radius > 0) and set(model.body) >= {1, 2, 3, 4, 5, 6}
    mat = ~model.is_line  # material capsules: the body's radius; lines (the skeleton): thin
    np.testing.assert_allclose(model.radius[mat], np.array(BUILTIN_RADII_M[name])[model.body[mat]])
    np.testing.assert_allclose(model.radius[~mat], LINE_RADIUS_M)


def test_generic_radii_for_another_arm():
    from dataclasses import replace

    robot = replace(load_robot("ur5"), name="my_arm", collision=None)  # no [collision] table, not built-in
    model = capsule_model(robot)
    assert model.radii_source.startswith("generic")
    reach = np.sum(np.abs(robot.a)) + np.sum(np.abs(robot.d))
    assert np.all(model.radius >= 0.05 * reach - 1e-12) and np.all(model.radius <= 0.10 * reach + 1e-12)
    assert model.allowed_pairs == ()


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_self_collision_pairs_exclude_adjacent_and_allowed(name):
    model = capsule_model(load_robot(name))
    body_pairs = self_collision_body_pairs(model)
    assert body_pairs, "no pair checked"
    for i, j in body_pairs:
        assert j - i > 1
        assert (i, j) not in BUILTIN_ALLOWED_PAIRS[name]
    pairs = self_collision_pairs(model)
    got = {(int(model.body[a]), int(model.body[b])) for a, b in pairs}
    assert got == set(body_pairs)
    # every non-adjacent pair of present bodies is either checked, allowed, or bridged by a sphere
    present = sorted(set(model.body.tolist()))
    for i in present:
        for j in present:
            if j > i + 1 and (i, j) not in body_pairs:
                bridged = j == i + 2 and np.all(
                    np.linalg.norm(
                        np.diff(
                            capsule_segments(model, chain_frames(load_robot(name), np.zeros(6)))[0][
                                model.body == i + 1
                            ],
                            axis=1,
                        ),
                        axis=-1,
                    )
                    == 0
                )
                assert (i, j) in BUILTIN_ALLOWED_PAIRS[name] or bridged


@pytest.mark.parametrize(
    ("name", "pair"),
    [(n, p) for n, ps in BUILTIN_ALLOWED_PAIRS.items() for p in ps if p not in BUILTIN_OVERLAPPING_ALLOWED.get(n, ())],
)
def test_allowed_pairs_never_touch(name, pair):
    """An allowed pair hides no collision: its capsules stay apart at random configurations."""
    robot = load_robot(name)
    model = capsule_model(robot)
    q = np.random.default_rng(13).uniform(robot.q_min, robot.q_max, (3000, 6))
    S = capsule_segments(model, chain_frames(robot, q))
    mat = ~model.is_line  # lines stand for no material: not in self-collision
    ia, ib = np.flatnonzero((model.body == pair[0]) & mat), np.flatnonzero((model.body == pair[1]) & mat)
    d = min(capsule_distance(S[:, a], model.radius[a], S[:, b], model.radius[b]).min() for a in ia for b in ib)
    assert d > 0


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_self_distances_vectorised_equal_loop(name):
    robot = load_robot(name)
    model = capsule_model(robot)
    q = np.random.default_rng(17).uniform(robot.q_min, robot.q_max, (40, 6))
    S = capsule_segments(model, chain_frames(robot, q))
    d, names = self_distances(model, S)
    loop = np.array(
        [
            [
                capsule_distance(S[n, a], model.radius[a], S[n, b], model.radius[b])
                for a, b in self_collision_pairs(model)
            ]
            for n in range(len(q))
        ]
    )
    np.testing.assert_array_equal(d, loop)
    one = np.array(
        [self_distances(model, capsule_segments(model, chain_frames(robot, q[n])))[0][0] for n in range(len(q))]
    )
    np.testing.assert_allclose(d, one, atol=1e-15)
    assert len(names) == d.shape[1] and all(" – " in s for s in names)


def test_clearance_result():
    d = np.array([[0.2, 0.03], [0.004, 0.5]])
    c = clearance_from_distances(d, ["link 1 – link 4", "link 3 – table"], 0.005, "waypoint")
    assert c.status is ClearanceStatus.TOO_CLOSE and c.pair == "link 1 – link 4" and c.index == 1
    assert "waypoint 1" in c.reason and c.distance == 0.004
    c = clearance_from_distances(d - 0.01, ["a – b", "link 3 – table"], 0.005)
    assert c.status is ClearanceStatus.COLLISION and "overlap by 6.0 mm" in c.reason
    assert clearance_from_distances(d + 1, ["a", "b"]).status is ClearanceStatus.OK
    assert clearance_from_distances(np.zeros((3, 0)), []).status is ClearanceStatus.OK
