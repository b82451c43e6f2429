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
              "--intruders", "geoms=wheel", "--intruders", "match=whe*",
              "--no-watch-sinking"]  # fmt: skip


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
        intruders={"geoms": ["wheel"], "match": ["whe*"]}, watch_sinking=False,
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


def _subcommands() -> list[str]:
    sub = next(
        a for a in cli.build_parser()._actions if isinstance(a, cli.argparse._SubParsersAction)
    )
    return list(sub.choices)


#: Modules that `mjrft --help` and a subcommand's --help must not import (each subcommand
#: imports what it needs when it runs).
HEAVY = ("mujoco", "matplotlib", "rerun", "dm_control", "mjrft.sweep", "mjrft.field")


@pytest.mark.parametrize("command", [[], *([c] for c in _subcommands())], ids=" ".join)
def test_help_imports_no_heavy_module(command):
    """`python -m mjrft.app.cli [SUBCOMMAND] --help`, in a fresh process, prints its help and
    leaves mujoco, matplotlib, rerun, dm_control and the sweep machinery unimported."""
    child = (
        "import runpy, sys\n"
        f"sys.argv = ['mjrft', *{command!r}, '--help']\n"
        "try:\n    runpy.run_module('mjrft.app.cli', run_name='__main__')\n"
        "except SystemExit as exc:\n    code = exc.code\n"
        f"print(code, [m for m in {HEAVY!r} if m in sys.modules], file=sys.stderr)"
    )
    done = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True)
    assert done.stderr.strip().splitlines()[-1] == "0 []", done.stderr
    assert done.stdout.startswith(f"usage: {' '.join(['mjrft', *command])} ")


def test_subcommand_typos_suggest_the_closest(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["rnu"])
    assert exc.value.code == 2
    assert "invalid choice: 'rnu'" in (err := capsys.readouterr().err)
    assert "did you mean 'run'?" in err
    with pytest.raises(SystemExit):
        cli.main(["run", "sphere_drop", "--duration", "1", "--out", "x", "--integrator", "rk5"])
    assert "did you mean 'rk4'?" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["xyzzy"])
    assert "did you mean" not in capsys.readouterr().err


def test_model_name_typos_suggest_the_shipped_model(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", "hexapod_snad", "--duration", "1", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "no shipped model of that name" in err
    assert "did you mean 'hexapod_sand'?" in err
    assert not out.exists()
    with pytest.raises(ValueError, match="no shipped model") as exc:
        simulate.resolve_model("qwertyuiop")
    assert "did you mean" not in str(exc.value)  # nothing close: no suggestion


def test_low_speed_choices_are_the_fields_modes():
    from mjrft.field.lowspeed import MODES

    assert cli.LOW_SPEED_MODES == MODES
