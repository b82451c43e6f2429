"""A dm_control ``Physics`` of a model that carries the granular RFT engine.

The model comes from ``mjrft.load_model`` (or an environment's ``build_model``): it carries the
engine plugin ``mjrft.granular``, which computes the RFT wrench inside every MuJoCo forward pass of
that model and writes it into ``xfrc_applied``, with its state in ``mjData.plugin_state``. So the
force acts in every substep and in every ``forward()`` (resets, rendering) with nothing to install
or release, and dm_control's split stepping (``legacy_step=True``, the default of
``control.Environment``: ``Physics.step`` runs ``mj_step2`` on the forces the previous call's
``mj_step1`` computed) keeps the wrench that ``mj_step1`` writes in ``xfrc_applied`` (and the
engine's state in ``plugin_state``) until the next ``mj_step2`` applies it; when the controls
changed since that ``mj_step1``, ``step`` runs the velocity stage again first, since the
mechanism treatment predicts the actuators' forces from them. ``GranularPhysics`` adds the
field's description (``field``, a :class:`mjrft.GranularField` for observations: surface,
bodies, elements, the deforming ground), loaders that keep the engine
(dm_control's own ``from_xml_path``/``from_xml_string`` compile plain models without it), copies
and pickles that keep the scene options, and actuator-work accounting.

Per substep the physics accumulates the mechanical work of every actuator,
``|actuator_force * actuator_velocity| * dt`` [J] (no regeneration: negative work costs too),
and counts substeps; tasks read and reset these with :meth:`GranularPhysics.take_work`.

Do not assign ``xfrc_applied`` rows of intruding bodies between ``mj_step1`` and ``mj_step2``
(e.g. in a Task's ``before_step`` under legacy stepping): the step that follows would apply the
assigned value without that substep's RFT force (the engine takes an assigned component as the
user's part from its next pass on; README, "How the forces enter MuJoCo").
"""

from __future__ import annotations

import threading
from typing import Any

import mujoco
import numpy as np
from dm_control.mujoco import engine, wrapper

from mjrft import GranularField, SceneOptions, load_model
from mjrft.field import plugin

#: What a pickled physics keeps of its MjData (mj_getState): the whole integration state,
#: the engine's ``plugin_state`` and the user's inputs (ctrl, applied forces) included.
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


class GranularPhysics(engine.Physics):
    """dm_control ``mujoco.Physics`` of a model that carries the granular engine.

    Build with :meth:`from_mjmodel` (a model from ``mjrft.load_model``), or with
    :meth:`from_xml_path` / :meth:`from_xml_string` (MJCF with an ``mjrft:`` section; scene
    options as keywords). A model without the engine is refused (``EngineError`` naming
    ``mjrft.load_model``). Everything else is dm_control's Physics.

    Attributes (after construction):
      field: the :class:`mjrft.GranularField` of the model (shared by copies that share the
        model); ``field.wrench_of(physics.data.ptr)`` or :attr:`rft_wrench` is the wrench of
        this physics' latest forward pass.
      substeps: physics steps taken since construction.
    """

    _scene_options: SceneOptions | None = None  # the model's scene options (set on load)
    field: GranularField | None = None

    # -- construction ----------------------------------------------------------------------
    @classmethod
    def from_mjmodel(
        cls, model: mujoco.MjModel, options: SceneOptions | None = None
    ) -> GranularPhysics:
        """Physics of a compiled model that carries the engine.

        Args:
          model: a ``mujoco.MjModel`` from ``mjrft.load_model`` (or ``mjrft.add_granular``).
          options: the SceneOptions the model was loaded with, for a model loaded outside this
            process (an MJB file); by default those ``mjrft.load_model`` recorded.
        Raises:
          mjrft.field.plugin.EngineError for a model without the engine; SceneError for
          options that do not give the model's tables.
        """
        obj = cls.__new__(cls)
        obj._scene_options = options if options is not None else plugin.options_of(model)
        obj.__init__(wrapper.MjData(wrapper.MjModel(model)))
        return obj

    @classmethod
    def from_xml_path(cls, file_path: str, **options: Any) -> GranularPhysics:
        """Physics of an MJCF file with an ``mjrft:`` section, loaded with the engine
        (``mjrft.load_model``); options: SceneOptions fields (material, n_triangles, ...)."""
        return cls.from_mjmodel(load_model(str(file_path), **options))

    @classmethod
    def from_xml_string(
        cls, xml_string: str, assets: dict | None = None, **options: Any
    ) -> GranularPhysics:
        """Physics of an MJCF string with an ``mjrft:`` section, loaded with the engine;
        assets: ``{filename: bytes}`` the MJCF refers to; options: SceneOptions fields."""
        spec = mujoco.MjSpec.from_string(xml_string, assets=assets or {})
        return cls.from_mjmodel(load_model(spec, **options))

    def reload_from_xml_path(self, file_path: str, **options: Any) -> None:
        """Reload from an MJCF file, with the engine (as :meth:`from_xml_path`)."""
        model = load_model(str(file_path), **options)
        self._scene_options = plugin.options_of(model)
        self._reload_from_model(wrapper.MjModel(model))

    def reload_from_xml_string(
        self, xml_string: str, assets: dict | None = None, **options: Any
    ) -> None:
        """Reload from an MJCF string, with the engine (as :meth:`from_xml_string`)."""
        model = load_model(mujoco.MjSpec.from_string(xml_string, assets=assets or {}), **options)
        self._scene_options = plugin.options_of(model)
        self._reload_from_model(wrapper.MjModel(model))

    def _reload_from_data(self, data: wrapper.MjData) -> None:
        model = data.model.ptr
        if self.field is None or self.field.model is not model:
            if self._scene_options is None:
                self._scene_options = plugin.options_of(model)
            # A copied model carries the same tables; the options say how they were made.
            self.field = GranularField(model, options=self._scene_options)
        self.substeps = 0
        self._work = np.zeros(model.nu)
        self._work_substeps = 0
        super()._reload_from_data(data)  # runs forward(): the engine acts in it

    # -- copies ----------------------------------------------------------------------------
    def _blank(self) -> GranularPhysics:
        """An uninitialised instance with this one's scene options."""
        new = type(self).__new__(type(self))
        new._warnings_cause_exception = True
        new._scene_options = self._scene_options
        return new

    def copy(self, share_model: bool = False) -> GranularPhysics:
        """A copy (MjData copied with the engine's state); with ``share_model`` it shares the
        model and its field, else it has a copy of the model (with the engine) and its field."""
        new = self._blank()
        if share_model:
            new.field = self.field
        new._reload_from_data(self.data._make_copy(share_model=share_model))
        return new

    def __getstate__(self) -> tuple[mujoco.MjModel, np.ndarray, SceneOptions]:
        # The model and the state (mj_getState), not the MjData: MuJoCo's pickle of an MjData
        # copies its plugin_data pointers, so the unpickled copy would share (and free) the
        # original's engine instance.
        m, d = self.model.ptr, self.data.ptr
        state = np.empty(mujoco.mj_stateSize(m, _STATE))
        mujoco.mj_getState(m, d, state, _STATE)
        return m, state, self._scene_options

    def __setstate__(self, state: tuple[mujoco.MjModel, np.ndarray, SceneOptions]) -> None:
        model, values, options = state
        data = mujoco.MjData(model)
        mujoco.mj_setState(model, data, values, _STATE)
        self._contexts_lock = threading.Lock()
        self._warnings_cause_exception = True
        self._scene_options = options
        self._reload_from_data(wrapper.MjData(data))

    # -- the field's results ---------------------------------------------------------------
    @property
    def rft_wrench(self) -> np.ndarray:
        """(nbody, 6) RFT wrench of this physics' latest forward pass, world frame: force [N]
        then torque [N m] about each body's CoM (a view, updated by every pass)."""
        return self.field.wrench_of(self.data.ptr)

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
            if split and self._inputs_changed(d):
                # The engine's pass of this state ran in the last mj_step1, before the task set
                # this step's controls; the mechanism treatment predicts the actuators' forces
                # from them, so it runs again (a repeated pass at the same time reads the inputs
                # the first one read) and mj_step2 applies what mj_step would have.
                mujoco.mj_fwdVelocity(m, d)
            for _ in range(nstep):
                if split:  # dm_control's legacy step, one substep at a time
                    mujoco.mj_step2(m, d)
                    mujoco.mj_step1(m, d)
                    self._inputs = (d.ctrl.copy(), d.act.copy())
                else:
                    mujoco.mj_step(m, d)
                    if self.legacy_step:  # RK4: dm_control re-syncs positions with mj_step1
                        mujoco.mj_step1(m, d)
                self._work += np.abs(d.actuator_force * d.actuator_velocity) * dt
                self._work_substeps += 1
                self.substeps += 1

    def _inputs_changed(self, d: mujoco.MjData) -> bool:
        """True unless ctrl and act are what the last mj_step1's pass saw."""
        seen = getattr(self, "_inputs", None)
        return (
            seen is None
            or not np.array_equal(seen[0], d.ctrl)
            or not np.array_equal(seen[1], d.act)
        )

    def take_work(self) -> tuple[np.ndarray, int]:
        """(work per actuator [J], substeps) accumulated since the last call; resets both."""
        work, n = self._work.copy(), self._work_substeps
        self._work[:] = 0.0
        self._work_substeps = 0
        return work, n
