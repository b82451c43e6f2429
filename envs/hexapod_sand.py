"""``hexapod_sand``: a C-leg hexapod walking on a granular medium (``models/hexapod_sand.xml``).

Six half-ring legs on position servos (intvelocity: ctrl = reference angular velocity, act =
reference angle) turn continuously in an alternating tripod gait, like RHex and the robot of
Li, Zhang & Goldman, Science 339:1408 (2013). The robot touches nothing but the medium: RFT on
the legs and the body box (belly drag) carries and propels it, in every physics substep.

Action (2,), float64:
  [0] gait frequency f [Hz] in [0, 4]: every hip reference turns at 2 pi f;
  [1] phase offset [rad] in [0, 2 pi]: tripod B's (RF, LM, RR) reference angle minus tripod
      A's (LF, RM, LR), modulo 2 pi (pi = alternating tripod, 0 = all legs together). Offset
      changes are applied smoothly: the B references turn faster or slower by at most
      ``MAX_PHASE_RATE`` until they reach the new offset.

Observations (ordered dict, float64):
  height (1,): torso (hip axes) height above the surface under it (vertical) [m]; on deforming
    ground, above the ground as it is now;
  up (3,): world up in the torso frame; heading (2,): cos, sin of the torso yaw;
  velocity (3,) [m/s], angular_velocity (3,) [rad/s]: torso, in the torso frame;
  leg_phase (12,): cos, sin of the six hip angles (LF LM LR RF RM RR);
  leg_rate (6,): hip angular velocities [rad/s].

Reward: forward speed, the torso's world-x displacement over the control step divided by its
duration [m/s].

Episode: the keyframe pose (tripod A down, B up) turned by a random gait phase in [0, 2 pi), the
torso lowered or raised until its lowest RFT element touches the surface, everything at rest;
``time_limit`` (default 20 s); where the medium has a region (``mjrft:region``, as the
deforming lane), the episode also ends, with discount 0, once the torso leaves it.

``forward_speed`` measures the steady walking speed at one gait frequency; the script
``scripts/hexapod_frequency_sweep.py`` sweeps it and plots docs/hexapod_speed_vs_frequency.png.
"""

from __future__ import annotations

import collections
import math
from typing import Any

import mujoco
import numpy as np
from dm_control.suite import base
from dm_env import specs

from mjrft import Material, SceneOptions, load_model

from .base import (
    forward_kinematics,
    lowest_clearance,
    make_environment,
    models_dir,
    resolve_random,
)
from .physics import GranularPhysics

LEGS = ("LF", "LM", "LR", "RF", "RM", "RR")  # actuator / hip order in the MJCF
TRIPOD_A = (0, 2, 4)  # LF, LR, RM
TRIPOD_B = (1, 3, 5)  # LM, RF, RR
MAX_FREQUENCY = 4.0  # Hz
MAX_PHASE_RATE = 2 * math.pi  # rad/s: fastest re-phasing of tripod B (extra hip speed)
HIP_QPOS = slice(7, 13)  # hip angles in qpos (after the free joint)
HIP_QVEL = slice(6, 12)
#: The medium's region when the ground deforms [m, world]: (xmin, ymin, zmin, xmax, ymax, zmax),
#: the walk's +x lane for 3.3 m (20 s at the 1 Hz gait's 15 cm/s, the default episode), 40 cm
#: wide (the robot spans 23 cm), 15 cm deep (the legs reach 9 cm below the hips). An episode
#: ends when the torso leaves it (HexapodWalk.get_termination).
DEFORM_REGION = (-0.3, -0.2, -0.15, 3.3, 0.2, 0.1)


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % (2 * math.pi) - math.pi


class HexapodWalk(base.Task):
    """Task: walk forward (+x) on the medium by choosing gait frequency and tripod phasing."""

    def __init__(self, random: Any = None, control_timestep: float = 0.02) -> None:
        super().__init__(random=random)
        self._control_timestep = float(control_timestep)
        self._x = 0.0
        self._reward = 0.0

    def initialize_episode(self, physics: GranularPhysics) -> None:
        physics.reset(0)
        d = physics.data
        phase = self.random.uniform(0.0, 2 * math.pi)
        hips = d.qpos[HIP_QPOS] + phase
        d.qpos[HIP_QPOS] = hips
        d.act[:] = hips  # servo references = current angles: at rest, no lag
        d.qvel[:] = 0.0
        d.ctrl[:] = 0.0
        forward_kinematics(physics)
        d.qpos[2] -= lowest_clearance(physics)  # the lowest foot point on the surface
        physics.forward()
        self._x = float(d.qpos[0])
        self._reward = 0.0

    def action_spec(self, physics: GranularPhysics) -> specs.BoundedArray:
        return specs.BoundedArray(
            (2,), np.float64, [0.0, 0.0], [MAX_FREQUENCY, 2 * math.pi], name="frequency,offset"
        )

    def before_step(self, action: np.ndarray, physics: GranularPhysics) -> None:
        freq, offset = np.asarray(action, dtype=np.float64)
        freq = float(np.clip(freq, 0.0, MAX_FREQUENCY))
        omega = 2 * math.pi * freq
        act = physics.data.act
        ref = act[TRIPOD_A[0]]  # the gait clock: LF's reference angle
        target = np.zeros(6)
        target[list(TRIPOD_B)] = offset
        error = _wrap(target - (act - ref))
        limit = MAX_PHASE_RATE * self._control_timestep
        correction = np.clip(error, -limit, limit) / self._control_timestep
        physics.data.ctrl[:] = omega + correction

    def after_step(self, physics: GranularPhysics) -> None:
        x = float(physics.data.qpos[0])
        self._reward = (x - self._x) / self._control_timestep
        self._x = x

    def get_reward(self, physics: GranularPhysics) -> float:
        return self._reward

    def get_termination(self, physics: GranularPhysics) -> float | None:
        """0 (the episode ends, no future reward) once the torso's (x, y) leaves the medium's
        region (``mjrft:region``, as on the deforming lane): beyond it there is no medium and
        the robot would fall; else None (the episode goes on)."""
        region = physics.field.region
        if region is None:
            return None
        x, y = physics.data.qpos[0], physics.data.qpos[1]
        inside = region[0, 0] <= x <= region[1, 0] and region[0, 1] <= y <= region[1, 1]
        return None if inside else 0.0

    def get_observation(self, physics: GranularPhysics) -> collections.OrderedDict:
        d = physics.data
        rot = d.xmat[1].reshape(3, 3)  # torso (body 1), world <- torso
        hips = d.qpos[HIP_QPOS]
        fld = physics.field
        # The surface under the torso: the deforming ground as it is now, else the fixed one.
        ground = fld.soil(physics.data.ptr).height_at if fld.deforms else fld.surface.height
        return collections.OrderedDict(
            height=d.qpos[2] - ground(d.qpos[0:1], d.qpos[1:2]),
            up=rot[2].copy(),
            heading=np.array([rot[0, 0], rot[1, 0]]) / max(1e-12, math.hypot(rot[0, 0], rot[1, 0])),
            velocity=rot.T @ d.qvel[0:3],
            angular_velocity=d.qvel[3:6].copy(),  # free joint: already in the torso frame
            leg_phase=np.stack([np.cos(hips), np.sin(hips)], axis=1).ravel(),
            leg_rate=d.qvel[HIP_QVEL].copy(),
        )


def build_spec(
    *,
    slope: tuple[float, float] | None = None,
    region: tuple[float, float, float, float, float, float] | None = None,
) -> mujoco.MjSpec:
    """The hexapod's MJCF (``models/hexapod_sand.xml``) as an MjSpec, without the engine
    (``mjrft.load_model`` adds it).

    Args:
      slope: (slope, downhill azimuth from +x) [degrees]: a tilted plane through the origin
        (``mjrft:surface_slope``); default the flat surface.
      region: (xmin, ymin, zmin, xmax, ymax, zmax) [m, world]: the medium's box
        (``mjrft:region``, as ``DEFORM_REGION``); default unbounded.
    """
    spec = mujoco.MjSpec.from_file(str(models_dir() / "hexapod_sand.xml"))
    if slope is not None:
        spec.add_numeric(name="mjrft:surface_slope", data=[float(v) for v in slope])
    if region is not None:
        spec.add_numeric(name="mjrft:region", data=[float(v) for v in region])
    return spec


def make(
    *,
    random: Any = None,
    seed: int | None = None,
    time_limit: float = 20.0,
    control_timestep: float = 0.02,
    material: Material | str | None = None,
    n_triangles: int | None = None,
    slope: tuple[float, float] | None = None,
    deform_cell: float | None = None,
    repose: float | None = None,
    deform_every: int | None = None,
    deform_travel: float | None = None,
):
    """The ``hexapod_sand`` environment.

    Args:
      random / seed: task randomness (int seed or RandomState).
      time_limit: episode length [s]. control_timestep: [s], a multiple of the 1 ms timestep.
      material: medium override (preset name or Material); default the MJCF's glass beads
        (Li 2013 used poppy seeds: ``material="poppy_seeds_lp"``).
      n_triangles: RFT triangles on the body box (the legs are meshes with their own).
      slope: (slope, downhill azimuth from +x) [degrees]: walk on a tilted plane through the
        origin (``mjrft:surface_slope``; azimuth 0: the gait's +x is downhill, 180: uphill);
        default the flat surface.
      deform_cell: walk on ground that deforms and remembers (footprints, ruts; docs/terrain.md)
        on a grid of this cell [m] over ``DEFORM_REGION`` (on the flat surface only); each
        episode starts from pristine ground. repose: its angle of repose [deg] (default the
        material preset's). deform_every: steps between its updates (default 1), or
        deform_travel: the cells the legs travel between them (docs/terrain.md).
    """
    if deform_cell and slope is not None:
        raise ValueError("deform_cell: the deforming ground starts flat; pass slope=None")
    spec = build_spec(slope=slope, region=DEFORM_REGION if deform_cell else None)
    options = SceneOptions(
        material=material, n_triangles=n_triangles, deform_cell=deform_cell, repose=repose,
        deform_every=deform_every if deform_cell else None,
        deform_travel=deform_travel if deform_cell else None,
    )  # fmt: skip
    physics = GranularPhysics.from_mjmodel(load_model(spec, options))
    task = HexapodWalk(random=resolve_random(random, seed), control_timestep=control_timestep)
    return make_environment(physics, task, time_limit=time_limit, control_timestep=control_timestep)


def forward_speed(
    frequency: float,
    *,
    env: Any = None,
    cycles: float = 3.0,
    transient: float = 1.0,
    offset: float = math.pi,
    **make_kwargs: Any,
) -> float:
    """Steady forward speed [m/s] of the alternating-tripod gait at one frequency.

    Resets ``env`` (or a new ``make(seed=0, **make_kwargs)``), walks at ``frequency`` [Hz]
    (> 0) for a transient of max(``transient`` s, one cycle), then returns the torso's world-x
    displacement over the next ``cycles`` gait cycles (rounded to whole control steps) divided by
    their duration.
    """
    if not (math.isfinite(frequency) and frequency > 0):
        raise ValueError(f"frequency must be > 0 Hz, got {frequency}")
    own = env is None
    if own:
        make_kwargs.setdefault("seed", 0)
        make_kwargs.setdefault("time_limit", float("inf"))
        env = make(**make_kwargs)
    try:
        dt = env.control_timestep()
        env.reset()
        action = np.array([frequency, offset])
        for _ in range(max(1, round(max(transient, 1.0 / frequency) / dt))):
            env.step(action)
        n = max(1, round(cycles / frequency / dt))
        x0 = float(env.physics.data.qpos[0])
        for _ in range(n):
            env.step(action)
        return (float(env.physics.data.qpos[0]) - x0) / (n * dt)
    finally:
        if own:
            env.close()
