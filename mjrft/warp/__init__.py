"""The granular field on MuJoCo Warp: every world's RFT wrenches in a few kernel launches.

``WarpField(mjm)`` takes the engine's element tables of the MJCF's scene
(``mjrft.field.plugin.setup``: the same meshing, culling bounds, material and region as
``mjrft.load_model`` gives the C++ engine) from a plain compiled model (MuJoCo Warp runs no C
plugins, so ``mjm`` is compiled without the engine), keeps them on the Warp device, and each
forward pass computes, for every world of an ``mjw.Data``, the wrench on every tagged body from
that world's ``xpos``, ``xmat``, ``cvel`` and ``subtree_com``; it writes them into
``xfrc_applied`` (user part kept, per component, as the engine does) so load cells see them,
with the engine's low-speed treatment (free bodies, bodies in mechanisms) and, if the scene's
ground deforms, one deforming height grid per world. ``field.install()`` makes it MuJoCo Warp's
passive callback, so ``mjw.step`` (and a CUDA graph
of it) includes the field. What it supports and how it differs from the CPU engine: docs/gpu.md.

Optional: needs ``pip install "mjrft[gpu]"`` (warp-lang, mujoco-warp). Runs on Warp's CPU
device too, which is how the tests check it against the engine on the CPU.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

import mujoco

try:
    import mujoco_warp
    import warp
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(
        "mjrft.warp needs warp-lang and mujoco-warp: pip install 'mjrft[gpu]'"
    ) from exc


def _check_versions() -> None:
    """MuJoCo Warp's release must match mujoco's major.minor (it reads MjModel's layout)."""
    try:
        mjw_version = version("mujoco-warp")
    except PackageNotFoundError:  # pragma: no cover
        return
    want = ".".join(mujoco.__version__.split(".")[:2])
    have = ".".join(mjw_version.split(".")[:2])
    if want != have:
        raise ImportError(
            f"mjrft.warp: mujoco-warp {mjw_version} does not match mujoco {mujoco.__version__}; "
            f"install mujoco-warp=={want}.* (pip install 'mujoco-warp~={want}.0')"
        )


_check_versions()

from mjrft.warp.field import UnsupportedScene, WarpField, element_forces  # noqa: E402
from mjrft.warp.hexapod import HexapodVecEnv  # noqa: E402

__all__ = [
    "HexapodVecEnv",
    "UnsupportedScene",
    "WarpField",
    "element_forces",
    "mujoco_warp",
    "warp",
]
