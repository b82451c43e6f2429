"""mjrft.warp on Warp's CPU device: the same RFT forces as the C++ engine, world by world.

MuJoCo Warp gets each rig compiled without the engine plugin (it runs no C plugins); the CPU
side is the same rig loaded with the engine (``mjrft.load_model``) and stepped by MuJoCo; here
both run the pure model (``low_speed="off"``; the treatment: tests/test_warp_lowspeed.py).

Warp compiles each kernel module once and caches it (~/.cache/warp); MuJoCo Warp's own step
compiles for a few seconds per model on first use.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")

import mujoco_warp as mjw
import warp as wp
from mjrft.envs import hexapod_sand
from warp_worlds import put, world_kinematics

import mjrft
import mjrft.warp as mw
from mjrft import Material
from mjrft.app.simulate import models_dir
from mjrft.field import GranularField

DEVICE = "cpu"
wp.config.quiet = True  # no line per kernel module loaded
# The Warp law is the engine's equations in float64 with libm tanh and log (the engine uses
# polynomials accurate to ~2e-15): the two agree to rounding.
RTOL_LAW = 1e-12
# Wrenches: the same quadrature on the same states, summed in another order.
RTOL_WRENCH = 1e-12
# Trajectories: MuJoCo Warp steps in float32 (single-precision kinematics, constraint solver
# and integration), the CPU reference in float64; over 200 steps of 1 ms the measured gap is
# 1.9e-5 m (hexapod), 6e-7 rad (ellipsoid rig) and 2e-6 m (sphere); this bound leaves 5x.
ATOL_QPOS = 1e-4
NWORLD = 4


def random_elements(rng, n):
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    normal[: n // 20] = [0.0, 0.0, 1.0]  # horizontal plates: the frame from v
    normal[n // 20 : n // 10] = [0.0, 0.0, -1.0]
    vel = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 0.5, (n, 1))
    vel[: n // 40, :2] = 0.0  # horizontal plates moving straight up or down: world x frame
    vel[n // 10 : n // 10 + 10] = 0.0  # at rest
    pos = rng.uniform(-0.05, 0.05, (n, 3))
    pos[:, 2] = rng.uniform(-0.05, 0.01, n)
    area = rng.uniform(1e-6, 1e-4, n)
    return pos, normal, area, vel


def assert_forces_close(got, want, rtol):
    scale = np.linalg.norm(want, axis=1)
    err = np.linalg.norm(got - want, axis=1)
    assert np.all(err <= rtol * scale), (err / np.maximum(scale, 1e-300)).max()


@pytest.mark.parametrize("dynamic", [False, True])
@pytest.mark.parametrize("preset", ["glass_beads", "poppy_seeds_lp"])
def test_the_warp_law_equals_element_forces(preset, dynamic):
    rng = np.random.default_rng(11)
    pos, normal, area, vel = random_elements(rng, 20_000)
    material = Material.preset(preset)
    if dynamic:
        material = material.with_dynamic(1500.0, 0.8)
    want = mjrft.element_forces(pos, normal, area, vel, material, surface_z=0.002)
    given = material if dynamic else preset  # a preset's name is the preset
    got = mw.element_forces(pos, normal, area, vel, given, surface_z=0.002, device=DEVICE)
    assert np.count_nonzero(np.any(want != 0.0, axis=1)) > 5000  # the test has teeth
    assert_forces_close(got, want, RTOL_LAW)


def spec_of(name: str) -> mujoco.MjSpec:
    """A rig of models/; "hexapod_slope": the hexapod on a plane tilted 12 deg (downhill +x)."""
    if name == "hexapod_slope":
        return hexapod_sand.build_spec(slope=(12.0, 0.0))
    return mujoco.MjSpec.from_file(str(models_dir() / f"{name}.xml"))


def load(name: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The rig compiled without the engine (MuJoCo Warp's model), and its keyframe's MjData."""
    mjm = spec_of(name).compile()
    mjd = mujoco.MjData(mjm)
    if mjm.nkey:
        mujoco.mj_resetDataKeyframe(mjm, mjd, 0)
    return mjm, mjd


def load_cpu(
    name: str, low_speed: str = "off"
) -> tuple[mujoco.MjModel, mujoco.MjData, GranularField]:
    """The rig with the engine (default: the pure model, low_speed="off"), an MjData, its
    field."""
    model = mjrft.load_model(spec_of(name), low_speed=low_speed)
    return model, mujoco.MjData(model), GranularField(model)


def initial_states(name, mjm, mjd):
    """(NWORLD, nq), (NWORLD, nv): four different states that intrude."""
    qpos = np.tile(mjd.qpos, (NWORLD, 1))
    qvel = np.zeros((NWORLD, mjm.nv))
    for w in range(NWORLD):
        if name == "sphere_drop":  # lowered, thrown sideways and spinning
            qpos[w, 2] = 0.008 - 0.005 * w
            qvel[w, :6] = [0.1 * w, 0.0, -0.2, 0.0, 3.0, 0.0]
        elif name in ("hexapod_sand", "hexapod_slope"):  # the legs stand in the medium
            qpos[w, 2] = 0.035 - 0.004 * w
            qvel[w, :3] = [0.05 * w, 0.0, -0.1]
        elif name == "dune_drop":  # the three spheres pushed into the dune, moving
            for j in range(3):
                qpos[w, 7 * j + 2] -= 0.004 + 0.003 * w
                qvel[w, 6 * j : 6 * j + 6] = [0.05 * w, -0.03, -0.1, 2.0, 0.0, 1.0]
        else:  # the ellipsoid rig: every joint moving
            qvel[w] = 0.5 * (w + 1) * np.random.default_rng(w).normal(size=mjm.nv)
    return qpos, qvel


@pytest.mark.parametrize(
    "name", ["sphere_drop", "hexapod_sand", "ellipsoid_pitch", "hexapod_slope", "dune_drop"]
)
def test_wrenches_equal_the_cpu_field_on_the_same_states(name):
    mjm, mjd = load(name)
    field = mw.WarpField(mjm, device=DEVICE, store_element_forces=True, low_speed="off")
    qpos, qvel = initial_states(name, mjm, mjd)
    m, d = put(mjm, mjd, qpos, qvel)
    if name == "ellipsoid_pitch":  # drive the rig into the medium first
        field.install(m)
        for _ in range(300):
            mjw.step(m, d)
    mjw.forward(m, d)
    field.compute(d)
    got = field.wrenches(d)
    elem = field.element_forces_of(d)
    _, cpu_d, cpu = load_cpu(name)
    sizes = [len(b.areas) for b in cpu.bodies]
    offsets = {b.body: int(o) for b, o in zip(cpu.bodies, np.cumsum([0, *sizes[:-1]]), strict=True)}
    acting = 0
    for w in range(NWORLD):
        world_kinematics(cpu_d, d, w)
        want = cpu.wrench(cpu_d)
        assert np.abs(want).max() > 0.0
        np.testing.assert_allclose(got[w], want, rtol=0, atol=RTOL_WRENCH * np.abs(want).max())
        for st in cpu.element_states(cpu_d):  # per element, where the engine evaluated
            offset = offsets[st.body]  # the Warp field's elements: the bodies' blocks in order
            assert_forces_close(elem[w, offset + st.index], st.force, RTOL_WRENCH)
            acting += np.count_nonzero(np.any(st.force != 0.0, axis=1))
    assert acting > 50


def cpu_trajectory(model, data, qpos, qvel, nstep):
    """qpos after nstep mj_steps of the engine's model (the engine in every step) from the
    keyframe (or the reset state) with qpos, qvel."""
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    else:
        mujoco.mj_resetData(model, data)
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    for _ in range(nstep):
        mujoco.mj_step(model, data)
    return data.qpos.copy()


@pytest.mark.parametrize(
    ("name", "nstep", "low_speed"),
    [("sphere_drop", 60, "off"), ("hexapod_sand", 200, "off"), ("ellipsoid_pitch", 200, "off"),
     ("hexapod_sand", 200, "stick"), ("ellipsoid_pitch", 200, "stick")],
)  # fmt: skip
def test_trajectories_follow_the_cpu_field_world_by_world(name, nstep, low_speed):
    """Four worlds moving through the medium, with the pure model and with the low-speed
    treatment (the legs and the rig's carriage in mechanisms: held, slipping or pure as they
    move), each against the engine stepped alone."""
    mjm, mjd = load(name)
    assert mjm.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    field = mw.WarpField(mjm, device=DEVICE, low_speed=low_speed)
    qpos, qvel = initial_states(name, mjm, mjd)
    m, d = put(mjm, mjd, qpos, qvel)
    with field.installed(m, d):
        for _ in range(nstep):
            mjw.step(m, d)
    got = d.qpos.numpy()
    cpu_model, cpu_d, _ = load_cpu(name, low_speed)
    for w in range(NWORLD):
        want = cpu_trajectory(cpu_model, cpu_d, qpos[w], qvel[w], nstep)
        moved = np.abs(want - qpos[w]).max()
        assert moved > 20 * ATOL_QPOS  # the run goes somewhere
        np.testing.assert_allclose(got[w], want, rtol=0, atol=ATOL_QPOS)


def test_a_geom_above_the_surface_is_culled_and_feels_nothing():
    mjm, mjd = load("sphere_drop")
    field = mw.WarpField(mjm, device=DEVICE, store_element_forces=True)
    qpos = np.tile(mjd.qpos, (2, 1))
    qpos[0, 2] = 0.05  # 4 cm above the surface
    qpos[1, 2] = -0.005
    qvel = np.zeros((2, mjm.nv))
    qvel[:, 2] = -0.1
    m, d = put(mjm, mjd, qpos, qvel)
    mjw.forward(m, d)
    field.compute(d)
    cull = field._worlds_of(d).cull.numpy()
    assert cull[0, 0] == 1 and cull[1, 0] == 0
    w = field.wrenches(d)
    assert np.all(w[0] == 0.0) and w[1, 1, 2] > 0.0
    assert np.all(field.element_forces_of(d)[0] == 0.0)


def test_the_users_part_of_xfrc_applied_survives():
    mjm, mjd = load("sphere_drop")
    field = mw.WarpField(mjm, device=DEVICE)
    qpos = np.tile(mjd.qpos, (2, 1))
    qpos[:, 2] = -0.005
    m, d = put(mjm, mjd, qpos, np.zeros((2, mjm.nv)))
    user = np.zeros((2, mjm.nbody, 6), dtype=np.float32)
    user[1, 1] = [0.01, 0.0, 0.2, 0.0, 0.0, 0.001]  # a push on world 1's sphere
    d.xfrc_applied.assign(user)
    with field.installed(m, d):
        mjw.step(m, d)
        rft = field.wrenches(d)
        total = d.xfrc_applied.numpy()
        np.testing.assert_allclose(total, user + rft.astype(np.float32), rtol=0, atol=1e-7)
        pushed = total.copy()
        pushed[0, 1, 0] = 0.5  # the user assigns one component of world 0's row
        d.xfrc_applied.assign(pushed)
        mjw.step(m, d)
        rft = field.wrenches(d)
        want = user.copy()
        want[0, 1, 0] = 0.5
        np.testing.assert_allclose(
            d.xfrc_applied.numpy(), want + rft.astype(np.float32), rtol=0, atol=1e-7
        )
    np.testing.assert_array_equal(d.xfrc_applied.numpy(), want)  # the user's values, restored


def test_a_field_refuses_another_models_model_and_data_naming_both():
    mjm, mjd = load("sphere_drop")
    field = mw.WarpField(mjm, device=DEVICE)
    spec = spec_of("sphere_drop")  # the same sizes, a 4 cm box where the 1 cm sphere was
    spec.geom("sphere").type = mujoco.mjtGeom.mjGEOM_BOX
    spec.geom("sphere").size = [0.02, 0.02, 0.02]
    with pytest.raises(ValueError, match=r"not made from the WarpField's model 'sphere_drop' "
                       r"\(geom_type; the intruding geoms' geom_size differ\)"):  # fmt: skip
        field.install(mjw.put_model(spec.compile()))
    dune, dune_d = load("dune_drop")
    with pytest.raises(ValueError, match=r"sizes nq=21, nv=18, nbody=4.*not nq=7, nv=6, nbody=2"):
        field.install(mjw.put_model(dune))
    with pytest.raises(ValueError, match=r"another model \(nq=21.*'sphere_drop' \(nq=7, nv=6"):
        field.prepare(mjw.put_data(dune, dune_d, nworld=1))
    m = mjw.put_model(mjm)
    with field.installed(m):  # its own model and data are served
        field.prepare(mjw.put_data(mjm, mjd, nworld=1))


SCENE = """
<mujoco>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    {extra}
    <tuple name="mjrft:intruders"><element objtype="geom" objname="ball" prm="200"/></tuple>
  </custom>
  <worldbody>
    <body name="ball" pos="0 0 0.01"><freejoint/><geom name="ball" size="0.01"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        ('<text name="mjrft:model" data="agarwal3d"/>', "agarwal3d"),
    ],
)
def test_unsupported_scenes_are_named(extra, named):
    mjm = mujoco.MjModel.from_xml_string(SCENE.format(extra=extra))
    with pytest.raises(mw.UnsupportedScene, match=named):
        mw.WarpField(mjm, device=DEVICE)


def test_the_treatment_under_rk4_is_refused_naming_the_integrator():
    """MuJoCo Warp's RK4 runs its stage passes at the step's start time, so the engine's stage
    rule (a stuck body's wrench held over the step) cannot recognise them."""
    mjm = mujoco.MjModel.from_xml_string(SCENE.format(extra=""))
    mjm.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    field = mw.WarpField(mjm, device=DEVICE)
    with pytest.raises(ValueError, match=r"treatment is not supported under the RK4.*'off'"):
        field.install(mjw.put_model(mjm))
    mw.WarpField(mjm, device=DEVICE, low_speed="off").install(mjw.put_model(mjm))  # the pure model


def test_a_model_with_the_engine_is_refused_naming_the_plain_one():
    """MuJoCo Warp runs no C plugins (mjw.put_model cannot take a model with the engine's
    instance): WarpField says which model to give it instead."""
    mjm = mjrft.load_model(SCENE.format(extra=""))
    with pytest.raises(ValueError, match=r"carries the engine plugin.*plain model"):
        mw.WarpField(mjm, device=DEVICE)
    plain = mujoco.MjModel.from_xml_string(SCENE.format(extra=""))
    field = mw.WarpField(plain, device=DEVICE)
    assert field.nelem == GranularField(mjm).n_elements  # the engine's elements


@pytest.mark.filterwarnings("ignore::mjrft.core.material.MaterialWarning")  # a stand-in medium
def test_a_material_of_python_callables_is_named():
    mjm = mujoco.MjModel.from_xml_string(SCENE.format(extra=""))
    medium = Material.from_callables(
        lambda b, g: 0.2 + 0.0 * b, lambda b, g: 0.1 + 0.0 * b, zeta=3e5, name="my_sand"
    )
    with pytest.raises(mw.UnsupportedScene, match="callable material.*my_sand"):
        mw.WarpField(mjm, medium, device=DEVICE)


def test_a_mujoco_warp_release_of_another_mujoco_is_refused(monkeypatch):
    monkeypatch.setattr(mw, "version", lambda name: "3.16.0")
    with pytest.raises(ImportError, match=r"mujoco-warp 3\.16\.0 does not match mujoco 3\.17"):
        mw._check_versions()


def test_too_many_worlds_for_the_device_are_refused_before_allocating():
    with pytest.raises(MemoryError, match="nworld=100000"):
        mw.field.check_memory(100_000, 2_000, wp.get_device(DEVICE), free=10 * 2**20)


def test_the_gpu_benchmark_runs_on_the_cpu_device(tmp_path):
    import runpy

    bench = runpy.run_path(str(Path(__file__).resolve().parents[1] / "benchmarks" / "gpu.py"))
    out = tmp_path / "gpu.csv"
    rows = bench["main"](
        ["--device", DEVICE, "--nworld", "2", "--models", "hexapod_sand", "--steps", "20",
         "--repeats", "1", "--out", str(out)]
    )  # fmt: skip
    assert [r["field"] for r in rows] == ["off", "on", "treated", "ground", "env"]
    for r in rows:
        assert float(r["steps_per_s"]) > 0.0
    assert 0.0 < float(rows[1]["rft_share"]) < 1.0 and 0.0 < float(rows[2]["rft_share"]) < 1.0
    assert out.read_text().startswith("model,nworld,triangles,field")


@pytest.mark.parametrize("slope", [None, (10.0, 30.0)])
def test_the_vector_hexapod_observes_and_controls_as_the_dm_control_task(slope):
    from mjrft.envs import hexapod_sand

    from mjrft.warp.hexapod import OBS_SIZE, OBSERVATIONS, HexapodVecEnv

    env = hexapod_sand.make(seed=3, slope=slope)
    env.reset()
    action = np.array([1.5, 2.0])
    for _ in range(5):  # somewhere into the walk: moving, turned, tripods re-phasing
        ts = env.step(action)
    physics = env.physics
    venv = HexapodVecEnv(2, device=DEVICE, slope=slope)
    obs = venv.reset(seed=1).numpy()
    assert obs.shape == (2, OBS_SIZE) and np.all(np.isfinite(obs))
    assert np.all(np.abs(obs[:, 0] - obs[0, 0]) < 0.01)  # both lowered onto the surface
    d = venv.d
    state = {"qpos": physics.data.qpos, "qvel": physics.data.qvel, "act": physics.data.act}
    for name, value in state.items():
        getattr(d, name).assign(np.tile(value, (2, 1)).astype(np.float32))
    mjw.forward(venv.m, d)
    venv._observe()
    want = np.concatenate([ts.observation[name] for name, _ in OBSERVATIONS])
    # float32 state and kinematics on the device
    np.testing.assert_allclose(venv.obs.numpy()[0], want, rtol=0, atol=2e-5)
    gait = np.array([[1.5, 2.0], [0.5, 0.3]], dtype=np.float32)
    wp.launch(
        mw.hexapod.gait_kernel, dim=(2, 6),
        inputs=[venv.control_timestep, hexapod_sand.MAX_FREQUENCY, hexapod_sand.MAX_PHASE_RATE,
                wp.array(gait, dtype=float, device=DEVICE), d.act],
        outputs=[d.ctrl], device=DEVICE,
    )  # fmt: skip
    for w in range(2):
        env.task.before_step(gait[w].astype(float), physics)
        np.testing.assert_allclose(d.ctrl.numpy()[w], physics.data.ctrl, rtol=0, atol=1e-4)
    obs, reward, done = venv.step(np.tile(action, (2, 1)))
    assert not done and np.all(np.isfinite(obs.numpy()))
    assert np.all(np.abs(reward.numpy()) < 1.0)  # a walking speed [m/s], not a jump
