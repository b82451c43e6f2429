"""mjrft: granular Resistive Force Theory for MuJoCo."""

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
    "Material",
    "element_forces",
]
