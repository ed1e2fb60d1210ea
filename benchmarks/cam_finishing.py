"""CAM-style test programs for the feed law: written the way a CAM system posts them.

``finishing_program``: ball-nose parallel (raster) finishing of a freeform surface, the program
shops run most. The tool-tip (CL) points come from drop-cutter -- the ball of radius R lowered
onto the surface at every point of a fine grid along each drive line, as CAM computes them -- then
reduced to G1 chords within the chordal tolerance (0.01 mm by default: each chord keeps every
dropped point within the tolerance, so the segments are uneven: long where the surface is flat,
short where it curves), printed to 0.001 mm. Rows are cut zig-zag along X at the finishing feed;
the step-over between rows runs at a lower feed, the approach plunges at a third; ``G64 P``
gives the blending tolerance. Deterministic: no randomness.

``inch_arc_program``: an inch (G20) program of R-word arcs in G17 (a rounded-rectangle contour
and a row of S-bends) under ``G64 P``, at two feeds.

``helix_program``: helical arcs (I/J/K) in G17, G18 and G19, the helix axis along each plane's normal.

Used by ``tests/test_feed_finishing.py`` and ``benchmarks/bench_toolpath.py``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["finishing_program", "helix_program", "inch_arc_program", "surface_mm"]


#: X (mm) of the cliff: a 4 mm step, a wall of up to 40 degrees whose fillets (radius >= 3.7 mm)
#: the R3 ball follows, sampled 4x finer within 4 mm of it.
CLIFF_X_MM = 18.0
#: Length (mm, in X) of the surface patches whose boundaries CAM keeps as points, and the sampling
#: near them (mm).
PATCH_MM = 7.3
PATCH_SAMPLE_MM = 0.01


def surface_mm(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The freeform surface, height (mm) over the program's X, Y (mm): two waves and a bump."""
    return (
        3.0 * np.sin(2.0 * np.pi * x / 55.0) * np.cos(2.0 * np.pi * y / 47.0)
        + 2.5 * np.exp(-((x - 12.0) ** 2 + (y + 6.0) ** 2) / 180.0)
        + 0.02 * x
        + 4.0 / (1.0 + np.exp(-(x - CLIFF_X_MM) / 1.2))
    )


def _drop_cutter(x: np.ndarray, y: float, radius_mm: float) -> np.ndarray:
    """Tool-tip heights (mm) of a ball-nose of radius ``radius_mm`` dropped onto the surface at
    ``(x, y)``: the highest contact of the ball's lower face, found on a polar grid of its footprint
    and refined on finer and finer patches around the best point (to about 0.1 µm)."""

    def tip(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
        r2 = dx**2 + dy**2
        lift = np.sqrt(np.maximum(radius_mm**2 - r2, 0.0)) - radius_mm  # the ball's lower face above its tip
        z = surface_mm(x[:, None] + dx, y + dy) - lift
        return np.where(r2 <= radius_mm**2, z, -np.inf)  # outside the footprint: no contact

    r = np.linspace(0.0, radius_mm, 9)[1:]
    a = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    dx = np.r_[0.0, (r[:, None] * np.cos(a)).ravel()][None, :]
    dy = np.r_[0.0, (r[:, None] * np.sin(a)).ravel()][None, :]
    z = tip(dx, dy)
    k = np.argmax(z, axis=1)
    bx, by, best = dx[0, k], dy[0, k], z[np.arange(len(x)), k]
    step = radius_mm / 8.0
    g = np.linspace(-1.0, 1.0, 5)
    gx, gy = (v.ravel()[None, :] for v in np.meshgrid(g, g))
    for _ in range(6):
        cx = bx[:, None] + step * gx
        cy = by[:, None] + step * gy
        z = tip(cx, cy)
        k = np.argmax(z, axis=1)
        rows = np.arange(len(x))
        better = z[rows, k] > best
        bx = np.where(better, cx[rows, k], bx)
        by = np.where(better, cy[rows, k], by)
        best = np.maximum(best, z[rows, k])
        step /= 2.0
    return best


def _chords(p: np.ndarray, tol_mm: float, max_mm: float, forced: np.ndarray) -> list[int]:
    """Indices of the points kept: each chord stays within ``tol_mm`` of every point it skips and
    is at most ``max_mm`` long (greedy, as CAM's chordal reduction: the farthest point reachable
    from the last kept one, found by doubling then bisection); the points ``forced`` (a bool mask:
    the surface patches' boundaries) are always kept."""

    def ok(i: int, j: int) -> bool:
        c = p[j] - p[i]
        L = float(np.linalg.norm(c))
        if L > max_mm or forced[i + 1 : j].any():
            return False
        mid = p[i + 1 : j] - p[i]
        return not mid.size or float(np.linalg.norm(mid - np.outer(mid @ c / L**2, c), axis=1).max()) <= tol_mm

    keep = [0]
    i, n = 0, len(p)
    while i < n - 1:
        good, step = i + 1, 1
        while good + step < n and ok(i, good + step):  # doubling
            good += step
            step *= 2
        bad = min(good + step, n)
        while bad - good > 1:  # bisection between the last good and the first bad end
            mid = (good + bad) // 2
            if ok(i, mid):
                good = mid
            else:
                bad = mid
        keep.append(good)
        i = good
    return keep


def finishing_program(
    n_rows: int = 12,
    width_mm: float = 60.0,
    depth_mm: float = 40.0,
    ball_radius_mm: float = 3.0,
    chordal_tol_mm: float = 0.01,
    g64_p_mm: float = 0.02,
    feed: int = 1200,
    stepover_feed: int = 600,
    plunge_feed: int = 300,
    sample_mm: float = 0.05,
    max_chord_mm: float = 5.0,
) -> str:
    """A ball-nose parallel finishing program (G21), text.

    ``n_rows`` rows along X (``width_mm`` long), spread over ``depth_mm`` in Y, centred on the
    program zero; the surface is :func:`surface_mm` and the Z of the program zero its mean level.
    """
    y_rows = np.linspace(-depth_mm / 2, depth_mm / 2, n_rows) if n_rows > 1 else np.zeros(1)
    xs = np.arange(-width_mm / 2, width_mm / 2 + 1e-9, sample_mm)
    near = np.arange(CLIFF_X_MM - 4.0, CLIFF_X_MM + 4.0, sample_mm / 4.0)
    # the surface's patch boundaries (every PATCH_MM in X), kept as CAM keeps them, sampled finely
    # on either side: the chord before a boundary can be as short as 10 µm
    edges = np.arange(-width_mm / 2 + PATCH_MM, width_mm / 2, PATCH_MM)
    fine = (edges[:, None] + np.arange(-20, 21)[None, :] * PATCH_SAMPLE_MM).ravel()
    xs = np.unique(np.round(np.r_[xs, near, fine], 6))
    xs = xs[(xs >= -width_mm / 2) & (xs <= width_mm / 2)]
    forced = np.isin(np.round(xs, 6), np.round(edges, 6))
    lines = [
        "%",
        f"(3D FINISHING - BALL NOSE R{ball_radius_mm:.1f} - PARALLEL X - CHORDAL TOL {chordal_tol_mm:.3f})",
        "G21 G90 G94 G17 G40 G49",
        "G54",
        f"G64 P{g64_p_mm:.3f}",
        "T1 M6",
        "S12000 M3",
    ]
    first = True
    for i, y in enumerate(y_rows):
        x = xs if i % 2 == 0 else xs[::-1]
        z = _drop_cutter(x, float(y), ball_radius_mm)
        pts = np.c_[x, np.full_like(x, y), z]
        keep = _chords(pts, chordal_tol_mm, max_chord_mm, forced if i % 2 == 0 else forced[::-1])
        if first:
            lines += [f"G0 Z{z[0] + 10:.3f}", f"X{x[0]:.3f} Y{y:.3f}", f"G1 Z{z[0]:.3f} F{plunge_feed}"]
            first = False
        else:
            lines.append(f"X{x[0]:.3f} Y{y:.3f} Z{z[0]:.3f} F{stepover_feed}")
        fed = False
        for k in keep[1:]:
            word = f"X{pts[k, 0]:.3f} Z{pts[k, 2]:.3f}"
            if not fed:
                word += f" F{feed}"
                fed = True
            lines.append(word)
    lines += [f"G0 Z{float(_drop_cutter(xs[-1:], float(y_rows[-1]), ball_radius_mm)[0]) + 10:.3f}", "M5", "M30", "%"]
    return "\n".join(lines) + "\n"


def inch_arc_program(g64_p_in: float = 0.004, feed: float = 40.0, slow_feed: float = 15.0) -> str:
    """An inch (G20) contour of R arcs in G17 under ``G64 P`` (inches), text."""
    r = 0.35
    w, h = 2.4, 1.6
    x0, y0 = -w / 2, -h / 2
    lines = ["%", "(INCH CONTOUR, R ARCS)", "G20 G90 G94 G17 G40", f"G64 P{g64_p_in:.4f}", "G0 Z0.2"]
    lines += [f"X{x0 + r:.4f} Y{y0:.4f}", f"G1 Z-0.05 F{slow_feed:g}", f"F{feed:g}"]
    lines += [
        f"G1 X{x0 + w - r:.4f} Y{y0:.4f}",
        f"G3 X{x0 + w:.4f} Y{y0 + r:.4f} R{r:.4f}",
        f"G1 Y{y0 + h - r:.4f}",
        f"G3 X{x0 + w - r:.4f} Y{y0 + h:.4f} R{r:.4f}",
        f"G1 X{x0 + r:.4f}",
        f"G3 X{x0:.4f} Y{y0 + h - r:.4f} R{r:.4f}",
        f"G1 Y{y0 + r:.4f}",
        f"G3 X{x0 + r:.4f} Y{y0:.4f} R{r:.4f}",
    ]
    # S-bends: tangent half circles of alternating sense, then a slower pass back
    x = x0 + r
    lines.append(f"G1 Y{y0 + 0.3:.4f}")
    for k in range(5):
        code = "G2" if k % 2 == 0 else "G3"
        x += 0.4
        lines.append(f"{code} X{x:.4f} Y{y0 + 0.3:.4f} R0.2000")
    lines.append(f"G1 X{x:.4f} Y{y0 + 0.6:.4f} F{slow_feed:g}")
    for k in range(5):
        code = "G2" if k % 2 == 0 else "G3"
        x -= 0.4
        lines.append(f"{code} X{x:.4f} Y{y0 + 0.6:.4f} R0.2000")
    lines += ["G0 Z0.2", "M30", "%"]
    return "\n".join(lines) + "\n"


def helix_program(radius_mm: float = 8.0, pitch_mm: float = 1.5, feed: int = 900) -> str:
    """Helical arcs in the three planes (G17: Z, G18: Y, G19: X travel), G21, text."""
    r, p = radius_mm, pitch_mm
    lines = ["%", "(HELICES IN G17 G18 G19)", "G21 G90 G94 G40", "G64 P0.010", "G0 X0 Y0 Z5"]
    lines += [f"G1 X{r:.3f} Y0 Z0 F{feed}"]
    lines += ["G17", f"G2 X{r:.3f} Y0 Z{-p:.3f} I{-r:.3f} J0 P2"]
    lines += [f"G1 X{r:.3f} Y0 Z{-p:.3f}", "G18", f"G3 X{r:.3f} Y{p:.3f} Z{-p:.3f} I{-r:.3f} K0"]
    lines += ["G19", f"G2 X{r + p:.3f} Y{p + 2 * r:.3f} Z{-p:.3f} J{r:.3f} K0"]
    lines += ["G0 Z10", "M30", "%"]
    return "\n".join(lines) + "\n"
