"""The low-speed treatment of free bodies (engine/lowspeed.cc) as Warp functions, float64.

The engine's rules, decision for decision (docs/stability.md; engine/lowspeed.h states them):
a free body whose motion keeps its sense and is fast feels the pure model (if the explicit step
adds no energy); a slow moving body gets one Newton step of backward Euler across its motion
(``implicit_wrench``); a body whose velocity would pass through zero within the step sticks (ends
the step at rest) or slips on the medium's resistance to its free motion (``stick_or_slip``).
One thread per (world, tagged body): the probes of the medium's wrench at other twists
(``twist_wrench``) loop over the body's elements in that thread, since which probes a body
needs depends on its decisions.

Twists are (CoM velocity [m/s], angular velocity [rad/s]) and wrenches (force [N], torque about
the CoM [N m]), world frame, as ``vec6d``; 3x3 inertias in world axes [kg m^2].
"""

from __future__ import annotations

import warp as wp

from mjrft.field import lowspeed as ls
from mjrft.warp.law import element_force, f64, vec3d
from mjrft.warp.quadrature import quadrature_point
from mjrft.warp.surface import Surface

vec6d = wp.types.vector(length=6, dtype=f64)
mat66d = wp.types.matrix(shape=(6, 6), dtype=f64)
mat33d = wp.mat33d

#: Decisions (engine/lowspeed.h): the pure model, stuck, slipping, linearly implicit.
PURE = wp.constant(0)
STICK = wp.constant(1)
SLIP = wp.constant(2)
IMPLICIT = wp.constant(3)
#: A relative energy balance below this counts as zero (engine kRounding: 64 eps).
ROUNDING = wp.constant(f64(64.0 * 2.220446049250313e-16))
_Z = wp.constant(f64(0.0))
_ONE = wp.constant(f64(1.0))

assert ls.DEFAULT_REACH == 4.0  # the engine's default (engine/lowspeed.h kDefaultReach)


@wp.struct
class Medium:
    """The medium and its extent: combined coefficients co (18,), alpha_y, zeta [N/m^3], the
    dynamic term's lambda rho_c [kg/m^3] (0: off), the free surface and the region box [m]
    (used if use_region); world frame."""

    co: wp.array(dtype=f64)
    ay: f64
    zeta: f64
    lam_rho: f64
    surface: Surface
    use_region: int
    region_lo: vec3d
    region_hi: vec3d


@wp.struct
class Elements:
    """The element tables (body frame), their grouping by tagged geom and body, and the tagged
    geoms' ids and bounding radii [m]."""

    pos: wp.array(dtype=vec3d)
    normal: wp.array(dtype=vec3d)
    area: wp.array(dtype=f64)
    reach: wp.array(dtype=f64)
    patch: wp.array2d(dtype=f64)
    tgeom_elemadr: wp.array(dtype=int)
    tgeom_elemnum: wp.array(dtype=int)
    tgeom_geomid: wp.array(dtype=int)
    tgeom_rbound: wp.array(dtype=f64)
    tbody_geomadr: wp.array(dtype=int)
    tbody_geomnum: wp.array(dtype=int)


@wp.func
def widen(v: wp.vec3) -> vec3d:
    return vec3d(f64(v[0]), f64(v[1]), f64(v[2]))


@wp.func
def widen_mat(m: wp.mat33) -> mat33d:
    return mat33d(
        f64(m[0, 0]), f64(m[0, 1]), f64(m[0, 2]),
        f64(m[1, 0]), f64(m[1, 1]), f64(m[1, 2]),
        f64(m[2, 0]), f64(m[2, 1]), f64(m[2, 2]),
    )  # fmt: skip


@wp.func
def lin(x: vec6d) -> vec3d:
    return vec3d(x[0], x[1], x[2])


@wp.func
def ang(x: vec6d) -> vec3d:
    return vec3d(x[3], x[4], x[5])


@wp.func
def six(a: vec3d, b: vec3d) -> vec6d:
    return vec6d(a[0], a[1], a[2], b[0], b[1], b[2])


@wp.func
def twist_wrench(
    el: Elements, medium: Medium, k: int, cull: wp.array2d(dtype=int), w: int, rot: mat33d,
    origin: vec3d, com: vec3d, v: vec3d, omega: vec3d,
) -> vec6d:  # fmt: skip
    """The RFT wrench on tagged body k's geoms in play (not culled in world w) with the body at
    rot, origin (world) moving with CoM velocity v [m/s] and angular velocity omega [rad/s]:
    force [N], torque about the CoM com [N m] (the engine's TwistWrench)."""
    f = vec3d(_Z, _Z, _Z)
    t = vec3d(_Z, _Z, _Z)
    sf = medium.surface
    sf.w = w
    g0 = el.tbody_geomadr[k]
    for g in range(g0, g0 + el.tbody_geomnum[k]):
        if cull[w, g] != 0:
            continue
        e0 = el.tgeom_elemadr[g]
        for i in range(e0, e0 + el.tgeom_elemnum[g]):
            q = quadrature_point(
                el.pos[i], el.normal[i], el.area[i], el.reach[i], el.patch, i, rot, origin,
                omega, v, com, sf, f64(k + 1), medium.use_region, medium.region_lo,
                medium.region_hi,
            )  # fmt: skip
            if q.w > _Z:
                fe = element_force(
                    q.n, q.v, q.w, q.a, medium.co, medium.ay, medium.zeta, medium.lam_rho
                )
                f += fe
                t += wp.cross(q.p - com, fe)
    return six(f, t)


@wp.struct
class Body:
    """A free body's terms over a step (engine lowspeed::Body): twist, the other wrenches on it
    (gravity, the user's, the gyroscopic torque), mass [kg], world inertia about the CoM and its
    inverse."""

    twist: vec6d
    other: vec6d
    mass: f64
    iw: mat33d
    ii: mat33d


@wp.func
def mdot(a: vec6d, b: vec6d, mass: f64, iw: mat33d) -> f64:
    """<a, b>_M = m a_lin . b_lin + a_ang . Iw b_ang."""
    return mass * wp.dot(lin(a), lin(b)) + wp.dot(ang(a), iw * ang(b))


@wp.func
def mdot_body(a: vec6d, b: vec6d, body: Body) -> f64:
    return mdot(a, b, body.mass, body.iw)


@wp.func
def step_work(w: vec6d, twist: vec6d, end: vec6d, other: vec6d, mass: f64, dt: f64, semi: int):
    """2 / dt times the mechanical energy a step gains with the medium's wrench w (engine
    StepWork: the trapezoid, less dt^2/(2m) F_c . (F_c + f) under semi-implicit Euler)."""
    p = wp.dot(w, twist + end)
    if semi != 0:
        p -= dt * wp.dot(lin(other), lin(other) + lin(w)) / mass
    return p


@wp.func
def end_twist(body: Body, w: vec6d, dt: f64) -> vec6d:
    """The explicit step's end twist with the medium's wrench w."""
    tau = ang(body.other) + ang(w)
    return body.twist + six(dt * (lin(body.other) + lin(w)) / body.mass, dt * (body.ii * tau))


@wp.func
def vabs(x: vec6d) -> vec6d:
    return vec6d(wp.abs(x[0]), wp.abs(x[1]), wp.abs(x[2]), wp.abs(x[3]), wp.abs(x[4]), wp.abs(x[5]))


@wp.func
def adds_no_energy(w: vec6d, body: Body, dt: f64, semi: int) -> bool:
    """True if the explicit step with the medium's wrench w adds no mechanical energy (StepWork
    <= rounding of its terms)."""
    end = end_twist(body, w, dt)
    size = wp.dot(vabs(w), vabs(body.twist) + vabs(end))
    if semi != 0:
        o = vec3d(wp.abs(body.other[0]), wp.abs(body.other[1]), wp.abs(body.other[2]))
        aw = vec3d(wp.abs(w[0]), wp.abs(w[1]), wp.abs(w[2]))
        size += dt * wp.dot(o, o + aw) / body.mass
    work = step_work(w, body.twist, end, body.other, body.mass, dt, semi)
    return work <= ROUNDING * size


@wp.func
def stick_fraction(
    stick: vec6d, twist: vec6d, other: vec6d, mass: f64, n2: f64, dt: f64, semi: int
) -> f64:
    """The largest fraction in [0, 1] of the stick wrench that adds no energy (engine
    StickFraction)."""
    size = wp.dot(vabs(stick), vabs(twist))
    if semi != 0:
        for c in range(3):
            size += dt * wp.abs(other[c]) * (wp.abs(other[c]) + wp.abs(stick[c])) / mass
    zero = vec6d()
    if step_work(stick, twist, zero, other, mass, dt, semi) <= ROUNDING * size:
        return _ONE
    a2 = n2 / dt
    b1 = -a2 + wp.dot(stick, twist)
    c0 = _Z
    if semi != 0:
        for c in range(3):
            b1 -= dt * other[c] * stick[c] / mass
            c0 -= dt * other[c] * other[c] / mass
    root = wp.sqrt(b1 * b1 - f64(4.0) * a2 * c0)
    lam = _Z
    if b1 > _Z:
        lam = -f64(2.0) * c0 / (b1 + root)
    else:
        lam = (root - b1) / (f64(2.0) * a2)
    if _Z > lam:
        lam = _Z
    if _ONE < lam:
        lam = _ONE
    return lam


@wp.func
def solve6(a: mat66d, rhs: vec6d) -> vec6d:
    """x with a x = rhs: Gaussian elimination with partial pivoting (engine Solve6)."""
    for k in range(6):
        p = k
        for r in range(k + 1, 6):
            if wp.abs(a[r, k]) > wp.abs(a[p, k]):
                p = r
        if p != k:
            for c in range(6):
                tmp = a[k, c]
                a[k, c] = a[p, c]
                a[p, c] = tmp
            tmp = rhs[k]
            rhs[k] = rhs[p]
            rhs[p] = tmp
        for r in range(k + 1, 6):
            f = a[r, k] / a[k, k]
            for c in range(k, 6):
                a[r, c] = a[r, c] - f * a[k, c]
            rhs[r] = rhs[r] - f * rhs[k]
    x = vec6d()
    for kk in range(6):
        k = 5 - kk
        s = rhs[k]
        for c in range(k + 1, 6):
            s -= a[k, c] * x[c]
        x[k] = s / a[k, k]
    return x


@wp.func
def transverse_basis(twist: vec6d, body: Body, n: f64) -> mat66d:
    """Rows: the twist's unit direction, then 5 directions M-orthonormal to it and to each other
    (pivoted Gram-Schmidt over the scaled coordinate axes; engine TransverseBasis)."""
    basis = mat66d()
    for c in range(6):
        basis[0, c] = twist[c] / n
    for k in range(1, 6):
        best_n = -_ONE
        best = vec6d()
        for j in range(6):
            axis = vec6d()
            mjj = body.mass
            if j >= 3:
                mjj = body.iw[j - 3, j - 3]
            axis[j] = _ONE / wp.sqrt(mjj)
            res = axis
            for q in range(k):
                bq = basis[q]
                res = res - mdot_body(bq, axis, body) * bq
            rn2 = mdot_body(res, res, body)
            rn = wp.sqrt(wp.max(rn2, _Z))
            if rn > best_n:
                best_n = rn
                best = res
        for c in range(6):
            basis[k, c] = best[c] / best_n
    return basis


@wp.func
def m_times(body: Body, x: vec6d) -> vec6d:
    return six(body.mass * lin(x), body.iw * ang(x))


@wp.struct
class Pose:
    """Where a tagged body is in world w, for probes of the medium's wrench."""

    w: int
    k: int
    rot: mat33d
    origin: vec3d
    com: vec3d


@wp.func
def probe(el: Elements, medium: Medium, cull: wp.array2d(dtype=int), at: Pose, x: vec6d):
    return twist_wrench(el, medium, at.k, cull, at.w, at.rot, at.origin, at.com, lin(x), ang(x))


@wp.func
def implicit_wrench(
    el: Elements, medium: Medium, cull: wp.array2d(dtype=int), at: Pose, body: Body, dt: f64,
    semi: int, w: vec6d, h_rel: f64,
):  # fmt: skip
    """One Newton step of backward Euler across the motion (engine ImplicitWrench): returns
    (True, the wrench) or (False, w)."""
    twist = body.twist
    n = wp.sqrt(mdot_body(twist, twist, body))
    basis = transverse_basis(twist, body, n)
    h = h_rel * n
    jac = mat66d()
    for q in range(1, 6):
        e = basis[q]
        pw = probe(el, medium, cull, at, twist + h * e)
        mu = m_times(body, e)
        jac += wp.outer((pw - w) / h, mu)
    end_pure = end_twist(body, w, dt)
    e2 = mdot_body(end_pure, end_pure, body)
    cs = wp.sqrt(wp.max(e2, _Z)) / n
    if not (cs > _Z):
        return False, w
    jac = jac / cs
    mm = mat66d()
    for c in range(3):
        mm[c, c] = body.mass
        for r in range(3):
            mm[3 + r, 3 + c] = body.iw[r, c]
    f = w + jac * solve6(mm - dt * jac, mm * (end_pure - cs * twist))
    for c in range(6):
        if not wp.isfinite(f[c]):
            return False, w
    end = end_twist(body, f, dt)
    if mdot_body(end, twist, body) <= _Z:
        return False, w
    if step_work(f, twist, end, body.other, body.mass, dt, semi) > _Z:
        return False, w
    return True, f


@wp.func
def stick_or_slip(
    el: Elements, medium: Medium, cull: wp.array2d(dtype=int), at: Pose, body: Body,
    free: vec6d, dt: f64, semi: int, w: vec6d, keeps: bool,
):  # fmt: skip
    """Step 3 of the treatment (engine StickOrSlip): (decision, wrench)."""
    mass = body.mass
    omf = ang(free)
    iomf = body.iw * omf
    n2 = mass * wp.dot(lin(free), lin(free)) + wp.dot(omf, iomf)
    if n2 > _Z:
        rw = probe(el, medium, cull, at, free)
        diss = -wp.dot(rw, free)
        if dt * diss < n2:
            end = free + six(dt * lin(rw) / mass, dt * (body.ii * ang(rw)))
            if step_work(rw, body.twist, end, body.other, mass, dt, semi) <= _Z:
                return SLIP, rw
            if keeps and adds_no_energy(w, body, dt, semi):
                return PURE, w
    stick = six(-mass * lin(free) / dt, -iomf / dt)
    lam = stick_fraction(stick, body.twist, body.other, mass, n2, dt, semi)
    return STICK, lam * stick


@wp.func
def treat_body(
    el: Elements, medium: Medium, cull: wp.array2d(dtype=int), at: Pose, body: Body,
    gvec: vec3d, user: vec6d, dt: f64, semi: int, w: vec6d, reach: f64, h_rel: f64,
):  # fmt: skip
    """The treatment of one free body (engine TreatBody): (decision, wrench), w the pure
    wrench."""
    mass = body.mass
    v = lin(body.twist)
    om = ang(body.twist)
    iom = body.iw * om
    v_free = v + dt * (gvec + lin(user) / mass)
    om_free = om + dt * (body.ii * ang(body.other))
    dom_pure = dt * (body.ii * ang(w))
    sq = mass * wp.dot(v, v) + wp.dot(om, iom)
    dxi = wp.dot((v_free - v + dt * lin(w) / mass) * mass, v)
    dxi += wp.dot(om_free - om + dom_pure, iom)
    if sq + reach * dxi > _Z:
        wn2 = wp.dot(lin(w), lin(w)) / mass + wp.dot(ang(w), body.ii * ang(w))
        rdt = reach * dt
        fast = rdt * rdt * wn2 < sq
        if (fast or not (h_rel > _Z)) and adds_no_energy(w, body, dt, semi):
            return PURE, w
        if h_rel > _Z:
            ok, f = implicit_wrench(el, medium, cull, at, body, dt, semi, w, h_rel)
            if ok:
                return IMPLICIT, f
    dec, f2 = stick_or_slip(
        el, medium, cull, at, body, six(v_free, om_free), dt, semi, w, sq + dxi > _Z
    )
    return dec, f2


@wp.kernel
def treat_kernel(
    # Model
    el: Elements, medium: Medium, tbody_bodyid: wp.array(dtype=int),
    tbody_rootid: wp.array(dtype=int), tbody_treat: wp.array(dtype=int), reach: f64, h_rel: f64,
    semi: int, gravity_on: int, timestep: wp.array(dtype=float), gravity: wp.array(dtype=wp.vec3),
    body_mass: wp.array2d(dtype=float), body_inertia: wp.array2d(dtype=wp.vec3),
    body_gravcomp: wp.array2d(dtype=float),
    # Data in
    xpos: wp.array2d(dtype=wp.vec3), xmat: wp.array2d(dtype=wp.mat33),
    xipos: wp.array2d(dtype=wp.vec3), ximat: wp.array2d(dtype=wp.mat33),
    cvel: wp.array2d(dtype=wp.spatial_vector), subtree_com: wp.array2d(dtype=wp.vec3),
    cull: wp.array2d(dtype=int), user: wp.array2d(dtype=wp.spatial_vector),
    # Data in and out
    force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
    # Data out
    decision: wp.array2d(dtype=int),
):  # fmt: skip
    """The low-speed treatment of tagged free body k in world w (engine lowspeed::TreatAll):
    force, torque hold its pure wrench and get the treated one; decision[w, k] its decision."""
    w, k = wp.tid()
    decision[w, k] = PURE
    if tbody_treat[k] == 0:
        return
    dt = f64(timestep[w % timestep.shape[0]])
    if not (dt > f64(0.0)):
        return
    in_play = int(0)
    g0 = el.tbody_geomadr[k]
    for g in range(g0, g0 + el.tbody_geomnum[k]):
        if cull[w, g] == 0:
            in_play = 1
    if in_play == 0:
        return
    b = tbody_bodyid[k]
    wm = w % body_mass.shape[0]
    mass = f64(body_mass[wm, b])
    inertia = widen(body_inertia[w % body_inertia.shape[0], b])
    if not (mass > f64(0.0) and inertia[0] > f64(0.0) and inertia[1] > f64(0.0)
            and inertia[2] > f64(0.0)):  # fmt: skip
        return
    gvec = vec3d(f64(0.0), f64(0.0), f64(0.0))
    if gravity_on != 0:
        comp = f64(body_gravcomp[w % body_gravcomp.shape[0], b])
        gvec = widen(gravity[w % gravity.shape[0]]) * (f64(1.0) - comp)
    x = widen_mat(ximat[w, b])
    body = Body()
    body.iw = x * wp.diag(inertia) * wp.transpose(x)
    body.ii = x * wp.diag(vec3d(f64(1.0) / inertia[0], f64(1.0) / inertia[1],
                                f64(1.0) / inertia[2])) * wp.transpose(x)  # fmt: skip
    body.mass = mass
    tw = cvel[w, b]
    om = vec3d(f64(tw[0]), f64(tw[1]), f64(tw[2]))
    com = widen(xipos[w, b])
    r = com - widen(subtree_com[w, tbody_rootid[k]])
    v = vec3d(f64(tw[3]), f64(tw[4]), f64(tw[5])) + wp.cross(om, r)
    u32 = user[w, k]
    u = vec6d()
    for c in range(6):
        u[c] = f64(u32[c])
    body.twist = six(v, om)
    body.other = six(mass * gvec + lin(u), ang(u) - wp.cross(om, body.iw * om))
    at = Pose()
    at.w = w
    at.k = k
    at.rot = widen_mat(xmat[w, b])
    at.origin = widen(xpos[w, b])
    at.com = com
    pure = six(force[w, k], torque[w, k])
    dec, f = treat_body(el, medium, cull, at, body, gvec, u, dt, semi, pure, reach, h_rel)
    force[w, k] = lin(f)
    torque[w, k] = ang(f)
    decision[w, k] = dec
