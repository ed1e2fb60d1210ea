"""The cut of a program as its load: the stock cut in program order, the engagement at every sample,
the mechanistic force at every waypoint (``docs/cutting.md``).

Steps (program frame, SI):

1. the stock becomes a z-map (:mod:`problems.cutting.stock`);
2. the waypoints' moves are cut from it in order (:func:`problems.cutting.simulate.simulate`), each
   feed move sampled every :data:`SAMPLE_SPACING_M` and at its end, the engagement of each sample made
   against the stock as it is before the move;
3. each sample's mean wrench over a spindle revolution and its peak force
   (:func:`models.cutting.force.cut_wrench`) with the feed per tooth ``c = F / (N n)`` of the
   programmed feed ``F`` (its horizontal part: the model's chip is the flank's) and the spindle speed
   ``n`` of the program's S; a counter-clockwise spindle's (M4) result is mirrored back;
4. the feed frame turned into the program frame (``x`` the move's horizontal direction, ``z`` the
   program's +Z, the tool axis); the waypoint's wrench is that of the sample at its end, the move
   arriving there.

The wrench is the force the cut puts on the tool, its moment about the tool tip (the TCP).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from models.errors import InputError

from .prediction import MILLING_CODES, CutPrediction, Milling

__all__ = ["MAX_FIGURE_CELLS", "RAPID_CRASH_M3", "SAMPLE_SPACING_M", "predict_cut"]

#: Feed moves are sampled at most this far apart (and at their ends), m.
SAMPLE_SPACING_M = 1e-3
#: A rapid removing more than this from the stock is a crash (1 mm^3), m^3.
RAPID_CRASH_M3 = 1e-9
#: The largest side of the stock images kept for the report (cells).
MAX_FIGURE_CELLS = 400
#: A tool axis further than this from the program's +Z is 5-axis (rad).
THREE_AXIS_TOL_RAD = 1e-6


#: A sample's kind (:mod:`problems.cutting.engagement_zmap`) as a :class:`Milling`.
_KIND = {"air": Milling.AIR, "up": Milling.UP, "down": Milling.DOWN, "slot": Milling.SLOT, "plunge": Milling.PLUNGE}


def _codes(kinds: np.ndarray) -> np.ndarray:
    """The :data:`MILLING_CODES` index of each sample's kind (``"air"``, ``"up"``, ...), shape (S,)."""
    out = np.full(len(kinds), MILLING_CODES.index(Milling.PARTIAL), dtype=int)
    for word, kind in _KIND.items():
        out[np.asarray(kinds) == word] = MILLING_CODES.index(kind)
    return out


#: The per-waypoint fields a sample sets.
_FIELDS = ("wrench", "peak", "depth", "width", "entry", "exit", "kind")


@dataclass
class _Acc:
    """Per-waypoint accumulation of the samples' results."""

    n: int

    def __post_init__(self) -> None:
        n = self.n
        self.wrench = np.zeros((n, 6))
        self.peak = np.zeros(n)
        self.depth = np.zeros(n)
        self.width = np.zeros(n)
        self.entry = np.full(n, np.nan)
        self.exit = np.full(n, np.nan)
        self.kind = np.full(n, MILLING_CODES.index(Milling.AIR), dtype=int)
        self.seg_peak = np.zeros(n)
        self.plunge_cut = np.zeros(n, dtype=bool)
        # the first sample of the move ending at each waypoint (the cut a stop starts)
        self.first_t = np.full(n, np.inf)
        self.first = {k: np.zeros_like(getattr(self, k)) for k in _FIELDS}

    def record(self, into: dict[str, np.ndarray] | None, s: np.ndarray, values: dict[str, np.ndarray]) -> None:
        """Set the fields of waypoints ``s`` (``into``: the first-sample store, None: the waypoint's)."""
        for k, v in values.items():
            (getattr(self, k) if into is None else into[k])[s] = v

    def take(self, e: Any, cw: Any, sense: np.ndarray, P: np.ndarray) -> None:
        """Record a chunk of samples (``e``: :class:`~problems.cutting.engagement_zmap.SampleEngagement`,
        ``cw``: their :class:`~models.cutting.force.CutWrench`): each move's end sample is its waypoint's,
        its first sample kept for :meth:`starts`; the wrench turned from the feed frame into the
        program frame (an M4 spindle's mirrored back)."""
        seg = e.segment
        W = cw.mean.copy()
        ccw = sense[seg] < 0
        W[np.ix_(ccw, [1, 3, 5])] *= -1.0
        x, y = _frames(P, seg)
        z = np.array([0.0, 0.0, 1.0])
        Wp = np.hstack([W[:, i : i + 1] * x + W[:, i + 1 : i + 2] * y + W[:, i + 2 : i + 3] * z for i in (0, 3)])
        np.maximum.at(self.seg_peak, seg, np.nan_to_num(cw.peak_force_N))
        np.logical_or.at(self.plunge_cut, seg, e.plunge)  # its mask is empty: whether it cuts is known after the move
        values = {
            "wrench": Wp,
            "peak": np.nan_to_num(cw.peak_force_N),
            "depth": e.axial_depth_m,
            "width": e.radial_width_m,
            "entry": e.entry_rad,
            "exit": e.exit_rad,
            "kind": _codes(e.kind),
        }
        end = np.flatnonzero(e.t >= 1.0 - 1e-12)
        self.record(None, seg[end], {k: v[end] for k, v in values.items()})
        order = np.lexsort((e.t, seg))
        segs, at = np.unique(seg[order], return_index=True)
        rows = order[at]
        better = e.t[rows] < self.first_t[segs]
        rows, segs = rows[better], segs[better]
        self.first_t[segs] = e.t[rows]
        self.record(self.first, segs, {k: v[rows] for k, v in values.items()})

    def starts(self, rapid: np.ndarray, stop: np.ndarray) -> None:
        """A stop where the cutter starts cutting (the move arriving there in the air or a plunge,
        the move leaving it a feed move that cuts from its first sample) carries the force of the cut
        it starts: it acts from the first tooth pass, and the compensation must be there when the arm
        sets off.  (Entering the stock from the side along a move, the force grows with the samples.)"""
        idle = (self.kind == MILLING_CODES.index(Milling.AIR)) | (self.kind == MILLING_CODES.index(Milling.PLUNGE))
        first_idle = (self.first["kind"] == MILLING_CODES.index(Milling.AIR)) | (
            self.first["kind"] == MILLING_CODES.index(Milling.PLUNGE)
        )
        i = np.flatnonzero(stop[:-1] & idle[:-1] & ~first_idle[1:] & np.isfinite(self.first_t[1:]) & ~rapid[1:])
        for k in _FIELDS:
            getattr(self, k)[i] = self.first[k][i + 1]


def _spindle(setup: Any, way: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per waypoint: spindle speed (rad/s), sense (+1, -1, 0) and the S line (0: none)."""
    n = way.n
    if way.spindle is None or way.move is None:  # CL data: the [cut] table's
        w = setup.spindle_rpm * 2.0 * math.pi / 60.0
        return np.full(n, w), np.full(n, 1 if setup.spindle_cw else -1), np.zeros(n, dtype=int)
    k = np.maximum(way.move, 0)
    return way.spindle.speed_rad_s[k], way.spindle.sense[k], way.spindle.s_line[k]


def _check_speed(way: Any, speed: np.ndarray) -> None:
    """Refuse a program with feed moves and no spindle speed (no S word, or S0) before them."""
    feeding = ~way.rapid
    feeding[0] = False
    if feeding.any() and not np.any(speed[feeding] > 0.0):
        k = int(np.argmax(feeding))
        raise InputError(
            f"{way.source}:{int(way.line[k])}: the program gives no spindle speed (no S word, or S0) before its "
            "first feed move; the cut force needs it (feed per tooth = F / (flutes x S)): add S (rev/min)"
        )


def _check_axes(way: Any) -> None:
    if way.tool_axis is None:
        return
    tilt = np.arccos(np.clip(way.tool_axis[:, 2], -1.0, 1.0))
    bad = np.flatnonzero(tilt > THREE_AXIS_TOL_RAD)
    if bad.size:
        k = int(bad[0])
        raise InputError(
            f"{way.source}:{int(way.line[k])}: the tool axis is tilted {math.degrees(tilt[k]):.3g} deg from the "
            "program's +Z; the cut force is predicted for 3-axis programs only (a z-map holds one height per "
            "column): leave out [material]/[stock] and give the load as [wrench] (docs/cutting.md, 'Limits')"
        )


def _feed_per_tooth(setup: Any, way: Any, speed: np.ndarray) -> np.ndarray:
    """Programmed feed per tooth of the move ending at each waypoint, horizontal part, m (0 on rapids)."""
    P = way.points_m
    d = np.diff(P, axis=0, prepend=P[:1])
    length = np.linalg.norm(d, axis=1)
    horiz = np.where(length > 0.0, np.linalg.norm(d[:, :2], axis=1) / np.where(length > 0.0, length, 1.0), 0.0)
    feed = np.where(way.rapid | ~np.isfinite(way.feed_m_s), 0.0, np.nan_to_num(way.feed_m_s))
    rev_s = speed / (2.0 * math.pi)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(rev_s > 0.0, feed / (setup.mill.flutes * rev_s), 0.0)
    return c * horiz


def _frames(P: np.ndarray, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The feed frame's x and y of each sample's move (program frame, unit, horizontal)."""
    d = P[seg] - P[seg - 1]
    h = d[:, :2]
    norm = np.linalg.norm(h, axis=1, keepdims=True)
    x = np.zeros((len(seg), 3))
    ok = norm[:, 0] > 0.0
    x[ok, :2] = h[ok] / norm[ok]
    y = np.column_stack([-x[:, 1], x[:, 0], np.zeros(len(seg))])  # z x x
    return x, y


#: Slice counts the samples of a chunk are grouped by before their force is computed (a sample is in
#: the first group holding its highest engaged slice): the slices above it are empty, and leaving
#: them out is exact.
DEPTH_GROUPS = (4, 16, 64, 256)


def _wrench_by_depth(mill: Any, coeffs: Any, batch: Any, c: np.ndarray, depth_m: np.ndarray) -> Any:
    """:func:`models.cutting.force.cut_wrench` of a batch, its samples grouped by engaged depth
    ``depth_m`` (the samples' highest engaged slice's top, m) and each group's mask cut to its slices
    (the same result, far less work for shallow cuts; samples in air are not computed: zero)."""
    from models.cutting.engagement import EngagementBatch
    from models.cutting.force import CutWrench, cut_wrench

    m = batch.mask
    S, K, _ = m.shape
    top = np.rint(np.asarray(depth_m) / batch.dz_m).astype(int)
    mean, peak = np.zeros((S, 6)), np.zeros(S)
    lo = 0
    for g in (*DEPTH_GROUPS, K):
        hi = min(g, K)
        rows = np.flatnonzero((top > lo) & (top <= hi)) if lo < K else np.zeros(0, dtype=int)
        if rows.size:
            sub = EngagementBatch(np.ascontiguousarray(m[rows, :hi, :]), batch.dz_m)
            w = cut_wrench(mill, coeffs, sub, c[rows])
            mean[rows], peak[rows] = w.mean, w.peak_force_N
        lo = hi
        if hi >= K:
            break
    return CutWrench(mean, peak)


def _image(z: Any) -> np.ndarray:
    """The stock's top for figures, (ny, nx) at most MAX_FIGURE_CELLS a side (NaN: no material)."""
    top = np.asarray(z.top_m, dtype=float)
    step = max(1, int(math.ceil(max(top.shape) / MAX_FIGURE_CELLS)))
    return top[::step, ::step].T.copy()


def predict_cut(setup: Any, way: Any, program2base: np.ndarray) -> CutPrediction:
    """The predicted cut of a program's waypoints.

    Parameters
    ----------
    setup : problems.problem_file.cut_section.CutSetup
        The cutter, the material, the stock and the [cut] options.
    way : problems.toolpath.waypoints.ProgramWaypoints
        The waypoints, program frame.
    program2base : ndarray, shape (3, 3)
        The program frame's rotation in the base frame.

    Raises
    ------
    InputError
        5-axis CL data; a program with no S (or S0) on a move that cuts; a move that cuts with the
        spindle stopped; a rapid into the stock; a cut deeper than the cutter's length; a program that
        never touches the stock.
    """
    from .simulate import simulate

    _check_axes(way)
    mill, n = setup.mill, way.n
    speed, sense, _s_line = _spindle(setup, way)
    _check_speed(way, speed)
    c = _feed_per_tooth(setup, way, speed)
    zmap = setup.stock.to_zmap() if setup.resolution_m is None else setup.stock.to_zmap(setup.resolution_m)
    before = _image(zmap)
    volume0 = zmap.volume_m3()
    acc = _Acc(n)
    P = way.points_m
    coeffs = setup.coefficients
    dz_kw = {} if setup.slice_height_m is None else {"dz_m": setup.slice_height_m}

    def on_chunk(e: Any) -> None:
        acc.take(e, _wrench_by_depth(mill, coeffs, e.batch, c[e.segment], e.axial_depth_m), sense, P)

    sim = simulate(
        zmap,
        mill,
        P,
        way.rapid.copy(),
        sense >= 0,
        sample_spacing_m=SAMPLE_SPACING_M,
        on_chunk=on_chunk,
        in_place=True,
        **dz_kw,
    )
    acc.plunge_cut &= np.asarray(sim.removed_m3) > 0.0  # a plunge that removes material
    acc.kind[(acc.kind == MILLING_CODES.index(Milling.PLUNGE)) & ~acc.plunge_cut] = MILLING_CODES.index(Milling.AIR)
    acc.starts(np.asarray(way.rapid, dtype=bool), np.asarray(way.stop, dtype=bool))
    _refuse(setup, way, sim, sense, speed, volume0)
    warnings = _warnings(way, acc, np.asarray(sim.removed_m3))
    x0, y0, r = zmap.x0_m, zmap.y0_m, zmap.resolution_m
    nx, ny = zmap.shape
    return CutPrediction(
        wrench_program=acc.wrench,
        program2base=np.asarray(program2base, dtype=float),
        peak_force_N=acc.peak,
        axial_depth_m=acc.depth,
        radial_width_m=acc.width,
        entry_rad=acc.entry,
        exit_rad=acc.exit,
        milling=acc.kind,
        feed_per_tooth_m=c,
        spindle_rad_s=speed * np.abs(sense),
        removed_m3=float(np.sum(sim.removed_m3)),
        stock_volume_m3=float(volume0),
        heights_before=before,
        heights_after=_image(sim.stock_after),
        grid_extent_m=(x0, x0 + nx * r, y0, y0 + ny * r),
        warnings=tuple(warnings),
        material=coeffs,
        mill=mill,
        stand_in=setup.stand_in,
        stand_in_frame=setup.stand_in_frame,
        extra={"segment_peak_force_N": acc.seg_peak, "samples": sim.n_samples, "resolution_m": r},
    )


def _refuse(setup: Any, way: Any, sim: Any, sense: np.ndarray, speed: np.ndarray, volume0: float) -> None:
    """The errors only the cut itself reveals (see :func:`predict_cut`)."""
    removed = np.asarray(sim.removed_m3)
    src = way.source
    crash = np.flatnonzero(way.rapid & (removed > RAPID_CRASH_M3))
    if crash.size:
        k = int(crash[0])
        raise InputError(
            f"{src}:{int(way.line[k])}: a rapid (G0) move cuts {removed[k] * 1e9:.3g} mm^3 of the stock: a crash "
            f"({len({int(way.line[i]) for i in crash})} rapid line(s) do); check the program or the [stock] "
            "(box/mesh, program frame)"
        )
    deep = np.flatnonzero(np.asarray(sim.holder_hit))
    if deep.size:
        k = int(deep[0])
        raise InputError(
            f"{src}:{int(way.line[k])}: the cut is deeper than the cutter's length "
            f"({setup.mill.length_m * 1e3:g} mm stick-out): the holder would hit the stock"
        )
    cuts = (removed > 0.0) & ~way.rapid
    idle = np.flatnonzero(cuts & ((sense == 0) | (speed <= 0.0)))
    if idle.size:
        k = int(idle[0])
        raise InputError(
            f"{src}:{int(way.line[k])}: this move cuts the stock with the spindle stopped (no M3/M4 in force, "
            "or M5, or S0); add M3 or M4 and S before it"
        )
    if not np.any(removed > 0.0):
        lo, hi = np.min(way.points_m, axis=0) * 1e3, np.max(way.points_m, axis=0) * 1e3
        raise InputError(
            f"{src}: the program never touches the [stock] ({volume0 * 1e9:.4g} mm^3; its tool tip stays within "
            f"x {lo[0]:.4g}..{hi[0]:.4g}, y {lo[1]:.4g}..{hi[1]:.4g}, z {lo[2]:.4g}..{hi[2]:.4g} mm, program frame): "
            "the stock must be given in the program frame (m), where the program cuts"
        )


#: A feed move whose horizontal travel is below this share of its length is a plunge.
PLUNGE_SHARE = 1e-9


def _warnings(way: Any, acc: _Acc, removed: np.ndarray) -> list[str]:
    out = []
    P = way.points_m
    d = np.diff(P, axis=0, prepend=P[:1])
    vertical = np.linalg.norm(d[:, :2], axis=1) <= PLUNGE_SHARE * np.maximum(np.linalg.norm(d, axis=1), 1e-300)
    plunges = np.flatnonzero(acc.plunge_cut | (vertical & ~way.rapid & (removed > 0.0)))
    if plunges.size:
        lines = sorted({int(way.line[k]) for k in plunges})
        shown = ", ".join(str(v) for v in lines[:8]) + (", ..." if len(lines) > 8 else "")
        out.append(
            f"{len(lines)} program line(s) plunge straight down into the stock (lines {shown}): the peripheral force "
            "model gives no force for the end cutting edges there (docs/cutting.md, 'Limits'); their wrench is 0"
        )
    return out
