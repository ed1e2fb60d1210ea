"""The stock in the program frame as a z-map: one material interval per column of a regular X-Y grid.

Frame: the **program frame** (the CAM program's own X, Y, Z, m); the tool axis is +Z (3-axis).

A :class:`ZMap` is a grid of ``nx x ny`` square cells of side ``resolution_m``; cell ``(i, j)`` covers
``[x0 + i res, x0 + (i + 1) res] x [y0 + j res, y0 + (j + 1) res]`` and is represented by its centre.
Each column holds a single material interval ``[bottom, top]`` (NaN, NaN when empty): the stock is
the union of the prisms ``cell x [bottom, top]``.  Its limit is that of any z-map: it cannot hold
two intervals in one column (an undercut, an overhang or a horizontal hole seen from above), so a
mesh that needs them is refused rather than silently filled.

Sources: :class:`StockBox` (an axis-aligned box) and :class:`StockMesh` (a closed triangle mesh,
read with trimesh); both give a :class:`ZMap` by ``to_zmap(resolution_m)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from models.errors import InputError

__all__ = ["MAX_ZMAP_CELLS", "ZMAP_RESOLUTION_M", "StockBox", "StockMesh", "ZMap"]

#: Default side of a z-map cell, m (0.1 mm).
ZMAP_RESOLUTION_M = 1e-4
#: Most cells a z-map may have (two float64 arrays: 16 bytes a cell, 480 MB at the bound).
MAX_ZMAP_CELLS = 30_000_000
#: Two crossings of a column by a mesh closer than this (m) with the same facing are one
#: (the column passes through an edge or vertex shared by two triangles).
MESH_CROSSING_TOL_M = 1e-9


@dataclass
class ZMap:
    """A z-map: per column of a regular X-Y grid, one material interval (program frame, m).

    Attributes
    ----------
    x0_m, y0_m : float
        Lower-left corner of the grid, m.
    resolution_m : float
        Cell side, m.
    bottom_m, top_m : ndarray, float64, shape (nx, ny)
        The column's material interval, m; both NaN where the column is empty.  Mutated by cuts.
    """

    x0_m: float
    y0_m: float
    resolution_m: float
    bottom_m: np.ndarray
    top_m: np.ndarray

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0.0):
            raise InputError(f"z-map resolution must be > 0 m, got {self.resolution_m!r}")
        b, t = np.asarray(self.bottom_m, dtype=float), np.asarray(self.top_m, dtype=float)
        if b.ndim != 2 or b.shape != t.shape:
            raise InputError(f"z-map bottom and top must be 2-D arrays of one shape, got {b.shape} and {t.shape}")
        empty = ~(t >= b)
        self.bottom_m = np.where(empty, np.nan, b)
        self.top_m = np.where(empty, np.nan, t)

    @property
    def shape(self) -> tuple[int, int]:
        """(nx, ny): cells along X and Y."""
        return self.bottom_m.shape  # type: ignore[return-value]

    def x_centres_m(self) -> np.ndarray:
        """X of the cell centres, m, shape (nx,)."""
        return self.x0_m + (np.arange(self.shape[0]) + 0.5) * self.resolution_m

    def y_centres_m(self) -> np.ndarray:
        """Y of the cell centres, m, shape (ny,)."""
        return self.y0_m + (np.arange(self.shape[1]) + 0.5) * self.resolution_m

    def thickness_m(self) -> np.ndarray:
        """Material height of each column, m, shape (nx, ny) (0 where empty)."""
        return np.nan_to_num(self.top_m - self.bottom_m, nan=0.0)

    def volume_m3(self) -> float:
        """Volume of the material left, m^3 (sum of the columns' prisms)."""
        return float(self.thickness_m().sum() * self.resolution_m**2)

    def copy(self) -> ZMap:
        """An independent copy (cuts on it leave this one as it is)."""
        return ZMap(self.x0_m, self.y0_m, self.resolution_m, self.bottom_m.copy(), self.top_m.copy())

    def column_interval(self, x_m: np.ndarray, y_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The material interval ``(bottom, top)`` of the column whose cell holds each point (its
        nearest centre), m; both NaN where the column is empty or the point is off the grid.

        Parameters
        ----------
        x_m, y_m : ndarray
            Program-frame coordinates, m, broadcastable to one shape.
        """
        nx, ny = self.shape
        ix = np.floor((np.asarray(x_m) - self.x0_m) / self.resolution_m).astype(np.int64)
        iy = np.floor((np.asarray(y_m) - self.y0_m) / self.resolution_m).astype(np.int64)
        on = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        flat = np.where(on, ix * ny + iy, 0)
        bottom, top = np.take(self.bottom_m, flat), np.take(self.top_m, flat)
        if not on.all():
            bottom, top = np.where(on, bottom, np.nan), np.where(on, top, np.nan)
        return bottom, top

    def contains(self, x_m: np.ndarray, y_m: np.ndarray, z_m: np.ndarray) -> np.ndarray:
        """Whether points are in material, by the column whose cell holds the point (its nearest
        centre): the z-map's own model of the stock, piecewise constant per cell.

        Parameters
        ----------
        x_m, y_m, z_m : ndarray
            Program-frame coordinates, m, broadcastable to one shape.

        Returns
        -------
        ndarray, bool
            True where ``bottom <= z <= top`` of the point's column (False off the grid).
        """
        bottom, top = self.column_interval(x_m, y_m)
        z = np.asarray(z_m)
        return (bottom <= z) & (z <= top)


def _grid(lo_xy: np.ndarray, hi_xy: np.ndarray, resolution_m: float, what: str) -> tuple[float, float, int, int]:
    """A grid of square cells covering [lo, hi] in X-Y, centred on it; refuses one too large."""
    if not (math.isfinite(resolution_m) and resolution_m > 0.0):
        raise InputError(f"{what}: z-map resolution must be > 0 m, got {resolution_m!r}")
    span = hi_xy - lo_xy
    n = np.maximum(np.ceil(span / resolution_m - 1e-9), 1).astype(int)
    cells = int(n[0]) * int(n[1])
    if cells > MAX_ZMAP_CELLS:
        need = math.sqrt(float(span[0] * span[1]) / MAX_ZMAP_CELLS)
        raise InputError(
            f"{what}: a z-map of {span[0] * 1e3:g} x {span[1] * 1e3:g} mm at resolution {resolution_m * 1e3:g} mm "
            f"has {cells} cells, more than the bound {MAX_ZMAP_CELLS}; use a resolution >= {need * 1e3:.3g} mm"
        )
    x0, y0 = (lo_xy + hi_xy) / 2.0 - n * resolution_m / 2.0
    return float(x0), float(y0), int(n[0]), int(n[1])


@dataclass(frozen=True)
class StockBox:
    """An axis-aligned box of stock in the program frame.

    Attributes
    ----------
    min_m, max_m : array_like, shape (3,)
        Opposite corners, m (``min_m < max_m`` on every axis).
    """

    min_m: tuple[float, float, float]
    max_m: tuple[float, float, float]

    def __post_init__(self) -> None:
        lo, hi = np.asarray(self.min_m, dtype=float), np.asarray(self.max_m, dtype=float)
        if lo.shape != (3,) or hi.shape != (3,) or not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise InputError(f"stock box corners must be 3 finite numbers each, got {self.min_m!r} and {self.max_m!r}")
        if not np.all(hi > lo):
            raise InputError(f"stock box max {hi.tolist()} m must exceed min {lo.tolist()} m on every axis")

    def volume_m3(self) -> float:
        """The box's volume, m^3."""
        return float(np.prod(np.asarray(self.max_m, dtype=float) - np.asarray(self.min_m, dtype=float)))

    def to_zmap(self, resolution_m: float = ZMAP_RESOLUTION_M) -> ZMap:
        """The box as a z-map: the columns whose centre lies in the box's X-Y footprint hold
        [min z, max z] (exact when the box's sides are whole multiples of the resolution)."""
        lo, hi = np.asarray(self.min_m, dtype=float), np.asarray(self.max_m, dtype=float)
        x0, y0, nx, ny = _grid(lo[:2], hi[:2], resolution_m, "stock box")
        xc = x0 + (np.arange(nx) + 0.5) * resolution_m
        yc = y0 + (np.arange(ny) + 0.5) * resolution_m
        inside = ((xc >= lo[0]) & (xc <= hi[0]))[:, None] & ((yc >= lo[1]) & (yc <= hi[1]))[None, :]
        return ZMap(x0, y0, resolution_m, np.where(inside, lo[2], np.nan), np.where(inside, hi[2], np.nan))


@dataclass(frozen=True)
class StockMesh:
    """A closed (watertight) triangle mesh of stock, in the program frame after scaling.

    Attributes
    ----------
    path : str or Path
        A mesh file trimesh reads (STL, OBJ, PLY, ...).
    unit_m : float
        Metres per file unit (1e-3 for a file in mm).
    """

    path: str | Path
    unit_m: float = 1.0

    def load(self):
        """The scaled trimesh mesh; refuses an unreadable or open one."""
        import trimesh

        if not (math.isfinite(self.unit_m) and self.unit_m > 0.0):
            raise InputError(f"stock mesh {self.path}: unit must be > 0 m per file unit, got {self.unit_m!r}")
        try:
            mesh = trimesh.load(str(self.path), force="mesh")
        except Exception as exc:  # trimesh raises many kinds
            raise InputError(f"stock mesh {self.path}: cannot be read as a triangle mesh ({exc})") from exc
        if len(mesh.faces) == 0:
            raise InputError(f"stock mesh {self.path}: has no triangles")
        if not mesh.is_watertight:
            raise InputError(f"stock mesh {self.path}: is not closed (watertight); a stock must be a solid")
        if not mesh.is_winding_consistent:
            raise InputError(f"stock mesh {self.path}: its triangles are not consistently oriented")
        if mesh.volume < 0.0:  # inward normals: turn them out, so +Z-facing triangles are tops
            mesh.invert()
        mesh.apply_scale(self.unit_m)
        return mesh

    def to_zmap(self, resolution_m: float = ZMAP_RESOLUTION_M) -> ZMap:
        """The mesh as a z-map, by casting a vertical line through every cell centre.

        Raises
        ------
        InputError
            The mesh is open, too large for the resolution, or a column crosses it more than twice
            (more than one material interval: the message names the mesh and that column's x, y).
        """
        mesh = self.load()
        lo, hi = mesh.bounds
        x0, y0, nx, ny = _grid(lo[:2], hi[:2], resolution_m, f"stock mesh {self.path}")
        col, z, up = _column_crossings(np.asarray(mesh.triangles, dtype=float), x0, y0, resolution_m, nx, ny)
        bottom = np.full((nx, ny), np.nan)
        top = np.full((nx, ny), np.nan)
        if col.size == 0:
            return ZMap(x0, y0, resolution_m, bottom, top)
        order = np.lexsort((z, col))
        col, z, up = col[order], z[order], up[order]
        # one crossing per surface: drop repeats (an edge or vertex shared by triangles)
        keep = np.r_[True, (col[1:] != col[:-1]) | (np.abs(z[1:] - z[:-1]) > MESH_CROSSING_TOL_M) | (up[1:] != up[:-1])]
        col, z, up = col[keep], z[keep], up[keep]
        ucol, start, count = np.unique(col, return_index=True, return_counts=True)
        bad = (count != 2) | up[start] | ~up[np.minimum(start + 1, col.size - 1)]
        if np.any(bad):
            c = int(ucol[np.argmax(bad)])
            xb, yb = x0 + (c // ny + 0.5) * resolution_m, y0 + (c % ny + 0.5) * resolution_m
            raise InputError(
                f"stock mesh {self.path}: the vertical line at x={xb * 1e3:.4g} mm, y={yb * 1e3:.4g} mm crosses "
                f"its surface {int(count[np.argmax(bad)])} times; a z-map holds one material interval per column "
                "(no undercut, overhang or horizontal hole)"
            )
        bottom.ravel()[ucol] = z[start]
        top.ravel()[ucol] = z[start + 1]
        return ZMap(x0, y0, resolution_m, bottom, top)


def _column_crossings(
    tri: np.ndarray, x0: float, y0: float, res: float, nx: int, ny: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where vertical lines through cell centres cross triangles (vertical ones skipped).

    Returns flat column indices ``i * ny + j``, crossing heights (m) and whether the triangle faces
    up (+Z normal: the top of material).
    """
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    nz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    cols, zs, ups = [], [], []
    for t in np.flatnonzero(np.abs(nz) > 1e-30):
        a, b, c = tri[t]
        lo, hi = tri[t, :, :2].min(axis=0), tri[t, :, :2].max(axis=0)
        i0, i1 = max(int(np.ceil((lo[0] - x0) / res - 0.5)), 0), min(int(np.floor((hi[0] - x0) / res - 0.5)), nx - 1)
        j0, j1 = max(int(np.ceil((lo[1] - y0) / res - 0.5)), 0), min(int(np.floor((hi[1] - y0) / res - 0.5)), ny - 1)
        if i1 < i0 or j1 < j0:
            continue
        I, J = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
        px, py = x0 + (I + 0.5) * res, y0 + (J + 0.5) * res
        # barycentric coordinates of the centre in the triangle's X-Y projection
        w1 = ((px - a[0]) * e2[t, 1] - (py - a[1]) * e2[t, 0]) / nz[t]
        w2 = ((py - a[1]) * e1[t, 0] - (px - a[0]) * e1[t, 1]) / nz[t]
        tol = 1e-12
        inside = (w1 >= -tol) & (w2 >= -tol) & (w1 + w2 <= 1.0 + tol)
        if not inside.any():
            continue
        w1, w2 = w1[inside], w2[inside]
        cols.append((I[inside] * ny + J[inside]).ravel())
        zs.append(a[2] + w1 * (b[2] - a[2]) + w2 * (c[2] - a[2]))
        ups.append(np.full(w1.size, nz[t] > 0.0))
    if not cols:
        return np.zeros(0, int), np.zeros(0), np.zeros(0, bool)
    return np.concatenate(cols), np.concatenate(zs), np.concatenate(ups)
