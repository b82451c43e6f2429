"""Intruders selected by body subtree, geom-name pattern and collision geoms, in MJCF and in
Python (docs/mjcf.md): each picks the expected geoms, a selection of nothing is refused by name,
and a geom selected twice is counted once."""

import mujoco
import numpy as np
import pytest

import mjrft
from mjrft.field import GranularField, SceneError

LEG = """
  <body name="{p}_thigh" pos="{x} 0 -0.02">
    <joint name="{p}_hip" axis="0 1 0"/>
    <geom name="{p}_thigh_g" type="capsule" fromto="0 0 0 0 0 -0.04" size="0.008"/>
    <body name="{p}_calf" pos="0 0 -0.04">
      <joint name="{p}_knee" axis="0 1 0"/>
      <geom name="{p}_calf_g" type="capsule" fromto="0 0 0 0 0 -0.04" size="0.006"/>
      <geom name="{p}_foot" pos="0 0 -0.04" size="0.01"/>
    </body>
  </body>"""


def robot(custom: str) -> str:
    """A small two-legged body standing 1 cm deep in glass beads, with a visual-only geom."""
    legs = LEG.format(p="fl", x=0.05) + LEG.format(p="hl", x=-0.05)
    return f"""<mujoco><option timestep="0.001"/>
      <custom><text name="mjrft:material" data="glass_beads"/>
        <numeric name="mjrft:triangles" data="80"/>{custom}</custom>
      <worldbody>
        <geom name="floor_marker" type="box" size="0.01 0.01 0.01" pos="1 1 1"/>
        <body name="trunk" pos="0 0 0.1"><freejoint/>
          <geom name="trunk_g" type="box" size="0.08 0.03 0.02"/>
          <geom name="trunk_vis" type="sphere" size="0.02" pos="0 0 0.03"
                contype="0" conaffinity="0"/>{legs}
        </body>
      </worldbody></mujoco>"""


def text(form: str, data: str) -> str:
    return f'<text name="mjrft:intruders_{form}" data="{data}"/>'


def tagged(xml: str, **kw) -> set[str]:
    return {i.name for i in GranularField(mjrft.load_model(xml, **kw)).scene.intruders}


FL = {"fl_thigh_g", "fl_calf_g", "fl_foot"}
HL = {"hl_thigh_g", "hl_calf_g", "hl_foot"}
COLLIDING = FL | HL | {"trunk_g"}


def test_a_subtree_tags_its_body_and_every_descendant():
    assert tagged(robot(text("subtree", "fl_thigh"))) == FL
    assert tagged(robot(text("subtree", "fl_thigh hl_calf"))) == FL | {"hl_calf_g", "hl_foot"}
    # "world": every geom of every moving body (the world's own geoms stay out)
    assert tagged(robot(text("subtree", "world"))) == COLLIDING | {"trunk_vis"}


def test_a_pattern_tags_the_geoms_whose_names_match():
    assert tagged(robot(text("match", "*foot"))) == {"fl_foot", "hl_foot"}
    assert tagged(robot(text("match", "*foot *calf*"))) == {
        "fl_foot", "hl_foot", "fl_calf_g", "hl_calf_g"
    }  # fmt: skip
    assert tagged(robot(text("match", "?l_thigh_g"))) == {"fl_thigh_g", "hl_thigh_g"}
    unnamed = robot(text("match", "*")).replace('name="trunk_vis" ', "")
    with pytest.raises(SceneError, match="geom 'floor_marker' belongs to the world body"):
        tagged(unnamed)
    assert tagged(unnamed.replace('name="floor_marker" ', "")) == COLLIDING  # unnamed: never


def test_collision_tags_every_collision_geom_of_the_model_or_a_subtree():
    assert tagged(robot(text("collision", "world"))) == COLLIDING
    assert tagged(robot(text("collision", "trunk"))) == COLLIDING
    assert tagged(robot(text("collision", "hl_thigh"))) == HL


def test_the_forms_add_up_and_a_geom_selected_twice_is_counted_once():
    custom = (
        '<tuple name="mjrft:intruders"><element objtype="geom" objname="fl_foot" prm="200"/>'
        "</tuple>" + text("match", "*foot *_foot") + text("subtree", "fl_calf")
    )
    fld = GranularField(mjrft.load_model(robot(custom)))
    names = [i.name for i in fld.scene.intruders]
    assert sorted(names) == sorted({"fl_foot", "hl_foot", "fl_calf_g"})
    assert len(names) == len(set(names))
    tri = {i.name: i.n_triangles for i in fld.scene.intruders}
    assert tri == {"fl_foot": 200, "hl_foot": 80, "fl_calf_g": 80}  # the tuple's prm kept


def test_python_intruders_take_the_same_forms_and_replace_the_mjcfs():
    xml = robot(text("match", "*foot"))
    assert tagged(xml, intruders={"subtree": "fl_thigh"}) == FL
    assert tagged(xml, intruders={"match": ["*calf*", "*foot"]}) == {
        "fl_calf_g", "hl_calf_g", "fl_foot", "hl_foot"
    }  # fmt: skip
    assert tagged(xml, intruders={"collision": "world"}) == COLLIDING
    assert tagged(xml, intruders={"geoms": "trunk_g", "bodies": "hl_calf"}) == {
        "trunk_g", "hl_calf_g", "hl_foot"
    }  # fmt: skip
    # and a model with no MJCF tagging at all is tagged from Python
    assert tagged(robot(""), intruders={"match": "*thigh*"}) == {"fl_thigh_g", "hl_thigh_g"}


@pytest.mark.parametrize(
    ("custom", "kw", "message"),
    [
        (
            text("match", "*foot *toe*"),
            {},
            r"<text name='mjrft:intruders_match'>: pattern '\*toe\*' matches no geom name; "
            r"geoms: floor_marker, trunk_g, trunk_vis, fl_thigh_g",
        ),
        (
            text("subtree", "fl_shin"),
            {},
            r"intruders_subtree'>: no body named 'fl_shin'; bodies: world, trunk, fl_thigh",
        ),
        (
            text("collision", "world"),
            {"intruders": {"match": "*paw*"}},
            r"intruders\['match'\]: pattern '\*paw\*' matches no geom name; geoms: floor_marker",
        ),
        (
            "",
            {"intruders": {"collision": "fl_knee"}},
            r"intruders\['collision'\]: no body named 'fl_knee'",
        ),
        ("", {"intruders": {"geoms": "fl_paw"}}, r"intruders\['geoms'\]: no geom named 'fl_paw'"),
        (
            "",
            {"intruders": {"feet": "*foot"}},
            r"intruders: unknown key\(s\) 'feet'; valid: geoms, bodies, subtree, match, collision",
        ),
        ("", {"intruders": {"match": ""}}, r"intruders\['match'\] is empty"),
        (text("match", " "), {}, r"<text name='mjrft:intruders_match'> is empty"),
        ("", {}, r"no intruding geoms: .*intruders_match"),
    ],
)
def test_a_selection_of_nothing_is_refused_by_name(custom, kw, message):
    with pytest.raises(SceneError, match=message):
        mjrft.load_model(robot(custom), **kw)


def test_collision_refuses_a_subtree_without_collision_geoms():
    xml = robot("").replace(
        '<geom name="trunk_vis"', '<body name="lamp"><geom name="lamp_g" contype="0" '
        'conaffinity="0" size="0.01"/></body><geom name="trunk_vis"'
    )  # fmt: skip
    with pytest.raises(SceneError, match=r"body 'lamp' has no collision geom \(contype or "):
        mjrft.load_model(xml, intruders={"collision": "lamp"})


def test_a_pattern_gives_the_forces_of_the_explicit_listing_of_the_same_geoms():
    listed = "".join(f'<element objtype="geom" objname="{g}" prm="0"/>' for g in sorted(FL | HL))
    explicit = robot(f'<tuple name="mjrft:intruders">{listed}</tuple>')
    runs = []
    for xml in (explicit, robot(text("match", "*_thigh_g *_calf_g *_foot"))):
        model = mjrft.load_model(xml)
        data = mujoco.MjData(model)
        data.qpos[2] = 0.09  # feet 1 cm deep
        for _ in range(50):
            mujoco.mj_step(model, data)
        runs.append((data.qpos.copy(), data.qvel.copy(), data.xfrc_applied.copy()))
    assert np.abs(runs[0][2][:, 2]).max() > 0.1  # the medium holds the feet up [N]
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
