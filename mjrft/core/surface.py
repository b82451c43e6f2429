"""The medium's free surface as a function of horizontal position: flat, a tilted plane, a
height grid (a MuJoCo height field), or a deforming height grid with memory (``mjrft.core.soil``).

Depth is measured vertically: an element at (x, y, z) is at depth ``height(x, y) - z``. RFT's
resistive stresses are measured under a horizontal free surface (Li, Zhang & Goldman 2013;
Treers, Cao & Stuart 2021), and their depth is the vertical distance below it; on a slope the
same rule is applied with the local surface height, so a plate at local vertical depth d feels
what it would at depth d under flat ground (the hydrostatic-like growth of the resistance with
depth is taken along gravity, not along the slope's normal, and the slope's own weakening near
the angle of repose is not modelled: docs/field.md, "Surfaces").

A surface is two arrays, so the compiled pass takes it as model data:

* ``prm`` (PRM_SIZE,): kind (FLAT, PLANE, GRID), the reference height z0 [m], the gradient
  (gx, gy) of a plane, and for a grid its lower corner (x0, y0) [m], spacing (dx, dy) [m],
  number of columns (along x) and rows (along y), and the largest height [m];
* ``grid`` (nrow, ncol): heights [m] of a grid's vertices, row r at y0 + r dy, column c at
  x0 + c dx (a flat or plane surface carries a (1, 1) grid that is not read);
* ``soil`` (1D): per-MjData state of a deforming grid (kind SOIL; ``soil_block`` below gives its
  layout), read from the MjData's ``userdata``; the other kinds take a stand-in that is not read.

A SOIL surface is a grid whose vertex v has, on top of the initial heights ``grid``, offsets of
its surface height h and of its compacted level c (c <= h), and a memory depth p >= 0: below c
the medium resists as at depth (h + p) - z, the depth it had before an intruder pressed the
column down, while the loose material between c and h resists as at depth h - z
(``mjrft.core.soil``; docs/terrain.md).

A grid is the surface MuJoCo's own collision builds from a height field: each cell is split into
two triangles along its diagonal from (c, r) to (c + 1, r + 1), and the height is linear over
each triangle. Outside the grid the height of its nearest edge continues. World frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

FLAT, PLANE, GRID, SOIL = 0, 1, 2, 3
#: Slots of ``prm``; SOIL only: TAN_REPOSE, the tangent of the medium's angle of repose, and
#: EVERY, the steps between updates of the ground (1: every step).
KIND, Z0, GX, GY, X0, Y0, DX, DY, NCOL, NROW, ZMAX, TAN_REPOSE, EVERY = range(13)
PRM_SIZE = 13
#: Head of a soil block: how far the highest point rose above prm[ZMAX] [m]; 1 once the grid
#: followed a configuration; the time of that configuration [s]; the vertex box (r0, r1, c0, c1)
#: still relaxing; the box of the intruders' last footprints. Then the offsets of h and of c
#: [m] and the memory p [m], nrow * ncol each (row-major). All zero: the initial surface, so
#: ``mj_resetData`` (which zeroes userdata) restores it.
SOIL_ZOFF, SOIL_DONE, SOIL_TIME = 0, 1, 2
SOIL_PENDING, SOIL_FOOT = 3, 7
SOIL_HEAD = 11
#: An element within this height [m] above a SOIL surface still touches it: the grid follows an
#: intruder's lower surface exactly, and rounding must not decide whether the intruder touches
#: the floor it just pressed (0.1 um: far below a grain).
SOIL_CONTACT = 1e-7
_JIT = {"cache": True, "error_model": "numpy"}


@numba.njit(inline="always", **_JIT)
def grid_height(prm, grid, x, y):
    """Height [m] of a GRID surface at (x, y) [m]: linear over the two triangles of each cell
    (diagonal (c, r)-(c + 1, r + 1), as MuJoCo's height-field collision), the edge beyond."""
    ncol, nrow = int(prm[NCOL]), int(prm[NROW])
    u = (x - prm[X0]) / prm[DX]
    v = (y - prm[Y0]) / prm[DY]
    u = min(max(u, 0.0), ncol - 1.0)
    v = min(max(v, 0.0), nrow - 1.0)
    c = min(int(u), ncol - 2)
    r = min(int(v), nrow - 2)
    fu = u - c
    fv = v - r
    h00 = grid[r, c]
    h11 = grid[r + 1, c + 1]
    if fu >= fv:
        return h00 + fu * (grid[r, c + 1] - h00) + fv * (h11 - grid[r, c + 1])
    return h00 + fv * (grid[r + 1, c] - h00) + fu * (h11 - grid[r + 1, c])


def soil_block(nrow: int, ncol: int) -> int:
    """Size of the soil block of an nrow x ncol SOIL grid (userdata entries)."""
    return SOIL_HEAD + 3 * nrow * ncol


@numba.njit(inline="always", **_JIT)
def _cell(prm, x, y):
    """(r, c, fu, fv, upper) of (x, y) in a grid: its cell, the position inside it, and whether
    it lies in the cell's triangle (c, r)-(c + 1, r)-(c + 1, r + 1) (fu >= fv)."""
    ncol, nrow = int(prm[NCOL]), int(prm[NROW])
    u = min(max((x - prm[X0]) / prm[DX], 0.0), ncol - 1.0)
    v = min(max((y - prm[Y0]) / prm[DY], 0.0), nrow - 1.0)
    c = min(int(u), ncol - 2)
    r = min(int(v), nrow - 2)
    return r, c, u - c, v - r, u - c >= v - r


@numba.njit(inline="always", **_JIT)
def _tri(a00, a10, a01, a11, fu, fv, upper):
    """Linear interpolation over a cell's triangle: a00 at (c, r), a10 at (c + 1, r), a01 at
    (c, r + 1), a11 at (c + 1, r + 1)."""
    if upper:
        return a00 + fu * (a10 - a00) + fv * (a11 - a10)
    return a00 + fv * (a01 - a00) + fu * (a11 - a01)


@numba.njit(inline="always", **_JIT)
def soil_vertex(prm, grid, soil, r, c):
    """(h, c, p) [m] at vertex (r, c) of a SOIL grid: surface, compacted level, memory."""
    n = int(prm[NCOL]) * int(prm[NROW])
    i = SOIL_HEAD + r * int(prm[NCOL]) + c
    base = grid[r, c]
    return base + soil[i], base + soil[i + n], soil[i + 2 * n]


@numba.njit(inline="always", **_JIT)
def soil_depth(prm, grid, soil, x, y, z):
    """Resisting depth [m] of the point (x, y, z) under a SOIL surface (<= 0: not in it)."""
    r, c, fu, fv, upper = _cell(prm, x, y)
    h00, c00, p00 = soil_vertex(prm, grid, soil, r, c)
    h10, c10, p10 = soil_vertex(prm, grid, soil, r, c + 1)
    h01, c01, p01 = soil_vertex(prm, grid, soil, r + 1, c)
    h11, c11, p11 = soil_vertex(prm, grid, soil, r + 1, c + 1)
    h = _tri(h00, h10, h01, h11, fu, fv, upper)
    if z >= h + SOIL_CONTACT:
        return 0.0
    depth = max(h - z, 0.0)
    if z < _tri(c00, c10, c01, c11, fu, fv, upper) + SOIL_CONTACT:
        depth += _tri(p00, p10, p01, p11, fu, fv, upper)
    return depth


@numba.njit(inline="always", **_JIT)
def height(prm, grid, soil, x, y):
    """Surface height [m] at the horizontal position (x, y) [m], world frame."""
    kind = prm[KIND]
    if kind == FLAT:
        return prm[Z0]
    if kind == PLANE:
        return prm[Z0] + prm[GX] * x + prm[GY] * y
    if kind == GRID:
        return grid_height(prm, grid, x, y)
    r, c, fu, fv, upper = _cell(prm, x, y)
    h00 = soil_vertex(prm, grid, soil, r, c)[0]
    h10 = soil_vertex(prm, grid, soil, r, c + 1)[0]
    h01 = soil_vertex(prm, grid, soil, r + 1, c)[0]
    h11 = soil_vertex(prm, grid, soil, r + 1, c + 1)[0]
    return _tri(h00, h10, h01, h11, fu, fv, upper)


@numba.njit(inline="always", **_JIT)
def depth(prm, grid, soil, x, y, z):
    """Resisting depth [m] of the world point (x, y, z): vertical distance below the surface
    (and, under a SOIL surface, the memory of its compacted part); <= 0 outside the medium."""
    if prm[KIND] == SOIL:
        return soil_depth(prm, grid, soil, x, y, z)
    return height(prm, grid, soil, x, y) - z


@numba.njit(inline="always", **_JIT)
def ceiling(prm, soil):
    """An upper bound [m] of the height below which a point can be in the medium anywhere: the
    flat height, a grid's highest point, or +inf for a plane."""
    kind = prm[KIND]
    if kind == FLAT:
        return prm[Z0]
    if kind == PLANE:
        return np.inf
    if kind == GRID:
        return prm[ZMAX]
    return prm[ZMAX] + soil[SOIL_ZOFF] + SOIL_CONTACT


@numba.njit(inline="always", **_JIT)
def highest_near(prm, soil, x, y, r):
    """An upper bound [m] of the surface height within horizontal distance r [m] of (x, y)."""
    if prm[KIND] == PLANE:
        return prm[Z0] + prm[GX] * x + prm[GY] * y + r * math.hypot(prm[GX], prm[GY])
    return ceiling(prm, soil)


@dataclass(frozen=True)
class Surface:
    """A free surface (module docstring): ``prm`` (PRM_SIZE,) and ``grid`` (nrow, ncol)."""

    prm: np.ndarray
    grid: np.ndarray

    @property
    def kind(self) -> int:
        return int(self.prm[KIND])

    @property
    def z0(self) -> float:
        """Reference height [m]: the flat surface's, the plane's at x = y = 0, a grid's lowest."""
        return float(self.prm[Z0])

    def height(self, x, y) -> np.ndarray:
        """Surface height [m] at horizontal positions x, y [m] (arrays of one shape; world)."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        out = np.empty(x.shape)
        # A SOIL surface as it starts (its state all zeros); per MjData: GranularField.soil.
        soil = NO_SOIL if self.kind != SOIL else np.zeros(soil_block(*self.grid.shape))
        _heights(self.prm, self.grid, soil, x.ravel(), y.ravel(), out.reshape(-1))
        return out


#: The soil stand-in of the surfaces that have no per-MjData state.
NO_SOIL = np.zeros(1)


@numba.njit(**_JIT)
def _heights(prm, grid, soil, x, y, out):
    for i in range(x.shape[0]):
        out[i] = height(prm, grid, soil, x[i], y[i])


def _prm(kind: int, z0: float) -> np.ndarray:
    prm = np.zeros(PRM_SIZE)
    prm[KIND], prm[Z0], prm[ZMAX] = kind, z0, z0
    return prm


def flat(z: float) -> Surface:
    """The horizontal surface at height z [m]."""
    return Surface(_prm(FLAT, float(z)), np.zeros((1, 1)))


def plane(z0: float, slope: float, azimuth: float) -> Surface:
    """A plane through (0, 0, z0) [m] descending at `slope` [rad] from the horizontal towards the
    horizontal direction at `azimuth` [rad] from +x (counter-clockwise about +z)."""
    prm = _prm(PLANE, float(z0))
    grade = math.tan(slope)
    prm[GX], prm[GY] = -grade * math.cos(azimuth), -grade * math.sin(azimuth)
    return Surface(prm, np.zeros((1, 1)))


def grid(heights: np.ndarray, x0: float, y0: float, dx: float, dy: float) -> Surface:
    """A height grid: heights (nrow, ncol) [m] at x0 + c dx, y0 + r dy (nrow, ncol >= 2)."""
    h = np.ascontiguousarray(heights, dtype=np.float64)
    if h.ndim != 2 or min(h.shape) < 2:
        raise ValueError(f"a height grid needs at least 2 x 2 vertices, got shape {h.shape}")
    if not np.all(np.isfinite(h)):
        raise ValueError("a height grid's heights must be finite")
    if not (dx > 0.0 and dy > 0.0):
        raise ValueError(f"a height grid's spacing must be positive, got dx={dx}, dy={dy}")
    prm = _prm(GRID, float(h.min()))
    prm[X0], prm[Y0], prm[DX], prm[DY] = x0, y0, dx, dy
    prm[NCOL], prm[NROW] = h.shape[1], h.shape[0]
    prm[ZMAX] = float(h.max())
    return Surface(prm, h)
