"""A gymnasium view of the dm_control environments (needs the optional ``gymnasium`` package).

::

    from mjrft.envs.gym_wrapper import GymnasiumEnv
    env = GymnasiumEnv("hexapod_sand", control_timestep=0.02)   # or GymnasiumEnv(dm_env_instance)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

Observations are the dm_control observation dict flattened in its key order into one float64
vector (``GymnasiumEnv.observation_keys`` / ``observation_slices`` say which entries are which).
The action space is the dm_control action spec as a ``Box``. The time limit ends an episode as
``truncated``; a dm_control termination with discount 0 as ``terminated``.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from . import load


class GymnasiumEnv(gymnasium.Env):
    """``gymnasium.Env`` around a dm_control environment of this package.

    Args:
      env: an environment from ``envs.load`` or an environment name (``envs.NAMES``).
      render_mode: None or "rgb_array" (dm_control's offscreen renderer; needs MUJOCO_GL).
      **kwargs: passed to ``envs.load`` when ``env`` is a name.
    """

    #: A class attribute, gymnasium's convention. render_fps: one frame per control step, here
    #: the default 0.02 s step's rate; each instance's metadata has its environment's.
    metadata = {"render_modes": ["rgb_array"], "render_fps": 50.0}  # noqa: RUF012

    def __init__(self, env: Any, render_mode: str | None = None, **kwargs: Any) -> None:
        self._env = load(env, **kwargs) if isinstance(env, str) else env
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        fps = round(1.0 / self._env.control_timestep(), 9)
        self.metadata = {**type(self).metadata, "render_fps": fps}
        aspec = self._env.action_spec()
        self.action_space = spaces.Box(
            low=np.broadcast_to(aspec.minimum, aspec.shape).astype(np.float64),
            high=np.broadcast_to(aspec.maximum, aspec.shape).astype(np.float64),
            dtype=np.float64,
        )
        ospec = self._env.observation_spec()
        self.observation_keys: tuple[str, ...] = tuple(ospec)
        self.observation_slices: dict[str, slice] = {}
        start = 0
        for key, spec in ospec.items():
            size = int(np.prod(spec.shape))
            self.observation_slices[key] = slice(start, start + size)
            start += size
        self.observation_space = spaces.Box(-np.inf, np.inf, (start,), dtype=np.float64)

    @property
    def dm_env(self) -> Any:
        """The wrapped dm_control environment."""
        return self._env

    def _flatten(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        return np.concatenate(
            [np.asarray(observation[k], dtype=np.float64).ravel() for k in self.observation_keys]
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; ``seed`` reseeds the task's RandomState."""
        super().reset(seed=seed)
        if seed is not None:
            self._env.task.random.seed(seed)
        ts = self._env.reset()
        return self._flatten(ts.observation), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control step: (observation, reward, terminated, truncated, info)."""
        ts = self._env.step(np.asarray(action, dtype=np.float64))
        last = ts.last()
        terminated = bool(last and ts.discount == 0.0)
        truncated = bool(last and not terminated)
        info = {"discount": float(ts.discount)}
        return self._flatten(ts.observation), float(ts.reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """An RGB frame of the scene if ``render_mode == "rgb_array"``."""
        if self.render_mode == "rgb_array":
            return self._env.physics.render(height=240, width=320)
        return None

    def close(self) -> None:
        """Close the wrapped environment (frees its MuJoCo data)."""
        self._env.close()
