"""The field of a plugin model: scene parsing, wrenches, the engine's pass inside mj_step and
its composition rules."""

import copy
import ctypes

import mujoco
import numpy as np
import pytest
import quadrature_reference

import mjrft
from mjrft.body import quat_to_mat
from mjrft.core import engine
from mjrft.field import GranularField
from mjrft.field.scene import SceneError

GLASS = mjrft.Material.preset("glass_beads")
# Same physics evaluated in a different order of floating-point operations.
ROUNDOFF = 1e-9
# MuJoCo stores mesh vertices in float32 (relative precision 6e-8) after re-centring them.
MESH_FLOAT32 = 1e-6


def scene_xml(bodies: str, custom_extra: str = "", tagged=(("geom", "ball", 400),), option=""):
    elements = "".join(f'<element objtype="{t}" objname="{n}" prm="{p}"/>' for t, n, p in tagged)
    return f"""
<mujoco>
  <option timestep="0.001" {option}/>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    {custom_extra}
    <tuple name="mjrft:intruders">{elements}</tuple>
  </custom>
  <worldbody>{bodies}</worldbody>
</mujoco>"""


BALL = """
<body name="b" pos="0.01 -0.02 -0.004">
  <freejoint/>
  <geom name="ball" size="0.01" density="2500" contype="0" conaffinity="0"/>
</body>"""


def ball_model(options=None, **kw):
    """The ball scene with the engine plugin (options: mjrft.SceneOptions fields)."""
    return mjrft.load_model(scene_xml(BALL, **kw), **(options or {}))


# A heavy ball shot steeply into the medium keeps moving throughout the comparison runs: RFT is
# discontinuous where a velocity reverses (the low-speed treatment's territory), and there round-off
# differences between two equivalent paths would grow chaotically instead of staying at 1e-15.
HEAVY_BALL = BALL.replace('density="2500"', 'density="60000"')
SHOT = {"v": (0.2, -0.1, -1.0), "w": (3.0, -2.0, 1.0)}


def heavy_model(plugin=True, **kw):
    """The heavy ball's scene with the engine plugin, or without it (no RFT at all)."""
    xml = scene_xml(HEAVY_BALL, **kw)
    return mjrft.load_model(xml) if plugin else mujoco.MjModel.from_xml_string(xml)


def set_motion(d, v=(0.02, -0.01, -0.03), w=(1.0, -2.0, 0.5)):
    d.qvel[:3] = v
    d.qvel[3:6] = w


def test_wrench_layout_and_zero_elsewhere():
    m = ball_model({"low_speed": "off"})
    d = mujoco.MjData(m)
    set_motion(d)
    mujoco.mj_forward(m, d)
    w = GranularField(m).wrench(d)
    assert w.shape == (m.nbody, 6)
    assert np.all(w[0] == 0)
    assert w[1, 2] > 0  # moving down into the medium: pushed up


# ------------------------------------------------------------------ geometry and frames
MESH_VERTS = np.array(
    [
        [0, 0, 0],
        [0.03, 0, 0],
        [0, 0.02, 0],
        [0.03, 0.02, 0],
        [0, 0, 0.01],
        [0.03, 0, 0.01],
        [0, 0.02, 0.01],
        [0.03, 0.02, 0.01],
    ]
) + [0.05, 0.02, -0.01]
MESH_FACES = np.array(
    [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ]
)
GEOM_POS = np.array([0.01, -0.02, 0.015])
GEOM_QUAT = np.array([0.9, 0.2, -0.3, 0.25]) / np.linalg.norm([0.9, 0.2, -0.3, 0.25])


def mesh_scene():
    verts = " ".join(f"{x:.17g}" for x in MESH_VERTS.ravel())
    faces = " ".join(str(i) for i in MESH_FACES.ravel())
    pos = " ".join(map(str, GEOM_POS))
    quat = " ".join(f"{x:.17g}" for x in GEOM_QUAT)
    return f"""
<mujoco>
  <asset><mesh name="slab" vertex="{verts}" face="{faces}"/></asset>
  <custom>
    <text name="mjrft:material" data="glass_beads"/>
    <tuple name="mjrft:intruders"><element objtype="geom" objname="slab" prm="0"/></tuple>
  </custom>
  <worldbody>
    <body name="holder" pos="0 0 -0.02" quat="0.8 0.1 0.5 -0.2">
      <freejoint/>
      <geom name="slab" type="mesh" mesh="slab" pos="{pos}" quat="{quat}" density="3000"
            contype="0" conaffinity="0"/>
      <geom name="counterweight" pos="-0.02 0 0.01" size="0.005" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>"""


def test_com_wrench_equals_element_sum_for_offset_rotated_mesh():
    m = mjrft.load_model(mesh_scene(), low_speed="off")
    # MuJoCo re-centred the mesh: the geom frame is no longer what the MJCF wrote.
    assert not np.allclose(m.geom_pos[0], GEOM_POS)
    d = mujoco.MjData(m)
    v, w_local = np.array([0.03, -0.02, -0.05]), np.array([1.5, -0.7, 2.0])
    d.qvel[:3], d.qvel[3:6] = v, w_local
    mujoco.mj_forward(m, d)
    wrench = GranularField(m).wrench(d)

    # Independent: the mesh as written in the MJCF, placed by the MJCF's geom pos/quat.
    es = mjrft.ElementSet.from_triangles(MESH_VERTS, MESH_FACES)
    rb, pb = d.xmat[1].reshape(3, 3), d.xpos[1]
    body_set = es.transformed(quat_to_mat(GEOM_QUAT), GEOM_POS)
    omega = rb @ w_local  # free joint angular velocity is in the body frame
    # free joint linear velocity is of the body origin; the slow reference of the quadrature
    f, torque = quadrature_reference.body_wrench(body_set, pb, rb, v, omega, GLASS, d.xipos[1])
    np.testing.assert_allclose(wrench[1, :3], f, rtol=MESH_FLOAT32)
    np.testing.assert_allclose(wrench[1, 3:], torque, atol=MESH_FLOAT32 * np.linalg.norm(torque))


TWO_BODIES = """
<body name="a" pos="0 0 -0.01" euler="20 -10 35">
  <freejoint/>
  <geom name="a_box" type="box" size="0.01 0.015 0.005" pos="0.01 0 0" euler="0 30 0"
        contype="0" conaffinity="0"/>
  <geom name="a_cap" type="capsule" size="0.004 0.01" pos="-0.01 0.01 0" contype="0"
        conaffinity="0"/>
  <geom name="a_untagged" size="0.01" pos="0 0 0.03" contype="0" conaffinity="0"/>
</body>
<body name="c" pos="0.1 0 -0.005">
  <freejoint/>
  <geom name="c_cyl" type="cylinder" size="0.006 0.01" euler="90 0 0" contype="0"
        conaffinity="0"/>
  <geom name="c_ell" type="ellipsoid" size="0.004 0.006 0.008" pos="0 0 -0.01" contype="0"
        conaffinity="0"/>
</body>"""
TWO_TAGS = (("geom", "a_box", 300), ("geom", "a_cap", 200), ("body", "c", 250))


def test_several_geoms_and_bodies_match_core_body_wrench():
    m = mjrft.load_model(scene_xml(TWO_BODIES, tagged=TWO_TAGS), low_speed="off")
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    d.qvel[:] = rng.normal(size=m.nv) * 0.1
    mujoco.mj_forward(m, d)
    fld = GranularField(m)
    assert {be.name for be in fld.bodies} == {"a", "c"}
    wrench = fld.wrench(d)
    for be in fld.bodies:
        b = be.body
        es = fld.body_element_set(b)  # the field's elements, by the core's rigid-body path
        v_origin = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, b, v_origin, 0)
        ref = mjrft.body.body_wrench(
            es,
            d.xpos[b],
            d.xmat[b].reshape(3, 3),
            v_origin[3:],
            v_origin[:3],
            GLASS,
            point=d.xipos[b],
        )
        np.testing.assert_allclose(wrench[b, :3], ref.force, rtol=ROUNDOFF, atol=1e-12)
        np.testing.assert_allclose(wrench[b, 3:], ref.moment, rtol=ROUNDOFF, atol=1e-12)
        assert np.any(wrench[b] != 0)


def test_above_surface_and_region_culling():
    region = '<numeric name="mjrft:region" data="-0.05 -0.05 -0.5 0.05 0.05 0.1"/>'
    m = ball_model(custom_extra=region)
    d = mujoco.MjData(m)
    set_motion(d)
    fld = GranularField(m)
    d.qpos[2] = 0.0105  # entirely above the surface
    mujoco.mj_forward(m, d)
    assert fld.element_states(d) == [] and np.all(fld.wrench(d) == 0)
    d.qpos[:3] = [0.2, 0, -0.02]  # submerged but outside the region
    mujoco.mj_forward(m, d)
    assert fld.element_states(d) == [] and np.all(fld.wrench(d) == 0)
    d.qpos[:3] = [0.05, 0, -0.02]  # straddling the region's wall: only the inside half acts
    mujoco.mj_forward(m, d)
    (st,) = fld.element_states(d)
    assert np.all(st.pos[:, 0] <= 0.05) and 0.3 < len(st.index) / len(fld.bodies[0].areas) < 0.7


def test_surface_height_from_mjcf():
    m0 = ball_model()
    m1 = ball_model(custom_extra='<numeric name="mjrft:surface_z" data="0.25"/>')
    d0, d1 = mujoco.MjData(m0), mujoco.MjData(m1)
    for d in (d0, d1):
        set_motion(d)
    d1.qpos[2] += 0.25
    mujoco.mj_forward(m0, d0)
    mujoco.mj_forward(m1, d1)
    np.testing.assert_allclose(
        GranularField(m1).wrench(d1), GranularField(m0).wrench(d0), rtol=1e-7, atol=1e-12
    )


# ------------------------------------------------------------------ the engine's pass in mj_step
def simulate(m, n, *, user=None, motion=None):
    """(n, nq + nv) states of n mj_steps of m from set_motion's start, with the user's forces
    user (nbody, 6) assigned to xfrc_applied once before them; and the MjData."""
    d = mujoco.MjData(m)
    set_motion(d, **(motion or {}))
    d.xfrc_applied[:] = 0.0 if user is None else user
    traj = []
    for _ in range(n):
        mujoco.mj_step(m, d)
        traj.append(np.concatenate([d.qpos, d.qvel]))
    return np.array(traj), d


def simulate_explicit(m, plain, n, *, user, motion):
    """The explicit path: plain (m's scene without the plugin) stepped with xfrc_applied = user
    + GranularField(m).wrench of each state, evaluated on an MjData of m set to that state."""
    fld = GranularField(m)
    d, probe = mujoco.MjData(plain), mujoco.MjData(m)
    set_motion(d, **motion)
    traj = []
    for _ in range(n):
        probe.time, probe.qpos[:], probe.qvel[:] = d.time, d.qpos, d.qvel
        mujoco.mj_forward(m, probe)
        d.xfrc_applied[:] = user + fld.wrench(probe, user_xfrc=user)
        mujoco.mj_step(plain, d)
        traj.append(np.concatenate([d.qpos, d.qvel]))
    return np.array(traj)


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast"])
def test_explicit_path_equals_the_engines_pass(integrator):
    option = f'integrator="{integrator}"'
    m, plain = heavy_model(option=option), heavy_model(plugin=False, option=option)
    user = np.zeros((m.nbody, 6))
    user[1] = [0.01, -0.02, 0.03, 1e-4, 0, -2e-4]
    a, _ = simulate(m, 80, user=user, motion=SHOT)
    assert np.all(a[:, m.nq + 2] < -0.1)  # still plunging: no velocity reversal
    b = simulate_explicit(m, plain, 80, user=user, motion=SHOT)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    free, _ = simulate(plain, 80, user=user, motion=SHOT)
    assert not np.allclose(a, free, atol=1e-3)  # the field really acted


def test_no_lag_force_is_from_the_state_being_stepped():
    m = ball_model()
    plain = mujoco.MjModel.from_xml_string(scene_xml(BALL))
    fld = GranularField(m)
    d = mujoco.MjData(m)
    set_motion(d)
    for _ in range(5):
        before = copy.copy(d)
        mujoco.mj_forward(m, before)
        expected = fld.wrench(before)
        mujoco.mj_step(m, d)
        np.testing.assert_allclose(fld.wrench_of(d), expected, rtol=1e-12, atol=1e-15)
        # The step's acceleration is that of the pre-step state under exactly that wrench.
        alone = mujoco.MjData(plain)
        alone.qpos[:], alone.qvel[:], alone.xfrc_applied[:] = before.qpos, before.qvel, expected
        mujoco.mj_forward(plain, alone)
        np.testing.assert_allclose(d.qacc, alone.qacc, rtol=1e-9, atol=1e-9)


def test_load_cell_sees_the_field():
    # MuJoCo's force sensor reads external forces only through xfrc_applied (cfrc_ext).
    xml = scene_xml(
        """<body name="holder" pos="0 0 -0.01"><joint type="slide" axis="0 0 1"/>
             <geom size="0.002" pos="0 0 0.05" contype="0" conaffinity="0"/>
             <body name="b"><site name="cell"/>
               <geom name="ball" size="0.01" mass="0.01" contype="0" conaffinity="0"/></body>
           </body>""",
        option='gravity="0 0 0"',
    ).replace("</mujoco>", '<sensor><force name="cell" site="cell"/></sensor></mujoco>')
    m = mjrft.load_model(xml)
    d = mujoco.MjData(m)
    d.qvel[0] = -0.01
    fld = GranularField(m)
    mujoco.mj_forward(m, d)
    w = fld.wrench_of(d)[m.body("b").id]
    assert w[2] > 0.01
    # Parent-on-child force = m a - F_ext; this slide keeps x, y from accelerating.
    acc = np.zeros(6)
    mujoco.mj_objectAcceleration(m, d, mujoco.mjtObj.mjOBJ_BODY, m.body("b").id, acc, 0)
    expected = m.body("b").mass[0] * acc[3:] - w[:3]
    np.testing.assert_allclose(d.sensordata[:3], expected, rtol=1e-6, atol=1e-9)


def test_user_rows_survive_assignment_between_steps():
    """Between steps a tagged row holds the user's part plus the last pass's RFT; what the user
    assigns there is the user's part from then on."""
    m = ball_model()
    fld = GranularField(m)
    d = mujoco.MjData(m)
    set_motion(d)
    push = np.array([0.01, 0.0, 0.02, 0.0, 1e-4, 0.0])
    d.xfrc_applied[1] = push
    mujoco.mj_step(m, d)
    np.testing.assert_array_equal(d.xfrc_applied[1], push + fld.wrench_of(d)[1])
    np.testing.assert_array_equal(fld.user_xfrc(d)[1], push)
    d.xfrc_applied[:] = 0.0  # what the interactive viewer does before applying a perturbation
    mujoco.mj_step(m, d)
    np.testing.assert_array_equal(d.xfrc_applied[1], fld.wrench_of(d)[1])
    np.testing.assert_array_equal(fld.user_xfrc(d)[1], np.zeros(6))
    d.xfrc_applied[1] = 2 * push
    mujoco.mj_step(m, d)
    np.testing.assert_array_equal(fld.user_xfrc(d)[1], 2 * push)
    np.testing.assert_array_equal(d.xfrc_applied[1], 2 * push + fld.wrench_of(d)[1])


def test_writing_one_component_assigns_only_that_component():
    """A 0.1 mN push written into one component of a resting ball's row is the user's part of
    that component only: the RFT force in the other components stays the field's (read as the
    user's, it would be added again every step and throw the ball out of the medium)."""
    m = ball_model()
    fld = GranularField(m)
    d = mujoco.MjData(m)
    for _ in range(300):  # released partly submerged: sinks a little and rests
        mujoco.mj_step(m, d)
    rest = d.qpos[2]
    assert fld.wrench_of(d)[1, 2] > 0.5 * m.body_mass[1] * 9.81  # the medium carries it
    d.xfrc_applied[1, 0] = 1e-4
    for _ in range(500):
        mujoco.mj_step(m, d)
    user = fld.user_xfrc(d)[1]
    np.testing.assert_array_equal(user, [1e-4, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(d.xfrc_applied[1], user + fld.wrench_of(d)[1])
    assert abs(d.qpos[2] - rest) < 1e-3  # still in the medium, not thrown out


def test_copied_data_keeps_only_the_user_part():
    m = heavy_model()
    fld = GranularField(m)
    d = mujoco.MjData(m)
    set_motion(d, **SHOT)
    d.xfrc_applied[1, :3] = [0.1, 0.0, 0.2]
    for _ in range(10):
        mujoco.mj_step(m, d)
    twin = copy.copy(d)
    mujoco.mj_step(m, d)  # the original moves on before the copy's first step
    twin_late = copy.copy(d)
    mujoco.mj_step(m, twin)  # now all three are at step 11
    for _ in range(20):
        mujoco.mj_step(m, d)
        mujoco.mj_step(m, twin)
        mujoco.mj_step(m, twin_late)
    np.testing.assert_array_equal(twin.qpos, d.qpos)
    np.testing.assert_array_equal(twin_late.qpos, d.qpos)
    np.testing.assert_array_equal(fld.user_xfrc(twin)[1, :3], [0.1, 0.0, 0.2])


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_user_xfrc_is_neither_lost_nor_double_counted(integrator):
    # A constant user force u at the CoM of a single free body is the same physics as gravity
    # changed by u/mass. Any loss or double counting of u (in any of RK4's 4 passes) breaks this.
    m = heavy_model(option=f'integrator="{integrator}"')
    u = np.array([0.5, -0.3, 0.8])
    user = np.zeros((m.nbody, 6))
    user[1, :3] = u
    a, da = simulate(m, 80, user=user, motion=SHOT)
    assert np.all(a[:, m.nq + 2] < -0.1)
    np.testing.assert_array_equal(GranularField(m).user_xfrc(da), user)  # still the user's
    m2 = heavy_model(option=f'integrator="{integrator}"')
    m2.opt.gravity[:] = m.opt.gravity + u / m.body_mass[1]
    b, _ = simulate(m2, 80, motion=SHOT)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    c, _ = simulate(m, 80, motion=SHOT)  # without the user force: visibly different
    assert not np.allclose(a, c, atol=1e-5)


def test_rk4_evaluates_a_moving_body_in_every_stage():
    m = heavy_model(option='integrator="RK4"')
    fld = GranularField(m)
    d = mujoco.MjData(m)
    set_motion(d, **SHOT)
    for n in range(1, 4):
        mujoco.mj_step(m, d)
        assert fld.stats_of(d)["calls"] == 4 * n
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER  # the engine reads the model live
    mujoco.mj_step(m, d)
    assert fld.stats_of(d)["calls"] == 13


def test_rk4_holds_a_body_at_rest_over_the_step():
    """A body the treatment holds keeps its first stage's wrench over the step: one evaluated
    pass per step, and it ends each step exactly at rest."""
    m = ball_model(option='integrator="RK4"')
    fld = GranularField(m)
    d = mujoco.MjData(m)
    for _ in range(300):  # released at rest, partly submerged: sinks a little and stops
        mujoco.mj_step(m, d)
    calls, stuck = fld.stats_of(d)["calls"], fld.stats_of(d)["stuck"]
    for n in range(1, 4):
        mujoco.mj_step(m, d)
        assert fld.stats_of(d)["calls"] == calls + n and fld.stats_of(d)["stuck"] == stuck + n
        assert np.abs(d.qvel).max() <= 1e-15  # at rest to round-off
    mujoco.mj_forward(m, d)  # a user's forward pass between steps is evaluated afresh
    mujoco.mj_step(m, d)  # ... and so is the next step's first stage, at the same time
    assert fld.stats_of(d)["calls"] == calls + 5


def test_interleaved_mjdata_of_one_model_step_as_if_alone():
    """The engine keeps its state (hold and freeze flags, RK4 records) per MjData: stepping two
    MjData in turn must give bit for bit what each gives stepped alone, including a body the
    treatment holds at rest under RK4."""
    m = ball_model(option='integrator="RK4"')
    fld = GranularField(m)
    steps = 320  # the resting ball is held from ~step 250 on (previous test)

    def fresh(moving):
        d = mujoco.MjData(m)
        if moving:
            set_motion(d)
        return d

    alone = []
    for moving in (False, True):
        d = fresh(moving)
        for _ in range(steps):
            mujoco.mj_step(m, d)
        alone.append(d)
    pair = [fresh(False), fresh(True)]
    for _ in range(steps):
        for d in pair:
            mujoco.mj_step(m, d)
    assert fld.stats_of(pair[0])["stuck"] > 0  # the hold (RK4 records) was exercised
    for d, one in zip(pair, alone, strict=True):
        np.testing.assert_array_equal(d.qpos, one.qpos)
        np.testing.assert_array_equal(d.qvel, one.qvel)
        np.testing.assert_array_equal(d.plugin_state, one.plugin_state)


def test_rk4_stage_rule_equals_the_reference():
    """The engine's RK4 stage rule (rk4::StageHeld, through the library's test entry point)
    against its plain statement, on one step's passes and on other patterns."""
    from field_reference import rk4_stage_held

    prototype = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.c_void_p)
    stage_held = prototype(("mjrft_test_stage_held", engine.library()))
    h, t0 = 0.003, 0.7
    # one step: stage 1 evaluated, 2-4 held; the next step's stage 1 (t0 + h) evaluated again
    steps = [t0, t0 + 0.5 * h, t0 + 0.5 * h, t0 + 1.0 * h, t0 + h, (t0 + h) + 0.5 * h]
    # anything else is evaluated: a pass before any stage 1, a repeated time, a third pass at
    # the half step, a pass that skips ahead
    other = [t0 + 0.5 * h, t0, t0, t0 + 0.5 * h, t0 + 0.5 * h, t0 + 0.5 * h, t0 + 3.0 * h]
    for seq, want in (
        (steps, [False, True, True, True, False, True]),
        (other, [False, False, False, True, True, False, False]),
    ):
        rec, reference = np.zeros(2), [0.0, 0.0]
        assert [bool(stage_held(t, h, rec.ctypes.data)) for t in seq] == want
        assert [rk4_stage_held(t, h, reference) for t in seq] == want
        assert rec.tolist() == reference


def test_a_medium_of_python_callables_runs_as_its_table():
    """The engine runs a medium given by Python callables as a table sampled at load
    (docs/materials.md): glass beads written as callables give the Fourier preset's wrench to
    the table's accuracy."""
    glass = mjrft.Material.preset("glass_beads")
    mat = mjrft.Material.from_callables(
        glass.fourier.alpha_x, glass.fourier.alpha_z, glass.zeta, name="glass, callables"
    )
    wrenches = []
    for material in (mat, glass):
        m = ball_model({"material": material})
        d = mujoco.MjData(m)
        set_motion(d)
        mujoco.mj_forward(m, d)
        wrenches.append(GranularField(m).wrench_of(d).copy())
    scale = np.abs(wrenches[1]).max()
    assert scale > 0.0
    # the table's bound for Li's set at the default grid: 1.7e-7 of an element's scale
    # (tests/test_tabulated.py); 1e-6 of the largest component leaves room for the sum
    np.testing.assert_allclose(wrenches[0], wrenches[1], atol=1e-6 * scale)


def test_a_model_without_the_plugin_feels_nothing_and_no_callback_is_set():
    """The field lives in the models that carry the plugin: the same scene compiled without it
    steps with no RFT beside one that has it, and MuJoCo's global passive callback stays unset."""
    m = ball_model()
    d = mujoco.MjData(m)
    set_motion(d)
    other = mujoco.MjModel.from_xml_string(scene_xml(BALL))
    d_other = mujoco.MjData(other)
    set_motion(d_other)
    with GranularField(m).installed():  # kept for old scripts: changes nothing
        mujoco.mj_step(m, d)
        mujoco.mj_step(other, d_other)
    assert np.any(d.xfrc_applied[1] != 0)
    assert np.array_equal(d_other.xfrc_applied, np.zeros((other.nbody, 6)))
    assert mujoco.get_mjcb_passive() is None


def test_two_models_stepped_in_turn_do_not_interfere():
    m1 = ball_model()
    m2 = mjrft.load_model(scene_xml(TWO_BODIES, tagged=TWO_TAGS))
    alone1, _ = simulate(m1, 100)
    alone2, _ = simulate(m2, 100)
    d1, d2 = mujoco.MjData(m1), mujoco.MjData(m2)
    set_motion(d1)
    set_motion(d2)
    both1, both2 = [], []
    for _ in range(100):
        mujoco.mj_step(m1, d1)
        mujoco.mj_step(m2, d2)
        both1.append(np.concatenate([d1.qpos, d1.qvel]))
        both2.append(np.concatenate([d2.qpos, d2.qvel]))
    np.testing.assert_array_equal(np.array(both1), alone1)
    np.testing.assert_array_equal(np.array(both2), alone2)


def test_a_users_passive_callback_runs_beside_the_engine():
    m = ball_model()
    fld = GranularField(m)
    seen = []

    def user_cb(mm, dd):
        seen.append(mm is m)

    mujoco.set_mjcb_passive(user_cb)
    try:
        d = mujoco.MjData(m)
        set_motion(d)
        mujoco.mj_step(m, d)
        assert seen == [True]
        assert fld.stats_of(d)["calls"] == 1 and fld.wrench_of(d)[1, 2] > 0
        assert mujoco.get_mjcb_passive() is user_cb
    finally:
        mujoco.set_mjcb_passive(None)


def test_non_finite_state_raises_naming_body_and_the_process_survives():
    # MuJoCo's own check resets NaN qvel before the forward pass unless autoreset is disabled.
    m = ball_model(option='><flag autoreset="disable"/></option><option')
    d = mujoco.MjData(m)
    set_motion(d)
    for _ in range(3):  # repeated errors out of mj_step must stay safe
        d.qvel[0] = np.nan
        with pytest.raises(mujoco.FatalError, match=r"body 'b'.*time .*\(step \d+\)"):
            mujoco.mj_step(m, d)
    d.qvel[:] = 0
    mujoco.mj_step(m, d)
    assert np.all(np.isfinite(d.qpos))
    probe = copy.copy(d)
    probe.cvel[1, 3] = np.nan  # kinematics of a non-finite velocity (mj_forward would raise)
    with pytest.raises(FloatingPointError, match=r"body 'b'.*time .*\(step \d+\)"):
        GranularField(m).wrench(probe)  # the explicit evaluation refuses it too


# ------------------------------------------------------------------ MJCF errors
def xml_with(custom: str, geom='<geom name="ball" size="0.01" contype="0" conaffinity="0"/>'):
    return f"""<mujoco><custom>{custom}</custom>
      <worldbody><body name="b"><freejoint/>{geom}</body>
      <geom name="floor" type="plane" size="1 1 0.1"/></worldbody></mujoco>"""


TAG = '<tuple name="mjrft:intruders"><element objtype="geom" objname="ball" prm="0"/></tuple>'
MAT = '<text name="mjrft:material" data="glass_beads"/>'


@pytest.mark.parametrize(
    ("custom", "geom", "match"),
    [
        (MAT, None, "no intruding geoms.*mjrft:intruders"),
        (TAG, None, "no material.*mjrft:material"),
        ('<text name="mjrft:material" data="sand"/>' + TAG, None, "unknown material 'sand'"),
        (
            MAT + '<tuple name="mjrft:intruders"><element objtype="geom" objname="floor" prm="0"/>'
            "</tuple>",
            None,
            "geom 'floor' has type 'plane'",
        ),
        (
            MAT + '<tuple name="mjrft:intruders"><element objtype="geom" objname="ball" prm="5"/>'
            "</tuple>",
            None,
            "geom 'ball': prm=5",
        ),
        (MAT + '<numeric name="mjrft:surface" data="0"/>' + TAG, None, "unknown.*'mjrft:surface'"),
        (MAT + '<numeric name="mjrft:region" data="0 0 0 1 1"/>' + TAG, None, "mjrft:region"),
        (MAT + '<numeric name="mjrft:region" data="0 0 0 1 -1 1"/>' + TAG, None, "min must be"),
        (MAT + '<numeric name="mjrft:zeta" data="1e5"/>' + TAG, None, "both mjrft:material"),
        ('<numeric name="mjrft:zeta" data="-3"/>' + TAG, None, "mjrft:zeta.*> 0"),
        (
            '<numeric name="mjrft:zeta" data="1e5"/><numeric name="mjrft:coefficients" data="1 2"/>'
            + TAG,
            None,
            "mjrft:coefficients.*9 numbers",
        ),
        (MAT + '<numeric name="mjrft:triangles" data="3.5"/>' + TAG, None, "mjrft:triangles"),
        (
            MAT + '<tuple name="mjrft:intruders"><element objtype="geom" objname="m" prm="100"/>'
            "</tuple>",
            '<geom name="m" type="mesh" mesh="tet"/>',
            "geom 'm' is a mesh.*prm must be 0",
        ),
    ],
)
def test_mjcf_errors_name_the_culprit(custom, geom, match):
    asset = '<asset><mesh name="tet" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/></asset>' if geom else ""
    xml = xml_with(custom, geom or '<geom name="ball" size="0.01"/>').replace(
        "<custom>", asset + "<custom>"
    )
    with pytest.raises(SceneError, match=match):
        mjrft.load_model(xml)


def test_world_geom_cannot_intrude():
    xml = xml_with(
        MAT + '<tuple name="mjrft:intruders"><element objtype="geom" objname="w" prm="0"/></tuple>'
    ).replace("<worldbody>", '<worldbody><geom name="w" size="0.01"/>')
    with pytest.raises(SceneError, match="geom 'w' belongs to the world body"):
        mjrft.load_model(xml)


def test_material_from_mjcf_coefficients_and_zeta():
    li = " ".join(str(x) for x in (0.206, 0.169, 0.212, 0.358, 0.055, -0.124, 0.253, 0.007, 0.088))
    custom = (
        '<numeric name="mjrft:zeta" data="330000"/>'
        f'<numeric name="mjrft:coefficients" data="{li}"/>'
    )
    m1 = mjrft.load_model(xml_with(custom + TAG))
    m2 = mjrft.load_model(xml_with(MAT + TAG))
    d1, d2 = mujoco.MjData(m1), mujoco.MjData(m2)
    for d in (d1, d2):
        d.qpos[2] = -0.02
        set_motion(d)
    mujoco.mj_forward(m1, d1)
    mujoco.mj_forward(m2, d2)
    np.testing.assert_allclose(
        GranularField(m1).wrench(d1), GranularField(m2).wrench(d2), rtol=1e-12
    )
