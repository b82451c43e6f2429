"""Geoms that sink without being intruders are reported (engine/watch.h): a SinkingWarning,
once per geom and MjData, naming the geom, its body and the time; switchable off."""

from __future__ import annotations

import warnings

import mujoco
import pytest

import mjrft
from mjrft.field.scene import SceneError

_XML = """
<mujoco>
  <option timestep="0.002"/>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    {extra}
    <tuple name="mjrft:intruders"><element objtype="geom" objname="foot" prm="100"/></tuple>
  </custom>
  <worldbody>
    <geom name="rock" type="sphere" size="0.05" pos="0.5 0 0"/>
    <body name="leg" pos="0 0 0.1">
      <freejoint/>
      <geom name="foot" type="sphere" size="0.01" pos="0 0 -0.05" contype="0" conaffinity="0"/>
      <geom name="knee" type="capsule" size="0.01 0.02" contype="1" conaffinity="1"/>
      <geom name="shell" type="box" size="0.05 0.05 0.05" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>"""


def _run(steps=600, extra="", **options):
    model = mjrft.load_model(_XML.format(extra=extra), low_speed="off", **options)
    data = mujoco.MjData(model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(steps):
            mujoco.mj_step(model, data)
    return [w for w in caught if issubclass(w.category, mjrft.SinkingWarning)], data


def test_an_untagged_collision_geom_below_the_surface_is_reported_once_by_name():
    reports, data = _run()
    assert len(reports) == 1  # the knee only: not the tagged foot, the visual shell, the rock
    text = str(reports[0].message)
    assert "geom 'knee' of body 'leg'" in text and "not an intruder" in text
    t = float(text.split("at time ")[1].split(" s")[0])
    assert 0.0 < t < data.time  # when it happened, not when the run ended
    assert data.geom("knee").xpos[2] < 0.0  # it did sink: the report was not spurious


def test_nothing_is_reported_above_the_surface():
    reports, data = _run(steps=20)
    assert reports == []
    assert data.geom("knee").xpos[2] - 0.03 > 0.0  # still above the surface


def test_the_check_is_switched_off_by_option_or_mjcf():
    assert _run(watch_sinking=False)[0] == []
    assert _run(extra='<numeric name="mjrft:watch_sinking" data="0"/>')[0] == []
    with pytest.raises(SceneError, match="watch_sinking"):
        _run(extra='<numeric name="mjrft:watch_sinking" data="2"/>')
    with pytest.raises(SceneError, match="watch_sinking"):
        _run(watch_sinking="no")


def test_a_copy_does_not_report_again():
    model = mjrft.load_model(_XML.format(extra=""), low_speed="off")
    data = mujoco.MjData(model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(600):
            mujoco.mj_step(model, data)
        copy = mujoco.MjData(model)
        mujoco.mj_copyData(copy, model, data)
        for _ in range(10):
            mujoco.mj_step(model, copy)
    assert sum(issubclass(w.category, mjrft.SinkingWarning) for w in caught) == 1
