"""mjrft: granular Resistive Force Theory for MuJoCo.

The physics core (materials, kernel, geometry, rigid-body evaluation) imports no mujoco;
``mjrft.GranularField`` (the MuJoCo field) is loaded on first use.
"""

from typing import Any

from mjrft.elements import ElementSet
from mjrft.material import LI_GENERIC, PRESETS, FourierCoefficients, Material
from mjrft.rft import element_forces
from mjrft.units import N_PER_CM3

__all__ = [
    "LI_GENERIC",
    "N_PER_CM3",
    "PRESETS",
    "ElementSet",
    "FourierCoefficients",
    "GranularField",
    "Material",
    "element_forces",
]


def __getattr__(name: str) -> Any:
    if name == "GranularField":
        from mjrft.field import GranularField

        return GranularField
    raise AttributeError(f"module 'mjrft' has no attribute {name!r}")
