"""The medium's free surface as a function of horizontal position: flat, a tilted plane, or a
height grid (a MuJoCo height field).

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
  x0 + c dx (a flat or plane surface carries a (1, 1) grid that is not read).

A grid is the surface MuJoCo's own collision builds from a height field: each cell is split into
two triangles along its diagonal from (c, r) to (c + 1, r + 1), and the height is linear over
each triangle. Outside the grid the height of its nearest edge continues. World frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

FLAT, PLANE, GRID = 0, 1, 2
#: Slots of ``prm``.
KIND, Z0, GX, GY, X0, Y0, DX, DY, NCOL, NROW, ZMAX = range(11)
PRM_SIZE = 11
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


@numba.njit(inline="always", **_JIT)
def height(prm, grid, x, y):
    """Surface height [m] at the horizontal position (x, y) [m], world frame."""
    kind = prm[KIND]
    if kind == FLAT:
        return prm[Z0]
    if kind == PLANE:
        return prm[Z0] + prm[GX] * x + prm[GY] * y
    return grid_height(prm, grid, x, y)


@numba.njit(inline="always", **_JIT)
def ceiling(prm):
    """An upper bound [m] of the surface height anywhere: the flat height, a grid's highest
    point, or +inf for a plane."""
    kind = prm[KIND]
    if kind == FLAT:
        return prm[Z0]
    if kind == PLANE:
        return np.inf
    return prm[ZMAX]


@numba.njit(inline="always", **_JIT)
def highest_near(prm, x, y, r):
    """An upper bound [m] of the surface height within horizontal distance r [m] of (x, y)."""
    if prm[KIND] == PLANE:
        return prm[Z0] + prm[GX] * x + prm[GY] * y + r * math.hypot(prm[GX], prm[GY])
    return ceiling(prm)


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
        _heights(self.prm, self.grid, x.ravel(), y.ravel(), out.reshape(-1))
        return out


@numba.njit(**_JIT)
def _heights(prm, grid, x, y, out):
    for i in range(x.shape[0]):
        out[i] = height(prm, grid, x[i], y[i])


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
