"""The command line's own contract: its version, and what it refuses."""

import subprocess
import sys
from importlib.metadata import version

import pytest

import mjrft
from mjrft.app import cli


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
