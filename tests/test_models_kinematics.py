"""Kinematic checks of the MJCF rigs in models/ with plain MuJoCo (no RFT forces applied).

Load-cell sign/frame convention (MuJoCo <force>/<torque> sensors, verified below in
test_load_cell_reads_weight_and_convention): the sensor site sits on the child body (the
intruder's jointless body) and reads the force and the torque that the PARENT body exerts ON the
child's subtree, expressed in the site frame, the torque taken about the site origin. So for a
child subtree of mass m with acceleration a (at its centre of mass) under an external force F and
external torque T about the site (e.g. the RFT wrench):
    f_site = R_site^T (m (a - g_vec) - F),    g_vec = (0, 0, -9.81)
which is +m g along world up at rest in air and -F (+ weight) quasi-statically; likewise the
torque is minus the external moment about the site (plus gravity/inertia moments).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

MODELS = Path(__file__).resolve().parent.parent / "models"
XMLS = sorted(MODELS.glob("*.xml"))
#: Robots tag their legs by subtree and stand on a medium of their own (tests/test_go2_sand.py);
#: the rig conventions below (an intruder tuple, glass beads, key "start") are the rigs'.
ROBOTS = {"go2_sand.xml"}
RIGS = [p for p in XMLS if p.name not in ROBOTS]
G = 9.81


def load(name: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_path(str(MODELS / name))
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    return model, data


def intruders(model: mujoco.MjModel) -> dict[int, float]:
    """geom id -> prm of the mjrft:intruders tuple."""
    t = model.tuple("mjrft:intruders")
    adr, size = int(model.tuple_adr[t.id]), int(model.tuple_size[t.id])
    out = {}
    for k in range(adr, adr + size):
        assert model.tuple_objtype[k] == mujoco.mjtObj.mjOBJ_GEOM
        out[int(model.tuple_objid[k])] = float(model.tuple_objprm[k])
    return out


def text(model: mujoco.MjModel, name: str) -> str:
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, name)
    assert i >= 0, f"no <text name={name!r}>"
    adr, size = model.text_adr[i], model.text_size[i]
    return bytes(model.text_data[adr : adr + size]).rstrip(b"\0").decode()


def geom_min_z(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> float:
    """Lowest world z of geom g's bounding box."""
    centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    row = data.geom_xmat[g].reshape(3, 3)[2]
    return float(data.geom_xpos[g, 2] + row @ centre - np.abs(row) @ half)


def mesh_world_vertices(model: mujoco.MjModel, data: mujoco.MjData, geom: str) -> np.ndarray:
    g = model.geom(geom)
    mid = int(g.dataid[0])
    adr, n = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
    verts = model.mesh_vert[adr : adr + n]
    return data.geom(geom).xpos + verts @ data.geom(geom).xmat.reshape(3, 3).T


def zero_crossing_times(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    i = np.where((x[:-1] < 0.0) & (x[1:] >= 0.0))[0]
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


# --- every model ---------------------------------------------------------------------------------


def test_models_exist():
    names = {p.name for p in XMLS}
    assert {
        "plate_rig.xml",
        "ellipsoid_pitch.xml",
        "root_circumnutation.xml",
        "sphere_drop.xml",
    } <= names


@pytest.mark.parametrize("xml", RIGS, ids=lambda p: p.stem)
def test_tags_and_no_contacts(xml: Path):
    model, _ = load(xml.name)
    tags = intruders(model)
    assert tags, "mjrft:intruders lists no geoms"
    for g, prm in tags.items():
        assert 0 <= g < model.ngeom
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            assert prm == 0
        assert prm >= 0 and prm == int(prm)
    assert text(model, "mjrft:material") == "glass_beads"
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, "mjrft:surface_hfield") >= 0:
        hfield = model.hfield(text(model, "mjrft:surface_hfield")).id  # placed by its one geom
        assert list(model.geom_dataid[model.geom_type == mujoco.mjtGeom.mjGEOM_HFIELD]) == [hfield]
    else:
        assert model.numeric("mjrft:surface_z").data[0] == 0.0
    assert model.numeric("mjrft:triangles").data[0] > 0
    assert np.all(model.geom_contype == 0) and np.all(model.geom_conaffinity == 0)
    assert model.nkey >= 1 and model.key(0).name == "start"
    assert model.opt.timestep == 0.001
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER


@pytest.mark.parametrize("integrator", ["EULER", "RK4"])
@pytest.mark.parametrize("xml", XMLS, ids=lambda p: p.stem)
def test_runs_one_second(xml: Path, integrator: str):
    model, data = load(xml.name)
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator}")
    mujoco.mj_resetDataKeyframe(model, data, 0)
    for _ in range(round(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    for arr in (data.qpos, data.qvel, data.act, data.sensordata, data.qacc):
        assert np.all(np.isfinite(arr))
    assert data.time == pytest.approx(1.0)
    # No warnings (instabilities, bad qacc, constraint overflows).
    assert all(w.number == 0 for w in data.warning)


# --- ellipsoid_pitch.xml ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def ellipsoid_run() -> dict[str, np.ndarray]:
    model, data = load("ellipsoid_pitch.xml")
    skip = {"ellipsoid", "stalk", "sand_surface"}  # intruder, rod into the sand, world visual
    check_geoms = [g for g in range(model.ngeom) if model.geom(g).name not in skip]
    linkage_bodies = [model.body(n).id for n in ("carriage", "crank", "coupler")]
    n = 12000
    out = {k: np.zeros(n + 1) for k in ("t", "pitch", "crank", "pivot_z", "closure")}
    out["min_z"] = np.inf
    for i in range(n + 1):
        # mj_step1 computes positions and position sensors of the current state; record between
        # it and mj_step2 (integration) so values and time agree (after a full mj_step the
        # sensors and xpos lag qpos by one step).
        mujoco.mj_step1(model, data)
        out["t"][i] = data.time
        out["pitch"][i] = data.sensor("pitch").data[0]
        out["crank"][i] = data.sensor("crank_angle").data[0]
        out["pivot_z"][i] = data.sensor("pivot_pos").data[2]
        pin, end = data.sensor("rocker_pin_pos").data, data.sensor("coupler_end_pos").data
        out["closure"][i] = np.linalg.norm(pin - end)
        if i % 10 == 0:
            low = min(geom_min_z(model, data, g) for g in check_geoms)
            low = min(low, float(data.xpos[linkage_bodies, 2].min()))
            out["min_z"] = min(out["min_z"], low)
        mujoco.mj_step2(model, data)
    return out


def test_ellipsoid_pitch_amplitude_and_frequency(ellipsoid_run):
    t, p = ellipsoid_run["t"], ellipsoid_run["pitch"]
    amp = np.abs(p[t > 1.6]).max()
    assert amp == pytest.approx(math.radians(9.0), rel=0.05)
    # Both extremes are +-9 deg by design (to 1e-3 deg with the linkage solved exactly).
    assert p[t > 1.6].max() == pytest.approx(math.radians(9.0), abs=math.radians(0.01))
    assert p[t > 1.6].min() == pytest.approx(-math.radians(9.0), abs=math.radians(0.01))
    freq = 1.0 / np.diff(zero_crossing_times(t, p)).mean()
    assert freq == pytest.approx(0.625, rel=0.05)
    assert freq == pytest.approx(0.625, rel=1e-4)  # phase-locked crank: essentially exact
    # Close to 9 deg sin(omega t): max deviation 0.47 deg by design (second harmonic).
    w = 2.0 * math.pi * 0.625
    assert np.abs(p - math.radians(9.0) * np.sin(w * t)).max() < math.radians(0.5)
    # Crank tracks omega t.
    assert np.abs(ellipsoid_run["crank"] - w * t).max() < 1e-4


def test_ellipsoid_pitch_starts_at_zero_and_rises(ellipsoid_run):
    t, p = ellipsoid_run["t"], ellipsoid_run["pitch"]
    assert abs(p[0]) < 1e-9
    assert np.all(np.diff(p[t <= 0.3]) > 0.0)


def test_ellipsoid_descent_and_start_height(ellipsoid_run):
    t, z = ellipsoid_run["t"], ellipsoid_run["pivot_z"]
    assert z[0] == pytest.approx(0.018, abs=1e-6)  # the authors' start: pivot 1.8 cm up
    speed = -np.polyfit(t, z, 1)[0]
    assert speed == pytest.approx(0.005, rel=0.02)
    assert z[-1] == pytest.approx(0.018 - 0.06, abs=1e-4)


def test_ellipsoid_has_the_released_dimensions():
    """Semi-axes of the authors' released ellipsoid about its centre (their point of rotation):
    from the 1.8 cm start height the tip starts 0.05 mm below the surface; the stalk starts at
    the ellipsoid's top."""
    model, data = load("ellipsoid_pitch.xml")
    ellipsoid = model.geom("ellipsoid")
    np.testing.assert_allclose(ellipsoid.size, [0.0096, 0.0096, 0.01805], rtol=1e-12)
    assert geom_min_z(model, data, ellipsoid.id) == pytest.approx(-0.00005, abs=1e-9)
    stalk = model.geom("stalk")  # a vertical capsule: pos = midpoint, size[1] = half-length
    assert stalk.pos[2] - stalk.size[1] == pytest.approx(0.01805, abs=1e-9)


def test_ellipsoid_loop_closure(ellipsoid_run):
    assert ellipsoid_run["closure"][0] < 1e-9
    assert ellipsoid_run["closure"].max() < 1e-4


def test_ellipsoid_linkage_stays_above_surface(ellipsoid_run):
    assert ellipsoid_run["min_z"] > 0.0


def test_ellipsoid_loop_closure_under_rft_sized_load():
    """10 N forces and 0.1 N m moments on the ellipsoid keep the loop closed to < 0.1 mm."""
    model, data = load("ellipsoid_pitch.xml")
    b = model.body("ellipsoid").id
    worst = 0.0
    for _ in range(3000):
        ramp = min(1.0, data.time / 0.5)
        data.xfrc_applied[b, :3] = ramp * np.array([-10.0, 5.0, 10.0]) * math.sin(3 * data.time)
        data.xfrc_applied[b, 3:] = ramp * np.array([0.1, -0.1, 0.1]) * math.cos(5 * data.time)
        mujoco.mj_step(model, data)
        pin, end = data.sensor("rocker_pin_pos").data, data.sensor("coupler_end_pos").data
        worst = max(worst, float(np.linalg.norm(pin - end)))
    assert worst < 1e-4
    assert np.all(np.isfinite(data.qpos))


def test_load_cell_reads_weight_and_convention():
    model, data = load("ellipsoid_pitch.xml")
    # Hold the rig still in air: zero velocity commands, servos at their static targets.
    data.qvel[:] = 0.0
    data.ctrl[:] = 0.0
    subtree = model.body_subtreemass[model.body("carriage").id]
    data.act[:] = [0.0, data.qpos[0] + subtree * G / 1e5]  # crank target 0, descent + sag
    b = model.body("ellipsoid").id
    m = model.body_subtreemass[b]
    for _ in range(1000):
        mujoco.mj_step(model, data)
    rot = data.site("load_cell").xmat.reshape(3, 3)
    f_world = rot @ data.sensor("load_cell_force").data
    t_world = rot @ data.sensor("load_cell_torque").data
    # Parent pushes the child up with its weight: the sensor reads +m g along world up.
    np.testing.assert_allclose(f_world, [0.0, 0.0, m * G], atol=0.01 * m * G)
    np.testing.assert_allclose(t_world, 0.0, atol=1e-6)
    # An external force/torque on the child (applied at its centre = the site) is read negated.
    force, torque = np.array([0.05, 0.02, -0.03]), np.array([1e-3, 2e-3, -3e-3])
    data.xfrc_applied[b] = np.concatenate([force, torque])
    for _ in range(1000):
        mujoco.mj_step(model, data)
    rot = data.site("load_cell").xmat.reshape(3, 3)
    f_world = rot @ data.sensor("load_cell_force").data
    t_world = rot @ data.sensor("load_cell_torque").data
    np.testing.assert_allclose(f_world, [0.0, 0.0, m * G] - force, atol=1e-4)
    np.testing.assert_allclose(t_world, -torque, atol=1e-6)


# --- root_circumnutation.xml ------------------------------------------------------------------


def test_root_start_tip_depth():
    model, data = load("root_circumnutation.xml")
    assert data.sensor("descent_pos").data[0] == 0.0  # pivot at the surface
    low = mesh_world_vertices(model, data, "root_tip")[:, 2].min()
    assert low == pytest.approx(-0.0358 * math.cos(math.radians(10.0)), abs=5e-4)
    assert model.mesh_facenum[model.mesh("root_tip").id] >= 2000


def test_root_has_the_released_dimensions():
    """The authors' released root tip: 34.6 mm from apex to base, 10 mm base radius, the apex
    35.8 mm below the pivot (their point of rotation) on the axis."""
    tol = 1e-8  # m: MuJoCo stores mesh vertices in single precision (~2e-9 m at 2 cm)
    model, data = load("root_circumnutation.xml")
    root = data.body("root")
    local = (mesh_world_vertices(model, data, "root_tip") - root.xpos) @ root.xmat.reshape(3, 3)
    assert local[:, 2].min() == pytest.approx(-0.0358, abs=tol)
    assert local[:, 2].max() == pytest.approx(-0.0358 + 0.0346, abs=tol)
    assert np.hypot(local[:, 0], local[:, 1]).max() == pytest.approx(0.010, abs=tol)
    apex = local[np.argmin(local[:, 2])]
    np.testing.assert_allclose(apex, [0.0, 0.0, -0.0358], atol=tol)
    np.testing.assert_allclose(model.site("tip").pos, apex, atol=tol)  # site "tip" = apex


def test_root_one_turn_in_24_s_and_4_cm_per_turn():
    model, data = load("root_circumnutation.xml")
    yaw0, z0 = data.joint("yaw").qpos[0], data.joint("descent").qpos[0]
    tip = [data.sensor("tip_pos").data.copy()]
    for i in range(24000):
        mujoco.mj_step(model, data)
        if i % 1000 == 999:
            tip.append(data.sensor("tip_pos").data.copy())
    assert data.time == pytest.approx(24.0)
    turns = (data.joint("yaw").qpos[0] - yaw0) / (2.0 * math.pi)
    drop = z0 - data.joint("descent").qpos[0]
    assert turns == pytest.approx(1.0, rel=0.02)
    assert drop / turns == pytest.approx(0.04, rel=0.02)
    # The tip circles at radius 35.8 sin(10 deg) about the pivot's vertical.
    radius = np.hypot(*np.array(tip)[:, :2].T)
    np.testing.assert_allclose(radius, 0.0358 * math.sin(math.radians(10.0)), rtol=1e-3)


# --- plate_rig.xml --------------------------------------------------------------------------


def plate_lowest_corner(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    half = model.geom("plate").size
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    corners = data.geom("plate").xpos + (signs * half) @ data.geom("plate").xmat.reshape(3, 3).T
    return float(corners[:, 2].min())


def test_plate_start_clearance_and_speed():
    model, data = load("plate_rig.xml")
    assert plate_lowest_corner(model, data) == pytest.approx(0.002, abs=5e-4)
    for _ in range(200):
        mujoco.mj_step(model, data)
    z1 = data.sensor("plate_pos").data.copy()
    for _ in range(300):
        mujoco.mj_step(model, data)
    vel = (data.sensor("plate_pos").data - z1) / 0.3
    np.testing.assert_allclose(vel, [0.0, 0.0, -0.01], atol=0.02 * 0.01)
    assert data.sensor("vz").data[0] == pytest.approx(-0.01, rel=0.02)


# --- sphere_drop.xml ------------------------------------------------------------------------


@pytest.mark.parametrize("integrator", ["EULER", "RK4"])
def test_sphere_free_fall(integrator: str):
    model, data = load("sphere_drop.xml")
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator}")
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    z0 = data.sensor("sphere_pos").data[2]
    assert z0 - 0.01 == pytest.approx(0.001, abs=1e-12)  # lowest point 1 mm above the surface
    h = model.opt.timestep
    for n in range(1, 11):
        mujoco.mj_step(model, data)
        z = data.qpos[2]
        t = n * h
        if integrator == "RK4":  # exact for constant acceleration
            assert z == pytest.approx(z0 - G * t**2 / 2, abs=1e-6)
        else:
            # Semi-implicit Euler: z_n = z0 - g h^2 n (n + 1) / 2, i.e. the analytic value minus
            # g h t / 2 (49 um at 10 ms): compare with the discrete solution instead.
            assert z == pytest.approx(z0 - G * h * h * n * (n + 1) / 2, abs=1e-9)
            assert z == pytest.approx(z0 - G * t**2 / 2, abs=G * h * t / 2 + 1e-9)
    mujoco.mj_forward(model, data)
    assert data.sensor("sphere_vel").data[2] == pytest.approx(-G * 10 * h, abs=1e-9)
