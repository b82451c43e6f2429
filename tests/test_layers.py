"""The layers: mjrft.core imports no mujoco, and no module imports from a layer above its own."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mjrft"
# Each layer may import from itself and the layers listed (mjrft's own modules only).
ALLOWED = {
    "core": {"core"},
    "field": {"core", "field"},
    "app": {"core", "field", "app"},
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
            if target in ("envs", "body", "geometry", "batch", "viz", "simulate"):
                bad.append(f"{path.name} imports the public alias {name}; use the layer's module")
    assert not bad, bad


def test_core_imports_no_mujoco_rerun_or_plotting():
    modules = sorted(f"mjrft.core.{p.stem}" for p in (PACKAGE / "core").glob("*.py"))
    code = (
        f"import sys, mjrft, mjrft.app.demos, {', '.join(modules)}; "
        "bad = [m for m in ('mujoco', 'rerun', 'matplotlib', 'dm_control') if m in sys.modules]; "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
