"""Contract tests of the dm_control environments in envs/, and the hexapod's speed trend."""

from __future__ import annotations

import math
import pickle
import subprocess
import sys
import zipfile
from pathlib import Path

import mujoco
import numpy as np
import pytest
from dm_control.mujoco import engine, wrapper
from dm_env import specs
from mjrft.envs import base, go2_sand, hexapod_sand
from mjrft.envs.physics import GranularPhysics

from mjrft import envs, load_model
from mjrft.field.plugin import EngineError

try:
    import gymnasium
except ImportError:  # optional dependency
    gymnasium = None

ROOT = Path(__file__).resolve().parents[1]
# Coarser primitive meshes keep the suite fast (the ellipsoid: 1000 instead of 4000 triangles);
# these tests are about the environment contract, not RFT resolution.
FAST = {
    "ellipsoid_burrow": {"n_triangles": 1000},
    "root_probe": {},
    "hexapod_sand": {},
    "go2_sand": {},
}
# An action per environment that drives the intruder into the medium at once.
PUSH = {
    "ellipsoid_burrow": np.array([2 * math.pi * 0.625, 5.0]),
    "root_probe": np.array([0.2, 0.5]),
    "hexapod_sand": np.array([1.0, math.pi]),
    "go2_sand": go2_sand.trot_offsets(0.5),  # a trot's stride: two legs lifted, two pushing
}
#: Action sizes: the quadruped drives its 12 servos, the rigs two set-points.
ACTION_SIZE = {"ellipsoid_burrow": 2, "root_probe": 2, "hexapod_sand": 2, "go2_sand": 12}


def push(name: str, k: int) -> np.ndarray:
    """The action of control step k that keeps the intruders moving in the medium: PUSH, or,
    for the quadruped, its trot (a constant stride would bring it to rest)."""
    if name == "go2_sand":
        return go2_sand.trot_offsets(0.02 * k)
    return PUSH[name]


def make(name: str, **kwargs) -> envs.GranularEnvironment:
    return envs.load(name, **{**FAST[name], **kwargs})


def random_actions(spec: specs.BoundedArray, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(spec.minimum, spec.maximum, size=(n, *spec.shape))


@pytest.fixture(params=envs.NAMES)
def name(request) -> str:
    return request.param


# --- package ------------------------------------------------------------------------------------


def test_names_and_unknown_name():
    assert envs.NAMES == ("ellipsoid_burrow", "root_probe", "hexapod_sand", "go2_sand")
    with pytest.raises(ValueError, match="unknown environment 'nope'.*hexapod_sand"):
        envs.load("nope")


@pytest.mark.parametrize(
    ("where", "module"),
    [("repository root", "envs"), ("repository root", "mjrft.envs"), ("elsewhere", "mjrft.envs")],
)
def test_import_envs_in_a_fresh_interpreter(where, module, tmp_path):
    cwd = ROOT if where == "repository root" else tmp_path
    out = subprocess.run(
        [sys.executable, "-c", f"import {module} as e; print(','.join(e.NAMES))"],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == ",".join(envs.NAMES)


def test_no_top_level_envs_package_is_installed(tmp_path):
    """An installed wheel holds only mjrft (with mjrft.envs and its model data): an RL project's
    own envs/ folder is not shadowed. (An editable install puts the repository on sys.path, as
    scikit-build-core's editable mode does for every project: a developer's checkout only.)"""
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", str(ROOT), "-w", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("mjrft-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    top = {n.split("/")[0] for n in names}
    assert {t for t in top if not t.endswith(".dist-info")} == {"mjrft"}
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    probe = f"import sys; sys.path.insert(0, {str(site)!r}); import envs"
    out = subprocess.run(  # -S: no site-packages, so only the wheel's files are importable
        [sys.executable, "-S", "-c", probe], cwd=tmp_path, capture_output=True, text=True
    )
    assert out.returncode != 0 and "No module named 'envs'" in out.stderr
    assert "mjrft/envs/__init__.py" in names and "mjrft/envs/hexapod_sand.py" in names


@pytest.mark.skipif(gymnasium is None, reason="gymnasium not installed")
def test_environments_are_registered_with_gymnasium():
    for name in envs.NAMES:
        spec = gymnasium.spec(f"mjrft/{name}-v0")
        assert spec.kwargs == {"env": name}
    env = gymnasium.make("mjrft/hexapod_sand-v0", time_limit=0.2)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    env.close()


@pytest.mark.skipif(gymnasium is None, reason="gymnasium not installed")
def test_gymnasium_makes_them_by_module_and_id_in_a_fresh_interpreter_without_warnings():
    """gymnasium >= 1.0 loads no plugins: "module:id" is its way to make an environment of a
    package not yet imported. Warnings are errors: render_fps is declared (one frame per control
    step), so gymnasium's environment checker has nothing to say when it renders."""
    probe = (
        "import sys, numpy as np, gymnasium\n"
        "assert 'mjrft.envs' not in sys.modules\n"
        "env = gymnasium.make('mjrft.envs:mjrft/hexapod_sand-v0', render_mode='rgb_array',\n"
        "                     time_limit=0.1, control_timestep=0.04)\n"
        "env.reset(seed=0)\n"
        "env.step(env.action_space.sample())\n"
        "frame = np.zeros((240, 320, 3), np.uint8)\n"
        "env.unwrapped.render = lambda: frame  # what is checked is the metadata, not OpenGL\n"
        "assert env.render() is frame\n"
        "print(env.metadata['render_fps'], type(env.unwrapped).metadata['render_fps'])\n"
        "env.close()\n"
    )
    out = subprocess.run(
        [sys.executable, "-W", "error", "-c", probe], capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["25.0", "50.0"]


# --- the contract, for every environment --------------------------------------------------------


def test_specs_are_valid_and_observations_match(name):
    env = make(name, seed=0)
    try:
        aspec = env.action_spec()
        assert isinstance(aspec, specs.BoundedArray) and aspec.dtype == np.float64
        assert aspec.shape == (ACTION_SIZE[name],)
        assert np.all(np.isfinite(aspec.minimum)) and np.all(np.isfinite(aspec.maximum))
        assert np.all(aspec.minimum < aspec.maximum)
        ospec = env.observation_spec()
        assert ospec and all(s.dtype == np.float64 for s in ospec.values())
        ts = env.reset()
        assert ts.first() and ts.reward is None
        assert list(ts.observation) == list(ospec)
        for key, spec in ospec.items():
            spec.validate(ts.observation[key])
        for action in (aspec.minimum, aspec.maximum, aspec.generate_value()):
            aspec.validate(action)
            ts = env.step(action)
            assert ts.mid() and np.isfinite(ts.reward) and ts.discount == 1.0
            for key, spec in ospec.items():
                spec.validate(ts.observation[key])
        assert env.physics.data.time == pytest.approx(3 * env.control_timestep())
    finally:
        env.close()


def rollout(env, actions) -> tuple[list[dict], list[float]]:
    obs, rewards = [env.reset().observation], []
    for a in actions:
        ts = env.step(a)
        obs.append(ts.observation)
        rewards.append(ts.reward)
    return obs, rewards


def test_deterministic_under_a_seed(name):
    a, b, c = make(name, seed=7), make(name, seed=7), make(name, seed=8)
    try:
        actions = random_actions(a.action_spec(), 40, seed=1)
        obs_a, rew_a = rollout(a, actions)
        obs_b, rew_b = rollout(b, actions)
        assert rew_a == rew_b
        for oa, ob in zip(obs_a, obs_b, strict=True):
            for key in oa:
                np.testing.assert_array_equal(oa[key], ob[key])
        # The seed matters: each task randomises its start (raise, yaw or gait phase).
        first_c = c.reset().observation
        assert any(not np.array_equal(first_c[k], obs_a[0][k]) for k in first_c)
    finally:
        for env in (a, b, c):
            env.close()


def test_reset_starts_a_clean_episode(name):
    used, fresh = make(name, seed=3), make(name, seed=3)
    try:
        used.reset()
        for a in random_actions(used.action_spec(), 25, seed=2):
            used.step(a)
        again = used.reset()
        fresh.reset()
        expected = fresh.reset()  # the same draw of the task's random numbers
        assert again.first() and used.physics.data.time == 0.0
        for key in expected.observation:
            np.testing.assert_array_equal(again.observation[key], expected.observation[key])
        # And the episodes that follow are identical too (no state leaks through the reset).
        actions = random_actions(used.action_spec(), 10, seed=4)
        for a in actions:
            ta, tb = used.step(a), fresh.step(a)
            assert ta.reward == tb.reward
            for key in ta.observation:
                np.testing.assert_array_equal(ta.observation[key], tb.observation[key])
    finally:
        used.close()
        fresh.close()


def test_no_nan_over_1000_control_steps_of_random_actions(name):
    env = make(name, seed=11, time_limit=float("inf"))
    try:
        env.reset()
        acted = restarts = 0
        intruding = [be.body for be in env.physics.field.bodies]
        for a in random_actions(env.action_spec(), 1000, seed=5):
            ts = env.step(a)
            restarts += ts.first()  # the step after an episode that ended (the quadruped fell)
            assert ts.first() or np.isfinite(ts.reward)
            for key, value in ts.observation.items():
                assert np.all(np.isfinite(value)), f"{key} not finite at t={ts}"
            acted += bool(np.any(env.physics.rft_wrench[intruding] != 0.0))
        d = env.physics.data
        for arr in (d.qpos, d.qvel, d.act, d.qacc, d.xfrc_applied):
            assert np.all(np.isfinite(arr))
        assert acted > 500, "the medium hardly ever acted"
        assert restarts < 10
        assert env.physics.substeps == (1000 - restarts) * env.n_sub_steps
    finally:
        env.close()


def test_time_limit_ends_the_episode_and_the_next_step_resets(name):
    env = make(name, seed=0, time_limit=0.1)
    try:
        env.reset()
        steps = [env.step(PUSH[name]) for _ in range(5)]
        assert [ts.step_type for ts in steps[:-1]] == [1, 1, 1, 1] and steps[-1].last()
        assert steps[-1].discount == 1.0  # truncation, not termination
        assert env.step(PUSH[name]).first()
    finally:
        env.close()


# --- the field acts in every substep ------------------------------------------------------------


def test_after_every_substep_xfrc_holds_the_rft_wrench_of_the_new_state(name):
    """Split stepping: each substep's mj_step1 writes the RFT wrench of the state it reached into
    xfrc_applied, which the next substep's mj_step2 applies. Check it after every substep against
    the engine's pass on a copy of the whole state (the low-speed treatment of a standing robot
    depends on its remembered holds and the last step's accelerations, which an explicit
    evaluation, field.wrench, does not have) and, where nothing is held, against field.wrench."""
    env = make(name, seed=0)
    try:
        env.reset()
        for _ in range(10):  # into the medium
            env.step(PUSH[name])
        phys = env.physics
        field, data = phys.field, phys.data.ptr
        rows = [be.body for be in field.bodies]
        for _ in range(3 * env.n_sub_steps):
            phys.step(1)
            stepped = phys.rft_wrench[rows].copy()  # the engine's, from the substep's mj_step1
            copy = mujoco.MjData(phys.model.ptr)
            mujoco.mj_copyData(copy, phys.model.ptr, data)
            mujoco.mj_forward(phys.model.ptr, copy)  # a repeated pass at the same state
            expected = field.wrench_of(copy)[rows]
            np.testing.assert_allclose(data.xfrc_applied[rows], expected, rtol=1e-12, atol=1e-15)
            assert np.any(expected != 0.0), "a substep without RFT force"
            np.testing.assert_array_equal(stepped, expected)
            if not np.any(field.decision_of(data) != 0):  # no body held: the pure model
                np.testing.assert_array_equal(stepped, field.wrench(data)[rows])
    finally:
        env.close()


def step_reference(model, data, ctrl, n, wrench_first=None):
    """n mj_steps with `ctrl`; wrench_first (nbody, 6): apply only in the first step."""
    data.ctrl[:] = ctrl
    for i in range(n):
        if wrench_first is not None:
            data.xfrc_applied[:] = wrench_first if i == 0 else 0.0
        mujoco.mj_step(model, data)


def test_trajectory_equals_rft_in_every_substep_and_not_once_per_control_step(name):
    env = make(name, seed=0)
    try:
        phys = env.physics
        model, data = phys.model.ptr, phys.data.ptr
        env.reset()
        for k in range(10):  # into the medium
            env.step(push(name, k))
        # Reference 1: plain mj_step on this model (it carries the engine: RFT in every step).
        every = mujoco.MjData(model)
        # Reference 2: the rig compiled without the engine; the wrench at the start of each
        # control step (evaluated on a probe of the engine's model) held for its first substep
        # only (what a Task-level force would do).
        stale_model = getattr(envs, name).build_spec().compile()
        once, probe = mujoco.MjData(stale_model), mujoco.MjData(model)
        # the whole state, the engine's included (the mechanism treatment remembers its holds)
        mujoco.mj_copyData(every, model, data)
        once.qpos[:], once.qvel[:], once.act[:] = data.qpos, data.qvel, data.act
        once.time = data.time
        n = env.n_sub_steps
        for k in range(10, 15):
            env.step(push(name, k))
            ctrl = data.ctrl.copy()
            step_reference(model, every, ctrl, n)
            probe.qpos[:], probe.qvel[:], probe.act[:] = once.qpos, once.qvel, once.act
            probe.time = once.time
            mujoco.mj_forward(model, probe)
            step_reference(stale_model, once, ctrl, n, phys.field.wrench(probe))
        scale = np.abs(data.qvel).max()
        err_every = np.abs(every.qvel - data.qvel).max() / scale
        err_once = np.abs(once.qvel - data.qvel).max() / scale
        assert err_every < 1e-9, err_every
        assert err_once > 1e-3, err_once  # the check above would catch a missing substep
    finally:
        env.close()


# --- the model carries the engine ---------------------------------------------------------------


def test_two_environments_do_not_interfere_and_the_model_keeps_its_engine_after_close():
    alone = make("hexapod_sand", seed=0)
    actions = random_actions(alone.action_spec(), 15, seed=9)
    solo, _ = rollout(alone, actions)
    alone.close()
    a, b = make("hexapod_sand", seed=0), make("ellipsoid_burrow", seed=0)
    model = a.physics.model.ptr
    try:
        a.reset()
        b.reset()
        for i, act in enumerate(actions):
            b.step(PUSH["ellipsoid_burrow"])
            ts = a.step(act)
            for key in ts.observation:
                np.testing.assert_array_equal(ts.observation[key], solo[i + 1][key])
    finally:
        a.close()
        b.close()
    # Closing frees the physics, not the engine: the model carries it, so new MjData of the model
    # stand on the medium (RFT written into xfrc_applied) rather than fall through it.
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    for _ in range(200):
        mujoco.mj_step(model, data)
    assert data.qpos[2] > -0.1 and np.any(data.xfrc_applied != 0.0)


def test_physics_copy_shares_or_rebuilds_the_field():
    env = make("root_probe", seed=0)
    try:
        env.reset()
        for _ in range(5):  # into the medium
            env.step(PUSH["root_probe"])
        phys = env.physics
        shared = phys.copy(share_model=True)
        own = phys.copy()
        # A pickle keeps the model and mj_getState's state, not the MjData (whose pickle would
        # share the original's engine instance: freeing both below would free it twice).
        pickled = pickle.dumps(phys)
        unpickled, again = pickle.loads(pickled), pickle.loads(pickled)
        assert shared.field is phys.field
        assert own.field is not phys.field and unpickled.field is not phys.field
        assert own.model.ptr is not phys.model.ptr and unpickled.model.ptr is not phys.model.ptr
        # The copies carry the engine's state (e.g. the low-speed treatment's) with the MjData.
        np.testing.assert_array_equal(shared.data.plugin_state, own.data.plugin_state)
        for p in (shared, own, unpickled, again):
            p.step(20)
            assert np.any(p.rft_wrench != 0.0)
        # Copies continue exactly (a copied RFT wrench is not taken for a user force); a state
        # restored from a pickle steps as a new MjData with that state does (the mechanism
        # treatment's predictor needs the previous forward pass's qacc, which MuJoCo's state
        # does not hold), so two unpickled copies agree exactly.
        np.testing.assert_array_equal(shared.data.qpos, own.data.qpos)
        np.testing.assert_array_equal(unpickled.data.qpos, again.data.qpos)
        np.testing.assert_allclose(unpickled.data.qpos, own.data.qpos, atol=1e-6)
        for p in (shared, own, unpickled, again):
            p.free()
        env.step(PUSH["root_probe"])  # the original steps on, with its engine
        assert np.any(phys.rft_wrench != 0.0)
    finally:
        env.close()


def test_physics_from_mjcf_carries_the_engine_and_a_plain_model_is_refused():
    """dm_control's loaders compile MJCF without the engine; GranularPhysics' load it with the
    engine (scene options as keywords), and dm_control's Physics.from_model keeps the engine of
    a model that carries it."""
    path = ROOT / "models" / "sphere_drop.xml"
    loaded = (
        GranularPhysics.from_xml_path(str(path), material="poppy_seeds_lp"),
        GranularPhysics.from_xml_string(path.read_text(), material="poppy_seeds_lp"),
        engine.Physics.from_model(wrapper.MjModel(load_model(str(path)))),
    )
    reloaded = GranularPhysics.from_xml_path(str(path))
    reloaded.reload_from_xml_path(str(path), material="poppy_seeds_lp")
    plain = engine.Physics.from_xml_path(str(path))
    assert plain.model.nplugin == 0
    plain.reset(0)
    plain.step(100)  # 0.1 s of free fall: 4.9 cm, through the medium
    for phys in (*loaded, reloaded):
        phys.reset(0)
        phys.step(100)  # the sphere falls into the medium, which holds it within a few mm
        assert phys.data.qpos[2] > plain.data.qpos[2] + 0.02
        assert np.any(phys.data.xfrc_applied[1] != 0.0)
    for phys in (*loaded[:2], reloaded):
        assert phys.field.material.name == "poppy_seeds_lp"
        np.testing.assert_array_equal(phys.rft_wrench[1], phys.data.xfrc_applied[1])
    np.testing.assert_array_equal(loaded[0].data.qpos, loaded[1].data.qpos)
    np.testing.assert_array_equal(loaded[0].data.qpos, reloaded.data.qpos)
    with pytest.raises(EngineError, match="mjrft.load_model"):
        GranularPhysics.from_model(plain.model)


# --- rewards ------------------------------------------------------------------------------------


def test_burrow_reward_is_depth_gained_per_actuator_work():
    env = make("ellipsoid_burrow", seed=0)
    try:
        env.reset()
        task = env.task
        for _ in range(20):
            d0 = task.depth(env.physics)
            ts = env.step(PUSH["ellipsoid_burrow"])
            d1 = ts.observation["depth"][0]
            assert task.last_work > 0.0
            assert ts.reward == pytest.approx((d1 - d0) / (task.last_work + envs.base.WORK_FLOOR))
        assert ts.observation["depth"][0] > 0.0  # it went in
    finally:
        env.close()


def test_hexapod_reward_is_forward_speed():
    env = make("hexapod_sand", seed=0)
    try:
        env.reset()
        x0 = env.physics.data.qpos[0]
        total = sum(env.step(PUSH["hexapod_sand"]).reward for _ in range(50))
        dx = env.physics.data.qpos[0] - x0
        assert total * env.control_timestep() == pytest.approx(dx)
        assert dx > 0.02  # 1 s at 1 Hz walks several centimetres forwards
    finally:
        env.close()


# --- the hexapod's speed vs leg frequency -------------------------------------------------------


def test_hexapod_speed_rises_with_leg_frequency_at_low_frequency():
    """Li, Zhang & Goldman 2013 (Fig. 4): at low frequency, speed increases with frequency.

    In the quasi-static regime the distance per gait cycle is nearly constant, so the speed is
    about proportional to f: require each doubling of f to raise the speed by at least 1.5x.
    """
    env = hexapod_sand.make(seed=0, time_limit=float("inf"))
    try:
        freqs = (0.25, 0.5, 1.0)
        speeds = [hexapod_sand.forward_speed(f, env=env, cycles=2.0) for f in freqs]
    finally:
        env.close()
    assert speeds[0] > 0.005, speeds  # it walks forwards (m/s)
    assert speeds[1] > 1.5 * speeds[0], speeds
    assert speeds[2] > 1.5 * speeds[1], speeds


def test_hexapod_on_a_slope_starts_on_the_surface_and_walks_faster_downhill():
    """make(slope=...) walks the hexapod on a tilted plane: an episode starts with the lowest
    foot point on the local surface, the height observation is above that surface, and the
    gait (+x) is faster down a 10-degree slope than up it."""
    speeds = {}
    for azimuth in (0.0, 180.0):
        env = hexapod_sand.make(seed=0, time_limit=float("inf"), slope=(10.0, azimuth))
        try:
            ts = env.reset()
            physics = env.physics
            assert abs(base.lowest_clearance(physics)) < 1e-12
            torso = physics.data.qpos[:3]
            local = float(physics.field.surface.height(torso[0], torso[1]))
            assert ts.observation["height"][0] == pytest.approx(torso[2] - local, abs=1e-12)
            speeds[azimuth] = hexapod_sand.forward_speed(1.0, env=env, cycles=2.0)
        finally:
            env.close()
    assert speeds[180.0] > 0.0, speeds  # it still climbs
    assert speeds[0.0] > speeds[180.0], speeds


def test_hexapod_on_deforming_ground_leaves_footprints_and_conserves_volume():
    """make(deform_cell=...) walks the hexapod on ground that remembers: 10 s of the gait cut
    footprints and raise rims, the volume stays (1e-9 of what was cut: only rounding moves it),
    and every episode starts from pristine ground."""
    env = hexapod_sand.make(seed=0, time_limit=float("inf"), deform_cell=0.005)
    try:
        env.reset()
        physics = env.physics
        soil = physics.field.soil(physics.data.ptr)
        assert not np.any(soil.height)
        action = np.array([1.0, math.pi])
        for _ in range(round(10.0 / env.control_timestep())):
            env.step(action)
        soil = physics.field.soil(physics.data.ptr)
        cut = soil.counters["excavated"]
        assert cut > 1e-4  # m^3
        assert abs(soil.volume()) <= 1e-9 * cut
        assert soil.height.min() < -0.01 and soil.height.max() > 0.003  # m
        assert physics.data.qpos[0] > 1.0  # it walked (1.5 m measured)
        torso = physics.data.qpos[:3]
        obs = env._task.get_observation(physics)["height"][0]
        assert obs == pytest.approx(torso[2] - soil.height_at(torso[0], torso[1]), abs=1e-12)
        env.reset()
        assert not np.any(physics.field.soil(physics.data.ptr).height)
    finally:
        env.close()
    with pytest.raises(ValueError, match="slope=None"):
        hexapod_sand.make(deform_cell=0.005, slope=(10.0, 0.0))


def test_hexapod_episode_ends_when_it_leaves_the_deforming_lane():
    """Beyond the medium's region there is no medium: an episode on the deforming lane ends
    (discount 0) at the control step whose torso is past its end, and not before; without a
    region the medium is unbounded and nothing ends it."""
    env = hexapod_sand.make(seed=0, time_limit=float("inf"), deform_cell=0.01)
    try:
        env.reset()
        physics = env.physics
        xmax = hexapod_sand.DEFORM_REGION[3]
        assert env.step(np.array([1.0, math.pi])).discount == 1.0
        with physics.reset_context():
            physics.data.qpos[0] = xmax + 0.01  # the torso just past the lane's end
        ts = env.step(np.array([1.0, math.pi]))
        assert ts.last() and ts.discount == 0.0
        assert env.step(np.array([1.0, math.pi])).first()  # the next step starts an episode
    finally:
        env.close()
    env = hexapod_sand.make(seed=0, time_limit=float("inf"))
    try:
        env.reset()
        with env.physics.reset_context():
            env.physics.data.qpos[0] = xmax + 1.0
        assert env.step(np.array([1.0, math.pi])).discount == 1.0
    finally:
        env.close()


# --- gymnasium ----------------------------------------------------------------------------------


def test_gymnasium_wrapper():
    gymnasium = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env
    from mjrft.envs.gym_wrapper import GymnasiumEnv

    env = GymnasiumEnv("hexapod_sand", time_limit=0.1)
    try:
        assert isinstance(env, gymnasium.Env)
        check_env(env, skip_render_check=True)
        obs, info = env.reset(seed=4)
        assert obs.shape == env.observation_space.shape and info == {}
        again, _ = env.reset(seed=4)
        np.testing.assert_array_equal(obs, again)
        assert obs[env.observation_slices["height"]].shape == (1,)
        for i in range(5):
            obs, reward, terminated, truncated, _ = env.step(np.array([1.0, math.pi]))
            assert env.observation_space.contains(obs) and np.isfinite(reward)
            assert not terminated and truncated == (i == 4)
    finally:
        env.close()


def test_bad_actions_and_a_closed_environment_are_named():
    env = make("hexapod_sand", time_limit=0.1)
    env.reset()
    with pytest.raises(ValueError, match=r"shape \(1,\), expected \(2,\) \(frequency,offset\)"):
        env.step([1.0])
    with pytest.raises(ValueError, match="not finite"):
        env.step([1.0, float("nan")])
    env.close()
    for call in (env.reset, lambda: env.step([1.0, 0.0])):
        with pytest.raises(RuntimeError, match="closed environment"):
            call()


# --- the quadruped -------------------------------------------------------------------------------


#: The sinkage is the analytic geom's; the force comes from its triangles' curved patches, which
#: reach the analytic surface only at their corners: a capsule of 100 triangles deviates by up to
#: its chords' sag (0.5 mm at 11 mm radius, ~10 facets around), so within that a geom just above
#: the surface may still feel a little of the medium.
MESH_SAG = 1e-3


#: Momentum balance of the trotting Go2 [fraction of its weight]: it closes up to the Euler
#: step's discretisation in joint coordinates, in which the robot's momentum is not linear
#: (measured 4e-4 over 2 s; 2e-3 with the joints' damping and armature set to zero).
LIFT_ATOL = 5e-3


def vertical_momentum(model, data) -> float:
    """The robot's (body 1's subtree's) vertical momentum [kg m/s], world frame."""
    mujoco.mj_subtreeVel(model, data)
    return float(model.body_subtreemass[1] * data.subtree_linvel[1][2])


def test_go2_foot_readings_are_the_lower_leg_wrench_and_the_feet_depth():
    """foot_readings: per leg the RFT force on its lower leg (the calf body's wrench) and how deep
    its foot sphere's lowest point is below the surface; in the trot a geom above the surface
    reads no force and the observations carry the same numbers; with no floor the feet carry the
    robot: their force balances its weight and its change of momentum."""
    env = make("go2_sand", seed=0, time_limit=float("inf"))
    try:
        env.reset()
        physics = env.physics
        model, data = physics.model.ptr, physics.data.ptr
        calves = [model.body(f"{leg}_calf").id for leg in go2_sand.LEGS]
        feet = [model.geom(f"{leg}_foot").id for leg in go2_sand.LEGS]
        radius = model.geom_size[feet, 0]
        weight = model.body_subtreemass[1] * -model.opt.gravity[2]
        lifted = planted = 0
        lift = []
        for k in range(100):  # 2 s of trot
            ts = env.step(go2_sand.trot_offsets(0.02 * k))
            forces, sinkage = go2_sand.foot_readings(physics)
            assert forces.shape == (4, 3) and sinkage.shape == (4,)
            # the sensors' sum is the calf body's wrench, up to the round-off of adding three geoms
            wrench = physics.field.wrench_of(data)[calves, :3]
            np.testing.assert_allclose(forces, wrench, rtol=0, atol=1e-12 * (1 + abs(wrench).max()))
            depth = np.maximum(0.0, -(data.geom_xpos[feet, 2] - radius))  # flat surface at z = 0
            np.testing.assert_allclose(sinkage, depth, rtol=0, atol=1e-12)
            np.testing.assert_array_equal(ts.observation["foot_force"], forces.ravel())
            np.testing.assert_array_equal(ts.observation["foot_sinkage"], sinkage)
            up = sinkage == 0.0
            for leg in go2_sand.LEGS:  # a geom clear of the surface feels nothing
                for part in go2_sand.LOWER_LEG:
                    reading = data.sensor(f"rft:{leg}_{part}").data
                    clear = reading[6] < -MESH_SAG
                    assert not clear or np.all(reading[:3] == 0.0), (leg, part, reading)
            lifted += up.sum()
            planted += (~up).sum()
        assert lifted > 25 and planted > 200  # both seen (50 and 350), mostly planted
        # No floor: over 2 s more of the trot the feet's vertical force, averaged over the steps,
        # is the weight plus the robot's change of vertical momentum over that time.
        momentum0, time0 = vertical_momentum(model, data), data.time
        for _ in range(1000):
            data.ctrl[:] = go2_sand.trot_ctrl(data.time)
            mujoco.mj_step(model, data)
            lift.append(go2_sand.foot_readings(physics)[0][:, 2].sum())
        change = (vertical_momentum(model, data) - momentum0) / (data.time - time0)
        assert np.mean(lift) == pytest.approx(weight + change, abs=LIFT_ATOL * weight)
    finally:
        env.close()


def test_go2_reward_is_forward_speed_along_its_heading():
    """Each step's reward is the torso's horizontal displacement over the step along its heading
    at the step's start, over the step's duration."""
    env = make("go2_sand", seed=3, time_limit=float("inf"))
    try:
        ts = env.reset()
        data = env.physics.data
        along = 0.0
        for k in range(100):
            heading, x0 = ts.observation["heading"], data.qpos[0:2].copy()
            ts = env.step(go2_sand.trot_offsets(0.02 * k))
            step = (data.qpos[0:2] - x0) @ heading
            assert ts.reward == pytest.approx(step / env.control_timestep(), rel=1e-12, abs=1e-15)
            along += step
        assert along > 0.1  # it walks where it faces (0.15 m in 2 s measured)
    finally:
        env.close()


def test_go2_episode_ends_when_it_tips_over():
    env = make("go2_sand", seed=0, time_limit=float("inf"))
    try:
        env.reset()
        assert env.step(np.zeros(12)).discount == 1.0
        with env.physics.reset_context():  # roll it 70 degrees onto its side
            env.physics.data.qpos[3:7] = [math.cos(0.61), math.sin(0.61), 0.0, 0.0]
        ts = env.step(np.zeros(12))
        assert ts.last() and ts.discount == 0.0
        assert env.step(np.zeros(12)).first()
    finally:
        env.close()
