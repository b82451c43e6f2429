"""The free surface as Warp functions: flat, tilted or a height grid (``mjrft.core.surface``).

Depth is measured vertically below the surface at the point's horizontal position; a grid is
linear over the two triangles of each cell (diagonal (c, r)-(c + 1, r + 1), as MuJoCo's
height-field collision), its nearest edge's height beyond it. A deforming grid (kind SOIL) adds
per world the offsets of its heights and compacted levels and its memory (the engine's soil
block, one row per world of ``soil``; ``w`` selects the row: a kernel sets it on its copy of
the struct), and its resisting depth (engine surface::SoilDepth). World frame, float64.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from mjrft.core import surface as s
from mjrft.warp.law import f64, vec3d

FLAT = wp.constant(s.FLAT)
PLANE = wp.constant(s.PLANE)
GRID = wp.constant(s.GRID)
SOIL = wp.constant(s.SOIL)
#: engine/surface.h: the soil block's head and its slots; the contact height [m].
SOIL_HEAD = wp.constant(s.SOIL_HEAD)
SOIL_ZOFF = wp.constant(s.SOIL_ZOFF)
SOIL_CONTACT = wp.constant(wp.float64(s.SOIL_CONTACT))


@wp.struct
class Surface:
    """kind (FLAT, PLANE, GRID, SOIL); z0 [m]; a plane's gradient gx, gy; a grid's corner x0,
    y0 [m], spacing dx, dy [m], ncol x nrow vertices of heights grid [m] and its highest point
    zmax; a deforming grid's tangent of repose, steps between updates (every; 0: travel's
    rule), cells the intruders travel between updates (travel), per-world soil blocks soil
    (nworld, block) and the world w whose row is read."""

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
    tan_repose: f64
    every: f64
    travel: f64
    soil: wp.array2d(dtype=f64)
    w: int


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
    if out.kind == s.SOIL:
        out.tan_repose, out.every = f64(p[s.TAN_REPOSE]), f64(p[s.EVERY])
        out.travel = f64(p[s.TRAVEL])
    out.soil = wp.zeros((1, 1), dtype=f64, device=device)  # per world: with_soil
    out.w = 0
    return out


def with_soil(sf: Surface, soil: wp.array) -> Surface:
    """A copy of sf reading the per-world soil blocks soil (nworld, block)."""
    out = Surface()
    for name in Surface.vars:
        setattr(out, name, getattr(sf, name))
    out.soil = soil
    return out


@wp.func
def cell_of(sf: Surface, x: f64, y: f64):
    """The cell of (x, y) [m] in the grid: row r, column c and the position (fu, fv) inside it,
    the grid's edge continuing beyond it (engine surface::CellOf)."""
    u = wp.min(wp.max((x - sf.x0) / sf.dx, f64(0.0)), f64(sf.ncol - 1))
    v = wp.min(wp.max((y - sf.y0) / sf.dy, f64(0.0)), f64(sf.nrow - 1))
    c = wp.min(int(u), sf.ncol - 2)
    r = wp.min(int(v), sf.nrow - 2)
    return r, c, u - f64(c), v - f64(r)


@wp.func
def tri(a: f64, b: f64, d: f64, e: f64, fu: f64, fv: f64) -> f64:
    """Linear over a cell's triangle: a at (c, r), b at (c + 1, r), d at (c, r + 1), e at
    (c + 1, r + 1) (engine surface::Tri)."""
    if fu >= fv:
        return a + fu * (b - a) + fv * (e - b)
    return a + fv * (d - a) + fu * (e - d)


@wp.func
def soil_levels(sf: Surface, x: f64, y: f64) -> vec3d:
    """(h, c, p) [m] of world sf.w's deforming grid at (x, y), linear over the cell's triangle
    (engine SoilLevels)."""
    n = sf.ncol * sf.nrow
    r, c, fu, fv = cell_of(sf, x, y)
    out = vec3d()
    for lev in range(3):
        out[lev] = tri(soil_vertex(sf, n, r, c, lev), soil_vertex(sf, n, r, c + 1, lev),
                       soil_vertex(sf, n, r + 1, c, lev), soil_vertex(sf, n, r + 1, c + 1, lev),
                       fu, fv)  # fmt: skip
    return out


@wp.func
def soil_vertex(sf: Surface, n: int, r: int, c: int, lev: int) -> f64:
    """Level lev (0 surface h, 1 compacted c, 2 memory p) [m] of vertex (r, c) of world sf.w."""
    i = r * sf.ncol + c
    x = sf.soil[sf.w, SOIL_HEAD + lev * n + i]
    if lev < 2:
        x = sf.grid[r, c] + x
    return x


@wp.func
def levels_depth(h: f64, lc: f64, mem: f64, z: f64) -> f64:
    """Resisting depth [m] at height z under the levels (h, c, p) [m] of a deforming grid at a
    point: (h + p) - z below c, h - z above it (engine SoilDepth)."""
    if z >= h + SOIL_CONTACT:
        return h - z
    out = wp.max(h - z, f64(0.0))
    if z < lc + SOIL_CONTACT:
        out += mem
    return out


@wp.func
def beside_depth(sf: Surface, n: int, r: int, c: int, fu: f64, fv: f64, body: f64,
                 z: f64) -> f64:  # fmt: skip
    """Resisting depth [m] at height z of a point of the intruder marked body that presses on
    some of cell (r, c)'s vertices and not on the others (engine surface::BesideDepth): above
    the pressed vertices' surface, they take the levels of the cell's highest free vertex."""
    h = wp.vector(dtype=f64, length=4)
    lc = wp.vector(dtype=f64, length=4)
    mem = wp.vector(dtype=f64, length=4)
    pressed = wp.vector(dtype=int, length=4)
    floor = f64(-1.0e300)
    free = int(-1)
    for q in range(4):
        rr = r + q // 2
        cc = c + q % 2
        h[q] = soil_vertex(sf, n, rr, cc, 0)
        lc[q] = soil_vertex(sf, n, rr, cc, 1)
        mem[q] = soil_vertex(sf, n, rr, cc, 2)
        if sf.soil[sf.w, SOIL_HEAD + 3 * n + rr * sf.ncol + cc] == body:
            pressed[q] = 1
            floor = wp.max(floor, h[q])
        elif free < 0:
            free = q
        elif h[q] > h[free]:
            free = q
    if z >= floor + SOIL_CONTACT:  # beside the intruder: the free column up to its side
        for q in range(4):
            if pressed[q] != 0:
                h[q] = h[free]
                lc[q] = lc[free]
                mem[q] = mem[free]
    return levels_depth(tri(h[0], h[1], h[2], h[3], fu, fv),
                        tri(lc[0], lc[1], lc[2], lc[3], fu, fv),
                        tri(mem[0], mem[1], mem[2], mem[3], fu, fv), z)  # fmt: skip


@wp.func
def soil_depth(sf: Surface, p: vec3d, body: f64) -> f64:
    """Resisting depth [m] of p under world sf.w's deforming grid (engine SoilDepth): (h + p) - z
    below the compacted level c, h - z above it (negative above the surface, as under a fixed
    grid, so the force pass clips an element the surface crosses where it crosses). body: k + 1
    for a point of tagged body k, 0 for none: in a cell k presses on only in part, a point above
    its floor is beside it (beside_depth)."""
    if body > f64(0.0):
        n = sf.ncol * sf.nrow
        r, c, fu, fv = cell_of(sf, p[0], p[1])
        count = int(0)
        for q in range(4):
            i = (r + q // 2) * sf.ncol + c + q % 2
            if sf.soil[sf.w, SOIL_HEAD + 3 * n + i] == body:
                count += 1
        if count > 0 and count < 4:
            return beside_depth(sf, n, r, c, fu, fv, body, p[2])
    at = soil_levels(sf, p[0], p[1])
    return levels_depth(at[0], at[1], at[2], p[2])


@wp.func
def grid_height(sf: Surface, x: f64, y: f64) -> f64:
    """Height [m] of the grid at (x, y) [m] (``mjrft.core.surface.grid_height``)."""
    r, c, fu, fv = cell_of(sf, x, y)
    return tri(sf.grid[r, c], sf.grid[r, c + 1], sf.grid[r + 1, c], sf.grid[r + 1, c + 1], fu, fv)


@wp.func
def height(sf: Surface, x: f64, y: f64) -> f64:
    """Surface height [m] at the horizontal position (x, y) [m]."""
    if sf.kind == FLAT:
        return sf.z0
    if sf.kind == PLANE:
        return sf.z0 + sf.gx * x + sf.gy * y
    if sf.kind == SOIL:
        return soil_levels(sf, x, y)[0]
    return grid_height(sf, x, y)


@wp.func
def depth(sf: Surface, p: vec3d, body: f64) -> f64:
    """Resisting depth [m] of the world point p: vertically below the surface (<= 0: above it;
    a deforming grid adds its memory below the compacted level). body: k + 1 for a point of
    tagged body k, 0 for none (soil_depth)."""
    if sf.kind == SOIL:
        return soil_depth(sf, p, body)
    return height(sf, p[0], p[1]) - p[2]


@wp.func
def ceiling(sf: Surface) -> f64:
    """An upper bound [m] of the surface anywhere: the flat height, a grid's highest point, or
    +inf for a plane."""
    if sf.kind == FLAT:
        return sf.z0
    if sf.kind == PLANE:
        return f64(wp.inf)
    if sf.kind == SOIL:
        return sf.zmax + sf.soil[sf.w, SOIL_ZOFF] + SOIL_CONTACT
    return sf.zmax


@wp.func
def highest_near(sf: Surface, x: f64, y: f64, r: f64) -> f64:
    """An upper bound [m] of the surface height within horizontal distance r [m] of (x, y)."""
    if sf.kind == PLANE:
        return sf.z0 + sf.gx * x + sf.gy * y + r * wp.sqrt(sf.gx * sf.gx + sf.gy * sf.gy)
    return ceiling(sf)
