"""A run says when it leaves the quasi-static regime (mjrft.app.regime): the Froude number
v^2 / (g L) of each body in the medium, checked against analytic values."""

from __future__ import annotations

import warnings

import pytest

import mjrft
from mjrft.app import regime, simulate

DROP = """<mujoco><option timestep="0.0005"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="ball" prm="300"/></tuple></custom>
<worldbody><body name="ball" pos="0 0 {z}"><freejoint/>
<geom name="ball" size="0.01" density="7800"/></body></worldbody></mujoco>"""


def test_a_sphere_dropped_from_5_cm_leaves_the_quasi_static_regime():
    """Falling h = 5 cm, a 1 cm sphere enters at sqrt(2 g h): Fr = 2 h / L = 5 (L its
    diameter); the first check in the medium sees about that, and the run warns once."""
    h, radius = 0.05, 0.01
    m = mjrft.load_model(DROP.format(z=radius + h))
    with pytest.warns(regime.QuasiStaticWarning, match="'ball'.*Froude number") as caught:
        _, rec = simulate.run(m, 0.2, record_every=10)
    assert len(caught) == 1
    # The mesh's centroid extent is a little under the diameter; the check runs every 5 ms.
    assert rec.max_froude["ball"] == pytest.approx(2 * h / (2 * radius), rel=0.15)


def test_a_slow_rig_stays_quasi_static_and_says_nothing():
    """The plate rig moves at 1 cm/s: Fr = v^2 / (g L) = 2.0e-4 for its 5.1 cm plate."""
    m = simulate.load_model("plate_rig")
    with warnings.catch_warnings():
        warnings.simplefilter("error", regime.QuasiStaticWarning)
        _, rec = simulate.run(m, 1.0, record_every=10)
    # L: the plate's largest extent in its own frame, its 5.1 cm side (less a triangle).
    assert rec.max_froude["plate"] == pytest.approx(0.01**2 / (9.81 * 0.051), rel=0.01)
