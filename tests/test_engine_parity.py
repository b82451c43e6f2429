"""The C++ engine plugin against the compiled numba pass, step by step on the golden scenes.

Each scene runs twice in lockstep from the same state: once with the numba field installed
(``GranularField.installed``), once as a model carrying the ``mjrft.granular`` plugin
(``mjrft.field.plugin.load_model``). Every step, the tagged bodies' rows of ``xfrc_applied``
(user part + RFT, world frame) and the states are compared. Same operation order, so the target
is equality; WRENCH_RTOL bounds what rounding could leave if an operation order ever differed.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjrft import simulate
from mjrft.field import plugin
from mjrft.field.numba_field import GranularField as NumbaField

from golden_runs import MODELS, THROWN

#: Relative difference allowed between the engines' wrenches (issue: 1e-12 relative) and the
#: absolute floor under which a component counts as zero [N, N m].
WRENCH_RTOL, WRENCH_ATOL = 1e-12, 1e-12
#: Allowed difference of the trajectories over a scene [m, rad, m/s].
STATE_ATOL = 1e-9


def _lockstep(source: str, steps: int, *, integrator=None, n_triangles=None, prepare=None,
              each=None) -> dict:  # fmt: skip
    if source.endswith(".xml"):
        from mjrft.field.numba_field import load_plain  # userdata for the ground

        numba_model = load_plain(source)
    else:
        numba_model = mujoco.MjModel.from_xml_string(source)
    plugin_model = plugin.load_model(source, n_triangles=n_triangles)
    worst = {"wrench": 0.0, "state": 0.0, "acting": 0}
    models = (numba_model, plugin_model)
    for m in models:
        simulate.configure(m, None, integrator)
    field = NumbaField(numba_model, n_triangles=n_triangles)
    datas = [simulate.reset_data(m, 0) for m in models]
    if prepare is not None:
        for d in datas:
            prepare(d)
    rows = field.body_ids
    with field.installed():
        for i in range(steps):
            for m, d in zip(models, datas, strict=True):
                if each is not None:
                    each(i, m, d)
                mujoco.mj_step(m, d)
            a, b = (d.xfrc_applied[rows] for d in datas)
            scale = np.maximum(np.abs(a), WRENCH_ATOL)
            worst["wrench"] = max(worst["wrench"], float(np.max(np.abs(a - b) / scale)))
            worst["acting"] += int(np.any(a != 0))
            sa, sb = (np.concatenate([d.qpos, d.qvel]) for d in datas)
            worst["state"] = max(worst["state"], float(np.max(np.abs(sa - sb))))
    return worst


RIGS = {
    "ellipsoid_pitch_euler": ("ellipsoid_pitch", 1.0, 400, None),
    "ellipsoid_pitch_rk4": ("ellipsoid_pitch", 1.0, 400, "rk4"),
    "root_circumnutation": ("root_circumnutation", 1.0, 400, None),
    "plate_rig": ("plate_rig", 1.0, 400, None),
    "sphere_drop_euler": ("sphere_drop", 0.5, 600, None),
    "sphere_drop_rk4": ("sphere_drop", 0.5, 600, "rk4"),
    "sphere_drop_implicitfast": ("sphere_drop", 0.5, 600, "implicitfast"),
    "hexapod_sand": ("hexapod_sand", 0.5, None, None),
    "dune_drop": ("dune_drop", 0.5, None, None),
    "wheel_rig": ("wheel_rig", 0.3, None, None),
}


@pytest.mark.parametrize("name", sorted(RIGS))
def test_the_plugin_steps_the_rigs_as_the_numba_pass(name):
    model, duration, n_triangles, integrator = RIGS[name]
    path = str(MODELS / f"{model}.xml")
    steps = round(duration / mujoco.MjModel.from_xml_path(path).opt.timestep)
    worst = _lockstep(path, steps, integrator=integrator, n_triangles=n_triangles)
    assert worst["acting"] > 0, "the scene never touched the medium: it tests nothing"
    assert worst["wrench"] <= WRENCH_RTOL
    assert worst["state"] <= STATE_ATOL


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
@pytest.mark.parametrize("lowered", [False, True])
def test_the_plugin_treats_thrown_and_lowered_bodies_as_the_numba_pass(integrator, lowered):
    xml = THROWN.format(integrator=integrator, density=2500 if lowered else 8000)
    if lowered:
        xml = xml.replace('pos="0 0 0.004"', 'pos="0 0 0.0125"')

    def prepare(d):
        d.qvel[:] = (0, 0, 0, 0.2, -0.1, 0) if lowered else (0.3, -0.1, -0.5, 4.0, -2.0, 6.0)

    def each(i, m, d):
        if lowered:  # the user holds it, then lets go over 1 s: the user part of xfrc_applied
            weight = float(m.body_mass[1]) * 9.81
            d.xfrc_applied[1] = (0, 0, weight * max(0.0, 1.0 - i / 1000), 0, 0, 0)

    worst = _lockstep(xml, 1200, prepare=prepare, each=each)
    assert worst["acting"] > 0
    assert worst["wrench"] <= WRENCH_RTOL
    assert worst["state"] <= STATE_ATOL
