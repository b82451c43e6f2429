"""docs/choosing_zeta.md's sinkage formulas against the engine: a loaded foot on a vertical slider
settles where the formula says, pushed in slowly (damped) or set down at the surface and let go."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.optimize import brentq

import mjrft

G = 9.81
# Li's generic set: alpha_z of a face tilted theta from level, pushed straight down, is
# A + B cos(2 theta) with A = A00 + B01 and B = A10 + B11 + B-11.
LI = mjrft.LI_GENERIC.as_mapping()
A = LI["A00"] + LI["B01"]
B = LI["A10"] + LI["B11"] + LI["B-11"]


def plate_force(depth: float, area: float, zeta: float) -> float:
    """[N] on a horizontal plate of area [m^2] pushed straight down at depth [m]."""
    return zeta * area * max(depth, 0.0)


def sphere_force(depth: float, radius: float, zeta: float) -> float:
    """[N] on a sphere whose lowest point is depth [m] below the surface, pushed straight down:
    2 pi R^2 zeta times the integral over u = cos(theta) of (A - B + 2 B u^2)(depth - R + R u)
    over the submerged lower hemisphere."""
    if depth <= 0.0:
        return 0.0
    a, b, c = A - B, 2.0 * B, depth - radius
    u0 = max(0.0, 1.0 - depth / radius)

    def antiderivative(u: float) -> float:
        return a * c * u + a * radius * u**2 / 2 + b * c * u**3 / 3 + b * radius * u**4 / 4

    return 2.0 * math.pi * radius**2 * zeta * (antiderivative(1.0) - antiderivative(u0))


def static_depth(force, weight: float) -> float:
    """Depth [m] where force(depth) = weight."""
    return brentq(lambda d: force(d) - weight, 1e-9, 10.0, xtol=1e-12)


def drop_depth(force, weight: float) -> float:
    """Depth [m] where a foot let go at rest at the surface stops: the weight's work equals the
    force's (RFT gives nothing back on the way up)."""
    from scipy.integrate import quad

    return brentq(lambda d: quad(force, 0.0, d)[0] - weight * d, 1e-6, 10.0, xtol=1e-12)


def settle(geom: str, bottom: float, mass: float, zeta: float, damping: float) -> float:
    """Final depth [m] of a foot's lowest point after 4 s on a vertical slider with this damping
    [N s/m], released at rest with its lowest point at the surface."""
    xml = f"""<mujoco><option timestep="0.001"/>
      <custom><numeric name="mjrft:zeta" data="{zeta}"/>
        <text name="mjrft:intruders_match" data="foot"/></custom>
      <worldbody><body name="leg" pos="0 0 {bottom}">
        <joint type="slide" axis="0 0 1" damping="{damping}"/>
        <geom name="foot" {geom} mass="{mass}" contype="0" conaffinity="0"/>
      </body></worldbody></mujoco>"""
    model = mjrft.load_model(xml, n_triangles=1000)
    data = mujoco.MjData(model)
    for _ in range(4000):
        mujoco.mj_step(model, data)
    assert abs(data.qvel[0]) < 1e-6  # at rest [m/s]
    return -float(data.qpos[0])


SPHERE = 'size="0.022"'
PLATE = 'type="box" size="0.03 0.03 0.005"'  # a 6 x 6 cm plate, 1 cm thick
#: Relative tolerance of a settled depth: the meshes' force error at 1000 triangles (0.06 % on
#: the sphere, 0.4 % on the plate measured) and the sphere's faceting.
RTOL = 0.01


@pytest.mark.parametrize("zeta", [1e6, 2e6])
@pytest.mark.parametrize("mass", [1.0, 3.0])
def test_a_foot_pushed_in_slowly_settles_at_the_static_depth(mass, zeta):
    """Overdamped (4 sqrt(k m) with k the force's slope at the static depth): the foot creeps
    down without overshoot and stops where the medium carries its weight."""
    weight = mass * G
    for geom, bottom, force in (
        (SPHERE, 0.022, lambda d: sphere_force(d, 0.022, zeta)),
        (PLATE, 0.005, lambda d: plate_force(d, 0.06**2, zeta)),
    ):
        expected = static_depth(force, weight)
        slope = (force(expected * 1.01) - force(expected * 0.99)) / (0.02 * expected)
        got = settle(geom, bottom, mass, zeta, damping=4.0 * math.sqrt(slope * mass))
        assert got == pytest.approx(expected, rel=RTOL), geom


@pytest.mark.parametrize("zeta", [1e6, 2e6])
def test_a_foot_let_go_at_the_surface_stops_at_the_drop_depth(zeta):
    """Undamped: it overshoots to where the weight's work equals the medium's, twice the static
    depth for a plate (a spring that gives nothing back), and stays there."""
    mass = 3.0
    weight = mass * G
    plate = lambda d: plate_force(d, 0.06**2, zeta)  # noqa: E731
    assert drop_depth(plate, weight) == pytest.approx(2.0 * static_depth(plate, weight))
    for geom, bottom, force in (
        (SPHERE, 0.022, lambda d: sphere_force(d, 0.022, zeta)),
        (PLATE, 0.005, plate),
    ):
        got = settle(geom, bottom, mass, zeta, damping=0.0)
        assert got == pytest.approx(drop_depth(force, weight), rel=RTOL), geom
        assert got > 1.5 * static_depth(force, weight)


def test_the_sphere_formula_is_the_engines_force():
    """The formula against the engine's force on a sphere held at depth, moving down slowly."""
    xml = """<mujoco><custom><numeric name="mjrft:zeta" data="1e6"/>
      <text name="mjrft:intruders_match" data="foot"/></custom>
      <worldbody><body pos="0 0 0.1"><freejoint/><geom name="foot" size="0.022"/></body>
      </worldbody></mujoco>"""
    model = mjrft.load_model(xml, low_speed="off", n_triangles=4000)
    fld = mjrft.GranularField(model)
    data = mujoco.MjData(model)
    for depth in (0.005, 0.011, 0.022, 0.036, 0.06):
        data.qpos[2] = 0.022 - depth
        data.qvel[:] = [0.0, 0.0, -0.01, 0.0, 0.0, 0.0]
        mujoco.mj_forward(model, data)
        # 4000 triangles: the mesh's force error is below 0.1 % (0.03 % measured at 1 R).
        assert fld.wrench_of(data)[1, 2] == pytest.approx(sphere_force(depth, 0.022, 1e6), rel=1e-3)
    assert np.isclose(A + B, 1.0)  # the generic set's normalisation: alpha_z(0, pi/2) = 1
