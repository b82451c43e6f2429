"""The MuJoCo field: scene parsing, wrenches, the installed path and its composition rules."""

import copy

import mujoco
import numpy as np
import pytest
import quadrature_reference

import mjrft
from mjrft.body import quat_to_mat
from mjrft.field import GranularField
from mjrft.field import guard as _callback
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


def ball_model(**kw):
    return mujoco.MjModel.from_xml_string(scene_xml(BALL, **kw))


# A heavy ball shot steeply into the medium keeps moving throughout the comparison runs: RFT is
# discontinuous where a velocity reverses (the low-speed treatment's territory), and there round-off
# differences between two equivalent paths would grow chaotically instead of staying at 1e-15.
HEAVY_BALL = BALL.replace('density="2500"', 'density="60000"')
SHOT = {"v": (0.2, -0.1, -1.0), "w": (3.0, -2.0, 1.0)}


def heavy_model(**kw):
    return mujoco.MjModel.from_xml_string(scene_xml(HEAVY_BALL, **kw))


def set_motion(d, v=(0.02, -0.01, -0.03), w=(1.0, -2.0, 0.5)):
    d.qvel[:3] = v
    d.qvel[3:6] = w


def test_wrench_layout_and_zero_elsewhere():
    m = ball_model()
    d = mujoco.MjData(m)
    set_motion(d)
    mujoco.mj_forward(m, d)
    w = GranularField(m, low_speed="off").wrench(d)
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
    m = mujoco.MjModel.from_xml_string(mesh_scene())
    # MuJoCo re-centred the mesh: the geom frame is no longer what the MJCF wrote.
    assert not np.allclose(m.geom_pos[0], GEOM_POS)
    d = mujoco.MjData(m)
    v, w_local = np.array([0.03, -0.02, -0.05]), np.array([1.5, -0.7, 2.0])
    d.qvel[:3], d.qvel[3:6] = v, w_local
    mujoco.mj_forward(m, d)
    wrench = GranularField(m, low_speed="off").wrench(d)

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
    m = mujoco.MjModel.from_xml_string(scene_xml(TWO_BODIES, tagged=TWO_TAGS))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    d.qvel[:] = rng.normal(size=m.nv) * 0.1
    mujoco.mj_forward(m, d)
    fld = GranularField(m, low_speed="off")
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


# ------------------------------------------------------------------ installed path
def simulate(m, n, *, installed=True, user=None, explicit=False, fld=None, motion=None):
    d = mujoco.MjData(m)
    set_motion(d, **(motion or {}))
    fld = fld or GranularField(m)
    user = np.zeros((m.nbody, 6)) if user is None else user
    traj = []
    if explicit:
        for _ in range(n):
            mujoco.mj_forward(m, d)
            d.xfrc_applied[:] = user + fld.wrench(d)
            mujoco.mj_step(m, d)
            traj.append(np.concatenate([d.qpos, d.qvel]))
        return np.array(traj), d
    d.xfrc_applied[:] = user
    with fld.installed() if installed else _null():
        for _ in range(n):
            mujoco.mj_step(m, d)
            traj.append(np.concatenate([d.qpos, d.qvel]))
    return np.array(traj), d


class _null:
    def __enter__(self):
        return self

    def __exit__(self, *a):
        return False


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast"])
def test_explicit_path_equals_installed_path(integrator):
    m = heavy_model(option=f'integrator="{integrator}"')
    user = np.zeros((m.nbody, 6))
    user[1] = [0.01, -0.02, 0.03, 1e-4, 0, -2e-4]
    a, _ = simulate(m, 80, user=user, motion=SHOT)
    assert np.all(a[:, m.nq + 2] < -0.1)  # still plunging: no velocity reversal
    b, _ = simulate(m, 80, user=user, explicit=True, motion=SHOT)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    free, _ = simulate(m, 80, user=user, installed=False, motion=SHOT)
    assert not np.allclose(a, free, atol=1e-3)  # the field really acted


def test_no_lag_force_is_from_the_state_being_stepped():
    m = ball_model()
    fld = GranularField(m)
    d = mujoco.MjData(m)
    set_motion(d)
    for _ in range(5):
        before = mujoco.MjData(m)
        before.qpos[:], before.qvel[:] = d.qpos, d.qvel
        mujoco.mj_forward(m, before)
        expected = fld.wrench(before)
        with fld.installed():
            mujoco.mj_step(m, d)
            np.testing.assert_allclose(fld.last_wrench, expected, rtol=1e-12, atol=1e-15)
        # The step's acceleration is that of the pre-step state under exactly that wrench.
        before.xfrc_applied[:] = expected
        mujoco.mj_forward(m, before)
        np.testing.assert_allclose(d.qacc, before.qacc, rtol=1e-9, atol=1e-9)


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
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[0] = -0.01
    fld = GranularField(m)
    with fld.installed():
        mujoco.mj_forward(m, d)
    w = fld.last_wrench[m.body("b").id]
    assert w[2] > 0.01
    # Parent-on-child force = m a - F_ext; this slide keeps x, y from accelerating.
    acc = np.zeros(6)
    mujoco.mj_objectAcceleration(m, d, mujoco.mjtObj.mjOBJ_BODY, m.body("b").id, acc, 0)
    expected = m.body("b").mass[0] * acc[3:] - w[:3]
    np.testing.assert_allclose(d.sensordata[:3], expected, rtol=1e-6, atol=1e-9)


def test_user_rows_survive_assignment_between_steps_and_are_restored():
    m = ball_model()
    fld = GranularField(m)
    d = mujoco.MjData(m)
    set_motion(d)
    push = np.array([0.01, 0.0, 0.02, 0.0, 1e-4, 0.0])
    with fld.installed():
        d.xfrc_applied[1] = push
        mujoco.mj_step(m, d)
        np.testing.assert_array_equal(d.xfrc_applied[1], push + fld.last_wrench[1])
        np.testing.assert_array_equal(fld.user_xfrc(d)[1], push)
        d.xfrc_applied[:] = 0.0  # what the interactive viewer does before applying a perturbation
        mujoco.mj_step(m, d)
        np.testing.assert_array_equal(d.xfrc_applied[1], fld.last_wrench[1])
        np.testing.assert_array_equal(fld.user_xfrc(d)[1], np.zeros(6))
        d.xfrc_applied[1] = 2 * push
        mujoco.mj_step(m, d)
        np.testing.assert_array_equal(fld.user_xfrc(d)[1], 2 * push)
    np.testing.assert_array_equal(d.xfrc_applied[1], 2 * push)  # the field's part is removed


def test_writing_one_component_assigns_only_that_component():
    """A 0.1 mN push written into one component of a resting ball's row is the user's part of
    that component only: the RFT force in the other components stays the field's (read as the
    user's, it would be added again every step and throw the ball out of the medium)."""
    m = ball_model()
    fld = GranularField(m)
    d = mujoco.MjData(m)
    with fld.installed():
        for _ in range(300):  # released partly submerged: sinks a little and rests
            mujoco.mj_step(m, d)
        rest = d.qpos[2]
        assert fld.last_wrench[1, 2] > 0.5 * m.body_mass[1] * 9.81  # the medium carries it
        d.xfrc_applied[1, 0] = 1e-4
        for _ in range(500):
            mujoco.mj_step(m, d)
        user = fld.user_xfrc(d)[1]
        np.testing.assert_array_equal(user, [1e-4, 0, 0, 0, 0, 0])
        np.testing.assert_array_equal(d.xfrc_applied[1], user + fld.last_wrench[1])
    assert abs(d.qpos[2] - rest) < 1e-3  # still in the medium, not thrown out
    np.testing.assert_array_equal(d.xfrc_applied[1], [1e-4, 0, 0, 0, 0, 0])  # restored


def test_copied_data_keeps_only_the_user_part():
    m = heavy_model()
    fld = GranularField(m)
    d = mujoco.MjData(m)
    set_motion(d, **SHOT)
    d.xfrc_applied[1, :3] = [0.1, 0.0, 0.2]
    with fld.installed():
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
    assert np.array_equal(da.xfrc_applied, user)  # untouched by the field
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
    with fld.installed():
        for n in range(1, 4):
            mujoco.mj_step(m, d)
            assert fld.stats["calls"] == 4 * n  # natively handled passes count too
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER  # read live by the native pass
    with fld.installed():
        mujoco.mj_step(m, d)
    assert fld.stats["calls"] == 13


def test_rk4_holds_a_body_at_rest_over_the_step():
    """A body the treatment holds keeps its first stage's wrench over the step: one evaluated
    pass per step, and it ends each step exactly at rest."""
    m = ball_model(option='integrator="RK4"')
    fld = GranularField(m)
    d = mujoco.MjData(m)
    with fld.installed():
        for _ in range(300):  # released at rest, partly submerged: sinks a little and stops
            mujoco.mj_step(m, d)
        calls, stuck = fld.stats["calls"], fld.stats["stuck"]
        for n in range(1, 4):
            mujoco.mj_step(m, d)
            assert fld.stats["calls"] == calls + n and fld.stats["stuck"] == stuck + n
            assert np.abs(d.qvel).max() <= 1e-15  # at rest to round-off
        mujoco.mj_forward(m, d)  # a user's forward pass between steps is evaluated afresh
        mujoco.mj_step(m, d)  # ... and so is the next step's first stage, at the same time
        assert fld.stats["calls"] == calls + 5


def test_interleaved_mjdata_of_one_field_step_as_if_alone():
    """The pass keeps its work arrays (hold and freeze flags, culling rows, RK4 records) per
    MjData: stepping two MjData in turn must give bit for bit what each gives stepped alone,
    including a body the treatment holds at rest under RK4."""
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
        with fld.installed():
            for _ in range(steps):
                mujoco.mj_step(m, d)
        alone.append((d.qpos.copy(), d.qvel.copy()))
    pair = [fresh(False), fresh(True)]
    with fld.installed():
        for _ in range(steps):
            for d in pair:
                mujoco.mj_step(m, d)
    assert fld.stats["stuck"] > 0  # the hold (RK4_HOLD records) was exercised
    for d, (qpos, qvel) in zip(pair, alone, strict=True):
        np.testing.assert_array_equal(d.qpos, qpos)
        np.testing.assert_array_equal(d.qvel, qvel)


def test_rk4_stage_rule_equals_the_reference():
    from field_reference import rk4_stage_held

    from mjrft.field.rk4 import stage_held

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
        assert [bool(stage_held(t, h, rec)) for t in seq] == want
        assert [rk4_stage_held(t, h, reference) for t in seq] == want


# A light ball just below the surface, sinking slowly: the implicit step moves it, and RK4's
# later stages keep its first stage's twist and correction (mjrft.field.rk4.RK4_FROZEN).
SINKING_BALL = BALL.replace('pos="0.01 -0.02 -0.004"', 'pos="0.01 -0.02 0.008"')
SINKING = {"v": (0.001, 0.0, -0.01), "w": (0.3, -0.2, 0.1)}


@pytest.mark.parametrize("start", ["moving", "resting", "sinking"])
def test_python_material_path_follows_the_same_rk4_rule(start):
    """A medium given as Python callables (evaluated in Python inside the compiled pass) follows
    the same RK4 rule."""
    if start == "sinking":
        m = mujoco.MjModel.from_xml_string(scene_xml(SINKING_BALL, option='integrator="RK4"'))
    else:
        m = heavy_model(option='integrator="RK4"')
    compiled = GranularField(m)
    mat = mjrft.Material.from_callables(
        compiled.material.fourier.alpha_x, compiled.material.fourier.alpha_z,
        compiled.material.zeta, name="glass, callables",
    )  # fmt: skip
    fld = GranularField(m, material=mat)
    rest = {"v": (0.0, 0.0, 0.0), "w": (0.0, 0.0, 0.0)}
    motion = {"moving": SHOT, "resting": rest, "sinking": SINKING}[start]
    a, _ = simulate(m, 40, fld=fld, motion=motion)
    b, _ = simulate(m, 40, fld=compiled, motion=motion)
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9)
    held = compiled.stats["calls"] < 4 * 40  # some steps held (resting), none (moving)
    assert held == (start == "resting")
    implicit = compiled.stats["implicit"]  # its RK4 stages keep the twist, evaluated anew
    assert fld.stats["implicit"] == implicit and (implicit > 0 or start != "sinking")


def test_compilation_works_while_installed_and_callback_restored():
    m = ball_model()
    assert mujoco.get_mjcb_passive() is None
    with GranularField(m).installed():
        other = mujoco.MjModel.from_xml_string(scene_xml(BALL))
        spec = mujoco.MjSpec.from_string(scene_xml(BALL))
        spec.compile()
        d = mujoco.MjData(other)
        mujoco.mj_step(other, d)  # another model steps without the field
        assert np.array_equal(d.xfrc_applied, np.zeros((other.nbody, 6)))
    assert mujoco.get_mjcb_passive() is None
    assert _callback.installed_models() == 0


def test_two_fields_on_two_models_do_not_interfere():
    m1 = ball_model()
    m2 = mujoco.MjModel.from_xml_string(scene_xml(TWO_BODIES, tagged=TWO_TAGS))
    f1, f2 = GranularField(m1), GranularField(m2)
    alone1, _ = simulate(m1, 100, fld=f1)
    alone2, _ = simulate(m2, 100, fld=f2)
    d1, d2 = mujoco.MjData(m1), mujoco.MjData(m2)
    set_motion(d1)
    set_motion(d2)
    both1, both2 = [], []
    with f1.installed(), f2.installed():
        for _ in range(100):
            mujoco.mj_step(m1, d1)
            mujoco.mj_step(m2, d2)
            both1.append(np.concatenate([d1.qpos, d1.qvel]))
            both2.append(np.concatenate([d2.qpos, d2.qvel]))
    np.testing.assert_array_equal(np.array(both1), alone1)
    np.testing.assert_array_equal(np.array(both2), alone2)
    with f1.installed(), pytest.raises(RuntimeError, match="already installed"):
        with GranularField(m1).installed():
            pass


def test_user_passive_callback_is_chained_and_restored():
    m = ball_model()
    seen = []

    def user_cb(mm, dd):
        seen.append(mm is m)

    mujoco.set_mjcb_passive(user_cb)
    try:
        d = mujoco.MjData(m)
        with GranularField(m).installed():
            mujoco.mj_step(m, d)
        assert seen == [True]
        assert mujoco.get_mjcb_passive() is user_cb
    finally:
        mujoco.set_mjcb_passive(None)


def test_non_finite_state_raises_naming_body_and_interpreter_survives():
    # MuJoCo's own check resets NaN qvel before the forward pass unless autoreset is disabled.
    m = ball_model(option='><flag autoreset="disable"/></option><option')
    d = mujoco.MjData(m)
    set_motion(d)
    fld = GranularField(m)
    with fld.installed():
        for _ in range(3):  # repeated escapes through mj_step must stay safe
            d.qvel[0] = np.nan
            with pytest.raises(FloatingPointError, match=r"body 'b'.*time .*\(step \d+\)"):
                mujoco.mj_step(m, d)
        d.qvel[:] = 0
        mujoco.mj_step(m, d)
    assert np.all(np.isfinite(d.qpos))


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
    m = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(SceneError, match=match):
        GranularField(m)


def test_world_geom_cannot_intrude():
    xml = xml_with(
        MAT + '<tuple name="mjrft:intruders"><element objtype="geom" objname="w" prm="0"/></tuple>'
    ).replace("<worldbody>", '<worldbody><geom name="w" size="0.01"/>')
    with pytest.raises(SceneError, match="geom 'w' belongs to the world body"):
        GranularField(mujoco.MjModel.from_xml_string(xml))


def test_material_from_mjcf_coefficients_and_zeta():
    li = " ".join(str(x) for x in (0.206, 0.169, 0.212, 0.358, 0.055, -0.124, 0.253, 0.007, 0.088))
    custom = (
        '<numeric name="mjrft:zeta" data="330000"/>'
        f'<numeric name="mjrft:coefficients" data="{li}"/>'
    )
    m1 = mujoco.MjModel.from_xml_string(xml_with(custom + TAG))
    m2 = mujoco.MjModel.from_xml_string(xml_with(MAT + TAG))
    d1, d2 = mujoco.MjData(m1), mujoco.MjData(m2)
    for d in (d1, d2):
        d.qpos[2] = -0.02
        set_motion(d)
    mujoco.mj_forward(m1, d1)
    mujoco.mj_forward(m2, d2)
    np.testing.assert_allclose(
        GranularField(m1).wrench(d1), GranularField(m2).wrench(d2), rtol=1e-12
    )
