"""The free surface as Warp functions: flat, tilted or a height grid (``mjrft.core.surface``).

Depth is measured vertically below the surface at the point's horizontal position; a grid is
linear over the two triangles of each cell (diagonal (c, r)-(c + 1, r + 1), as MuJoCo's
height-field collision), its nearest edge's height beyond it. World frame, float64. The
deforming grid (kind SOIL) is not here: the Warp field refuses it.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from mjrft.core import surface as s
from mjrft.warp.law import f64, vec3d

FLAT = wp.constant(s.FLAT)
PLANE = wp.constant(s.PLANE)
GRID = wp.constant(s.GRID)


@wp.struct
class Surface:
    """kind (FLAT, PLANE, GRID); z0 [m]; a plane's gradient gx, gy; a grid's corner x0, y0 [m],
    spacing dx, dy [m], ncol x nrow vertices of heights grid [m] and its highest point zmax."""

    kind: int
    z0: f64
    gx: f64
    gy: f64
    x0: f64
    y0: f64
    dx: f64
    dy: f64
    ncol: int
    nrow: int
    zmax: f64
    grid: wp.array2d(dtype=f64)


def from_core(surf: s.Surface, device) -> Surface:
    """The Warp struct of a flat, plane or grid ``mjrft.core.surface.Surface``."""
    p = surf.prm
    out = Surface()
    out.kind = int(p[s.KIND])
    for name, slot in (("z0", s.Z0), ("gx", s.GX), ("gy", s.GY), ("x0", s.X0), ("y0", s.Y0),
                       ("dx", s.DX), ("dy", s.DY), ("zmax", s.ZMAX)):  # fmt: skip
        setattr(out, name, f64(p[slot]))
    out.ncol, out.nrow = int(p[s.NCOL]), int(p[s.NROW])
    out.grid = wp.array(np.ascontiguousarray(surf.grid, dtype=np.float64), dtype=f64, device=device)
    return out


@wp.func
def grid_height(sf: Surface, x: f64, y: f64) -> f64:
    """Height [m] of the grid at (x, y) [m] (``mjrft.core.surface.grid_height``)."""
    ncol = sf.ncol
    nrow = sf.nrow
    u = wp.min(wp.max((x - sf.x0) / sf.dx, f64(0.0)), f64(ncol - 1))
    v = wp.min(wp.max((y - sf.y0) / sf.dy, f64(0.0)), f64(nrow - 1))
    c = wp.min(int(u), ncol - 2)
    r = wp.min(int(v), nrow - 2)
    fu = u - f64(c)
    fv = v - f64(r)
    h00 = sf.grid[r, c]
    h11 = sf.grid[r + 1, c + 1]
    if fu >= fv:
        return h00 + fu * (sf.grid[r, c + 1] - h00) + fv * (h11 - sf.grid[r, c + 1])
    return h00 + fv * (sf.grid[r + 1, c] - h00) + fu * (h11 - sf.grid[r + 1, c])


@wp.func
def height(sf: Surface, x: f64, y: f64) -> f64:
    """Surface height [m] at the horizontal position (x, y) [m]."""
    if sf.kind == FLAT:
        return sf.z0
    if sf.kind == PLANE:
        return sf.z0 + sf.gx * x + sf.gy * y
    return grid_height(sf, x, y)


@wp.func
def depth(sf: Surface, p: vec3d) -> f64:
    """Vertical depth [m] of the world point p below the surface (<= 0: above it)."""
    return height(sf, p[0], p[1]) - p[2]


@wp.func
def ceiling(sf: Surface) -> f64:
    """An upper bound [m] of the surface anywhere: the flat height, a grid's highest point, or
    +inf for a plane."""
    if sf.kind == FLAT:
        return sf.z0
    if sf.kind == PLANE:
        return f64(wp.inf)
    return sf.zmax


@wp.func
def highest_near(sf: Surface, x: f64, y: f64, r: f64) -> f64:
    """An upper bound [m] of the surface height within horizontal distance r [m] of (x, y)."""
    if sf.kind == PLANE:
        return sf.z0 + sf.gx * x + sf.gy * y + r * wp.sqrt(sf.gx * sf.gx + sf.gy * sf.gy)
    return ceiling(sf)
