"""The engine's surface quadrature (engine/quadrature.h) per element, as Warp functions.

The same rule (mjrft.core.quadrature, docs/accuracy.md "Quadrature"): an element is evaluated
at its centroid unless its bounds say the free surface or the leading boundary n . v = 0 may
cross it; then its corners decide, and a crossed element (or one within the band of the
surface) is integrated over its submerged leading part, blended into the one-point rule.
On a GPU each element is one thread, so the engine kernel's hold-and-triage passes
become branches of one function. Flat, tilted or height-grid surfaces (mjrft.warp.surface).
"""

from __future__ import annotations

import warp as wp

from mjrft.core import quadrature as q
from mjrft.core.law import LEADING_SLACK
from mjrft.warp import surface
from mjrft.warp.law import f64, vec3d
from mjrft.warp.surface import Surface

_Z = wp.constant(f64(0.0))
_ONE = wp.constant(f64(1.0))
_THIRD = wp.constant(f64(1.0 / 3.0))
_TWELFTH = wp.constant(f64(1.0 / 12.0))
_BAND = wp.constant(f64(q.UNEVEN_REACH))
_NORMAL = wp.constant(q.PATCH_NORMAL)
_SPREAD = wp.constant(q.PATCH_SPREAD)
_SLACK = wp.constant(f64(LEADING_SLACK))
#: A triangle clipped by two half-planes has at most 5 vertices (rows: barycentric points).
mat83d = wp.types.matrix(shape=(8, 3), dtype=f64)


@wp.struct
class Point:
    """Where and how an element is evaluated: W = 0 means nothing acts.

    w: the depth integral [m^3]; a: the acting area [m^2]; p: point [m]; n: unit normal;
    v: velocity [m/s]; all world frame."""

    w: f64
    a: f64
    p: vec3d
    n: vec3d
    v: vec3d


@wp.func
def _clip(src: mat83d, ns: int, v0: f64, v1: f64, v2: f64):
    """Sutherland-Hodgman: the polygon src[:ns] (barycentric rows) where the linear function
    with corner values v0-v2 is >= 0; returns (polygon, count)."""
    dst = mat83d()
    nd = int(0)
    for k in range(ns):
        kb = k + 1
        if kb == ns:
            kb = 0
        fa = src[k, 0] * v0 + src[k, 1] * v1 + src[k, 2] * v2
        fb = src[kb, 0] * v0 + src[kb, 1] * v1 + src[kb, 2] * v2
        if fa >= _Z:
            for c in range(3):
                dst[nd, c] = src[k, c]
            nd += 1
        if (fa >= _Z) != (fb >= _Z):
            t = fa / (fa - fb)
            for c in range(3):
                dst[nd, c] = src[k, c] + (src[kb, c] - src[k, c]) * t
            nd += 1
    return dst, nd


@wp.func
def _clipped(d: vec3d, s: vec3d, area: f64):
    """(W, barycentric depth-weighted centroid, acting area) of the part of a triangle where
    depth (corner values d) and lead (s) are >= 0 (kernel._clipped's formulas)."""
    src = mat83d()
    src[0, 0] = _ONE
    src[1, 1] = _ONE
    src[2, 2] = _ONE
    p1, n1 = _clip(src, 3, d[0], d[1], d[2])
    p, n = _clip(p1, n1, s[0], s[1], s[2])
    acc = vec3d(_Z, _Z, _Z)
    w = _Z
    wet = _Z
    for k in range(1, n - 1):
        frac = wp.abs(
            (p[k, 1] - p[0, 1]) * (p[k + 1, 2] - p[0, 2])
            - (p[k, 2] - p[0, 2]) * (p[k + 1, 1] - p[0, 1])
        )
        da = p[0, 0] * d[0] + p[0, 1] * d[1] + p[0, 2] * d[2]
        db = p[k, 0] * d[0] + p[k, 1] * d[1] + p[k, 2] * d[2]
        dc = p[k + 1, 0] * d[0] + p[k + 1, 1] * d[1] + p[k + 1, 2] * d[2]
        a = frac * area
        sd = da + db + dc
        w += a * sd * _THIRD
        wet += a
        for c in range(3):
            lc = p[0, c] + p[k, c] + p[k + 1, c]
            acc[c] += a * _TWELFTH * (sd * lc + da * p[0, c] + db * p[k, c] + dc * p[k + 1, c])
    if not w > _Z:
        return _Z, vec3d(_Z, _Z, _Z), _Z
    return w, acc * (_ONE / w), wet


@wp.func
def _corner_cut(da: f64, db: f64, dc: f64, fa: f64, fb: f64, fc: f64, area: f64):
    """(W, W x barycentric centroid (a, b, c), area) of the corner a of a triangle that f = 0
    cuts off (kernel._corner_cut)."""
    t1 = fa / (fa - fb)
    t2 = fa / (fa - fc)
    e1 = da + t1 * (db - da)
    e2 = da + t2 * (dc - da)
    a = area * t1 * t2
    s = da + e1 + e2
    k = a * _TWELFTH
    ma = k * (s * (f64(3.0) - t1 - t2) + da + e1 * (_ONE - t1) + e2 * (_ONE - t2))
    return a * s * _THIRD, vec3d(ma, k * t1 * (s + e1), k * t2 * (s + e2)), a


@wp.func
def _cut(d: vec3d, f: vec3d, area: f64):
    """As _clipped, for the part where the linear f >= 0 (corner values f) and depth > 0
    everywhere on it: one line crosses the triangle (kernel._cut, closed form)."""
    i0 = f[0] >= _Z
    i1 = f[1] >= _Z
    i2 = f[2] >= _Z
    n = int(i0) + int(i1) + int(i2)
    sd = d[0] + d[1] + d[2]
    if n == 0:
        return _Z, vec3d(_Z, _Z, _Z), _Z
    if n == 3:
        return area * sd * _THIRD, (vec3d(sd, sd, sd) + d) * (_ONE / (f64(4.0) * sd)), area
    w = _Z
    m = vec3d(_Z, _Z, _Z)
    a = _Z
    # The odd corner is the one inside alone (n == 1) or outside alone (n == 2).
    if i0 == (n == 1):
        w, m, a = _corner_cut(d[0], d[1], d[2], f[0], f[1], f[2], area)
    elif i1 == (n == 1):
        w, mr, a = _corner_cut(d[1], d[2], d[0], f[1], f[2], f[0], area)
        m = vec3d(mr[2], mr[0], mr[1])
    else:
        w, mr, a = _corner_cut(d[2], d[0], d[1], f[2], f[0], f[1], area)
        m = vec3d(mr[1], mr[2], mr[0])
    if n == 2:
        k = area * _TWELFTH
        w = area * sd * _THIRD - w
        a = area - a
        m = k * (vec3d(sd, sd, sd) + d) - m
    if not w > _Z:
        return _Z, vec3d(_Z, _Z, _Z), _Z
    return w, m * (_ONE / w), a


@wp.func
def _row3(patch: wp.array2d(dtype=f64), i: int, col: int) -> vec3d:
    return vec3d(patch[i, col], patch[i, col + 1], patch[i, col + 2])


@wp.func
def _blend(
    patch: wp.array2d(dtype=f64), i: int, n_body: vec3d, area: f64, depth0: f64, band_r: f64,
    d: vec3d, w: f64, lam: vec3d, rot: wp.mat33d, p0: vec3d, omega: vec3d, v_ref: vec3d,
    p_ref: vec3d,
) -> Point:  # fmt: skip
    """The quadrature point from the acting part (W w, barycentric centroid lam), blended into
    the one-point rule as the element leaves the band (kernel._blend). n_body: the element's
    body-frame normal; d: corner depths; depth0 at the centroid p0 (world)."""
    out = Point()
    sd = d[0] + d[1] + d[2]
    ramp = _ONE
    if band_r > _Z:
        ramp = wp.min(_ONE, wp.max(_Z, sd / (f64(3.0) * band_r)))
    g = lam
    c0 = _row3(patch, i, _NORMAL)
    c1 = _row3(patch, i, _NORMAL + 3)
    c2 = _row3(patch, i, _NORMAL + 6)
    mn = lam[0] * c0 + lam[1] * c1 + lam[2] * c2
    if ramp > _Z:
        fw = (vec3d(sd, sd, sd) + d) * (_ONE / (f64(4.0) * sd))
        g = g - ramp * fw
        mn = mn + ramp * (n_body - (fw[0] * c0 + fw[1] * c1 + fw[2] * c2))
        w += ramp * area * (depth0 - sd * _THIRD)
        if not w > _Z:
            return out
    off = g[0] * _row3(patch, i, 0) + g[1] * _row3(patch, i, 3) + g[2] * _row3(patch, i, 6)
    out.p = p0 + rot * off
    out.n = rot * wp.normalize(mn)
    out.v = v_ref + wp.cross(omega, out.p - p_ref)
    out.w = w
    return out


@wp.func
def quadrature_point(
    cent: vec3d, n_body: vec3d, area: f64, reach: f64, patch: wp.array2d(dtype=f64), i: int,
    rot: wp.mat33d, origin: vec3d, omega: vec3d, v_ref: vec3d, p_ref: vec3d, sf: Surface,
    body: f64, use_region: int, region_lo: vec3d, region_hi: vec3d,
) -> Point:  # fmt: skip
    """Where element i (body frame: centroid cent, unit normal n_body, area, reach, patch row)
    of a body at rot, origin moving with omega at v_ref at p_ref (world) is evaluated under
    the surface sf (depth measured vertically; body: k + 1 for tagged body k, surface.depth)."""
    out = Point()
    p = rot * cent + origin
    depth = surface.ceiling(sf) - p[2]  # an element above the ceiling is dry wherever it is
    if depth <= -_BAND * reach:
        return out
    if sf.kind != surface.FLAT:
        depth = surface.depth(sf, p, body)
        if depth <= -_BAND * reach:
            return out
    if use_region != 0:
        for j in range(3):
            if p[j] < region_lo[j] or p[j] > region_hi[j]:
                return out
    n = rot * n_body
    v = v_ref + wp.cross(omega, p - p_ref)
    lead = wp.dot(n, v)
    spread = patch[i, _SPREAD]
    excess = wp.abs(lead) - wp.length(omega) * reach
    clear = (
        depth >= _BAND * reach and excess > _Z and excess * excess > spread * spread * wp.dot(v, v)
    )
    if not clear:
        # Corner depths and corner n . v - LEADING_SLACK |v|, > 0 where the corner leads (body
        # frame: v = lin_b + ang_b x c at the corner c).
        ang_b = wp.transpose(rot) * omega
        lin_b = wp.transpose(rot) * (v_ref + wp.cross(omega, origin - p_ref))
        d = vec3d(_Z, _Z, _Z)
        s = vec3d(_Z, _Z, _Z)
        for k in range(3):
            o = _row3(patch, i, 3 * k)
            corner = cent + o
            vc = lin_b + wp.cross(ang_b, corner)
            s[k] = wp.dot(_row3(patch, i, _NORMAL + 3 * k), vc) - _SLACK * wp.length(vc)
            if sf.kind == surface.FLAT:
                d[k] = sf.z0 - (p[2] + (rot * o)[2])
            else:
                d[k] = surface.depth(sf, p + rot * o, body)
        if (s[0] < _Z and s[1] < _Z and s[2] < _Z) or (d[0] <= _Z and d[1] <= _Z and d[2] <= _Z):
            return out
        whole = s[0] > _Z and s[1] > _Z and s[2] > _Z and d[0] > _Z and d[1] > _Z and d[2] > _Z
        if not (whole and d[0] + d[1] + d[2] >= f64(3.0) * _BAND * reach):
            w = _Z
            lam = vec3d(_Z, _Z, _Z)
            a = _Z
            if d[0] > _Z and d[1] > _Z and d[2] > _Z:  # the leading boundary may cut it
                w, lam, a = _cut(d, s, area)
            elif s[0] > _Z and s[1] > _Z and s[2] > _Z:  # only the free surface cuts it
                w, lam, a = _cut(d, d, area)
            else:
                w, lam, a = _clipped(d, s, area)
            if w == _Z:
                return out
            out = _blend(patch, i, n_body, area, depth, _BAND * reach, d, w, lam, rot, p,
                         omega, v_ref, p_ref)  # fmt: skip
            out.a = a
            return out
    if depth <= _Z or lead <= _SLACK * wp.length(v):
        return out
    out.w = depth * area
    out.a = area
    out.p = p
    out.n = n
    out.v = v
    return out
