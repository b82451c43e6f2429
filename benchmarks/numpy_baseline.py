"""A straightforward vectorised NumPy implementation of the element law: the speed baseline.

The law is docs/design.md section 2.

Written the obvious way (angles via arctan2, the Fourier phases' cosines and sines evaluated
directly, np.cross for the frame), as a user would first write it. benchmarks/kernel.py times the
engine's C++ kernel against it and checks both agree.
"""

from __future__ import annotations

import numpy as np

from mjrft.core.material import HARMONICS, Material


def baseline_forces(pos, normal, area, vel, material: Material, surface_z=0.0) -> np.ndarray:
    """Element forces [N], world frame, for (n, 3) pos/normal/vel and (n,) area (SI)."""
    n = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    speed = np.linalg.norm(vel, axis=1)
    v = np.divide(vel, speed[:, None], out=np.zeros_like(vel), where=speed[:, None] > 0)
    depth = surface_z - pos[:, 2]
    act = (depth > 0) & (speed > 0) & (np.sum(n * v, axis=1) > 0)
    z = np.array([0.0, 0.0, 1.0])
    flat = np.abs(n[:, 2]) >= 1 - 1e-3
    h = np.where(flat[:, None], v, n) * [1.0, 1.0, 0.0]
    hn = np.linalg.norm(h, axis=1)
    e2 = np.where(hn[:, None] > 0, h / np.where(hn > 0, hn, 1)[:, None], [1.0, 0.0, 0.0])
    e1 = np.cross(e2, z)
    v1 = np.sum(v * e1, axis=1)[:, None] * e1
    v23 = v - v1
    beta = np.arctan2(n[:, 2], np.sum(n * e2, axis=1)) + np.pi / 2
    gamma = -np.arctan2(v23[:, 2], np.sum(v23 * e2, axis=1))
    co = material.fourier
    az = np.zeros(len(n))
    ax = np.zeros(len(n))
    for k, (m, nn) in enumerate(HARMONICS):
        phase = 2 * m * beta + nn * gamma
        az += co.a[k] * np.cos(phase) + co.b[k] * np.sin(phase)
        ax += co.c[k] * np.cos(phase) + co.d[k] * np.sin(phase)
    vt = np.linalg.norm(v1, axis=1)
    vn = np.linalg.norm(v23, axis=1)
    f1 = (
        0.440850096954369
        * (np.tanh(3.62263982880971 * vt - 1.60910808139526) + np.tanh(1.60910808139526))
        / 0.832324700111401
    )
    f23 = (
        1.99392673405210
        * (np.arctanh(1.61146827229181 * vn - 0.973746396532650) + np.arctanh(0.973746396532650))
        / 5.81083560370960
    )
    s = (material.zeta * depth * area)[:, None]
    f = s * (
        -(f1 * material.alpha_y0 * np.sign(np.sum(v * e1, axis=1)))[:, None] * e1
        - (f23 * ax)[:, None] * e2
        + (f23 * az)[:, None] * z
    )
    return np.where(act[:, None], f, 0.0)
