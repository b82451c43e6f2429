"""The README's examples work as written, and its commands are the ones CI and users run."""

import contextlib
import io
import re
from pathlib import Path

import mujoco
import numpy as np

import mjrft
from mjrft import GranularField

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def fenced(lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", README, flags=re.M | re.S)


def test_readme_is_a_front_door():
    assert len(README.splitlines()) <= 200
    assert len(fenced("xml")) == 1 and len(fenced("python")) >= 1 and len(fenced("bash")) == 2


def test_readme_mjcf_scene_compiles_and_runs():
    (xml,) = fenced("xml")
    model = mjrft.load_model(xml)
    field = GranularField(model)
    assert {be.name for be in field.bodies} == {"ball", "foot"}
    assert field.region is not None and field.surface_z == 0.0
    data = mujoco.MjData(model)
    for _ in range(300):
        mujoco.mj_step(model, data)
    ball = model.body("ball").id
    assert data.xpos[ball, 2] < 0.011  # it fell into the medium
    assert np.all(np.isfinite(data.qpos))


def test_readme_python_examples_run_on_the_scene_and_print_what_they_say(tmp_path, monkeypatch):
    """The python blocks run in order, in a directory holding the xml block as scene.xml; what
    they print is what their comments say they print."""
    monkeypatch.chdir(tmp_path)
    (xml,) = fenced("xml")
    (tmp_path / "scene.xml").write_text(xml)
    (tmp_path / "models").symlink_to(ROOT / "models", target_is_directory=True)
    namespace = {"__name__": "readme"}
    for i, code in enumerate(fenced("python")):
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(code, f"README.md (python block {i + 1})", "exec"), namespace)
        comments = [line[2:] for line in code.splitlines() if line.startswith("# ")]
        for printed in out.getvalue().splitlines():
            assert any(c.startswith(printed) for c in comments), f"unannounced output {printed!r}"


def test_readme_quick_start_commands_match_ci():
    ci = (ROOT / ".ci" / "run").read_text()
    demo_cmd, test_cmd = (block.strip() for block in fenced("bash"))
    assert test_cmd in ci
    assert demo_cmd.endswith("mjrft demo") and "pip install -q ." in demo_cmd
