"""mjrft view: force arrows as scene decorations, and the viewer loop (with a stand-in window)."""

import contextlib

import mujoco
import numpy as np
import pytest

from mjrft.app import cli, mujoco_viewer, simulate
from mjrft.field.granular_field import GranularField


def settled_ellipsoid(steps=1500):
    model = simulate.load_model("ellipsoid_pitch")
    fld = GranularField(model)
    data = simulate.reset_data(model)
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return model, fld, data


def test_body_arrow_is_the_fields_force_at_the_com():
    model, fld, data = settled_ellipsoid()
    scn = mujoco.MjvScene(model, maxgeom=100)
    drawn = mujoco_viewer.draw_forces(scn, model, data, fld, force_scale=0.1)
    assert drawn == len(fld.body_ids) == 1
    b = fld.body_ids[0]
    g = scn.geoms[0]
    force = fld.wrench_of(data)[b, :3]
    assert force[2] > 0.05  # in the medium, pushed up
    # An mjv arrow starts at pos and points along the z axis of mat, size[2] long.
    axis = np.asarray(g.mat).reshape(3, 3)[:, 2]
    np.testing.assert_allclose(g.pos, data.xipos[b], atol=1e-12)
    np.testing.assert_allclose(g.size[2] * axis, 0.1 * force, rtol=1e-6, atol=1e-9)
    assert g.type == mujoco.mjtGeom.mjGEOM_ARROW


def test_triangle_arrows_are_bounded_and_the_scene_never_overflows():
    model, fld, data = settled_ellipsoid()
    scn = mujoco.MjvScene(model, maxgeom=1000)
    n = mujoco_viewer.draw_forces(scn, model, data, fld, triangles=True, max_triangle_arrows=50)
    assert 1 + 10 <= n <= 1 + 50 and scn.ngeom == n
    # Drawing again replaces the arrows rather than adding to them.
    assert mujoco_viewer.draw_forces(scn, model, data, fld, triangles=False) == 1
    small = mujoco.MjvScene(model, maxgeom=5)
    assert mujoco_viewer.draw_forces(small, model, data, fld, triangles=True) == 5 == small.ngeom
    with pytest.raises(ValueError, match="force_scale"):
        mujoco_viewer.draw_forces(scn, model, data, fld, force_scale=0.0)


class StandInViewer:
    """What launch() uses of mujoco.viewer's handle, without a window."""

    def __init__(self, model):
        self.user_scn = mujoco.MjvScene(model, maxgeom=50)
        self.syncs = 0

    def is_running(self):
        return True

    def lock(self):
        return contextlib.nullcontext()

    def sync(self):
        self.syncs += 1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_launch_steps_in_real_time_with_the_field_and_the_controller(monkeypatch):
    import mujoco.viewer

    model = simulate.load_model("hexapod_sand")
    fld = GranularField(model)
    handle = StandInViewer(model)
    monkeypatch.setattr(mujoco.viewer, "launch_passive", lambda m, d: handle)
    monkeypatch.setattr(mujoco_viewer, "has_display", lambda: True)
    calls = []
    data = mujoco_viewer.launch(
        model, fld, data=simulate.reset_data(model), duration=0.05,
        ctrl=lambda t, d: calls.append(t) or np.full(model.nu, 0.3),
    )  # fmt: skip
    assert handle.syncs == len(calls) == 50 and np.all(data.ctrl == 0.3)
    assert handle.user_scn.ngeom >= 1  # the feet in the sand carry arrows
    assert np.any(fld.wrench_of(data)[fld.body_ids, 2] > 0)


def test_view_without_a_display_names_the_headless_route(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("mjrft.app.view.sys.platform", "linux")
    assert cli.main(["view", "sphere_drop"]) == 2
    assert "no display" in capsys.readouterr().err
