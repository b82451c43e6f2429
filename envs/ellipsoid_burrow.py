"""``ellipsoid_burrow``: the mole-crab ellipsoid rig pushed into the medium while it pitches.

The physics is ``models/ellipsoid_pitch.xml`` (the Treers et al. 2021 ellipsoid, 36.1 x 19.2 mm,
pitching +-9 deg through a crank-rocker four-bar on a vertical carriage) with one change that
makes burrowing a control problem: the carriage's vertical drive is a **force** (thrust) motor
instead of a velocity servo, and the rig's counterweight balances the carriage and linkage
(``gravcomp`` on carriage, crank, coupler and pitch body), so the ellipsoid goes as deep as the
thrust, its own weight (0.07 N) and the granular resistance let it. The pitch amplitude is fixed
by the linkage (+-9 deg); the crank speed sets the pitch frequency (one crank turn = one pitch
cycle). Whether pitching lowers the vertical resistance enough to pay for its work is what the
reward measures (the paper: pitching lowers the vertical force transiently).

Action (2,), float64:
  [0] crank speed [rad/s] in [0, 4 pi] (pitch frequency 0-2 Hz); drives the rig's intvelocity
      crank servo (phase-locked, act = integrated target angle);
  [1] thrust [N] in [0, max_thrust] (default 5 N), pushing the carriage down.

Observations (ordered dict, float64):
  depth (1,): depth of the ellipsoid centre (pitch pivot) below the surface [m];
  descent_rate (1,): its downward velocity [m/s];
  pitch (1,) [rad], pitch_rate (1,) [rad/s]: rotation about +y (models/ellipsoid_pitch.xml);
  crank_phase (2,): cos, sin of the crank angle;
  load_cell_force (3,) [N], load_cell_torque (3,) [N m]: the rig's load cell (force exerted by
      the stalk on the ellipsoid, ellipsoid frame; force-stage sensors of the last substep).

Reward: depth gained by the centre over the control step per unit of actuator work, [m/J]
(``envs.base.DepthPerWorkTask``; crank and thrust work, |force x velocity| summed per substep).

Episode: starts at rest from the rig's keyframe (pitch 0, ellipsoid tip 0.05 mm below the
surface) raised by a random 0-5 mm; ``time_limit`` (default 20 s); no termination otherwise.
"""

from __future__ import annotations

import collections
import math
from typing import Any

import mujoco
import numpy as np
from dm_env import specs

from mjrft import Material, SceneOptions, load_model

from .base import DepthPerWorkTask, make_environment, models_dir, resolve_random
from .physics import GranularPhysics

MAX_CRANK_SPEED = 4 * math.pi  # rad/s: 2 Hz pitch
DEFAULT_MAX_THRUST = 5.0  # N
#: Reflected inertia of the thrust drive on the carriage slide [kg] (a light linear drive;
#: the rig's velocity servo had 1 kg).
THRUST_ARMATURE = 0.05
#: Viscous friction of the carriage's linear bearing [N s/m].
SLIDE_DAMPING = 20.0
START_RAISE = 0.005  # m: the start pose is raised by U(0, START_RAISE)
COUNTERWEIGHTED = ("carriage", "crank", "coupler", "pitch_body")


def build_spec(max_thrust: float = DEFAULT_MAX_THRUST) -> mujoco.MjSpec:
    """The ellipsoid rig with a thrust-driven, counterweighted carriage (see module docstring),
    as an MjSpec without the engine (``build_model`` adds it)."""
    spec = mujoco.MjSpec.from_file(str(models_dir() / "ellipsoid_pitch.xml"))
    crank = spec.actuator("crank")
    crank.ctrlrange = [0.0, MAX_CRANK_SPEED]
    thrust = spec.actuator("descent")
    thrust.set_to_motor()
    thrust.name = "thrust"
    thrust.gear = [-1.0, 0, 0, 0, 0, 0]  # positive ctrl pushes down (joint axis is +z)
    thrust.ctrlrange = [0.0, float(max_thrust)]
    thrust.actlimited = 0
    slide = spec.joint("descent")
    slide.armature = THRUST_ARMATURE
    slide.damping = [SLIDE_DAMPING, 0.0, 0.0]
    for name in COUNTERWEIGHTED:
        spec.body(name).gravcomp = 1.0
    key = spec.key("start")
    key.qvel = [0.0] * 4
    key.ctrl = [0.0, 0.0]
    key.act = [0.0]
    return spec


def build_model(
    max_thrust: float = DEFAULT_MAX_THRUST, options: SceneOptions | None = None
) -> mujoco.MjModel:
    """The rig of ``build_spec`` compiled with the granular engine (``mjrft.load_model``);
    options: SceneOptions on top of the MJCF's (material, n_triangles, ...)."""
    return load_model(build_spec(max_thrust), options)


class EllipsoidBurrow(DepthPerWorkTask):
    """Task: burrow the pitching ellipsoid deep for little actuator work."""

    def initialize_episode(self, physics: GranularPhysics) -> None:
        physics.reset(0)
        physics.named.data.qpos["descent"] = self.random.uniform(0.0, START_RAISE)
        physics.forward()
        self._start_episode(physics)

    def action_spec(self, physics: GranularPhysics) -> specs.BoundedArray:
        lo, hi = physics.model.actuator_ctrlrange.T
        return specs.BoundedArray((2,), np.float64, lo.copy(), hi.copy(), name="crank_speed,thrust")

    def before_step(self, action: np.ndarray, physics: GranularPhysics) -> None:
        physics.set_control(np.asarray(action, dtype=np.float64))

    def depth(self, physics: GranularPhysics) -> float:
        return physics.field.surface_z - float(physics.named.data.sensordata["pivot_pos"][2])

    def _observation(self, physics: GranularPhysics) -> collections.OrderedDict:
        d = physics.named.data
        crank = float(d.qpos["crank"][0])
        return collections.OrderedDict(
            depth=np.array([self.depth(physics)]),
            descent_rate=np.array([-float(d.qvel["descent"][0])]),
            pitch=d.qpos["pitch"].copy(),
            pitch_rate=d.qvel["pitch"].copy(),
            crank_phase=np.array([math.cos(crank), math.sin(crank)]),
            load_cell_force=d.sensordata["load_cell_force"].copy(),
            load_cell_torque=d.sensordata["load_cell_torque"].copy(),
        )


def make(
    *,
    random: Any = None,
    seed: int | None = None,
    time_limit: float = 20.0,
    control_timestep: float = 0.02,
    max_thrust: float = DEFAULT_MAX_THRUST,
    material: Material | str | None = None,
    n_triangles: int | None = None,
):
    """The ``ellipsoid_burrow`` environment.

    Args:
      random / seed: task randomness (int seed or RandomState).
      time_limit: episode length [s]. control_timestep: [s], a multiple of the 1 ms timestep.
      max_thrust: upper bound of the thrust action [N].
      material: medium override (preset name or Material; default the rig's glass beads).
      n_triangles: RFT triangles on the ellipsoid (default the rig's 4000).
    """
    options = SceneOptions(material=material, n_triangles=n_triangles)
    physics = GranularPhysics.from_mjmodel(build_model(max_thrust, options))
    task = EllipsoidBurrow(random=resolve_random(random, seed))
    return make_environment(physics, task, time_limit=time_limit, control_timestep=control_timestep)
