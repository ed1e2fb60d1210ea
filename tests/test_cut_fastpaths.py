"""The cut's fast paths against plain implementations written here (issue 35, speed).

The engagement masks (one column lookup per angle on the flank, compact masks written into a chunk),
the removal (only the columns above the lowest tip examined) and the force grouped by the engaged
depth must give what the straightforward computations give: the masks and the stock exactly, the
wrench to rounding.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from models.cutting.cutter import CutterShape, EndMill
from models.cutting.engagement import EngagementBatch
from models.cutting.force import cut_wrench
from models.cutting.material import material
from models.errors import InputError
from problems.cutting.engagement_zmap import concatenate_engagements, n_slices, segment_engagement
from problems.cutting.program_cut import predict_cut
from problems.cutting.removal import cut_segment, sweep_envelope
from problems.cutting.simulate import simulate
from problems.cutting.stock import StockBox, ZMap

RES = 2e-4
R = 3e-3
#: Wrench by depth groups against one cut_wrench call: rounding of the matrix products (relative).
WRENCH_RTOL = 1e-9
#: Peak force: single precision (relative).
PEAK_RTOL = 1e-5


def mills() -> list[EndMill]:
    return [
        EndMill(CutterShape.FLAT, 2 * R, 0.0, 3, math.radians(30), 0.008, 0.02),
        EndMill(CutterShape.BALL, 2 * R, R, 2, math.radians(30), 0.008, 0.02),
        EndMill(CutterShape.BULL_NOSE, 2 * R, 1e-3, 4, math.radians(30), 0.008, 0.02),
    ]


def stepped_stock(seed: int = 0) -> ZMap:
    """A block with a random terraced top (steps of 0.5 mm) and some empty columns."""
    rng = np.random.default_rng(seed)
    z = StockBox((-0.01, -0.01, 0.0), (0.03, 0.01, 0.01)).to_zmap(RES)
    nx, ny = z.shape
    coarse = rng.integers(0, 8, size=(nx // 10 + 1, ny // 10 + 1)) * 5e-4
    top = np.minimum(z.top_m, 0.006 + np.kron(coarse, np.ones((10, 10)))[:nx, :ny])
    bottom = z.bottom_m.copy()
    hole = np.zeros((nx, ny), bool)
    hole[nx // 2 : nx // 2 + 5, :] = True
    return ZMap(z.x0_m, z.y0_m, z.resolution_m, np.where(hole, np.nan, bottom), np.where(hole, np.nan, top))


def brute_mask(z: ZMap, mill: EndMill, ps: np.ndarray, xh: np.ndarray, yh: np.ndarray, K: int, J: int) -> np.ndarray:
    """The mask by a loop over every edge point and the nearest-cell rule (no rising-move correction)."""
    out = np.zeros((ps.shape[0], K, J), dtype=bool)
    w = 2.0 * math.pi / J
    nx, ny = z.shape
    for s, p in enumerate(ps):
        for k in range(K):
            zk = (k + 0.5) * 1e-4
            rho = float(mill.radius_at(zk))
            for j in range(J):
                phi = (j + 0.5) * w
                if phi > math.pi:
                    continue
                e = math.sin(phi) * xh + math.cos(phi) * yh
                q = p + rho * e + np.array([0.0, 0.0, zk])
                i, jj = math.floor((q[0] - z.x0_m) / RES), math.floor((q[1] - z.y0_m) / RES)
                if 0 <= i < nx and 0 <= jj < ny:
                    out[s, k, j] = bool(z.bottom_m[i, jj] <= q[2] <= z.top_m[i, jj])
            # a run of engaged bins with no point that is still in material one z-map cell nearer the
            # axis is a sliver below the z-map's resolution, and dropped (SLIVER_CELLS = 1)
            half = [j for j in range(J) if (j + 0.5) * w <= math.pi]
            runs, cur = [], []
            for j in half:
                if out[s, k, j]:
                    cur.append(j)
                elif cur:
                    runs.append(cur)
                    cur = []
            if cur:
                runs.append(cur)
            for run in runs:
                deep = False
                for j in run:
                    phi = (j + 0.5) * w
                    e = math.sin(phi) * xh + math.cos(phi) * yh
                    q = p + max(rho - RES, 0.0) * e + np.array([0.0, 0.0, zk])
                    i, jj = math.floor((q[0] - z.x0_m) / RES), math.floor((q[1] - z.y0_m) / RES)
                    deep |= 0 <= i < nx and 0 <= jj < ny and bool(z.bottom_m[i, jj] <= q[2] <= z.top_m[i, jj])
                if not deep:
                    out[s, k, run] = False
    return out


@pytest.mark.parametrize("mill", mills(), ids=lambda m: m.shape.value)
@pytest.mark.parametrize(("cw", "terraced"), [(True, True), (False, True), (True, False)])
def test_masks_match_a_point_by_point_lookup(mill, cw, terraced):
    """Terraced: steps, a gap and walls; plain: a block whose top the highest slices reach."""
    z = stepped_stock() if terraced else StockBox((-0.01, -0.01, 0.0), (0.03, 0.01, 0.00618)).to_zmap(RES)
    p0, p1 = np.array([-0.002, -0.001, 0.005]), np.array([0.004, 0.0025, 0.0045])  # descending: no correction
    t = np.array([0.3, 1.0])
    J = 36
    e = segment_engagement(z, mill, p0, p1, t, cw, n_angles=J)
    K = n_slices(mill, 1e-4)
    v = p1 - p0
    xh = np.array([v[0], v[1], 0.0]) / math.hypot(v[0], v[1])
    yh = np.array([-xh[1], xh[0], 0.0]) * (1.0 if cw else -1.0)
    expect = brute_mask(z, mill, p0 + t[:, None] * v, xh, yh, K, J)
    assert expect.any() and not expect.all()
    np.testing.assert_array_equal(e.batch.mask, expect)
    top = np.where(expect.any(axis=2), np.arange(1, K + 1), 0).max(axis=1)
    np.testing.assert_allclose(e.axial_depth_m, top * 1e-4, rtol=0, atol=1e-15)


def test_column_interval_and_contains_against_a_loop():
    z = stepped_stock(1)
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.012, 0.032, 500)
    y = rng.uniform(-0.012, 0.012, 500)
    zz = rng.uniform(-0.001, 0.011, 500)
    bot, top = z.column_interval(x, y)
    inside = z.contains(x, y, zz)
    nx, ny = z.shape
    for a, b, c, lo, hi, got in zip(x, y, zz, bot, top, inside, strict=True):
        i, j = math.floor((a - z.x0_m) / RES), math.floor((b - z.y0_m) / RES)
        on = 0 <= i < nx and 0 <= j < ny
        want = (z.bottom_m[i, j], z.top_m[i, j]) if on else (np.nan, np.nan)
        np.testing.assert_array_equal([lo, hi], want)
        assert got == (on and bool(want[0] <= c <= want[1]))


def test_out_buffer_and_joined_chunk_equal_fresh_masks():
    z, mill = stepped_stock(), mills()[0]
    moves = [((0.0, 0.0, 0.005), (0.003, 0.001, 0.005)), ((0.003, 0.001, 0.005), (0.003, 0.004, 0.0048))]
    K, J = n_slices(mill, 1e-4), 360
    buf = np.zeros((5, K, J), dtype=bool)
    parts, fresh, used = [], [], 0
    for (p0, p1), t in zip(moves, (np.array([0.5, 1.0]), np.array([0.2, 0.6, 1.0])), strict=True):
        fresh.append(segment_engagement(z, mill, p0, p1, t))
        parts.append(segment_engagement(z, mill, p0, p1, t, out=buf[used : used + t.size]))
        used += t.size
    joined = concatenate_engagements(parts, buf)
    np.testing.assert_array_equal(joined.batch.mask, concatenate_engagements(fresh).batch.mask)
    assert joined.batch.mask is buf and joined.batch.mask.any()
    np.testing.assert_array_equal(joined.axial_depth_m, np.concatenate([f.axial_depth_m for f in fresh]))
    with pytest.raises(InputError, match="joined mask"):
        concatenate_engagements(parts, buf[:4])
    with pytest.raises(InputError, match="output mask"):
        segment_engagement(z, mill, *moves[0], np.array([1.0]), out=np.zeros((1, K, J - 1), dtype=bool))


def plain_cut(z: ZMap, mill: EndMill, p0, p1) -> float:
    """The removal over every column of the bounding box (no candidate filter)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    i0 = max(math.floor((min(p0[0], p1[0]) - R - z.x0_m) / RES), 0)
    i1 = min(math.ceil((max(p0[0], p1[0]) + R - z.x0_m) / RES), z.shape[0])
    j0 = max(math.floor((min(p0[1], p1[1]) - R - z.y0_m) / RES), 0)
    j1 = min(math.ceil((max(p0[1], p1[1]) + R - z.y0_m) / RES), z.shape[1])
    x = z.x0_m + (np.arange(i0, i1) + 0.5) * RES
    y = z.y0_m + (np.arange(j0, j1) + 0.5) * RES
    low, high = sweep_envelope(mill, p0, p1, x[:, None], y[None, :])
    top, bot = z.top_m[i0:i1, j0:j1], z.bottom_m[i0:i1, j0:j1]
    hit = (low < top) & (high > bot)
    new_top = np.where(hit & (low > bot), np.minimum(top, low), top)
    new_bot = np.where(hit & (low <= bot) & (high < top), high, bot)
    gone = hit & (low <= bot) & (high >= top)
    new_top[gone], new_bot[gone] = np.nan, np.nan
    removed = float(np.nansum(top - bot) - np.nansum(new_top - new_bot)) * RES * RES
    z.top_m[i0:i1, j0:j1], z.bottom_m[i0:i1, j0:j1] = new_top, new_bot
    return removed


@pytest.mark.parametrize("mill", mills(), ids=lambda m: m.shape.value)
def test_removal_with_the_candidate_filter_equals_the_plain_one(mill):
    """Same stock, bit for bit, over passes that re-cut their own floor (horizontal, ramps, a plunge)."""
    fast, plain = stepped_stock(2), stepped_stock(2)
    pts = [(-0.004, -0.004, 0.007), (-0.004, -0.004, 0.0052)]
    for row in range(4):
        y = -0.004 + row * 0.002
        pts += [(0.012 if row % 2 == 0 else -0.004, y, 0.0052), (0.012 if row % 2 == 0 else -0.004, y + 0.002, 0.005)]
    pts += [(0.0, 0.0, 0.0055), (0.006, 0.001, 0.0055), (0.006, 0.001, 0.0055), (0.0, 0.0, 0.0052)]
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        got = cut_segment(fast, mill, a, b).removed_m3
        want = plain_cut(plain, mill, a, b)
        assert got == pytest.approx(want, rel=1e-12, abs=1e-24)
    np.testing.assert_array_equal(fast.top_m, plain.top_m)
    np.testing.assert_array_equal(fast.bottom_m, plain.bottom_m)
    assert np.nansum(fast.top_m) < np.nansum(stepped_stock(2).top_m)  # it did cut


def test_predicted_wrench_equals_cut_wrench_of_every_sample():
    """predict_cut (masks written into chunks, force grouped by depth) against simulate + one
    cut_wrench call over all samples, the feed frame turned into the program frame here."""
    mill = EndMill(CutterShape.FLAT, 2 * R, 0.0, 3, math.radians(30), 0.008, 0.02)
    stock = StockBox((-0.01, -0.01, 0.0), (0.03, 0.01, 0.01))
    P = np.array(
        [
            [0.0, -0.002, 0.02],
            [0.0, -0.002, 0.011],  # rapids to above the block
            [0.0, -0.002, 0.009],  # plunge
            [0.01, -0.002, 0.009],
            [0.01, 0.001, 0.0085],  # ramp
            [0.0, 0.001, 0.0085],
            [0.0, 0.001, 0.005],
            [0.012, 0.001, 0.005],  # 5 mm deep
        ]
    )
    n = len(P)
    rapid = np.zeros(n, bool)
    rapid[:2] = True
    feed = np.full(n, 0.02)
    way = SimpleNamespace(
        n=n, points_m=P, rapid=rapid, feed_m_s=feed, spindle=None, move=None, tool_axis=None, source="t",
        line=np.arange(n), stop=np.zeros(n, bool),  # no stop: every waypoint has its arriving move's end sample
    )  # fmt: skip
    coeffs = material("al7075_t6")
    setup = SimpleNamespace(
        mill=mill, coefficients=coeffs, stock=stock, resolution_m=RES, spindle_rpm=10000.0, spindle_cw=True,
        slice_height_m=None, stand_in=None, stand_in_frame="tool",
    )  # fmt: skip
    cut = predict_cut(setup, way, np.eye(3))
    chunks = []
    simulate(stock.to_zmap(RES), mill, P, rapid, np.ones(n, bool), sample_spacing_m=1e-3, on_chunk=chunks.append)
    seg = np.concatenate([c.segment for c in chunks])
    t = np.concatenate([c.t for c in chunks])
    mask = np.concatenate([c.batch.mask for c in chunks])
    d = np.diff(P, axis=0)
    c = 0.02 / (3 * 10000.0 / 60.0) * np.linalg.norm(d[:, :2], axis=1) / np.linalg.norm(d, axis=1)
    w = cut_wrench(mill, coeffs, EngagementBatch(mask, 1e-4), c[seg - 1])
    end = t >= 1.0
    for s, fw, pk in zip(seg[end], w.mean[end], w.peak_force_N[end], strict=True):
        x = np.array([d[s - 1, 0], d[s - 1, 1], 0.0])
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 0 else x
        y = np.array([-x[1], x[0], 0.0])
        Rm = np.column_stack([x, y, [0.0, 0.0, 1.0]])
        want = np.concatenate([Rm @ fw[:3], Rm @ fw[3:]])
        np.testing.assert_allclose(cut.wrench_program[s], want, rtol=WRENCH_RTOL, atol=1e-12 * np.abs(want).max())
        assert cut.peak_force_N[s] == pytest.approx(pk, rel=PEAK_RTOL)
    assert np.abs(cut.wrench_program[-1, :3]).max() > 1.0  # the deep cut has a load
    seg_peak = np.zeros(n)
    np.maximum.at(seg_peak, seg, w.peak_force_N)
    np.testing.assert_allclose(cut.extra["segment_peak_force_N"], seg_peak, rtol=PEAK_RTOL)
