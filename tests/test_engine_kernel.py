"""The C++ RFT kernel (engine/law.h, quadrature.h, kernel.h) against the numba one, bit for bit.

Every exported C function (engine/capi_kernel.cc: mjrft_forces, mjrft_checked_unit_normals,
mjrft_input_flags, mjrft_body_wrench, mjrft_trajectory) is called beside its numba original
(mjrft.core.kernel) on the same seeded random inputs: thousands of triangles of random size and
orientation, flat and curved (corner normals apart from the element's), dry, submerged and
straddling the surface, moving with random twists, and the degenerate frames (horizontal plates,
vertical motion, rest, speeds that take the rescaling path), for every coefficient form
(Treers' 18 combined coefficients of two presets, with the dynamic term 19, Agarwal's
parameters, with the dynamic term), under every surface (flat, tilted plane, height grid,
deforming ground with random offsets), with and without a region. Then BodyWrench through the
engine's own caller (evaluate.cc's PureWrenches, via engine_bridge) on real scenes against
mjrft.field.evaluate.pure_wrenches. Every comparison is exact (assert_array_equal): the C++ code
performs the same operations in the same order and fuses a multiply-add exactly where numba's
_fma does (-ffp-contract=off).
"""

from __future__ import annotations

import ctypes

import engine_bridge as eb
import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.core import kernel, quadrature, surface
from mjrft.field import evaluate
from mjrft.field.numba_field import GranularField, load_plain

P = ctypes.c_void_p
D = ctypes.c_double
I64 = ctypes.c_int64
GLASS = mjrft.Material.preset("glass_beads")
MATERIALS = {
    "li_generic": mjrft.Material.preset("generic_1ncm3"),
    "glass": GLASS,
    "glass_dynamic": GLASS.with_dynamic(1500.0),
    "agarwal": GLASS.with_model("agarwal3d"),
    "agarwal_dynamic": GLASS.with_model("agarwal3d").with_dynamic(1500.0),
}


@pytest.fixture(scope="module")
def lib():
    lib = eb.library()
    lib.mjrft_forces.restype = ctypes.c_int
    lib.mjrft_forces.argtypes = [P, P, P, P, I64, P, I64, D, D, D, P]
    lib.mjrft_checked_unit_normals.restype = ctypes.c_int
    lib.mjrft_checked_unit_normals.argtypes = [P, P, P, P, I64, P, P]
    lib.mjrft_input_flags.restype = None
    lib.mjrft_input_flags.argtypes = [P, P, P, P, I64, P, P]
    lib.mjrft_body_wrench.restype = ctypes.c_int
    lib.mjrft_body_wrench.argtypes = (
        [P] * 5 + [I64, I64, P, I64, D, D, P, P, ctypes.c_int] + [P] * 11
    )
    lib.mjrft_trajectory.restype = None
    lib.mjrft_trajectory.argtypes = [P] * 5 + [I64, P, I64, D, D, D] + [P] * 5 + [I64, P]
    lib.mjrft_test_pure_wrenches.restype = ctypes.c_int
    lib.mjrft_test_pure_wrenches.argtypes = [P, P, P, P, P]
    return lib


def ptr(a: np.ndarray | None) -> ctypes.c_void_p:
    if a is None:
        return P(None)
    assert a.flags.c_contiguous and a.dtype in (np.float64, np.int64)
    return P(a.ctypes.data)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rotation(rng):
    q = rng.normal(size=4)
    x = np.zeros(9)
    mujoco.mju_quat2Mat(x, q / np.linalg.norm(q))
    return x.reshape(3, 3)


# ------------------------------------------------------------------ random element sets


def body_elements(rng, n, size=0.05):
    """(cent, norm, area, reach, patch) of n random triangles in a body frame, within size [m]
    of its origin: sizes from 0.3 mm to 5 mm, a quarter of them horizontal plates (normal
    exactly +-z), half curved (corner normals apart from the element's)."""
    cent = rng.uniform(-size, size, (n, 3))
    h = 10.0 ** rng.uniform(-3.5, -2.3, (n, 1, 1))
    off = rng.normal(size=(n, 3, 3)) * h
    off[: n // 4, :, 2] = 0.0  # horizontal plates: the cross product is exactly along z
    off -= off.mean(axis=1, keepdims=True)
    cross = np.cross(off[:, 1] - off[:, 0], off[:, 2] - off[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    norm = _unit(cross)
    corner_normals = np.repeat(norm[:, None, :], 3, axis=1)
    curved = rng.random(n) < 0.5
    corner_normals[curved] = _unit(
        corner_normals[curved] + rng.normal(scale=0.1, size=(int(curved.sum()), 3, 3))
    )
    reach, patch = quadrature.patch_table(cent, cent[:, None, :] + off, norm, corner_normals)
    return (np.ascontiguousarray(cent), np.ascontiguousarray(norm), np.ascontiguousarray(area),
            reach, np.ascontiguousarray(patch))  # fmt: skip


def surfaces(rng):
    """(name, prm, grid, soil): flat, a tilted plane, a height grid and a deforming ground with
    random offsets of its surface and compacted level and a random memory."""
    out = [("flat", surface.flat(0.004).prm, np.zeros((1, 1)), np.zeros(1))]
    pl = surface.plane(0.002, 0.35, 0.8)
    out.append(("plane", pl.prm, pl.grid, np.zeros(1)))
    heights = rng.uniform(-0.012, 0.012, (11, 13))
    gr = surface.grid(heights, -0.06, -0.05, 0.01, 0.011)  # the body reaches beyond its edges
    out.append(("grid", gr.prm, gr.grid, np.zeros(1)))
    prm = gr.prm.copy()
    prm[surface.KIND] = surface.SOIL
    prm[surface.TAN_REPOSE] = 0.6
    prm[surface.EVERY] = 1
    nrow, ncol = gr.grid.shape
    soil = np.zeros(surface.soil_block(nrow, ncol))
    n = nrow * ncol
    dh = rng.uniform(-0.006, 0.004, n)
    soil[surface.SOIL_HEAD : surface.SOIL_HEAD + n] = dh
    soil[surface.SOIL_HEAD + n : surface.SOIL_HEAD + 2 * n] = dh - rng.uniform(0.0, 0.004, n)
    soil[surface.SOIL_HEAD + 2 * n :] = rng.uniform(0.0, 0.003, n) * (rng.random(n) < 0.7)
    soil[surface.SOIL_ZOFF] = max(0.0, float((gr.grid.reshape(-1) + dh).max() - prm[surface.ZMAX]))
    out.append(("soil", prm, gr.grid, soil))
    return out


MOTIONS = ("random", "vertical", "spin", "rest", "tiny", "huge")


def motion(rng, kind):
    """(rot, omega, v_ref, p_ref offset) of a body: random; identity frame moving straight down
    (horizontal plates with vertical motion: the world-x frame); spinning in place; at rest;
    speeds that take the gather's rescaling path."""
    rot = _rotation(rng)
    omega = rng.normal(size=3) * 3.0
    v_ref = rng.normal(size=3) * 0.2
    if kind == "vertical":
        rot, omega, v_ref = np.eye(3), np.zeros(3), np.array([0.0, 0.0, -0.1])
    elif kind == "spin":
        v_ref = np.zeros(3)
    elif kind == "rest":
        omega, v_ref = np.zeros(3), np.zeros(3)
    elif kind == "tiny":
        omega, v_ref = omega * 1e-35, v_ref * 1e-35
    elif kind == "huge":
        omega, v_ref = omega * 1e35, v_ref * 1e35
    return np.ascontiguousarray(rot), omega, v_ref


def numba_body_wrench(el, start, stop, co, ay, zeta, prm, grid, use_region, region, soil, pose,
                      rows):  # fmt: skip
    rot, pos, omega, v_ref, p_ref, com = pose
    n = el[0].shape[0]
    wrench = np.zeros(6)
    force = np.full((n, 3), 7.0)
    rws = np.full((n, kernel.ROW), 7.0) if rows else np.empty((0, kernel.ROW))
    count = kernel.body_wrench(
        *el, start, stop, co, ay, zeta, prm, grid, use_region, region, soil,
        rot, pos, omega, v_ref, p_ref, com, wrench, force, rws,
    )  # fmt: skip
    return count, wrench, force, (rws if rows else None)


def cpp_body_wrench(lib, el, start, stop, co, ay, zeta, prm, grid, use_region, region, soil, pose,
                    rows):  # fmt: skip
    rot, pos, omega, v_ref, p_ref, com = pose
    n = el[0].shape[0]
    wrench = np.zeros(6)
    force = np.full((n, 3), 7.0)
    rws = np.full((n, kernel.ROW), 7.0) if rows else None
    count = lib.mjrft_body_wrench(
        *map(ptr, el), start, stop, ptr(co), len(co), ay, zeta, ptr(prm), ptr(grid),
        int(use_region), ptr(region), ptr(soil), ptr(rot), ptr(pos), ptr(omega), ptr(v_ref),
        ptr(p_ref), ptr(com), ptr(wrench), ptr(force), ptr(rws),
    )  # fmt: skip
    return count, wrench, force, rws


REGION = np.array([[-0.035, -0.1, -0.1], [0.04, 0.03, 0.1]])


@pytest.mark.parametrize("material", list(MATERIALS), ids=list(MATERIALS))
def test_body_wrench_equals_numba(lib, material):
    """Every surface x motion x region, one seeded element set of 3000 triangles per case
    (positioned so that about half is submerged), element forces, wrench and count exact; the
    quadrature rows too (the path for media given as callables)."""
    mat = MATERIALS[material]
    co = np.ascontiguousarray(mat.kernel_coefficients)
    ay, zeta = float(mat.alpha_y0), float(mat.zeta)
    rng = np.random.default_rng(list(MATERIALS).index(material))
    acting = 0
    for name, prm, grid, soil in surfaces(rng):
        for kind in MOTIONS:
            for use_region in (False, True):
                el = body_elements(rng, 3000)
                rot, omega, v_ref = motion(rng, kind)
                x, y = rng.uniform(-0.01, 0.01, 2)
                pos = np.array([x, y, surface.height(prm, grid, soil, x, y)])
                p_ref = pos + rng.normal(scale=0.02, size=3)
                com = pos + rng.normal(scale=0.02, size=3)
                pose = (rot, pos, omega, v_ref, p_ref, com)
                start, stop = 5, 2990  # rows outside are left alone
                args = (el, start, stop, co, ay, zeta, prm, grid, use_region, REGION, soil, pose)
                for rows in (False, True):
                    ref = numba_body_wrench(*args, rows)
                    got = cpp_body_wrench(lib, *args, rows)
                    case = f"{name} {kind} region={use_region} rows={rows}"
                    assert got[0] == ref[0], case
                    np.testing.assert_array_equal(got[1], ref[1], err_msg=case)
                    np.testing.assert_array_equal(got[2], ref[2], err_msg=case)
                    if rows:
                        np.testing.assert_array_equal(got[3], ref[3], err_msg=case)
                if kind not in ("rest",):
                    acting += ref[0]
    assert acting > 10000  # the cases act (the comparison could fail)


def test_body_wrench_clips(lib):
    """The quadrature's paths are taken: with a mesh straddling the surface, held elements are
    clipped (rows of clipped elements carry W != depth x area), and their forces match."""
    rng = np.random.default_rng(7)
    el = body_elements(rng, 2000, size=0.004)  # small cloud around the surface: most straddle
    co = GLASS.kernel_coefficients
    prm, grid, soil = surface.flat(0.0).prm, np.zeros((1, 1)), np.zeros(1)
    pose = (_rotation(rng), np.zeros(3), rng.normal(size=3), rng.normal(size=3) * 0.1,
            np.zeros(3), np.zeros(3))  # fmt: skip
    args = (el, 0, 2000, co, GLASS.alpha_y0, GLASS.zeta, prm, grid, False, REGION, soil, pose)
    ref = numba_body_wrench(*args, True)
    got = cpp_body_wrench(lib, *args, True)
    np.testing.assert_array_equal(got[3], ref[3])
    acting = ref[3][:, 0] != 7.0
    rot = pose[0]
    depth = -((el[0] @ rot.T)[:, 2])
    clipped = acting & ~np.isclose(ref[3][:, 9], depth * el[2], rtol=1e-9, atol=0)
    assert clipped.sum() > 100
    ref = numba_body_wrench(*args, False)
    got = cpp_body_wrench(lib, *args, False)
    assert got[0] == ref[0]
    np.testing.assert_array_equal(got[1], ref[1])
    np.testing.assert_array_equal(got[2], ref[2])


def world_inputs(rng, n):
    """World-frame element arrays as tests/test_kernel.py's: horizontal plates, vertical motion,
    motion in the plate's plane, rest, tiny and huge speeds, random depths about the surface."""
    pos = rng.normal(scale=0.05, size=(n, 3))
    n_hat = _unit(rng.normal(size=(n, 3)))
    n_hat[:50] = [0, 0, -1]
    n_hat[50:80] = [0, 0, 1]
    vel = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-6, 1, size=(n, 1))
    vel[:20, :2] = 0.0
    n_hat[100:130] = [0.0, 1.0, 0.0]
    vel[100:130] = [0.3, 0.0, -0.2]
    vel[130:140] = 0.0
    vel[140:150] *= 1e-200
    vel[150:160] *= 1e200
    area = rng.uniform(0, 1e-4, size=n)
    return pos, n_hat, area, vel


@pytest.mark.parametrize("material", list(MATERIALS), ids=list(MATERIALS))
@pytest.mark.parametrize("n", [1, 7, 256, 257, 5000])  # chunk boundaries
def test_forces_equals_numba(lib, material, n):
    mat = MATERIALS[material]
    co = np.ascontiguousarray(mat.kernel_coefficients)
    rng = np.random.default_rng(n)
    pos, n_hat, area, vel = (np.ascontiguousarray(a[:n]) for a in world_inputs(rng, max(n, 200)))
    ref = np.full((n, 3), np.nan)
    got = np.full((n, 3), np.nan)
    c_ref = kernel.forces(pos, n_hat, area, vel, co, mat.alpha_y0, mat.zeta, 0.01, ref)
    c_got = lib.mjrft_forces(ptr(pos), ptr(n_hat), ptr(area), ptr(vel), n, ptr(co), len(co),
                             mat.alpha_y0, mat.zeta, 0.01, ptr(got))  # fmt: skip
    assert c_got == c_ref
    np.testing.assert_array_equal(got, ref)
    if n == 5000:
        assert c_ref > 1000


def _flags(lib, pos, normal, area, vel):
    bad, nonunit = ctypes.c_int(-1), ctypes.c_int(-1)
    lib.mjrft_input_flags(ptr(pos), ptr(normal), ptr(area), ptr(vel), len(area),
                          ctypes.byref(bad), ctypes.byref(nonunit))  # fmt: skip
    return bool(bad.value), bool(nonunit.value)


def _checked(lib, pos, normal, area, vel):
    n_hat = np.full(pos.shape, 7.0)
    index = ctypes.c_int64(-7)
    code = lib.mjrft_checked_unit_normals(ptr(pos), ptr(normal), ptr(area), ptr(vel), len(area),
                                          ptr(n_hat), ctypes.byref(index))  # fmt: skip
    return code, index.value, n_hat


BAD = {  # (array, row, column, value): one bad input each
    "pos_nan": (0, 1, np.nan), "pos_inf": (0, 0, np.inf), "normal_nan": (1, 2, np.nan),
    "normal_inf": (1, 1, -np.inf), "vel_nan": (3, 0, np.nan), "vel_inf": (3, 2, np.inf),
    "area_nan": (2, None, np.nan), "area_inf": (2, None, np.inf), "area_neg": (2, None, -1e-9),
    "normal_zero": (1, "all", 0.0),
}  # fmt: skip


@pytest.mark.parametrize("bad", [None, *BAD], ids=["clean", *BAD])
def test_input_checks_equal_numba(lib, bad):
    """checked_unit_normals (code, index and every normal: unit ones copied, others scaled and
    normalised, including tiny and huge ones) and input_flags, clean and with one bad input (two
    bad elements: the first is named)."""
    rng = np.random.default_rng(3)
    n = 3000
    pos, n_hat, area, vel = world_inputs(rng, n)
    normal = n_hat * 10.0 ** rng.uniform(-150, 150, (n, 1)) * (rng.random((n, 1)) < 0.5)
    normal[normal[:, 0] == 0.0] = n_hat[normal[:, 0] == 0.0]  # half of them exactly as given
    arrays = [np.ascontiguousarray(a) for a in (pos, normal, area, vel)]
    if bad is not None:
        which, col, value = BAD[bad]
        for i in (1234, 2345):
            if col is None:
                arrays[which][i] = value
            elif col == "all":
                arrays[which][i] = 0.0
            else:
                arrays[which][i, col] = value
    ref_n = np.full((n, 3), 7.0)
    ref_code, ref_index = kernel.checked_unit_normals(*arrays, ref_n)
    code, index, got_n = _checked(lib, *arrays)
    assert (code, index) == (ref_code, ref_index)
    assert (ref_code == kernel.INPUT_OK) == (bad is None)
    np.testing.assert_array_equal(got_n, ref_n)
    assert _flags(lib, *arrays) == tuple(kernel.input_flags(*arrays))
    unit = [np.ascontiguousarray(a) for a in (arrays[0], ref_n, arrays[2], arrays[3])]
    assert _flags(lib, *unit) == tuple(kernel.input_flags(*unit))
    if bad is None:
        assert _flags(lib, *unit) == (False, False)
        assert _flags(lib, *arrays) == (False, True)


@pytest.mark.parametrize("material", ["glass", "glass_dynamic", "agarwal"])
def test_trajectory_equals_numba(lib, material):
    mat = MATERIALS[material]
    co = np.ascontiguousarray(mat.kernel_coefficients)
    rng = np.random.default_rng(11)
    el = body_elements(rng, 1500, size=0.02)
    T = 40
    rot = np.ascontiguousarray(np.stack([_rotation(rng) for _ in range(T)]))
    pos = np.column_stack([rng.normal(scale=0.01, size=(T, 2)), np.linspace(0.02, -0.02, T)])
    lin_vel = rng.normal(scale=0.1, size=(T, 3))
    ang_vel = rng.normal(scale=2.0, size=(T, 3))
    point = pos + rng.normal(scale=0.01, size=(T, 3))
    ref = np.full((T, 6), 7.0)
    got = np.full((T, 6), 7.0)
    kernel.trajectory(*el, co, mat.alpha_y0, mat.zeta, 0.001, rot, pos, lin_vel, ang_vel, point,
                      ref)  # fmt: skip
    lib.mjrft_trajectory(
        *map(ptr, el), 1500, ptr(co), len(co), mat.alpha_y0, mat.zeta, 0.001,
        ptr(rot), ptr(pos), ptr(lin_vel), ptr(ang_vel), ptr(point), T, ptr(got),
    )  # fmt: skip
    np.testing.assert_array_equal(got, ref)
    assert np.count_nonzero(ref[:, 2]) > T // 3


# ------------------------------------------------------------------ real scenes, through the bridge

SCENE = """
<mujoco><option timestep="0.001"/><custom><text name="mjrft:material" data="{material}"/>
  {extra}
  <tuple name="mjrft:intruders"><element objtype="body" objname="b" prm="700"/>
    <element objtype="body" objname="c" prm="300"/></tuple>
</custom><worldbody>
  <body name="b" pos="0 0 -0.004" euler="10 20 30"><freejoint/>
    <geom type="ellipsoid" size="0.01 0.02 0.015" contype="0" conaffinity="0"/>
    <geom type="box" size="0.01 0.01 0.002" pos="0.02 0 0.01" contype="0" conaffinity="0"/>
    <geom type="sphere" size="0.005" pos="0 0 0.2" contype="0" conaffinity="0"/>
  </body>
  <body name="c" pos="0.05 0.01 0.003" euler="0 0 0"><freejoint/>
    <geom type="cylinder" size="0.008 0.01" contype="0" conaffinity="0"/>
  </body>
</worldbody></mujoco>"""


def _pure_wrenches_pair(lib, fld, m, d):
    """Runs numba's pure_wrenches on the field's own state and the C++ PureWrenches on the
    bridge's copy of it (both from the same state); returns the bridge."""
    br = eb.Bridge(fld, d)
    fd = br.field_state.arrays
    for name in ("keep", "frz", "cull"):
        getattr(fd, name)[:] = 0
        br.arrays[name][:] = 0
    acting = ctypes.c_int(-1)
    ev = lib.mjrft_test_pure_wrenches(*br.pointers(m, d), ctypes.byref(acting))
    ref_ev, ref_act = evaluate.pure_wrenches(fld._tables.address, br.field_state.address)
    assert (ev, acting.value) == (ref_ev, ref_act)
    np.testing.assert_array_equal(br.arrays["wrench"], fd.wrench)
    np.testing.assert_array_equal(br.arrays["elem_force"], fd.elem_force)
    np.testing.assert_array_equal(br.arrays["cull"], fd.cull)
    return ref_act


@pytest.mark.parametrize("material", ["glass_beads", "generic_1ncm3"])
@pytest.mark.parametrize("region", [False, True])
def test_pure_wrenches_on_a_scene(lib, material, region):
    """Two free bodies (an ellipsoid, a box, a far sphere; a cylinder) moving through the
    medium, many states along a run: s.wrench and s.elem_force of PureWrenches (evaluate.cc,
    which calls BodyWrench per geom) equal numba's pure_wrenches."""
    extra = '<numeric name="mjrft:region" data="-0.5 -0.5 -0.5 0.012 0.5 0.5"/>' if region else ""
    m = mujoco.MjModel.from_xml_string(SCENE.format(material=material, extra=extra))
    d = mujoco.MjData(m)
    fld = GranularField(m, low_speed="off")
    rng = np.random.default_rng(5)
    acting = 0
    for _ in range(12):
        d.qvel[:] = rng.normal(size=m.nv) * np.tile([0.05, 0.05, 0.05, 3.0, 3.0, 3.0], 2)
        d.qpos[2] = rng.uniform(-0.02, 0.01)
        d.qpos[9] = rng.uniform(-0.01, 0.01)
        mujoco.mj_forward(m, d)
        acting += _pure_wrenches_pair(lib, fld, m, d)
    assert acting > 1000


def test_pure_wrenches_on_a_rig(lib):
    """A rig from models/ (the ellipsoid pitching on its linkage) stepped into the medium."""
    m = mujoco.MjModel.from_xml_path(str(eb.ROOT / "models" / "ellipsoid_pitch.xml"))
    d = mujoco.MjData(m)
    fld = GranularField(m, low_speed="off")
    acting = 0
    for step in range(600):
        mujoco.mj_step(m, d)
        if step % 100 == 99:
            acting += _pure_wrenches_pair(lib, fld, m, d)
    assert acting > 0


FOOT = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.06 -0.06 -0.1 0.06 0.06 0.05"/>
<numeric name="mjrft:deform_cell" data="0.004"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="foot" prm="600"/></tuple></custom>
<worldbody><body name="foot" pos="0.003 -0.002 0.004" euler="12 -8 20">
<joint name="z" type="slide" axis="0 0 1"/><joint name="x" type="slide" axis="1 0 0"/>
<geom name="foot" type="ellipsoid" size="0.02 0.015 0.008" mass="1"/></body></worldbody>
<actuator><position joint="z" kp="1e5" kv="2000"/><position joint="x" kp="1e5" kv="2000"/>
</actuator></mujoco>"""


def test_pure_wrenches_on_deforming_ground(lib):
    """A tilted foot pressed into the deforming ground and dragged sideways (installed steps,
    so the soil block deforms): PureWrenches reads the bridge's copy of the soil block, numba
    the MjData's userdata, at states along the run."""
    m = load_plain(mujoco.MjSpec.from_string(FOOT))
    fld = GranularField(m)
    assert fld._tables.arrays.surface_prm[surface.KIND] == surface.SOIL
    d = mujoco.MjData(m)
    acting = 0
    with fld.installed():
        for i, (z, x) in enumerate([(-0.004, 0.0), (-0.008, 0.004), (-0.006, 0.012)] * 2):
            d.ctrl[:] = z, x
            for _ in range(15):
                mujoco.mj_step(m, d)
            st = fld._states.of(d)
            assert np.any(st.userdata[surface.SOIL_HEAD :] != 0.0) or i == 0
            acting += _pure_wrenches_pair(lib, fld, m, d)
    assert acting > 100
