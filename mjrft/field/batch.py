"""Many copies of one granular scene stepped together on MuJoCo's threaded batch.

``mujoco.batch.Batch`` steps many simulations of one model on a thread pool and refuses Python
callbacks, so here the granular forces enter the way the design card describes for batches:
through ``xfrc_applied`` between steps. Each substep: one native call computes the RFT wrenches of
every copy from the bound position- and velocity-stage fields (``mjrft.field.passive.batch``),
``xfrc_applied = user + RFT`` is written, and the batch steps with ``stage=mjSTAGE_VEL``, which
leaves those fields current at the new state (a persistent batch then continues from them, so
this costs no extra forward pass). The RFT pass runs on ``nthread`` Python threads over disjoint
sets of copies (the native call releases the GIL), between MuJoCo's batch steps, so the two
never compete for cores. Each copy gets the field's one compiled pass in its explicit form
(``mjrft.field.passive``: the force is evaluated at the state at the start of the substep and
held over it), so a batch gives the same trajectories as ``GranularField.wrench`` on single
MjData, bit for bit (tests/test_batch.py).
"""

from __future__ import annotations

import itertools
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import mujoco
import numpy as np
from mujoco.batch import Batch

from mjrft.field import passive
from mjrft.field.granular_field import GranularField

#: Fewest copies per RFT thread (below it, fewer threads).
_MIN_COPIES_PER_THREAD = 4


class BatchedField:
    """A GranularField applied to ``nsim`` simulations of its model on ``nthread`` threads.

    Args:
      field: the field (its model is the batch's model; Fourier-form materials only).
      nsim: number of simulations (copies); they may differ in state and controls.
      nthread: threads for MuJoCo's batch and for the RFT pass (default: all cores).
    Attributes:
      batch: the underlying ``mujoco.batch.Batch``: set initial states and controls through it
        (``batch.qpos``, ``batch.ctrl``, ``batch.reset(key=...)``).
      user_xfrc: (nsim, nbody, 6) your own applied forces [N, N m], world frame, at each body's
        CoM; the RFT wrench is added to it every substep (``xfrc_applied`` itself is rewritten).
      wrench: (nsim, nbody, 6) RFT wrenches of the last substep.
    """

    _DERIVED = ("xpos", "xmat", "xipos", "ximat", "cvel", "subtree_com", "geom_xpos")

    def __init__(self, field: GranularField, nsim: int, nthread: int | None = None) -> None:
        if not field._native:
            raise ValueError(
                f"material {field.material.name!r} is given by Python callables; batched "
                "stepping needs a Fourier-form material (a preset, a table, or zeta)"
            )
        if nsim < 1:
            raise ValueError(f"nsim must be >= 1, got {nsim}")
        self.field = field
        self.model = field.model
        kw = {} if nthread is None else {"nthread": nthread}
        self.batch = Batch(self.model, nsim=nsim, persistent=True, **kw)
        self._arrays = {name: self.batch.bind(name) for name in self._DERIVED}
        self._xfrc = self.batch.bind("xfrc_applied")
        self._time = self.batch.bind("time")
        self._userdata = self.batch.bind("userdata")
        self._user = np.zeros_like(self._xfrc)
        self._wrench = np.zeros_like(self._xfrc)
        # RFT threads: at least _MIN_COPIES_PER_THREAD copies each (a hand-off costs ~20 us).
        n_rft = max(1, min(nthread or os.cpu_count() or 1, nsim // _MIN_COPIES_PER_THREAD))
        bounds = np.linspace(0, nsim, n_rft + 1).round().astype(int)
        # Each RFT thread has its own state (work arrays, counters in the field's stats); each
        # copy an entry record pointing at its rows of the batch's arrays.
        self._states = [field._counted_state() for _ in range(n_rft)]
        self._entries = [
            self._copy_entries(st, range(lo, hi))
            for st, (lo, hi) in zip(self._states, itertools.pairwise(bounds.tolist()), strict=True)
        ]
        self._jobs = [
            (field._tables.address, np.uint64(e.ctypes.data), len(e), passive.BATCH)
            for e in self._entries
        ]
        self._starts = bounds[:-1].tolist()
        self._stepping = threading.Lock()
        self._pool = ThreadPoolExecutor(n_rft - 1) if n_rft > 1 else None

    def _copy_entries(self, st, sims: range) -> np.ndarray:
        """Entry records of copies sims: their rows of the bound arrays, their user wrenches
        and output rows, and the thread state st's work arrays."""
        out = np.repeat(st.entry, len(sims))
        rows = {**self._arrays, "user_in": self._user, "wrench": self._wrench}
        nsoil = self.field._tables.arrays.nsoil
        for i, sim in enumerate(sims):
            views = {name: arr[sim] for name, arr in rows.items()}
            if self.field.deforms:  # each copy's ground: its userdata, stamped with its time
                views["time"] = self._time[sim : sim + 1]
                views["userdata"] = self._userdata[sim, self._userdata.shape[1] - nsoil :]
            for name, view in views.items():
                if not view.flags.c_contiguous:  # the entry describes each copy's rows
                    raise RuntimeError(f"mujoco.batch's {name} rows are not contiguous")
                out[name][i] = view.ctypes.data
        return out

    @property
    def user_xfrc(self) -> np.ndarray:
        """(nsim, nbody, 6) your applied wrenches [N, N m], world frame, at each body's CoM;
        write in place or assign (assignment copies into the same array)."""
        return self._user

    @user_xfrc.setter
    def user_xfrc(self, value: np.ndarray) -> None:
        self._user[...] = value

    @property
    def wrench(self) -> np.ndarray:
        """(nsim, nbody, 6) RFT wrenches of the last substep [N, N m] (read only: rewritten)."""
        return self._wrench

    @property
    def nsim(self) -> int:
        """Number of simulations."""
        return self.batch.nsim

    def reset(self, keyframe: int | np.ndarray = -1) -> None:
        """Reset every simulation (to a keyframe, one each, or -1: model defaults)."""
        self.batch.reset(keyframe=keyframe)

    def forward(self) -> None:
        """Make the derived fields current after you write states (qpos, qvel, act) directly."""
        self.batch.forward(stage=mujoco.mjtStage.mjSTAGE_VEL.value)

    def step(self, nstep: int = 1) -> None:
        """Advance every simulation by nstep substeps with granular forces acting in each.

        The derived fields must describe the current states: they do after ``reset``, ``step``
        and ``forward``; call ``forward`` after writing states yourself. One thread at a time
        (the batch's work arrays are shared by its copies): a second concurrent call raises
        RuntimeError.
        """
        if not self._stepping.acquire(blocking=False):
            raise RuntimeError(
                "BatchedField.step is already running in another thread; a batch steps from one "
                "thread at a time (make one BatchedField per thread)"
            )
        try:
            self._step(nstep)
        finally:
            self._stepping.release()

    def _step(self, nstep: int) -> None:
        vel = mujoco.mjtStage.mjSTAGE_VEL.value
        for _ in range(nstep):
            if self._pool is None:
                status = [self._rft(0)]
            else:  # the last slice on this thread, the others on the pool
                jobs = [self._pool.submit(self._rft, k) for k in range(len(self._jobs) - 1)]
                status = [self._rft(len(self._jobs) - 1)]
                status = [j.result() for j in jobs] + status
            bad = [st for st in status if st is not None]
            if bad:
                sim = min(bad)
                raise FloatingPointError(
                    f"simulation {sim} of the batch has a non-finite intruding-body state (or "
                    "an intruder below the deforming ground) at "
                    f"time {float(self.batch.bind('time')[sim]):.6g} s; the granular field "
                    "refuses to feed NaN forward"
                )
            np.add(self._user, self._wrench, out=self._xfrc)
            self.batch.step(stage=vel)

    def _rft(self, k: int) -> int | None:
        """RFT wrenches of the copies of job k; the first bad copy's index or None."""
        status = passive.batch(*self._jobs[k])
        return None if status == passive.OK else self._starts[k] + (-1 - status)

    def close(self) -> None:
        """Stop the RFT threads (also done when the object is garbage collected)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __del__(self) -> None:
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.shutdown(wait=False)


def single_step_reference(
    field: GranularField, data: mujoco.MjData, user: np.ndarray | None = None
) -> None:
    """The single-MjData explicit path a BatchedField substep reproduces (for tests/benchmarks).

    mj_forward; xfrc_applied = user + field.wrench(data); mj_step.
    """
    mujoco.mj_forward(field.model, data)
    u = np.zeros((field.model.nbody, 6)) if user is None else user
    data.xfrc_applied[:] = u + field.wrench(data, user_xfrc=u)
    mujoco.mj_step(field.model, data)
