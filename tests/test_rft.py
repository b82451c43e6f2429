"""The force kernel against the element law (docs/design.md section 2): analytic cases,
symmetries, a reference loop."""

import numpy as np
import pytest
from rft_reference import reference_forces

import mjrft
from mjrft.core.law import HORIZONTAL_PLATE_NZ, f1, f23
from mjrft.core.material import MaterialWarning
from mjrft.core.rft import element_forces

GLASS = mjrft.Material.preset("glass_beads")
ZETA = 0.33 * mjrft.N_PER_CM3
# Float64 round-off of a handful of operations on O(1) numbers, with headroom.
EXACT = 1e-12


def random_elements(rng, n, submerged=True):
    pos = rng.normal(scale=0.05, size=(n, 3))
    if submerged:
        pos[:, 2] = -np.abs(pos[:, 2]) - 1e-4
    normal = rng.normal(size=(n, 3)) * rng.uniform(0.1, 10.0, size=(n, 1))  # not unit length
    area = rng.uniform(1e-6, 1e-4, size=n)
    vel = rng.normal(size=(n, 3)) * rng.uniform(1e-3, 1.0, size=(n, 1))
    return pos, normal, area, vel


def test_horizontal_plate_pushed_down_is_exact():
    depth, area = 0.037, 2.6e-3
    f = element_forces([[0.3, -0.2, -depth]], [[0, 0, -1]], [area], [[0, 0, -0.01]], GLASS)
    expected = ZETA * depth * area * 1.0  # alpha_z(0, pi/2) = 1 in generic form
    assert f[0, 2] == pytest.approx(expected, rel=EXACT)
    assert np.all(f[0, :2] == 0.0)


def test_speed_does_not_matter():
    args = ([[0, 0, -0.02]], [[0.3, 0.1, -1.0]], [1e-4])
    slow = element_forces(*args, [[0.01, 0.02, -0.03]], GLASS)
    fast = element_forces(*args, [[1.0, 2.0, -3.0]], GLASS)
    np.testing.assert_allclose(slow, fast, rtol=EXACT)


@pytest.mark.parametrize(
    ("beta", "gamma", "az", "ax"),
    # docs/design.md section 2.5 (Li 2013 Fig. 2 generic values).
    [
        (0.0, np.pi / 2, 1.0, 0.0),
        (0.0, 0.0, 0.375, 0.136),
        (np.pi / 2, 0.0, 0.037, 0.370),
        (0.0, -np.pi / 2, -0.25, 0.0),
    ],
)
def test_tabulated_alphas(beta, gamma, az, ax):
    gax, gay, gaz = GLASS.alpha_generic(beta, gamma)
    assert gaz == pytest.approx(az, abs=EXACT)
    assert gax == pytest.approx(ax, abs=EXACT)
    assert gay == pytest.approx(0.136, abs=EXACT)  # alpha_y = alpha_x(0, 0)


def test_alpha_symmetry_and_periodicity():
    rng = np.random.default_rng(1)
    b, g = rng.uniform(-np.pi, np.pi, 500), rng.uniform(-np.pi, np.pi, 500)
    ax, _, az = GLASS.alpha_generic(b, g)
    axm, _, azm = GLASS.alpha_generic(-b, np.pi - g)
    np.testing.assert_allclose(azm, az, atol=EXACT)
    np.testing.assert_allclose(axm, -ax, atol=EXACT)
    axp, _, azp = GLASS.alpha_generic(b + np.pi, g)
    np.testing.assert_allclose(azp, az, atol=EXACT)
    np.testing.assert_allclose(axp, ax, atol=EXACT)


def test_scaling_functions_endpoints():
    assert f1(np.array(0.0)) == pytest.approx(0.0, abs=1e-9)
    assert f1(np.array(1.0)) == pytest.approx(1.0, abs=1e-9)
    assert f23(np.array(0.0)) == pytest.approx(0.0, abs=1e-9)
    assert f23(np.array(1.0)) == pytest.approx(1.0, abs=1e-9)
    x = np.linspace(0, 1, 101)
    assert np.all(np.diff(f1(x)) > 0) and np.all(np.diff(f23(x)) > 0)


def test_dissipation_dense_sample():
    rng = np.random.default_rng(2)
    pos, normal, area, vel = random_elements(rng, 200_000)
    f = element_forces(pos, normal, area, vel, GLASS)
    acting = np.any(f != 0.0, axis=1)
    assert acting.sum() > 90_000  # about half are leading
    power = np.einsum("ij,ij->i", f, vel)
    assert np.all(power[acting] < 0.0)
    assert np.all(power[~acting] == 0.0)


def test_dissipation_on_angle_grid_including_degenerate_frames():
    # Every normal direction on a fine grid (poles, horizontal plates included) against every
    # velocity direction on a fine grid: F.v < 0 wherever a force acts.
    th = np.linspace(0, np.pi, 37)
    ph = np.linspace(-np.pi, np.pi, 72, endpoint=False)
    t, p = np.meshgrid(th, ph)
    dirs = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    nn, vv = np.repeat(dirs, len(dirs), 0), np.tile(dirs, (len(dirs), 1))
    pos = np.zeros_like(nn)
    pos[:, 2] = -0.01
    f = element_forces(pos, nn, np.ones(len(nn)), vv, GLASS)
    power = np.einsum("ij,ij->i", f, vv)
    acting = np.any(f != 0.0, axis=1)
    assert np.all(power[acting] < 0.0)
    assert np.all(np.isfinite(f))


def test_rotation_about_vertical_rotates_force():
    rng = np.random.default_rng(3)
    pos, normal, area, vel = random_elements(rng, 5000)
    f = element_forces(pos, normal, area, vel, GLASS)
    for angle in (0.3, np.pi / 2, 2.0, -1.234):
        c, s = np.cos(angle), np.sin(angle)
        rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        fr = element_forces(pos @ rz.T, normal @ rz.T, area, vel @ rz.T, GLASS)
        np.testing.assert_allclose(fr, f @ rz.T, rtol=1e-9, atol=1e-12 * np.abs(f).max())
        np.testing.assert_allclose(
            np.linalg.norm(fr, axis=1), np.linalg.norm(f, axis=1), rtol=1e-9, atol=1e-15
        )


def test_rotation_invariance_of_horizontal_plate_moving_vertically():
    # World x is picked as e2 here; the force must not depend on that arbitrary choice.
    for n in ([0, 0, -1], [0, 0, 1]):
        for v in ([0, 0, -1], [0, 0, 1]):
            f = element_forces([[0, 0, -0.01]], [n], [1e-3], [v], GLASS)
            assert np.all(f[0, :2] == 0.0)


def test_linear_in_depth_and_area():
    rng = np.random.default_rng(4)
    pos, normal, area, vel = random_elements(rng, 1000)
    f = element_forces(pos, normal, area, vel, GLASS)
    deeper = pos.copy()
    deeper[:, 2] *= 3.0
    np.testing.assert_allclose(element_forces(deeper, normal, area, vel, GLASS), 3 * f, rtol=EXACT)
    np.testing.assert_allclose(
        element_forces(pos, normal, 2.5 * area, vel, GLASS), 2.5 * f, rtol=EXACT
    )


def test_surface_height_shifts_depth():
    rng = np.random.default_rng(5)
    pos, normal, area, vel = random_elements(rng, 500)
    f = element_forces(pos, normal, area, vel, GLASS)
    shifted = pos + [0.0, 0.0, 0.7]
    np.testing.assert_allclose(
        element_forces(shifted, normal, area, vel, GLASS, surface_z=0.7), f, rtol=1e-9, atol=1e-15
    )


def test_zero_above_surface_trailing_and_at_rest():
    rng = np.random.default_rng(6)
    pos, normal, area, vel = random_elements(rng, 1000)
    above = pos.copy()
    above[:, 2] = np.abs(above[:, 2])
    assert np.all(element_forces(above, normal, area, vel, GLASS) == 0.0)
    at_surface = pos.copy()
    at_surface[:, 2] = 0.0
    assert np.all(element_forces(at_surface, normal, area, vel, GLASS) == 0.0)
    trailing = -np.sign(np.einsum("ij,ij->i", normal, vel))[:, None] * vel
    trailing = np.where(trailing == 0, 0.0, trailing)
    assert np.all(element_forces(pos, normal, area, trailing, GLASS) == 0.0)
    assert np.all(element_forces(pos, normal, area, np.zeros_like(vel), GLASS) == 0.0)


@pytest.mark.parametrize("material_name", ["li", "callables", "table", "alpha_y"])
@pytest.mark.filterwarnings("ignore::mjrft.core.material.MaterialWarning")  # stand-in media
def test_kernel_matches_reference_loop(material_name):
    materials = {
        "li": GLASS,
        "callables": mjrft.Material.from_callables(
            lambda b, g: 0.3 * np.cos(g) + 0.1 * np.sin(2 * b) - 0.05 * np.sin(b + g),
            lambda b, g: 0.6 + 0.2 * np.cos(2 * b) + 0.4 * np.sin(g) + 0.1 * np.cos(b - g),
            2.0e5,
        ),
        "table": mjrft.Material.from_table(
            {
                "A00": 0.05,
                "A10": 0.04,
                "A-10": 0.01,
                "A01": 0.02,
                "B11": 0.05,
                "B01": 0.09,
                "B-11": 0.01,
                "B10": 0.02,
                "C11": -0.03,
                "C01": 0.06,
                "C-11": 0.002,
                "C00": 0.01,
                "D10": 0.02,
                "D01": 0.01,
                "D-11": 0.005,
            },
            strict=False,  # a stand-in exercising every coefficient, not a real medium
        ),
        "alpha_y": mjrft.Material.from_callables(
            lambda b, g: 0.25 * np.cos(g),
            lambda b, g: 0.5 + 0.5 * np.sin(g),
            1e6,
            alpha_y=lambda b: 0.1 + 0.05 * np.cos(2 * b),
        ),
    }
    m = materials[material_name]
    rng = np.random.default_rng(7)
    pos, normal, area, vel = random_elements(rng, 3000, submerged=False)
    # Include the degenerate frames: horizontal plates, vertical and purely out-of-plane motion.
    normal[:200] = [0, 0, -1]
    normal[200:300] = [0, 0, 1]
    normal[300:400, 2] = np.sign(normal[300:400, 2]) * 50.0  # within the horizontal-plate band
    vel[:100, :2] = 0.0
    vel[400:500, 2] = 0.0
    f = element_forces(pos, normal, area, vel, m)
    ref = reference_forces(pos, normal, area, vel, m)
    scale = np.abs(ref).max()
    assert scale > 0
    np.testing.assert_allclose(f, ref, rtol=EXACT, atol=EXACT * scale)
    assert np.count_nonzero(np.any(f != 0, axis=1)) > 500  # ~1/4: submerged and leading


def test_nearly_horizontal_plate_threshold():
    # Exactly at the threshold the branch is decided by the last bit of the normalised normal, so
    # test just either side of it: the kernel must switch frames where the specification does.
    nz = HORIZONTAL_PLATE_NZ
    for tilt in (nz - 1e-9, nz + 1e-9, 1.0):
        n = np.array([[np.sqrt(1 - tilt**2), 0.0, -tilt]])
        f = element_forces([[0, 0, -0.01]], n, [1e-3], [[0.3, 0.2, -1.0]], GLASS)
        ref = reference_forces(np.array([[0, 0, -0.01]]), n, [1e-3], [[0.3, 0.2, -1.0]], GLASS)
        np.testing.assert_allclose(f, ref, rtol=EXACT, atol=1e-15)


def test_no_nan_for_extreme_finite_inputs():
    rng = np.random.default_rng(8)
    n = 20_000
    pos = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-12, 1, size=(n, 1))
    normal = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-150, 150, size=(n, 1))
    vel = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-150, 150, size=(n, 1))
    vel[::7, :2] = 0.0
    vel[::11, 2] = 0.0
    normal[::13, :2] = 0.0
    area = 10.0 ** rng.uniform(-12, 0, size=n)
    area[::17] = 0.0
    f = element_forces(pos, normal, area, vel, GLASS)
    assert np.all(np.isfinite(f))
    # Direction depends only on unit vectors: rescaling inputs changes nothing.
    np.testing.assert_allclose(
        element_forces(pos, normal * 1e-100, area, vel * 1e100, GLASS), f, rtol=1e-9, atol=0
    )


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"pos": np.zeros((3, 2))}, "pos has shape"),
        ({"normal": np.ones((2, 3))}, "normal has shape"),
        ({"vel": np.ones(3)}, "vel has shape"),
        ({"area": np.ones(4)}, "area has shape"),
        ({"area": np.array([1.0, -1.0, 1.0])}, "area of element 1 is negative"),
        ({"normal": np.array([[0, 0, 1.0], [0, 0, 0], [1, 0, 0]])}, "normal of element 1 .*zero"),
        ({"vel": np.array([[0, 0, 1.0], [0, np.nan, 0], [1, 0, 0]])}, "vel of element 1 .*finite"),
        ({"pos": np.array([[0, 0, np.inf]] * 3)}, "pos of element 0 .*finite"),
        ({"surface_z": np.nan}, "surface_z"),
        ({"area": np.array([1.0, 1.0, np.nan])}, "area of element 2 .*finite"),
        ({"normal": np.array([[0, 0, 1.0], [0, 0, 1.0], [0, -np.inf, 0]])}, "normal of element 2"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = {
        "pos": -np.ones((3, 3)),
        "normal": np.ones((3, 3)),
        "area": np.ones(3),
        "vel": -np.ones((3, 3)),
        "material": GLASS,
        "surface_z": 0.0,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        element_forces(**args)


def test_element_force_does_not_depend_on_the_other_elements():
    # Unit normals skip normalisation only where every normal of the call is unit; a unit
    # normal must give the same bits whether or not other normals in the call needed it.
    rng = np.random.default_rng(7)
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    pos, area, vel = rng.normal(scale=0.01, size=(200, 3)) - [0, 0, 0.02], np.ones(200), n * 0.1
    alone = element_forces(pos, n, area, vel, GLASS)
    mixed = n.copy()
    mixed[::7] *= 3.0  # a few normals of other lengths
    together = element_forces(pos, mixed, area, vel, GLASS)
    unit = np.ones(200, bool)
    unit[::7] = False
    np.testing.assert_array_equal(together[unit], alone[unit])
    np.testing.assert_allclose(together[~unit], alone[~unit], rtol=1e-14, atol=1e-16)


def test_authors_stand_in_alpha_functions_plug_in():
    # The stand-in 2D model shipped with the authors' released MATLAB code (rft_3D_body.m), in
    # generic form: az = (0.6 sin g + 0.4) cos b, ax = 0.25 cos g (1 - cos 2b), with the first-
    # order alpha_y = ax(0, 0) = 0. Plugged in as callables, the kernel must equal the plain
    # transcription of the method, and a hand-computed element.
    with pytest.warns(MaterialWarning, match="not a dissipative medium"):  # a stand-in indeed
        stand_in = mjrft.Material.from_callables(
            lambda b, g: 0.25 * np.cos(g) * (1 - np.cos(2 * b)),
            lambda b, g: (0.6 * np.sin(g) + 0.4) * np.cos(b),
            ZETA,
        )
    assert stand_in.alpha_y0 == 0.0
    rng = np.random.default_rng(9)
    pos, normal, area, vel = random_elements(rng, 2000)
    f = element_forces(pos, normal, area, vel, stand_in)
    ref = reference_forces(pos, normal, area, vel, stand_in)
    np.testing.assert_allclose(f, ref, rtol=EXACT, atol=EXACT * np.abs(ref).max())
    # Vertical plate facing +x (beta = pi/2) pushed along +x (gamma = 0): az = 0.4 cos(pi/2) = 0,
    # ax = 0.25 * 1 * (1 - cos pi) = 0.5, force = -zeta d A ax e2 = -0.5 zeta d A x.
    one = element_forces([[0, 0, -0.02]], [[1.0, 0, 0]], [1e-4], [[0.01, 0, 0]], stand_in)
    np.testing.assert_allclose(one[0], [-0.5 * ZETA * 0.02 * 1e-4, 0, 0], atol=1e-15)
