"""The low-speed treatment of bodies in mechanisms (engine/mechanism.cc): a robot standing on
sand stays put, moving rigs keep the pure model, a passive chain settles without gaining energy.

Reduced sizes of benchmarks/standing.py (the full table: docs/stability.md, "Mechanisms"). The
engine's pass (the mjrft.granular plugin) is checked against its plain statement
(tests/field_reference.py) here on the standing hexapod, and in tests/test_paths.py (a body on a
slide).
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import benchmark_scripts
import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.field import GranularField, lowspeed

MODELS = Path(__file__).resolve().parents[1] / "models"
#: The issue's bar for a standing robot: drift below 0.1 mm over the whole stand, force change
#: below 1 % of the weight step to step.
DRIFT_M, FORCE_CHANGE = 1e-4, 0.01
#: A rig's force while it moves (after its first MOVING_AFTER steps, where it starts from rest
#: and may be held) equals the pure model's within this fraction of its peak: the issue's 0.1 %.
RIG_FORCE_RTOL, MOVING_AFTER = 1e-3, 100


def standing_hexapod(integrator: int, timestep: float, low_speed: str):
    model = mjrft.load_model(MODELS / "hexapod_sand.xml", low_speed=low_speed)
    model.opt.integrator, model.opt.timestep = integrator, timestep
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    data.ctrl[:] = 0.0  # gait stopped: each hip servo holds its angle
    data.qvel[:] = 0.0
    return model, data, GranularField(model)


def stand(integrator: int, timestep: float, low_speed: str, seconds: float = 3.0):
    """(torso positions (n, 3), total RFT vertical force (n,), weight) over the last second."""
    model, data, fld = standing_hexapod(integrator, timestep, low_speed)
    weight = float(model.body_subtreemass[1]) * -model.opt.gravity[2]
    n, last = round(seconds / timestep), round(1.0 / timestep)
    pos, fz = [], []
    for i in range(n):
        mujoco.mj_step(model, data)
        if i >= n - last:
            pos.append(data.xpos[1].copy())
            fz.append(fld.wrench_of(data)[fld.body_ids, 2].sum())
    return np.array(pos), np.array(fz), weight


@pytest.mark.parametrize(
    "integrator",
    [mujoco.mjtIntegrator.mjINT_EULER, mujoco.mjtIntegrator.mjINT_IMPLICITFAST],
    ids=["Euler", "implicitfast"],
)
def test_a_standing_hexapod_stays_put(integrator):
    pos, fz, weight = stand(integrator, 1e-3, "stick")
    assert np.abs(pos - pos[0]).max() < DRIFT_M
    assert np.median(np.abs(np.diff(fz))) < FORCE_CHANGE * weight
    assert fz[-1] == pytest.approx(weight, rel=1e-3)  # the medium carries the robot


def test_a_leg_held_at_the_last_step_is_held_again_without_evaluating_it():
    """A body the last step held ended it at rest, where the pure model's direction is
    round-off: it is held again, and its triangles are evaluated only if the treatment needs
    them (it slips on its pure model, or the loads cannot be predicted). The standing hexapod's
    held legs cost no evaluation; driven out of their holds, they are evaluated again."""
    model, data, fld = standing_hexapod(mujoco.mjtIntegrator.mjINT_EULER, 1e-3, "stick")
    for _ in range(1500):
        mujoco.mj_step(model, data)
    before = fld.stats_of(data)["evaluated"]
    for _ in range(100):
        mujoco.mj_step(model, data)
    held = fld.decision_of(data) == lowspeed.STICK
    assert held.sum() >= 4  # the legs in the medium
    triangles = np.array([len(be.areas) for be in fld.bodies])
    evaluated = fld.stats_of(data)["evaluated"] - before
    assert evaluated <= 100 * triangles[~held].sum()
    data.act[:] += 0.2  # every hip's setpoint 0.2 rad away: the servos pull the legs out
    before = fld.stats_of(data)["evaluated"]
    for _ in range(20):
        mujoco.mj_step(model, data)
    assert not (fld.decision_of(data) == lowspeed.STICK).any()
    assert fld.stats_of(data)["evaluated"] - before > 20 * triangles[held].sum() / 2


def test_without_the_mechanism_treatment_it_creeps():
    """The same stand with low_speed="free" (the pure model for the legs): the failure the
    treatment removes, so the test above can fail."""
    pos, fz, weight = stand(mujoco.mjtIntegrator.mjINT_EULER, 1e-3, "free")
    assert np.abs(pos - pos[0]).max() > 10 * DRIFT_M
    assert np.median(np.abs(np.diff(fz))) > FORCE_CHANGE * weight


def test_the_legs_are_treated_and_the_free_body_rule_is_not_used_for_them():
    _, _, fld = standing_hexapod(mujoco.mjtIntegrator.mjINT_EULER, 1e-3, "stick")
    assert fld.mechanism_eligible.all() and not fld.stick_eligible.any()
    assert lowspeed.LowSpeed("free").on and not lowspeed.LowSpeed("free").mechanisms


@pytest.mark.parametrize("rig", ["plate_rig", "ellipsoid_pitch"])
def test_a_moving_rig_feels_the_pure_model(rig):
    forces = {}
    for mode in ("free", "stick"):
        model = mjrft.load_model(MODELS / f"{rig}.xml", n_triangles=400, low_speed=mode)
        data = mujoco.MjData(model)
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, data, 0)
        fld = GranularField(model)
        out = []
        for _ in range(3000):
            mujoco.mj_step(model, data)
            out.append(fld.wrench_of(data)[fld.body_ids[0], :3].copy())
        forces[mode] = np.array(out)
    moving = slice(MOVING_AFTER, None)
    peak = np.abs(forces["free"][moving]).max()
    assert peak > 0.05  # the rig is in the medium
    np.testing.assert_allclose(
        forces["stick"][moving], forces["free"][moving], rtol=0, atol=RIG_FORCE_RTOL * peak
    )


CHAIN = """
<mujoco>
  <option timestep="{dt}" integrator="{integrator}"><flag contact="disable"/></option>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders">
      <element objtype="geom" objname="base" prm="300"/>
      <element objtype="geom" objname="flap" prm="300"/>
    </tuple>
  </custom>
  <worldbody>
    <body name="base" pos="0 0 0.006">
      <freejoint/>
      <geom name="base" type="box" size="0.02 0.015 0.006" density="2500"/>
      <body name="flap" pos="0.03 0 0">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="1e-5"/>
        <geom name="flap" type="box" size="0.01 0.015 0.003" pos="0 0 -0.002" density="2500"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""
#: Energy gain allowed per step: 1e-9 J + 1e-6 of the chain's mechanical energy scale (the
#: free-body tests' tolerance).
GAIN_J, GAIN_REL = 1e-9, 1e-6


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "RK4"])
def test_a_passive_chain_settles_and_gains_no_energy(integrator):
    model = mjrft.load_model(CHAIN.format(dt=1e-3, integrator=integrator))
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    data.qvel[:6] = [0.02, 0.0, -0.2, 0.0, 1.0, 0.0]  # thrown in, tumbling
    fld = GranularField(model)
    assert fld.mechanism_eligible.all()
    energy, held = [], 0
    for _ in range(1500):
        mujoco.mj_step(model, data)
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        energy.append(data.energy.sum())
        held += int(np.any(fld.decision_of(data) == lowspeed.STICK))
    energy = np.array(energy)
    scale = np.abs(energy).max()
    assert np.diff(energy).max() <= GAIN_J + GAIN_REL * scale
    assert held > 100  # the chain came to rest and was held
    assert np.abs(data.qvel).max() < 1e-9  # and stays at rest


def engine_tables(fld: GranularField):
    """A ctypes ``Tables`` (engine/tables.h, tests/engine_bridge.py) over the field's engine
    tables (``fld._tables``, the arrays the model carries), for the engine's C entry points of
    single stages."""
    import engine_bridge

    return engine_bridge.tables_of(fld._tables)


@pytest.mark.parametrize("name", ["hexapod_sand", "plate_rig", "ellipsoid_pitch"])
def test_the_predicted_actuator_forces_are_mujocos(name):
    """The mechanism step predicts this state's servo forces by MuJoCo's affine rule
    (mechanism::ActuatorForces, the engine's C entry mjrft_test_actuator_forces); after
    mj_forward they must equal MuJoCo's actuator_force (same formula, same inputs)."""
    model = mjrft.load_model(MODELS / f"{name}.xml")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    fld = GranularField(model)
    rng = np.random.default_rng(2)
    for _ in range(200):
        data.ctrl[:] += 0.01 * rng.normal(size=model.nu)
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    lib = mjrft.field.plugin.library()
    lib.mjrft_test_actuator_forces.argtypes = [ctypes.c_void_p] * 4
    lib.mjrft_test_actuator_forces.restype = None
    tables = engine_tables(fld)
    out = np.empty(model.nu)
    lib.mjrft_test_actuator_forces(
        ctypes.c_void_p(model._address), ctypes.c_void_p(data._address),
        ctypes.addressof(tables), out.ctypes.data,
    )  # fmt: skip
    np.testing.assert_allclose(out, data.actuator_force, rtol=1e-12, atol=1e-12)


def test_a_rig_stopped_mid_stroke_holds_still_with_its_load_cell_constant():
    """The plate rig's stiff carriage servo (kp 4e5 N/m) stopped 3 s into its stroke: with the
    pure model its load cell chatters by about 13 N step to step; held, it reads a constant."""
    readings = {}
    for mode in ("free", "stick"):
        model = mjrft.load_model(MODELS / "plate_rig.xml", n_triangles=400, low_speed=mode)
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        sensor = model.sensor("load_cell_force")
        out, z = [], []
        for i in range(4000):
            if i == 3000:
                data.ctrl[:] = 0.0  # stop the carriage
            mujoco.mj_step(model, data)
            if i >= 3500:
                out.append(data.sensordata[sensor.adr[0] : sensor.adr[0] + 3].copy())
                z.append(data.qpos[2])
        readings[mode] = (np.array(out), np.array(z))
    chatter = np.abs(np.diff(readings["free"][0], axis=0)).max()
    held, z = readings["stick"]
    assert chatter > 1.0  # N: what the treatment removes
    assert np.abs(np.diff(held, axis=0)).max() < FORCE_CHANGE * np.abs(held).max()
    assert np.ptp(z) < 1e-9 and np.abs(held[-1, 2]) > 1.0  # still, and loaded by the medium


def reference_twin(model, data, fld, plain):
    """(twin, reference): an MjData of plain (the model compiled without the plugin) in data's
    state, and a field_reference.ReferenceField that continues data's treatment on it. Besides
    the state, the twin takes the last step's qacc and actuator_force, which both treatments
    read at the next step's first pass, and the reference the engine's held bodies, their
    wrenches and the time of its last pass."""
    import field_reference as ref

    plain.opt.integrator, plain.opt.timestep = model.opt.integrator, model.opt.timestep
    twin = mujoco.MjData(plain)
    spec = int(mujoco.mjtState.mjSTATE_INTEGRATION) & ~int(mujoco.mjtState.mjSTATE_PLUGIN)
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    mujoco.mj_setState(plain, twin, state, spec)
    twin.qacc[:], twin.actuator_force[:] = data.qacc, data.actuator_force
    rows, nk = fld.body_ids, len(fld.body_ids)
    held = fld.state_array(data, "mech_held").astype(bool)
    prev = fld.state_array(data, "mech_prev").reshape(nk, 6)
    reference = ref.ReferenceField(fld)
    reference.state[twin._address] = {
        "user": np.zeros((nk, 6)), "written": np.array(data.xfrc_applied[rows]),
        "record": [0.0, 0.0], "modes": {},
        "mech_time": float(fld.state_array(data, "mech_time")[0]),
        "mech_tau": fld.state_array(data, "mech_tau").copy(),
        "mech_held": {k: True for k in range(nk) if held[k]},
        "mech_prev": {k: prev[k].copy() for k in range(nk) if held[k]},
    }  # fmt: skip
    return twin, reference


def follow_reference(model, data, fld, plain, steps: int, drive):
    """(engine, reference): qpos and qvel (steps, nq + nv) and each step's decisions of the
    engine continuing data, and of field_reference.ReferenceField (MuJoCo's passive callback)
    continuing its twin on plain (reference_twin); drive(d, i) acts on either before step i."""
    twin, reference = reference_twin(model, data, fld, plain)
    out = {}
    for name, m, d in (("engine", model, data), ("reference", plain, twin)):
        if name == "reference":
            mujoco.set_mjcb_passive(reference.apply)
        states, decisions = [], []
        try:
            for i in range(steps):
                drive(d, i)
                mujoco.mj_step(m, d)
                states.append(np.concatenate([d.qpos, d.qvel]))
                dec = reference.decisions if name == "reference" else fld.decision_of(d)
                decisions.append(list(map(int, dec)))
        finally:
            mujoco.set_mjcb_passive(None)
        out[name] = (np.array(states), decisions)
    return out["engine"], out["reference"]


def test_the_engine_follows_the_plain_reference_on_the_standing_hexapod():
    """Six legs and the belly held by the medium, their hip servos nudged (within what the holds
    supply, so that no body slips): from one settled state, the engine's pass (the plugin, in
    mj_step) against field_reference.mechanism_wrenches (MuJoCo's mj_fullM and mj_jacBodyCom,
    dense solves, the actuator rule written plainly) as MuJoCo's passive callback on the same
    model compiled without the plugin, states and decisions.

    From the settled state on, not from the fall into the sand: a slipping body's wrench is the
    medium's force at a direction computed in two orders of operations, and one triangle on the
    leading/trailing boundary can flip between them (a 3 mN jump on a 1 N leg)."""
    model, data, fld = standing_hexapod(mujoco.mjtIntegrator.mjINT_EULER, 1e-3, "stick")
    for _ in range(1500):
        mujoco.mj_step(model, data)
    plain = mujoco.MjModel.from_xml_path(str(MODELS / "hexapod_sand.xml"))

    def nudged(d, i):
        if i == 60:
            d.act[:] += 1e-4  # every hip's setpoint moves by 0.1 mrad: the holds follow

    # the reference takes ~0.25 s a step here; 140 steps follow the nudge
    (fast, fast_dec), (slow, slow_dec) = follow_reference(model, data, fld, plain, 200, nudged)
    np.testing.assert_allclose(fast, slow, rtol=1e-6, atol=1e-12)
    assert fast_dec == slow_dec
    assert sum(d.count(lowspeed.STICK) for d in slow_dec) > 300  # bodies were held


def test_the_engine_releases_the_holds_the_reference_releases_on_a_trotting_quadruped():
    """The Go2 trotting: its stance legs fail their holds together, and the engine evaluates
    the medium's resistance only for holds that could fall shortest (engine/mechanism.h,
    WorstHold). The plain reference evaluates every one and releases the worst, then solves the
    others again: the same legs slip, in the same order (the second leg's release direction,
    and so its wrench, depends on which went first)."""
    from mjrft.envs import go2_sand

    model = mjrft.load_model(MODELS / "go2_sand.xml")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    fld = GranularField(model)

    def trot(d, i):
        d.ctrl[:] = go2_sand.trot_ctrl(d.time)

    for i in range(TROT_SETTLE):
        trot(data, i)
        mujoco.mj_step(model, data)
    plain = go2_sand.plain_spec().compile()
    (fast, fast_dec), (slow, slow_dec) = follow_reference(model, data, fld, plain, TROT_STEPS, trot)
    assert fast_dec == slow_dec
    assert sum(d.count(lowspeed.SLIP) >= 2 for d in slow_dec) > TROT_STEPS // 2  # legs together
    np.testing.assert_allclose(fast, slow, rtol=0, atol=TROT_ATOL)


#: The trotting Go2 against the reference: TROT_STEPS steps (the reference takes ~0.1 s a step)
#: after TROT_SETTLE of the trot from the home keyframe (2 ms steps); states within TROT_ATOL (a
#: slipping leg's wrench can differ by one element turning leading between the two orders of
#: operations; a leg released in another order moves its foot by ~1e-4 m in a step).
TROT_SETTLE, TROT_STEPS, TROT_ATOL = 300, 30, 1e-6


#: The stance targets of a standing robot: torso drift [m] and step-to-step change of the total
#: RFT vertical force [fraction of the weight] (docs/stability.md, "Mechanisms").
STANCE_DRIFT_M, STANCE_FORCE_CHANGE = 1e-5, 0.01


@pytest.mark.parametrize(
    ("integrator", "timestep", "kp"),
    [("euler", 1e-3, 10.0), ("euler", 2e-3, 100.0), ("rk4", 1e-3, 1.0)],
)
def test_a_light_quadruped_on_soft_servos_holds(integrator, timestep, kp):
    """benchmarks/stance.py's 0.6 kg quadruped (15 g shins) settled 1 s, then standing 1 s: its
    hold system has a nearly null mode; solved exactly, two feet at a time were released every
    step and it crept by 0.5 mm a second with its load jumping between diagonal feet."""
    stance = benchmark_scripts.load("stance")  # its light quadruped's MJCF
    model = mjrft.load_model(stance.quadruped(kp, 0.015, timestep, integrator))
    data = mujoco.MjData(model)
    fld = GranularField(model)
    weight = float(model.body_subtreemass[1]) * -model.opt.gravity[2]
    for _ in range(round(1.0 / timestep)):
        mujoco.mj_step(model, data)
    start = data.xpos[1].copy()
    lift = []
    for _ in range(round(1.0 / timestep)):
        mujoco.mj_step(model, data)
        lift.append(fld.wrench_of(data)[fld.body_ids, 2].sum())
        assert np.all(fld.decision_of(data) == lowspeed.STICK)
    assert np.abs(data.xpos[1] - start).max() <= STANCE_DRIFT_M
    assert np.abs(np.diff(lift)).max() <= STANCE_FORCE_CHANGE * weight
    assert lift[-1] == pytest.approx(weight, rel=1e-6)  # the medium carries it
