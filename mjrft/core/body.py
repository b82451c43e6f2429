"""Rigid-body RFT: element sets in a body frame + pose + twist -> force and moment (world frame).

This generalises what the authors' MATLAB ``rft_3D_body`` does: any element set, any pose, any
point about which moments are taken, and whole prescribed trajectories at once, with the
kernel's surface quadrature (``mjrft.core.quadrature``). Media given by coefficients run on the
C++ engine's kernel (``mjrft.core.engine``; one thread, no BLAS, whatever the machine's load);
for media given as Python callables the kernel places the quadrature points and the NumPy
evaluation gives their forces.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mjrft.core import engine, surface
from mjrft.core.elements import ElementSet
from mjrft.core.material import Material, as_material
from mjrft.core.rft import quadrature_forces


class Wrench(NamedTuple):
    """Force [N] and moment [N m], world frame; moment about the stated point."""

    force: np.ndarray
    moment: np.ndarray


def quat_to_mat(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) from quaternions (..., 4) in MuJoCo order (w, x, y, z).

    Quaternions are normalised first; a zero quaternion raises ValueError.
    """
    q = np.asarray(quat, dtype=np.float64)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(~(norm > 0.0)) or not np.all(np.isfinite(q)):
        raise ValueError("quaternion must be finite and non-zero (MuJoCo order w, x, y, z)")
    w, x, y, z = np.moveaxis(q / norm, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def as_rotation(rotation: np.ndarray, batch_shape: tuple[int, ...] = ()) -> np.ndarray:
    """(…, 3, 3) rotation matrices from matrices or (w, x, y, z) quaternions."""
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape == (*batch_shape, 4):
        return quat_to_mat(r)
    if r.shape == (*batch_shape, 3, 3):
        if not np.all(np.isfinite(r)):
            raise ValueError("rotation matrix must be finite")
        return r
    raise ValueError(
        f"rotation has shape {r.shape}; expected {(*batch_shape, 3, 3)} (matrix, body -> world) "
        f"or {(*batch_shape, 4)} (quaternion w, x, y, z)"
    )


def _vec(name: str, x: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"{name} has shape {a.shape}, expected {shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {a}")
    return a


def body_wrench(
    elements: ElementSet,
    position: np.ndarray,
    rotation: np.ndarray,
    lin_vel: np.ndarray,
    ang_vel: np.ndarray,
    material: Material | str,
    *,
    point: np.ndarray | None = None,
    surface_z: float = 0.0,
) -> Wrench:
    """Total RFT force and moment on a rigid body.

    Args:
      elements: the body's surface elements in the body frame.
      position: (3,) body-frame origin, world frame [m].
      rotation: (3, 3) body -> world matrix, or (4,) quaternion (w, x, y, z).
      lin_vel: (3,) velocity of the body-frame origin, world frame [m/s].
      ang_vel: (3,) angular velocity, world frame [rad/s].
      material: the medium, or a preset's name (``mjrft.PRESETS``).
      point: (3,) world point about which the moment is taken [m]; default the body origin.
      surface_z: free-surface height [m].
    Returns:
      Wrench(force (3,) [N], moment (3,) [N m]), world frame.
    """
    position = _vec("position", position, (3,))
    rotation = as_rotation(rotation)
    lin_vel = _vec("lin_vel", lin_vel, (3,))
    ang_vel = _vec("ang_vel", ang_vel, (3,))
    c = position if point is None else _vec("point", point, (3,))
    material = as_material(material)
    w = _trajectory(
        elements, position[None], rotation[None], lin_vel[None], ang_vel[None], c[None],
        material, surface_z,
    )  # fmt: skip
    return Wrench(w[0, :3], w[0, 3:])


def _trajectory(elements, positions, rotations, lin_vels, ang_vels, points, material,
                surface_z) -> np.ndarray:  # fmt: skip
    """(T, 6) wrenches from the kernel's quadrature (one thread, no BLAS); inputs checked.
    Media given by Python callables: the kernel places the quadrature points, NumPy evaluates."""
    reach, patch = elements.quadrature
    cent, norm, area = elements.centroids, elements.normals, elements.areas
    if material.compiled:
        return engine.trajectory(
            cent, norm, area, reach, patch, material.kernel_coefficients, material.alpha_y0,
            material.zeta, float(surface_z), rotations, positions, lin_vels, ang_vels, points,
        )  # fmt: skip
    out = np.zeros((len(positions), 6))
    flat = surface.flat(float(surface_z))
    n = len(area)
    no_coef = np.zeros(engine.N_COMBINED)  # read by no force model: rows only
    for t in range(len(positions)):
        rows = np.zeros((n, engine.ROW))
        engine.body_wrench(
            cent, norm, area, reach, patch, no_coef, 0.0, 0.0, flat.prm, flat.grid, None, None,
            rotations[t], positions[t], ang_vels[t], lin_vels[t], positions[t], points[t], rows,
        )  # fmt: skip
        f = quadrature_forces(rows, material)
        out[t, :3] = f.sum(axis=0)
        out[t, 3:] = np.cross(rows[:, :3] - points[t], f).sum(axis=0)
    return out


def trajectory_wrenches(
    elements: ElementSet,
    positions: np.ndarray,
    rotations: np.ndarray,
    lin_vels: np.ndarray,
    ang_vels: np.ndarray,
    material: Material | str,
    *,
    points: np.ndarray | None = None,
    surface_z: float = 0.0,
) -> Wrench:
    """RFT force and moment time series along a prescribed rigid-body trajectory.

    Args:
      elements: surface elements in the body frame.
      positions: (T, 3) body-frame origin over time, world frame [m].
      rotations: (T, 3, 3) body -> world matrices or (T, 4) quaternions (w, x, y, z).
      lin_vels: (T, 3) velocity of the body-frame origin, world frame [m/s].
      ang_vels: (T, 3) angular velocity, world frame [rad/s].
      material: the medium, or a preset's name (``mjrft.PRESETS``).
      points: (T, 3) world points for the moments [m]; default the body origin at each time.
      surface_z: free-surface height [m].
    Returns:
      Wrench(force (T, 3) [N], moment (T, 3) [N m]), world frame.
    """
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"positions has shape {positions.shape}, expected (T, 3)")
    t = positions.shape[0]
    positions = _vec("positions", positions, (t, 3))
    rotations = as_rotation(rotations, (t,))
    lin_vels = _vec("lin_vels", lin_vels, (t, 3))
    ang_vels = _vec("ang_vels", ang_vels, (t, 3))
    points = positions if points is None else _vec("points", points, (t, 3))
    if not np.isfinite(float(surface_z)):
        raise ValueError(f"surface_z must be finite, got {surface_z}")
    material = as_material(material)
    w = _trajectory(elements, positions, rotations, lin_vels, ang_vels, points, material, surface_z)
    return Wrench(w[:, :3], w[:, 3:])
