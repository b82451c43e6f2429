"""The field's state for one MjData: the arrays of ``tables.FieldData`` and their entry record.

A ``DataState`` belongs to the MjData it was made for (the field keys them by MjData, see
``GranularField``): per-pass work arrays, element forces, the ``xfrc_applied`` ownership record,
the RK4 stage record and the counters all live here, so two threads stepping two MjData of one
field share nothing but the static tables and the field's report arrays.
"""

from __future__ import annotations

import weakref

import mujoco
import numpy as np

from mjrft.field import layout
from mjrft.field.model import StaticTables
from mjrft.field.ownership import XFRC_HISTORY
from mjrft.field.tables import (
    ENTRY_RECORD,
    N_STATS,
    RK4_BODY,
    RK4_HEAD,
    FieldData,
    MjDataArrays,
    pack,
)


def _mjdata_arrays(data: mujoco.MjData | None, nbody: int, ngeom: int) -> tuple:
    """MjDataArrays views of data (with the address of data.time), or zero stand-ins."""
    if data is None:  # a batch thread's state: the batch passes each copy's arrays itself
        arrays = MjDataArrays(
            *(np.zeros((nbody, 3)), np.zeros((nbody, 3, 3)), np.zeros((nbody, 3))),
            *(np.zeros((nbody, 3, 3)), np.zeros((nbody, 6)), np.zeros((nbody, 3))),
            np.zeros((ngeom, 3)), np.zeros(1), np.zeros((nbody, 6)),
        )  # fmt: skip
        return arrays, arrays.time.ctypes.data
    arrays = MjDataArrays(
        data.xpos, data.xmat.reshape(nbody, 3, 3), data.xipos, data.ximat.reshape(nbody, 3, 3),
        data.cvel, data.subtree_com, data.geom_xpos, np.zeros(1), data.xfrc_applied,
    )  # fmt: skip
    return arrays, layout.time_address(data)


class DataState:
    """The field's state for one MjData (or a batch thread's, if data is None).

    Attributes:
      arrays: the ``tables.FieldData`` arrays (wrenches world frame, torque about the CoM).
      ref: weak reference to the MjData (None for a batch thread's state); the entry record
        holds the addresses of its arrays, the state holds no reference that keeps it alive.
      owned: True once the installed path took ownership of the MjData's xfrc_applied rows.
      registered: True while the native guard runs the pass on this MjData.
    """

    def __init__(
        self,
        tables: StaticTables,
        report: tuple[np.ndarray, np.ndarray],
        data: mujoco.MjData | None = None,
        ring: int = XFRC_HISTORY,
    ) -> None:
        fm = tables.arrays
        nb, ne = fm.nbody, len(fm.elem_area)
        ng, nk = len(fm.tgeom_geomid), len(fm.tbody_bodyid)
        self.ref = None if data is None else weakref.ref(data)
        self.owned = False
        self.registered = False
        self.mjdata, time_address = _mjdata_arrays(data, nb, fm.ngeom)
        i64 = lambda *shape: np.zeros(shape, dtype=np.int64)  # noqa: E731
        self.arrays = FieldData(
            user=np.zeros((nb, 6)), written=np.zeros((nb, 6)), user_in=np.zeros((nb, 6)),
            wrench=np.zeros((nb, 6)), elem_force=np.zeros((ne, 3)), scratch=np.zeros((ne, 3)),
            rk4=np.zeros(RK4_HEAD + RK4_BODY * nk), geom_dirty=np.ones(ng, dtype=np.int64),
            cull=i64(ng), keep=i64(nk), frz=i64(nk), slow=i64(nk), frozen=np.zeros((nk, 12)),
            decision=i64(nk), stats=i64(N_STATS), status=i64(1),
            ring=np.zeros((ring + 1, 2, nk, 6)), report_wrench=report[0],
            report_decision=report[1],
        )  # fmt: skip
        self.entry = pack(ENTRY_RECORD, (self.mjdata, self.arrays), {"nring": ring})
        self.entry["time"] = time_address
        if data is not None:  # views of an MjData keep it alive: keep only their addresses
            self.mjdata = None

    @property
    def address(self) -> np.uint64:
        """Address of the entry record (``passive.step``'s second argument; uint64)."""
        return np.uint64(self.entry.ctypes.data)

    def data(self) -> mujoco.MjData | None:
        """The MjData, if it is still alive."""
        return None if self.ref is None else self.ref()
