"""mjrft: granular Resistive Force Theory for MuJoCo.

Layers (each a subpackage; imports go downwards only):

* ``mjrft.core``: the physics (media, the RFT element law and its kernels, surface elements,
  rigid bodies); imports no mujoco;
* ``mjrft.field``: the binding to a compiled MjModel (``GranularField``, batches);
* ``mjrft.app``: simulation runs, the CLI, reports, rerun recordings, demos;
* ``mjrft.envs``: dm_control environments (and their gymnasium registration);
* ``mjrft.warp``: the field on MuJoCo Warp for many worlds (optional extra ``gpu``) and the
  hexapod task as a vector environment (its constants from ``mjrft.envs.hexapod_sand``).

``mjrft.GranularField`` is loaded on first use, so ``import mjrft`` does not import mujoco.
"""

from importlib.metadata import PackageNotFoundError, version
from typing import Any

from mjrft.core.elements import ElementSet
from mjrft.core.material import LI_GENERIC, PRESETS, FourierCoefficients, Material
from mjrft.core.rft import element_forces
from mjrft.core.units import N_PER_CM3

try:
    __version__ = version("mjrft")
except PackageNotFoundError:  # imported from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = [
    "LI_GENERIC",
    "N_PER_CM3",
    "PRESETS",
    "ElementSet",
    "FourierCoefficients",
    "GranularField",
    "Material",
    "SceneOptions",
    "SinkingWarning",
    "__version__",
    "add_granular",
    "add_sensors",
    "element_forces",
    "load_model",
]


def __getattr__(name: str) -> Any:
    if name == "GranularField":
        from mjrft.field.granular_field import GranularField

        return GranularField
    if name in ("load_model", "add_granular", "add_sensors"):
        from mjrft.field import plugin

        return getattr(plugin, name)
    if name == "SinkingWarning":
        from mjrft.core.engine import SinkingWarning

        return SinkingWarning
    if name == "SceneOptions":
        from mjrft.field.options import SceneOptions

        return SceneOptions
    raise AttributeError(f"module 'mjrft' has no attribute {name!r}")
