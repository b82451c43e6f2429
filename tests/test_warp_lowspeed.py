"""The low-speed treatment on MuJoCo Warp (mjrft.warp.lowspeed) against the C++ engine's.

On Warp's CPU device: the free-body treatment's decisions and wrenches equal the engine's on the
same states (``GranularField.wrench`` on an MjData holding the Warp world's kinematics), a
resting body stands still, and thrown passive bodies gain no energy from the medium (the
engine's energy test, benchmarks/energy.py, on Warp). The first run compiles the field's
kernels (~30 s on one core; cached in ~/.cache/warp after).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

pytest.importorskip("warp")
pytest.importorskip("mujoco_warp")

import benchmark_scripts
import mujoco_warp as mjw
import warp as wp
from warp_worlds import put, world_kinematics

import mjrft
import mjrft.warp as mw
from mjrft.app.simulate import models_dir
from mjrft.field import GranularField, lowspeed

DEVICE = "cpu"
wp.config.quiet = True
#: MuJoCo Warp's model holds mass, inertia and gravity in float32 (relative 6e-8 each), and the
#: stick and slip wrenches scale with them (-M xi_free / dt): measured 1.2e-7 of the largest
#: wrench component over the 40 states below; 8x that.
RTOL_TREATED = 1e-6
#: The pure model's wrench is the same quadrature in float64 on the same states.
RTOL_PURE = 1e-12
#: The issue's bar for a body held at rest: drift [m] over the run and step-to-step change of
#: the vertical force as a fraction of the weight.
DRIFT_M, FORCE_CHANGE = 1e-5, 0.01
#: The Warp run against the engine's, qpos after 400 steps: MuJoCo Warp's float32 state
#: resolves ~2e-10 m at these heights (measured gap 1.9e-10); 50x that.
ATOL_QPOS = 1e-8
#: A standing robot's torso position [m] and qpos against the engine's at the end of the run.
#: The hexapod, restarted at rest: MuJoCo Warp's float32 servo and joint dynamics leave the
#: torso 2.3e-10 m and the hip angles 1.7e-6 rad apart (measured); 40x and 6x that. The
#: quadruped settles from its initial state through 400 steps of feet switching between stuck
#: and slipping, which amplifies float32 differences as the pure model's chatter does (measured
#: 8.8e-5 m and 5.5e-3 rad; about 2x that): it ends in the same stance, not on the same path.
FOLLOW = {"hexapod": (1e-8, 1e-5), "quadruped": (2e-4, 1e-2)}


energy = benchmark_scripts.load("energy")
gpu_benchmark = benchmark_scripts.load("gpu")


def sphere(low_speed: str, integrator: str = "Euler"):
    """The sphere rig compiled without the engine (MuJoCo Warp's), its MjData, a WarpField."""
    mjm = mujoco.MjModel.from_xml_path(str(models_dir() / "sphere_drop.xml"))
    mjm.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    return mjm, mujoco.MjData(mjm), mw.WarpField(mjm, device=DEVICE, low_speed=low_speed)


def test_free_body_decisions_and_wrenches_are_the_engines_on_the_same_states():
    """40 seeded states of the sphere, some pushed by the user: every decision of the engine
    (pure, stick, slip, implicit) occurs, and each world's decision and treated wrench are the
    engine's on that world's kinematics."""
    mjm, mjd, field = sphere("free")
    rng = np.random.default_rng(0)
    n = 40
    qpos = np.tile(mjd.qpos, (n, 1))
    qpos[:, 2] = rng.uniform(-0.008, 0.0, n)
    qvel = np.zeros((n, 6))
    qvel[:, :3] = rng.normal(size=(n, 3)) * 10 ** rng.uniform(-3, -0.5, (n, 1))
    qvel[:, 3:] = rng.normal(size=(n, 3)) * 10 ** rng.uniform(-2, 1, (n, 1))
    m, d = put(mjm, mjd, qpos, qvel)
    user = np.zeros((n, mjm.nbody, 6), dtype=np.float32)
    user[::5, 1] = [0.0625, 0.0, -0.125, 0.0, 0.0009765625, 0.0]  # float32-exact pushes
    d.xfrc_applied.assign(user)
    mjw.forward(m, d)
    field.compute(d)
    pure = field.wrenches(d)
    field.take_user_part(d)
    field.treat(m, d)
    got, decisions = field.wrenches(d), field.decisions(d)[:, 0]
    cpu_model = mjrft.load_model(str(models_dir() / "sphere_drop.xml"), low_speed="free")
    cpu_d, cpu = mujoco.MjData(cpu_model), GranularField(cpu_model)
    want_decisions = []
    for w in range(n):
        world_kinematics(cpu_d, d, w)
        want = cpu.wrench(cpu_d, user_xfrc=user[w].astype(float))
        want_decisions.append(int(cpu.decision_of(cpu_d)[0]))
        scale = np.abs(want).max()
        rtol = RTOL_PURE if want_decisions[-1] == lowspeed.PURE else RTOL_TREATED
        np.testing.assert_allclose(got[w], want, rtol=0, atol=rtol * scale, err_msg=f"world {w}")
    np.testing.assert_array_equal(decisions, want_decisions)
    codes = (lowspeed.PURE, lowspeed.STICK, lowspeed.SLIP, lowspeed.IMPLICIT)
    assert set(want_decisions) == set(codes)  # the test has teeth: every rule decides somewhere
    treated = decisions != lowspeed.PURE
    assert np.all(np.abs(got[treated] - pure[treated]).max(axis=(1, 2)) > 0.0)


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "implicit"])
def test_a_resting_sphere_stands_still_and_follows_the_engine(integrator):
    """Spheres released at rest at two depths and one dropped in: 400 steps of 1 ms; over the
    last 200 the resting ones stay put and their force stays constant, where the pure model
    chatters (low_speed="off", the same run); every world follows the engine stepped alone."""
    nstep = 400
    result = {}
    for low_speed in ("off", "free"):
        mjm, mjd, field = sphere(low_speed, integrator)
        qpos = np.tile(mjd.qpos, (3, 1))
        qpos[:, 2] = [-0.0032, -0.004, 0.0]
        qvel = np.zeros((3, 6))
        qvel[2, 2] = -0.1
        m, d = put(mjm, mjd, qpos, qvel)
        pos, fz = [], []
        with field.installed(m, d):
            for _ in range(nstep):
                mjw.step(m, d)
                pos.append(d.xpos.numpy()[:, 1].copy())  # a copy: numpy() is a live view
                fz.append(field.wrenches(d)[:, 1, 2])
        result[low_speed] = np.array(pos)[nstep // 2 :], np.array(fz)[nstep // 2 :]
        final = d.qpos.numpy().copy()
    weight = float(mjm.body_mass[1]) * -mjm.opt.gravity[2]
    pos, fz = result["free"]
    drift = np.abs(pos - pos[0]).max(axis=(0, 2))
    change = np.abs(np.diff(fz, axis=0)).max(axis=0) / weight
    assert np.all(drift[:2] <= DRIFT_M) and np.all(change[:2] <= FORCE_CHANGE), (drift, change)
    assert fz[-1, 0] == pytest.approx(weight, rel=1e-3)  # the medium carries it
    pos_off, fz_off = result["off"]
    assert np.all(np.abs(pos_off - pos_off[0]).max(axis=(0, 2))[:2] > 10 * DRIFT_M)
    assert np.all(np.abs(np.diff(fz_off, axis=0)).max(axis=0)[:2] > 10 * FORCE_CHANGE * weight)
    # "free" last: the engine with the treatment, world by world
    cpu_model = mjrft.load_model(str(models_dir() / "sphere_drop.xml"), low_speed="free")
    cpu_model.opt.integrator = mjm.opt.integrator
    cpu_d = mujoco.MjData(cpu_model)
    for w in range(3):
        mujoco.mj_resetData(cpu_model, cpu_d)
        cpu_d.qpos[:], cpu_d.qvel[:] = qpos[w], qvel[w]
        for _ in range(nstep):
            mujoco.mj_step(cpu_model, cpu_d)
        np.testing.assert_allclose(final[w], cpu_d.qpos, rtol=0, atol=ATOL_QPOS)


#: The models of the throws of benchmarks/energy.py that gained energy under the unguarded pure
#: model (the engine's tests/test_energy.py GAINED; RK4 is refused on Warp): sharp-edged meshes
#: and a spinning capsule under Euler, implicit and implicitfast, each model with four seeded
#: throws as four worlds.
THROWS = [
    ("mesh", 5.0, 0.002, "Euler"),
    ("capsule", 5.0, 0.002, "implicitfast"),
    ("mesh", 0.5, 0.001, "implicit"),
    ("mesh", 0.05, 0.002, "implicitfast"),
    ("mesh", 0.5, 0.001, "Euler"),
]
#: A step's energy gain tolerance: benchmarks/energy.py's 1e-9 J + 1e-6 |E|, plus what MuJoCo
#: Warp's float32 state resolves of the energy (|E| ~ 3 J: 6e-8 |E| per term, a few terms).
E_ABS, E_REL = 1e-9, 2e-6


def _energy(plain, cpu_d, d, w):
    cpu_d.qpos[:] = d.qpos.numpy()[w]
    cpu_d.qvel[:] = d.qvel.numpy()[w]
    mujoco.mj_forward(plain, cpu_d)
    return energy.energy(plain, cpu_d)


@pytest.mark.parametrize("case", THROWS, ids=lambda c: "-".join(map(str, c)))
def test_thrown_bodies_gain_no_energy_from_the_medium(case):
    """Each step with the field against the same step from the same state without it (a second
    mjw.Data): the mechanical energy gained beyond the free step's stays within the tolerance."""
    nthrow, nstep = 4, round(energy.DURATION / case[2])  # 0.5 s, as benchmarks/energy.py
    plain = mujoco.MjModel.from_xml_string(energy.scene(*case))
    field = mw.WarpField(plain, device=DEVICE)
    starts = [energy.thrown((*case, k))[1] for k in range(nthrow)]
    mjd = mujoco.MjData(plain)
    qpos = np.array([s.qpos for s in starts])
    qvel = np.array([s.qvel for s in starts])
    m, d = put(plain, mjd, qpos, qvel)
    m_free, free = put(plain, mjd, qpos, qvel)
    cpu_d = mujoco.MjData(plain)
    worst, decided = 0.0, set()
    with field.installed(m, d):
        e0 = [_energy(plain, cpu_d, d, w) for w in range(nthrow)]
        for _ in range(nstep):
            wp.copy(free.qpos, d.qpos)
            wp.copy(free.qvel, d.qvel)
            mjw.step(m_free, free)
            mjw.step(m, d)
            decided |= set(field.decisions(d)[:, 0].tolist())
            for w in range(nthrow):
                e_free = _energy(plain, cpu_d, free, w)
                e1 = _energy(plain, cpu_d, d, w)
                gain = e1 - e0[w] - max(e_free - e0[w], 0.0)
                worst = max(worst, gain / (E_ABS + E_REL * abs(e0[w])))
                e0[w] = e1
    assert decided - {lowspeed.PURE}  # the treatment acted in these throws
    assert worst <= 1.0, worst


#: A quadruped of two-joint legs (hip and knee servos) standing on four ball feet, 1.4 kg
#: (benchmarks/gpu.py's, which stands it for 5 s).
QUADRUPED = gpu_benchmark.QUADRUPED


def settled(robot: str, integrator: str):
    """The robot's start: for the hexapod its state after 2 s standing on the CPU engine (gait
    stopped: each hip servo holds its angle), for the quadruped its initial state (None; its
    servos hold zero, it settles within 0.4 s); and its plain model (MuJoCo Warp's) and engine
    model under integrator."""
    hexapod = str(models_dir() / "hexapod_sand.xml")
    flag = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    if robot == "hexapod":
        cpu_model, plain = mjrft.load_model(hexapod), mujoco.MjModel.from_xml_path(hexapod)
    else:
        cpu_model = mjrft.load_model(QUADRUPED)
        plain = mujoco.MjModel.from_xml_string(QUADRUPED)
    cpu_model.opt.integrator = plain.opt.integrator = flag
    if robot == "quadruped":
        return plain, cpu_model, None
    cpu_d = restart(cpu_model, None)
    for _ in range(2000):
        mujoco.mj_step(cpu_model, cpu_d)
    return plain, cpu_model, (cpu_d.qpos.copy(), cpu_d.qvel.copy(), cpu_d.act.copy())


def restart(model, state):
    """An MjData of model at state (qpos, qvel, act), or at its keyframe (None; at rest), with
    ctrl 0 (the hexapod's gait stopped)."""
    d = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, d, 0)
    d.qvel[:] = 0.0
    if state is not None:
        d.qpos[:], d.qvel[:], d.act[:] = state
    d.ctrl[:] = 0.0
    return d


@pytest.mark.parametrize(
    ("robot", "integrator", "nstep", "settle"),
    [("hexapod", "Euler", 400, 100), ("hexapod", "implicitfast", 400, 100),
     ("quadruped", "Euler", 600, 400)],
)  # fmt: skip
def test_a_standing_robot_is_held_by_the_mechanism_treatment(robot, integrator, nstep, settle):
    """A robot standing in the medium (the hexapod's C-legs on hip servos; a quadruped's ball
    feet on two-joint legs), two worlds, steps of 1 ms on Warp: torso drift and step-to-step
    change of the total vertical RFT force within the issue's bars after settle steps, where
    low_speed="free" (the legs' pure model) creeps; the robot follows the engine stepped from
    the same state. The hexapod restarts from the engine's settled state: the restart's first
    pass has no previous pass to read the loads from (the engine's rule after a reset: the pure
    model acts once), so it drops ~1e-5 m in that step and is held from the next."""
    plain, cpu_model, state = settled(robot, integrator)
    weight = float(plain.body_subtreemass[1]) * -plain.opt.gravity[2]
    result = {}
    for low_speed in ("free", "stick"):
        field = mw.WarpField(plain, device=DEVICE, low_speed=low_speed)
        mjd = restart(plain, state)
        m = mjw.put_model(plain)
        d = mjw.put_data(plain, mjd, nworld=2)
        pos, fz = [], []
        with field.installed(m, d):
            for _ in range(nstep):
                mjw.step(m, d)
                pos.append(d.xpos.numpy()[:, 1].copy())  # a copy: numpy() is a live view
                fz.append(field.wrenches(d)[:, field.body_ids, 2].sum(axis=1))
        pos, fz = np.array(pos)[settle:], np.array(fz)[settle:]
        drift = np.abs(pos - pos[0]).max()
        result[low_speed] = drift, np.abs(np.diff(fz, axis=0)).max() / weight, fz[-1]
    held = np.count_nonzero(field.decisions(d) == lowspeed.STICK, axis=1)
    assert np.all(held >= 3)  # the feet in the medium are held (hexapod: 5 of 7 bodies)
    drift, change, last = result["stick"]
    assert drift <= DRIFT_M and change <= FORCE_CHANGE, result
    assert np.all(last == pytest.approx(weight, rel=1e-3))  # the medium carries the robot
    assert result["free"][0] > 10 * DRIFT_M, result
    cpu_d = restart(cpu_model, state)
    for _ in range(nstep):
        mujoco.mj_step(cpu_model, cpu_d)
    atol_torso, atol_joint = FOLLOW[robot]
    np.testing.assert_allclose(d.xpos.numpy()[0, 1], cpu_d.xpos[1], rtol=0, atol=atol_torso)
    np.testing.assert_allclose(d.qpos.numpy()[0], cpu_d.qpos, rtol=0, atol=atol_joint)


def test_the_trotting_go2_releases_the_engines_holds():
    """The Go2 trotting from its home keyframe, on Warp's CPU device and on the engine, side by
    side: the same decisions at every step, two stance legs slipping in most. Both test the
    hold of most power first and evaluate the others' resistance only where it could fall
    shorter (engine/mechanism.h, WorstHold); releasing another leg first changes which legs
    are held at the next steps."""
    from mjrft.envs import go2_sand

    cpu_model = mjrft.load_model(go2_sand.build_spec())
    plain = go2_sand.plain_spec().compile()
    fld, field = GranularField(cpu_model), mw.WarpField(plain, device=DEVICE)
    cpu_d, mjd = mujoco.MjData(cpu_model), mujoco.MjData(plain)
    mujoco.mj_resetDataKeyframe(cpu_model, cpu_d, cpu_model.key("home").id)
    mujoco.mj_resetDataKeyframe(plain, mjd, plain.key("home").id)
    m, d = mjw.put_model(plain), mjw.put_data(plain, mjd, nworld=1)
    engine, warp = [], []
    with field.installed(m, d):
        for _ in range(TROT_STEPS):
            ctrl = go2_sand.trot_ctrl(cpu_d.time)
            cpu_d.ctrl[:] = ctrl
            mujoco.mj_step(cpu_model, cpu_d)
            d.ctrl.assign(np.array([ctrl], dtype=np.float32))
            mjw.step(m, d)
            engine.append(list(map(int, fld.decision_of(cpu_d))))
            warp.append(list(map(int, field.decisions(d)[0])))
    assert warp == engine
    assert sum(dec.count(lowspeed.SLIP) >= 2 for dec in engine) > TROT_STEPS // 2


#: Steps of the trot above (2 ms each): 62 of the first 100 have two legs slipping.
TROT_STEPS = 100
