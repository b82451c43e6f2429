"""MuJoCo's viewer shows the forces: headless screenshots, counting the arrows' pixels.

The scene is rendered offscreen by ``mujoco.Renderer`` in a child process (MuJoCo picks its
OpenGL backend from MUJOCO_GL when it is first imported): with EGL, else OSMesa; where neither
can open a context the test is skipped, saying so. The arrows are added to the rendered scene
by ``mujoco_viewer.draw_forces`` exactly as ``mjrft view`` adds them to the viewer's scene.
"""

import json
import os
import subprocess
import sys
import textwrap

import pytest

CHILD = textwrap.dedent(
    """
    import json, sys
    import mujoco

    # An OpenGL context first, or this child fails here (and the test is skipped).
    probe = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    mujoco.Renderer(probe, 8, 8)
    print("GL_OK", flush=True)

    import numpy as np
    from mjrft.app import mujoco_viewer as mv, simulate
    from mjrft.field.granular_field import GranularField

    xml, steps = sys.argv[1], int(sys.argv[2])
    model = simulate.load_model(xml)
    renderer = mujoco.Renderer(model, 240, 320)
    fld = GranularField(model)
    data = simulate.reset_data(model)
    arrows = mv.ForceArrows(model, fld)  # the automatic scale, carried over the steps
    scratch = mujoco.MjvScene(model, maxgeom=1000)
    for _ in range(steps):
        mujoco.mj_step(model, data)
        mv.draw_forces(scratch, model, data, fld, arrows=arrows, triangles=True)
    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, cam)
    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, fld.body_ids[0])
    mv.track(cam, model, body)
    cam.distance = 3 * float(arrows.sizes.max())

    def arrow_pixels(image, rgba):
        px = image.reshape(-1, 3).astype(float)
        rgb = np.asarray(rgba[:3], float)
        cos = px @ rgb / (np.linalg.norm(px, axis=1) * np.linalg.norm(rgb) + 1e-9)
        return int(np.sum((cos > COSINE) & (px.max(axis=1) > BRIGHT)))

    COSINE, BRIGHT = 0.97, 60
    renderer.update_scene(data, cam)
    plain = renderer.render().copy()
    n = mv.draw_forces(renderer.scene, model, data, fld, arrows=arrows, triangles=True,
                       keep=renderer.scene.ngeom)
    shown = renderer.render().copy()
    out = {"arrows": n}
    for name, rgba in (("body", arrows.body_rgba), ("triangle", arrows.triangle_rgba)):
        out[name] = [arrow_pixels(plain, rgba), arrow_pixels(shown, rgba)]
    print("RESULT " + json.dumps(out), flush=True)
    """
)

# An orange box (the hexapod torso's colour) dropped into the sand (drawn translucent, as the
# shipped models draw it): its arrows must not be orange.
ORANGE_BOX = """<mujoco><option timestep="0.001"><flag contact="disable"/></option>
<custom><text name="mjrft:material" data="glass_beads"/>
<tuple name="mjrft:intruders"><element objtype="body" objname="box" prm="800"/></tuple></custom>
<worldbody><light pos="0 0 1" dir="0 0 -1"/>
<geom type="plane" size="0.2 0.2 0.01" rgba="0.86 0.76 0.55 0.5" contype="0" conaffinity="0"/>
<body name="box" pos="0 0 0.012"><freejoint/>
<geom type="box" size="0.03 0.02 0.01" rgba="0.8 0.45 0.2 1" density="2000"/></body>
</worldbody></mujoco>"""

#: Pixels of 320 x 240 the arrows must cover at least: the body arrow is about its body's size
#: at a camera three body sizes away, some thousand pixels; 100 is far above a stray pixel.
MIN_ARROW_PIXELS = 100
#: Pixels of the arrow colour the model alone may show (its colours are chosen away from them).
MAX_PLAIN_PIXELS = 10


def _screenshot(scene: str, steps: int) -> dict:
    for backend in ("egl", "osmesa"):
        env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
        proc = subprocess.run([sys.executable, "-c", CHILD, scene, str(steps)],
                              capture_output=True, text=True, env=env, timeout=300)  # fmt: skip
        if "GL_OK" in proc.stdout.splitlines():  # rendering works: the rest must
            lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
            assert lines, proc.stderr
            return json.loads(lines[0][len("RESULT ") :])
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
    pytest.skip(f"no headless OpenGL here (MUJOCO_GL=egl and osmesa both failed: {last})")


@pytest.mark.parametrize(("scene", "steps"), [("sphere_drop", 300), ("orange_box", 40)])
def test_the_viewers_arrows_are_seen_in_a_screenshot(tmp_path, scene, steps):
    if scene == "orange_box":
        path = tmp_path / "orange_box.xml"
        path.write_text(ORANGE_BOX)
        scene = str(path)
    result = _screenshot(scene, steps)
    assert result["arrows"] > 1
    for kind in ("body", "triangle"):
        plain, shown = result[kind]
        assert plain <= MAX_PLAIN_PIXELS, (kind, result)  # the model has no such colour
        assert shown >= MIN_ARROW_PIXELS, (kind, result)  # and the arrows cover many pixels
