"""Free surfaces that vary with position: a tilted plane and a MuJoCo height field
(mjrft.core.surface; depth measured vertically below the local surface)."""

import field_reference as ref
import mujoco
import numpy as np
import pytest

import mjrft
from mjrft import Material
from mjrft.core import soil, surface
from mjrft.field import GranularField, SceneError

# A sum of element forces over a body symmetric about its centre, each force linear in its
# depth, equals the force at the centre's depth up to rounding of the depth sums.
SYMMETRIC_RTOL = 1e-9
# MuJoCo's mj_ray finds the height-field surface by intersecting its triangles; it agrees with
# the interpolation to rounding of the ray parameter.
RAY_ATOL = 1e-9


def scene(surface: str, body: str, asset: str = "", extra_geom: str = "") -> str:
    return f"""<mujoco><option timestep="0.001"><flag contact="disable"/></option>
      <asset>{asset}</asset>
      <custom><text name="mjrft:material" data="glass_beads"/>{surface}
        <tuple name="mjrft:intruders"><element objtype="body" objname="b" prm="0"/></tuple>
        <numeric name="mjrft:triangles" data="600"/>
      </custom>
      <worldbody>{extra_geom}{body}</worldbody></mujoco>"""


PLATE = """<body name="b" pos="0.3 -0.2 0"><freejoint/>
  <geom type="box" size="0.01 0.015 0.002" density="2500"/></body>"""
SPHERE = """<body name="b" pos="0 0 0"><freejoint/>
  <geom type="sphere" size="0.01" density="2500"/></body>"""


def hfield_asset(nrow: int, ncol: int, elevation: np.ndarray, size: str) -> str:
    values = " ".join(f"{v:.6f}" for v in elevation.ravel())
    return f'<hfield name="dune" nrow="{nrow}" ncol="{ncol}" size="{size}" elevation="{values}"/>'


def hfield_geom(pos: str = "0.05 -0.02 0.01") -> str:
    return (
        f'<geom name="ground" type="hfield" hfield="dune" pos="{pos}" contype="0" conaffinity="0"/>'
    )


def placed(m: mujoco.MjModel, pos, quat, v, omega) -> mujoco.MjData:
    d = mujoco.MjData(m)
    d.qpos[:3], d.qpos[3:7] = pos, quat
    d.qvel[:3], d.qvel[3:6] = v, omega
    mujoco.mj_forward(m, d)
    return d


def test_height_field_surface_is_mujocos_collision_surface():
    """The surface's height at random points equals where MuJoCo's own ray casting meets the
    height field (its collision triangles), across the whole footprint and beyond its edge."""
    rng = np.random.default_rng(3)
    nrow, ncol = 7, 9
    asset = hfield_asset(nrow, ncol, rng.uniform(size=(nrow, ncol)), "0.3 0.2 0.05 0.01")
    m = mjrft.load_model(scene(
        '<text name="mjrft:surface_hfield" data="dune"/>', SPHERE, asset, hfield_geom()
    ))  # fmt: skip
    fld = GranularField(m)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    x = 0.05 + rng.uniform(-0.3, 0.3, 200)
    y = -0.02 + rng.uniform(-0.2, 0.2, 200)
    geomid = np.zeros(1, dtype=np.int32)
    ground = None  # every geom group
    ray = []
    for xi, yi in zip(x, y, strict=True):
        dist = mujoco.mj_ray(m, d, np.array([xi, yi, 1.0]), np.array([0, 0, -1.0]), ground, 1,
                             m.body("b").id, geomid)  # fmt: skip
        assert geomid[0] == m.geom("ground").id
        ray.append(1.0 - dist)
    np.testing.assert_allclose(fld.surface.height(x, y), ray, atol=RAY_ATOL)
    np.testing.assert_allclose(ref.surface_height(fld, x, y), ray, atol=RAY_ATOL)
    # Beyond the footprint the edge continues.
    np.testing.assert_allclose(fld.surface.height(0.05 + 0.5, -0.02 - 0.2),
                               fld.surface.height(0.05 + 0.3, -0.02 - 0.2), atol=0)  # fmt: skip


def _over_triangles(prm: np.ndarray, values: np.ndarray, x, y) -> np.ndarray:
    """values (nrow, ncol) at a grid's vertices interpolated at (x, y), written plainly: linear
    over the two triangles of each cell split along (c, r)-(c+1, r+1), the nearest edge's value
    beyond the grid."""
    nrow, ncol = values.shape
    u = np.clip((x - prm[surface.X0]) / prm[surface.DX], 0, ncol - 1)
    v = np.clip((y - prm[surface.Y0]) / prm[surface.DY], 0, nrow - 1)
    c, r = np.minimum(u.astype(int), ncol - 2), np.minimum(v.astype(int), nrow - 2)
    fu, fv = u - c, v - r
    upper = fu >= fv  # the triangle (c, r), (c+1, r), (c+1, r+1)
    corner = np.where(upper, values[r, c + 1], values[r + 1, c])
    a, b = np.where(upper, fu, fv), np.where(upper, fv, fu)
    return values[r, c] + a * (corner - values[r, c]) + b * (values[r + 1, c + 1] - corner)


def test_heights_and_depths_follow_the_stated_rules():
    """surface.height and surface.depth (the engine's functions) on every kind of surface
    against mjrft.core.surface's rules written plainly: vertical depth below a flat surface, a
    plane, a grid linear over each cell's two triangles (the edge beyond); under a deforming
    grid (h + p) - z below the compacted level c, h - z between c and h and above h. Both do the
    same operations in the same order (the engine is built without contraction to fused
    multiply-adds), so they agree to the last bit."""
    rng = np.random.default_rng(8)
    x, y, z = (
        rng.uniform(-0.5, 0.5, 400),
        rng.uniform(-0.4, 0.4, 400),
        rng.uniform(-0.05, 0.05, 400),
    )
    flat = surface.flat(0.01)
    np.testing.assert_array_equal(surface.depth(flat.prm, flat.grid, None, x, y, z), 0.01 - z)
    slope = surface.plane(0.01, np.radians(20.0), np.radians(30.0))
    want = 0.01 + slope.prm[surface.GX] * x + slope.prm[surface.GY] * y
    np.testing.assert_array_equal(surface.height(slope.prm, slope.grid, None, x, y), want)
    dune = surface.grid(rng.uniform(-0.02, 0.02, (5, 7)), -0.3, -0.2, 0.1, 0.1)
    want = _over_triangles(dune.prm, dune.grid, x, y)
    np.testing.assert_array_equal(dune.height(x, y), want)
    np.testing.assert_array_equal(surface.depth(dune.prm, dune.grid, None, x, y, z), want - z)
    # The same grid deforming: random offsets of h and c (c <= h) and memory p at its vertices.
    prm = dune.prm.copy()
    prm[surface.KIND] = surface.SOIL
    block = np.zeros(surface.soil_block(*dune.grid.shape))
    dh, dc, mem = soil.block_views(prm, block)
    dh[:] = rng.uniform(-0.01, 0.01, dh.shape)
    dc[:] = dh - rng.uniform(0.0, 0.01, dc.shape)
    mem[:] = rng.uniform(0.0, 0.01, mem.shape)
    h = _over_triangles(prm, dune.grid + dh, x, y)
    c = _over_triangles(prm, dune.grid + dc, x, y)
    p = _over_triangles(prm, mem, x, y)
    touch = surface.SOIL_CONTACT
    want = np.where(z >= h + touch, h - z, np.maximum(h - z, 0.0) + np.where(z < c + touch, p, 0.0))
    assert np.any(z < c) and np.any((z >= c) & (z < h)) and np.any(z > h)  # every case
    np.testing.assert_array_equal(surface.height(prm, dune.grid, block, x, y), h)
    np.testing.assert_array_equal(surface.depth(prm, dune.grid, block, x, y, z), want)
    # Scalars in, a float out (the field layer asks for one point at a time).
    assert surface.depth(prm, dune.grid, block, x[0], y[0], z[0]) == want[0]
    with pytest.raises(ValueError, match="a deforming .SOIL. surface needs its soil block"):
        surface.depth(prm, dune.grid, None, x, y, z)


def test_a_flat_height_field_equals_the_flat_surface():
    """A height field of one elevation gives a sphere moving through the medium the wrench of
    the flat surface at that height, to 1e-12."""
    h = 0.01  # the geom's height: a constant elevation normalises to 0
    asset = hfield_asset(3, 4, np.zeros((3, 4)), "0.3 0.2 0.05 0.01")
    hf = mjrft.load_model(scene(
        '<text name="mjrft:surface_hfield" data="dune"/>', SPHERE, asset, hfield_geom()
    ), low_speed="off")  # fmt: skip
    flat = mjrft.load_model(
        scene(f'<numeric name="mjrft:surface_z" data="{h}"/>', SPHERE), low_speed="off"
    )
    state = ([0.04, 0.01, h - 0.006], [0.9, 0.1, 0.3, 0.2], [0.1, -0.05, -0.2], [1.0, 2.0, 0.5])
    w_hf = GranularField(hf).wrench(placed(hf, *state))[1]
    w_flat = GranularField(flat).wrench(placed(flat, *state))[1]
    assert np.linalg.norm(w_flat[:3]) > 1e-3
    np.testing.assert_allclose(w_hf, w_flat, rtol=1e-12, atol=1e-12 * np.abs(w_flat).max())


@pytest.mark.parametrize("slope, azimuth", [(20.0, 0.0), (30.0, 135.0)])
def test_a_plate_on_a_slope_feels_the_flat_force_at_its_local_depth(slope, azimuth):
    """Depth is vertical below the local surface. A horizontal plate sinking straight down feels
    the vertical force it feels under flat ground at the depth of its centre (its faces pair up
    symmetrically and each element's force is linear in its depth); moving obliquely and tilted,
    its force differs from the flat one only through the depth differences across it (bounded
    element by element) and follows the reference written plainly."""
    slope_xml = f'<numeric name="mjrft:surface_slope" data="{slope} {azimuth}"/>'
    tilted = mjrft.load_model(scene(slope_xml, PLATE), low_speed="off")
    flat = mjrft.load_model(scene("", PLATE), low_speed="off")
    fld, fld_flat = GranularField(tilted), GranularField(flat)
    centre = np.array([0.3, -0.2, 0.0])
    local = float(fld.surface.height(centre[0], centre[1]))
    downhill = np.array([np.cos(np.radians(azimuth)), np.sin(np.radians(azimuth))])
    assert local == pytest.approx(-np.tan(np.radians(slope)) * centre[:2] @ downhill, rel=1e-12)
    depth = 0.03
    for quat, motion in [
        ([1.0, 0.0, 0.0, 0.0], ([0.0, 0.0, -0.1], [0.0, 0.0, 0.0])),
        ([np.cos(0.2), 0.0, np.sin(0.2), 0.0], ([0.05, 0.02, -0.1], [0.0, 0.0, 0.0])),
    ]:
        d_tilted = placed(tilted, centre + [0, 0, local - depth], quat, *motion)
        d_flat = placed(flat, centre - [0, 0, depth], quat, *motion)
        w_tilted, w_flat = fld.wrench(d_tilted)[1], fld_flat.wrench(d_flat)[1]
        assert w_flat[2] > 1.0
        be = fld.bodies[0]
        every = np.arange(len(be.areas))
        plain = ref.body_wrench_at(fld, d_tilted, be, every, np.zeros(3), motion[0],
                                   d_tilted.xpos[1])  # fmt: skip
        np.testing.assert_allclose(w_tilted, plain, rtol=1e-10, atol=1e-12)
        states = fld.element_states(d_tilted)[0]
        height = fld.surface.height(states.pos[:, 0], states.pos[:, 1])
        extra = height - local  # each element's depth beyond the flat case's
        bound = np.sum(np.linalg.norm(states.force, axis=1) * np.abs(extra)
                       / (height - states.pos[:, 2]))  # fmt: skip
        assert np.linalg.norm(w_tilted[:3] - w_flat[:3]) <= bound
        if quat[0] == 1.0:
            assert w_tilted[2] == pytest.approx(w_flat[2], rel=SYMMETRIC_RTOL)
        else:
            assert bound > 1e-3 * w_flat[2]  # the oblique case does test the bound


def test_a_ball_resting_on_a_gentle_slope_stays_put():
    """The low-speed treatment holds a body on a slope gentler than the angle of repose: a
    sphere released on a 15-degree slope settles and then does not move."""
    slope_xml = '<numeric name="mjrft:surface_slope" data="15 0"/>'
    m = mjrft.load_model(scene(slope_xml, SPHERE))
    fld = GranularField(m)
    d = placed(m, [0.0, 0.0, 0.01], [1, 0, 0, 0], [0, 0, 0], [0, 0, 0])
    for _ in range(1000):
        mujoco.mj_step(m, d)
    settled = d.xpos[1].copy()
    for _ in range(2000):
        mujoco.mj_step(m, d)
    bottom = settled[2] - 0.01
    assert bottom < fld.surface.height(settled[0], settled[1]) - 0.002  # it sank into the slope
    assert np.linalg.norm(d.xpos[1] - settled) < 1e-7  # held: < 0.1 um over 2 s
    assert np.linalg.norm(d.qvel) < 1e-9


@pytest.mark.parametrize(
    "custom, asset, geom, message",
    [
        ('<text name="mjrft:surface_hfield" data="dunes"/>', "H", "", "no such hfield.*dune"),
        ('<text name="mjrft:surface_hfield" data="dune"/>', "H", "none", "0 geoms use it"),
        ('<text name="mjrft:surface_hfield" data="dune"/>', "H", "rot", "is rotated"),
        ('<numeric name="mjrft:surface_slope" data="75 0"/>', "", "", "slope = 75"),
        ('<numeric name="mjrft:surface_slope" data="10"/>', "", "", "2 numbers"),
        ('<numeric name="mjrft:surface_slope" data="10 0"/>'
         '<text name="mjrft:surface_hfield" data="dune"/>', "H", "", "both"),
        ('<numeric name="mjrft:surface_z" data="0.1"/>'
         '<text name="mjrft:surface_hfield" data="dune"/>', "H", "", "both"),
        ('<text name="mjrft:surface_hfield" data="dune"/>'
         '<numeric name="mjrft:region" data="-1 -1 -1 1 1 1"/>', "H", "", "covers x"),
    ],
)  # fmt: skip
def test_bad_surfaces_are_named(custom, asset, geom, message):
    asset = hfield_asset(3, 3, np.arange(9.0).reshape(3, 3), "0.3 0.2 0.05 0.01") if asset else ""
    extra = {"": hfield_geom() if asset else "", "none": "",
             "rot": hfield_geom().replace("/>", ' euler="0 0 30"/>')}[geom]  # fmt: skip
    with pytest.raises(SceneError, match=message):
        mjrft.load_model(scene(custom, SPHERE, asset, extra))


def test_a_python_material_runs_on_a_tilted_surface_too():
    """A medium given by Python callables runs in the engine as its table under any surface:
    on a 10 deg slope it gives the Fourier preset's wrench to the table's accuracy."""
    slope_xml = '<numeric name="mjrft:surface_slope" data="10 0"/>'
    glass = Material.preset("glass_beads")
    callables = Material.from_callables(
        glass.fourier.alpha_x, glass.fourier.alpha_z, glass.zeta, name="glass as callables"
    )
    wrenches = []
    for material in (callables, glass):
        m = mjrft.load_model(scene(slope_xml, SPHERE), material=material)
        d = mujoco.MjData(m)
        d.qvel[:3] = (0.05, 0.02, -0.1)
        mujoco.mj_forward(m, d)
        wrenches.append(GranularField(m).wrench_of(d).copy())
    scale = np.abs(wrenches[1]).max()
    assert scale > 0.0
    np.testing.assert_allclose(wrenches[0], wrenches[1], atol=1e-6 * scale)  # table: ~2e-7


def test_a_batch_on_a_height_field_gives_each_copy_the_explicit_wrench():
    """mujoco.batch steps the plugin's model with the same surface: every copy's step equals
    mj_step on a single MjData in that copy's state, and its wrench the explicit wrench of
    that state."""
    from mujoco.batch import Batch

    rng = np.random.default_rng(5)
    asset = hfield_asset(5, 6, rng.uniform(size=(5, 6)), "0.3 0.2 0.02 0.01")
    m = mjrft.load_model(scene(
        '<text name="mjrft:surface_hfield" data="dune"/>', SPHERE, asset, hfield_geom()
    ), low_speed="off")  # fmt: skip
    fld = GranularField(m)
    batch = Batch(m, nsim=3, nthread=1, persistent=True)
    batch.reset()
    qpos, qvel = batch.bind("qpos"), batch.bind("qvel")
    qpos[:, :3] = [[0.0, 0.0, 0.012], [0.1, -0.05, 0.015], [-0.1, 0.1, 0.02]]
    qvel[:, 2] = -0.1
    batch.forward(stage=mujoco.mjtStage.mjSTAGE_VEL.value)
    starts = [(np.array(qpos[i]), np.array(qvel[i])) for i in range(3)]
    batch.step(nstep=1)  # the wrench of each copy's state at the start of the step
    for i, (q, v) in enumerate(starts):
        copy = batch.get_data(i)
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:] = q, v
        mujoco.mj_forward(m, d)
        np.testing.assert_array_equal(fld.wrench_of(copy), fld.wrench(d))
        assert abs(fld.wrench_of(copy)[1, 2]) > 0  # the copy is in the medium
        mujoco.mj_step(m, d)
        np.testing.assert_array_equal(copy.qpos, d.qpos)
        np.testing.assert_array_equal(copy.qvel, d.qvel)


def test_a_recording_draws_the_surface_it_simulates(tmp_path):
    """The rerun recording's world/surface mesh lies on the tilted plane, not on z = surface_z."""
    pytest.importorskip("rerun")
    from mjrft.app import viz

    m = mjrft.load_model(scene('<numeric name="mjrft:surface_slope" data="15 30"/>', SPHERE))
    fld = GranularField(m)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    path = tmp_path / "slope.rrd"
    with viz.Recorder(m, fld, path, every=1) as recorder:
        recorder.log_state(0, 0.0, d)
    (row,) = viz.read_entity(path, "world/surface")
    vertices = np.asarray(row["Mesh3D:vertex_positions"], dtype=float).reshape(-1, 3)
    assert len(vertices) == viz.SURFACE_SAMPLES**2
    np.testing.assert_allclose(vertices[:, 2], fld.surface.height(vertices[:, 0], vertices[:, 1]),
                               atol=1e-6)  # fmt: skip
    assert np.ptp(vertices[:, 2]) > 0.005  # it does slope (7 mm over the drawn 27 mm)


def test_run_figures_plot_the_depth_below_the_local_surface():
    """mjrft run's figures put a body's force against its CoM depth below the surface under it:
    a CoM moving along a tilted plane at a constant local depth has no depth range, so the
    figure uses its horizontal travel instead."""
    from mjrft.app import report

    plane = surface.plane(0.0, np.radians(20.0), 0.0)
    x = np.linspace(0.0, 0.1, 50)
    com = np.stack([x, 0 * x, plane.height(x, 0 * x) - 0.02], axis=1)
    local = report.abscissa(com, plane)
    assert local.name == "horizontal distance"
    assert report.abscissa(com, 0.0).name == "depth"  # below z = 0 it sinks 3.6 cm
