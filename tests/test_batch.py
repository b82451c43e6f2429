"""Batched stepping equals the single-MjData path copy by copy."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft import simulate
from mjrft.batch import BatchedField, single_step_reference
from mjrft.field import GranularField

MODELS = Path(__file__).resolve().parents[1] / "models"


def test_batch_matches_single_copies_with_different_states_and_controls():
    m = simulate.load_model(MODELS / "ellipsoid_pitch.xml")
    fld = GranularField(m, n_triangles=400)
    n = 3
    bf = BatchedField(fld, nsim=n, nthread=2)
    bf.reset(keyframe=np.zeros(n, dtype=int))
    ctrl = bf.batch.bind("ctrl")
    qpos = bf.batch.bind("qpos")
    crank = m.actuator("crank").id
    ctrl[:, crank] *= np.array([0.5, 1.0, 1.7])
    slide = m.joint("descent").qposadr[0]
    qpos[1, slide] -= 0.004  # copy 1 starts deeper (and its servo target with it)
    bf.batch.bind("act")[1, m.actuator("descent").actadr[0]] -= 0.004
    bf.forward()
    bf.user_xfrc[2, m.body("ellipsoid").id, :3] = [0.02, 0.0, -0.05]  # a push on copy 2 only
    # Every state field the batch integrates (the solver's warm start included).
    fields = ("time", "qpos", "qvel", "act", "ctrl", "qacc_warmstart")
    starts = [{f: np.array(bf.batch.bind(f)[i]) for f in fields} for i in range(n)]
    bf.step(800)
    assert np.any(bf.wrench != 0)
    for i, start in enumerate(starts):
        d = mujoco.MjData(m)
        d.time = float(start.pop("time"))
        for f, v in start.items():
            getattr(d, f)[:] = v
        for _ in range(800):
            single_step_reference(fld, d, bf.user_xfrc[i])
        np.testing.assert_array_equal(bf.batch.bind("qpos")[i], d.qpos)
        np.testing.assert_array_equal(bf.batch.bind("qvel")[i], d.qvel)
    final = bf.batch.bind("qpos")
    assert not np.allclose(final[0], final[2])  # the copies really differ


@pytest.mark.filterwarnings("ignore::mjrft.core.material.MaterialWarning")  # a stand-in model
def test_batch_rejects_callable_materials_and_bad_sizes():
    m = simulate.load_model(MODELS / "sphere_drop.xml")
    mat = mjrft.Material.from_callables(lambda b, g: 0 * b + 0.1, lambda b, g: 0 * b + 1.0, 1e5)
    with pytest.raises(ValueError, match="callables"):
        BatchedField(GranularField(m, material=mat), nsim=2)
    with pytest.raises(ValueError, match="nsim"):
        BatchedField(GranularField(m), nsim=0)


def test_batch_refuses_non_finite_state_naming_the_copy():
    m = simulate.load_model(MODELS / "sphere_drop.xml")
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    bf = BatchedField(GranularField(m, n_triangles=100), nsim=3, nthread=1)
    bf.reset()
    bf.batch.bind("qvel")[1, 2] = np.nan
    bf.forward()
    with pytest.raises(FloatingPointError, match="simulation 1"):
        bf.step()


def test_threaded_rft_pass_equals_one_thread_and_counts_every_copy():
    """With enough copies the RFT pass runs on several threads over disjoint copies: the states,
    the field's statistics and the copy named in an error are those of a single thread."""
    m = simulate.load_model(MODELS / "ellipsoid_pitch.xml")
    n, crank = 9, m.actuator("crank").id
    runs = []
    for nthread in (1, 2):
        fld = GranularField(m, n_triangles=200)
        bf = BatchedField(fld, nsim=n, nthread=nthread)
        assert len(bf._jobs) == nthread  # 9 copies: one thread, or two of 4 and 5 copies
        bf.reset(keyframe=np.zeros(n, dtype=int))
        bf.batch.bind("ctrl")[:, crank] *= np.linspace(0.6, 1.4, n)
        bf.user_xfrc = np.zeros((n, m.nbody, 6))  # assignment copies into the bound array
        bf.user_xfrc[7, m.body("ellipsoid").id, 2] = -0.05
        bf.step(1500)
        runs.append((np.array(bf.batch.bind("qpos")), np.array(bf.wrench), fld.stats))
        bf.close()
    (q1, w1, s1), (q2, w2, s2) = runs
    assert np.any(w1 != 0)
    np.testing.assert_array_equal(q2, q1)
    np.testing.assert_array_equal(w2, w1)
    assert s2 == s1 and s1["calls"] == 1500 * n
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    bf = BatchedField(GranularField(m, n_triangles=200), nsim=n, nthread=2)
    bf.reset(keyframe=np.zeros(n, dtype=int))
    bf.batch.bind("qvel")[6] = np.nan  # a copy of the second thread's share
    bf.forward()
    with pytest.raises(FloatingPointError, match="simulation 6"):
        bf.step()


def test_a_batch_refuses_to_step_from_two_threads_at_once():
    import threading

    m = simulate.load_model(MODELS / "sphere_drop.xml")
    bf = BatchedField(GranularField(m, n_triangles=100), nsim=2, nthread=1)
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
