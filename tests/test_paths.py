"""The engine's pass, many callers: the plain reference, threads stepping MjData of one model."""

from __future__ import annotations

import threading

import field_reference as ref
import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.field import GranularField

SCENE = """
<mujoco>
  <option timestep="0.001" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <numeric name="mjrft:region" data="-0.2 -0.2 -0.3 0.2 0.2 0.1"/>
    <tuple name="mjrft:intruders">
      <element objtype="geom" objname="shell" prm="300"/>
      <element objtype="geom" objname="fin" prm="120"/>
      <element objtype="body" objname="ball" prm="200"/>
    </tuple>
  </custom>
  <worldbody>
    <body name="crab" pos="0 0 0.004">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.008 0.006 0.012" density="2500"/>
      <geom name="fin" type="box" size="0.006 0.001 0.004" pos="0.008 0 0.006" density="2500"/>
    </body>
    <body name="ball" pos="0.05 0 0.008">
      <joint type="slide" axis="0 0 1"/>
      <geom type="sphere" size="0.01" density="1500"/>
    </body>
  </worldbody>
</mujoco>"""
# Starts: a free body thrown in spinning (pure model, then implicit steps, slip and stick) and a
# body on a slide (never treated) sinking under its weight.
QVEL = {"thrown": (0.05, -0.02, -0.15, 3.0, -2.0, 1.5, -0.05), "resting": (0,) * 7}
# The reference sums NumPy-transformed element forces: the same physics in another order of
# floating-point operations (1e-16 per step), which the treatment's decisions may amplify.
PATH_RTOL = 1e-6


def model(integrator: str) -> mujoco.MjModel:
    """The scene with the engine plugin."""
    return mjrft.load_model(SCENE.format(integrator=integrator))


def plain_model(integrator: str) -> mujoco.MjModel:
    """The same scene without the plugin: no RFT unless a callback adds it."""
    return mujoco.MjModel.from_xml_string(SCENE.format(integrator=integrator))


def start(m: mujoco.MjModel, kind: str) -> mujoco.MjData:
    d = mujoco.MjData(m)
    d.qvel[:] = QVEL[kind]
    return d


def push(d: mujoco.MjData, i: int) -> None:
    """The user's part of xfrc_applied: assigned now and then, as a controller would."""
    if i % 40 == 0:
        d.xfrc_applied[1] = (0.01 * np.sin(i), 0.0, 0.05, 0.0, 1e-4, 0.0)
    if i == 120:
        d.xfrc_applied[:] = 0.0  # what the interactive viewer does before a perturbation


def run_engine(m, kind, steps):
    fld = GranularField(m)
    d = start(m, kind)
    out = []
    for i in range(steps):
        push(d, i)
        mujoco.mj_step(m, d)
        out.append((np.concatenate([d.qpos, d.qvel]), int(fld.decision_of(d)[0])))
    return out, fld.stats_of(d)


def run_reference(integrator, kind, steps):
    """The reference as MuJoCo's passive callback of the scene without the plugin (its field
    describes the plugin model, of the same bodies)."""
    reference = ref.ReferenceField(GranularField(model(integrator)))
    m = plain_model(integrator)
    d = start(m, kind)
    out = []
    mujoco.set_mjcb_passive(reference.apply)
    try:
        for i in range(steps):
            push(d, i)
            mujoco.mj_step(m, d)
            out.append((np.concatenate([d.qpos, d.qvel]), reference.decisions[0]))
    finally:
        mujoco.set_mjcb_passive(None)
    return out


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "RK4"])
@pytest.mark.parametrize("kind", ["thrown", "resting"])
def test_the_engines_pass_follows_the_plain_reference(integrator, kind):
    """The plugin's pass inside mj_step (treatment, RK4 rule, ownership of xfrc_applied)
    against the same rules written plainly (field_reference.ReferenceField) as MuJoCo's passive
    callback of the scene without the plugin."""
    steps = 240
    fast, stats = run_engine(model(integrator), kind, steps)
    slow = run_reference(integrator, kind, steps)
    states = np.array([s for s, _ in fast])
    np.testing.assert_allclose(
        states, np.array([s for s, _ in slow]), rtol=PATH_RTOL, atol=PATH_RTOL * 1e-3
    )
    assert [k for _, k in fast] == [k for _, k in slow]
    decided = {name for name in ("stuck", "slipping", "implicit") if stats[name]}
    assert "stuck" in decided and (kind == "resting" or "implicit" in decided)
    assert np.ptp(states[:, 7]) > 1e-4  # the ball on its slide sank
    assert kind == "resting" or np.ptp(states[:, 2]) > 1e-3  # the thrown body moved


def _step_alone(m, kind, steps):
    d = start(m, kind)
    for i in range(steps):
        push(d, i)
        mujoco.mj_step(m, d)
    return d


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_two_threads_step_two_mjdata_of_one_model_as_if_alone(integrator):
    """mj_step releases the GIL, so two threads run the engine's pass at the same time; each
    MjData's engine state is its own, so each gets bit for bit what it gets stepped alone."""
    m = model(integrator)
    steps = 400
    alone = {kind: _step_alone(m, kind, steps) for kind in QVEL}
    fld = GranularField(m)
    datas = {kind: start(m, kind) for kind in QVEL}
    barrier = threading.Barrier(len(datas))

    def work(d):
        barrier.wait()
        for i in range(steps):
            push(d, i)
            mujoco.mj_step(m, d)

    threads = [threading.Thread(target=work, args=(d,)) for d in datas.values()]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for kind, d in datas.items():
        np.testing.assert_array_equal(d.qpos, alone[kind].qpos, err_msg=kind)
        np.testing.assert_array_equal(d.qvel, alone[kind].qvel, err_msg=kind)
        np.testing.assert_array_equal(d.plugin_state, alone[kind].plugin_state, err_msg=kind)
    assert sum(fld.stats_of(d)["calls"] for d in datas.values()) >= 2 * steps
