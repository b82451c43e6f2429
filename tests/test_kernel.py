"""The compiled kernels equal the NumPy evaluation of the same equations."""

import mujoco
import numpy as np
import pytest
from field_reference import pure_wrench

import mjrft
from mjrft.core import kernel as _kernel
from mjrft.core.rft import _unit_rows, numpy_forces
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
    count = _kernel.forces(
        pos, n_hat, area, vel, material.kernel_coefficients, material.alpha_y0,
        material.zeta, 0.0, out,
    )  # fmt: skip
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
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[:] = [0.02, -0.01, -0.05, 2.0, -1.0, 0.5]
    mujoco.mj_forward(m, d)
    fld = GranularField(m, low_speed="off")
    fast = fld.wrench(d)
    slow = pure_wrench(fld, d)  # NumPy transforms and element_forces, culling by region there
    assert np.any(slow != 0)
    np.testing.assert_allclose(fast, slow, rtol=1e-10, atol=1e-12 * np.abs(slow).max())
    for st in fld.element_states(d):  # the pass's element forces at the states it reports
        ref = mjrft.element_forces(st.pos, st.normal, st.area, st.vel, fld.material)
        np.testing.assert_allclose(st.force, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    # The sphere 20 cm up is culled by its bounding sphere: its triangles are never evaluated.
    sizes = np.diff(fld.bodies[0].segments)
    assert fld.stats["evaluated"] == sizes[0] + sizes[1]


def _forces(material, pos, n_hat, area, vel):
    out = np.full(pos.shape, np.nan)
    _kernel.forces(
        pos, n_hat, area, vel, material.kernel_coefficients, material.alpha_y0,
        material.zeta, 0.0, out,
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
