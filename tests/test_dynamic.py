"""The dynamic RFT term (Material.with_dynamic, mjrft:dynamic): the momentum flux
-lambda rho_c (n . v)^2 A n on leading submerged faces, on top of either force model."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft import Material
from mjrft.core.material import MaterialWarning
from mjrft.field import GranularField, SceneError

RHO_C = 1500.0  # kg/m^3, a bulk density of glass beads
LAM = 0.8
# The term is one product per element, added to the model's force: rounding only.
RTOL = 1e-12


def random_elements(rng, n):
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    vel = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 0.5, (n, 1))
    pos = rng.uniform(-0.05, 0.05, (n, 3))
    pos[:, 2] = rng.uniform(-0.05, 0.01, n)  # most submerged, some above the surface
    area = rng.uniform(1e-6, 1e-4, n)
    return pos, normal, area, vel


@pytest.mark.parametrize("model", ["treers2021", "agarwal3d"])
def test_the_term_is_the_momentum_flux_on_leading_submerged_elements(model):
    rng = np.random.default_rng(3)
    pos, normal, area, vel = random_elements(rng, 20_000)
    static = Material.preset("glass_beads").with_model(model)
    dynamic = static.with_dynamic(RHO_C, LAM)
    assert dynamic.model == model and dynamic.dynamic == pytest.approx(RHO_C * LAM)
    f0 = mjrft.element_forces(pos, normal, area, vel, static)
    f1 = mjrft.element_forces(pos, normal, area, vel, dynamic)
    vn = np.einsum("ij,ij->i", normal, vel)
    acts = (pos[:, 2] < 0.0) & (vn > 0.0)
    want = -(RHO_C * LAM * np.where(acts, vn, 0.0) ** 2 * area)[:, None] * normal
    scale = np.abs(f1).max(axis=1, keepdims=True)
    np.testing.assert_allclose(f1 - f0, want, rtol=0, atol=1e-15 + RTOL * scale.max())
    assert np.all(f1[~acts] == 0.0)
    assert np.abs(want).max() > 1e-3 * np.abs(f0).max()  # the term is not negligible here


@pytest.mark.parametrize("model", ["treers2021", "agarwal3d"])
def test_the_term_dissipates_on_every_element(model):
    rng = np.random.default_rng(4)
    pos, normal, area, vel = random_elements(rng, 100_000)
    static = Material.preset("glass_beads").with_model(model)
    f0 = mjrft.element_forces(pos, normal, area, vel, static)
    f1 = mjrft.element_forces(pos, normal, area, vel, static.with_dynamic(RHO_C, LAM))
    p0 = np.einsum("ij,ij->i", f0, vel)
    p1 = np.einsum("ij,ij->i", f1, vel)
    acting = np.any(f1 != 0.0, axis=1)
    assert np.all(p1[acting] < 0.0), p1[acting].max()
    assert np.all(p1 <= p0 + RTOL * np.abs(p0)), (p1 - p0).max()  # it only adds dissipation


def test_off_by_default_and_zero_is_off():
    glass = Material.preset("glass_beads")
    assert glass.dynamic == 0.0 and glass.kernel_coefficients.shape == (18,)
    assert glass.with_dynamic(0.0).kernel_coefficients.shape == (18,)
    assert glass.with_dynamic(RHO_C).kernel_coefficients.shape == (19,)
    # the term goes with the medium when the model changes
    assert glass.with_dynamic(RHO_C).with_model("agarwal3d").dynamic == RHO_C


PLATE = """
<mujoco>
  <option gravity="0 0 0"/>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <text name="mjrft:low_speed" data="off"/>
    {dynamic}
    <tuple name="mjrft:intruders"><element objtype="geom" objname="plate" prm="800"/></tuple>
  </custom>
  <worldbody>
    <body name="plate" pos="{pos}"><freejoint/>
      <geom name="plate" type="box" size="{size}" density="2000"/>
    </body>
  </worldbody>
</mujoco>"""


def plate_force(size, pos, vel, dynamic=""):
    m = mjrft.load_model(
        PLATE.format(size=" ".join(map(str, size)), pos=" ".join(map(str, pos)), dynamic=dynamic)
    )
    d = mujoco.MjData(m)
    d.qvel[:3] = vel
    mujoco.mj_forward(m, d)
    return GranularField(m).wrench(d)[1, :3].copy()


DYNAMIC = f'<numeric name="mjrft:dynamic" data="{RHO_C} {LAM}"/>'


def test_a_flat_plate_pushed_down_feels_the_flux_through_its_face():
    """Horizontal plate 4 x 3 cm, 1 cm deep, pushed down at 1.5 m/s: the extra force is
    lambda rho_c v^2 A, straight up (its sides move in their own planes, its top trails)."""
    size, v = (0.02, 0.015, 0.002), 1.5
    f0 = plate_force(size, (0, 0, -0.01), (0, 0, -v))
    f1 = plate_force(size, (0, 0, -0.01), (0, 0, -v), DYNAMIC)
    want = LAM * RHO_C * v**2 * (2 * size[0]) * (2 * size[1])
    np.testing.assert_allclose(f1 - f0, [0.0, 0.0, want], rtol=RTOL, atol=RTOL * want)


def test_a_wall_cut_by_the_surface_feels_it_on_its_submerged_part_only():
    """Vertical plate 4 cm wide, 4 cm tall, its centre 3 mm above the surface, pushed sideways
    along its normal at 1 m/s: the front face's triangles the surface crosses count by their
    submerged part (kernel._cut), so the extra force is lambda rho_c v^2 w (h/2 - 3 mm)."""
    size, lift, v = (0.002, 0.02, 0.02), 0.003, 1.0
    f0 = plate_force(size, (0, 0, lift), (v, 0, 0))
    f1 = plate_force(size, (0, 0, lift), (v, 0, 0), DYNAMIC)
    want = LAM * RHO_C * v**2 * (2 * size[1]) * (size[2] - lift)
    np.testing.assert_allclose(f1 - f0, [-want, 0.0, 0.0], rtol=1e-9, atol=1e-9 * want)


SPHERE = """
<mujoco>
  <option timestep="0.0005" integrator="{integrator}"/>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    {dynamic}
    <tuple name="mjrft:intruders"><element objtype="geom" objname="ball" prm="600"/></tuple>
  </custom>
  <worldbody>
    <body name="ball" pos="0 0 0.06"><freejoint/>
      <geom name="ball" size="0.01" density="7800"/>
    </body>
  </worldbody>
</mujoco>"""


def drop(dynamic: str, integrator: str = "Euler", throw=(0.0,) * 6):
    """A 1 cm steel sphere dropped from 5 cm (enters at ~1 m/s), optionally thrown (initial
    qvel: world linear [m/s], then angular [rad/s]): (lowest centre height [m], mechanical
    energy per step [J], final speed [m/s])."""
    m = mjrft.load_model(SPHERE.format(dynamic=dynamic, integrator=integrator))
    d = mujoco.MjData(m)
    d.qvel[:] = throw
    mass, inertia, g = m.body_mass[1], m.body_inertia[1], -m.opt.gravity[2]
    energy, low = [], np.inf
    for _ in range(1200):
        mujoco.mj_step(m, d)
        w = d.qvel[3:]
        energy.append(0.5 * mass * d.qvel[:3] @ d.qvel[:3] + 0.5 * inertia @ (w * w)
                      + mass * g * d.qpos[2])  # fmt: skip
        low = min(low, d.qpos[2])
    return low, np.array(energy), float(np.linalg.norm(d.qvel))


def test_a_dropped_sphere_stops_shallower_loses_energy_every_step_and_comes_to_rest():
    low0, e0, v0 = drop("")
    low1, e1, v1 = drop(DYNAMIC)
    assert low1 > low0 + 1e-4  # the inertial term brakes the impact: it stops shallower
    for e in (e0, e1):
        # Euler's free fall loses m g^2 dt^2 / 2 per step; the medium only removes energy.
        assert np.all(np.diff(e) <= 1e-12 * np.abs(e).max()), np.diff(e).max()
    assert v0 < 1e-6 and v1 < 1e-6  # held at rest by the low-speed treatment: no v^2 left


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
def test_a_thrown_spinning_sphere_with_the_term_never_gains_energy(integrator):
    """Thrown in at 1 m/s sideways and 0.5 m/s down, spinning at 30 rad/s about a tilted axis:
    with the term on, under each integrator and the default low-speed treatment, the mechanical
    energy never rises over a step (RK4 conserves a free fall to O(dt^5); the bound is the
    rounding of the energy sum) and the sphere comes to rest."""
    _, energy, speed = drop(DYNAMIC, integrator, throw=(1.0, 0.0, -0.5, 20.0, 10.0, 20.0))
    assert np.all(np.diff(energy) <= 1e-9 * np.abs(energy).max()), np.diff(energy).max()
    assert speed < 1e-6


@pytest.mark.parametrize(("data", "message"), [
    ("-1", "rho_c = -1.0: expected a finite number >= 0"),
    ("1500 -0.5", "lambda = -0.5: expected a finite number >= 0"),
    ("1500 1 2", "expected rho_c"),
])  # fmt: skip
def test_bad_dynamic_settings_are_named(data, message):
    xml = SPHERE.format(
        dynamic=f'<numeric name="mjrft:dynamic" data="{data}"/>', integrator="Euler"
    )
    with pytest.raises(SceneError, match=f"mjrft:dynamic.*{message}"):
        mjrft.load_model(xml)


def test_a_density_in_the_wrong_units_warns_and_callables_are_refused():
    with pytest.warns(MaterialWarning, match="denser than any granular medium"):
        Material.preset("glass_beads").with_dynamic(2.0e4)  # the grains' density, say
    with pytest.raises(ValueError, match="rho_c = 1.5e\\+06 kg/m\\^3: expected 0 to 25000"):
        Material.preset("glass_beads").with_dynamic(1.5e6)  # in g/m^3: no medium is this dense
    glass = Material.preset("glass_beads")
    python = Material.from_callables(
        lambda b, g: glass.alpha_generic(b, g)[0],
        lambda b, g: glass.alpha_generic(b, g)[2],
        zeta=glass.zeta,
    )
    with pytest.raises(ValueError, match="runs in the compiled kernel only"):
        python.with_dynamic(RHO_C)


def test_the_field_and_mjrft_run_override_the_mjcf(tmp_path):
    xml = SPHERE.format(dynamic=DYNAMIC, integrator="Euler")
    assert GranularField(mjrft.load_model(xml)).material.dynamic == pytest.approx(RHO_C * LAM)
    assert GranularField(mjrft.load_model(xml, dynamic=0)).material.dynamic == 0.0
    assert GranularField(mjrft.load_model(xml, dynamic=(1000.0, 0.5))).material.dynamic == 500.0
    with pytest.raises(SceneError, match=r"dynamic = \(1, 2, 3\): expected rho_c"):
        mjrft.load_model(xml, dynamic=(1, 2, 3))
    from mjrft.app import cli

    path = tmp_path / "ball.xml"
    path.write_text(SPHERE.format(dynamic="", integrator="Euler"))
    out = tmp_path / "run"
    assert cli.main(["run", str(path), "--duration", "0.05", "--out", str(out), "--no-plots",
                     "--dynamic", "1500", "0.8"]) == 0  # fmt: skip
    args = cli.build_parser().parse_args(["run", str(path), "--duration", "1", "--out", "x",
                                          "--dynamic", "1500"])  # fmt: skip
    assert cli._scene(args, str(path))[2].material.dynamic == 1500.0


def test_the_mechanism_treatment_with_the_dynamic_term_keeps_a_trotting_robot_on_its_feet():
    """A hold's resistance is the medium's to a start from rest: evaluated at the release
    velocity -dt A W instead (tens of m/s for a light lower leg), the dynamic term's v^2 would
    make a slipping leg's wrench enormous; the Go2 trotting for 1 s then reached 1e7 rad/s."""
    from mjrft.envs import go2_sand

    model = mjrft.load_model(go2_sand.build_spec(), dynamic=1500.0)  # default: low_speed stick
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    fastest = 0.0
    for _ in range(500):
        data.ctrl[:] = go2_sand.trot_ctrl(data.time)
        mujoco.mj_step(model, data)
        fastest = max(fastest, float(np.abs(data.qvel[6:]).max()))
    # The trot's own joint speeds stay below 7 rad/s with or without the term.
    assert np.all(np.isfinite(data.qpos)) and fastest < 20.0
    assert data.xmat[1][8] > np.cos(np.radians(30.0))  # upright
