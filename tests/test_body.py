"""Rigid-body and trajectory evaluation against the slow reference of the quadrature."""

import numpy as np
import pytest
import quadrature_reference

import mjrft
from mjrft.body import body_wrench, quat_to_mat, trajectory_wrenches

GLASS = mjrft.Material.preset("glass_beads")
#: The same medium given as callables: evaluated by the NumPy path, not the compiled kernel.
GLASS_CALLABLES = mjrft.Material.from_callables(
    GLASS.fourier.alpha_x, GLASS.fourier.alpha_z, GLASS.zeta, name="glass_beads as callables"
)
#: Compiled kernel against the NumPy evaluation: polynomial exp / log and fused multiply-adds
#: differ from libm and NumPy by a few ulp per element (tests/test_kernel.py).
KERNEL_RTOL = 1e-12


def octahedron(size=0.02):
    v = size * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    f = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return mjrft.ElementSet.from_triangles(v + [0.003, -0.002, 0.001], np.array(f))


def random_rotation(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def test_quaternion_convention_matches_mujoco():
    mujoco = pytest.importorskip("mujoco")
    rng = np.random.default_rng(0)
    for _ in range(10):
        q = random_rotation(rng)
        m = np.zeros(9)
        mujoco.mju_quat2Mat(m, q)
        np.testing.assert_allclose(quat_to_mat(q), m.reshape(3, 3), atol=1e-14)


def test_body_wrench_is_the_quadrature_sum_and_moment_transfers():
    rng = np.random.default_rng(1)
    es = octahedron()
    for _ in range(20):
        q = random_rotation(rng)
        r = quat_to_mat(q)
        pos = np.array([0.01, 0.02, -0.015])
        v, w = rng.normal(size=3) * 0.05, rng.normal(size=3)
        f, m = quadrature_reference.body_wrench(es, pos, r, v, w, GLASS, pos)
        wr = body_wrench(es, pos, q, v, w, GLASS)
        np.testing.assert_allclose(wr.force, f, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(wr.moment, m, rtol=1e-12, atol=1e-15)
        c = np.array([0.1, -0.3, 0.2])
        wc = body_wrench(es, pos, r, v, w, GLASS, point=c)
        np.testing.assert_allclose(wc.force, wr.force, rtol=1e-12)
        np.testing.assert_allclose(
            wc.moment, wr.moment + np.cross(pos - c, wr.force), rtol=1e-9, atol=1e-15
        )


def test_trajectory_equals_pointwise_evaluation():
    rng = np.random.default_rng(2)
    es = octahedron()
    t = 37
    pos = rng.normal(scale=0.01, size=(t, 3)) - [0, 0, 0.02]
    quats = np.array([random_rotation(rng) for _ in range(t)])
    v, w = rng.normal(size=(t, 3)), rng.normal(size=(t, 3))
    pts = rng.normal(size=(t, 3))
    traj = trajectory_wrenches(es, pos, quats, v, w, GLASS, points=pts)
    traj_m = trajectory_wrenches(es, pos, quat_to_mat(quats), v, w, GLASS, points=pts)
    for i in range(t):
        one = body_wrench(es, pos[i], quats[i], v[i], w[i], GLASS, point=pts[i])
        np.testing.assert_allclose(traj.force[i], one.force, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(traj.moment[i], one.moment, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(traj_m.force, traj.force, rtol=1e-12, atol=1e-15)


def test_compiled_trajectory_equals_numpy_evaluation():
    rng = np.random.default_rng(4)
    es = octahedron()
    t = 64
    pos = rng.uniform(-0.03, 0.03, size=(t, 3))  # dry, half and fully submerged samples
    quats = np.array([random_rotation(rng) for _ in range(t)])
    v, w = rng.normal(size=(t, 3)) * 0.1, rng.normal(size=(t, 3))
    fast = trajectory_wrenches(es, pos, quats, v, w, GLASS, surface_z=0.002)
    slow = trajectory_wrenches(es, pos, quats, v, w, GLASS_CALLABLES, surface_z=0.002)
    assert np.any(slow.force != 0) and np.any(np.all(slow.force == 0, axis=1))
    scale = np.abs(slow.force).max()
    np.testing.assert_allclose(fast.force, slow.force, rtol=KERNEL_RTOL, atol=KERNEL_RTOL * scale)
    np.testing.assert_allclose(
        fast.moment, slow.moment, rtol=KERNEL_RTOL, atol=KERNEL_RTOL * scale * 0.02
    )
    one = body_wrench(es, pos[5], quats[5], v[5], w[5], GLASS_CALLABLES, surface_z=0.002)
    np.testing.assert_allclose(one.force, fast.force[5], rtol=KERNEL_RTOL, atol=1e-15)


def test_above_surface_body_feels_nothing():
    es = octahedron()
    wr = body_wrench(es, [0, 0, 0.05], np.eye(3), [0, 0, -1.0], [1.0, 0, 0], GLASS)
    assert np.all(wr.force == 0) and np.all(wr.moment == 0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"position": [0, 0]}, "position has shape"),
        ({"rotation": np.zeros(4)}, "quaternion must be finite and non-zero"),
        ({"rotation": np.eye(2)}, "rotation has shape"),
        ({"lin_vel": [0, np.nan, 0]}, "lin_vel must be finite"),
        ({"ang_vel": [0, 0]}, "ang_vel has shape"),
    ],
)
def test_body_wrench_bad_input(kwargs, match):
    args = {
        "elements": octahedron(),
        "position": [0, 0, -0.1],
        "rotation": np.eye(3),
        "lin_vel": [0, 0, -1.0],
        "ang_vel": [0, 0, 0.0],
        "material": GLASS,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        body_wrench(**args)


def test_a_material_may_be_a_preset_name_and_anything_else_is_named():
    """``material="glass_beads"`` is the preset, in element_forces, body_wrench and
    trajectory_wrenches alike; an unknown name or another type names the argument and the
    presets."""
    el = octahedron()
    pose = dict(position=[0.0, 0.0, -0.01], rotation=np.eye(3), lin_vel=[0.01, 0.0, -0.02],
                ang_vel=[0.0, 0.5, 0.0])  # fmt: skip
    want = body_wrench(el, material=GLASS, **pose)
    got = body_wrench(el, material="glass_beads", **pose)
    np.testing.assert_array_equal(got.force, want.force)
    t = trajectory_wrenches(el, [pose["position"]], [np.eye(3)], [pose["lin_vel"]],
                            [pose["ang_vel"]], "glass_beads")  # fmt: skip
    np.testing.assert_array_equal(t.force[0], want.force)
    args = (el.centroids - [0, 0, 0.01], el.normals, el.areas, np.tile([0.0, 0.0, -0.1], (8, 1)))
    np.testing.assert_array_equal(
        mjrft.element_forces(*args, "glass_beads"), mjrft.element_forces(*args, GLASS)
    )
    with pytest.raises(ValueError, match=r"material='sand': unknown material preset.*glass_beads"):
        mjrft.element_forces(*args, "sand")
    with pytest.raises(TypeError, match=r"material must be a mjrft.Material or a preset name "
                       r"\(generic_1ncm3, glass_beads, .*\), got dict"):  # fmt: skip
        body_wrench(el, material={"zeta": 1.0}, **pose)
