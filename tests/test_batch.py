"""A batch of a plugin model: each copy steps exactly as its MjData stepped alone."""

import threading
from pathlib import Path

import mujoco
import numpy as np
import pytest
from mujoco.batch import SimulationError
from soil_scenes import PLATE

import mjrft
from mjrft import simulate
from mjrft.batch import BatchedField, single_step_reference
from mjrft.field import GranularField

MODELS = Path(__file__).resolve().parents[1] / "models"
INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION

# A free body (the free-body treatment: pure model, implicit steps, slip and stick) and a ball on
# a slide (the mechanism treatment, which reads the previous step's qacc from the MjData).
SCENE = """
<mujoco>
  <option timestep="0.001" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <numeric name="mjrft:region" data="-0.2 -0.2 -0.3 0.2 0.2 0.1"/>
    <tuple name="mjrft:intruders">
      <element objtype="geom" objname="shell" prm="200"/>
      <element objtype="body" objname="ball" prm="150"/>
    </tuple>
  </custom>
  <worldbody>
    <body name="crab" pos="0 0 0.004">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.008 0.006 0.012" density="2500"/>
    </body>
    <body name="ball" pos="0.05 0 0.008">
      <joint type="slide" axis="0 0 1"/>
      <geom type="sphere" size="0.01" density="1500"/>
    </body>
  </worldbody>
</mujoco>"""
THROWN = np.array([0.05, -0.02, -0.15, 3.0, -2.0, 1.5, -0.05])


def scene_batch(integrator: str, nsim: int, nthread: int) -> BatchedField:
    """Copies thrown at speeds from 0 (at rest) to 1.5 times THROWN, ready to step."""
    field = GranularField(mjrft.load_model(SCENE.format(integrator=integrator)))
    bf = BatchedField(field, nsim=nsim, nthread=nthread)
    bf.reset()
    bf.batch.bind("qvel")[:] = np.linspace(0.0, 1.5, nsim)[:, None] * THROWN
    bf.forward()
    return bf


def push(bf: BatchedField, i: int) -> None:
    """User forces on the free body of every other copy at step i, changed now and then."""
    if i % 40 == 0:
        bf.user_xfrc[::2, 1] = (0.01 * np.sin(i), 0.0, 0.05, 0.0, 1e-4, 0.0)
    if i == 120:
        bf.user_xfrc[:] = 0.0


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_each_copy_steps_exactly_as_its_mjdata_alone(integrator):
    """The engine acts inside each copy's mj_step, with the copy's own state: a copy's whole
    state (engine state included), wrench, decisions and counters after batched steps are those
    of its MjData stepped alone by mj_step, bit for bit."""
    n = 5
    bf = scene_batch(integrator, n, nthread=2)
    field, m = bf.field, bf.model
    alone = [bf.batch.get_data(i) for i in range(n)]
    for k, nstep in enumerate((1, 1, 38, 40, 1, 79, 80)):  # calls of one and of many steps
        push(bf, 40 * k)
        bf.step(nstep)
        for d, user in zip(alone, bf.user_xfrc, strict=True):
            for _ in range(nstep):
                single_step_reference(field, d, user)
    state = np.zeros(mujoco.mj_stateSize(m, INTEGRATION))
    for i, d in enumerate(alone):
        mujoco.mj_getState(m, d, state, INTEGRATION)
        np.testing.assert_array_equal(bf.batch.state[i], state, err_msg=f"copy {i}")
        np.testing.assert_array_equal(bf.wrench[i], field.wrench_of(d))
        np.testing.assert_array_equal(bf.state_array("decision")[i], field.decision_of(d))
    assert bf.stats == {k: sum(field.stats_of(d)[k] for d in alone) for k in bf.stats}
    assert bf.stats["stuck"] > 0 and bf.stats["implicit"] > 0  # the treatment decided
    assert np.all(bf.wrench[1:, 2, 2] != 0.0)  # the field acts on every copy's ball
    qpos = bf.batch.bind("qpos")
    assert not np.allclose(qpos[1], qpos[3])  # the copies really differ


def test_user_forces_are_the_users_part_and_the_field_adds_to_them():
    bf = scene_batch("Euler", 2, nthread=1)
    bf.user_xfrc = np.zeros((2, bf.model.nbody, 6))  # assignment copies into the same array
    bf.user_xfrc[0, 1] = (0.01, 0.0, 0.02, 0.0, 1e-4, 0.0)
    bf.step(3)
    xfrc = bf.batch.bind("xfrc_applied")
    np.testing.assert_array_equal(xfrc[:, 1], bf.user_xfrc[:, 1] + bf.wrench[:, 1])
    for i in range(2):
        np.testing.assert_array_equal(bf.field.user_xfrc(bf.batch.get_data(i)), bf.user_xfrc[i])


def test_thread_counts_give_the_same_bits():
    runs = []
    for nthread in (1, 2):
        bf = scene_batch("RK4", 7, nthread)
        for i in range(200):
            push(bf, i)
            bf.step()
        runs.append((np.array(bf.batch.state), np.array(bf.wrench), bf.stats))
    (s1, w1, c1), (s2, w2, c2) = runs
    assert np.any(w1 != 0.0)
    np.testing.assert_array_equal(s2, s1)
    np.testing.assert_array_equal(w2, w1)
    assert c2 == c1


def test_a_failing_copy_is_named_and_the_others_step_on():
    m = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=100)
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET  # else MuJoCo resets NaN qvel
    bf = BatchedField(GranularField(m), nsim=3, nthread=1)
    bf.reset()
    bf.batch.bind("qvel")[1, 2] = np.nan
    with pytest.raises(SimulationError, match=r"simulation 1: body 'sphere' has a non-finite"):
        bf.step()
    np.testing.assert_array_equal(bf.batch.bind("time"), [m.opt.timestep, 0.0, m.opt.timestep])


def test_each_copy_has_its_own_ground():
    """Two copies pressed to different depths carry the grounds their MjData get alone."""
    field = GranularField(mjrft.load_model(PLATE))
    bf = BatchedField(field, nsim=2, nthread=1)
    bf.reset()
    alone = [bf.batch.get_data(i) for i in range(2)]
    targets = np.array([-0.004, -0.007])
    for i in range(120):
        bf.batch.bind("ctrl")[:, 0] = targets * min(1.0, i / 60)
        for d, target in zip(alone, targets, strict=True):
            d.ctrl[0] = target * min(1.0, i / 60)
            single_step_reference(field, d)
        bf.step()
    for i, d in enumerate(alone):
        np.testing.assert_array_equal(bf.soil(i).height, field.soil(d).height)
        assert bf.soil(i).counters == field.soil(d).counters
    assert not np.array_equal(bf.soil(0).height, bf.soil(1).height)


def test_bad_sizes_and_names_are_refused():
    m = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=100)
    with pytest.raises(ValueError, match="nsim"):
        BatchedField(GranularField(m), nsim=0)
    bf = BatchedField(GranularField(m), nsim=2)
    with pytest.raises(KeyError, match="'elem_force' is not one of the engine's persistent"):
        bf.state_array("elem_force")
    with pytest.raises(ValueError, match="does not deform"):
        bf.soil(0)


def test_a_batch_refuses_to_step_from_two_threads_at_once():
    m = simulate.load_model(MODELS / "sphere_drop.xml", n_triangles=100)
    bf = BatchedField(GranularField(m), nsim=2, nthread=1)
    bf.reset()
    errors = []
    with bf._stepping:  # another thread is inside step()

        def second():
            try:
                bf.step()
            except RuntimeError as exc:
                errors.append(str(exc))

        t = threading.Thread(target=second)
        t.start()
        t.join()
    assert errors and "one thread at a time" in errors[0]
    bf.step()  # once the other call is done, stepping works again
    bf.close()
