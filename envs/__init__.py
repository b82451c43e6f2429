"""dm_control environments on the mjrft granular force field (installed as ``mjrft.envs``).

::

    from mjrft import envs
    env = envs.load("hexapod_sand", seed=0)          # a dm_control.rl.control.Environment
    ts = env.reset()
    ts = env.step([1.0, 3.14159])                     # 1 Hz alternating tripod
    env.close()                                       # frees the MuJoCo data

``envs.NAMES`` lists the environments; each module's docstring gives its actions, observations
and reward (SI units). The granular RFT field acts inside every physics substep: the model of
each environment's physics (an ``envs.physics.GranularPhysics``) carries the engine.
``envs.gym_wrapper.GymnasiumEnv`` wraps any of them as a ``gymnasium.Env`` (optional
dependency); with gymnasium installed, importing this package registers them as
``mjrft/<name>-v0``: ``gymnasium.make("mjrft/hexapod_sand-v0")`` after ``import mjrft.envs``, or
``gymnasium.make("mjrft.envs:mjrft/hexapod_sand-v0")`` without.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from . import ellipsoid_burrow, go2_sand, hexapod_sand, root_probe
from .base import GranularEnvironment
from .physics import GranularPhysics

_MAKERS: dict[str, Callable[..., GranularEnvironment]] = {
    "ellipsoid_burrow": ellipsoid_burrow.make,
    "root_probe": root_probe.make,
    "hexapod_sand": hexapod_sand.make,
    "go2_sand": go2_sand.make,
}

#: Names accepted by :func:`load`.
NAMES: tuple[str, ...] = tuple(_MAKERS)

#: gymnasium ids registered for NAMES (when gymnasium is installed).
GYMNASIUM_IDS: dict[str, str] = {name: f"mjrft/{name}-v0" for name in NAMES}

__all__ = ["GYMNASIUM_IDS", "NAMES", "GranularEnvironment", "GranularPhysics", "load"]


def load(name: str, **kwargs: Any) -> GranularEnvironment:
    """Build the environment ``name`` (one of :data:`NAMES`).

    Keyword arguments go to the environment's ``make`` (all accept ``seed`` or ``random``,
    ``time_limit`` [s], ``control_timestep`` [s], ``material`` and ``n_triangles``; see each
    module). Raises ValueError for an unknown name.
    """
    try:
        maker = _MAKERS[name]
    except KeyError:
        raise ValueError(f"unknown environment {name!r}; valid: {', '.join(NAMES)}") from None
    return maker(**kwargs)


def _register_gymnasium() -> None:
    """Register every environment with gymnasium's registry, if gymnasium is installed."""
    try:
        import gymnasium
    except ImportError:
        return
    for name, env_id in GYMNASIUM_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id, entry_point=f"{__name__}.gym_wrapper:GymnasiumEnv", kwargs={"env": name}
            )


_register_gymnasium()
