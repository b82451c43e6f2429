"""Leading is decided with a slack for rounding (docs/design.md 2.1): a face parallel to the
motion up to rounding feels nothing, in the engine, the NumPy law and the plain reference."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import rft_reference
from scipy.spatial.transform import Rotation

from mjrft.app import wheel
from mjrft.core import engine, geometry, surface
from mjrft.core.law import LEADING_SLACK
from mjrft.core.material import Material
from mjrft.core.rft import numpy_forces

GLASS = Material.preset("glass_beads")


def _wrench(field, es, keep, rot, pos, omega, v_ref, p_ref, com):
    """The engine's wrench on the elements es[keep] (body frame) of a body at rot, pos."""
    reach, patch = es.quadrature
    m = field.material
    surf = field.surface
    return engine.body_wrench(
        es.centroids[keep], es.normals[keep], es.areas[keep], reach[keep], patch[keep],
        m.kernel_coefficients, m.alpha_y0, m.zeta, surf.prm, surf.grid, field.region, None,
        rot, pos, omega, v_ref, p_ref, com,
    )  # fmt: skip


@pytest.mark.parametrize("slip", [-0.2, 0.0, 0.9])
def test_wheel_end_caps_feel_nothing(slip):
    """The rig's wheel, sunk and rolling at slip, gets the same wrench from the medium with its
    end caps (normals along the axle up to rounding) as with the caps removed."""
    model, field, data = wheel.rig(slip)
    body = model.body("wheel").id
    es = field.body_element_set(body)
    axle = model.jnt_axis[model.joint("spin").id]  # body frame
    cap = np.abs(es.normals @ axle) > 0.999
    assert cap.sum() > 500  # the caps are there, their normals off the axle only by rounding
    assert np.abs(es.normals[cap] @ axle).min() > 1.0 - 1e-12
    rim = ~cap
    vel = np.zeros(6)
    for _ in range(4):
        for _ in range(300):  # sinking in, then rolling at its steady sinkage
            mujoco.mj_step(model, data)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, vel, 0)
        pose = (data.xmat[body].reshape(3, 3), data.xpos[body], vel[:3], vel[3:],
                data.xpos[body], data.xipos[body])  # fmt: skip
        full, force, _ = _wrench(field, es, np.ones(len(es.areas), bool), *pose)
        bare, _, _ = _wrench(field, es, rim, *pose)
        assert abs(full[0]) > 0.01  # the wheel is in the medium
        assert np.all(force[cap] == 0.0)
        np.testing.assert_allclose(full, bare, rtol=0.0, atol=1e-6)
        # The field, stepping the rig, sees the same.
        np.testing.assert_allclose(field.wrench(data)[body], bare, rtol=0.0, atol=1e-6)


def test_rotated_box_parallel_faces_feel_nothing():
    """A submerged box moving along one of its faces' normals, turned through many random
    orientations: the four faces parallel to the motion feel nothing (engine, NumPy law and
    the plain reference), only the leading face does."""
    es = geometry.box([0.02, 0.015, 0.01], n_triangles=96)
    axis = np.argmax(np.abs(es.normals), axis=1)
    parallel = axis != 0  # faces with normals +-y, +-z: parallel to motion along x
    front = (axis == 0) & (es.normals[:, 0] > 0.0)
    rng = np.random.default_rng(45)
    flat = surface.flat(0.0)
    for rot in Rotation.random(200, random_state=rng).as_matrix():
        pos = np.array([0.1, -0.05, -0.2])
        speed = 10.0 ** rng.uniform(-3.0, 1.0)
        v = rot[:, 0] * speed
        n = es.normals @ rot.T
        lead = n @ v
        assert np.abs(lead[parallel]).max() <= 4.0 * LEADING_SLACK * speed  # zero up to rounding
        # the engine, over the body's elements (the quadrature included)
        _, force, _ = engine.body_wrench(
            es.centroids, es.normals, es.areas, *es.quadrature, GLASS.kernel_coefficients,
            GLASS.alpha_y0, GLASS.zeta, flat.prm, flat.grid,
            None, None, rot, pos, np.zeros(3), v, pos, pos,
        )  # fmt: skip
        assert np.all(force[parallel] == 0.0)
        assert np.all(np.abs(force[front]).sum(axis=1) > 0.0)
        # the element law: engine, NumPy and the plain reference
        c = es.centroids @ rot.T + pos
        vel = np.tile(v, (len(es.areas), 1))
        kernel, _ = engine.forces(
            c, n, es.areas, vel, GLASS.kernel_coefficients, GLASS.alpha_y0, GLASS.zeta, 0.0
        )
        for f in (
            kernel,
            numpy_forces(c, n, es.areas, vel, GLASS, 0.0),
            rft_reference.reference_forces(c, n, es.areas, vel, GLASS, 0.0),
        ):
            assert np.all(f[parallel] == 0.0)
            assert np.all(np.abs(f[front]).sum(axis=1) > 0.0)
