"""``HexapodVecEnv``: the hexapod walking task for many worlds on MuJoCo Warp, tensors in and out.

The task of ``mjrft.envs.hexapod_sand`` (its gait control, observation and reward, documented
there) without dm_control: ``reset`` and ``step`` take and return Warp arrays on the device,
(nworld, ...) each, and everything between two control steps (the gait controller, the
physics substeps with the field, the observations and the reward) runs as kernels there, so
``step`` can be captured in a CUDA graph. Episodes of all worlds start and end together (the
time limit); ``reset`` draws each world's random gait phase on the host.
"""

from __future__ import annotations

import math

import mujoco
import mujoco_warp as mjw
import numpy as np
import warp as wp

from mjrft.envs.hexapod_sand import (
    HIP_QPOS,
    HIP_QVEL,
    MAX_FREQUENCY,
    MAX_PHASE_RATE,
    TRIPOD_B,
    build_spec,
)
from mjrft.warp import surface
from mjrft.warp.field import WarpField
from mjrft.warp.surface import Surface

#: Observation columns, in order: (name, size), as ``hexapod_sand``'s ordered dict.
OBSERVATIONS = (
    ("height", 1), ("up", 3), ("heading", 2), ("velocity", 3), ("angular_velocity", 3),
    ("leg_phase", 12), ("leg_rate", 6),
)  # fmt: skip
OBS_SIZE = sum(n for _, n in OBSERVATIONS)
_TWO_PI = 2.0 * math.pi
_vec6 = wp.types.vector(6, dtype=float)
_B_MASK = wp.constant(_vec6(*[1.0 if j in TRIPOD_B else 0.0 for j in range(6)]))  # tripod B
_HIP_Q = wp.constant(HIP_QPOS.start)
_HIP_V = wp.constant(HIP_QVEL.start)


@wp.func
def _wrap(a: float) -> float:
    """a wrapped to [-pi, pi)."""
    return a - wp.floor((a + wp.pi) / (2.0 * wp.pi)) * (2.0 * wp.pi)


@wp.kernel
def gait_kernel(
    control_dt: float, max_frequency: float, max_phase_rate: float,
    action: wp.array2d(dtype=float), act: wp.array2d(dtype=float),
    ctrl: wp.array2d(dtype=float),
):  # fmt: skip
    """ctrl[w, j] = 2 pi f + the re-phasing of tripod B (``HexapodWalk.before_step``)."""
    w, j = wp.tid()
    freq = wp.clamp(action[w, 0], 0.0, max_frequency)
    target = _B_MASK[j] * action[w, 1]
    error = _wrap(target - (act[w, j] - act[w, 0]))
    limit = max_phase_rate * control_dt
    ctrl[w, j] = 2.0 * wp.pi * freq + wp.clamp(error, -limit, limit) / control_dt


@wp.kernel
def observe_kernel(
    control_dt: float, sf: Surface,
    qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float),
    xmat: wp.array2d(dtype=wp.mat33),
    x_prev: wp.array(dtype=float), obs: wp.array2d(dtype=float), reward: wp.array(dtype=float),
):  # fmt: skip
    """Observations (OBSERVATIONS) and reward (world-x speed over the control step) per world."""
    w = wp.tid()
    r = xmat[w, 1]  # torso, world <- torso
    ground = surface.height(sf, wp.float64(qpos[w, 0]), wp.float64(qpos[w, 1]))
    obs[w, 0] = qpos[w, 2] - float(ground)  # above the surface under the torso, vertically
    for i in range(3):
        obs[w, 1 + i] = r[2, i]
    h = wp.max(1e-12, wp.sqrt(r[0, 0] * r[0, 0] + r[1, 0] * r[1, 0]))
    obs[w, 4] = r[0, 0] / h
    obs[w, 5] = r[1, 0] / h
    v = wp.transpose(r) * wp.vec3(qvel[w, 0], qvel[w, 1], qvel[w, 2])
    for i in range(3):
        obs[w, 6 + i] = v[i]
        obs[w, 9 + i] = qvel[w, 3 + i]  # free joint: already in the torso frame
    for j in range(6):
        a = qpos[w, _HIP_Q + j]
        obs[w, 12 + 2 * j] = wp.cos(a)
        obs[w, 13 + 2 * j] = wp.sin(a)
        obs[w, 24 + j] = qvel[w, _HIP_V + j]
    x = qpos[w, 0]
    reward[w] = (x - x_prev[w]) / control_dt
    x_prev[w] = x


class HexapodVecEnv:
    """The hexapod walking on the medium, nworld worlds at once on one Warp device.

    Args:
      nworld: number of worlds. device: Warp device (default Warp's).
      control_timestep [s]: a multiple of the model's 1 ms timestep. time_limit [s].
      seed: the random gait phases of the first ``reset``.
      material, n_triangles, slope: as ``mjrft.envs.hexapod_sand.make`` (slope: (slope,
        downhill azimuth) [deg], a tilted plane; no deforming ground).
    Action: (nworld, 2) gait frequency [Hz] in [0, 4] and tripod B's phase offset [rad].
    Observation: (nworld, OBS_SIZE) float32, the columns of OBSERVATIONS (frames and units as
    ``hexapod_sand``). Reward: (nworld,) forward speed [m/s]. low_speed: the field's low-speed
    treatment (default the MJCF's, "stick": legs standing in the medium are held as by the
    engine; docs/gpu.md).
    """

    def __init__(self, nworld: int, *, device: str | None = None, control_timestep: float = 0.02,
                 time_limit: float = 20.0, seed: int = 0, material=None,
                 n_triangles: int | None = None,
                 slope: tuple[float, float] | None = None,
                 low_speed: str | None = None) -> None:  # fmt: skip
        #: The hexapod compiled without the engine plugin (MuJoCo Warp runs no C plugins; the
        #: field is the WarpField).
        self.mjm = build_spec(slope=slope).compile()
        dt = float(self.mjm.opt.timestep)
        self.substeps = round(control_timestep / dt)
        if self.substeps < 1 or abs(self.substeps * dt - control_timestep) > 1e-9:
            raise ValueError(
                f"control_timestep = {control_timestep!r} s: expected a whole multiple of the "
                f"model's timestep {dt} s"
            )
        self.nworld = int(nworld)
        self.device = wp.get_device(device)
        self.control_timestep = float(control_timestep)
        self.time_limit = float(time_limit)
        self.field = WarpField(
            self.mjm, material, n_triangles=n_triangles, low_speed=low_speed, device=device
        )
        self._rng = np.random.default_rng(seed)
        self._mjd = mujoco.MjData(self.mjm)
        with wp.ScopedDevice(self.device):
            self.m = mjw.put_model(self.mjm)
            self.d = mjw.put_data(self.mjm, self._mjd, nworld=self.nworld)
            self.obs = wp.zeros((self.nworld, OBS_SIZE), dtype=float)
            self.reward = wp.zeros(self.nworld, dtype=float)
            self._x_prev = wp.zeros(self.nworld, dtype=float)
        self.field.prepare(self.d)
        self.field.install(self.m)
        self._steps = 0

    # ------------------------------------------------------------------ episodes
    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """(nworld, nq) qpos and (nworld, na) act: the keyframe turned by a random gait phase,
        lowered until the lowest element touches the surface (``HexapodWalk``)."""
        m, d = self.mjm, self._mjd
        qpos = np.empty((self.nworld, m.nq))
        act = np.empty((self.nworld, m.na))
        ground = self.field.setup.scene.surface.height
        for w in range(self.nworld):
            mujoco.mj_resetDataKeyframe(m, d, 0)
            d.qpos[HIP_QPOS] += self._rng.uniform(0.0, _TWO_PI)
            mujoco.mj_kinematics(m, d)
            low = np.inf
            for be in self.field.setup.bodies:
                rot = d.xmat[be.body].reshape(3, 3)
                x, y, z = (d.xpos[be.body, i] + be.centroids @ rot[i] for i in range(3))
                low = min(low, float((z - ground(x, y)).min()))
            d.qpos[2] -= low
            qpos[w] = d.qpos
            act[w] = d.qpos[HIP_QPOS]  # servo references = current angles: at rest
        return qpos, act

    def reset(self, seed: int | None = None) -> wp.array:
        """Start every world's episode; returns the observations (nworld, OBS_SIZE)."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        qpos, act = self._initial_state()
        d = self.d
        d.qpos.assign(qpos.astype(np.float32))
        d.act.assign(act.astype(np.float32))
        d.qvel.zero_()
        d.ctrl.zero_()
        d.time.zero_()
        self.field.reset(d)  # the treatment's records of the previous episode
        mjw.forward(self.m, d)
        self._x_prev.assign(qpos[:, 0].astype(np.float32))
        self._observe()
        self._steps = 0
        return self.obs

    def _observe(self) -> None:
        wp.launch(
            observe_kernel, dim=self.nworld,
            inputs=[self.control_timestep, self.field.surface, self.d.qpos, self.d.qvel,
                    self.d.xmat],
            outputs=[self._x_prev, self.obs, self.reward], device=self.device,
        )  # fmt: skip

    def advance(self, action: wp.array) -> None:
        """One control step of every world, kernels only (capturable in a CUDA graph): the gait
        controller from action (nworld, 2), the physics substeps with the field, then
        ``obs`` and ``reward`` are updated in place."""
        wp.launch(
            gait_kernel, dim=(self.nworld, 6),
            inputs=[self.control_timestep, MAX_FREQUENCY, MAX_PHASE_RATE, action, self.d.act],
            outputs=[self.d.ctrl], device=self.device,
        )  # fmt: skip
        for _ in range(self.substeps):
            mjw.step(self.m, self.d)
        self._observe()

    def step(self, action) -> tuple[wp.array, wp.array, bool]:
        """One control step of every world: (observations, rewards, episode over); action
        (nworld, 2), a Warp array on the device or anything NumPy reads."""
        if not isinstance(action, wp.array):
            action = wp.array(np.asarray(action, dtype=np.float32), dtype=float, device=self.device)
        if action.shape != (self.nworld, 2):
            raise ValueError(f"action: expected shape ({self.nworld}, 2), got {action.shape}")
        self.advance(action)
        self._steps += 1
        done = self._steps * self.control_timestep >= self.time_limit - 1e-9
        return self.obs, self.reward, done
