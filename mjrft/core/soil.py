"""Ground that deforms and remembers: a height grid pressed down by intruders, bulldozed and
relaxed to the angle of repose, with the memory of how deep its compacted columns were.

The grid (``mjrft.core.surface``, kind SOIL) has vertices every dx, dy over the medium's region;
vertex v stands for the column of one cell area centred on it. Its state, per MjData (the soil
block, part of the engine's state in ``plugin_state``, so that MuJoCo copies, saves and resets
it with the rest of the state), is its surface height h, its compacted level c <= h and its
memory p >= 0. The resisting depth of a point at height z in the column is (h + p) - z below c
and h - z between c and h (``surface.depth``). Pristine ground has c = h, p = 0, so pristine
depth is h - z.

One update, run by the C++ engine inside MuJoCo's step (engine/deform.cc, engine/soil.cc),
follows the intruders to a new configuration:

1. *Footprints*: every downward-facing triangle of an intruder (its lower
   surface, seen from above) is rasterised onto the vertices below it; a vertex whose floor (the
   lowest such triangle over it) lies below its surface h is occupied.
2. *Excavation*: an occupied column is cut down to the floor, which becomes its compacted level
   (c = h = floor) and remembers as its depth reference the larger of the old surface h and the
   old c + p (Chrono SCM's sinkage memory plays this role in Bekker-Wong soil).
3. *Deposition*: each intruder's excavated volume is spread over the rim of its footprint (the
   unoccupied vertices next to it), weighted towards the horizontal motion of the footprint's
   centre: a vertical intrusion raises an even rim, a horizontal one bulldozes ahead of it. It
   lands as loose material (h grows, c and p unchanged).
4. *Relaxation*: wherever two neighbouring vertices (along x, y and both diagonals) differ by
   more than tan(repose) times their distance, material moves from the higher to the lower one
   (half the excess, so the pair ends exactly at the repose slope): one sweep over the box of
   recent activity, then vertex by vertex wherever material moved, never into or out of a
   column an intruder presses on or the grid's edge ring, and into the gap under a hovering
   intruder only up to its floor.

Every move subtracts from one vertex exactly what it adds to another, and the edge ring never
changes, so the volume under the surface (dx dy times the sum of h over the vertices) is
conserved up to rounding. World frame, SI units. This module holds the ground's parameters and
builds its grid (``grid_over``); ``block_views`` reads a block. The constants below are the
engine's (engine/soil.h), stated here for Python callers and tests.
"""

from __future__ import annotations

import math

import numpy as np

from mjrft.core import surface
from mjrft.core.surface import NCOL, NROW, SOIL_HEAD, TAN_REPOSE

#: Barycentric slack of the rasterisation: a vertex on an edge shared by two triangles is
#: covered by both, whatever the rounding.
EDGE_SLACK = 1e-12
#: Relaxation work per update at most, in sweeps of the update's boxes (one per intruder,
#: around where it is and where it was at the last update, and the box left unrelaxed): the
#: pair visits of this many sweeps; what is left continues at the next update (counted in
#: "unrelaxed"). A pile's excess travels down its slope diffusively, so a growing berm would
#: take ~its width squared in sweeps to settle exactly at every step; the budget bounds a step's
#: cost and lets the slope settle over the next steps.
MAX_SWEEPS = 16
#: A neighbouring pair may be steeper than the repose slope by this fraction of its rise (or by
#: SLOPE_SLACK if that is more) before material moves; it then moves until the pair is at the
#: repose slope. 1 % of tan(repose), 0.2 deg at 23 deg: inside the scatter of measured angles
#: of repose (+-1 deg and more between tests of one medium). A fraction of the slope, so the
#: relaxation stops at the same angle on every cell; it sets how far a small excess travels down
#: a slope standing at repose, and with it the relaxation's work (the walking hexapod at a 2 mm
#: cell: 67,000 pair visits per update, against 127,000 with a 1 um slack alone).
SLOPE_TOLERANCE = 0.01
#: The least excess [m] that moves material (1 um: a thousandth of a 1 mm grain; rounding must
#: not keep a pair moving).
SLOPE_SLACK = 1e-6
#: Largest grid accepted (vertices): its soil block then takes 4 x 8 bytes per vertex per MjData.
MAX_VERTICES = 2_000_000
#: deform_cell = "auto" puts this many cells across the narrowest intruder (the smallest extent
#: of its bounding box, which resolves its thinnest side as it cuts): a 5 x 5 x 1 cm plate's
#: rest depth is then within 0.8 % of the cell-free estimate, the Go2's feet depth within
#: 1.3 % of a cell half as large
#: (``python benchmarks/deform_convergence.py``; docs/terrain.md).
CELLS_ACROSS = 10
#: Work counters: updates, volume excavated [m^3], volume that found no rim [m^3], updates whose
#: relaxation hit MAX_SWEEPS, triangles rasterised, footprint vertices at the edge ring, pairs of
#: neighbouring vertices the relaxation compared (its work).
N_SOIL_STATS = 7
SOIL_STATS = ("updates", "excavated", "unplaced", "unrelaxed", "rasterised", "edge", "visits")
#: Default angle of repose [deg] per material preset, the relaxation's limit slope. Smooth
#: spherical glass beads pile at 20-26 deg (e.g. Zhou et al., Phys. Rev. E 64:021301 (2001),
#: monosized spheres, experiment and DEM; review: Al-Hashemi & Al-Amoudi, Powder Technology
#: 330:397 (2018)); 23 deg is used for the paper's 0.8 mm beads. For poppy seeds and the generic
#: medium no measured value is at hand: 30 deg, typical of dry sands and rounded seeds in the
#: same review. Set mjrft:repose from a tilted-bed or poured-pile test of your own medium.
REPOSE_DEG = {"glass_beads": 23.0, "poppy_seeds_lp": 30.0, "poppy_seeds_cp": 30.0}
DEFAULT_REPOSE_DEG = 30.0


def repose_of(material_name: str) -> float:
    """The default angle of repose [deg] of a material by name (REPOSE_DEG, else 30)."""
    return REPOSE_DEG.get(material_name, DEFAULT_REPOSE_DEG)


def grid_shape(region: np.ndarray, cell: float) -> tuple[int, int]:
    """(nrow, ncol) of the grid with vertices every cell [m] covering region's (2, 3) x-y."""
    lo, hi = region[0, :2], region[1, :2]
    ncol = int(math.ceil((hi[0] - lo[0]) / cell - 1e-9)) + 1  # noqa: RUF046
    nrow = int(math.ceil((hi[1] - lo[1]) / cell - 1e-9)) + 1  # noqa: RUF046
    return nrow, ncol


def auto_cell(widths) -> float:
    """The cell [m] that puts CELLS_ACROSS cells across the narrowest of the intruders' widths
    [m] (deform_cell = "auto")."""
    return float(min(widths)) / CELLS_ACROSS


def fit_cell(region: np.ndarray, cell: float) -> float:
    """cell [m], or the least multiple of it by a power of 1.05 whose grid over the region's
    (2, 3) horizontal extent has at most MAX_VERTICES vertices."""
    while math.prod(grid_shape(region, cell)) > MAX_VERTICES:
        cell *= 1.05
    return cell


def grid_over(
    initial: surface.Surface,
    region: np.ndarray,
    cell: float,
    repose_deg: float,
    every: int = 1,
    travel: float = 0.0,
) -> surface.Surface:
    """A SOIL surface with vertices every `cell` [m] over the region's (2, 3) horizontal extent,
    starting as `initial` (sampled at the vertices) with angle of repose repose_deg [deg],
    following the intruders every `every` steps, or (every 0) once they may have travelled
    `travel` cells since it last did (engine/deform.h, Due)."""
    lo = region[0, :2]
    nrow, ncol = grid_shape(region, cell)
    x = lo[0] + cell * np.arange(ncol)
    y = lo[1] + cell * np.arange(nrow)
    heights = initial.height(*np.meshgrid(x, y))
    out = surface.grid(heights, float(lo[0]), float(lo[1]), cell, cell)
    prm = out.prm.copy()
    prm[surface.KIND] = surface.SOIL
    prm[TAN_REPOSE] = math.tan(math.radians(repose_deg))
    prm[surface.EVERY] = every
    prm[surface.TRAVEL] = travel
    return surface.Surface(prm, out.grid)


def block_views(prm: np.ndarray, block: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Views (nrow, ncol) of a soil block's offsets of h and c [m] and its memory p [m]."""
    nrow, ncol = int(prm[NROW]), int(prm[NCOL])
    n = nrow * ncol
    return tuple(block[SOIL_HEAD + q * n : SOIL_HEAD + (q + 1) * n].reshape(nrow, ncol)
                 for q in range(3))  # fmt: skip


__all__ = [
    "DEFAULT_REPOSE_DEG",
    "MAX_SWEEPS",
    "MAX_VERTICES",
    "N_SOIL_STATS",
    "REPOSE_DEG",
    "SLOPE_SLACK",
    "SLOPE_TOLERANCE",
    "SOIL_STATS",
    "block_views",
    "grid_over",
    "grid_shape",
    "repose_of",
]
