"""The sensor plugin mjrft.sensor: per intruder geom, the applied RFT wrench and the sinkage.

The readings are checked against what the engine applied (xfrc_applied, through
GranularField.wrench_of), against the pure model's per-triangle forces (element_states), and the
sinkage against a brute-force lowest point of each primitive sampled densely in this file.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.field.plugin import READING, SENSOR
from mjrft.field.scene import SceneError

#: Sums of a few hundred element forces against the engine's own sums: round-off only.
ROUNDOFF = 1e-12

_SCENE = """
<mujoco>
  <option timestep="0.001" integrator="implicitfast"/>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <text name="mjrft:low_speed" data="{low_speed}"/>
    <tuple name="mjrft:intruders">
      <element objtype="body" objname="foot" prm="200"/>
      <element objtype="body" objname="shin" prm="200"/>
    </tuple>
  </custom>
  <worldbody>
    <body name="foot" pos="0 0 0.005">
      <freejoint/>
      <geom name="heel" type="sphere" size="0.02" density="3000" contype="0" conaffinity="0"/>
      <geom name="toe" type="sphere" size="0.01" pos="0.03 0 0" density="3000" contype="0"
            conaffinity="0"/>
    </body>
    <body name="shin" pos="0.2 0 0.01">
      <freejoint/>
      <geom name="shin" type="capsule" size="0.01 0.03" euler="0 60 0" density="2000"
            contype="0" conaffinity="0"/>
    </body>
    <body name="free" pos="0.5 0 0.1">
      <freejoint/>
      <geom name="loose" type="box" size="0.01 0.01 0.01" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>
"""


def _model(low_speed="stick", geoms=("heel", "toe", "shin")):
    spec = mujoco.MjSpec.from_string(_SCENE.format(low_speed=low_speed))
    names = mjrft.add_sensors(spec, list(geoms))
    return mjrft.load_model(spec), names


def _reading(data, name):
    return data.sensor(name).data.copy()


def _moved(wrench, frm, to):
    """A wrench (force, torque about frm), world frame, with its torque taken about `to`."""
    out = wrench.copy()
    out[3:] += np.cross(np.asarray(frm) - np.asarray(to), wrench[:3])
    return out


@pytest.mark.parametrize("low_speed", ["stick", "off"])
def test_readings_add_up_to_the_applied_wrench(low_speed):
    model, names = _model(low_speed)
    data = mujoco.MjData(model)
    field = mjrft.GranularField(model)
    foot = model.body("foot").id
    for _ in range(300):
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        total = np.zeros(6)
        for name, geom in zip(names[:2], ("heel", "toe"), strict=True):
            r = _reading(data, name)
            total += _moved(r[:6], data.geom(geom).xpos, data.xipos[foot])
        applied = field.wrench_of(data)[foot]
        scale = np.abs(applied).max() + 1e-300
        np.testing.assert_allclose(total, applied, rtol=0, atol=ROUNDOFF * scale * 10)
    assert np.abs(applied[2]) > 0.1  # the foot is in the medium and carried by it


def test_single_geom_reading_is_the_body_wrench_and_the_pure_model():
    model, names = _model("off")
    data = mujoco.MjData(model)
    field = mjrft.GranularField(model)
    shin = model.body("shin").id
    data.qvel[6:9] = [0.05, 0.0, -0.1]  # the shin's free joint: moving into the medium
    mujoco.mj_forward(model, data)
    reading = _reading(data, names[2])
    applied = _moved(field.wrench_of(data)[shin], data.xipos[shin], data.geom("shin").xpos)
    np.testing.assert_allclose(reading[:6], applied, rtol=0, atol=ROUNDOFF * np.abs(applied).max())
    # the pure model's per-triangle forces (element_states), summed independently
    (state,) = [s for s in field.element_states(data) if s.body == shin]
    force = state.force.sum(axis=0)
    torque = np.cross(state.pos - data.geom("shin").xpos, state.force).sum(axis=0)
    np.testing.assert_allclose(reading[:3], force, rtol=0, atol=ROUNDOFF * np.abs(force).max())
    np.testing.assert_allclose(reading[3:6], torque, rtol=0, atol=1e-10 * np.abs(torque).max())
    assert np.abs(force).max() > 0.01


def _sampled_lowest(kind, size, rot, pos, n=400_000):
    """Lowest z [m] of a primitive, from a dense sample of its surface (geom frame -> world)."""
    rng = np.random.default_rng(7)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    if kind == "sphere":
        p = size[0] * u
    elif kind == "ellipsoid":
        p = u * np.asarray(size)
    elif kind == "box":
        p = np.sign(u) * np.asarray(size)  # corners and edges included
    elif kind in ("capsule", "cylinder"):
        r, h = size[0], size[1]
        t = rng.uniform(-1, 1, n)
        ring = u[:, :2] / np.linalg.norm(u[:, :2], axis=1, keepdims=True)
        if kind == "capsule":
            p = np.concatenate([np.c_[r * ring, h * t], r * u + [0, 0, h], r * u - [0, 0, h]])
        else:
            p = np.concatenate([np.c_[r * ring, h * np.sign(t)], np.c_[r * ring, h * t]])
    return float((p @ rot.T + pos)[:, 2].min())


@pytest.mark.parametrize(
    ("kind", "size"),
    [
        ("sphere", "0.02"),
        ("capsule", "0.01 0.03"),
        ("cylinder", "0.015 0.02"),
        ("ellipsoid", "0.02 0.01 0.015"),
        ("box", "0.02 0.01 0.015"),
    ],
)
def test_sinkage_is_the_depth_of_the_lowest_point(kind, size):
    xml = f"""
    <mujoco>
      <custom>
        <numeric name="mjrft:zeta" data="1e6"/>
        <numeric name="mjrft:surface_z" data="0.01"/>
        <tuple name="mjrft:intruders"><element objtype="geom" objname="g" prm="100"/></tuple>
      </custom>
      <worldbody>
        <body name="b" pos="0.1 -0.2 0.004" euler="23 41 -67">
          <freejoint/>
          <geom name="g" type="{kind}" size="{size}" contype="0" conaffinity="0"/>
        </body>
      </worldbody>
    </mujoco>"""
    spec = mujoco.MjSpec.from_string(xml)
    (name,) = mjrft.add_sensors(spec)  # every intruder geom
    model = mjrft.load_model(spec)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    g = data.geom("g")
    low = _sampled_lowest(kind, model.geom_size[g.id], g.xmat.reshape(3, 3), g.xpos)
    # the sample's lowest point is above the true one by at most its spacing's square (~1e-8 m)
    assert _reading(data, name)[6] == pytest.approx(0.01 - low, abs=2e-6)
    assert _reading(data, name)[6] > 0.0


def test_sensor_data_layout_and_names():
    model, names = _model()
    assert names == ["rft:heel", "rft:toe", "rft:shin"]
    assert len(READING) == 7
    assert all(model.sensor(n).dim[0] == len(READING) for n in names)


def test_a_sensor_on_a_geom_the_medium_does_not_act_on_is_refused_by_name():
    with pytest.raises(SceneError, match=r"geom 'loose' is not an intruder.*'heel'"):
        _model(geoms=("heel", "loose"))
    spec = mujoco.MjSpec.from_string(_SCENE.format(low_speed="stick"))
    spec.activate_plugin(SENSOR)
    s = spec.add_sensor(
        name="bad", type=mujoco.mjtSensor.mjSENS_PLUGIN, objtype=mujoco.mjtObj.mjOBJ_BODY,
        objname="foot",
    )  # fmt: skip
    s.plugin = spec.add_plugin(plugin_name=SENSOR, active=True)
    with pytest.raises(SceneError, match=r"sensor 'bad': objtype must be \"geom\""):
        mjrft.load_model(spec)


def test_mjcf_sensors_and_copies_read_alike():
    xml = _SCENE.format(low_speed="stick").replace(
        "</worldbody>",
        """</worldbody>
  <extension><plugin plugin="mjrft.sensor"/></extension>
  <sensor><plugin name="heel" plugin="mjrft.sensor" objtype="geom" objname="heel"/></sensor>""",
    )
    model = mjrft.load_model(xml)
    data = mujoco.MjData(model)
    for _ in range(50):
        mujoco.mj_step(model, data)
    copy = mujoco.MjData(model)
    mujoco.mj_copyData(copy, model, data)
    for _ in range(20):
        mujoco.mj_step(model, data)
        mujoco.mj_step(model, copy)
    np.testing.assert_array_equal(_reading(copy, "heel"), _reading(data, "heel"))
    assert _reading(data, "heel")[2] > 0.0


def test_rollout_threads_record_the_sensors_as_stepping_alone():
    """mujoco.rollout returns sensordata: on two threads the mjrft.sensor readings of each
    rollout equal those of stepping its initial state alone, bit for bit."""
    from mujoco import rollout

    model, _ = _model("stick")
    nroll, nstep = 4, 60
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.zeros((nroll, mujoco.mj_stateSize(model, spec)))
    rng = np.random.default_rng(3)
    for i in range(nroll):
        d = mujoco.MjData(model)
        d.qvel[2] = -rng.uniform(0.05, 0.2)  # the foot pushed down at different speeds
        mujoco.mj_getState(model, d, initial[i], spec)
    datas = [mujoco.MjData(model) for _ in range(2)]
    _, sensors = rollout.rollout(model, datas, initial, nstep=nstep)
    for i in range(nroll):
        d = mujoco.MjData(model)
        mujoco.mj_setState(model, d, initial[i], spec)
        alone = np.zeros((nstep, model.nsensordata))
        for t in range(nstep):
            mujoco.mj_step(model, d)
            alone[t] = d.sensordata
        np.testing.assert_array_equal(sensors[i], alone)
    assert np.abs(sensors[:, -1, 2]).max() > 0.0  # the heel is loaded
