"""The engine's kernel (C++, through mjrft.core.engine) equals the NumPy evaluation of the same
equations, and its Python bindings check what they are given."""

import mujoco
import numpy as np
import pytest
from field_reference import pure_wrench

import mjrft
from mjrft import geometry
from mjrft.core import engine, quadrature, surface
from mjrft.core.body import quat_to_mat
from mjrft.core.rft import _unit_rows, numpy_forces, quadrature_forces
from mjrft.field import GranularField

GLASS = mjrft.Material.preset("glass_beads")
POPPY = mjrft.Material.preset("poppy_seeds_cp")
# Different but equivalent operation orders (combined coefficients, exp/log forms of tanh/atanh).
ROUNDOFF = 1e-12


def inputs(rng, n):
    pos = rng.normal(scale=0.05, size=(n, 3))
    n_hat, _ = _unit_rows(rng.normal(size=(n, 3)))
    n_hat[:50] = [0, 0, -1]  # horizontal plates
    n_hat[50:80] = [0, 0, 1]
    vel = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-6, 1, size=(n, 1))
    vel[:20, :2] = 0.0  # vertical motion of a horizontal plate: world-x frame
    # Moving exactly in the plate's plane (n . v == 0 exactly): not leading, no force. (Nearly
    # in-plane motion is where leading flips with round-off: the method is discontinuous there.)
    n_hat[100:130] = [0.0, 1.0, 0.0]
    vel[100:130] = [0.3, 0.0, -0.2]
    vel[130:140] = 0.0
    vel[140:150] *= 1e-200  # tiny and huge speeds take the rescaling path
    vel[150:160] *= 1e200
    area = rng.uniform(0, 1e-4, size=n)
    return pos, n_hat, area, vel


@pytest.mark.parametrize("material", [GLASS, POPPY], ids=["glass", "poppy_cp"])
@pytest.mark.parametrize("n", [1, 7, 256, 257, 5000])  # chunk boundaries
def test_compiled_forces_equal_numpy(material, n):
    rng = np.random.default_rng(n)
    pos, n_hat, area, vel = inputs(rng, max(n, 200))
    pos, n_hat, area, vel = pos[:n], n_hat[:n], area[:n], vel[:n]
    out = np.full((n, 3), np.nan)
    got, count = engine.forces(
        pos, n_hat, area, vel, material.kernel_coefficients, material.alpha_y0,
        material.zeta, 0.0, out,
    )  # fmt: skip
    assert got is out  # written in place
    ref = numpy_forces(pos, n_hat, area, vel, material, 0.0)
    scale = max(np.abs(ref).max(), 1e-300)
    np.testing.assert_allclose(out, ref, rtol=ROUNDOFF, atol=ROUNDOFF * scale)
    assert count == np.count_nonzero(np.any(ref != 0, axis=1))


def test_body_kernel_equals_field_numpy_path():
    xml = """
    <mujoco><custom><text name="mjrft:material" data="glass_beads"/>
      <numeric name="mjrft:region" data="-0.5 -0.5 -0.5 0.012 0.5 0.5"/>
      <tuple name="mjrft:intruders"><element objtype="body" objname="b" prm="700"/></tuple>
    </custom><worldbody><body name="b" pos="0 0 -0.01" euler="10 20 30"><freejoint/>
      <geom type="ellipsoid" size="0.01 0.02 0.015" contype="0" conaffinity="0"/>
      <geom type="box" size="0.01 0.01 0.002" pos="0.02 0 0.01" contype="0" conaffinity="0"/>
      <geom type="sphere" size="0.005" pos="0 0 0.2" contype="0" conaffinity="0"/>
    </body></worldbody></mujoco>"""
    m = mjrft.load_model(xml, low_speed="off")
    d = mujoco.MjData(m)
    d.qvel[:] = [0.02, -0.01, -0.05, 2.0, -1.0, 0.5]
    mujoco.mj_forward(m, d)
    fld = GranularField(m)
    fast = fld.wrench(d)
    slow = pure_wrench(fld, d)  # NumPy transforms and element_forces, culling by region there
    assert np.any(slow != 0)
    np.testing.assert_allclose(fast, slow, rtol=1e-10, atol=1e-12 * np.abs(slow).max())
    for st in fld.element_states(d):  # the pass's element forces at the states it reports
        ref = mjrft.element_forces(st.pos, st.normal, st.area, st.vel, fld.material)
        np.testing.assert_allclose(st.force, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    # The sphere 20 cm up is culled by its bounding sphere: its triangles are never evaluated
    # (in mj_forward's pass and in wrench's).
    sizes = np.diff(fld.bodies[0].segments)
    stats = fld.stats_of(d)
    assert stats["calls"] == 2
    assert stats["evaluated"] == stats["calls"] * (sizes[0] + sizes[1])


def _forces(material, pos, n_hat, area, vel):
    out, _ = engine.forces(
        pos, n_hat, area, vel, material.kernel_coefficients, material.alpha_y0,
        material.zeta, 0.0,
    )  # fmt: skip
    return out


def test_scaling_functions_over_their_whole_range():
    """The kernel's exp and log polynomials (f1 and f23 on bounded arguments) against NumPy's
    tanh/arctanh, on a dense grid of velocity directions at a vertical plate (normal +x) that
    includes the ends: |v.e1| = 0 and 1 (sideways), |v23| = 0 and 1, and every octave of the
    log's argument."""
    th = np.linspace(0.0, 0.5 * np.pi, 401)[:-1]  # angle from the normal, leading only
    ph = np.linspace(0.0, 2.0 * np.pi, 97)
    th, ph = (a.ravel() for a in np.meshgrid(th, ph))
    vel = np.stack([np.cos(th), np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph)], axis=1)
    n = len(vel)
    pos = np.tile([0.0, 0.0, -0.1], (n, 1))
    n_hat = np.tile([1.0, 0.0, 0.0], (n, 1))
    area = np.full(n, 1e-4)
    for material in (GLASS, POPPY):
        out = _forces(material, pos, n_hat, area, vel)
        ref = numpy_forces(pos, n_hat, area, vel, material, 0.0)
        np.testing.assert_allclose(out, ref, rtol=ROUNDOFF, atol=ROUNDOFF * np.abs(ref).max())


def test_result_does_not_depend_on_the_slot_in_a_chunk():
    """An element's force is bit-identical wherever it lands in a chunk (the vectorised body of
    the loop or its scalar remainder), so splitting or reordering work never changes results."""
    rng = np.random.default_rng(11)
    pos, n_hat, area, vel = inputs(rng, 300)
    base = _forces(GLASS, pos, n_hat, area, vel)
    for shift in (1, 2, 3, 5, 250):
        perm = np.roll(np.arange(300), shift)
        out = _forces(GLASS, pos[perm], n_hat[perm], area[perm], vel[perm])
        np.testing.assert_array_equal(out, base[perm])
    for n in (1, 2, 3, 9):
        sub = _forces(GLASS, pos[:n], n_hat[:n], area[:n], vel[:n])
        np.testing.assert_array_equal(sub, base[:n])


@pytest.mark.parametrize("scale", [1e-300, 1e-31, 1e-9, 1.0, 1e30, 1e31, 1e300])
def test_speed_scale_never_changes_the_force(scale):
    """RFT forces depend on the direction of motion only: the kernel's range guard (velocities
    rescaled outside |w|^2 in [1e-60, 1e60]) and its products of speed-scaled factors hold over
    the whole double range, nearly horizontal plates (frame from the velocity) included."""
    rng = np.random.default_rng(5)
    pos, n_hat, area, vel = inputs(rng, 400)
    vel = _unit_rows(vel)[0]  # rows 130-140 stay at rest
    n_hat[200:260] = _unit_rows(n_hat[200:260] * [1e-3, 1e-3, 1.0] + [0, 0, 1e-9])[0]
    ref = _forces(GLASS, pos, n_hat, area, vel)
    out = _forces(GLASS, pos, n_hat, area, vel * scale)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, ref, rtol=ROUNDOFF, atol=ROUNDOFF * np.abs(ref).max())


def _plate_body():
    """A body of a few body-frame elements (its quadrature data from the box's triangles)."""
    es = geometry.box([0.01, 0.02, 0.005])
    reach, patch = es.quadrature
    return es.centroids, es.normals, es.areas, reach, patch


def test_body_wrench_rows_give_the_evaluated_wrench():
    """The quadrature rows body_wrench writes instead of forces (media given as callables),
    evaluated by the NumPy path, sum to the wrench the kernel evaluates itself."""
    cent, norm, area, reach, patch = _plate_body()
    flat = surface.flat(0.0)
    rot = quat_to_mat(np.array([0.9, 0.2, 0.3, 0.1]))
    motion = (rot, [0.0, 0.0, -0.003], [0.7, 0.7, 0.0], [0.003, 0.0, -0.01], [0.0, 0.0, -0.003],
              [0.001, 0.0, -0.002])  # fmt: skip
    medium = (GLASS.kernel_coefficients, GLASS.alpha_y0, GLASS.zeta, flat.prm, flat.grid)
    wrench, elem_force, acting = engine.body_wrench(
        cent, norm, area, reach, patch, *medium, None, None, *motion
    )
    assert acting == np.count_nonzero(np.any(elem_force != 0.0, axis=1)) > 0
    np.testing.assert_allclose(wrench[:3], elem_force.sum(axis=0), rtol=1e-12)
    rows = np.zeros((len(area), engine.ROW))
    w0, f0, written = engine.body_wrench(
        cent, norm, area, reach, patch, *medium, None, None, *motion, rows
    )
    assert written >= acting and not np.any(w0) and not np.any(f0)
    # The acting part's area: the element's, or less where the quadrature clipped it.
    on = rows[:, 9] > 0.0
    assert np.all(rows[on, 10] > 0.0) and np.all(rows[on, 10] <= area[on])
    assert np.any(rows[on, 10] < area[on]) and np.any(rows[on, 10] == area[on])
    f = quadrature_forces(rows, GLASS)
    torque = np.cross(rows[:, :3] - motion[5], f).sum(axis=0)
    scale = np.abs(wrench).max()
    np.testing.assert_allclose(np.concatenate([f.sum(axis=0), torque]), wrench, rtol=0,
                               atol=ROUNDOFF * scale)  # fmt: skip
    # A sub-range evaluates only those elements; the rest of elem_force stays zero.
    _, part, _ = engine.body_wrench(
        cent, norm, area, reach, patch, *medium, None, None, *motion, start=2, stop=5
    )
    np.testing.assert_array_equal(part[2:5], elem_force[2:5])
    assert not np.any(part[:2]) and not np.any(part[5:])


def test_the_bindings_name_what_does_not_fit():
    """Arrays of the wrong shape, type or layout raise before the library is called, naming
    the argument; nothing is read or written out of bounds."""
    pos, n_hat, area, vel = inputs(np.random.default_rng(2), 200)
    co = GLASS.kernel_coefficients
    with pytest.raises(
        ValueError, match=r"forces: normal has shape \(199, 3\), expected \(200, 3\)"
    ):
        engine.forces(pos, n_hat[1:], area, vel, co, 0.1, 1.0, 0.0)
    with pytest.raises(ValueError, match=r"forces: area has shape \(200, 1\), expected \(200,\)"):
        engine.forces(pos, n_hat, area[:, None], vel, co, 0.1, 1.0, 0.0)
    with pytest.raises(ValueError, match="coef has 5 entries, a force model reads at least 18"):
        engine.forces(pos, n_hat, area, vel, co[:5], 0.1, 1.0, 0.0)
    with pytest.raises(TypeError, match="out must be a float64 NumPy array, got float32"):
        engine.forces(pos, n_hat, area, vel, co, 0.1, 1.0, 0.0, np.zeros((200, 3), np.float32))
    with pytest.raises(ValueError, match="out must be C-contiguous and writable"):
        engine.forces(pos, n_hat, area, vel, co, 0.1, 1.0, 0.0, np.zeros((3, 200)).T)
    with pytest.raises(TypeError, match="pos must be a real-valued array, got dtype complex128"):
        engine.input_flags(pos + 0j, n_hat, area, vel)
    # Inputs of other real types or layouts are converted: the same forces.
    f, _ = engine.forces(pos, n_hat, area, vel, co, 0.1, 1.0, 0.0)
    g, _ = engine.forces(np.asfortranarray(pos), n_hat.tolist(), area, vel, co, 0.1, 1.0, 0.0)
    np.testing.assert_array_equal(f, g)

    cent, norm, area, reach, patch = _plate_body()
    flat, n = surface.flat(0.0), len(area)
    motion = (np.eye(3), *np.zeros((5, 3)))
    args = (cent, norm, area, reach, patch, co, 0.1, 1.0)
    with pytest.raises(ValueError, match=r"patch has shape \(\d+, 18\), expected \(\d+, 19\)"):
        engine.body_wrench(*args[:4], patch[:, :18], *args[5:], flat.prm, flat.grid, None, None,
                           *motion)  # fmt: skip
    with pytest.raises(ValueError, match=r"elements 3..2 are not within the \d+ given"):
        engine.body_wrench(*args, flat.prm, flat.grid, None, None, *motion, start=3, stop=2)
    with pytest.raises(ValueError, match=rf"rows has shape \(2, 10\), expected \({n}, 11\)"):
        engine.body_wrench(*args, flat.prm, flat.grid, None, None, *motion, np.zeros((2, 10)))
    with pytest.raises(ValueError, match=r"region has shape \(6,\), expected \(2, 3\)"):
        engine.body_wrench(*args, flat.prm, flat.grid, np.zeros(6), None, *motion)
    ground = surface.grid(np.zeros((3, 4)), 0.0, 0.0, 0.1, 0.1)
    with pytest.raises(ValueError, match=r"surface grid has shape \(4, 3\), prm says \(3, 4\)"):
        engine.body_wrench(*args, ground.prm, ground.grid.T.copy(), None, None, *motion)
    soil = ground.prm.copy()
    soil[surface.KIND] = surface.SOIL
    with pytest.raises(ValueError, match="a deforming .SOIL. surface needs its soil block"):
        engine.body_wrench(*args, soil, ground.grid, None, None, *motion)
    needs = surface.soil_block(3, 4)  # the head and three levels of 12 vertices
    with pytest.raises(ValueError, match=f"soil has 12 entries, the grid's block needs {needs}"):
        engine.body_wrench(*args, soil, ground.grid, None, np.zeros(12), *motion)
    with pytest.raises(
        ValueError, match=r"trajectory: rot has shape \(3, 3\), expected \(1, 3, 3\)"
    ):
        engine.trajectory(*args, 0.0, np.eye(3), *np.zeros((4, 1, 3)))
    with pytest.raises(ValueError, match="the coordinates' shapes do not broadcast"):
        engine.surface_heights(flat.prm, flat.grid, None, np.zeros(3), np.zeros(4))
    assert quadrature.PATCH_SIZE == 19  # the kernel's patch row (engine/tables.h kPatchSize)
