"""The field's state for one MjData: the arrays of ``tables.FieldData`` and their entry record.

A ``DataState`` belongs to the MjData it was made for (the field keys them by MjData, see
``GranularField``): per-pass work arrays, element forces, the ``xfrc_applied`` ownership record,
the RK4 stage record and the counters all live here, so two threads stepping two MjData of one
field share nothing but the static tables and the field's report arrays.
"""

from __future__ import annotations

import threading
import weakref

import mujoco
import numpy as np

from mjrft.core.soil import N_SOIL_STATS
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
    arena,
    pack,
)


def _mjdata_arrays(data: mujoco.MjData | None, fm, na: int) -> tuple:
    """MjDataArrays views of data (with the address of data.time), or zero stand-ins."""
    nbody, ngeom, nv = fm.nbody, fm.ngeom, fm.nv
    if data is None:  # a batch thread's state: the batch passes each copy's arrays itself
        arrays = MjDataArrays(
            *(np.zeros((nbody, 3)), np.zeros((nbody, 3, 3)), np.zeros((nbody, 3))),
            *(np.zeros((nbody, 3, 3)), np.zeros((nbody, 6)), np.zeros((nbody, 3))),
            np.zeros((ngeom, 3)), np.zeros(1), np.zeros((nbody, 6)),
            np.zeros(fm.nC), np.zeros(nv), np.zeros(nv), np.zeros((nv, 6)),
            np.zeros(fm.nu), np.zeros(max(1, na)), np.zeros(fm.nu), np.zeros(fm.nu),
            np.zeros(fm.nu), np.zeros(fm.nJmom), np.zeros(fm.nu, np.int32),
            np.zeros(fm.nu, np.int32), np.zeros(fm.nJmom, np.int32), np.zeros(fm.nsoil),
        )  # fmt: skip
        return arrays, arrays.time.ctypes.data
    userdata = soil_block(data, fm.nsoil) if fm.soil else np.zeros(1)
    arrays = MjDataArrays(
        data.xpos, data.xmat.reshape(nbody, 3, 3), data.xipos, data.ximat.reshape(nbody, 3, 3),
        data.cvel, data.subtree_com, data.geom_xpos, np.zeros(1), data.xfrc_applied,
        data.M, data.qvel, data.qacc, data.cdof, data.ctrl, data.act, data.actuator_length,
        data.actuator_velocity, data.actuator_force, data.actuator_moment, data.moment_rownnz,
        data.moment_rowadr, data.moment_colind, userdata,
    )  # fmt: skip
    return arrays, layout.time_address(data)


def soil_block(data: mujoco.MjData, nsoil: int) -> np.ndarray:
    """The soil block of a deforming surface: a view of the last nsoil entries of userdata."""
    return data.userdata[data.userdata.shape[0] - nsoil :]


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
        self.finalizer: weakref.finalize | None = None
        na = int(tables.model.na)
        self.mjdata, time_address = _mjdata_arrays(data, fm, na)
        nv = fm.nv
        soil_shape = fm.surface_grid.shape if fm.soil else (1, 1)
        f8, i8 = np.float64, np.int64
        small = arena({  # touched every pass: side by side (tables.arena)
            "status": ((1,), i8, 0), "cull": ((ng,), i8, 0), "keep": ((nk,), i8, 0),
            "frz": ((nk,), i8, 0), "slow": ((nk,), i8, 0), "geom_dirty": ((ng,), i8, 1),
            "decision": ((nk,), i8, 0), "stats": ((N_STATS,), i8, 0),
            "wrench": ((nb, 6), f8, 0), "user": ((nb, 6), f8, 0), "written": ((nb, 6), f8, 0),
            "user_in": ((nb, 6), f8, 0), "frozen": ((nk, 12), f8, 0),
            "rk4": ((RK4_HEAD + RK4_BODY * nk,), f8, 0),
            "mech_tau": ((nv,), f8, 0), "mech_time": ((3,), f8, 0),
            "mech_prev": ((nk, 6), f8, 0), "mech_held": ((nk,), i8, 0),
            "mech_R": ((nk, 6), f8, 0), "mech_key": ((nk, 19), f8, 0),
            "mech_in": ((2, nv), f8, 0), "mech_in_prev": ((nk, 6), f8, 0),
            "mech_in_force": ((fm.nu,), f8, 0),
            "mech_in_held": ((nk,), i8, 0),
        })  # fmt: skip
        self.arrays = FieldData(
            **small,
            elem_force=np.zeros((ne, 3)),
            scratch=np.zeros((ne, 3)),
            ring=np.zeros((ring + 1, 2, nk, 6)),
            report_wrench=report[0],
            report_decision=report[1],
            mech_M=np.zeros((nv, nv)),
            mech_cfg=np.full(1 + nk + 6 * nv + 6 * nk, -1.0),
            mech_hkey=np.full(1 + 6 * nk, -2, dtype=np.int64),
            mech_L=np.zeros((nv, nv)),
            mech_J=np.zeros((6 * nk, nv)),
            mech_X=np.zeros((6 * nk, nv)),
            mech_A=np.zeros((6 * nk, 6 * nk)),
            mech_S=np.zeros((6 * nk, 6 * nk)),
            mech_vec=np.zeros((3, max(nv, 6 * nk))),
            soil_floor=np.full(soil_shape, np.inf),
            soil_owner=np.full(soil_shape, -1, dtype=np.int64),
            soil_queue=np.zeros(soil_shape[0] * soil_shape[1], dtype=np.int64),
            soil_box=np.zeros((nk + 3, 4)),
            soil_stats=np.zeros(N_SOIL_STATS),
        )
        self.entry = pack(ENTRY_RECORD, (self.mjdata, self.arrays), {"nring": ring, "na": na})
        self.entry["time"] = time_address
        #: The soil block (a view of userdata) or, without a deforming ground, its stand-in,
        #: which only this reference keeps alive.
        self.userdata = self.mjdata.userdata
        if data is not None:  # views of an MjData keep it alive: keep only their addresses
            self.mjdata = None

    @property
    def address(self) -> np.uint64:
        """Address of the entry record (``passive.step``'s second argument; uint64)."""
        return np.uint64(self.entry.ctypes.data)

    def data(self) -> mujoco.MjData | None:
        """The MjData, if it is still alive."""
        return None if self.ref is None else self.ref()


class States:
    """The DataStates of one field, keyed by MjData address (made on first sight, forgotten with
    the MjData), and the counters of states let go."""

    def __init__(self, tables: StaticTables, report: tuple[np.ndarray, np.ndarray]) -> None:
        self._tables, self._report = tables, report
        self._lock = threading.RLock()
        self._by_data: dict[int, DataState] = {}
        self._retired = np.zeros(N_STATS, dtype=np.int64)
        self._counted: weakref.WeakSet[DataState] = weakref.WeakSet()  # batch threads' states
        #: Called with (address, state) when a state is let go (the guard forgets it).
        self.on_forget = None

    def of(self, data: mujoco.MjData) -> DataState:
        """The state of an MjData, made on first sight."""
        key = data._address
        st = self._by_data.get(key)
        if st is not None and st.data() is data:
            return st
        st = DataState(self._tables, self._report, data)
        with self._lock:
            old = self._by_data.get(key)
            if old is not None:  # an MjData freed at this address before its finalizer ran
                self.forget(key, old)
            self._by_data[key] = st
        st.finalizer = weakref.finalize(data, self.forget, key, st)
        return st

    def find(self, data: mujoco.MjData) -> DataState | None:
        """The state of an MjData if it has one."""
        st = self._by_data.get(data._address)
        return st if st is not None and st.data() is data else None

    def forget(self, key: int, st: DataState) -> None:
        """Let a state go (its MjData was freed, or the field was uninstalled)."""
        with self._lock:
            if self._by_data.get(key) is not st:
                return
            self._by_data.pop(key)
            self._retired += st.arrays.stats
        if st.finalizer is not None:
            st.finalizer.detach()
        if self.on_forget is not None:
            self.on_forget(key, st)

    def forget_all(self) -> list[DataState]:
        """Let every state go; returns them."""
        states = list(self._by_data.items())
        for key, st in states:
            self.forget(key, st)
        return [st for _, st in states]

    def counted(self) -> DataState:
        """A state without MjData (a batch thread's) whose counters ``stats`` includes."""
        st = DataState(self._tables, self._report, None, ring=1)
        self._counted.add(st)
        weakref.finalize(st, _retire, self._retired, st.arrays.stats)
        return st

    def owned(self) -> list[DataState]:
        """States whose MjData the installed path owns (ownership of xfrc_applied taken)."""
        return [st for st in list(self._by_data.values()) if st.owned]

    def stats(self) -> np.ndarray:
        """(N_STATS,) counters summed over every state, past and present."""
        total = self._retired.copy()
        for st in [*self._by_data.values(), *self._counted]:
            total += st.arrays.stats
        return total


def _retire(total: np.ndarray, stats: np.ndarray) -> None:
    total += stats
