"""Bad scene input is named, and legal input that is almost surely a mistake is warned about."""

import warnings

import numpy as np
import pytest

import mjrft
from mjrft.core.material import LI_GENERIC, MaterialWarning, dissipation_violation
from mjrft.field import GranularField, SceneError
from mjrft.field.scene import SceneWarning

LI = " ".join(
    str(LI_GENERIC.as_mapping().get(k, 0.0))
    for k in ("A00", "A10", "B11", "B01", "B-11", "C11", "C01", "C-11", "D10")
)


def scene(
    custom: str, bodies: str = "", tags: str = '<element objtype="geom" objname="g" prm="100"/>'
):
    return f"""<mujoco><custom>{custom}<tuple name="mjrft:intruders">{tags}</tuple></custom>
      <worldbody>{bodies or '<body name="b"><freejoint/><geom name="g" size="0.01"/></body>'}
      </worldbody></mujoco>"""


def field(xml: str, **kw) -> GranularField:
    """The field of xml loaded with the engine plugin (kw: mjrft.SceneOptions fields)."""
    return GranularField(mjrft.load_model(xml, **kw))


GLASS = '<text name="mjrft:material" data="glass_beads"/>'


@pytest.mark.parametrize("name", ["MJRFT:region", "mjrft_region", "mjrft.low_speed", "Mjrft-zeta"])
def test_a_misspelt_prefix_is_refused_with_the_right_name(name):
    kind = "text" if "low_speed" in name else "numeric"
    data = "off" if kind == "text" else "1 2 3 4 5 6"
    xml = scene(GLASS + f'<{kind} name="{name}" data="{data}"/>')
    key = name[6:]
    with pytest.raises(
        SceneError, match=f"'{name}'.*start with 'mjrft:'.*did you mean 'mjrft:{key}'"
    ):
        field(xml)


@pytest.mark.parametrize(
    ("coefficients", "match"),
    [
        (" ".join(f"{-float(x):g}" for x in LI.split()), "must be > 0"),  # negated
        ("0 0 0 0 0 0 0 0 0", "must be > 0"),  # zero
        ("1e300 0 0 0 0 0 0 0 0", "magnitude 1e\\+300"),  # out of proportion
        ("0.206 0.169 0.212 0.358 0.055 0.124 -0.253 0.007 0.088", "not a dissipative medium"),
    ],
)
def test_coefficient_sets_that_are_not_a_medium_are_refused(coefficients, match):
    xml = scene(
        '<numeric name="mjrft:zeta" data="330000"/>'
        f'<numeric name="mjrft:coefficients" data="{coefficients}"/>'
    )
    with pytest.raises(SceneError, match=f"mjrft:coefficients.*{match}"):
        field(xml)


def test_li_coefficients_are_accepted_and_every_preset_dissipates():
    fld = field(
        scene(
            '<numeric name="mjrft:zeta" data="330000"/>'
            f'<numeric name="mjrft:coefficients" data="{LI}"/>'
        )
    )
    assert fld.material.zeta == 330000
    for name in mjrft.PRESETS:
        assert dissipation_violation(mjrft.Material.preset(name)) is None


def test_zeta_given_in_n_per_cm3_warns():
    with pytest.warns(MaterialWarning, match="0.33 N/m\\^3.*N/cm\\^3.*330000"):
        field(scene('<numeric name="mjrft:zeta" data="0.33"/>'))
    with pytest.raises(SceneError, match="above 1e\\+15"):
        field(scene('<numeric name="mjrft:zeta" data="1e300"/>'))


def test_a_geom_tagged_twice_is_refused():
    tags = (
        '<element objtype="geom" objname="g" prm="100"/>'
        '<element objtype="body" objname="b" prm="0"/>'
    )
    with pytest.raises(SceneError, match="'g' is tagged twice.*elements 0 and 1"):
        field(scene(GLASS, tags=tags))


@pytest.mark.parametrize("prm", ["inf", "nan", "-inf"])
def test_a_non_finite_prm_is_named(prm):
    tags = f'<element objtype="geom" objname="g" prm="{prm}"/>'
    with pytest.raises(SceneError, match="intruders element 0 has prm = "):
        field(scene(GLASS, tags=tags))


def test_a_tolerance_too_small_to_mesh_is_named():
    with pytest.raises(SceneError, match="mjrft:tolerance.*1e-300 needs about 1e3"):
        field(scene(GLASS + '<numeric name="mjrft:tolerance" data="1e-300"/>'))


def test_a_mesh_above_the_triangle_cap_is_refused_with_its_memory():
    verts = "0 0 0  1 0 0  0 1 0  0 0 1"
    faces = "0 2 1  0 1 3  0 3 2  1 2 3"
    xml = scene(
        GLASS + '<numeric name="mjrft:max_triangles" data="3"/>',
        bodies='<body name="b"><freejoint/><geom name="g" type="mesh" mesh="t"/></body>',
        tags='<element objtype="geom" objname="g" prm="0"/>',
    ).replace(
        "<worldbody>", f'<asset><mesh name="t" vertex="{verts}" face="{faces}"/></asset><worldbody>'
    )
    with pytest.raises(SceneError, match="'g' would have 4 triangles, above the cap of 3.*GB.*MB"):
        field(xml)
    with pytest.raises(SceneError, match="'g' would have 100 triangles, above the cap of 50"):
        field(scene(GLASS + '<numeric name="mjrft:max_triangles" data="50"/>'))


def test_a_tagged_geom_on_the_floor_or_welded_to_the_world_warns():
    floor = '<geom name="floor" type="plane" size="1 1 0.1"/>'
    ball = '<body name="b"><freejoint/><geom name="g" size="0.01"/></body>'
    with pytest.warns(SceneWarning, match="'g' is tagged and also collides with 'floor'"):
        field(scene(GLASS, bodies=floor + ball))
    apart = ball.replace('size="0.01"', 'size="0.01" contype="0" conaffinity="0"')
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        field(scene(GLASS, bodies=floor + apart))
    fixed = '<body name="b"><geom name="g" size="0.01"/></body>'
    with pytest.warns(SceneWarning, match="'b' is welded to the world"):
        field(scene(GLASS, bodies=fixed))


def test_material_may_be_a_preset_name():
    fld = field(scene(GLASS), material="poppy_seeds_cp")
    assert fld.material.name == "poppy_seeds_cp"
    with pytest.raises(SceneError, match="material='sand'.*glass_beads"):
        field(scene(GLASS), material="sand")
    with pytest.raises(SceneError, match="material must be a mjrft.Material"):
        field(scene(GLASS), material=3.0)


def test_a_table_that_pushes_plates_along_their_motion_is_refused_or_warned():
    negated_c = {k: (-v if k.startswith("C") else v) for k, v in LI_GENERIC.as_mapping().items()}
    with pytest.raises(ValueError, match="not a dissipative medium.*beta = .*gamma = "):
        mjrft.Material.from_table(negated_c)
    with pytest.warns(MaterialWarning, match="not a dissipative medium"):
        mjrft.Material.from_table(negated_c, strict=False)
    with pytest.warns(MaterialWarning, match="not a dissipative medium"):
        mjrft.Material.from_callables(lambda b, g: -1 + 0 * b, lambda b, g: 1 + 0 * b, 3e5)
    assert np.isfinite(mjrft.Material.from_table(LI_GENERIC.as_mapping()).zeta)
