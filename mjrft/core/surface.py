"""The medium's free surface as a function of horizontal position: flat, a tilted plane, a
height grid (a MuJoCo height field), or a deforming height grid with memory (``mjrft.core.soil``).

Depth is measured vertically: an element at (x, y, z) is at depth ``height(x, y) - z``. RFT's
resistive stresses are measured under a horizontal free surface (Li, Zhang & Goldman 2013;
Treers, Cao & Stuart 2021), and their depth is the vertical distance below it; on a slope the
same rule is applied with the local surface height, so a plate at local vertical depth d feels
what it would at depth d under flat ground (the hydrostatic-like growth of the resistance with
depth is taken along gravity, not along the slope's normal, and the slope's own weakening near
the angle of repose is not modelled: docs/field.md, "Surfaces").

A surface is two arrays, so the engine (engine/surface.h) takes it as model data:

* ``prm`` (PRM_SIZE,): kind (FLAT, PLANE, GRID), the reference height z0 [m], the gradient
  (gx, gy) of a plane, and for a grid its lower corner (x0, y0) [m], spacing (dx, dy) [m],
  number of columns (along x) and rows (along y), and the largest height [m];
* ``grid`` (nrow, ncol): heights [m] of a grid's vertices, row r at y0 + r dy, column c at
  x0 + c dx (a flat or plane surface carries a (1, 1) grid that is not read);
* ``soil`` (1D): per-MjData state of a deforming grid (kind SOIL; ``soil_block`` below gives its
  layout), the engine state's ``soil`` array; the other kinds take a stand-in that is not read.

A SOIL surface is a grid whose vertex v has, on top of the initial heights ``grid``, offsets of
its surface height h and of its compacted level c (c <= h), and a memory depth p >= 0: below c
the medium resists as at depth (h + p) - z, the depth it had before an intruder pressed the
column down, while the loose material between c and h resists as at depth h - z
(``mjrft.core.soil``; docs/terrain.md).

A grid is the surface MuJoCo's own collision builds from a height field: each cell is split into
two triangles along its diagonal from (c, r) to (c + 1, r + 1), and the height is linear over
each triangle. Outside the grid the height of its nearest edge continues. World frame.

Heights and depths are computed by the C++ engine (``height``, ``depth``: engine/surface.cc
through ``mjrft.core.engine``), the same functions the engine's step uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mjrft.core import engine

FLAT, PLANE, GRID, SOIL = 0, 1, 2, 3
#: Slots of ``prm``; SOIL only: TAN_REPOSE, the tangent of the medium's angle of repose; EVERY,
#: the steps between updates of the ground (0: TRAVEL's rule); TRAVEL, the cells the intruders
#: travel between updates (0: every step).
KIND, Z0, GX, GY, X0, Y0, DX, DY, NCOL, NROW, ZMAX, TAN_REPOSE, EVERY, TRAVEL = range(14)
PRM_SIZE = 14
#: Head of a soil block: how far the highest point rose above prm[ZMAX] [m]; 1 once the grid
#: followed a configuration; the time of that configuration [s]; the vertex box (r0, r1, c0, c1)
#: still relaxing; the box of the intruders' last footprints; how far [m] the intruders may have
#: travelled since, and the time [s] that distance was last accumulated. Then SOIL_LEVELS levels
#: of nrow * ncol each (row-major): the offsets of h and of c [m], the memory p [m] and the press
#: mark (k + 1 where tagged body k pressed on the vertex at the last update, 0 none; engine
#: surface::SoilDepth). All zero: the initial surface, so ``mj_resetData`` (which zeroes the
#: engine's state) restores it.
SOIL_ZOFF, SOIL_DONE, SOIL_TIME = 0, 1, 2
SOIL_PENDING, SOIL_FOOT = 3, 7
SOIL_TRAVEL, SOIL_CLOCK = 11, 12
SOIL_HEAD = 13
SOIL_LEVELS = 4
#: An element within this height [m] above a SOIL surface still touches it: the grid follows an
#: intruder's lower surface exactly, and rounding must not decide whether the intruder touches
#: the floor it just pressed (0.1 um: far below a grain).
SOIL_CONTACT = 1e-7


def soil_block(nrow: int, ncol: int) -> int:
    """Size of the soil block of an nrow x ncol SOIL grid (the engine state's ``soil``)."""
    return SOIL_HEAD + SOIL_LEVELS * nrow * ncol


def height(prm: np.ndarray, grid: np.ndarray, soil: np.ndarray | None, x, y):
    """Surface height [m] of the surface (prm, grid, soil) at horizontal positions x, y [m]
    (broadcast to one shape), world frame: an array of that shape, a float for scalars. soil:
    a SOIL surface's block (its state), None (or ``NO_SOIL``) for the other kinds. Raises
    ValueError if the arrays do not fit each other (``mjrft.core.engine``)."""
    out = engine.surface_heights(prm, grid, soil, x, y)
    return float(out) if out.ndim == 0 else out


def depth(prm: np.ndarray, grid: np.ndarray, soil: np.ndarray | None, x, y, z, body: int = 0):
    """Resisting depth [m] of the world points (x, y, z) [m] (broadcast to one shape): vertical
    distance below the surface (and, under a SOIL surface, the memory of its compacted part);
    <= 0 outside the medium. An array of that shape, a float for scalars; soil as ``height``.
    body: k + 1 for points of a field's tagged body k (beside its press marks a SOIL surface
    stands at the free material's height, engine/surface.h), 0 for none."""
    out = engine.surface_depths(prm, grid, soil, x, y, z, body=body)
    return float(out) if out.ndim == 0 else out


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
        # A SOIL surface as it starts (its state all zeros); per MjData: GranularField.soil.
        soil = NO_SOIL if self.kind != SOIL else np.zeros(soil_block(*self.grid.shape))
        return engine.surface_heights(self.prm, self.grid, soil, x, y)


#: The soil stand-in of the surfaces that have no per-MjData state.
NO_SOIL = np.zeros(1)


def _heights(prm, grid, soil, x, y, out) -> None:
    """Heights [m] at the points x, y (n,) [m] into out (n,) (``height``; the field layer's
    ``Soil.height_at`` calls it)."""
    engine.surface_heights(prm, grid, soil, x, y, out=out)


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
