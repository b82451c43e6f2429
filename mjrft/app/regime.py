"""Whether a run stays in the quasi-static regime RFT describes: the Froude number of each body
in the medium, with a warning when it leaves that regime.

RFT's stresses grow with depth like the medium's weight over it, rho g d; moving grains out of
the way costs an inertial stress rho v^2 on top, which RFT leaves out. Their ratio over a body
of size L is the Froude number Fr = v^2 / (g L). Where it is small the quasi-static model holds
(the rigs here run at 1e-5 to 0.1); above ``FROUDE_QUASI_STATIC`` = 1 the left-out term is as
large as the modelled one, an order-of-magnitude bound rather than a measured threshold. A
sphere 1 cm across dropped from 5 cm enters at about 1 m/s: Fr = 10.
"""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np

#: Froude number above which a body in the medium has left the quasi-static regime.
FROUDE_QUASI_STATIC = 1.0
#: Simulated time between checks [s] (an impact into sand lasts tens of milliseconds).
CHECK_PERIOD_S = 0.005


def com_velocity(
    model: mujoco.MjModel, data: mujoco.MjData, ids: np.ndarray, out: np.ndarray
) -> np.ndarray:
    """Write into out (n, 3) the world-frame linear velocity [m/s] of bodies ids' centres of
    mass: cvel is (angular, linear) at the c-frame origin, the subtree CoM of the body's root
    (mj_objectVelocity's transform, vectorised); returns out."""
    cvel = data.cvel[ids]
    arm = data.xipos[ids] - data.subtree_com[model.body_rootid[ids]]
    wx, wy, wz = cvel[:, 0], cvel[:, 1], cvel[:, 2]  # omega x arm, written out (np.cross: 10 us)
    out[:, 0] = cvel[:, 3] + wy * arm[:, 2] - wz * arm[:, 1]
    out[:, 1] = cvel[:, 4] + wz * arm[:, 0] - wx * arm[:, 2]
    out[:, 2] = cvel[:, 5] + wx * arm[:, 1] - wy * arm[:, 0]
    return out


class QuasiStaticWarning(UserWarning):
    """A body in the medium moved fast enough that RFT's quasi-static model misses the
    grains' inertia (``mjrft.app.regime``)."""


class FroudeWatch:
    """Tracks Fr = v^2 / (g L) of every body the field acts on and warns, once per run, when
    one exceeds FROUDE_QUASI_STATIC.

    v: speed of the body's centre of mass [m/s] (world frame); L: the largest extent of its RFT
    mesh [m]; g = |gravity| (no check without gravity). ``max_froude``: body name -> the largest
    Fr seen while the medium acted on it.
    """

    def __init__(self, model: mujoco.MjModel, fld) -> None:
        self.model, self.fld = model, fld
        self.g = float(np.linalg.norm(model.opt.gravity))
        self.every = max(1, round(CHECK_PERIOD_S / model.opt.timestep))
        self.sizes = np.array([float(np.ptp(be.centroids, axis=0).max()) for be in fld.bodies])
        self._v = np.empty((len(fld.bodies), 3))
        self.max_froude = {be.name: 0.0 for be in fld.bodies}
        self._warned = False

    def check(self, step: int, time: float, data: mujoco.MjData, wrench: np.ndarray) -> None:
        """``observe`` every ``every`` steps."""
        if step % self.every == 0:
            self.observe(time, data, wrench)

    def observe(self, time: float, data: mujoco.MjData, wrench: np.ndarray) -> None:
        """Fr of the bodies the last pass acted on (``wrench``, (nbody, 6)); data's kinematics
        and cvel describe the state at ``time`` [s]."""
        if self.g == 0.0:
            return
        b = self.fld.body_ids
        acting = np.any(wrench[b] != 0.0, axis=1)
        if not acting.any():
            return
        v = com_velocity(self.model, data, b, self._v)
        froude = np.einsum("ij,ij->i", v, v) / (self.g * np.maximum(self.sizes, 1e-12))
        for k in np.flatnonzero(acting):
            name = self.fld.bodies[k].name
            self.max_froude[name] = max(self.max_froude[name], float(froude[k]))
            if froude[k] > FROUDE_QUASI_STATIC and not self._warned:
                self._warned = True
                speed = math.sqrt(float(v[k] @ v[k]))
                inertia = (
                    "the dynamic term (mjrft:dynamic) adds the grains' inertia at leading faces"
                    if self.fld.material.dynamic > 0.0
                    else "the grains' inertia is left out (mjrft:dynamic adds a dynamic term)"
                )
                warnings.warn(
                    f"body {name!r} moves through the medium at {speed:.3g} m/s at t = "
                    f"{time:.4g} s: Froude number v^2/(g L) = {froude[k]:.3g} (L = "
                    f"{self.sizes[k]:.3g} m) > {FROUDE_QUASI_STATIC:g}, beyond the quasi-static "
                    f"regime RFT describes: {inertia} (mjrft.app.regime; said once per run; "
                    "each body's largest is in Recording.max_froude and mjrft run's run.json)",
                    QuasiStaticWarning,
                    stacklevel=3,
                )
