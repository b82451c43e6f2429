"""The command line's own contract: its version, what it refuses, and how its options reach the
scene (one mjrft.SceneOptions, given to load_model)."""

import subprocess
import sys
from dataclasses import fields
from importlib.metadata import version

import pytest

import mjrft
from mjrft import GranularField, SceneOptions
from mjrft.app import cli, simulate


def test_version_option_and_attribute(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"mjrft {mjrft.__version__}"
    assert mjrft.__version__ == version("mjrft")


def test_installed_command_runs():
    out = subprocess.run(
        [sys.executable, "-m", "mjrft.app.cli", "--version"], capture_output=True, text=True
    )
    assert out.returncode == 0 and out.stdout.strip() == f"mjrft {mjrft.__version__}"


# Every scene option, each different from the shipped wheel rig's own values.
SCENE_ARGS = ["--material", "poppy_seeds_lp", "--triangles", "300", "--low-speed", "free",
              "--stick-reach", "3", "--deform-cell", "0.01", "--repose", "25",
              "--deform-every", "2", "--dynamic", "1500", "0.8",
              "--intruders", "geoms=wheel", "--intruders", "match=whe*"]  # fmt: skip


@pytest.mark.parametrize("command", ["run", "view"])
def test_every_scene_option_reaches_load_model_through_scene_options(command):
    """cli.scene_options is the one place the command line reaches the scene: every
    SceneOptions field has its option in `mjrft run` and `mjrft view`, and the model is loaded
    with them (the field built from it describes that scene)."""
    assert set(cli.SCENE_OPTIONS) == {f.name for f in fields(SceneOptions)}
    extra = ["--duration", "1", "--out", "unused"] if command == "run" else []
    args = cli.build_parser().parse_args([command, "wheel_rig", *extra, *SCENE_ARGS])
    options = cli.scene_options(args)
    assert options == SceneOptions(
        material="poppy_seeds_lp", n_triangles=300, low_speed="free", stick_reach=3.0,
        deform_cell=0.01, repose=25.0, deform_every=2, dynamic=(1500.0, 0.8),
        intruders={"geoms": ["wheel"], "match": ["whe*"]},
    )  # fmt: skip
    _, _, fld = cli._scene(args, "wheel_rig")
    assert fld.material.name.startswith("poppy_seeds_lp") and fld.material.dynamic == 1200.0
    assert (fld.low_speed.mode, fld.low_speed.reach) == ("free", 3.0) and fld.deforms
    assert [i.name for i in fld.scene.intruders] == ["wheel"]  # selected twice, tagged once
    triangles = [GranularField(simulate.load_model("wheel_rig", n_triangles=n)).n_elements
                 for n in (300, None)]  # fmt: skip
    assert fld.n_elements == triangles[0] != triangles[1]
    bare = cli.build_parser().parse_args([command, "wheel_rig", *extra])
    assert cli.scene_options(bare) == SceneOptions()  # unset: the MJCF's values


def test_one_dynamic_value_is_rho_c_and_the_demo_options_are_scene_options():
    args = cli.build_parser().parse_args(["view", "sphere_drop", "--dynamic", "1500"])
    assert cli.scene_options(args).dynamic == 1500.0
    demo = cli.build_parser().parse_args(["demo", "--triangles", "500"])
    assert cli.scene_options(demo).given() == {"material": "glass_beads", "n_triangles": 500}
