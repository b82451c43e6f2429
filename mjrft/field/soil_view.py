"""Python's view of one MjData's deforming ground: read and write its grid (``mjrft.core.soil``).

The state lives in the MjData's ``userdata`` (the last ``surface.soil_block`` entries), so it is
copied by ``copy.copy(data)`` / ``mj_copyData``, saved by ``mj_getState(...,
mjSTATE_USERDATA)`` (part of ``mjSTATE_INTEGRATION``), and reset by ``mj_resetData``; this view
reads and writes it in place.
"""

from __future__ import annotations

import numpy as np

from mjrft.core import soil, surface
from mjrft.core.surface import Surface


class Soil:
    """The ground of one MjData: vertex heights, compacted levels and memory, world frame [m].

    Vertex (r, c) lies at (x[c], y[r]); it stands for the column of one cell (dx dy) around it.
    """

    def __init__(self, ground: Surface, block: np.ndarray, counters: np.ndarray) -> None:
        self._ground, self._block = ground, block
        self._dh, self._dc, self._p = soil.block_views(ground.prm, block)
        self._counters = counters

    @property
    def counters(self) -> dict[str, float]:
        """Work of this MjData's updates so far (``mjrft.core.soil.SOIL_STATS``): updates,
        excavated and unplaced volume [m^3], updates whose relaxation spent its budget before
        repose ("unrelaxed"), triangles rasterised, footprint vertices on the grid's edge ring,
        pairs of neighbouring vertices the relaxation compared ("visits")."""
        return {k: float(v) for k, v in zip(soil.SOIL_STATS, self._counters, strict=True)}

    @property
    def relaxed(self) -> bool:
        """True if the last update left no slope steeper than the angle of repose (its
        relaxation ended within its work budget; the next update goes on where it stopped)."""
        r0, r1, c0, c1 = self._block[surface.SOIL_PENDING : surface.SOIL_PENDING + 4]
        return not (r1 > r0 and c1 > c0)

    @property
    def tan_repose(self) -> float:
        """Tangent of the angle of repose: the steepest slope relaxation leaves."""
        return float(self._ground.prm[surface.TAN_REPOSE])

    @property
    def x(self) -> np.ndarray:
        """(ncol,) vertex x [m], world frame."""
        prm = self._ground.prm
        return prm[surface.X0] + prm[surface.DX] * np.arange(int(prm[surface.NCOL]))

    @property
    def y(self) -> np.ndarray:
        """(nrow,) vertex y [m], world frame."""
        prm = self._ground.prm
        return prm[surface.Y0] + prm[surface.DY] * np.arange(int(prm[surface.NROW]))

    @property
    def cell(self) -> float:
        """Spacing [m] of the vertices (the same along x and y)."""
        return float(self._ground.prm[surface.DX])

    @property
    def cell_area(self) -> float:
        """Area [m^2] each vertex's column stands for."""
        return float(self._ground.prm[surface.DX] * self._ground.prm[surface.DY])

    @property
    def initial(self) -> np.ndarray:
        """(nrow, ncol) initial surface heights [m] (what ``reset`` restores)."""
        return self._ground.grid.copy()

    @property
    def height(self) -> np.ndarray:
        """(nrow, ncol) surface heights h [m] (a copy; write with ``set_height``)."""
        return self._ground.grid + self._dh

    @property
    def compacted(self) -> np.ndarray:
        """(nrow, ncol) compacted levels c <= h [m]: below c the medium resists as at the
        depth (h + memory) - z (a copy)."""
        return self._ground.grid + self._dc

    @property
    def memory(self) -> np.ndarray:
        """(nrow, ncol) memory depths p >= 0 [m] of the compacted columns (a copy)."""
        return self._p.copy()

    def set_height(self, height: np.ndarray) -> None:
        """Give the ground new surface heights (nrow, ncol) [m], pristine there (no memory)."""
        h = np.asarray(height, dtype=np.float64)
        if h.shape != self._dh.shape or not np.all(np.isfinite(h)):
            raise ValueError(
                f"set_height needs finite heights of shape {self._dh.shape}, got "
                f"{'non-finite values' if h.shape == self._dh.shape else h.shape}"
            )
        self._dh[:] = h - self._ground.grid
        self._dc[:] = self._dh
        self._p[:] = 0.0
        n = self._dh.size  # no intruder pressed on the new ground (the press marks)
        self._block[surface.SOIL_HEAD + 3 * n : surface.SOIL_HEAD + 4 * n] = 0.0
        prm = self._ground.prm
        self._block[surface.SOIL_ZOFF] = max(0.0, float(h.max()) - prm[surface.ZMAX])
        # Relax everything at the next update: the new heights may be steeper than repose.
        box = (1, h.shape[0] - 1, 1, h.shape[1] - 1)  # head boxes: r0, r1 + 1, c0, c1 + 1
        self._block[surface.SOIL_PENDING : surface.SOIL_PENDING + 4] = box

    def reset(self) -> None:
        """Restore the initial surface (what ``mj_resetData`` also does)."""
        self._block[:] = 0.0

    def volume(self) -> float:
        """Volume [m^3] of the medium above the initial surface: cell area times the sum of the
        height offsets (every update conserves it: 0 for a ground that only deformed)."""
        return self.cell_area * float(self._dh.sum())

    def height_at(self, x, y) -> np.ndarray:
        """Surface height [m] at horizontal positions x, y [m] (arrays of one shape; world)."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        out = np.empty(x.shape)
        g = self._ground
        surface._heights(g.prm, g.grid, self._block, x.ravel(), y.ravel(), out.reshape(-1))
        return out

    def snapshot(self) -> Surface:
        """The current surface as a static height grid (``mjrft.core.surface.grid``)."""
        prm = self._ground.prm
        return surface.grid(
            self.height, prm[surface.X0], prm[surface.Y0], prm[surface.DX], prm[surface.DY]
        )
