"""The engine as a MuJoCo plugin: MuJoCo's own machinery carries it.

State in ``plugin_state`` follows ``mj_copyData``, ``mj_resetData`` and ``mj_getState``;
``mujoco.rollout`` steps it on several threads exactly as alone; a C program steps a saved model
with it; a model without the plugin, and a failing pass, are reported by name.
"""

from __future__ import annotations

import copy
import subprocess
import sys
import sysconfig
from pathlib import Path

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.core import engine
from mjrft.field.plugin import EngineError

# A dense ellipsoid thrown spinning into glass beads: every pass acts, and the low-speed
# treatment's records (persistent state) change step by step.
THROWN = """
<mujoco>
  <option timestep="0.001" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders"><element objtype="geom" objname="shell" prm="200"/></tuple>
  </custom>
  <worldbody>
    <body name="crab" pos="0 0 0.004">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.008 0.006 0.012" density="8000"/>
    </body>
  </worldbody>
</mujoco>"""
THROW = (0.3, -0.1, -0.5, 4.0, -2.0, 6.0)


def _thrown(integrator="Euler"):
    model = mjrft.load_model(THROWN.format(integrator=integrator))
    data = mujoco.MjData(model)
    data.qvel[:] = THROW
    return model, data


def _steps(model, data, n):
    out = []
    for _ in range(n):
        mujoco.mj_step(model, data)
        out.append(np.concatenate([data.qpos, data.qvel, data.xfrc_applied[1]]))
    return np.array(out)


def test_the_model_carries_the_plugin_and_it_acts_in_mj_step():
    model, data = _thrown()
    assert model.nplugin == 1 and model.npluginstate > 0
    mujoco.mj_step(model, data)
    assert np.any(data.xfrc_applied[1] != 0.0)
    field = mjrft.GranularField(model)
    np.testing.assert_array_equal(field.wrench_of(data)[1], data.xfrc_applied[1])


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_copied_data_steps_exactly_as_the_original(integrator):
    model, data = _thrown(integrator)
    _steps(model, data, 40)
    twin = copy.copy(data)  # mj_copyData: plugin_state comes along
    np.testing.assert_array_equal(_steps(model, twin, 60), _steps(model, data, 60))


def test_reset_data_restarts_the_engine_state():
    model, data = _thrown("RK4")
    first = _steps(model, data, 50)
    mujoco.mj_resetData(model, data)
    data.qvel[:] = THROW
    np.testing.assert_array_equal(_steps(model, data, 50), first)


def test_get_and_set_state_carry_the_engine_state():
    model, data = _thrown("RK4")
    _steps(model, data, 30)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    saved = np.zeros(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, saved, spec)
    ahead = _steps(model, data, 40)
    other = mujoco.MjData(model)
    mujoco.mj_setState(model, other, saved, spec)
    np.testing.assert_array_equal(_steps(model, other, 40), ahead)


def test_rollout_threads_step_each_data_as_alone():
    from mujoco import rollout

    model, _ = _thrown()
    nroll, nstep = 6, 80
    datas = [mujoco.MjData(model) for _ in range(2)]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    size = mujoco.mj_stateSize(model, spec)
    initial = np.zeros((nroll, size))
    rng = np.random.default_rng(7)
    for i in range(nroll):
        d = mujoco.MjData(model)
        d.qvel[:] = np.asarray(THROW) * rng.uniform(0.5, 1.5, 6)
        mujoco.mj_getState(model, d, initial[i], spec)
    state, _ = rollout.rollout(model, datas, initial, nstep=nstep)
    for i in range(nroll):
        d = mujoco.MjData(model)
        mujoco.mj_setState(model, d, initial[i], spec)
        alone = np.zeros((nstep, size))
        for t in range(nstep):
            mujoco.mj_step(model, d)
            mujoco.mj_getState(model, d, alone[t], spec)
        np.testing.assert_array_equal(state[i], alone)


def test_a_serial_rollout_reusing_one_data_steps_each_as_alone():
    # mj_setState(FULLPHYSICS) rewinds the engine's record but not xfrc_applied: the rows the
    # engine wrote at the end of one rollout must not turn into user forces of the next
    from mujoco import rollout

    model, _ = _thrown()
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.zeros((3, mujoco.mj_stateSize(model, spec)))
    for i in range(3):
        d = mujoco.MjData(model)
        d.qvel[:] = np.asarray(THROW) * (1.0 + 0.2 * i)
        mujoco.mj_getState(model, d, initial[i], spec)
    state, _ = rollout.rollout(model, [mujoco.MjData(model)], initial, nstep=60)
    for i in range(3):
        d = mujoco.MjData(model)
        mujoco.mj_setState(model, d, initial[i], spec)
        for _ in range(60):
            mujoco.mj_step(model, d)
        end = np.zeros(initial.shape[1])
        mujoco.mj_getState(model, d, end, spec)
        np.testing.assert_array_equal(state[i, -1], end)


def test_a_model_without_the_plugin_is_refused_with_how_to_add_it():
    model = mujoco.MjModel.from_xml_string(THROWN.format(integrator="Euler"))
    with pytest.raises(EngineError, match=r"mjrft.load_model"):
        mjrft.GranularField(model)


def test_a_non_finite_state_raises_naming_the_body_and_the_time():
    model, data = _thrown()
    # MuJoCo resets a data with a bad qvel before the forward pass unless told not to
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    _steps(model, data, 3)
    data.qvel[3] = np.nan
    with pytest.raises(mujoco.FatalError, match=r"body 'crab' has a non-finite .* at time 0\.003"):
        mujoco.mj_step(model, data)
    other = mujoco.MjData(model)  # the process stays usable
    other.qvel[:] = THROW
    _steps(model, other, 3)


C_PROGRAM = r"""
#include <stdio.h>
#include <mujoco/mujoco.h>
int main(int argc, char** argv) {
  /* an MJB file names plugins by registration slot: register what Python's mujoco registers
     (its plugin folder), then mjrft's library, as the process that saved it did */
  mj_loadAllPluginLibraries(argv[3], NULL);
  mj_loadPluginLibrary(argv[1]);
  mjModel* m = mj_loadModel(argv[2], NULL);
  if (!m) { fprintf(stderr, "load failed\n"); return 1; }
  mjData* d = mj_makeData(m);
  for (int i = 0; i < 6; i++) d->qvel[i] = (double[]){0.3, -0.1, -0.5, 4.0, -2.0, 6.0}[i];
  for (int t = 0; t < 100; t++) mj_step(m, d);
  for (int i = 0; i < 6; i++) printf("%.17g\n", d->xfrc_applied[6 + i]);
  for (int i = 0; i < m->nq; i++) printf("%.17g\n", d->qpos[i]);
  mj_deleteData(d);
  mj_deleteModel(m);
  return argc == 4 ? 0 : 2;
}
"""


def test_a_c_program_steps_a_saved_model_with_the_plugin(tmp_path):
    model, data = _thrown()
    mjb = tmp_path / "thrown.mjb"
    mujoco.mj_saveModel(model, str(mjb), None)
    mj = Path(mujoco.__file__).parent
    lib = next(mj.glob("libmujoco.so.*"))
    src = tmp_path / "step.c"
    src.write_text(C_PROGRAM)
    exe = tmp_path / "step"
    cc = sysconfig.get_config_var("CC").split()[0] if sysconfig.get_config_var("CC") else "cc"
    subprocess.run(
        [cc, "-O1", "-o", str(exe), str(src), f"-I{mj / 'include'}", str(lib),
         f"-Wl,-rpath,{mj}"],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    out = subprocess.run(
        [str(exe), str(engine.library_path()), str(mjb), str(mj / "plugin")], check=True,
        capture_output=True, text=True,
    )  # fmt: skip
    values = np.array([float(x) for x in out.stdout.split()])
    for _ in range(100):
        mujoco.mj_step(model, data)
    np.testing.assert_array_equal(values, np.concatenate([data.xfrc_applied[1], data.qpos]))


def test_the_library_reports_the_mujoco_it_was_built_against():
    assert engine.library().mjrft_mujoco_version() == mujoco.mj_version()
    assert sys.modules["mjrft.core.engine"].library_path().exists()


def test_a_second_copy_of_the_library_does_not_end_the_process(tmp_path):
    # MuJoCo refuses a second plugin of one name as a fatal error (it would exit the process):
    # a copy of the library loaded from another path leaves the registered one in place.
    import shutil

    copy_path = tmp_path / "libmjrft_granular_copy.so"
    shutil.copy(engine.library_path(), copy_path)
    script = (
        "import ctypes, mujoco, mjrft\n"
        "from mjrft.core import engine\n"
        "engine.library()\n"
        f"ctypes.CDLL({str(copy_path)!r})\n"
        f"m = mjrft.load_model({THROWN.format(integrator='Euler')!r})\n"
        "d = mujoco.MjData(m)\n"
        "mujoco.mj_step(m, d)\n"
        "print('still here')\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert out.returncode == 0 and "still here" in out.stdout, out.stderr + out.stdout


def test_a_restored_state_steps_as_a_new_mjdata_in_a_mechanism():
    # The mechanism treatment caches factors of M in the instance's work arrays: a state
    # restored by mj_setState (a rollout reusing one MjData) must start from empty caches, as a
    # new MjData does, and give its physics bit for bit.
    from mjrft.app.simulate import resolve_model

    model = mjrft.load_model(resolve_model("hexapod_sand"))
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    start = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, start, 0)
    saved = np.zeros(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, start, saved, spec)

    def run(d):
        d.ctrl[:] = model.key_ctrl[0]
        for _ in range(150):
            mujoco.mj_step(model, d)
        return np.concatenate([d.qpos, d.qvel])

    reused = mujoco.MjData(model)
    for _ in range(2):
        mujoco.mj_setState(model, reused, saved, spec)
        got = run(reused)
    fresh = mujoco.MjData(model)
    mujoco.mj_setState(model, fresh, saved, spec)
    np.testing.assert_array_equal(got, run(fresh))


def test_a_copied_robot_steps_exactly_as_the_original():
    # mj_copyData carries qacc, and the engine's copy callback the instance's caches and record:
    # the copy's mechanism treatment continues with its predictor
    from mjrft.app.simulate import resolve_model

    model = mjrft.load_model(resolve_model("hexapod_sand"))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    for _ in range(100):
        mujoco.mj_step(model, data)
    twin = copy.copy(data)
    for d in (data, twin):
        for _ in range(100):
            mujoco.mj_step(model, d)
    np.testing.assert_array_equal(twin.qpos, data.qpos)
    np.testing.assert_array_equal(twin.plugin_state, data.plugin_state)


def test_a_pickled_data_gets_its_own_engine_instance():
    # MuJoCo's pickling of an MjData copies plugin_data's raw pointers: the copy must get an
    # instance of its own (no shared work arrays, no double free when both are deleted)
    import gc
    import pickle

    model, data = _thrown("RK4")
    _steps(model, data, 20)
    twin = pickle.loads(pickle.dumps(data))
    np.testing.assert_array_equal(_steps(model, twin, 30), _steps(model, data, 30))
    del data
    gc.collect()
    _steps(model, twin, 5)  # the original's instance is gone; the twin's is its own
    del twin
    gc.collect()


def test_a_model_with_spring_and_damper_disabled_is_warned_of():
    # mj_passive returns before the plugins when both flags are disabled: no RFT would act
    from mjrft.field.scene import SceneWarning

    xml = THROWN.format(integrator="Euler").replace(
        '<flag contact="disable"/>', '<flag contact="disable" spring="disable" damper="disable"/>'
    )
    with pytest.warns(SceneWarning, match="feel no RFT"):
        model = mjrft.load_model(xml)
    data = mujoco.MjData(model)
    data.qvel[:] = THROW
    mujoco.mj_step(model, data)
    assert np.all(data.xfrc_applied == 0.0)  # the warning's reason, checked


def test_a_spec_given_the_engine_twice_keeps_one_instance_and_fresh_tables():
    spec = mujoco.MjSpec.from_string(THROWN.format(integrator="Euler"))
    mjrft.add_granular(spec)
    mjrft.add_granular(spec, n_triangles=80)  # the second tables replace the first
    model = spec.compile()
    assert model.nplugin == 1
    assert mjrft.GranularField(model, n_triangles=80).n_elements < 200
