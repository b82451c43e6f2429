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


def test_body_arrow_is_the_fields_force_outside_the_body():
    model, fld, data = settled_ellipsoid()
    scn = mujoco.MjvScene(model, maxgeom=100)
    drawn = mujoco_viewer.draw_forces(scn, model, data, fld, force_scale=0.1)
    assert drawn == len(fld.body_ids) == 1
    b = fld.body_ids[0]
    g = scn.geoms[0]
    force = fld.wrench_of(data)[b, :3]
    assert force[2] > 0.05  # in the medium, pushed up
    size = mujoco_viewer.body_sizes(fld)[0]
    # An mjv arrow starts at pos and points along the z axis of mat, size[2] long: here from
    # half the body's size out of its CoM along the force.
    axis = np.asarray(g.mat).reshape(3, 3)[:, 2]
    unit = force / np.linalg.norm(force)
    np.testing.assert_allclose(g.pos, data.xipos[b] + 0.5 * size * unit, atol=1e-12)
    np.testing.assert_allclose(g.size[2] * axis, 0.1 * force, rtol=1e-6, atol=1e-9)
    assert g.type == mujoco.mjtGeom.mjGEOM_ARROW
    np.testing.assert_array_equal(g.rgba, mujoco_viewer.arrow_colors(model)[0])


def test_the_automatic_scale_caps_every_arrow_at_its_bodys_size_and_recovers_slowly():
    sizes = np.array([0.15, 0.04])  # a torso and a leg [m]
    scale = mujoco_viewer.ArrowScale(sizes)
    big = np.array([[0.0, 0.0, 10.0], [0.0, 3.0, 0.0]])  # [N]
    s = scale.update(big, 0.0)
    lengths = s * np.linalg.norm(big, axis=1)
    assert np.all(lengths <= sizes * (1 + 1e-12))
    assert np.any(np.isclose(lengths, sizes))  # the binding body's arrow is its size
    # Forces ten times smaller: the scale grows back at most 2x per simulated second.
    assert scale.update(big / 10, 0.5) == pytest.approx(s * 2**0.5)
    assert scale.update(big / 10, 10.0) == pytest.approx(10 * s)  # then its cap
    assert scale.update(big, 10.001) == pytest.approx(s)  # larger forces: at once
    assert mujoco_viewer.ArrowScale(sizes, 0.05).update(big, 0.0) == 0.05  # a fixed scale


def test_arrow_colours_stand_out_from_the_models_own():
    """The hexapod's torso is orange: its arrows are not; an all-magenta model gets others."""
    for model in (simulate.load_model("hexapod_sand"), simulate.load_model("sphere_drop")):
        body, tri = mujoco_viewer.arrow_colors(model)
        own = mujoco_viewer.model_colors(model)
        for rgba in (body, tri):
            # RGB distance to the nearest colour of the model: at least half a colour axis.
            assert np.linalg.norm(own - rgba[:3], axis=1).min() >= MIN_COLOUR_GAP
        assert np.linalg.norm(body[:3] - tri[:3]) >= MIN_COLOUR_GAP
    hexapod = simulate.load_model("hexapod_sand")
    orange = [0.8, 0.45, 0.2]  # its torso
    assert any(np.allclose(c, orange, atol=1e-3) for c in mujoco_viewer.model_colors(hexapod))
    magenta = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom size="1" rgba="1 0 1 1"/></worldbody></mujoco>'
    )
    assert not np.allclose(mujoco_viewer.arrow_colors(magenta)[0][:3], [1, 0, 1])


#: Smallest RGB distance between an arrow colour and any colour of the model (each channel in
#: [0, 1]): half a channel's range, far beyond what shading makes of one colour.
MIN_COLOUR_GAP = 0.5


def test_track_follows_a_body_and_names_a_missing_one(monkeypatch, capsys):
    model = simulate.load_model("hexapod_sand")
    cam = mujoco.MjvCamera()
    mujoco_viewer.track(cam, model, "torso")
    assert cam.type == mujoco.mjtCamera.mjCAMERA_TRACKING
    assert cam.trackbodyid == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "torso")
    with pytest.raises(ValueError, match=r"--track 'torsoo': .*did you mean 'torso'\?"):
        mujoco_viewer.track(cam, model, "torsoo")
    monkeypatch.setattr(mujoco_viewer, "has_display", lambda: True)
    monkeypatch.setattr(mujoco_viewer, "launch", lambda *a, **k: pytest.fail("launched"))
    assert cli.main(["view", "hexapod_sand", "--track", "torsoo"]) == 2
    assert "did you mean 'torso'?" in capsys.readouterr().err


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
        self.cam = mujoco.MjvCamera()
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
        ctrl=lambda t, d: calls.append(t) or np.full(model.nu, 0.3), track_body="torso",
    )  # fmt: skip
    assert handle.syncs == len(calls) == 50 and np.all(data.ctrl == 0.3)
    assert handle.cam.type == mujoco.mjtCamera.mjCAMERA_TRACKING
    assert handle.user_scn.ngeom >= 1  # the feet in the sand carry arrows
    assert np.any(fld.wrench_of(data)[fld.body_ids, 2] > 0)


def test_view_without_a_display_names_the_headless_route(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("mjrft.app.view.sys.platform", "linux")
    assert cli.main(["view", "sphere_drop"]) == 2
    assert "no display" in capsys.readouterr().err
