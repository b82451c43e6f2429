"""The wheel rig (models/wheel_rig.xml) at a set slip: drawbar pull, wheel torque and sinkage.

``run(slip, ...)`` drives the wheel at ``omega`` and holds the carriage at v = (1 - slip) omega r,
then averages the load cells over the second half of each pass along the track (the first half
is the wheel's start: sinking in from rest and reaching its steady sinkage). With
``passes=2`` the carriage returns to the start after the first pass and the wheel runs again in
its own rut (the ground keeps its state only when deformation is on, ``deform_cell > 0``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from mjrft.field.granular_field import GranularField
from mjrft.field.plugin import load_model

MODEL = Path(__file__).resolve().parents[2] / "models" / "wheel_rig.xml"
#: Wheel radius [m] (geom "wheel" of models/wheel_rig.xml).
RADIUS = 0.05
#: Default wheel angular speed [rad/s]: rim speed 0.1 m/s, quasi-static (v^2/(g r) = 0.02).
OMEGA = 2.0


@dataclass(frozen=True)
class Pass:
    """Means over the second half of one pass along the track (world frame, SI units).

    drawbar_pull: the sand's net forward (+x) force on the wheel [N]; torque: the torque that
    turns the wheel about its axle (+y) [N m]; sinkage: depth of the rim's lowest point below
    the initial surface [m]; x0, x1: the carriage positions the means cover [m].
    """

    drawbar_pull: float
    torque: float
    sinkage: float
    x0: float
    x1: float


def run(
    slip: float,
    *,
    deform_cell: float = 0.0,
    length: float = 0.2,
    omega: float = OMEGA,
    passes: int = 1,
    n_triangles: int | None = None,
    model_path: Path = MODEL,
) -> list[Pass]:
    """Run the wheel rig at ``slip`` = 1 - v/(omega r) for ``passes`` passes of ``length`` [m].

    deform_cell: the deforming ground's cell [m] (0: the pristine surface at every step).
    Returns one ``Pass`` per pass.
    """
    if passes < 1 or length <= 0.0:
        raise ValueError(f"passes {passes!r} and length {length!r} [m] must be positive")
    model, _, data = rig(slip, deform_cell=deform_cell, omega=omega, n_triangles=n_triangles,
                         model_path=model_path)  # fmt: skip
    duration = length / data.ctrl[0]
    out = []
    for _ in range(passes):
        start = data.time
        data.qpos[:] = model.key("start").qpos  # the ground (in data.plugin_state) stays
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        out.append(_one_pass(model, data, start, duration))
    return out


def rig(
    slip: float,
    *,
    deform_cell: float = 0.0,
    omega: float = OMEGA,
    n_triangles: int | None = None,
    model_path: Path = MODEL,
) -> tuple[mujoco.MjModel, GranularField, mujoco.MjData]:
    """The rig's model, field and data at its start, its servos set to ``slip`` and ``omega``
    [rad/s] (deform_cell [m]: the deforming ground's cell, 0 for the pristine surface;
    n_triangles: the wheel's triangle count, None for the model's)."""
    if not -1.0 < slip < 1.0:
        raise ValueError(f"slip {slip!r}: must lie in (-1, 1) (the carriage must move forward)")
    model = load_model(str(model_path), deform_cell=deform_cell, n_triangles=n_triangles)
    field = GranularField(model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("start").id)
    data.ctrl[:] = ((1.0 - slip) * omega * RADIUS, omega)
    return model, field, data


def _one_pass(model, data, start: float, duration: float) -> Pass:
    """Step one pass; the means over its second half."""
    fx, tau, z, xs = [], [], [], []
    force, torque = data.sensor("axle_force").data, data.sensor("wheel_torque").data
    while data.time - start < duration:
        mujoco.mj_step(model, data)
        if data.time - start >= 0.5 * duration:
            fx.append(force[0])
            tau.append(torque[0])
            z.append(data.qpos[1])
            xs.append(data.qpos[0])
    # The carriage exerts on the hub minus the sand's net pull (steady motion, site axes = world).
    return Pass(-float(np.mean(fx)), float(np.mean(tau)), RADIUS - float(np.mean(z)), xs[0], xs[-1])
