"""A dm_control ``Physics`` whose every forward pass includes the granular RFT field.

``GranularPhysics`` owns a :class:`mjrft.GranularField` for its compiled model and keeps it
*installed* for as long as the physics lives (``free()``, ``close()`` or garbage collection end
it). Installing once, rather than around each ``step()``, matters because of dm_control's split
stepping (``legacy_step=True``, the default of ``control.Environment``): ``Physics.step`` runs
``mj_step2`` on forces computed by the *previous* call's ``mj_step1``, and ``mj_step1`` is where
MuJoCo's passive callback (the field) writes the RFT wrench into ``xfrc_applied``. A field
uninstalled between two ``step()`` calls would restore the user's ``xfrc_applied`` rows in
between, and the first substep of every control step would lose its RFT force. Installed for the
physics' lifetime, RFT acts in every substep and in every ``forward()`` (resets, rendering).

Why this is safe:

* model compilation elsewhere in the process is unaffected (mjrft's native callback guard
  forwards only models with an installed field; README "Callback safety");
* two environments (two models) in one process have two independent fields; physics copies that
  share one model (``copy(share_model=True)``) share its field, reference-counted.

Per substep the physics also accumulates the mechanical work of every actuator,
``|actuator_force * actuator_velocity| * dt`` [J] (no regeneration: negative work costs too),
and counts substeps; tasks read and reset these with :meth:`GranularPhysics.take_work`.

Do not assign ``xfrc_applied`` rows of intruding bodies between ``mj_step1`` and ``mj_step2``
(e.g. in a Task's ``before_step`` under legacy stepping): that step would miss its RFT force
(README, "How the forces enter MuJoCo").
"""

from __future__ import annotations

import contextlib
import threading
import weakref
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from dm_control.mujoco import engine, wrapper

from mjrft import GranularField, Material


@dataclass
class _Installed:
    """One installed field and how many live physics objects use it."""

    field: GranularField
    stack: contextlib.ExitStack
    users: int


_lock = threading.Lock()
_installed: dict[int, _Installed] = {}


def _acquire(model: mujoco.MjModel, options: dict[str, Any]) -> GranularField:
    """The installed field of `model`, building and installing it on first use."""
    with _lock:
        entry = _installed.get(model._address)
        if entry is None:
            field = GranularField(
                model, options.get("material"), n_triangles=options.get("n_triangles")
            )
            stack = contextlib.ExitStack()
            stack.enter_context(field.installed())
            entry = _Installed(field, stack, 0)
            _installed[model._address] = entry
        entry.users += 1
        return entry.field


def _release(key: int) -> None:
    """Drop one user of the field of model address `key`; uninstall it after the last."""
    with _lock:
        entry = _installed.get(key)
        if entry is None:
            return
        entry.users -= 1
        if entry.users > 0:
            return
        del _installed[key]
    entry.stack.close()


def installed_fields() -> int:
    """Number of models whose field an environment currently keeps installed."""
    return len(_installed)


class GranularPhysics(engine.Physics):
    """dm_control ``mujoco.Physics`` with the model's granular field installed for its lifetime.

    Build with :meth:`from_mjmodel` (or the inherited ``from_xml_path`` / ``from_xml_string``,
    which use the MJCF's material and resolution). Everything else is dm_control's Physics.

    Attributes (after construction):
      field: the :class:`mjrft.GranularField` acting on this physics (``field.last_wrench`` is
        the wrench of the latest forward pass).
      substeps: physics steps taken since construction.
    """

    _field_options: dict[str, Any] | None = None  # set per instance by from_mjmodel

    @classmethod
    def from_mjmodel(
        cls,
        model: mujoco.MjModel,
        *,
        material: Material | str | None = None,
        n_triangles: int | None = None,
    ) -> GranularPhysics:
        """Physics of a compiled model.

        Args:
          model: compiled ``mujoco.MjModel`` with an mjrft scene in its ``<custom>`` section.
          material: a :class:`mjrft.Material` or preset name overriding the MJCF medium.
          n_triangles: triangle count of every primitive intruding geom (meshes keep theirs).
        """
        if isinstance(material, str):
            material = Material.preset(material)
        obj = cls.__new__(cls)
        obj._field_options = {"material": material, "n_triangles": n_triangles}
        obj.__init__(wrapper.MjData(wrapper.MjModel(model)))
        return obj

    # -- lifetime of the installed field ---------------------------------------------------
    def _reload_from_data(self, data: wrapper.MjData) -> None:
        self._detach_field()
        model = data.model.ptr
        self.field = _acquire(model, self._field_options or {})
        self._finalizer = weakref.finalize(self, _release, model._address)
        self.substeps = 0
        self._work = np.zeros(model.nu)
        self._work_substeps = 0
        super()._reload_from_data(data)  # runs forward() with the field installed

    def _detach_field(self) -> None:
        finalizer = getattr(self, "_finalizer", None)
        if finalizer is not None:
            finalizer()  # runs _release once

    def free(self) -> None:
        """Uninstall the field (when no other physics shares the model) and free MuJoCo data."""
        self._detach_field()
        super().free()

    def copy(self, share_model: bool = False) -> GranularPhysics:
        """A copy with the same field options (and, with ``share_model``, the same field)."""
        new_data = self.data._make_copy(share_model=share_model)
        # The copied xfrc_applied rows hold user + RFT; a field that never saw them (a copied
        # model has its own) would take the RFT part for a user force. Keep the user part only;
        # the forward pass in _reload_from_data writes the RFT of the copied state again.
        new_data.xfrc_applied[:] = self.field.user_xfrc(self.data.ptr)
        new = type(self).__new__(type(self))
        new._warnings_cause_exception = True
        new._field_options = self._field_options
        new._reload_from_data(new_data)
        return new

    def __getstate__(self) -> tuple[wrapper.MjData, dict[str, Any], np.ndarray]:
        return self.data, self._field_options, self.field.user_xfrc(self.data.ptr)

    def __setstate__(self, state: Any) -> None:
        data, options, user_xfrc = state
        data.xfrc_applied[:] = user_xfrc  # without the RFT part (see copy)
        self._contexts_lock = threading.Lock()
        self._warnings_cause_exception = True
        self._field_options = options
        self._reload_from_data(data)

    # -- stepping --------------------------------------------------------------------------
    def step(self, nstep: int = 1) -> None:
        """Advance ``nstep`` physics steps, accumulating actuator work after each one.

        The same trajectory as ``engine.Physics.step(nstep)``, one substep at a time: with
        dm_control's legacy (split) stepping each substep is ``mj_step2`` then ``mj_step1`` (for
        RK4, ``mj_step`` then ``mj_step1``); otherwise ``mj_step``. After a split substep
        ``actuator_force`` is the force that acted over it and ``actuator_velocity`` the velocity
        the semi-implicit Euler update moved with, so ``|force * velocity| * dt`` is the work
        done in the substep (without legacy stepping the velocity is the pre-step one).
        """
        m, d = self.model.ptr, self.data.ptr
        dt = m.opt.timestep
        split = self.legacy_step and m.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
        with self.check_invalid_state():
            for _ in range(nstep):
                if split:  # dm_control's legacy step, one substep at a time
                    mujoco.mj_step2(m, d)
                    mujoco.mj_step1(m, d)
                else:
                    mujoco.mj_step(m, d)
                    if self.legacy_step:  # RK4: dm_control re-syncs positions with mj_step1
                        mujoco.mj_step1(m, d)
                self._work += np.abs(d.actuator_force * d.actuator_velocity) * dt
                self._work_substeps += 1
                self.substeps += 1

    def take_work(self) -> tuple[np.ndarray, int]:
        """(work per actuator [J], substeps) accumulated since the last call; resets both."""
        work, n = self._work.copy(), self._work_substeps
        self._work[:] = 0.0
        self._work_substeps = 0
        return work, n
