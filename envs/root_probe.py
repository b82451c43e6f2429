"""``root_probe``: the circumnutating root-tip paraboloid pushed into the medium.

The physics is ``models/root_circumnutation.xml`` (the Treers et al. 2021 root tip: paraboloid,
34.6 mm long, 10 mm base radius, pivot on its axis 35.8 mm above the apex) with three changes:

* the fixed 10 deg tilt becomes a hinge ``tilt`` about the yaw frame's y axis through the pivot,
  driven by a position servo (kp = 10 N m/rad, kv = 0.2 N m s/rad, armature 1e-3 kg m^2: a
  0.01 N m RFT moment moves it 1 mrad), so the tip angle is an action;
* the descent velocity servo becomes a constant **thrust** force (``thrust``, default 0.5 N)
  pushing the carriage down, with the carriage and yaw frame counterweighted (``gravcomp``) so
  the load on the tip is the thrust plus the tip's own weight (0.056 N): how deep the probe gets
  is up to the medium and the motion;
* the start pose has the apex touching the surface (pivot 35.8 mm x cos(tilt) above it).

The yaw drive stays the rig's intvelocity servo (ctrl = yaw rate). Circumnutation (yawing a
tilted tip) turns part of the tip's motion horizontal, where granular resistance to sinking is
lower: the reward says whether the depth gained pays for the extra work.

Action (2,), float64:
  [0] tip angle (tilt from vertical) [rad] in [0, 0.5] (0-28.6 deg);
  [1] yaw rate [rad/s] in [-1, 1] (the paper's circumnutation: 15 deg/s = 0.262 rad/s).

Observations (ordered dict, float64):
  depth (1,): depth of the tip (apex) below the surface [m];
  descent_rate (1,): downward velocity of the pivot [m/s];
  tilt (1,) [rad], tilt_rate (1,) [rad/s];
  yaw (2,): cos, sin of the yaw angle; yaw_rate (1,) [rad/s];
  load_cell_force (3,) [N], load_cell_torque (3,) [N m]: the rig's load cell (root frame).

Reward: depth gained by the tip over the control step per unit of actuator work [m/J]
(``envs.base.DepthPerWorkTask``: thrust, yaw and tilt work, |force x velocity| per substep).

Episode: tilt 10 deg (the paper's), yaw uniform in [0, 2 pi), at rest; ``time_limit`` (default
20 s); no termination otherwise.
"""

from __future__ import annotations

import collections
import math
from typing import Any

import mujoco
import numpy as np
from dm_env import specs

from mjrft import Material, SceneOptions, load_model
from mjrft.app.demos import ROOT_PIVOT_ABOVE_APEX

from .base import DepthPerWorkTask, make_environment, models_dir, resolve_random
from .physics import GranularPhysics

TIP_LENGTH = ROOT_PIVOT_ABOVE_APEX  # m, pivot to apex (models/root_circumnutation.xml)
MAX_TILT = 0.5  # rad
MAX_YAW_RATE = 1.0  # rad/s
START_TILT = math.radians(10.0)  # rad, the paper's tilt
DEFAULT_THRUST = 0.5  # N
#: Physics step [s]: the rig's 1 ms halved in cost (its servos and the RFT contact are stable at
#: 2 ms).
DEFAULT_TIMESTEP = 0.002
TILT_KP, TILT_KV, TILT_ARMATURE = 10.0, 0.2, 1e-3  # N m/rad, N m s/rad, kg m^2
#: Viscous friction of the carriage's linear bearing [N s/m] (damps RFT's stick-slip chatter).
SLIDE_DAMPING = 20.0
THRUST_ARMATURE = 0.05  # kg, reflected inertia of the thrust drive
COUNTERWEIGHTED = ("carriage", "yaw_frame")


def build_spec(timestep: float = DEFAULT_TIMESTEP) -> mujoco.MjSpec:
    """The root rig with a tilt servo and a thrust-driven carriage (see module docstring), as an
    MjSpec without the engine (``build_model`` adds it); timestep [s].

    Actuators, in order: thrust (motor on "descent", ctrl [N], positive down), yaw
    (intvelocity, ctrl [rad/s]), tilt (position, ctrl [rad]). qpos: descent, yaw, tilt.
    """
    spec = mujoco.MjSpec.from_file(str(models_dir() / "root_circumnutation.xml"))
    spec.option.timestep = timestep
    root = spec.body("root")
    root.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
    root.quat = [1.0, 0.0, 0.0, 0.0]
    root.add_joint(
        name="tilt", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0], armature=TILT_ARMATURE
    )
    thrust = spec.actuator("descent")
    thrust.set_to_motor()
    thrust.name = "thrust"
    thrust.gear = [-1.0, 0, 0, 0, 0, 0]
    thrust.ctrlrange = [0.0, 10.0]
    thrust.actlimited = 0
    spec.actuator("yaw").ctrlrange = [-MAX_YAW_RATE, MAX_YAW_RATE]
    tilt = spec.add_actuator(name="tilt", target="tilt", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    tilt.set_to_position(kp=TILT_KP, kv=TILT_KV)
    tilt.ctrlrange = [0.0, MAX_TILT]
    tilt.ctrllimited = 1
    slide = spec.joint("descent")
    slide.armature = THRUST_ARMATURE
    slide.damping = [SLIDE_DAMPING, 0.0, 0.0]
    for name in COUNTERWEIGHTED:
        spec.body(name).gravcomp = 1.0
    key = spec.key("start")
    key.qpos = [TIP_LENGTH * math.cos(START_TILT), 0.0, START_TILT]
    key.qvel = [0.0, 0.0, 0.0]
    key.ctrl = [DEFAULT_THRUST, 0.0, START_TILT]
    key.act = [0.0]
    return spec


def build_model(
    timestep: float = DEFAULT_TIMESTEP, options: SceneOptions | None = None
) -> mujoco.MjModel:
    """The rig of ``build_spec`` compiled with the granular engine (``mjrft.load_model``);
    options: SceneOptions on top of the MJCF's (material, ...)."""
    return load_model(build_spec(timestep), options)


class RootProbe(DepthPerWorkTask):
    """Task: drive the root tip deep under a constant thrust for little actuator work."""

    def __init__(self, random: Any = None, thrust: float = DEFAULT_THRUST) -> None:
        super().__init__(random=random)
        if not (math.isfinite(thrust) and 0.0 <= thrust <= 10.0):
            raise ValueError(f"thrust must be in [0, 10] N, got {thrust}")
        self.thrust = float(thrust)

    def initialize_episode(self, physics: GranularPhysics) -> None:
        physics.reset(0)
        yaw = self.random.uniform(0.0, 2 * math.pi)
        d = physics.named.data
        d.qpos["yaw"] = yaw
        d.act["yaw"] = yaw  # the yaw servo's integrated target
        d.ctrl["thrust"] = self.thrust
        physics.forward()
        self._start_episode(physics)

    def action_spec(self, physics: GranularPhysics) -> specs.BoundedArray:
        return specs.BoundedArray(
            (2,), np.float64, [0.0, -MAX_YAW_RATE], [MAX_TILT, MAX_YAW_RATE], name="tilt,yaw_rate"
        )

    def before_step(self, action: np.ndarray, physics: GranularPhysics) -> None:
        tilt, yaw_rate = np.asarray(action, dtype=np.float64)
        ctrl = physics.named.data.ctrl
        ctrl["thrust"] = self.thrust
        ctrl["yaw"] = yaw_rate
        ctrl["tilt"] = tilt

    def depth(self, physics: GranularPhysics) -> float:
        return physics.field.surface_z - float(physics.named.data.sensordata["tip_pos"][2])

    def _observation(self, physics: GranularPhysics) -> collections.OrderedDict:
        d = physics.named.data
        yaw = float(d.qpos["yaw"][0])
        return collections.OrderedDict(
            depth=np.array([self.depth(physics)]),
            descent_rate=np.array([-float(d.qvel["descent"][0])]),
            tilt=d.qpos["tilt"].copy(),
            tilt_rate=d.qvel["tilt"].copy(),
            yaw=np.array([math.cos(yaw), math.sin(yaw)]),
            yaw_rate=d.qvel["yaw"].copy(),
            load_cell_force=d.sensordata["load_cell_force"].copy(),
            load_cell_torque=d.sensordata["load_cell_torque"].copy(),
        )


def make(
    *,
    random: Any = None,
    seed: int | None = None,
    time_limit: float = 20.0,
    control_timestep: float = 0.02,
    timestep: float = DEFAULT_TIMESTEP,
    thrust: float = DEFAULT_THRUST,
    material: Material | str | None = None,
    n_triangles: int | None = None,
):
    """The ``root_probe`` environment.

    Args:
      random / seed: task randomness (int seed or RandomState).
      time_limit: episode length [s]. control_timestep: [s], a multiple of ``timestep``.
      timestep: physics step [s] (default ``DEFAULT_TIMESTEP``).
      thrust: constant downward push on the carriage [N], in [0, 10].
      material: medium override (preset name or Material; default the rig's glass beads).
      n_triangles: ignored for this mesh intruder (kept for a uniform signature).
    """
    options = SceneOptions(material=material, n_triangles=n_triangles)
    physics = GranularPhysics.from_mjmodel(build_model(timestep, options))
    task = RootProbe(random=resolve_random(random, seed), thrust=thrust)
    return make_environment(physics, task, time_limit=time_limit, control_timestep=control_timestep)
