"""Shared pieces of the granular environments: the Environment, a Task base, model lookup.

Conventions of every environment here: SI units; world frame z up, free surface of the medium at
z = ``field.surface_z`` (depth = surface_z - z); observations are ordered dicts of float64
arrays; actions are one bounded float64 vector.
"""

from __future__ import annotations

import collections
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from dm_control.rl import control
from dm_control.suite import base

from .physics import GranularPhysics

#: Work floor W0 [J] added to the work of a control step in depth-per-work rewards, so a step
#: with (almost) no work (e.g. everything at rest) gives a bounded reward.
WORK_FLOOR = 1e-4


def models_dir() -> Path:
    """The rig models: the repository's models/ folder (installed as ``mjrft.models``)."""
    try:
        import mjrft.models

        return Path(mjrft.models.__file__).parent
    except ImportError:  # a checkout that was never installed
        return Path(__file__).resolve().parents[1] / "models"


def resolve_random(random: Any = None, seed: int | None = None) -> np.random.RandomState:
    """A RandomState from ``random`` (int, RandomState or None) or its alias ``seed``."""
    if random is not None and seed is not None:
        raise ValueError("give either random or seed, not both")
    r = seed if random is None else random
    return r if isinstance(r, np.random.RandomState) else np.random.RandomState(r)


class GranularEnvironment(control.Environment):
    """``control.Environment`` whose ``close()`` frees the physics' MuJoCo data.

    Substeps: ``physics.step(n_sub_steps)`` per control step; the field acts in every one.
    """

    @property
    def n_sub_steps(self) -> int:
        """Physics steps per control step."""
        return self._n_sub_steps

    def close(self) -> None:
        """Free the physics' MuJoCo data; the environment is unusable after."""
        if hasattr(self._physics, "_data"):
            self._physics.free()
        self._closed = True

    def _check_open(self, what: str) -> None:
        if getattr(self, "_closed", False):
            raise RuntimeError(f"{what}() on a closed environment: load a new one (envs.load)")

    def reset(self):
        """Start an episode (dm_control's reset); RuntimeError after close()."""
        self._check_open("reset")
        return super().reset()

    def step(self, action):
        """One control step (dm_control's step): the action must match ``action_spec()``'s
        shape; ValueError naming the expected and given shapes otherwise, RuntimeError after
        close()."""
        self._check_open("step")
        spec = self.action_spec()
        a = np.asarray(action, dtype=np.float64)
        if a.shape != spec.shape:
            raise ValueError(
                f"action has shape {a.shape}, expected {spec.shape} "
                f"({spec.name or 'action_spec()'})"
            )
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action {a.tolist()} is not finite")
        return super().step(a)


def make_environment(
    physics: GranularPhysics,
    task: base.Task,
    *,
    time_limit: float,
    control_timestep: float,
) -> GranularEnvironment:
    """A GranularEnvironment with an integer number of substeps per control step."""
    dt = physics.model.opt.timestep
    n_sub = round(control_timestep / dt)
    if n_sub < 1 or abs(n_sub * dt - control_timestep) > 1e-9 * max(1.0, control_timestep):
        raise ValueError(
            f"control_timestep {control_timestep} s is not a positive multiple of the physics "
            f"timestep {dt} s"
        )
    return GranularEnvironment(physics, task, time_limit=time_limit, n_sub_steps=n_sub)


class DepthPerWorkTask(base.Task):
    """Base of the burrowing tasks: reward = depth gained per unit of actuator work.

    Per control step: ``reward = (d1 - d0) / (W + WORK_FLOOR)`` [m/J], with d the depth [m] of
    :meth:`depth` at the end/start of the step and W the work [J] of all actuators over its
    substeps, ``sum |actuator_force * actuator_velocity| * dt`` (GranularPhysics). Negative when
    the body rises. Subclasses implement ``depth``, ``_observation`` and the episode setup.
    """

    def __init__(self, random: Any = None) -> None:
        super().__init__(random=random)
        self._depth = 0.0
        self._reward = 0.0
        self.last_work = 0.0  #: work of the last control step [J]
        self.total_work = 0.0  #: work since the episode start [J]
        self.start_depth = 0.0  #: depth at the episode start [m]

    def depth(self, physics: GranularPhysics) -> float:
        """Depth [m] whose gain is rewarded."""
        raise NotImplementedError

    def _observation(self, physics: GranularPhysics) -> collections.OrderedDict:
        raise NotImplementedError

    def _start_episode(self, physics: GranularPhysics) -> None:
        physics.take_work()
        self._depth = self.start_depth = self.depth(physics)
        self._reward = 0.0
        self.last_work = self.total_work = 0.0

    def after_step(self, physics: GranularPhysics) -> None:
        work, _ = physics.take_work()
        self.last_work = float(work.sum())
        self.total_work += self.last_work
        depth = self.depth(physics)
        self._reward = (depth - self._depth) / (self.last_work + WORK_FLOOR)
        self._depth = depth

    def get_reward(self, physics: GranularPhysics) -> float:
        return self._reward

    def get_observation(self, physics: GranularPhysics) -> collections.OrderedDict:
        return self._observation(physics)


def lowest_clearance(physics: GranularPhysics) -> float:
    """Smallest height [m] of an intruding surface-triangle centroid above the free surface
    under it (vertical; negative when submerged; current kinematics)."""
    data = physics.data.ptr
    surface = physics.field.surface
    low = np.inf
    for be in physics.field.bodies:
        rot = data.xmat[be.body].reshape(3, 3)
        x, y, z = (data.xpos[be.body, i] + be.centroids @ rot[i] for i in range(3))
        low = min(low, float((z - surface.height(x, y)).min()))
    return low


def forward_kinematics(physics: GranularPhysics) -> None:
    """``mj_kinematics`` on the physics' data (positions only; no forces, no callbacks)."""
    mujoco.mj_kinematics(physics.model.ptr, physics.data.ptr)
