"""The MuJoCo binding: the granular field on a compiled MjModel.

``scene`` reads the MJCF's ``<custom>`` description; the field builds static tables once and
runs one compiled pass per forward pass (installed in MuJoCo's passive callback, explicitly, or
over a ``mujoco.batch.Batch``).
"""

from mjrft.field.granular_field import GranularField
from mjrft.field.scene import SceneError

__all__ = ["GranularField", "SceneError"]
