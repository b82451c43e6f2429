"""The README's examples work as written."""

import re
from pathlib import Path

import mujoco
import numpy as np

from mjrft import GranularField

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def test_readme_mjcf_scene_compiles_and_runs():
    (xml,) = re.findall(r"```xml\n(.*?)```", README, flags=re.S)
    model = mujoco.MjModel.from_xml_string(xml)
    field = GranularField(model)
    assert {be.name for be in field.bodies} == {"ball", "foot"}
    assert field.region is not None and field.surface_z == 0.0
    data = mujoco.MjData(model)
    with field.installed():
        for _ in range(300):
            mujoco.mj_step(model, data)
    ball = model.body("ball").id
    assert data.xpos[ball, 2] < 0.011  # it fell into the medium
    assert np.all(np.isfinite(data.qpos))


def test_readme_quick_start_commands_match_ci():
    ci = (Path(__file__).resolve().parents[1] / ".ci" / "run").read_text()
    test_cmd = re.findall(r"```bash\n(.*?)\n```", README, flags=re.S)[1]
    assert test_cmd in ci
