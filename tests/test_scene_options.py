"""Scene options that would do nothing, or whose values are absurd, are warned about or refused
at load with the reason (mjrft.field.scene)."""

import warnings

import pytest

import mjrft
from mjrft import Material
from mjrft.app import cli
from mjrft.field import SceneError
from mjrft.field.scene import SceneWarning


def scene(custom: str = "", material: str = "glass_beads") -> str:
    return f"""<mujoco><option timestep="0.001"><flag contact="disable"/></option>
      <custom><text name="mjrft:material" data="{material}"/>{custom}
        <tuple name="mjrft:intruders"><element objtype="body" objname="b" prm="0"/></tuple>
        <numeric name="mjrft:triangles" data="60"/>
      </custom>
      <worldbody><body name="b"><freejoint/><geom type="sphere" size="0.01"/></body>
      </worldbody></mujoco>"""


REGION = '<numeric name="mjrft:region" data="-0.05 -0.05 -0.1 0.05 0.05 0.05"/>'


def load_quietly(xml: str, **overrides):
    """The model, failing on any warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return mjrft.load_model(xml, **overrides)


@pytest.mark.parametrize(
    ("custom", "overrides", "message"),
    [
        ('<numeric name="mjrft:repose" data="30"/>', {}, "mjrft:repose'> does nothing"),
        ('<numeric name="mjrft:deform_every" data="2"/>', {}, "mjrft:deform_every'> does nothing"),
        ("", {"repose": 30.0}, "repose = 30.0 does nothing"),
        ("", {"deform_every": 2}, "deform_every = 2 does nothing"),
        (REGION, {"deform_cell": 0.0, "repose": 30.0}, "repose = 30.0 does nothing"),
    ],
)  # fmt: skip
def test_ground_settings_without_a_deforming_ground_warn(custom, overrides, message):
    with pytest.warns(SceneWarning, match=f"{message}: there is no deforming ground"):
        mjrft.load_model(scene(custom), **overrides)


def test_ground_settings_with_a_deforming_ground_or_turned_off_with_it_are_quiet():
    ground = REGION + (
        '<numeric name="mjrft:deform_cell" data="0.01"/>'
        '<numeric name="mjrft:repose" data="25"/><numeric name="mjrft:deform_every" data="2"/>'
    )
    load_quietly(scene(ground))
    load_quietly(scene(REGION), deform_cell=0.01, repose=25.0, deform_every=2)
    load_quietly(scene(ground), deform_cell=0.0)  # the override turns the MJCF's ground off


def test_the_cli_options_reach_the_warning():
    args = cli.build_parser().parse_args(
        ["run", "wheel_rig", "--duration", "1", "--out", "unused", "--repose", "30"]
    )
    assert cli.scene_options(args).repose == 30.0
    with pytest.warns(SceneWarning, match="repose = 30.0 does nothing"):
        cli._scene(args, "wheel_rig")


@pytest.mark.parametrize("model", ["", '<text name="mjrft:model" data="treers2021"/>'])
def test_mu_surf_without_agarwal3d_warns(model):
    with pytest.warns(SceneWarning, match="mjrft:mu_surf'> does nothing.*agarwal3d"):
        mjrft.load_model(scene(model + '<numeric name="mjrft:mu_surf" data="0.5"/>'))
    load_quietly(scene('<text name="mjrft:model" data="agarwal3d"/>'
                       '<numeric name="mjrft:mu_surf" data="0.5"/>'))  # fmt: skip


@pytest.mark.parametrize("mu", ["1e9", "100.5"])
def test_absurd_mu_surf_is_refused_with_the_range(mu):
    custom = '<text name="mjrft:model" data="agarwal3d"/>'
    custom += f'<numeric name="mjrft:mu_surf" data="{mu}"/>'
    with pytest.raises(SceneError, match="mu_surf = .*from 0 to 100 .*below 1.*never to cap"):
        mjrft.load_model(scene(custom))
    with pytest.raises(ValueError, match="from 0 to 100"):
        Material.preset("glass_beads").with_model("agarwal3d", mu_surf=float(mu))


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ("1e30", "rho_c = 1e\\+30 kg/m\\^3: expected 0 to 25000 kg/m\\^3.*osmium"),
        ("30000", "rho_c = 30000 kg/m\\^3: expected 0 to 25000"),
        ("1500 1e30", "lambda = 1e\\+30: expected 0 to 10, the share of the grains' momentum"),
    ],
)  # fmt: skip
def test_absurd_dynamic_terms_are_refused_with_the_range(data, message):
    with pytest.raises(SceneError, match=f"mjrft:dynamic.*{message}"):
        mjrft.load_model(scene(f'<numeric name="mjrft:dynamic" data="{data}"/>'))
    with pytest.raises(SceneError, match=message):
        mjrft.load_model(scene(), dynamic=tuple(float(v) for v in data.split()))


@pytest.mark.parametrize("azimuth", ["1e300", "361", "-400", "nan", "inf"])
def test_absurd_or_non_finite_azimuths_are_refused(azimuth):
    custom = f'<numeric name="mjrft:surface_slope" data="10 {azimuth}"/>'
    with pytest.raises(SceneError, match="surface_slope.*(-360 to 360|finite angles in degrees)"):
        mjrft.load_model(scene(custom))


def test_azimuths_within_a_turn_each_way_are_accepted():
    for azimuth in ("-360", "359.5", "360"):
        load_quietly(scene(f'<numeric name="mjrft:surface_slope" data="10 {azimuth}"/>'))


def test_a_slope_steeper_than_the_medium_s_repose_warns_with_both_angles():
    slope = '<numeric name="mjrft:surface_slope" data="40 0"/>'
    with pytest.warns(SceneWarning, match="slope = 40 degrees.*angle of repose, 23 degrees.*flow"):
        mjrft.load_model(scene(slope))  # glass beads: 23 degrees (soil.REPOSE_DEG)
    with pytest.warns(SceneWarning, match="angle of repose, 23 degrees"):
        mjrft.load_model(scene(slope + '<text name="mjrft:model" data="agarwal3d"/>'))
    load_quietly(scene('<numeric name="mjrft:surface_slope" data="20 0"/>'))
    # the deforming ground's own angle of repose is the one that counts
    ground = REGION + '<numeric name="mjrft:deform_cell" data="0.01"/>'
    load_quietly(scene(slope + ground), repose=45.0)
    with pytest.warns(SceneWarning, match="angle of repose, 35 degrees"):
        mjrft.load_model(scene(slope + ground), repose=35.0)
