"""Compiled (numba) RFT kernels for Fourier-form media: the same equations as ``mjrft.rft``.

Layout, chosen from measurements on the project's 2-core machine (benchmarks/kernel.py):

1. a gather pass picks the submerged, leading elements of a chunk (unit velocity, depth * area)
   into contiguous scratch arrays; trailing and dry elements cost only this pass;
2. ``_angles`` (branch-free, so LLVM vectorises it with AVX2): the frame of DESIGN 2.2, the sines
   and cosines of beta and gamma as normalised vector components (beta and gamma are never
   formed), the Fourier sums via angle-addition identities, and the arguments of the two
   transcendental functions;
3. ``_transcendental``: tanh via one exp and atanh via one log (libm's tanh/atanh cost 3-4x more
   here), in loops of independent iterations;
4. ``_combine``: the element forces of DESIGN 2.8.

Both drivers use these stages: ``forces`` over world-frame element arrays, and ``body_wrench``,
which transforms a body's elements from its frame, evaluates only submerged leading ones, writes
per-element forces and accumulates the body's wrench. Results equal ``mjrft.rft.numpy_forces`` to
round-off (tests/test_kernel.py). Compiled on first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from mjrft.rft import (
    _F1_GAIN,
    _F1_NORM,
    _F1_SHIFT,
    _F1_SLOPE,
    _F23_GAIN,
    _F23_NORM,
    _F23_SHIFT,
    _F23_SLOPE,
    HORIZONTAL_PLATE_NZ,
)

_TANH_F1_SHIFT = math.tanh(_F1_SHIFT)
_ATANH_F23_SHIFT = math.atanh(_F23_SHIFT)
_C1 = _F1_GAIN / _F1_NORM
_C23 = _F23_GAIN / _F23_NORM
#: Elements per chunk: scratch arrays stay in L1 cache.
CHUNK = 256
_JIT = {"cache": True, "error_model": "numpy"}


def combined_coefficients(fourier) -> np.ndarray:
    """(18,) coefficients of alpha_z then alpha_x as sums over the shared products used below.

    alpha = K0 + K1 c2 + K2 s2 + K3 cg + K4 sg + K5 c2 cg + K6 s2 sg + K7 c2 sg + K8 s2 cg, with
    c2, s2 = cos, sin(2 beta) and cg, sg = cos, sin(gamma); from the 6 harmonics (m, n) of
    mjrft.material.HARMONICS by cos(2 m b + n g) and sin(2 m b + n g) expanded.
    """

    def comb(c, s):  # c, s: cosine and sine coefficients over HARMONICS
        return [
            c[1],
            c[0] + c[2],
            s[2] - s[0],
            c[4],
            s[4],
            c[3] + c[5],
            c[3] - c[5],
            s[3] + s[5],
            s[5] - s[3],
        ]

    return np.array(comb(fourier.a, fourier.b) + comb(fourier.c, fourier.d), dtype=np.float64)


@numba.njit(**_JIT)
def _angles(k, nx, ny, nz, vx, vy, vz, co, ex_, ey_, a_, t1, t2, az_, ax_):
    """Stage 2 for k gathered elements (unit n, unit v, world frame); branch-free."""
    for j in range(k):
        # Frame (DESIGN 2.2): e2 from n, or from v for a nearly horizontal plate, or world x.
        flat = abs(nz[j]) >= HORIZONTAL_PLATE_NZ
        hx = vx[j] if flat else nx[j]
        hy = vy[j] if flat else ny[j]
        h2 = hx * hx + hy * hy
        none = h2 == 0.0
        ih = 1.0 / math.sqrt(1.0 if none else h2)
        ex = 1.0 if none else hx * ih
        ey = 0.0 if none else hy * ih
        # beta = atan2(nz, n2) + pi/2: cos beta = -nz / r, sin beta = n2 / r.
        n2 = nx[j] * ex + ny[j] * ey
        irn = 1.0 / math.sqrt(n2 * n2 + nz[j] * nz[j])
        cb = -nz[j] * irn
        sb = n2 * irn
        a = vx[j] * ey - vy[j] * ex  # v . e1, e1 = e2 x z
        b = vx[j] * ex + vy[j] * ey  # v . e2
        # gamma = -atan2(vz, b), and gamma = 0 when the in-plane velocity vanishes.
        vn2 = b * b + vz[j] * vz[j]
        moving = vn2 > 0.0
        ivn = 1.0 / math.sqrt(vn2 if moving else 1.0)
        vn = vn2 * ivn
        cg = b * ivn if moving else 1.0
        sg = -vz[j] * ivn if moving else 0.0
        c2 = cb * cb - sb * sb
        s2 = 2.0 * sb * cb
        p1 = c2 * cg
        p2 = s2 * sg
        p3 = c2 * sg
        p4 = s2 * cg
        az_[j] = (
            ((co[0] + co[1] * c2) + (co[2] * s2 + co[3] * cg))
            + ((co[4] * sg + co[5] * p1) + (co[6] * p2 + co[7] * p3))
            + co[8] * p4
        )
        ax_[j] = (
            ((co[9] + co[10] * c2) + (co[11] * s2 + co[12] * cg))
            + ((co[13] * sg + co[14] * p1) + (co[15] * p2 + co[16] * p3))
            + co[17] * p4
        )
        ex_[j] = ex
        ey_[j] = ey
        a_[j] = a
        # tanh(x) = 1 - 2 / (exp(2x) + 1); atanh(u) = log((1 + u) / (1 - u)) / 2.
        t1[j] = 2.0 * (_F1_SLOPE * abs(a) - _F1_SHIFT)
        u = _F23_SLOPE * vn - _F23_SHIFT
        t2[j] = (1.0 + u) / (1.0 - u)


@numba.njit(**_JIT)
def _transcendental(k, t1, t2):
    """Stage 3: exp and log in place (independent iterations)."""
    for j in range(k):
        t1[j] = math.exp(t1[j])
    for j in range(k):
        t2[j] = math.log(t2[j])


@numba.njit(**_JIT)
def _combine(k, da, ay, zeta, ex_, ey_, a_, t1, t2, az_, ax_, fx, fy, fz):
    """Stage 4: F = zeta d dA [-f1 ay sign(v.e1) e1 - f23 ax e2 + f23 az z] (DESIGN 2.8)."""
    for j in range(k):
        s = zeta * da[j]
        g23 = s * _C23 * (0.5 * t2[j] + _ATANH_F23_SHIFT)
        a = a_[j]
        sgn = 1.0 if a > 0.0 else (-1.0 if a < 0.0 else 0.0)
        f1 = _C1 * ((1.0 - 2.0 / (t1[j] + 1.0)) + _TANH_F1_SHIFT)
        g1 = -s * f1 * ay * sgn
        gx = -g23 * ax_[j]
        ex = ex_[j]
        ey = ey_[j]
        fx[j] = g1 * ey + gx * ex
        fy[j] = -g1 * ex + gx * ey
        fz[j] = g23 * az_[j]


@numba.njit(**_JIT)
def _scratch():
    return np.empty((17, CHUNK)), np.empty(CHUNK, np.int64)


@numba.njit(inline="always", **_JIT)
def _gather(buf, k, nx, ny, nz, wx, wy, wz, depth_area):
    """Normalise v and, if the element leads, append it to the chunk; returns the new count."""
    s2 = wx * wx + wy * wy + wz * wz
    if 1e-280 < s2 < 1e280:
        inv = 1.0 / math.sqrt(s2)
    else:  # rescale so the squares neither underflow nor overflow
        m = max(abs(wx), abs(wy), abs(wz))
        if m == 0.0:
            return k
        wx, wy, wz = wx / m, wy / m, wz / m
        inv = 1.0 / math.sqrt(wx * wx + wy * wy + wz * wz)
    wx, wy, wz = wx * inv, wy * inv, wz * inv
    if nx * wx + ny * wy + nz * wz <= 0.0:  # trailing (or moving in the plate's plane)
        return k
    buf[0, k] = nx
    buf[1, k] = ny
    buf[2, k] = nz
    buf[3, k] = wx
    buf[4, k] = wy
    buf[5, k] = wz
    buf[6, k] = depth_area
    return k + 1


@numba.njit(inline="always", **_JIT)
def _evaluate(buf, k, co, ay, zeta):
    """Stages 2-4 on the k gathered elements; forces land in buf[14:17, :k]."""
    _angles(
        k, buf[0], buf[1], buf[2], buf[3], buf[4], buf[5], co,
        buf[7], buf[8], buf[9], buf[10], buf[11], buf[12], buf[13],
    )  # fmt: skip
    _transcendental(k, buf[10], buf[11])
    _combine(
        k, buf[6], ay, zeta, buf[7], buf[8], buf[9], buf[10], buf[11], buf[12], buf[13],
        buf[14], buf[15], buf[16],
    )  # fmt: skip


@numba.njit(**_JIT)
def forces(pos, n_hat, area, vel, co, ay, zeta, surface_z, out):
    """Fill out (n, 3) with element forces [N]; inputs world frame, n_hat unit. Returns #acting.

    co: (18,) from combined_coefficients; ay: generic alpha_y; zeta [N/m^3]; surface_z [m].
    """
    n = pos.shape[0]
    buf, idx = _scratch()
    count = 0
    for c0 in range(0, n, CHUNK):
        k = 0
        for i in range(c0, min(n, c0 + CHUNK)):
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
            depth = surface_z - pos[i, 2]
            if depth <= 0.0:
                continue
            k_new = _gather(
                buf, k, n_hat[i, 0], n_hat[i, 1], n_hat[i, 2], vel[i, 0], vel[i, 1], vel[i, 2],
                depth * area[i],
            )  # fmt: skip
            if k_new > k:
                idx[k] = i
                k = k_new
        _evaluate(buf, k, co, ay, zeta)
        for j in range(k):
            i = idx[j]
            out[i, 0] = buf[14, j]
            out[i, 1] = buf[15, j]
            out[i, 2] = buf[16, j]
            if buf[14, j] != 0.0 or buf[15, j] != 0.0 or buf[16, j] != 0.0:
                count += 1
    return count


@numba.njit(**_JIT)
def body_wrench(
    cent, norm, area, start, stop, rot, pos, omega, v_ref, p_ref, com,
    co, ay, zeta, surface_z, use_region, region, wrench, elem_force,
):  # fmt: skip
    """Add to wrench (6,) the RFT wrench on elements start..stop of a body; returns #acting.

    cent, norm (n, 3): body-frame centroids [m], unit normals; area (n,) [m^2].
    rot (3, 3) body -> world; pos (3,) body origin [m]; omega (3,) angular velocity [rad/s];
    v_ref (3,) linear velocity [m/s] of the world point p_ref (3,) moving with the body;
    com (3,): point about which torque is taken [m]. All world frame.
    region (2, 3) world box of the medium, used if use_region. elem_force (n, 3): forces [N] are
    written for elements start..stop (zero where nothing acts).
    """
    buf, idx = _scratch()
    px_ = np.empty(CHUNK)
    py_ = np.empty(CHUNK)
    pz_ = np.empty(CHUNK)
    r = rot
    count = 0
    for c0 in range(start, stop, CHUNK):
        k = 0
        for i in range(c0, min(stop, c0 + CHUNK)):
            elem_force[i, 0] = 0.0
            elem_force[i, 1] = 0.0
            elem_force[i, 2] = 0.0
            cx, cy, cz = cent[i, 0], cent[i, 1], cent[i, 2]
            pz = r[2, 0] * cx + r[2, 1] * cy + r[2, 2] * cz + pos[2]
            depth = surface_z - pz
            if depth <= 0.0:
                continue
            px = r[0, 0] * cx + r[0, 1] * cy + r[0, 2] * cz + pos[0]
            py = r[1, 0] * cx + r[1, 1] * cy + r[1, 2] * cz + pos[1]
            if use_region and (
                px < region[0, 0] or py < region[0, 1] or pz < region[0, 2]
                or px > region[1, 0] or py > region[1, 1] or pz > region[1, 2]
            ):  # fmt: skip
                continue
            mx, my, mz = norm[i, 0], norm[i, 1], norm[i, 2]
            nx = r[0, 0] * mx + r[0, 1] * my + r[0, 2] * mz
            ny = r[1, 0] * mx + r[1, 1] * my + r[1, 2] * mz
            nz = r[2, 0] * mx + r[2, 1] * my + r[2, 2] * mz
            dx, dy, dz = px - p_ref[0], py - p_ref[1], pz - p_ref[2]
            vx = v_ref[0] + omega[1] * dz - omega[2] * dy
            vy = v_ref[1] + omega[2] * dx - omega[0] * dz
            vz = v_ref[2] + omega[0] * dy - omega[1] * dx
            k_new = _gather(buf, k, nx, ny, nz, vx, vy, vz, depth * area[i])
            if k_new > k:
                idx[k] = i
                px_[k] = px
                py_[k] = py
                pz_[k] = pz
                k = k_new
        _evaluate(buf, k, co, ay, zeta)
        for j in range(k):
            fx, fy, fz = buf[14, j], buf[15, j], buf[16, j]
            if fx == 0.0 and fy == 0.0 and fz == 0.0:
                continue
            count += 1
            i = idx[j]
            elem_force[i, 0] = fx
            elem_force[i, 1] = fy
            elem_force[i, 2] = fz
            ax_, ay_, az_ = px_[j] - com[0], py_[j] - com[1], pz_[j] - com[2]
            wrench[0] += fx
            wrench[1] += fy
            wrench[2] += fz
            wrench[3] += ay_ * fz - az_ * fy
            wrench[4] += az_ * fx - ax_ * fz
            wrench[5] += ax_ * fy - ay_ * fx
    return count


def warm_up() -> None:
    """Compile (or load from numba's disk cache) both kernels now rather than on first use."""
    co = np.zeros(18)
    one = np.array([[0.0, 0.0, -1.0]])
    out = np.zeros((1, 3))
    forces(one, one, np.ones(1), one, co, 0.1, 1.0, 0.0, out)
    body_wrench(
        one, one, np.ones(1), 0, 1, np.eye(3), np.zeros(3), np.zeros(3), np.ones(3), np.zeros(3),
        np.zeros(3), co, 0.1, 1.0, 0.0, False, np.zeros((2, 3)), np.zeros(6), out,
    )  # fmt: skip
