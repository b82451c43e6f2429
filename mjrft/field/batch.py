"""Many copies of one granular scene stepped together on MuJoCo's threaded batch.

A model from ``mjrft.load_model`` carries the engine plugin ``mjrft.granular``, and
``mujoco.batch.Batch`` runs a model's engine plugins inside each copy's ``mj_step``, with each
copy's engine state in its own ``plugin_state`` (part of the batch's state rows). So the medium
acts in a batch of such a model with nothing added: ``BatchedField`` steps ``nsim`` copies of the
plugin model on MuJoCo's threads, and each copy gets exactly what ``mj_step`` gives one MjData
stepped alone from the same MjData (the installed pass: low-speed treatment, RK4 stage rule,
deforming ground), bit for bit, at any thread count (tests/test_batch.py). On top of a bare
``Batch`` it keeps the user's applied forces apart from the field's (``user_xfrc``), reads every
copy's engine state (``wrench``, ``stats``, ``state_array``, ``soil``), and keeps each step a
full ``mj_step`` of every copy.

What a script written for the explicit scheme (the field evaluated by ``GranularField.wrench``
at the start of each substep and held over it, ``xfrc_applied = user + wrench``) finds here:

* the physics is the plugin's, that of ``mj_step`` on single MjData: under Euler and the
  implicit integrators it agrees with the explicit scheme to round-off; under RK4 the later
  stages follow the engine's stage rule instead of holding the first stage's wrench;
* ``nthread`` is the batch's thread count only: the field runs inside MuJoCo's step, on
  MuJoCo's threads;
* ``forward`` is needed only to read derived fields (or ``wrench``) of states you wrote:
  ``step`` is a full ``mj_step`` from the state rows;
* derived fields bound through ``batch`` describe the state before the last substep, as after
  ``mj_step``;
* a failing copy (a non-finite state, an intruder below the deforming ground) raises
  ``mujoco.batch.SimulationError`` (a RuntimeError) naming the copies and the engine's message
  (body and time); those copies keep the state they had before the call;
* a medium given by Python callables runs as the engine's table of it (docs/materials.md);
* ``user_xfrc`` is written into the copies' ``xfrc_applied`` at every ``step``, which the
  engine keeps as the user's part (its protocol for any MjData: ``GranularField.user_xfrc``).

The copies keep one MjData each (``Batch(persistent=True)``): the engine keeps work arrays in
the MjData's ``plugin_data`` from one pass to the next (the mechanism treatment's caches), which
are not in the state rows, so copies sharing MjData (a plain batch) would not step as alone.
"""

from __future__ import annotations

import ctypes
import threading

import mujoco
import numpy as np
from mujoco.batch import Batch

from mjrft.field import plugin
from mjrft.field.granular_field import STATS, GranularField
from mjrft.field.soil_view import Soil

_NONE = mujoco.mjtStage.mjSTAGE_NONE.value


class BatchedField:
    """``nsim`` simulations of a GranularField's model (which carries the engine plugin) on
    MuJoCo's threaded batch.

    Args:
      field: the field (``GranularField(mjrft.load_model(...))``); its model is the batch's.
      nsim: number of simulations (copies); they may differ in state and controls.
      nthread: threads of MuJoCo's batch (default: all cores).
    Attributes:
      batch: the underlying ``mujoco.batch.Batch``: set initial states and controls through it
        (``batch.qpos``, ``batch.ctrl``, ``batch.bind(name)``); its ``xfrc_applied`` is written
        from ``user_xfrc`` at every ``step``.
      field, model: the field and its model.
    """

    def __init__(self, field: GranularField, nsim: int, nthread: int | None = None) -> None:
        if nsim < 1:
            raise ValueError(f"nsim must be >= 1, got {nsim}")
        self.field = field
        self.model = field.model
        self.batch = Batch(self.model, nsim=nsim, nthread=nthread or 0, persistent=True)
        self._xfrc = self.batch.bind("xfrc_applied")
        self._plugin_state = self.batch.bind("plugin_state")
        self._user = np.zeros_like(self._xfrc)
        self._offsets = _persistent_offsets(self.model)
        wrench = self.state_array("wrench").reshape(nsim, self.model.nbody, 6)
        wrench.flags.writeable = False
        self._wrench = wrench
        self._stepping = threading.Lock()

    # ------------------------------------------------------------------ inputs and outputs
    @property
    def user_xfrc(self) -> np.ndarray:
        """(nsim, nbody, 6) your applied wrenches [N, N m], world frame, at each body's CoM,
        written into each copy's ``xfrc_applied`` at every ``step`` (the engine adds the field's
        wrench to the tagged rows inside the step); write in place or assign (assignment copies
        into the same array)."""
        return self._user

    @user_xfrc.setter
    def user_xfrc(self, value: np.ndarray) -> None:
        self._user[...] = value

    @property
    def wrench(self) -> np.ndarray:
        """(nsim, nbody, 6) each copy's RFT wrench of its most recent pass (inside the last
        substep, or ``forward``), world frame, torque about each CoM [N, N m]: a read-only view
        of the engine's ``wrench`` in the copies' ``plugin_state`` (``GranularField.wrench_of``
        of each copy)."""
        return self._wrench

    @property
    def stats(self) -> dict[str, int]:
        """The engine's work counters (``GranularField.stats_of``) summed over the copies, since
        each was last reset."""
        counts = self.state_array("stats").sum(axis=0)
        return dict(zip(STATS, (int(x) for x in counts), strict=True))

    def state_array(self, name: str) -> np.ndarray:
        """(nsim, size) view of the engine's persistent array `name` (engine/fields.h) in every
        copy's ``plugin_state`` (int64 for the engine's i64 arrays); a write is the copy's state
        at its next step. The engine's work arrays live outside the state rows: read them with
        ``GranularField.state_array`` on ``batch.get_data(sim)``."""
        if name not in self._offsets:
            persistent = ", ".join(self._offsets)
            raise KeyError(
                f"{name!r} is not one of the engine's persistent arrays (the ones in each copy's "
                f"plugin_state): {persistent}"
            )
        start, size, dtype = self._offsets[name]
        view = self._plugin_state[:, start : start + size]
        return view.view(np.int64) if dtype is np.int64 else view

    def soil(self, sim: int) -> Soil:
        """The deforming ground of copy sim (read and write; ``mjrft.field.soil_view``)."""
        if not self.field.deforms:
            raise ValueError(
                "this field's ground does not deform: add <numeric name='mjrft:deform_cell' "
                "data='0.002'/> (and mjrft:region) or load the model with deform_cell="
            )
        return Soil(
            self.field.scene.surface, self.state_array("soil")[sim],
            self.state_array("soil_stats")[sim],
        )  # fmt: skip

    @property
    def nsim(self) -> int:
        """Number of simulations."""
        return self.batch.nsim

    # ------------------------------------------------------------------ stepping
    def reset(self, keyframe: int | np.ndarray = -1) -> None:
        """Reset every simulation (to a keyframe, one each, or -1: model defaults), engine state
        included, then ``mj_forward`` each (as ``forward``)."""
        self.batch.reset(keyframe=keyframe)
        self._afresh()

    def forward(self) -> None:
        """``mj_forward`` on every copy: derived fields and the engine's pass (``wrench``) of the
        states you wrote (qpos, qvel, act). Stepping does not need it."""
        self.batch.forward()
        self._afresh()

    def _afresh(self) -> None:
        # A persistent batch would continue its next step from the stages just computed,
        # reusing the engine's pass (velocity stage), which read xfrc_applied before step()
        # wrote user_xfrc there: that step would lose the field's wrench. Marking no stage
        # computed makes every step a full mj_step.
        self.batch.forward(stage=_NONE)

    def step(self, nstep: int = 1) -> None:
        """Advance every simulation by nstep calls to ``mj_step``, with ``xfrc_applied`` set to
        ``user_xfrc`` before the first.

        One thread at a time (the batch reports failures through state that the next call
        overwrites): a second concurrent call raises RuntimeError. A copy MuJoCo or the engine
        fails in raises ``mujoco.batch.SimulationError`` naming it; the others ran to completion.
        """
        if not self._stepping.acquire(blocking=False):
            raise RuntimeError(
                "BatchedField.step is already running in another thread; a batch steps from one "
                "thread at a time (make one BatchedField per thread)"
            )
        try:
            self._xfrc[...] = self._user
            self.batch.step(nstep=nstep)
        finally:
            self._stepping.release()

    def close(self) -> None:
        """Release the batch (one MjData per copy) and the views into it; the object cannot
        step afterwards."""
        for name in ("batch", "_xfrc", "_plugin_state", "_wrench"):
            self.__dict__.pop(name, None)


def _persistent_offsets(model: mujoco.MjModel) -> dict[str, tuple[int, int, type]]:
    """Name -> (start, size, dtype) of each engine array that lives in ``plugin_state``: the
    same in every MjData of model (read from a probe MjData)."""
    lib, instance = plugin.library(), plugin.instance(model)
    probe = mujoco.MjData(model)
    m, d = ctypes.c_void_p(model._address), ctypes.c_void_p(probe._address)
    base, out = probe.plugin_state, {}
    for kind, name in plugin.layout().state:
        address = lib.mjrft_state_array(m, d, instance, name.encode())
        size = lib.mjrft_state_size(m, d, instance, name.encode())
        start = (address - base.ctypes.data) // base.itemsize if address else -1
        if 0 <= start and start + size <= base.shape[0]:
            out[name] = (start, size, np.int64 if kind == "i64" else np.float64)
    return out


def single_step_reference(
    field: GranularField, data: mujoco.MjData, user: np.ndarray | None = None
) -> None:
    """The single-MjData step that a BatchedField substep equals (for tests and benchmarks):
    ``xfrc_applied = user`` (zeros if None), then ``mj_step``."""
    data.xfrc_applied[:] = 0.0 if user is None else user
    mujoco.mj_step(field.model, data)
