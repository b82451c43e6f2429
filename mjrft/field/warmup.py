"""Compile every compiled entry point of the field now, rather than inside a first step.

numba compiles on first use and caches the machine code on disk (``cache=True``): the first run
in a new environment compiles for tens of seconds, later runs load the cache in about a second.
``warm_up`` does it up front on a tiny scene, so a caller can say so (the CLI prints it, the
tests report it) instead of charging it to whatever runs first.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from mjrft.core import kernel

_SCENE = """
<mujoco>
  <option integrator="RK4"/>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders"><element objtype="geom" objname="g" prm="48"/></tuple>
  </custom>
  <worldbody><body pos="0 0 0"><freejoint/><geom name="g" size="0.01"/></body></worldbody>
</mujoco>"""


def warm_up() -> float:
    """Compile (or load from numba's cache) the kernel, the field's pass in all its modes, the
    batch entry and the callback guard; returns the seconds it took."""
    from mjrft.field.batch import BatchedField
    from mjrft.field.granular_field import GranularField

    t0 = time.perf_counter()
    kernel.warm_up()
    model = mujoco.MjModel.from_xml_string(_SCENE)
    field = GranularField(model)
    data = mujoco.MjData(model)
    data.qvel[2] = -0.01
    mujoco.mj_forward(model, data)
    field.wrench(data)
    field.element_states(data)
    with field.installed():
        mujoco.mj_step(model, data)
    batch = BatchedField(field, nsim=1, nthread=1)
    batch.step()
    batch.close()
    assert np.all(np.isfinite(data.qpos))
    return time.perf_counter() - t0
