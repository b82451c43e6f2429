"""The wheel rig (models/wheel_rig.xml): the trends of terramechanics, at reduced size.

Single-wheel tests (Ding et al., J. Terramechanics 48, 2011; Wong, Theory of Ground Vehicles,
ch. 2) report that drawbar pull, driving torque and sinkage rise with slip, that a wheel rolling
freely (s = 0) feels a net resistance (negative drawbar pull), and that a wheel in the rut of an
earlier pass needs less torque than in fresh soil.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjrft.app import wheel

# Coarse wheel and short passes keep the tests fast; the trends hold at the full size too
# (benchmarks/wheel_slip.py, 1500 triangles, 15 cm passes).
TRIANGLES = 600
LENGTH = 0.08  # m
# 5 mm resolves a 10-17 mm sinkage (measured torque in the rut at s = 0.6: 0.984x at 5 mm,
# 0.983x at 10 mm, where the rut's walls are one cell).
CELL = 0.005  # m
# Every move takes from one vertex what it gives another: only rounding drifts the volume.
VOLUME_RTOL = 1e-9


@pytest.fixture(scope="module")
def fresh():
    return {s: wheel.run(s, length=LENGTH, n_triangles=TRIANGLES)[0] for s in (0.0, 0.3, 0.6, 0.9)}


def test_drawbar_pull_torque_and_sinkage_rise_with_slip(fresh):
    slips = sorted(fresh)
    for key in ("drawbar_pull", "torque", "sinkage"):
        values = [getattr(fresh[s], key) for s in slips]
        assert np.all(np.diff(values) > 0), (key, values)


def test_a_free_rolling_wheel_feels_resistance_and_a_slipping_one_pulls(fresh):
    assert fresh[0.0].drawbar_pull < 0.0
    assert fresh[0.9].drawbar_pull > 0.0
    # Weight 1.96 N rests on the sand alone: the wheel sinks but stays well above its axle.
    assert 0.005 < fresh[0.0].sinkage < 0.02


def test_in_its_own_rut_the_wheel_needs_less_torque():
    first, rut = wheel.run(0.6, deform_cell=CELL, length=LENGTH, n_triangles=TRIANGLES, passes=2)
    assert rut.torque < 0.99 * first.torque  # measured 0.984
    # Without memory the ground is pristine again: the two passes agree.
    a, b = wheel.run(0.6, length=LENGTH, n_triangles=TRIANGLES, passes=2)
    assert b.torque == pytest.approx(a.torque, rel=1e-3)


def test_volume_is_conserved_over_10_s_at_60_percent_slip():
    model, field, data = wheel.rig(0.6, deform_cell=CELL, n_triangles=TRIANGLES)
    while data.time < 10.0:
        mujoco.mj_step(model, data)
    soil = field.soil(data)
    excavated = soil.counters["excavated"]
    assert excavated > 1e-5  # m^3: a 0.4 m rut about 1.5 cm deep
    assert abs(soil.volume()) <= VOLUME_RTOL * excavated
    assert soil.counters["unplaced"] == 0.0


@pytest.mark.parametrize(("kwargs", "match"), [({"slip": 1.0}, "slip"),
                                               ({"slip": 0.2, "passes": 0}, "passes")])  # fmt: skip
def test_bad_input_is_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        wheel.run(**kwargs)
