"""The 3D RFT element law as a Warp function, float64: the equations of ``mjrft.core.rft``.

Treers, Cao & Stuart, RA-L 2021 on Li, Zhang & Goldman's 2D RFT (docs/design.md section 2),
written plainly (libm tanh and log, one element per thread): a GPU thread has no vector loop
to keep branch-free, so the polynomial exp and log of the engine (engine/law.cc) buy nothing here.
Coefficients are ``Material.kernel_coefficients``: the 18 combined Fourier coefficients of
alpha_z then alpha_x (``mjrft.core.material.combined_coefficients``), with the dynamic term's
lambda rho_c passed on its own.
"""

from __future__ import annotations

import math

import warp as wp

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
    LEADING_SLACK,
)

f64 = wp.float64
vec3d = wp.vec3d

_ZERO = wp.constant(f64(0.0))
_SLACK = wp.constant(f64(LEADING_SLACK))
_ONE = wp.constant(f64(1.0))
_HALF = wp.constant(f64(0.5))
_TWO = wp.constant(f64(2.0))
_PLATE_NZ = wp.constant(f64(HORIZONTAL_PLATE_NZ))
_F1_SLOPE = wp.constant(f64(F1_SLOPE))
_F1_SHIFT = wp.constant(f64(F1_SHIFT))
_F23_SLOPE = wp.constant(f64(F23_SLOPE))
_F23_SHIFT = wp.constant(f64(F23_SHIFT))
_TANH_F1_SHIFT = wp.constant(f64(math.tanh(F1_SHIFT)))
_ATANH_F23_SHIFT = wp.constant(f64(math.atanh(F23_SHIFT)))
_C1 = wp.constant(f64(F1_GAIN / F1_NORM))
_C23 = wp.constant(f64(F23_GAIN / F23_NORM))
#: In-plane speed |v23| below this counts as zero (gamma = 0), as in the engine (engine/law.cc).
_VN_MIN = wp.constant(f64(1e-100))


@wp.func
def alpha(co: wp.array(dtype=f64), o: int, c2: f64, s2: f64, cg: f64, sg: f64) -> f64:
    """alpha_z (o = 0) or alpha_x (o = 9) from the combined coefficients:
    K0 + K1 c2 + K2 s2 + K3 cg + K4 sg + K5 c2 cg + K6 s2 sg + K7 c2 sg + K8 s2 cg."""
    return (
        co[o]
        + co[o + 1] * c2
        + co[o + 2] * s2
        + co[o + 3] * cg
        + co[o + 4] * sg
        + co[o + 5] * c2 * cg
        + co[o + 6] * s2 * sg
        + co[o + 7] * c2 * sg
        + co[o + 8] * s2 * cg
    )


@wp.func
def element_force(
    n: vec3d, v: vec3d, depth_area: f64, area: f64, co: wp.array(dtype=f64), ay: f64,
    zeta: f64, lam_rho: f64,
) -> vec3d:  # fmt: skip
    """RFT force [N] on one element, world frame: unit normal n, velocity v [m/s], the depth
    integral depth_area [m^3] over its acting area [m^2]; zero unless depth_area > 0 and leading.

    co: (18,) combined coefficients; ay: generic alpha_y; zeta [N/m^3]; lam_rho: the dynamic
    term's lambda rho_c [kg/m^3] (0: off), adding -lambda rho_c (n . v)^2 area n.
    """
    m = wp.max(wp.abs(v[0]), wp.max(wp.abs(v[1]), wp.abs(v[2])))
    if depth_area <= _ZERO or m == _ZERO:
        return vec3d(_ZERO, _ZERO, _ZERO)
    w = v / m  # rescaled first, so that squaring neither overflows nor underflows
    vh = w / wp.length(w)
    if wp.dot(n, vh) <= _SLACK:  # not leading (LEADING_SLACK: rounding)
        return vec3d(_ZERO, _ZERO, _ZERO)
    # Frame (docs/design.md 2.2): e2 horizontal along the normal, or along v for nearly
    # horizontal plates (world x if v is vertical); e1 = e2 x z.
    hx = n[0]
    hy = n[1]
    if wp.abs(n[2]) >= _PLATE_NZ:
        hx = vh[0]
        hy = vh[1]
    h = wp.sqrt(hx * hx + hy * hy)
    e2x = _ONE
    e2y = _ZERO
    if h > _ZERO:
        e2x = hx / h
        e2y = hy / h
    a = vh[0] * e2y - vh[1] * e2x
    b = vh[0] * e2x + vh[1] * e2y
    c = vh[2]
    vn = wp.sqrt(b * b + c * c)
    n2 = n[0] * e2x + n[1] * e2y
    nz = n[2]
    rn2 = n2 * n2 + nz * nz
    # beta = atan2(nz, n2) + pi/2 and gamma = -atan2(c, b) enter through their sines/cosines.
    c2 = (nz * nz - n2 * n2) / rn2
    s2 = -_TWO * nz * n2 / rn2
    cg = _ONE
    sg = _ZERO
    if vn > _VN_MIN:
        cg = b / vn
        sg = -c / vn
    az = alpha(co, 0, c2, s2, cg, sg)
    ax = alpha(co, 9, c2, s2, cg, sg)
    f1 = _C1 * (wp.tanh(_F1_SLOPE * wp.abs(a) - _F1_SHIFT) + _TANH_F1_SHIFT)
    u = _F23_SLOPE * vn - _F23_SHIFT
    f23 = _C23 * (_HALF * wp.log((_ONE + u) / (_ONE - u)) + _ATANH_F23_SHIFT)
    # docs/design.md 2.8: F = zeta d dA [-f1 ay sign(v^.e1) e1 - f23 ax e2 + f23 az z].
    s = zeta * depth_area
    sgn = _ZERO
    if a > _ZERO:
        sgn = _ONE
    elif a < _ZERO:
        sgn = -_ONE
    g1 = -s * f1 * ay * sgn
    g23 = s * f23
    gx = -g23 * ax
    f = vec3d(g1 * e2y + gx * e2x, -g1 * e2x + gx * e2y, g23 * az)
    if lam_rho > _ZERO:  # docs/models.md "Dynamic RFT": the momentum flux of the grains set moving
        vnorm = wp.dot(n, v)
        f = f - lam_rho * area * vnorm * vnorm * n
    return f


@wp.kernel
def forces_kernel(
    # Model
    co: wp.array(dtype=f64), ay: f64, zeta: f64, lam_rho: f64, surface_z: f64,
    # Data in
    pos: wp.array(dtype=vec3d), normal: wp.array(dtype=vec3d), area: wp.array(dtype=f64),
    vel: wp.array(dtype=vec3d),
    # Data out
    force: wp.array(dtype=vec3d),
):  # fmt: skip
    """force[i] = element_force of element i under a flat surface at surface_z [m]."""
    i = wp.tid()
    a = area[i]
    w = (surface_z - pos[i][2]) * a
    force[i] = element_force(normal[i], vel[i], w, a, co, ay, zeta, lam_rho)
