"""``go2_sand``: a Unitree Go2-class quadruped on dry granular media (``models/go2_sand.xml``).

A 15.2 kg quadruped (the rigid-body model of MuJoCo Menagerie's Go2: masses, inertias, joints,
position servos) with no floor: RFT on its feet and calves carries it, in every physics substep.
The medium is Li, Zhang & Goldman 2013's generic coefficients at zeta = 2 N/cm^3
(docs/choosing_zeta.md); ``material=`` changes it.

Action (12,), float64: joint target offsets from the home pose [rad], order FR FL RR RL, per
  leg hip (abduction) in [-0.5, 0.5], thigh in [-0.6, 0.6], calf (knee) in [-0.8, 0.8]
  (``ACTION_RANGE``); the servos' ctrl = HOME_CTRL + action, inside every servo's range.
  Positive thigh offsets swing the foot backwards, negative calf offsets fold the knee.

Observations (ordered dict, float64; world frame z up):
  height (1,): torso (base) height above the surface under it [m];
  up (3,): world up in the torso frame; heading (2,): cos, sin of the torso yaw;
  velocity (3,) [m/s], angular_velocity (3,) [rad/s]: torso, in the torso frame;
  joint_angle (12,) [rad], joint_rate (12,) [rad/s]: the 12 hinges, in the action's order;
  foot_force (12,): per leg, the RFT force on its lower leg (calf capsules and foot), world
    frame [N] (``foot_readings``), rows FR FL RR RL flattened;
  foot_sinkage (4,): per foot, how deep its lowest point is below the surface [m], 0 above it.

Reward: forward speed, the torso's horizontal displacement over the control step along its
heading at the step's start, divided by the step's duration [m/s].

Episode: the ``home`` keyframe (the robot at rest on the medium with the home ctrl held) turned
to a random yaw in [0, 2 pi); ``time_limit`` (default 20 s). It ends with discount 0 at the
control step whose torso has tipped over: world up at more than ``FALL_TILT`` from the torso's up.

``trot_offsets`` / ``trot_ctrl``: an open-loop trot (diagonal pairs FR+RL and FL+RR half a cycle
apart) as actions or as servo ctrl; ``mjrft run go2_sand --ctrl mjrft.envs.go2_sand:trot_ctrl``
runs it from the command line.
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

from .base import make_environment, models_dir, resolve_random
from .physics import GranularPhysics

LEGS = ("FR", "FL", "RR", "RL")  # actuator, qpos and observation order
#: The servos' home targets [rad], per leg hip, thigh, calf (Menagerie's "home" pose).
HOME_CTRL = np.tile([0.0, 0.9, -1.8], 4)
#: Largest |action| per joint [rad]: offsets from HOME_CTRL inside every servo's control range
#: (hip, thigh, calf per leg; the knee's reaches 0.02 rad from its range's folded end).
ACTION_RANGE = np.tile([0.5, 0.6, 0.8], 4)
#: The episode ends once the torso's up axis is tilted more than this from world up [rad].
FALL_TILT = math.radians(60.0)
JOINT_QPOS = slice(7, 19)
JOINT_QVEL = slice(6, 18)
#: The open-loop trot's defaults: frequency [Hz], thigh swing amplitude [rad], knee lift [rad],
#: ramp-in time [s]. Measured: 0.96 m forward in 6 s, torso tilt at most 10.8 degrees, each
#: foot out of the medium 14 % of the time (docs/environments.md, "The quadruped").
TROT_FREQUENCY = 1.5
TROT_THIGH = 0.25
TROT_KNEE = 0.8
TROT_RAMP = 0.5
#: Phase of each leg in the trot [rad] (FR FL RR RL): the diagonal pairs FR+RL and FL+RR.
TROT_PHASE = np.array([0.0, math.pi, math.pi, 0.0])


#: The intruder geoms of a lower leg, each read by an mjrft.sensor named "rft:<leg>_<part>".
LOWER_LEG = ("foot", "calf_upper", "calf_lower")


def foot_readings(physics: GranularPhysics) -> tuple[np.ndarray, np.ndarray]:
    """Per-foot RFT force and sinkage of the physics' latest forward pass, from the model's
    ``mjrft.sensor`` sensors (MuJoCo sensor data: docs/mjcf.md, "Sensors").

    Returns:
      forces (4, 3): world frame [N], legs FR FL RR RL: the RFT force the engine applied to each
        lower leg (its foot sphere and two calf capsules, the sum of their sensors: the calf
        body's wrench).
      sinkage (4,): [m] how far the lowest point of each foot sphere is below the medium's
        surface at the foot (vertically; the deforming ground as it is now, where it deforms); 0
        for a foot above it.
    """
    data = physics.data.ptr
    forces = np.zeros((len(LEGS), 3))
    sinkage = np.zeros(len(LEGS))
    for i, leg in enumerate(LEGS):
        for part in LOWER_LEG:
            forces[i] += data.sensor(f"rft:{leg}_{part}").data[:3]
        sinkage[i] = max(0.0, data.sensor(f"rft:{leg}_foot").data[6])
    return forces, sinkage


def trot_offsets(
    t: float,
    frequency: float = TROT_FREQUENCY,
    thigh: float = TROT_THIGH,
    knee: float = TROT_KNEE,
    ramp: float = TROT_RAMP,
) -> np.ndarray:
    """(12,) joint target offsets [rad] of an open-loop trot at time t [s].

    Each leg's thigh target swings by ``thigh`` cos(2 pi f t + phase) and its knee folds by
    ``knee`` max(0, sin(2 pi f t + phase)) (lifting the foot while the thigh swings it forward);
    the diagonal pairs FR+RL and FL+RR are half a cycle apart; the amplitudes ramp in linearly
    over ``ramp`` seconds from the home pose.
    """
    theta = 2.0 * math.pi * frequency * t + TROT_PHASE
    scale = min(1.0, t / ramp) if ramp > 0.0 else 1.0
    out = np.zeros(12)
    out[1::3] = scale * thigh * np.cos(theta)
    out[2::3] = -scale * knee * np.maximum(0.0, np.sin(theta))
    return out


def trot_ctrl(t: float, data: Any = None) -> np.ndarray:
    """(12,) servo ctrl [rad] of the default trot at time t [s]: HOME_CTRL + trot_offsets(t).
    The ``ctrl(t, data)`` form of ``mjrft run --ctrl`` (data is not used)."""
    return HOME_CTRL + trot_offsets(t)


def _yaw_quat(angle: float) -> np.ndarray:
    return np.array([math.cos(angle / 2.0), 0.0, 0.0, math.sin(angle / 2.0)])


class Go2Walk(base.Task):
    """Task: walk forward (along the torso's heading) by choosing joint target offsets."""

    def __init__(self, random: Any = None, control_timestep: float = 0.02) -> None:
        super().__init__(random=random)
        self._control_timestep = float(control_timestep)
        self._start = np.zeros(3)
        self._heading = np.array([1.0, 0.0])
        self._reward = 0.0

    def initialize_episode(self, physics: GranularPhysics) -> None:
        physics.reset(0)  # the "home" keyframe: at rest on the medium, home ctrl held
        d = physics.data
        quat = np.empty(4)
        mujoco.mju_mulQuat(quat, _yaw_quat(self.random.uniform(0.0, 2 * math.pi)), d.qpos[3:7])
        d.qpos[3:7] = quat
        d.qvel[:] = 0.0
        physics.forward()
        self._remember(physics)
        self._reward = 0.0

    def _remember(self, physics: GranularPhysics) -> None:
        self._start = physics.data.qpos[0:3].copy()
        self._heading = _heading(physics.data.xmat[1].reshape(3, 3))

    def action_spec(self, physics: GranularPhysics) -> specs.BoundedArray:
        return specs.BoundedArray(
            (12,), np.float64, -ACTION_RANGE, ACTION_RANGE, name="joint offsets"
        )

    def before_step(self, action: np.ndarray, physics: GranularPhysics) -> None:
        offsets = np.clip(np.asarray(action, dtype=np.float64), -ACTION_RANGE, ACTION_RANGE)
        physics.data.ctrl[:] = HOME_CTRL + offsets
        self._remember(physics)

    def after_step(self, physics: GranularPhysics) -> None:
        moved = physics.data.qpos[0:2] - self._start[0:2]
        self._reward = float(moved @ self._heading) / self._control_timestep

    def get_reward(self, physics: GranularPhysics) -> float:
        return self._reward

    def get_termination(self, physics: GranularPhysics) -> float | None:
        """0 (the episode ends, no future reward) once the torso has tipped over by more than
        FALL_TILT; else None."""
        up_z = physics.data.xmat[1][8]  # world z of the torso's z axis
        return 0.0 if up_z < math.cos(FALL_TILT) else None

    def get_observation(self, physics: GranularPhysics) -> collections.OrderedDict:
        d = physics.data
        rot = d.xmat[1].reshape(3, 3)  # world <- torso
        fld = physics.field
        ground = fld.soil(d.ptr).height_at if fld.deforms else fld.surface.height
        forces, sinkage = foot_readings(physics)
        return collections.OrderedDict(
            height=d.qpos[2] - np.asarray(ground(d.qpos[0:1], d.qpos[1:2]), dtype=np.float64),
            up=rot[2].copy(),
            heading=_heading(rot),
            velocity=rot.T @ d.qvel[0:3],
            angular_velocity=d.qvel[3:6].copy(),  # free joint: already in the torso frame
            joint_angle=d.qpos[JOINT_QPOS].copy(),
            joint_rate=d.qvel[JOINT_QVEL].copy(),
            foot_force=forces.ravel(),
            foot_sinkage=sinkage,
        )


def _heading(rot: np.ndarray) -> np.ndarray:
    """cos, sin of the yaw of a torso with world <- torso rotation ``rot`` (3, 3)."""
    return np.array([rot[0, 0], rot[1, 0]]) / max(1e-12, math.hypot(rot[0, 0], rot[1, 0]))


def build_spec() -> mujoco.MjSpec:
    """The quadruped's MJCF (``models/go2_sand.xml``) as an MjSpec, without the engine
    (``mjrft.load_model`` adds it). The engine library is loaded first: the MJCF names its
    sensor plugin, which MuJoCo's parser must know."""
    from mjrft.field.plugin import library

    library()
    return mujoco.MjSpec.from_file(str(models_dir() / "go2_sand.xml"))


def plain_spec() -> mujoco.MjSpec:
    """The quadruped for MuJoCo alone: ``build_spec`` without mjrft's sensors and plugin
    declarations (no RFT; a floor, if wanted, is the caller's)."""
    spec = build_spec()
    for sensor in list(spec.sensors):
        if sensor.type == mujoco.mjtSensor.mjSENS_PLUGIN:
            spec.delete(sensor)
    for plugin in list(spec.plugins):
        spec.delete(plugin)
    return spec


def make(
    *,
    random: Any = None,
    seed: int | None = None,
    time_limit: float = 20.0,
    control_timestep: float = 0.02,
    material: Material | str | None = None,
    n_triangles: int | None = None,
):
    """The ``go2_sand`` environment.

    Args:
      random / seed: task randomness (int seed or RandomState): the start yaw.
      time_limit: episode length [s]. control_timestep: [s], a multiple of the 2 ms timestep.
      material: medium override (preset name or Material); default the MJCF's Li generic
        coefficients at zeta = 2 N/cm^3. The home keyframe is at rest on that medium; another
        medium settles it deeper or shallower in the first moments of an episode.
      n_triangles: RFT triangles per tagged primitive (default: the MJCF's own, 200 per foot
        sphere and 100 per calf capsule).
    """
    options = SceneOptions(material=material, n_triangles=n_triangles)
    physics = GranularPhysics.from_mjmodel(load_model(build_spec(), options))
    task = Go2Walk(random=resolve_random(random, seed), control_timestep=control_timestep)
    return make_environment(physics, task, time_limit=time_limit, control_timestep=control_timestep)
