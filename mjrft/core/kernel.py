"""Compiled (numba) RFT kernels for Fourier-form media: the same equations as ``mjrft.core.rft``.

Layout, chosen from measurements on the project's 2-core machine (benchmarks/kernel.py):

1. ``body_wrench`` only: a pass puts a chunk's centroids, normals and velocities in the world
   frame; an element the quadrature's bounds cannot clear (mjrft.core.quadrature) is held
   aside, and after the pass the held ones are tested exactly from their corners
   (``_corner_values``, ``_triage``) and only those the free surface or the leading boundary
   crosses, or near the surface, are clipped (``_clip_held``). Kept out of the first pass, this
   work does not slow it (measured: the clipping inlined there cost 7 ns on every element);
2. ``_gather``, scalar and branch-free: every element is written to the next scratch slot and
   the slot advances only if the element acts (submerged, inside the region, leading), so
   trailing and dry elements cost only this pass and no branch is mispredicted;
3. ``_evaluate``, one branch-free loop that LLVM vectorises with AVX2: the frame of
   docs/design.md 2.2, the sines and cosines of beta and gamma as normalised vector components
   (beta and gamma are never formed), the Fourier sums by angle addition, and tanh / atanh of
   f1 / f23 from exp and log polynomials on their bounded arguments (libm's exp/log are scalar
   calls: 8 ns each here). Per element: 3 square roots and 2 divisions, the rest multiply-adds;
4. a scalar pass scatters the element forces and accumulates the wrench.

Both drivers share stages 2-4: ``forces`` over world-frame element arrays, and ``body_wrench``,
which transforms a body's elements from its frame, evaluates only submerged leading ones, writes
per-element forces and accumulates the body's wrench. Results equal ``rft.numpy_forces`` to
round-off (tests/test_kernel.py) and do not depend on an element's slot in a chunk. Compiled on
first use and cached on disk (``cache=True``); ``numba_cache.refresh`` (run on import) clears
that cache when any compiled module changed, since numba itself does not track callees.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from mjrft.core import agarwal, numba_cache, quadrature, surface
from mjrft.core.law import (
    F1_GAIN,
    F1_NORM,
    F1_SHIFT,
    F1_SLOPE,
    F23_GAIN,
    F23_NORM,
    F23_SHIFT,
    F23_SLOPE,
    HORIZONTAL_PLATE_NZ,
)

numba_cache.refresh()  # before any compiled function of mjrft is loaded from the cache
_TANH_F1_SHIFT = math.tanh(F1_SHIFT)
_ATANH_F23_SHIFT = math.atanh(F23_SHIFT)
_C1 = F1_GAIN / F1_NORM
_C23 = F23_GAIN / F23_NORM
#: Elements per chunk: scratch arrays stay in L1 cache.
CHUNK = 256
_JIT = {"cache": True, "error_model": "numpy"}

# exp on the bounded argument of tanh in f1: x = 2 (slope |v1| - shift) with |v1| <= 1 lies in
# [_EXP_LO, _EXP_HI]; exp(x) = e^mid p((x - mid) / 16)^16, mid the centre, p the Taylor
# polynomial of exp of degree _EXP_DEGREE (truncation below 1e-18 for |y| <= 0.23; the four
# squarings multiply the rounding error by 16: ~2e-15 relative).
_EXP_LO = -2.0 * F1_SHIFT
_EXP_HI = 2.0 * (F1_SLOPE - F1_SHIFT)
_EXP_MID = 0.5 * (_EXP_LO + _EXP_HI)
_EXP_SCALE = math.exp(_EXP_MID)
_EXP_DEGREE = 12
_EXP_TAYLOR = tuple(1.0 / math.factorial(i) for i in range(_EXP_DEGREE + 1))
# log on (1 + u) / (1 - u), u = slope |v23| - shift in f23 (ratio in [0.013, 4.6]): five exact
# power-of-two steps bring the ratio into [2^-0.5, 2^0.5], then log r = 2 atanh(s),
# s = (r - 1) / (r + 1), |s| <= 0.1716, by its odd series to s^19 (next term < 1e-17 relative).
_LOG_STEPS = (  # (threshold on the ratio, below (True) or above, factor, log2 of the factor)
    (2.0**-2.2, True, 16.0, 4.0),
    (2.0**1.1, False, 0.25, -2.0),
    (2.0**-1.1, True, 4.0, 2.0),
    (2.0**0.5, False, 0.5, -1.0),
    (2.0**-0.5, True, 2.0, 1.0),
)
_LOG_TERMS = 10
_LN2 = math.log(2.0)
# 1 / rho for rho = 1 - eps, |eps| <= 1 - HORIZONTAL_PLATE_NZ^2 (< 2e-3): geometric series to eps^6.
_INV_TERMS = 7
#: Velocities are rescaled in the gather pass when |w|^2 leaves this range, so that the products
#: of up to three speed-scaled factors in _evaluate neither overflow nor underflow.
_W2_MIN, _W2_MAX = 1e-60, 1e60
#: In-plane speed |v23| below this counts as zero (gamma = 0): f23 there is below 1e-99.
_VN_MIN = 1e-100
#: Length of the treers2021 model's coefficients (``Material.kernel_coefficients``). A model's
#: coefficients with one more entry carry the dynamic (inertial) term's lambda rho_c [kg/m^3]
#: last (``_dynamic``); the length is how the kernel knows, so the default costs no argument.
N_COMBINED = 18


@intrinsic
def _fma(typingctx, a, b, c):
    """a * b + c rounded once (llvm.fma): vectorises to vfmadd, and the vector body and the
    scalar remainder of a loop round identically (LLVM's "contract" flag would not promise that,
    and results would depend on an element's slot in the chunk)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@numba.njit(inline="always", **_JIT)
def _exp_f1(x):
    """exp(x) for x in [_EXP_LO, _EXP_HI] (the f1 argument) without libm: vectorisable."""
    y = (x - _EXP_MID) * (1.0 / 16.0)
    p = _EXP_TAYLOR[_EXP_DEGREE]
    for i in range(_EXP_DEGREE - 1, -1, -1):
        p = _fma(p, y, _EXP_TAYLOR[i])
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    return p * _EXP_SCALE


@numba.njit(**_JIT)
def _evaluate(buf, k, co, ay, zeta):
    """Forces on k gathered elements (rows 0-8 of buf) into rows 9-11; branch-free, one pass.

    Rows: 0-2 unit normal n, 3-4 horizontal direction h of e2 (unnormalised), 5-7 velocity w
    (any scale with |w|^2 in [_W2_MIN, _W2_MAX]), 8 depth * area [m^3]; all world frame.
    Only sqrt and division are hardware operations: beta and gamma are never formed (their
    sines and cosines are normalised components), the Fourier sums follow by angle addition,
    and exp / log are the bounded-range polynomials above, so LLVM vectorises the loop.
    """
    for j in range(k):
        nx, ny, nz = buf[0, j], buf[1, j], buf[2, j]
        hx, hy = buf[3, j], buf[4, j]
        wx, wy, wz = buf[5, j], buf[6, j], buf[7, j]
        h2 = _fma(hx, hx, hy * hy)
        s2 = _fma(wx, wx, _fma(wy, wy, wz * wz))
        big_a = math.sqrt(h2)  # |h|
        t = math.sqrt(s2 * h2)  # |w| |h|
        p = _fma(wx, hy, -(wy * hx))  # (w . e1) |h|, e1 = e2 x z
        q = _fma(wx, hx, wy * hy)  # (w . e2) |h|
        r = math.sqrt(_fma(q, q, wz * wz * h2))  # |w| |h| |v23|
        moving = r > _VN_MIN * t
        rg = r if moving else t
        x = 1.0 / (t * big_a * rg)  # the one division of the frame: 1/t, 1/|h|, 1/rg below
        inv_t = big_a * rg * x
        inv_a = t * rg * x
        inv_r = t * big_a * x
        ex = hx * inv_a
        ey = hy * inv_a
        a = p * inv_t  # v^ . e1
        vn = r * inv_t  # |v23|
        cg = q * inv_r if moving else 1.0  # gamma = -atan2(v^.z, v^.e2)
        sg = -wz * big_a * inv_r if moving else 0.0
        # beta = atan2(nz, n2) + pi/2: cos 2 beta = (nz^2 - n2^2) / rho, sin 2 beta = -2 nz n2 / rho
        # with rho = n2^2 + nz^2 = 1 - (n . e1)^2 within 2e-3 of 1 (docs/design.md 2.2 frame).
        n2 = _fma(nx, ex, ny * ey)
        eps = 1.0 - _fma(n2, n2, nz * nz)
        inv_rho = 1.0
        for _ in range(_INV_TERMS - 1):
            inv_rho = _fma(inv_rho, eps, 1.0)
        c2 = (nz - n2) * (nz + n2) * inv_rho
        s2b = -2.0 * nz * n2 * inv_rho
        p1 = c2 * cg
        p2 = s2b * sg
        p3 = c2 * sg
        p4 = s2b * cg
        az = co[0]
        ax = co[9]
        for c, term in enumerate((c2, s2b, cg, sg, p1, p2, p3, p4)):  # unrolled by numba
            az = _fma(co[1 + c], term, az)
            ax = _fma(co[10 + c], term, ax)
        # f1 = C1 (tanh(slope |a| - shift) + tanh(shift)), tanh(z) = 1 - 2 / (exp(2z) + 1).
        e1 = _exp_f1(_fma(2.0 * F1_SLOPE, abs(a), -2.0 * F1_SHIFT)) + 1.0
        # f23 = C23 (atanh(u) + atanh(shift)), atanh(u) = log(num / den) / 2.
        num = _fma(F23_SLOPE, vn, 1.0 - F23_SHIFT)  # 1 + u
        den = _fma(-F23_SLOPE, vn, 1.0 + F23_SHIFT)  # 1 - u
        lg = 0.0
        for thr, below, fac, l2 in _LOG_STEPS:
            hit = num < thr * den if below else num > thr * den
            num = num * fac if hit else num
            lg = lg - l2 if hit else lg
        y = 1.0 / ((num + den) * e1)  # the second division: 1 / (num + den) and 1 / e1
        sr = (num - den) * e1 * y
        s_sq = sr * sr
        ser = 1.0 / (2 * _LOG_TERMS - 1)
        for i in range(_LOG_TERMS - 2, -1, -1):
            ser = _fma(ser, s_sq, 1.0 / (2 * i + 1))
        log_r = _fma(lg, _LN2, 2.0 * sr * ser)
        f1 = _C1 * (_fma(-2.0 * (num + den), y, 1.0) + _TANH_F1_SHIFT)
        # docs/design.md 2.8: F = zeta d dA [-f1 ay sign(v^.e1) e1 - f23 ax e2 + f23 az z].
        s = zeta * buf[8, j]
        g23 = s * _C23 * _fma(0.5, log_r, _ATANH_F23_SHIFT)
        sgn = 1.0 if a > 0.0 else (-1.0 if a < 0.0 else 0.0)
        g1 = -s * f1 * ay * sgn
        gx = -g23 * ax
        buf[9, j] = _fma(g1, ey, gx * ex)
        buf[10, j] = _fma(-g1, ex, gx * ey)
        buf[11, j] = g23 * az


@numba.njit(inline="always", **_JIT)
def _evaluate_model(buf, k, co, ay, zeta):
    """The force model the coefficients are for: Treers et al. 2021 (18 combined Fourier
    coefficients, ``_evaluate``) or Agarwal et al. 2023 (``agarwal.SIZE`` parameters)."""
    if co.shape[0] == agarwal.SIZE or co.shape[0] == agarwal.SIZE + 1:
        agarwal.evaluate(buf, k, co)
    else:
        _evaluate(buf, k, co, ay, zeta)


@numba.njit(inline="always", **_JIT)
def dynamic_coefficient(co):
    """lambda rho_c [kg/m^3] of the dynamic term the coefficients carry, 0.0 if none."""
    n = co.shape[0]
    return co[n - 1] if n == N_COMBINED + 1 or n == agarwal.SIZE + 1 else 0.0


@numba.njit(inline="always", **_JIT)
def _dynamic(buf, j, lam_rho, area, vx, vy, vz):
    """Add the dynamic RFT inertial term to the force (rows 9-11) of gathered element j:
    -lambda rho_c (n . v)^2 A n on its acting part of area A [m^2], unit normal n (rows 0-2),
    moving at v [m/s]; world frame. The momentum flux of the grains a leading face sets moving
    at its normal speed (docs/models.md, "Dynamic RFT"): F . v = -lambda rho_c (n . v)^3 A <= 0.
    """
    nx, ny, nz = buf[0, j], buf[1, j], buf[2, j]
    vn = max(0.0, nx * vx + ny * vy + nz * vz)
    g = lam_rho * area * vn * vn
    buf[9, j] -= g * nx
    buf[10, j] -= g * ny
    buf[11, j] -= g * nz


@numba.njit(**_JIT)
def _scratch():
    """Per-chunk scratch: rows 0-11 for _evaluate, 12-14 for the element positions and 15 for
    the acting areas (body_wrench; the area only with the dynamic term)."""
    return np.empty((16, CHUNK)), np.empty(CHUNK, np.int64)


#: Columns of body_wrench's quadrature rows: point (3), normal (3), velocity (3), weight.
ROW = 10
#: Vertices a triangle clipped by two half-planes can have (5), rounded up.
_POLY = 8


@numba.njit(inline="always", **_JIT)
def _clip(src, ns, dst, v0, v1, v2):
    """Clip the polygon src[:ns] (barycentric points, rows) to where the linear function with
    corner values v0, v1, v2 is >= 0 (Sutherland-Hodgman); writes dst, returns its count."""
    nd = 0
    for k in range(ns):
        kb = k + 1 if k + 1 < ns else 0
        fa = src[k, 0] * v0 + src[k, 1] * v1 + src[k, 2] * v2
        fb = src[kb, 0] * v0 + src[kb, 1] * v1 + src[kb, 2] * v2
        if fa >= 0.0:
            dst[nd, 0] = src[k, 0]
            dst[nd, 1] = src[k, 1]
            dst[nd, 2] = src[k, 2]
            nd += 1
        if (fa >= 0.0) != (fb >= 0.0):
            t = fa / (fa - fb)
            for c in range(3):
                dst[nd, c] = src[k, c] + (src[kb, c] - src[k, c]) * t
            nd += 1
    return nd


@numba.njit(inline="always", **_JIT)
def _clipped(poly, d0, d1, d2, s0, s1, s2, area):
    """(W, l0, l1, l2, a): the integral W [m^3] of the depth over the part of a triangle of area
    [m^2] where depth and lead are >= 0 (both linear, corner values d0-d2, s0-s2), that part's
    depth-weighted centroid in barycentric coordinates and its area a [m^2] (W = 0: nothing
    acts).

    The part is a polygon (fanned into triangles); on a triangle with corner depths da, db, dc
    the integral of depth is A (da + db + dc) / 3 and that of depth times the barycentric
    point l is A / 12 ((da + db + dc) (la + lb + lc) + da la + db lb + dc lc).
    """
    src, dst = poly[0], poly[1]
    for k in range(3):
        for c in range(3):
            src[k, c] = 0.0
    src[0, 0] = 1.0
    src[1, 1] = 1.0
    src[2, 2] = 1.0
    n = _clip(src, 3, dst, d0, d1, d2)
    n = _clip(dst, n, src, s0, s1, s2)
    acc = dst[0]  # free after the second clip
    acc[0] = 0.0
    acc[1] = 0.0
    acc[2] = 0.0
    w = 0.0
    wet = 0.0
    for k in range(1, n - 1):
        frac = abs(
            (src[k, 1] - src[0, 1]) * (src[k + 1, 2] - src[0, 2])
            - (src[k, 2] - src[0, 2]) * (src[k + 1, 1] - src[0, 1])
        )
        da = src[0, 0] * d0 + src[0, 1] * d1 + src[0, 2] * d2
        db = src[k, 0] * d0 + src[k, 1] * d1 + src[k, 2] * d2
        dc = src[k + 1, 0] * d0 + src[k + 1, 1] * d1 + src[k + 1, 2] * d2
        a = frac * area
        sd = da + db + dc
        w += a * sd / 3.0
        wet += a
        for c in range(3):
            lc = src[0, c] + src[k, c] + src[k + 1, c]
            acc[c] += a / 12.0 * (sd * lc + da * src[0, c] + db * src[k, c] + dc * src[k + 1, c])
    if not w > 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    q = 1.0 / w
    return w, acc[0] * q, acc[1] * q, acc[2] * q, wet


@numba.njit(inline="always", **_JIT)
def _corner_cut(da, db, dc, fa, fb, fc, area):
    """(W, Ma, Mb, Mc, a): the integral W [m^3] of the depth over the corner a of a triangle of
    area [m^2] that the line f = 0 cuts off (f linear, fa on one side, fb and fc on the other;
    depth corner values da, db, dc), W times that corner's depth-weighted centroid in the
    triangle's barycentric coordinates (a, b, c), and the corner's area a [m^2].

    The corner is the triangle a, a + t1 (b - a), a + t2 (c - a), t1 = fa / (fa - fb), t2 =
    fa / (fa - fc), of area t1 t2 A; on it the formulas of ``_clipped``.
    """
    t1 = fa / (fa - fb)
    t2 = fa / (fa - fc)
    e1 = da + t1 * (db - da)
    e2 = da + t2 * (dc - da)
    a = area * t1 * t2
    s = da + e1 + e2
    k = a / 12.0
    ma = k * (s * (3.0 - t1 - t2) + da + e1 * (1.0 - t1) + e2 * (1.0 - t2))
    return a * s / 3.0, ma, k * t1 * (s + e1), k * t2 * (s + e2), a


@numba.njit(inline="always", **_JIT)
def _cut(d0, d1, d2, f0, f1, f2, area):
    """(W, l0, l1, l2, a) as ``_clipped``, for the part of a triangle where the linear f >= 0
    (corner values f0-f2) and the depth (corner values d0-d2) is positive everywhere on it:
    one line crosses the triangle, so the part is the corner it cuts off (``_corner_cut``)
    or the triangle less that corner, in closed form."""
    i0, i1, i2 = f0 >= 0.0, f1 >= 0.0, f2 >= 0.0
    n = int(i0) + int(i1) + int(i2)
    sd = d0 + d1 + d2
    if n == 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    if n == 3:
        q = 1.0 / (4.0 * sd)
        return area * sd / 3.0, (sd + d0) * q, (sd + d1) * q, (sd + d2) * q, area
    # The odd corner is the one inside alone (n == 1) or outside alone (n == 2).
    if i0 == (n == 1):
        w, m0, m1, m2, a = _corner_cut(d0, d1, d2, f0, f1, f2, area)
    elif i1 == (n == 1):
        w, m1, m2, m0, a = _corner_cut(d1, d2, d0, f1, f2, f0, area)
    else:
        w, m2, m0, m1, a = _corner_cut(d2, d0, d1, f2, f0, f1, area)
    if n == 2:
        k = area / 12.0
        w = area * sd / 3.0 - w
        a = area - a
        m0, m1, m2 = k * (sd + d0) - m0, k * (sd + d1) - m1, k * (sd + d2) - m2
    if not w > 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    q = 1.0 / w
    return w, m0 * q, m1 * q, m2 * q, a


#: Rows of body_wrench's held scratch, for the elements whose corners are tested after a
#: chunk's one-point pass: depth at the centroid [m]; point (3) [m], normal (3) and velocity
#: (3) [m/s] of the one-point rule (world frame); corner depths (3) [m]; corner n . v (3).
_HELD_DEPTH, _HELD_POINT, _HELD_NORMAL, _HELD_VEL, _HELD_D, _HELD_S = 0, 1, 4, 7, 10, 13
_HELD = 16


@numba.njit(inline="always", **_JIT)
def _corner_values(patch, cf, later, held, nl, rot, ang_b, lin_b, surface_prm, surface_grid,
                   soil):  # fmt: skip
    """Corner depths [m] and corner n . v [m/s] of the held elements later[:nl] into held.

    n . v is taken in the body frame, v = lin_b + ang_b x c at the corner c (body frame; the
    body's motion expressed there, body_wrench), so corner normals are not rotated; a corner's
    depth is measured vertically at its world position (mjrft.core.surface).
    """
    gx, gy, gz = ang_b[0], ang_b[1], ang_b[2]
    lx, ly, lz = lin_b[0], lin_b[1], lin_b[2]
    r20, r21, r22 = rot[2, 0], rot[2, 1], rot[2, 2]
    flat = surface_prm[surface.KIND] == surface.FLAT
    top = surface_prm[surface.Z0]
    for j in range(nl):
        i = later[j]
        bx, by, bz = cf[3 * i], cf[3 * i + 1], cf[3 * i + 2]
        for q in range(3):
            o0, o1, o2 = patch[i, 3 * q], patch[i, 3 * q + 1], patch[i, 3 * q + 2]
            cx, cy, cz = bx + o0, by + o1, bz + o2
            g = quadrature.PATCH_NORMAL + 3 * q
            held[_HELD_S + q, j] = (
                patch[i, g] * (lx + gy * cz - gz * cy)
                + patch[i, g + 1] * (ly + gz * cx - gx * cz)
                + patch[i, g + 2] * (lz + gx * cy - gy * cx)
            )
            z = held[_HELD_POINT + 2, j] + (r20 * o0 + r21 * o1 + r22 * o2)
            held[_HELD_D + q, j] = top - z
    if flat:
        return
    if surface_prm[surface.KIND] == surface.PLANE:  # the centroid's depth plus the plane's rise
        gx, gy = surface_prm[surface.GX], surface_prm[surface.GY]
        a0 = gx * rot[0, 0] + gy * rot[1, 0] - r20
        a1 = gx * rot[0, 1] + gy * rot[1, 1] - r21
        a2 = gx * rot[0, 2] + gy * rot[1, 2] - r22
        for j in range(nl):
            i = later[j]
            for q in range(3):
                o0, o1, o2 = patch[i, 3 * q], patch[i, 3 * q + 1], patch[i, 3 * q + 2]
                held[_HELD_D + q, j] = held[_HELD_DEPTH, j] + (a0 * o0 + a1 * o1 + a2 * o2)
        return
    # An uneven surface: look the height up under each corner (kept out of the loop above, so
    # that a flat surface's loop stays small).
    for j in range(nl):
        i = later[j]
        for q in range(3):
            o0, o1, o2 = patch[i, 3 * q], patch[i, 3 * q + 1], patch[i, 3 * q + 2]
            held[_HELD_D + q, j] = surface.depth(
                surface_prm, surface_grid, soil,
                held[_HELD_POINT, j] + (rot[0, 0] * o0 + rot[0, 1] * o1 + rot[0, 2] * o2),
                held[_HELD_POINT + 1, j] + (rot[1, 0] * o0 + rot[1, 1] * o1 + rot[1, 2] * o2),
                held[_HELD_POINT + 2, j] + (r20 * o0 + r21 * o1 + r22 * o2),
            )  # fmt: skip


@numba.njit(inline="always", **_JIT)
def _blend(patch, normal, i, area, depth0, band_r, d0, d1, d2, w, l0, l1, l2, rot, px, py, pz,
           omega, v_ref, p_ref):  # fmt: skip
    """The quadrature point of element i from its acting part: the depth integral w [m^3]
    over the part and the part's depth-weighted centroid (l0, l1, l2) (barycentric), blended
    into the one-point rule's values (below). d0-d2: corner depths [m]; depth0 [m] at the
    centroid (px, py, pz) [m]; band_r [m] the clipping band; the body at rot (3, 3) moving
    with omega at v_ref at p_ref (world).

    Returns (W [m^3], x, y, z [m], nx, ny, nz, vx, vy, vz [m/s]), world frame; W = 0: nothing
    acts.
    """
    # Continuity with the one-point rule: the whole triangle's integral (depth-weighted
    # centroid l_j = (sum d + d_j) / (4 sum d), normal interpolated there, W = A mean d) is
    # replaced by the element's own point, normal and A d_centroid, with a weight ramping from
    # 0 at the surface to 1 at the band's edge, where an element leaves the clipped path: an
    # element that nothing clips then gets exactly the one-point rule's force, and the force
    # is continuous in the state (the implicit step differentiates it).
    sd = d0 + d1 + d2
    ramp = min(1.0, max(0.0, sd / (3.0 * band_r))) if band_r > 0.0 else 1.0
    g0, g1, g2 = l0, l1, l2  # the point's barycentric weights, before the centroid's ramp
    b = quadrature.PATCH_NORMAL
    mx = l0 * patch[i, b] + l1 * patch[i, b + 3] + l2 * patch[i, b + 6]
    my = l0 * patch[i, b + 1] + l1 * patch[i, b + 4] + l2 * patch[i, b + 7]
    mz = l0 * patch[i, b + 2] + l1 * patch[i, b + 5] + l2 * patch[i, b + 8]
    if ramp > 0.0:
        q = 1.0 / (4.0 * sd)
        f0, f1, f2 = (sd + d0) * q, (sd + d1) * q, (sd + d2) * q
        g0, g1, g2 = g0 - ramp * f0, g1 - ramp * f1, g2 - ramp * f2
        mx += ramp * (
            normal[i, 0] - (f0 * patch[i, b] + f1 * patch[i, b + 3] + f2 * patch[i, b + 6])
        )
        my += ramp * (
            normal[i, 1] - (f0 * patch[i, b + 1] + f1 * patch[i, b + 4] + f2 * patch[i, b + 7])
        )
        mz += ramp * (
            normal[i, 2] - (f0 * patch[i, b + 2] + f1 * patch[i, b + 5] + f2 * patch[i, b + 8])
        )
        w += ramp * area * (depth0 - sd / 3.0)
        if not w > 0.0:
            return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # The point: the centroid plus R (sum_j g_j offset_j), since the l_j and the f_j sum to 1
    # and the corners are the centroid plus R offset_j.
    ox = g0 * patch[i, 0] + g1 * patch[i, 3] + g2 * patch[i, 6]
    oy = g0 * patch[i, 1] + g1 * patch[i, 4] + g2 * patch[i, 7]
    oz = g0 * patch[i, 2] + g1 * patch[i, 5] + g2 * patch[i, 8]
    x = px + rot[0, 0] * ox + rot[0, 1] * oy + rot[0, 2] * oz
    y = py + rot[1, 0] * ox + rot[1, 1] * oy + rot[1, 2] * oz
    z = pz + rot[2, 0] * ox + rot[2, 1] * oy + rot[2, 2] * oz
    inv = 1.0 / math.sqrt(mx * mx + my * my + mz * mz)
    mx, my, mz = mx * inv, my * inv, mz * inv
    nx = rot[0, 0] * mx + rot[0, 1] * my + rot[0, 2] * mz
    ny = rot[1, 0] * mx + rot[1, 1] * my + rot[1, 2] * mz
    nz = rot[2, 0] * mx + rot[2, 1] * my + rot[2, 2] * mz
    dx, dy, dz = x - p_ref[0], y - p_ref[1], z - p_ref[2]
    vx = v_ref[0] + omega[1] * dz - omega[2] * dy
    vy = v_ref[1] + omega[2] * dx - omega[0] * dz
    vz = v_ref[2] + omega[0] * dy - omega[1] * dx
    return w, x, y, z, nx, ny, nz, vx, vy, vz


@numba.njit(inline="always", **_JIT)
def _triage(buf, idx, k, later, held, nl, area, reach, band):
    """Sort the held elements later[:nl] by their corner values: those trailing everywhere or
    dry leave; those neither the free surface nor the leading boundary crosses, beyond the
    band (band * reach of the surface), are gathered at slots k... with the one-point rule;
    the rest are moved to the front of later and held. Returns (next free slot, #rest)."""
    nc = 0
    for j in range(nl):
        i = later[j]
        d0, d1, d2 = held[_HELD_D, j], held[_HELD_D + 1, j], held[_HELD_D + 2, j]
        s0, s1, s2 = held[_HELD_S, j], held[_HELD_S + 1, j], held[_HELD_S + 2, j]
        if (s0 < 0.0 and s1 < 0.0 and s2 < 0.0) or (d0 <= 0.0 and d1 <= 0.0 and d2 <= 0.0):
            continue  # nothing of it is both submerged and leading
        if (
            s0 > 0.0 and s1 > 0.0 and s2 > 0.0 and d0 > 0.0 and d1 > 0.0 and d2 > 0.0
            and d0 + d1 + d2 >= 3.0 * band * reach[i]
        ):  # fmt: skip
            buf[12, k] = held[_HELD_POINT, j]
            buf[13, k] = held[_HELD_POINT + 1, j]
            buf[14, k] = held[_HELD_POINT + 2, j]
            buf[15, k] = area[i]
            k = _gather(
                buf, idx, k, i, held[_HELD_NORMAL, j], held[_HELD_NORMAL + 1, j],
                held[_HELD_NORMAL + 2, j], held[_HELD_VEL, j], held[_HELD_VEL + 1, j],
                held[_HELD_VEL + 2, j], held[_HELD_DEPTH, j], area[i], True,
            )  # fmt: skip
            continue
        if nc != j:
            later[nc] = i
            for r in range(_HELD):
                held[r, nc] = held[r, j]
        nc += 1
    return k, nc


@numba.njit(inline="always", **_JIT)
def _clip_held(j, i, held, patch, normal, area, band_r, poly, rot, omega, v_ref, p_ref):
    """(W [m^3], a [m^2], x, y, z [m], nx, ny, nz, vx, vy, vz [m/s]) of element i, held at
    column j: the submerged, leading part of its triangle (mjrft.core.quadrature, area a)
    blended into the one-point rule (_blend); W = 0: nothing acts. World frame."""
    d0, d1, d2 = held[_HELD_D, j], held[_HELD_D + 1, j], held[_HELD_D + 2, j]
    s0, s1, s2 = held[_HELD_S, j], held[_HELD_S + 1, j], held[_HELD_S + 2, j]
    if d0 > 0.0 and d1 > 0.0 and d2 > 0.0:  # the whole triangle, or the leading boundary cuts it
        w, l0, l1, l2, a = _cut(d0, d1, d2, s0, s1, s2, area)
    elif s0 > 0.0 and s1 > 0.0 and s2 > 0.0:  # only the free surface cuts it
        w, l0, l1, l2, a = _cut(d0, d1, d2, d0, d1, d2, area)
    else:
        w, l0, l1, l2, a = _clipped(poly, d0, d1, d2, s0, s1, s2, area)
    if w == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    w, x, y, z, nx, ny, nz, vx, vy, vz = _blend(
        patch, normal, i, area, held[_HELD_DEPTH, j], band_r, d0, d1, d2, w, l0, l1, l2, rot,
        held[_HELD_POINT, j], held[_HELD_POINT + 1, j], held[_HELD_POINT + 2, j], omega, v_ref,
        p_ref,
    )  # fmt: skip
    return w, a, x, y, z, nx, ny, nz, vx, vy, vz


@numba.njit(inline="always", **_JIT)
def _gather(buf, idx, k, i, nx, ny, nz, wx, wy, wz, depth, area, inside):
    """Write element i at slot k of the chunk; returns k + 1 if it acts (submerged, inside the
    region, leading: n . w > 0), else k, so the slot is reused (branch-free compaction).

    Scalar but cheap: the velocity is only rescaled when |w|^2 leaves [_W2_MIN, _W2_MAX], and the
    frame direction h is normalised here only for nearly horizontal plates (rare).
    """
    s2 = wx * wx + wy * wy + wz * wz
    if not (_W2_MIN <= s2 <= _W2_MAX):  # rescale so the squares neither underflow nor overflow
        m = max(abs(wx), abs(wy), abs(wz))
        if m > 0.0:
            wx, wy, wz = wx / m, wy / m, wz / m
    dot = nx * wx + ny * wy + nz * wz  # <= 0: trailing, moving in the plate's plane, or at rest
    if abs(nz) >= HORIZONTAL_PLATE_NZ:
        # Frame (docs/design.md 2.2) from the horizontal velocity, or world x if there is none.
        m = max(abs(wx), abs(wy))
        if m == 0.0:
            hx, hy = 1.0, 0.0
        else:
            hx, hy = wx / m, wy / m
            inv = 1.0 / math.sqrt(hx * hx + hy * hy)
            hx, hy = hx * inv, hy * inv
    else:
        hx, hy = nx, ny
    buf[0, k] = nx
    buf[1, k] = ny
    buf[2, k] = nz
    buf[3, k] = hx
    buf[4, k] = hy
    buf[5, k] = wx
    buf[6, k] = wy
    buf[7, k] = wz
    buf[8, k] = depth * area
    idx[k] = i
    return k + ((depth > 0.0) & inside & (dot > 0.0))


@numba.njit(**_JIT)
def forces(pos, n_hat, area, vel, co, ay, zeta, surface_z, out):
    """Fill out (n, 3) with element forces [N]; inputs world frame, n_hat unit. Returns #acting.

    co: (18,) from combined_coefficients, or (agarwal.SIZE,) Agarwal's model's parameters, with
    the dynamic term's lambda rho_c [kg/m^3] appended if it is on (``Material.
    kernel_coefficients``); ay: generic alpha_y; zeta [N/m^3]; surface_z [m].
    """
    n = pos.shape[0]
    buf, idx = _scratch()
    lam_rho = dynamic_coefficient(co)
    dyn = lam_rho > 0.0
    count = 0
    for c0 in range(0, n, CHUNK):
        c1 = min(n, c0 + CHUNK)
        k = 0
        for i in range(c0, c1):
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
        for i in range(c0, c1):
            k = _gather(
                buf, idx, k, i, n_hat[i, 0], n_hat[i, 1], n_hat[i, 2], vel[i, 0], vel[i, 1],
                vel[i, 2], surface_z - pos[i, 2], area[i], True,
            )  # fmt: skip
        _evaluate_model(buf, k, co, ay, zeta)
        if dyn:
            for j in range(k):
                i = idx[j]
                _dynamic(buf, j, lam_rho, area[i], vel[i, 0], vel[i, 1], vel[i, 2])
        for j in range(k):
            i = idx[j]
            out[i, 0] = buf[9, j]
            out[i, 1] = buf[10, j]
            out[i, 2] = buf[11, j]
            if buf[9, j] != 0.0 or buf[10, j] != 0.0 or buf[11, j] != 0.0:
                count += 1
    return count


#: A normal counts as unit if | |n|^2 - 1 | is below this (a few ulp: what normalising gives).
UNIT_NORMAL_SLACK = 4.0 * np.finfo(np.float64).eps


@numba.njit(**_JIT)
def input_flags(pos, normal, area, vel):
    """(any bad input, any normal not of unit length) of C-contiguous element arrays.

    Cheap and vectorised: flat or-reductions (x * 0 is NaN exactly for a non-finite x) and the
    squared length of each normal; about 1 ns per element, against 8-12 for the evaluation.
    """
    p, q, v = pos.reshape(-1), normal.reshape(-1), vel.reshape(-1)
    bad = False
    for j in range(p.shape[0]):
        bad |= (p[j] + q[j] + v[j]) * 0.0 != 0.0
    for i in range(area.shape[0]):
        bad |= (area[i] * 0.0 != 0.0) | (area[i] < 0.0)
    nonunit = False
    for i in range(area.shape[0]):
        n2 = q[3 * i] * q[3 * i] + q[3 * i + 1] * q[3 * i + 1] + q[3 * i + 2] * q[3 * i + 2]
        nonunit |= abs(n2 - 1.0) > UNIT_NORMAL_SLACK
    return bad, nonunit


@numba.njit(**_JIT)
def body_wrench(
    # Model: the body's elements (body frame), then the medium
    cent, norm, area, reach, patch, start, stop,
    co, ay, zeta, surface_prm, surface_grid, use_region, region,
    # Data in: the ground's state (a deforming surface's soil block), the body's pose and motion
    soil,
    rot, pos, omega, v_ref, p_ref, com,
    # Data out
    wrench, elem_force, rows,
):  # fmt: skip
    """Add to wrench (6,) the RFT wrench on elements start..stop of a body; returns #acting.

    cent, norm (n, 3): body-frame centroids [m], unit normals; area (n,) [m^2]; reach (n,) [m]
    and patch (n, quadrature.PATCH_SIZE) the quadrature's corner data (mjrft.core.quadrature:
    elements the free surface or the leading boundary may cross are clipped). co: the
    model's coefficients (``forces``), ay the generic alpha_y, zeta [N/m^3]; surface_prm,
    surface_grid, soil the free surface (mjrft.core.surface; depth measured vertically; soil is
    read only by a deforming one); region (2, 3) world box of the medium, used if use_region.
    rot (3, 3) body -> world; pos (3,) body origin [m]; omega (3,) angular velocity [rad/s];
    v_ref (3,) linear velocity [m/s] of the world point p_ref (3,) moving with the body; com
    (3,): point about which torque is taken [m]; all world frame.
    elem_force (n, 3): forces [N] are written for elements start..stop (zero where nothing acts).
    rows (n, ROW) or (0, ROW): if not empty, the quadrature points are written there instead
    of evaluated (for media given by Python callables): for each acting element, its point
    [m], unit normal, velocity direction (any scale) and weight W = depth x area [m^3], world
    frame; rows of the others are left as they are (the caller zeroes them).
    """
    buf, idx = _scratch()
    poly = np.empty((2, _POLY, 3))
    later = np.empty(CHUNK, np.int64)  # elements whose corners are tested (below)
    held = np.empty((_HELD, CHUNK))
    # Flat views and scalar invariants: constant-stride loads and no reloads in the loop below
    # (measured: 2D indexing with runtime strides cost ~1.7x here).
    cf = np.ascontiguousarray(cent).reshape(-1)
    nf = np.ascontiguousarray(norm).reshape(-1)
    r00, r01, r02 = rot[0, 0], rot[0, 1], rot[0, 2]
    r10, r11, r12 = rot[1, 0], rot[1, 1], rot[1, 2]
    r20, r21, r22 = rot[2, 0], rot[2, 1], rot[2, 2]
    ox, oy, oz = pos[0], pos[1], pos[2]
    wx, wy, wz = omega[0], omega[1], omega[2]
    ux, uy, uz = v_ref[0], v_ref[1], v_ref[2]
    qx, qy, qz = p_ref[0], p_ref[1], p_ref[2]
    lo_x, lo_y, lo_z = region[0, 0], region[0, 1], region[0, 2]
    hi_x, hi_y, hi_z = region[1, 0], region[1, 1], region[1, 2]
    flat = surface_prm[surface.KIND] == surface.FLAT
    band = quadrature.UNEVEN_REACH  # corner depths are within band * reach of the centroid's
    spin = math.sqrt(wx * wx + wy * wy + wz * wz)
    top = surface.ceiling(surface_prm, soil)  # an element above it is dry wherever it is
    # The first test of an element is top - (k . c + kz) for its body-frame centroid c: its
    # height below the ceiling, or under a plane (whose ceiling, +inf, would clear nothing) its
    # exact depth z0 + gx x + gy y - z, affine in c. One dot product either way.
    plane = surface_prm[surface.KIND] == surface.PLANE
    k0, k1, k2, kz = r20, r21, r22, oz
    if plane:
        gx, gy = surface_prm[surface.GX], surface_prm[surface.GY]
        k0, k1, k2 = r20 - gx * r00 - gy * r10, r21 - gx * r01 - gy * r11, r22 - gx * r02 - gy * r12
        kz = oz - gx * ox - gy * oy
        top = surface_prm[surface.Z0]
    lam_rho = dynamic_coefficient(co)
    dyn = lam_rho > 0.0
    # The body's motion in its own frame, v(c) = lin_b + ang_b x c at the body point c, for the
    # corners' n . v (_corner_values).
    ang_b, lin_b = np.empty(3), np.empty(3)
    ex, ey, ez = ox - qx, oy - qy, oz - qz
    tx, ty, tz = ux + wy * ez - wz * ey, uy + wz * ex - wx * ez, uz + wx * ey - wy * ex
    for c in range(3):
        ang_b[c] = rot[0, c] * wx + rot[1, c] * wy + rot[2, c] * wz
        lin_b[c] = rot[0, c] * tx + rot[1, c] * ty + rot[2, c] * tz
    count = 0
    for c0 in range(start, stop, CHUNK):
        k = 0
        nl = 0
        for i in range(c0, min(stop, c0 + CHUNK)):
            elem_force[i, 0] = 0.0
            elem_force[i, 1] = 0.0
            elem_force[i, 2] = 0.0
            # Dry elements leave here (a well-predicted branch: neighbouring triangles of a mesh
            # are dry together), after three multiply-adds.
            cx, cy, cz = cf[3 * i], cf[3 * i + 1], cf[3 * i + 2]
            depth = top - (k0 * cx + k1 * cy + k2 * cz + kz)
            ri = reach[i]
            if depth <= -band * ri:
                continue
            px = r00 * cx + r01 * cy + r02 * cz + ox
            py = r10 * cx + r11 * cy + r12 * cz + oy
            pz = r20 * cx + r21 * cy + r22 * cz + oz
            if not flat and not plane:
                depth = surface.depth(surface_prm, surface_grid, soil, px, py, pz)
                if depth <= -band * ri:
                    continue
            if use_region and (
                px < lo_x or py < lo_y or pz < lo_z or px > hi_x or py > hi_y or pz > hi_z
            ):
                continue
            mx, my, mz = nf[3 * i], nf[3 * i + 1], nf[3 * i + 2]
            nx = r00 * mx + r01 * my + r02 * mz
            ny = r10 * mx + r11 * my + r12 * mz
            nz = r20 * mx + r21 * my + r22 * mz
            dx, dy, dz = px - qx, py - qy, pz - qz
            vx = ux + wy * dz - wz * dy
            vy = uy + wz * dx - wx * dz
            vz = uz + wx * dy - wy * dx
            lead = nx * vx + ny * vy + nz * vz
            # The free surface or the leading boundary may cross the element: its corners are
            # tested after the chunk's one-point pass (a small loop here keeps this one fast).
            # Corner depths differ from the centroid's by at most reach under a level surface,
            # and n . v by at most spread |v| + |omega| reach (the corner normals are unit and
            # within spread of the element's), compared without a square root.
            spread = patch[i, quadrature.PATCH_SPREAD]
            excess = abs(lead) - spin * ri
            if depth < band * ri or (
                excess <= 0.0 or excess * excess <= spread * spread * (vx * vx + vy * vy + vz * vz)
            ):
                later[nl] = i
                held[_HELD_DEPTH, nl] = depth
                held[_HELD_POINT, nl] = px
                held[_HELD_POINT + 1, nl] = py
                held[_HELD_POINT + 2, nl] = pz
                held[_HELD_NORMAL, nl] = nx
                held[_HELD_NORMAL + 1, nl] = ny
                held[_HELD_NORMAL + 2, nl] = nz
                held[_HELD_VEL, nl] = vx
                held[_HELD_VEL + 1, nl] = vy
                held[_HELD_VEL + 2, nl] = vz
                nl += 1
                continue
            buf[12, k] = px
            buf[13, k] = py
            buf[14, k] = pz
            if dyn:
                buf[15, k] = area[i]
            k = _gather(buf, idx, k, i, nx, ny, nz, vx, vy, vz, depth, area[i], True)
        _corner_values(patch, cf, later, held, nl, rot, ang_b, lin_b, surface_prm, surface_grid,
                       soil)  # fmt: skip
        k, nc = _triage(buf, idx, k, later, held, nl, area, reach, band)
        for j in range(nc):
            i = later[j]
            wet, a_wet, px, py, pz, nx, ny, nz, vx, vy, vz = _clip_held(
                j, i, held, patch, norm, area[i], band * reach[i], poly, rot, omega, v_ref, p_ref
            )
            if wet == 0.0:
                continue
            buf[12, k] = px
            buf[13, k] = py
            buf[14, k] = pz
            buf[15, k] = a_wet
            k = _gather(buf, idx, k, i, nx, ny, nz, vx, vy, vz, 1.0, wet, True)  # wet: the integral
        if rows.shape[0] > 0:
            for j in range(k):
                for c in range(3):
                    rows[idx[j], c] = buf[12 + c, j]
                    rows[idx[j], 3 + c] = buf[c, j]
                    rows[idx[j], 6 + c] = buf[5 + c, j]
                rows[idx[j], 9] = buf[8, j]
            count += k
            continue
        _evaluate_model(buf, k, co, ay, zeta)
        if dyn:  # the velocity at each point: the body's twist (the gather may rescale w)
            for j in range(k):
                dx, dy, dz = buf[12, j] - qx, buf[13, j] - qy, buf[14, j] - qz
                _dynamic(buf, j, lam_rho, buf[15, j], ux + wy * dz - wz * dy,
                         uy + wz * dx - wx * dz, uz + wx * dy - wy * dx)  # fmt: skip
        for j in range(k):
            fx, fy, fz = buf[9, j], buf[10, j], buf[11, j]
            if fx == 0.0 and fy == 0.0 and fz == 0.0:
                continue
            count += 1
            i = idx[j]
            elem_force[i, 0] = fx
            elem_force[i, 1] = fy
            elem_force[i, 2] = fz
            ax_, ay_, az_ = buf[12, j] - com[0], buf[13, j] - com[1], buf[14, j] - com[2]
            wrench[0] += fx
            wrench[1] += fy
            wrench[2] += fz
            wrench[3] += ay_ * fz - az_ * fy
            wrench[4] += az_ * fx - ax_ * fz
            wrench[5] += ax_ * fy - ay_ * fx
    return count


#: Codes of ``checked_unit_normals``: which input of an element is bad.
INPUT_OK, BAD_POS, BAD_NORMAL, BAD_AREA, BAD_VEL, NEGATIVE_AREA, ZERO_NORMAL = range(7)


@numba.njit(**_JIT)
def checked_unit_normals(pos, normal, area, vel, n_hat):
    """Check every element's inputs and write its unit normal into n_hat (n, 3).

    Returns (INPUT_OK, -1) or (code, index) of the first bad element: a non-finite position,
    normal, area or velocity, a negative area, or a zero-length normal. A normal already unit
    (within UNIT_NORMAL_SLACK, as input_flags tests) is copied unchanged, so an element's force
    does not depend on the other elements of the call; others are scaled by their largest
    component before they are normalised, so no finite normal overflows or underflows.
    One branch-free pass that LLVM vectorises (a flag is or-ed, as x * 0 is NaN exactly for a
    non-finite x); only inputs that fail it are searched for the first culprit.
    """
    bad = False
    for i in range(pos.shape[0]):
        x0, y0, z0 = normal[i, 0], normal[i, 1], normal[i, 2]
        probe = (pos[i, 0] + pos[i, 1] + pos[i, 2]) * 0.0 + (
            vel[i, 0] + vel[i, 1] + vel[i, 2]
        ) * 0.0
        probe += (x0 + y0 + z0 + area[i]) * 0.0
        scale = max(abs(x0), abs(y0), abs(z0))
        bad |= (probe != 0.0) | (area[i] < 0.0) | (scale == 0.0)
        unit = abs(x0 * x0 + y0 * y0 + z0 * z0 - 1.0) <= UNIT_NORMAL_SLACK
        inv = 1.0 / scale
        x, y, z = x0 * inv, y0 * inv, z0 * inv
        q = 1.0 / math.sqrt(x * x + y * y + z * z)
        n_hat[i, 0] = x0 if unit else x * q
        n_hat[i, 1] = y0 if unit else y * q
        n_hat[i, 2] = z0 if unit else z * q
    if not bad:
        return INPUT_OK, -1
    return _first_bad_input(pos, normal, area, vel)


@numba.njit(**_JIT)
def _first_bad_input(pos, normal, area, vel):
    """(code, index) of the first element with a bad input (checked_unit_normals' codes)."""
    for i in range(pos.shape[0]):
        for c in range(3):
            if not np.isfinite(pos[i, c]):
                return BAD_POS, i
            if not np.isfinite(normal[i, c]):
                return BAD_NORMAL, i
            if not np.isfinite(vel[i, c]):
                return BAD_VEL, i
        if not np.isfinite(area[i]):
            return BAD_AREA, i
        if area[i] < 0.0:
            return NEGATIVE_AREA, i
        if normal[i, 0] == 0.0 and normal[i, 1] == 0.0 and normal[i, 2] == 0.0:
            return ZERO_NORMAL, i
    return INPUT_OK, -1


@numba.njit(**_JIT)
def trajectory(cent, norm, area, reach, patch, co, ay, zeta, surface_z, rot, pos, lin_vel,
               ang_vel, point, out):  # fmt: skip
    """RFT wrenches of a body along a prescribed trajectory: out (T, 6) = force [N], moment
    [N m] about point[t], world frame, for T samples of rot (T, 3, 3) body -> world, pos (T, 3)
    body origin [m], lin_vel (T, 3) its velocity [m/s], ang_vel (T, 3) [rad/s]; the elements
    cent, norm (n, 3), area (n,), reach (n,), patch (n, PATCH_SIZE) in the body frame
    (body_wrench). One thread, no BLAS."""
    region = np.zeros((2, 3))
    prm = np.zeros(surface.PRM_SIZE)
    prm[surface.Z0] = surface_z
    grid = np.zeros((1, 1))
    scratch = np.empty((cent.shape[0], 3))
    no_rows = np.empty((0, ROW))
    out[:] = 0.0
    for t in range(pos.shape[0]):
        body_wrench(
            cent, norm, area, reach, patch, 0, cent.shape[0], co, ay, zeta, prm, grid, False,
            region, grid[0],
            rot[t], pos[t], ang_vel[t], lin_vel[t], pos[t], point[t], out[t], scratch, no_rows,
        )  # fmt: skip


def warm_up() -> None:
    """Compile (or load from numba's disk cache) the kernels now rather than on first use."""
    co = np.zeros(18)
    one = np.array([[0.0, 0.0, -1.0]])
    out = np.zeros((1, 3))
    forces(one, one, np.ones(1), one, co, 0.1, 1.0, 0.0, out)
    patch = np.zeros((1, quadrature.PATCH_SIZE))
    body_wrench(
        one, one, np.ones(1), np.zeros(1), patch, 0, 1, co, 0.1, 1.0, np.zeros(surface.PRM_SIZE),
        np.zeros((1, 1)),
        False, np.zeros((2, 3)), np.zeros(1),
        np.eye(3), np.zeros(3), np.zeros(3), np.ones(3), np.zeros(3), np.zeros(3),
        np.zeros(6), out, np.empty((0, ROW)),
    )  # fmt: skip
    checked_unit_normals(one, one, np.ones(1), one, out)
    input_flags(one, one, np.ones(1), one)
    trajectory(one, one, np.ones(1), np.zeros(1), patch, co, 0.1, 1.0, 0.0, np.eye(3)[None],
               np.zeros((1, 3)),
               np.ones((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 6)))  # fmt: skip
