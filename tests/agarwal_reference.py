"""A slow, plainly written reference of Agarwal, Goldman & Kamrin's 3D-RFT (PNAS 2023), one
element at a time with numpy vectors, following the model as ``mjrft.core.agarwal`` states it.
The compiled kernel is checked against it (tests/test_agarwal.py)."""

from __future__ import annotations

import numpy as np

from mjrft.core import agarwal

# Exponents (of x1, x2, x3) of the 20 monomials, in the table's order: 1, x1, x2, x3, x1^2,
# x2^2, x3^2, x1 x2, x2 x3, x3 x1, x1^3, x2^3, x3^3, x1 x2^2, x2 x1^2, x2 x3^2, x3 x2^2,
# x3 x1^2, x1 x3^2, x1 x2 x3.
EXPONENTS = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (2, 0, 0), (0, 2, 0), (0, 0, 2),
             (1, 1, 0), (0, 1, 1), (1, 0, 1), (3, 0, 0), (0, 3, 0), (0, 0, 3), (1, 2, 0),
             (2, 1, 0), (0, 1, 2), (0, 2, 1), (2, 0, 1), (1, 0, 2), (1, 1, 1)]  # fmt: skip
Z = np.array([0.0, 0.0, 1.0])


def _horizontal(u: np.ndarray) -> np.ndarray | None:
    h = np.array([u[0], u[1], 0.0])
    n = np.linalg.norm(h)
    return h / n if n > agarwal.HORIZONTAL_EPS else None


def element_force(pos, normal, area, vel, xi_n, mu_surf, surface_z=0.0) -> np.ndarray:
    """Force [N] on one element (world frame, z up): centroid pos, outward unit normal, area
    [m^2], velocity [m/s]; zero above the surface, at rest or trailing."""
    depth = surface_z - pos[2]
    speed = np.linalg.norm(vel)
    if depth <= 0.0 or speed == 0.0 or np.dot(normal, vel) <= 0.0:
        return np.zeros(3)
    v = vel / speed
    n = np.asarray(normal, dtype=float)
    r = _horizontal(v)
    if r is None:
        r = _horizontal(n)
    if r is None:
        r = np.array([1.0, 0.0, 0.0])
    theta = np.cross(Z, r)
    a = np.arccos(np.clip(n @ Z, -1.0, 1.0))
    if n @ r >= 0.0:
        beta = -a if n @ Z >= 0.0 else np.pi - a
    else:
        beta = a if n @ Z >= 0.0 else a - np.pi
    g = np.arccos(np.clip(v @ r, -1.0, 1.0))
    gamma = g if v @ Z <= 0.0 else -g
    nh = _horizontal(n)
    psi = 0.0 if nh is None or nh @ r == 0.0 else np.arctan((nh @ theta) / (nh @ r))
    x = (np.sin(gamma), np.cos(beta),
         np.cos(psi) * np.cos(gamma) * np.sin(beta) + np.sin(gamma) * np.cos(beta))  # fmt: skip
    terms = np.array([x[0] ** e[0] * x[1] ** e[1] * x[2] ** e[2] for e in EXPONENTS])
    f1, f2, f3 = (terms @ np.array(c) for c in (agarwal.C1, agarwal.C2, agarwal.C3))
    alpha = ((f1 * np.sin(beta) * np.cos(psi) + f2 * np.cos(gamma)) * r
             + f1 * np.sin(beta) * np.sin(psi) * theta
             - (f1 * np.cos(beta) + f2 * np.sin(gamma) + f3) * Z)  # fmt: skip
    along = alpha @ -n
    alpha_n = abs(along) * -n
    alpha_t = alpha - along * -n
    if alpha_t @ -v < 0.0:
        alpha_t = -alpha_t
    t = np.linalg.norm(alpha_t)
    cap = 1.0 if t == 0.0 else min(mu_surf * np.linalg.norm(alpha_n) / t, 1.0)
    return xi_n * (alpha_n + cap * alpha_t) * depth * area
