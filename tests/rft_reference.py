"""A slow, plainly written per-element RFT, transcribed from docs/design.md section 2 step by step.

Deliberately different from the kernel: explicit angles via atan2, explicit Fourier sums, plain
Python floats and loops. Used only to check the fast kernel.
"""

from __future__ import annotations

import math

import numpy as np

from mjrft.core.law import LEADING_SLACK
from mjrft.core.material import HARMONICS, Material


def _norm(v):
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def _alphas(material: Material, beta: float, gamma: float) -> tuple[float, float, float]:
    if material.fourier is None:
        b, g = np.array([beta]), np.array([gamma])
        ax = float(material.alpha_x_fn(b, g)[0])
        az = float(material.alpha_z_fn(b, g)[0])
    else:
        co = material.fourier
        az = ax = 0.0
        for k, (m, n) in enumerate(HARMONICS):
            phase = 2 * m * beta + n * gamma
            az += co.a[k] * math.cos(phase) + co.b[k] * math.sin(phase)
            ax += co.c[k] * math.cos(phase) + co.d[k] * math.sin(phase)
    if material.alpha_y_fn is not None:
        ay = float(material.alpha_y_fn(np.array([beta]))[0])
    else:
        ay = material.alpha_y0
    return ax, ay, az


def reference_forces(pos, normal, area, vel, material: Material, surface_z=0.0) -> np.ndarray:
    out = np.zeros((len(area), 3))
    for i in range(len(area)):
        p, v = [float(x) for x in pos[i]], [float(x) for x in vel[i]]
        ln = _norm(normal[i])
        n = [float(x) / ln for x in normal[i]]
        depth = surface_z - p[2]
        speed = _norm(v)
        if depth <= 0 or speed == 0:
            continue
        vh = [x / speed for x in v]
        # Leading iff n . v^ > LEADING_SLACK (docs/design.md 2.1): zero up to rounding is not.
        if n[0] * vh[0] + n[1] * vh[1] + n[2] * vh[2] <= LEADING_SLACK:
            continue
        # e2: horizontal projection of n, or of v^ for a nearly horizontal plate, or world x.
        if abs(n[2]) >= 1 - 1e-3:
            h = [vh[0], vh[1]]
        else:
            h = [n[0], n[1]]
        lh = math.hypot(h[0], h[1])
        e2 = [1.0, 0.0, 0.0] if lh == 0 else [h[0] / lh, h[1] / lh, 0.0]
        e1 = [e2[1], -e2[0], 0.0]  # e2 x z
        d1 = vh[0] * e1[0] + vh[1] * e1[1]
        v1 = [d1 * e1[0], d1 * e1[1], 0.0]
        v23 = [vh[0] - v1[0], vh[1] - v1[1], vh[2]]
        n_e2 = n[0] * e2[0] + n[1] * e2[1]
        beta = math.atan2(n[2], n_e2) + math.pi / 2
        gamma = -math.atan2(v23[2], v23[0] * e2[0] + v23[1] * e2[1])
        ax, ay, az = _alphas(material, beta, gamma)
        vt, vn = _norm(v1), _norm(v23)
        f1 = (
            0.440850096954369
            * (math.tanh(3.62263982880971 * vt - 1.60910808139526) + math.tanh(1.60910808139526))
            / 0.832324700111401
        )
        f23 = (
            1.99392673405210
            * (
                math.atanh(1.61146827229181 * vn - 0.973746396532650)
                + math.atanh(0.973746396532650)
            )
            / 5.81083560370960
        )
        sgn = (d1 > 0) - (d1 < 0)
        s = material.zeta * depth * float(area[i])
        for k in range(3):
            zk = 1.0 if k == 2 else 0.0
            out[i, k] = s * (-f1 * ay * sgn * e1[k] - f23 * ax * e2[k] + f23 * az * zk)
    return out
