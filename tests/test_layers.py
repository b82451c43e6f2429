"""The layers: mjrft.core imports no mujoco (the engine library included), and no module imports
from a layer above its own."""

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mjrft"
# Each layer may import from itself and the layers listed (mjrft's own modules only).
# mjrft.sweep sits above the app layer: sweeps run simulations (app); the CLI names the sweep
# command's handler without importing it (mjrft.app.cli.SWEEP_COMMAND).
ALLOWED = {
    "core": {"core"},
    "field": {"core", "field"},
    "app": {"core", "field", "app"},
    "sweep": {"core", "field", "app", "sweep"},
    # mjrft.warp (optional): the field on MuJoCo Warp, and the hexapod task as a vector
    # environment, which takes the dm_control task's constants from mjrft.envs.hexapod_sand.
    "warp": {"core", "field", "app", "warp", "envs"},
}


def _imports(path: Path) -> set[str]:
    """Absolute module names a file imports (at any depth, lazy imports included)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
            out.update(f"{node.module}.{alias.name}" for alias in node.names)
    return out


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_no_module_imports_from_a_layer_above(layer):
    bad = []
    for path in sorted((PACKAGE / layer).glob("*.py")):
        for name in _imports(path):
            parts = name.split(".")
            if parts[0] != "mjrft" or len(parts) < 2:
                continue
            target = parts[1]
            if target in ALLOWED and target not in ALLOWED[layer]:
                bad.append(f"{path.name} imports {name}")
            if (
                target in ("envs", "body", "geometry", "batch", "viz", "simulate")
                and target not in ALLOWED[layer]
            ):
                bad.append(f"{path.name} imports the public alias {name}; use the layer's module")
    assert not bad, bad


def test_importing_the_app_layer_imports_nothing_of_the_sweep_layer():
    """app and sweep do not import each other: every module of mjrft.app imports (CLI parser
    built) without mjrft.sweep, which imports the app layer; the CLI reaches the sweep command
    by its name, and that name resolves."""
    modules = sorted(f"mjrft.app.{p.stem}" for p in (PACKAGE / "app").glob("*.py"))
    code = (
        f"import sys, importlib\nfor m in {modules!r}:\n    importlib.import_module(m)\n"
        "from mjrft.app import cli\ncli.build_parser()\n"
        "print(sorted(m for m in sys.modules if m.startswith('mjrft.sweep')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stdout + out.stderr
    from mjrft.app import cli

    module, _, name = cli.SWEEP_COMMAND.partition(":")
    handler = getattr(importlib.import_module(module), name)
    assert callable(handler) and module.startswith("mjrft.sweep.")


def test_core_imports_no_mujoco_rerun_or_plotting():
    """Nor does loading the engine library through the core layer (mjrft.core.engine: ctypes)."""
    modules = sorted(f"mjrft.core.{p.stem}" for p in (PACKAGE / "core").glob("*.py"))
    code = (
        f"import sys, mjrft, mjrft.app.demos, {', '.join(modules)}; "
        "mjrft.core.engine.library(); mjrft.core.engine.layout(); "
        "bad = [m for m in ('mujoco', 'rerun', 'matplotlib', 'dm_control') if m in sys.modules]; "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_the_field_and_the_public_calls_run_without_scipy():
    """scipy is only a test dependency (dm-control brings it too): the field, its Python face
    and the public calls run without it."""
    script = """
import sys
sys.modules["scipy"] = None  # any import of scipy fails
import mujoco, numpy as np, mjrft
from mjrft.app import demos
m = mjrft.load_model(sys.argv[1])
d = mujoco.MjData(m)
mujoco.mj_resetDataKeyframe(m, d, 0)
f = mjrft.GranularField(m)
for _ in range(1500):  # falls, then rests: the treatment's stick and slip paths run
    mujoco.mj_step(m, d)
b = m.body("sphere").id
assert abs(f.wrench_of(d)[b, 2] / (m.body_mass[b] * 9.81) - 1) < 1e-6, f.wrench_of(d)[b]
assert f.stats_of(d)["stuck"] > 0
assert demos.ellipsoid_pitch(n_triangles=300).force[:, 2].max() > 0
print("ok")
"""
    model = Path(__file__).resolve().parents[1] / "models" / "sphere_drop.xml"
    out = subprocess.run([sys.executable, "-c", script, str(model)], capture_output=True,
                         text=True, timeout=600)  # fmt: skip
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stdout + out.stderr
