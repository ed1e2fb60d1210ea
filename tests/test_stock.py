"""The stock z-map, the material a cutter removes and the engagement masks (issue 35).

Volumes are checked against closed forms written here; masks against the feed-frame geometry of
``docs/cutting.md`` (angles clockwise from +y, M4 mirrored).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from models.cutting.cutter import CutterShape, EndMill
from models.errors import InputError
from problems.cutting.engagement_zmap import segment_engagement
from problems.cutting.removal import reach_interval, cut_segment, lowest_by_search, sweep_envelope
from problems.cutting.simulate import simulate
from problems.cutting.stock import StockBox, StockMesh

#: Removed volumes against their closed forms (relative): the brief's bound.
VOLUME_RTOL = 0.01
#: Engaged angles against geometry: a few 1-degree bins (the grid blurs an edge by res/R ~ 0.7 deg).
ANGLE_TOL_RAD = math.radians(3.0)
RES = 1e-4
R = 4e-3


def flat() -> EndMill:
    return EndMill(CutterShape.FLAT, 2 * R, 0.0, 3, math.radians(30), 0.02, 0.04)


def ball() -> EndMill:
    return EndMill(CutterShape.BALL, 2 * R, R, 2, math.radians(30), 0.02, 0.04)


def bull(r: float = 1e-3) -> EndMill:
    return EndMill(CutterShape.BULL_NOSE, 2 * R, r, 4, math.radians(30), 0.02, 0.04)


def box(zmin: float = 0.0, zmax: float = 0.01, ymin: float = -0.02):
    return StockBox((-0.02, ymin, zmin), (0.06, 0.02, zmax)).to_zmap(RES)


def rel(a: float, b: float) -> float:
    return abs(a - b) / b


def test_box_volume_and_mesh_stock_agree(tmp_path):
    sb = StockBox((0.0, 0.0, 0.0), (0.03, 0.02, 0.01))
    zb = sb.to_zmap(RES)
    assert rel(zb.volume_m3(), 0.03 * 0.02 * 0.01) < 1e-9
    mesh = trimesh.creation.box(extents=(30.0, 20.0, 10.0))
    mesh.apply_translation((15.0, 10.0, 5.0))
    path = tmp_path / "stock.stl"
    mesh.export(path)
    zm = StockMesh(path, 1e-3).to_zmap(RES)
    assert rel(zm.volume_m3(), zb.volume_m3()) < 1e-9
    assert np.nanmin(zm.bottom_m) == pytest.approx(0.0, abs=1e-12)
    assert np.nanmax(zm.top_m) == pytest.approx(0.01, abs=1e-12)


def test_mesh_with_two_intervals_in_a_column_is_refused(tmp_path):
    lower = trimesh.creation.box(extents=(10.0, 10.0, 2.0))
    upper = trimesh.creation.box(extents=(10.0, 10.0, 2.0))
    upper.apply_translation((0.0, 0.0, 5.0))  # a gap of 3 mm between: two intervals per column
    path = tmp_path / "two.stl"
    trimesh.util.concatenate([lower, upper]).export(path)
    with pytest.raises(InputError, match=r"two\.stl.*x=.*y=.*crosses its surface 4 times"):
        StockMesh(path, 1e-3).to_zmap(2e-4)


def test_open_mesh_and_huge_grid_are_refused(tmp_path):
    mesh = trimesh.creation.box(extents=(10.0, 10.0, 2.0))
    mesh.update_faces(np.arange(len(mesh.faces) - 1))
    path = tmp_path / "open.stl"
    mesh.export(path)
    with pytest.raises(InputError, match="not closed"):
        StockMesh(path, 1e-3).to_zmap()
    with pytest.raises(InputError, match=r"cells, more than the bound .* use a resolution >="):
        StockBox((0, 0, 0), (2.0, 2.0, 0.1)).to_zmap(1e-4)


@pytest.mark.parametrize("mill_fn", [flat, ball, bull])
def test_straight_slot_volume(mill_fn):
    mill, z, L, h = mill_fn(), box(), 0.03, 2e-3
    cr = mill.corner_radius_m
    res = cut_segment(z, mill, (0.0, 0.0, 0.01 - h), (L, 0.0, 0.01 - h))
    if mill.shape is CutterShape.FLAT:
        expect = h * (2 * R * L + math.pi * R * R)
    elif mill.shape is CutterShape.BALL:  # circular segment x length + one spherical cap (the two ends)
        seg = R * R * math.acos((R - h) / R) - (R - h) * math.sqrt(2 * R * h - h * h)
        expect = seg * L + math.pi * h * h * (3 * R - h) / 3
    else:  # bull-nose, h >= r: profile area x length + the solid of revolution of the profile
        c = R - cr
        area = 2 * (c * h + cr * (h - cr) + math.pi * cr * cr / 4)
        ring = (h - cr) * (cr * cr / 2 + c * cr) + cr**3 / 3 + c * math.pi * cr**2 / 4
        rev = math.pi * c * c * h + 2 * math.pi * ring
        expect = area * L + rev
    err = rel(res.removed_m3, expect)
    assert err < VOLUME_RTOL, (mill.shape, err)
    assert rel(box().volume_m3() - z.volume_m3(), expect) < VOLUME_RTOL
    assert not res.holder_hit


def test_ball_capsule_envelope_matches_the_convex_search():
    """The ball's closed form against the golden-section minimum of z(t) + f(d(t)) (random moves)."""
    mill, rng = ball(), np.random.default_rng(3)
    for _ in range(20):
        p0, p1 = rng.uniform(-5e-3, 5e-3, 3), rng.uniform(-5e-3, 5e-3, 3)
        x, y = rng.uniform(-0.01, 0.01, 500), rng.uniform(-0.01, 0.01, 500)
        low, _ = sweep_envelope(mill, p0, p1, x, y)
        t1, t2, ok = reach_interval(R, p0, p1 - p0, x, y)
        ref = lowest_by_search(mill, p0, p1 - p0, x[ok], y[ok], t1[ok], t2[ok])
        # and a brute-force minimum over 20001 positions, independent of both
        ts = np.linspace(0.0, 1.0, 20001)[:, None]
        d = np.hypot(x[ok] - (p0[0] + ts * (p1 - p0)[0]), y[ok] - (p0[1] + ts * (p1 - p0)[1]))
        f = np.where(d <= R, R - np.sqrt(np.maximum(R * R - d * d, 0)), np.inf)
        brute = np.min(p0[2] + ts * (p1 - p0)[2] + f, 0)
        assert np.max(np.abs(low[ok] - ref)) < 1e-9
        assert np.max(np.abs(low[ok] - brute)) < 2e-6
        assert np.all(np.isnan(low[~ok]))


def test_ramp_volume():
    """A flat mill descending h over L into a box: h (L R + pi R^2) (half a slot and the end's disc)."""
    mill, z, L, h = flat(), box(), 0.03, 3e-3
    res = cut_segment(z, mill, (0.0, 0.0, 0.01), (L, 0.0, 0.01 - h))
    assert rel(res.removed_m3, h * (L * R + math.pi * R * R)) < VOLUME_RTOL


def test_pocket_with_step_overs_volume():
    """Zig-zag at step-over 6 mm then a contour: the rectangle of centres grown by R, times the depth."""
    mill, z, h = flat(), box(), 2e-3
    x0, x1, y0, y1, zc = 0.0, 0.03, -0.012, 0.012, 0.01 - h
    pts = [(x0, y0, 0.02), (x0, y0, zc)]
    for k, y in enumerate(np.arange(y0, y1 + 1e-9, 0.006)):
        a, b = (x0, x1) if k % 2 == 0 else (x1, x0)
        pts += [(a, y, zc), (b, y, zc)]
    pts += [(x0, y1, zc), (x0, y0, zc), (x1, y0, zc), (x1, y1, zc), (x0, y1, zc), (x0, y1, 0.02)]
    P = np.array(pts)
    rapid = np.zeros(len(P), bool)
    rapid[:2] = True
    v0 = z.volume_m3()
    out = simulate(z, mill, P, rapid, np.ones(len(P), bool), on_chunk=None)
    lx, ly = x1 - x0, y1 - y0
    expect = h * (lx * ly + 2 * R * (lx + ly) + math.pi * R * R)
    assert rel(out.removed_m3.sum(), expect) < VOLUME_RTOL
    assert out.removed_m3.sum() == pytest.approx(v0 - out.stock_after.volume_m3(), rel=1e-9)
    assert z.volume_m3() == v0  # the input stock is left as it was


def test_air_cut_removes_nothing_and_is_not_engaged():
    mill, z = ball(), box()
    v0 = z.volume_m3()
    e = segment_engagement(z, mill, (0.0, 0.0, 0.0105), (0.02, 0.005, 0.012), np.linspace(0.1, 1, 5))
    assert not e.batch.mask.any() and list(e.kind) == ["air"] * 5
    assert cut_segment(z, mill, (0.0, 0.0, 0.0105), (0.02, 0.005, 0.012)).removed_m3 == 0.0
    assert z.volume_m3() == v0


@pytest.mark.parametrize(
    ("ymin", "cw", "entry", "exit_", "kind"),
    [
        (0.0, True, 0.0, math.pi / 2, "up"),  # material on +y (left of the feed), M3: up-milling
        (0.0, False, math.pi / 2, math.pi, "down"),  # M4 mirrors: the same cut is climb
        (-0.02, True, 0.0, math.pi, "slot"),
    ],
)
def test_engaged_angles_and_depth(ymin, cw, entry, exit_, kind):
    mill, h, dz = flat(), 1.5e-3, 1e-4
    z = box(ymin=ymin)
    e = segment_engagement(z, mill, (0.0, 0.0, 0.01 - h), (0.01, 0.0, 0.01 - h), np.array([0.5, 1.0]), cw, dz)
    assert np.all(np.abs(e.entry_rad - entry) < ANGLE_TOL_RAD)
    assert np.all(np.abs(e.exit_rad - exit_) < ANGLE_TOL_RAD)
    assert list(e.kind) == [kind, kind]
    assert np.all(np.abs(e.axial_depth_m - h) <= dz)
    width = R * (math.cos(entry) - math.cos(exit_))
    assert np.all(np.abs(e.radial_width_m - width) < R * math.sin(ANGLE_TOL_RAD) + RES)
    phi = e.batch.angles_rad()
    assert not e.batch.mask[:, :, phi > math.pi].any()
    # the mask against the feed-frame geometry: edge point y = +-R cos(phi) in material, below the top
    side = (1 if cw else -1) * R * np.cos(phi)
    inside = (side >= ymin + RES) & (phi < math.pi)
    zk = e.batch.slice_heights_m()
    expect = (zk[:, None] < h - dz) & inside[None, :]
    sure = (zk[:, None] < h - dz) & ((side >= ymin + RES) | (side <= ymin - RES))[None, :] | (zk[:, None] > h + dz)
    assert np.array_equal(e.batch.mask[0][sure], expect[sure])


def test_plunge_is_marked_and_has_no_mask():
    e = segment_engagement(box(), flat(), (0.0, 0.0, 0.012), (0.0, 0.0, 0.008), np.array([0.5, 1.0]))
    assert e.plunge.all() and list(e.kind) == ["plunge", "plunge"] and not e.batch.mask.any()


def _in_swept_brute(mill, p0, p1, q, n=2001):
    """Whether points q (M, 3) are inside the ball mill swept from p0 to p1 (brute force over positions)."""
    ts = np.linspace(0.0, 1.0, n)[:, None]
    tip = p0[None, :] + ts * (p1 - p0)[None, :]  # (n, 3)
    dx = q[None, :, 0] - tip[:, 0, None]
    dy = q[None, :, 1] - tip[:, 1, None]
    dzq = q[None, :, 2] - tip[:, 2, None]
    d = np.hypot(dx, dy)
    sphere = d * d + (dzq - R) ** 2 < (R - 2e-6) ** 2
    body = (d < R - 2e-6) & (dzq > R) & (dzq < mill.length_m)
    return (sphere | body).any(axis=0)


@pytest.mark.parametrize("rise", [3e-3, -3e-3])
def test_ramp_masks_exclude_what_the_move_already_swept(rise):
    """A ball on a ramp: engaged edge points are never inside the solid the move swept before the sample,
    and (a rising move's corner) points the move swept are dropped although the stock still has them."""
    mill, z = ball(), box()
    p0, p1 = np.array([0.0, 0.0, 0.006]), np.array([0.01, 0.0, 0.006 + rise])
    e = segment_engagement(z, mill, p0, p1, np.array([0.5, 1.0]), True)
    s, k, j = np.nonzero(e.batch.mask)
    phi, zk = e.batch.angles_rad()[j], e.batch.slice_heights_m()[k]
    rho = mill.radius_at(zk)
    ps = e.position_m[s]
    q = ps + np.stack([rho * np.sin(phi), rho * np.cos(phi), zk], axis=1)
    assert len(q) > 100
    for i in range(2):
        sel = s == i
        assert not _in_swept_brute(mill, p0, ps[i], q[sel]).any()
    if rise > 0:  # without the check those points would count: the stock alone has more engaged points
        assert np.count_nonzero(e.batch.mask[:, : int(R / 1e-4)]) < np.count_nonzero(
            z.contains(*np.broadcast_arrays(*_all_front_points(mill, ps, e)))
        )


def _all_front_points(mill, ps, e):
    phi, zk = e.batch.angles_rad(), e.batch.slice_heights_m()[: int(R / 1e-4)]
    front = phi <= math.pi
    rho = mill.radius_at(zk)[None, :, None]
    X = ps[:, 0, None, None] + rho * np.sin(phi[front])[None, None, :]
    Y = ps[:, 1, None, None] + rho * np.cos(phi[front])[None, None, :]
    Z = ps[:, 2, None, None] + zk[None, :, None]
    return X, Y, Z


def test_simulate_chunks_and_a_crashing_rapid():
    mill, z = flat(), box()
    P = np.array([[0.0, 0.0, 0.02], [0.0, 0.0, 0.008], [0.02, 0.0, 0.008], [0.02, 0.01, 0.008], [0.04, 0.01, 0.009]])
    rapid = np.array([True, False, False, False, True])  # the last move is a rapid through the stock
    chunks = []
    out = simulate(
        z, mill, P, rapid, np.ones(5, bool), sample_spacing_m=1e-3, on_chunk=chunks.append, chunk_bytes=10**6
    )
    segs = np.concatenate([c.segment for c in chunks])
    assert len(chunks) > 1 and out.n_samples == segs.size == 12 + 20 + 10
    assert np.all(np.diff(segs) >= 0) and set(segs) == {1, 2, 3}
    assert all(c.batch.mask.nbytes <= 10**6 + c.batch.mask[0].nbytes * 20 for c in chunks)
    kinds = np.concatenate([c.kind for c in chunks])
    assert set(kinds[segs == 1]) == {"plunge"} and set(kinds[segs == 2]) == {"slot"}
    assert out.removed_m3[4] > 0.0  # the rapid crashes: the caller sees it by its volume
    assert rel(out.removed_m3[2], 2e-3 * 2 * R * 0.02) < VOLUME_RTOL  # slot after the plunge's hole
