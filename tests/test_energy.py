"""Thrown bodies gain no energy from the medium: the throws of benchmarks/energy.py that did
(a sharp-edged mesh and a capsule spinning into the medium, where the explicit step with the
pure model turned the motion within the step), each must stay within the tolerance."""

import importlib.util
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location(
    "energy_benchmark", Path(__file__).resolve().parents[1] / "benchmarks" / "energy.py"
)
energy = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(energy)

# (shape, mass [kg], dt [s], integrator, throw): each gained 3e4-1e5 x the tolerance in one step
# when the pure model was applied unguarded.
GAINED = [
    ("mesh", 5.0, 0.002, "Euler", 0),
    ("capsule", 5.0, 0.002, "implicitfast", 1),
    ("mesh", 0.5, 0.001, "implicit", 0),
    ("mesh", 0.05, 0.002, "implicitfast", 3),
    ("mesh", 0.5, 0.001, "Euler", 0),
]


@pytest.mark.parametrize("case", GAINED, ids=lambda c: "-".join(map(str, c)))
def test_a_thrown_body_gains_no_energy_from_the_medium(case):
    result = energy.throw(case)
    assert result["ratio"] <= 1.0, result
