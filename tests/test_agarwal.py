"""The agarwal3d force model (mjrft.core.agarwal): the engine's kernel against a slow
reference, dissipation, its limiting case, its symmetry, and the field running it."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from agarwal_reference import element_force

import mjrft
from mjrft import Material
from mjrft.core import agarwal
from mjrft.core.material import AGARWAL_PLATE_DOWN
from mjrft.field import GranularField, SceneError

GLASS = Material.preset("glass_beads").with_model("agarwal3d")
# Both evaluate the same closed form in float64, in different orders: rounding only.
REFERENCE_RTOL = 1e-12


def random_elements(rng, n, submerged=True):
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    vel = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 0, (n, 1))
    flip = np.einsum("ij,ij->i", normal, vel) < 0.0
    vel[flip] *= -1.0  # leading
    pos = rng.uniform(-0.05, 0.05, (n, 3))
    pos[:, 2] = -rng.uniform(1e-4, 0.05, n) if submerged else rng.uniform(1e-4, 0.05, n)
    area = rng.uniform(1e-6, 1e-4, n)
    return pos, normal, area, vel


def test_the_kernel_equals_the_slow_reference():
    rng = np.random.default_rng(0)
    pos, normal, area, vel = random_elements(rng, 3000)
    # Special directions: vertical motion, vertical normals, a horizontal plate pushed down.
    normal[:3] = [[0, 0, -1], [0, 0, -1], [0.6, 0, -0.8]]
    vel[:3] = [[0, 0, -0.1], [0.05, 0.02, -0.1], [0, 0, -0.1]]
    got = mjrft.element_forces(pos, normal, area, vel, GLASS)
    xi, mu = GLASS.agarwal[agarwal.XI_N], GLASS.agarwal[agarwal.MU_SURF]
    want = np.array([element_force(*e, xi, mu) for e in zip(pos, normal, area, vel, strict=True)])
    scale = np.abs(want).max()
    np.testing.assert_allclose(got, want, rtol=REFERENCE_RTOL, atol=REFERENCE_RTOL * scale)
    capped = Material.agarwal3d(GLASS.agarwal[agarwal.XI_N], 0.2)  # friction caps some
    got = mjrft.element_forces(pos, normal, area, vel, capped)
    want = np.array([element_force(*e, xi, 0.2) for e in zip(pos, normal, area, vel, strict=True)])
    np.testing.assert_allclose(got, want, rtol=REFERENCE_RTOL, atol=REFERENCE_RTOL * scale)
    assert not np.allclose(got, mjrft.element_forces(pos, normal, area, vel, GLASS))


def test_every_leading_element_dissipates_and_nothing_acts_above_or_behind():
    rng = np.random.default_rng(1)
    pos, normal, area, vel = random_elements(rng, 100_000)
    f = mjrft.element_forces(pos, normal, area, vel, GLASS)
    power = np.einsum("ij,ij->i", f, vel)
    assert np.all(power < 0.0), power.max()
    above = random_elements(rng, 1000, submerged=False)
    assert not np.any(mjrft.element_forces(*above, GLASS))
    p, n, a, v = random_elements(rng, 1000)
    assert not np.any(mjrft.element_forces(p, n, a, -v, GLASS))  # trailing


def test_linear_in_area_and_depth():
    rng = np.random.default_rng(2)
    pos, normal, area, vel = random_elements(rng, 500)
    f = mjrft.element_forces(pos, normal, area, vel, GLASS)
    np.testing.assert_allclose(mjrft.element_forces(pos, normal, 3 * area, vel, GLASS), 3 * f,
                               rtol=1e-14)  # fmt: skip
    deeper = pos.copy()
    deeper[:, 2] *= 2.0
    np.testing.assert_allclose(mjrft.element_forces(deeper, normal, area, vel, GLASS), 2 * f,
                               rtol=1e-14)  # fmt: skip


def test_a_plate_pushed_straight_down_feels_the_sum_of_the_table():
    """x1 = x2 = x3 = 1 there, so alpha = -(sum C1 + sum C2 + sum C3) along +z; the scale
    matched to glass_beads gives Treers' glass-bead force exactly."""
    pos, normal, area, vel = [[0, 0, -0.02]], [[0, 0, -1.0]], [1e-4], [[0, 0, -0.01]]
    table = sum(agarwal.C1) + sum(agarwal.C2) + sum(agarwal.C3)
    f = mjrft.element_forces(pos, normal, area, vel, GLASS)[0]
    xi = GLASS.agarwal[agarwal.XI_N]
    # cos(pi / 2) rounds to 6e-17, not 0: the horizontal part is rounding.
    np.testing.assert_allclose(f, [0.0, 0.0, -table * xi * 0.02 * 1e-4], rtol=1e-14,
                               atol=1e-15 * abs(f[2]))  # fmt: skip
    treers = mjrft.element_forces(pos, normal, area, vel, Material.preset("glass_beads"))[0]
    assert f[2] == pytest.approx(treers[2], rel=1e-12)
    assert table == pytest.approx(-0.87504, abs=1e-12) and AGARWAL_PLATE_DOWN == -table


def test_turning_the_motion_about_the_vertical_turns_the_force():
    """The model is isotropic in the horizontal plane: yawing normal and velocity together
    yaws the force."""
    rng = np.random.default_rng(3)
    pos, normal, area, vel = random_elements(rng, 2000)
    f = mjrft.element_forces(pos, normal, area, vel, GLASS)
    yaw = 0.7
    rz = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                   [0, 0, 1]])  # fmt: skip
    g = mjrft.element_forces(pos @ rz.T, normal @ rz.T, area, vel @ rz.T, GLASS)
    np.testing.assert_allclose(g, f @ rz.T, rtol=1e-9, atol=1e-12 * np.abs(f).max())


SPHERE = """<mujoco><option timestep="0.001"/>
<custom><text name="mjrft:material" data="glass_beads"/>{model}
<tuple name="mjrft:intruders"><element objtype="geom" objname="ball" prm="400"/></tuple></custom>
<worldbody><body name="ball" pos="0 0 0.011"><freejoint/>
<geom name="ball" size="0.01" density="7800"/></body></worldbody></mujoco>"""


def test_the_field_runs_the_model_the_mjcf_names():
    m = mjrft.load_model(SPHERE.format(model='<text name="mjrft:model" data="agarwal3d"/>'))
    field = GranularField(m)
    assert field.scene.material.model == "agarwal3d"
    d = mujoco.MjData(m)
    for _ in range(300):
        mujoco.mj_step(m, d)
    assert np.all(np.isfinite(d.qpos)) and d.qpos[2] < 0.01  # it fell in and was held
    d.qvel[:3] = [0.02, 0.0, -0.05]  # the pure model at a motion (at rest nothing acts)
    mujoco.mj_forward(m, d)
    (st,) = field.element_states(d)
    assert np.abs(st.force).max() > 0.0
    xi, mu = (field.scene.material.agarwal[i] for i in (agarwal.XI_N, agarwal.MU_SURF))
    want = np.array([element_force(*e, xi, mu)
                     for e in zip(st.pos, st.normal, st.area, st.vel, strict=True)])  # fmt: skip
    np.testing.assert_allclose(st.force, want, rtol=REFERENCE_RTOL,
                               atol=REFERENCE_RTOL * np.abs(want).max())  # fmt: skip
    plain = GranularField(mjrft.load_model(SPHERE.format(model="")))
    assert plain.scene.material.model == "treers2021"


@pytest.mark.parametrize(("extra", "message"), [
    ('<text name="mjrft:model" data="agarwal"/>', "unknown force model; valid: treers2021"),
    ('<text name="mjrft:model" data="agarwal3d"/><numeric name="mjrft:mu_surf" data="-1"/>',
     "mu_surf"),
])  # fmt: skip
def test_bad_model_settings_are_named(extra, message):
    with pytest.raises(SceneError, match=message):
        mjrft.load_model(SPHERE.format(model=extra))


def test_a_material_without_the_models_scale_is_refused():
    li = Material.preset("glass_beads").fourier
    callables = Material.from_callables(li.alpha_x, li.alpha_z, zeta=3.3e5, name="mine")
    with pytest.raises(ValueError, match="given by callables"):
        callables.with_model("agarwal3d")
    with pytest.raises(ValueError, match="unknown force model"):
        GLASS.with_model("rft2013")
    with pytest.raises(ValueError, match="is an agarwal3d medium"):
        GLASS.with_model("treers2021")
    rough = GLASS.with_model("agarwal3d", mu_surf=0.3)
    assert rough.agarwal[agarwal.MU_SURF] == 0.3
    assert rough.agarwal[agarwal.XI_N] == GLASS.agarwal[agarwal.XI_N]
