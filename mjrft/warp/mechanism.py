"""The low-speed treatment of bodies in mechanisms (engine/mechanism.cc) as a Warp kernel.

The engine's rules, step for step (docs/stability.md "Mechanisms"; engine/mechanism.h states
them): the other generalized forces are those of the previous pass (M qacc_prev - the field's
own), brought to this state for the affine actuators; a body in the medium keeps the pure model
while its twist keeps its sense and changes by less than its size over ``reach`` steps; the
others are held jointly (their twists end the step at zero: the least-norm correction of their
previous holds), and a hold the medium cannot supply slips on the medium's resistance to the
motion it would release, the worst first, until every hold is supplied.

One thread per world: the dense joint-space algebra (Cholesky of M and of the holds' system)
runs in that thread on the world's rows of per-world scratch arrays (``Mech``). It differs from
the engine in two ways that do not change a decision: the factors are rebuilt every pass (the
engine keeps them while the configuration moves less than 1e-12), and MuJoCo Warp's time is
float32, so the predictor accepts a pass one timestep after the last within float32's resolution
of the time.

Frames and units as mjrft.warp.lowspeed: world frame; twists (CoM velocity [m/s], angular
velocity [rad/s]), wrenches (force [N], torque about the CoM [N m]).
"""

from __future__ import annotations

import warp as wp

from mjrft.field import lowspeed as field_lowspeed
from mjrft.warp import lowspeed as ls
from mjrft.warp import surface
from mjrft.warp.law import f64, vec3d
from mjrft.warp.lowspeed import Elements, Medium, vec6d

_Z = wp.constant(f64(0.0))
_ONE = wp.constant(f64(1.0))
#: engine/mechanism.h: kHoldRegularisation, kResistanceReuseM, kResistanceReuseRad.
HOLD_REGULARISATION = wp.constant(f64(field_lowspeed.HOLD_REGULARISATION))
REUSE_M = wp.constant(f64(1e-9))
REUSE_RAD = wp.constant(f64(1e-2))
#: float32's relative resolution: MuJoCo Warp's time advances in float32.
_EPS32 = wp.constant(f64(1.1920928955078125e-07))


@wp.struct
class Mech:
    """The mechanism treatment's tables and per-world state (rows: worlds).

    Tables: nv, nk (tagged bodies), nu; tbody_mech (nk,), dofmask (nk, nv), body size (nk,)
    [m] (largest bounding radius of its geoms), the actuators' affine-rule flags and activation
    addresses (nu,), reach. State (the engine's mech_* arrays): time (3: last pass time,
    recorded, predictor valid), qin (2 nv: qacc and the field's generalized force read),
    tau (nv), prev and in_prev (6 nk), held and in_held (nk), in_force (nu), key (19 nk) and
    rcache (6 nk) of the resistance reuse. Scratch: mm, lo (nv x nv), jac, x (6 nk x nv),
    a, s (6 nk x 6 nk), u, g (nv), rhs, out (6 nk), rows (nk).
    """

    nv: int
    nk: int
    nu: int
    reach: f64
    tbody_mech: wp.array(dtype=int)
    dofmask: wp.array2d(dtype=int)
    size: wp.array(dtype=f64)
    affine: wp.array(dtype=int)
    gainaffine: wp.array(dtype=int)
    biasaffine: wp.array(dtype=int)
    actadr: wp.array(dtype=int)
    ctrllimited: wp.array(dtype=int)
    forcelimited: wp.array(dtype=int)
    time: wp.array2d(dtype=f64)
    qin: wp.array2d(dtype=f64)
    tau: wp.array2d(dtype=f64)
    prev: wp.array2d(dtype=f64)
    in_prev: wp.array2d(dtype=f64)
    held: wp.array2d(dtype=int)
    in_held: wp.array2d(dtype=int)
    in_force: wp.array2d(dtype=f64)
    key: wp.array2d(dtype=f64)
    rcache: wp.array2d(dtype=f64)
    mm: wp.array2d(dtype=f64)
    lo: wp.array2d(dtype=f64)
    jac: wp.array2d(dtype=f64)
    x: wp.array2d(dtype=f64)
    a: wp.array2d(dtype=f64)
    s: wp.array2d(dtype=f64)
    u: wp.array2d(dtype=f64)
    g: wp.array2d(dtype=f64)
    rhs: wp.array2d(dtype=f64)
    out: wp.array2d(dtype=f64)
    rows: wp.array2d(dtype=int)


@wp.struct
class Loads:
    """MuJoCo Warp's model and data arrays the treatment reads (float32 except where noted)."""

    timestep: wp.array(dtype=float)
    body_mass: wp.array2d(dtype=float)
    body_inertia: wp.array2d(dtype=wp.vec3)
    m_rownnz: wp.array(dtype=int)
    m_rowadr: wp.array(dtype=int)
    m_colind: wp.array(dtype=int)
    gainprm: wp.array2d(dtype=wp.types.vector(length=10, dtype=float))
    biasprm: wp.array2d(dtype=wp.types.vector(length=10, dtype=float))
    ctrlrange: wp.array2d(dtype=wp.vec2)
    forcerange: wp.array2d(dtype=wp.vec2)
    actuation_on: int
    clampctrl_on: int
    time: wp.array(dtype=float)
    qvel: wp.array2d(dtype=float)
    qacc: wp.array2d(dtype=float)
    mass_matrix: wp.array2d(dtype=float)
    cdof: wp.array2d(dtype=wp.spatial_vector)
    act: wp.array2d(dtype=float)
    ctrl: wp.array2d(dtype=float)
    actuator_length: wp.array2d(dtype=float)
    actuator_velocity: wp.array2d(dtype=float)
    actuator_force: wp.array2d(dtype=float)
    moment_rownnz: wp.array2d(dtype=int)
    moment_rowadr: wp.array2d(dtype=int)
    moment_colind: wp.array2d(dtype=int)
    actuator_moment: wp.array2d(dtype=float)


@wp.struct
class Kin:
    """A world's kinematics arrays (MuJoCo Warp's Data, float32)."""

    xpos: wp.array2d(dtype=wp.vec3)
    xmat: wp.array2d(dtype=wp.mat33)
    xipos: wp.array2d(dtype=wp.vec3)
    ximat: wp.array2d(dtype=wp.mat33)
    cvel: wp.array2d(dtype=wp.spatial_vector)
    subtree_com: wp.array2d(dtype=wp.vec3)
    geom_xpos: wp.array2d(dtype=wp.vec3)


# ------------------------------------------------------------------------- dense algebra
@wp.func
def cholesky(a: wp.array2d(dtype=f64), w: int, lda: int, n: int, eps: f64) -> bool:
    """In place on row w of a (stride lda): the lower factor of a[:n, :n] + eps I; False if a
    pivot is not positive (engine Cholesky)."""
    for j in range(n):
        s = a[w, lda * j + j] + eps
        for q in range(j):
            s -= a[w, lda * j + q] * a[w, lda * j + q]
        if not (s > _Z):
            return False
        a[w, lda * j + j] = wp.sqrt(s)
        for i in range(j + 1, n):
            v = a[w, lda * i + j]
            for q in range(j):
                v -= a[w, lda * i + q] * a[w, lda * j + q]
            a[w, lda * i + j] = v / a[w, lda * j + j]
    return True


@wp.func
def forward_solve(lo: wp.array2d(dtype=f64), w: int, lda: int, n: int,
                  x: wp.array2d(dtype=f64), xo: int):  # fmt: skip
    """x[w, xo:xo + n] = L^-1 x[w, xo:xo + n] (L: row w of lo, stride lda)."""
    for i in range(n):
        s = x[w, xo + i]
        for q in range(i):
            s -= lo[w, lda * i + q] * x[w, xo + q]
        x[w, xo + i] = s / lo[w, lda * i + i]


@wp.func
def back_solve(lo: wp.array2d(dtype=f64), w: int, lda: int, n: int,
               x: wp.array2d(dtype=f64), xo: int):  # fmt: skip
    """x[w, xo:xo + n] = L^-T x[w, xo:xo + n]."""
    for ii in range(n):
        i = n - 1 - ii
        s = x[w, xo + i]
        for q in range(i + 1, n):
            s -= lo[w, lda * q + i] * x[w, xo + q]
        x[w, xo + i] = s / lo[w, lda * i + i]


@wp.func
def cho_solve(lo: wp.array2d(dtype=f64), w: int, lda: int, n: int,
              x: wp.array2d(dtype=f64), xo: int):  # fmt: skip
    forward_solve(lo, w, lda, n, x, xo)
    back_solve(lo, w, lda, n, x, xo)


@wp.func
def row_dot(jac: wp.array2d(dtype=f64), w: int, r: int, x: wp.array2d(dtype=f64), nv: int):
    """jac[r, :nv] . x[w, :nv] (jac: row w, stride nv)."""
    acc = _Z
    for j in range(nv):
        acc += jac[w, nv * r + j] * x[w, j]
    return acc


@wp.func
def row_dot32(jac: wp.array2d(dtype=f64), w: int, r: int, x: wp.array2d(dtype=float), nv: int):
    acc = _Z
    for j in range(nv):
        acc += jac[w, nv * r + j] * f64(x[w, j])
    return acc


# ----------------------------------------------------------------------- the bodies' terms
@wp.func
def body_jacobian(mc: Mech, kin: Kin, ld: Loads, w: int, k: int, b: int, root: int, row: int):
    """Rows [row, row + 6) of mc.jac (stride nv): tagged body k's Jacobian at its CoM (CoM
    velocity, angular velocity; world). cdof is a motion at the root's subtree CoM."""
    nv = mc.nv
    r = ls.widen(kin.xipos[w, b]) - ls.widen(kin.subtree_com[w, root])
    for j in range(nv):
        for q in range(6):
            mc.jac[w, nv * (row + q) + j] = _Z
        if mc.dofmask[k, j] != 0:
            cd = ld.cdof[w, j]
            om = vec3d(f64(cd[0]), f64(cd[1]), f64(cd[2]))
            v = vec3d(f64(cd[3]), f64(cd[4]), f64(cd[5])) + wp.cross(om, r)
            for q in range(3):
                mc.jac[w, nv * (row + q) + j] = v[q]
                mc.jac[w, nv * (row + 3 + q) + j] = om[q]


@wp.func
def submerged(
    el: Elements, medium: Medium, cull: wp.array2d(dtype=int), kin: Kin, w: int, k: int, b: int
) -> bool:
    """True if an element of tagged body k's geoms in play is below the free surface (engine
    Submerged)."""
    pos = ls.widen(kin.xpos[w, b])
    rot = ls.widen_mat(kin.xmat[w, b])
    sf = medium.surface
    sf.w = w
    flat = sf.kind == surface.FLAT
    g0 = el.tbody_geomadr[k]
    for g in range(g0, g0 + el.tbody_geomnum[k]):
        if cull[w, g] != 0:
            continue
        r = el.tgeom_rbound[g]
        top = surface.ceiling(sf)
        if r > _Z:
            c = ls.widen(kin.geom_xpos[w, el.tgeom_geomid[g]])
            top = surface.highest_near(sf, c[0], c[1], r)
        e0 = el.tgeom_elemadr[g]
        for e in range(e0, e0 + el.tgeom_elemnum[g]):
            p = rot * el.pos[e] + pos
            if flat or p[2] >= top:
                if p[2] < top:
                    return True
                continue
            if surface.depth(sf, p, f64(k + 1)) > _Z:
                return True
    return False


@wp.func
def actuator_force(mc: Mech, ld: Loads, w: int, a: int) -> f64:
    """Force [N] of actuator a by MuJoCo's rule for fixed/affine gains and affine biases
    (engine ActuatorForce)."""
    if ld.actuation_on == 0:
        return _Z
    adr = mc.actadr[a]
    x = _Z
    if adr >= 0:
        x = f64(ld.act[w, adr])
    else:
        x = f64(ld.ctrl[w, a])
        if mc.ctrllimited[a] != 0 and ld.clampctrl_on != 0:
            cr = ld.ctrlrange[w % ld.ctrlrange.shape[0], a]
            x = wp.min(wp.max(x, f64(cr[0])), f64(cr[1]))
    length = f64(ld.actuator_length[w, a])
    velocity = f64(ld.actuator_velocity[w, a])
    g = ld.gainprm[w % ld.gainprm.shape[0], a]
    bp = ld.biasprm[w % ld.biasprm.shape[0], a]
    gain = f64(g[0])
    if mc.gainaffine[a] != 0:
        gain += f64(g[1]) * length + f64(g[2]) * velocity
    bias = _Z
    if mc.biasaffine[a] != 0:
        bias = f64(bp[0]) + f64(bp[1]) * length + f64(bp[2]) * velocity
    f = gain * x + bias
    if mc.forcelimited[a] != 0:
        fr = ld.forcerange[w % ld.forcerange.shape[0], a]
        f = wp.min(wp.max(f, f64(fr[0])), f64(fr[1]))
    return f


@wp.func
def world_inertia(kin: Kin, ld: Loads, w: int, b: int) -> wp.mat33d:
    x = ls.widen_mat(kin.ximat[w, b])
    inertia = ls.widen(ld.body_inertia[w % ld.body_inertia.shape[0], b])
    return x * wp.diag(inertia) * wp.transpose(x)


@wp.func
def wrench_of(force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d), w: int, k: int):
    return ls.six(force[w, k], torque[w, k])


# ------------------------------------------------------------------------- the steps
@wp.func
def setup(mc: Mech, kin: Kin, ld: Loads, tbody_bodyid: wp.array(dtype=int),
          tbody_rootid: wp.array(dtype=int), w: int, n: int, dt: f64) -> bool:  # fmt: skip
    """M = L L^T, the Jacobians of the rows and the free velocity u (engine Setup)."""
    nv = mc.nv
    for i in range(nv * nv):
        mc.mm[w, i] = _Z
    for i in range(nv):
        a0 = ld.m_rowadr[i]
        for a in range(a0, a0 + ld.m_rownnz[i]):
            j = ld.m_colind[a]
            v = f64(ld.mass_matrix[w, a])
            mc.mm[w, nv * i + j] = v
            mc.mm[w, nv * j + i] = v
    for i in range(nv * nv):
        mc.lo[w, i] = mc.mm[w, i]
    if not cholesky(mc.lo, w, nv, nv, _Z):
        return False
    for a in range(n):
        k = mc.rows[w, a]
        body_jacobian(mc, kin, ld, w, k, tbody_bodyid[k], tbody_rootid[k], 6 * a)
    for i in range(nv):  # tau_other = M qacc_prev - tau_field_prev
        acc = -mc.qin[w, nv + i]
        for j in range(nv):
            acc += mc.mm[w, nv * i + j] * mc.qin[w, j]
        mc.u[w, i] = acc
    for a in range(mc.nu):  # the affine actuators brought to this state
        if mc.affine[a] == 0:
            continue
        df = actuator_force(mc, ld, w, a) - mc.in_force[w, a]
        if df == _Z:
            continue
        q0 = ld.moment_rowadr[w, a]
        for q in range(q0, q0 + ld.moment_rownnz[w, a]):
            c = ld.moment_colind[w, q]
            mc.u[w, c] = mc.u[w, c] + f64(ld.actuator_moment[w, q]) * df
    cho_solve(mc.lo, w, nv, nv, mc.u, 0)
    for i in range(nv):
        mc.u[w, i] = f64(ld.qvel[w, i]) + dt * mc.u[w, i]
    return True


@wp.func
def classify(mc: Mech, kin: Kin, ld: Loads, tbody_bodyid: wp.array(dtype=int),
             force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
             code: wp.array2d(dtype=int), w: int, n: int, dt: f64):  # fmt: skip
    """code = STICK for the bodies in the medium that do not keep the pure model, and for those
    held at the last pass, which the prediction counts with their hold (engine Classify)."""
    nv = mc.nv
    for j in range(nv):
        mc.g[w, j] = _Z
    for a in range(n):
        k = mc.rows[w, a]
        for r in range(6):
            wr = reference(mc, force, torque, w, k, r)
            for j in range(nv):
                mc.g[w, j] = mc.g[w, j] + mc.jac[w, nv * (6 * a + r) + j] * wr
    cho_solve(mc.lo, w, nv, nv, mc.g, 0)
    for a in range(n):
        k = mc.rows[w, a]
        if mc.in_held[w, k] != 0:
            code[w, k] = ls.STICK
            continue
        b = tbody_bodyid[k]
        iw = world_inertia(kin, ld, w, b)
        mass = f64(ld.body_mass[w % ld.body_mass.shape[0], b])
        xi = vec6d()
        dxi = vec6d()
        for r in range(6):
            xi[r] = row_dot32(mc.jac, w, 6 * a + r, ld.qvel, nv)
            dxi[r] = row_dot(mc.jac, w, 6 * a + r, mc.u, nv) - xi[r]
            dxi[r] = dxi[r] + dt * row_dot(mc.jac, w, 6 * a + r, mc.g, nv)
        pred = xi + mc.reach * dxi
        n2 = ls.mdot(xi, xi, mass, iw)
        keeps = ls.mdot(pred, xi, mass, iw) > _Z
        fast = mc.reach * mc.reach * ls.mdot(dxi, dxi, mass, iw) < n2
        if not (keeps and fast):
            code[w, k] = ls.STICK


@wp.func
def hold_system(mc: Mech, w: int, n: int):
    """X = L^-1 J^T as rows and A = X^T X of the bodies in the medium (engine HoldSystem)."""
    nv = mc.nv
    lda = 6 * mc.nk
    for r in range(6 * n):
        for j in range(nv):
            mc.x[w, nv * r + j] = mc.jac[w, nv * r + j]
        forward_solve(mc.lo, w, nv, nv, mc.x, nv * r)
    for r in range(6 * n):
        for c in range(r, 6 * n):
            acc = _Z
            for j in range(nv):
                acc += mc.x[w, nv * r + j] * mc.x[w, nv * c + j]
            mc.a[w, lda * r + c] = acc
            mc.a[w, lda * c + r] = acc


@wp.func
def reference(mc: Mech, force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
              w: int, k: int, r: int) -> f64:  # fmt: skip
    """W_ref of a held body: its hold in the pass that read the loads, else its pure wrench."""
    if mc.in_held[w, k] != 0:
        return mc.in_prev[w, 6 * k + r]
    return wrench_of(force, torque, w, k)[r]


@wp.func
def solve_holds(mc: Mech, force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
                code: wp.array2d(dtype=int), w: int, n: int, dt: f64) -> bool:  # fmt: skip
    """The held bodies' wrenches (mc.out rows) that end their twists at zero (engine
    SolveHolds); False if the system cannot be factored."""
    nv = mc.nv
    lda = 6 * mc.nk
    h = int(0)
    for a in range(n):
        if code[w, mc.rows[w, a]] == ls.STICK:
            h += 6
    if h == 0:
        return True
    q = int(0)
    for a in range(n):
        if code[w, mc.rows[w, a]] != ls.STICK:
            continue
        for r0 in range(6):
            r = 6 * a + r0
            acc = -row_dot(mc.jac, w, r, mc.u, nv) / dt
            for a2 in range(n):
                k2 = mc.rows[w, a2]
                held = code[w, k2] == ls.STICK
                for c0 in range(6):
                    wv = mc.out[w, 6 * a2 + c0]
                    if held:
                        wv = reference(mc, force, torque, w, k2, c0)
                    acc -= mc.a[w, lda * r + 6 * a2 + c0] * wv
            mc.rhs[w, q] = acc
            q += 1
    qr = int(0)
    for a in range(n):
        if code[w, mc.rows[w, a]] != ls.STICK:
            continue
        for r0 in range(6):
            qc = int(0)
            for a2 in range(n):
                if code[w, mc.rows[w, a2]] != ls.STICK:
                    continue
                for c0 in range(6):
                    mc.s[w, lda * qr + qc] = mc.a[w, lda * (6 * a + r0) + 6 * a2 + c0]
                    qc += 1
            qr += 1
    for j in range(h):
        mc.s[w, lda * j + j] = mc.s[w, lda * j + j] * (_ONE + HOLD_REGULARISATION)
    if not cholesky(mc.s, w, lda, h, f64(1e-300)):
        return False
    cho_solve(mc.s, w, lda, h, mc.rhs, 0)
    q = int(0)
    for a in range(n):
        k = mc.rows[w, a]
        if code[w, k] != ls.STICK:
            continue
        for r in range(6):
            mc.out[w, 6 * a + r] = reference(mc, force, torque, w, k, r) + mc.rhs[w, q]
            q += 1
    return True


@wp.func
def resistance(el: Elements, medium: Medium, cull: wp.array2d(dtype=int), mc: Mech, kin: Kin,
               w: int, k: int, b: int, twist: vec6d) -> vec6d:  # fmt: skip
    """The RFT wrench on tagged body k moving with twist, reused while the body and the twist's
    direction are where they were when last evaluated (engine Resistance)."""
    size = mc.size[k]
    norm = _Z
    for r in range(6):
        v = twist[r]
        if r >= 3:
            v = v * size
        norm += v * v
    norm = wp.sqrt(norm)
    xi = ls.widen(kin.xipos[w, b])
    xm = ls.widen_mat(kin.ximat[w, b])
    o = 19 * k
    same = mc.key[w, o + 18] == _ONE
    for r in range(3):
        if wp.abs(xi[r] - mc.key[w, o + r]) > REUSE_M:
            same = False
    for r in range(9):
        if wp.abs(xm[r // 3, r % 3] * size - mc.key[w, o + 3 + r]) > REUSE_M:
            same = False
    for r in range(6):
        v = twist[r]
        if r >= 3:
            v = v * size
        if not (wp.abs(v / norm - mc.key[w, o + 12 + r]) <= REUSE_RAD):
            same = False
    out = vec6d()
    if same:
        for r in range(6):
            out[r] = mc.rcache[w, 6 * k + r]
        return out
    at = ls.Pose()
    at.w = w
    at.k = k
    at.rot = ls.widen_mat(kin.xmat[w, b])
    at.origin = ls.widen(kin.xpos[w, b])
    at.com = xi
    out = ls.probe(el, medium, cull, at, twist)
    for r in range(6):
        mc.rcache[w, 6 * k + r] = out[r]
    for r in range(3):
        mc.key[w, o + r] = xi[r]
    for r in range(9):
        mc.key[w, o + 3 + r] = xm[r // 3, r % 3] * size
    for r in range(6):
        v = twist[r]
        if r >= 3:
            v = v * size
        mc.key[w, o + 12 + r] = v / norm
    mc.key[w, o + 18] = _ONE
    return out


@wp.func
def hold_power(mc: Mech, w: int, a: int, dt: f64):
    """(power the hold of held row a dissipates, xf = -dt A_aa W_a: the twist it would take
    released alone) (engine HoldPower)."""
    lda = 6 * mc.nk
    xf = vec6d()
    for r in range(6):
        acc = _Z
        for c in range(6):
            acc += mc.a[w, lda * (6 * a + r) + 6 * a + c] * mc.out[w, 6 * a + c]
        xf[r] = -dt * acc
    hold = _Z
    for r in range(6):
        hold -= mc.out[w, 6 * a + r] * xf[r]
    return hold, xf


@wp.func
def worst_hold(el: Elements, medium: Medium, cull: wp.array2d(dtype=int), mc: Mech, kin: Kin,
               tbody_bodyid: wp.array(dtype=int), tbody_rootid: wp.array(dtype=int),
               force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
               code: wp.array2d(dtype=int), w: int, n: int, dt: f64):  # fmt: skip
    """(row of the held body the medium fails to supply by most or -1, its slip wrench)
    (engine WorstHold: the hold of most power first, then only holds whose power exceeds the
    largest shortfall found)."""
    first = int(-1)
    most = _Z
    for a in range(n):
        if code[w, mc.rows[w, a]] != ls.STICK:
            continue
        hold, xf = hold_power(mc, w, a, dt)
        if hold > most:
            first = a
            most = hold
    worst = int(-1)
    margin = _Z
    slip = vec6d()
    for i in range(-1, n):
        a = i
        if i < 0:
            a = first
        if a < 0 or (i >= 0 and a == first):
            continue
        k = mc.rows[w, a]
        if code[w, k] != ls.STICK:
            continue
        hold, xf = hold_power(mc, w, a, dt)
        if not (hold > _Z):
            continue
        if worst >= 0 and hold <= margin:
            continue  # no shorter than the worst found: the resistance dissipates
        r_w = resistance(el, medium, cull, mc, kin, w, k, tbody_bodyid[k], xf)
        med = -wp.dot(r_w, xf)
        short_by = hold - med - ls.ROUNDING * (hold + wp.abs(med))
        if short_by > margin or (worst >= 0 and short_by == margin and a < worst):
            worst = a
            margin = short_by
            slip = r_w
    if worst >= 0:
        k = mc.rows[w, worst]
        b = tbody_bodyid[k]
        tw = kin.cvel[w, b]
        om = vec3d(f64(tw[0]), f64(tw[1]), f64(tw[2]))
        arm = ls.widen(kin.xipos[w, b]) - ls.widen(kin.subtree_com[w, tbody_rootid[k]])
        v = vec3d(f64(tw[3]), f64(tw[4]), f64(tw[5])) + wp.cross(om, arm)
        if wp.dot(ls.lin(slip), v) + wp.dot(ls.ang(slip), om) > _Z:
            slip = wrench_of(force, torque, w, k)  # R would push along the motion: pure model
    return worst, slip


@wp.func
def predictor_valid(mc: Mech, w: int, time: f64, dt: f64, same_time: bool) -> bool:
    """True if the qacc read by the first pass at this time described this state's loads (the
    pass before it was one timestep before, within float32's resolution of the time)."""
    if same_time:
        return mc.time[w, 2] == _ONE
    t0 = mc.time[w, 0]
    tol = f64(1e-9) * dt + f64(4.0) * _EPS32 * (wp.abs(time) + dt)
    ok = mc.time[w, 1] == _ONE and wp.abs(time - (t0 + dt)) <= tol
    mc.time[w, 0] = time
    mc.time[w, 1] = _ONE
    if ok:
        mc.time[w, 2] = _ONE
    else:
        mc.time[w, 2] = _Z
    return ok


@wp.func
def read_loads(mc: Mech, ld: Loads, w: int):
    """The first pass at a new time reads the loads of the previous pass: its qacc, the field's
    generalized force then, its holds and the actuators' forces (engine TreatMechanisms 1)."""
    nv = mc.nv
    for i in range(nv):
        mc.qin[w, i] = f64(ld.qacc[w, i])
        mc.qin[w, nv + i] = mc.tau[w, i]
    for i in range(6 * mc.nk):
        mc.in_prev[w, i] = mc.prev[w, i]
    for a in range(mc.nu):
        mc.in_force[w, a] = f64(ld.actuator_force[w, a])
    for k in range(mc.nk):
        mc.in_held[w, k] = mc.held[w, k]


@wp.func
def gather(el: Elements, medium: Medium, cull: wp.array2d(dtype=int), kin: Kin, mc: Mech,
           tbody_bodyid: wp.array(dtype=int), w: int) -> int:  # fmt: skip
    """The tagged mechanism bodies in the medium (a geom in play with an element below the
    surface) into mc.rows, in order; returns their number (engine Gather)."""
    n = int(0)
    for k in range(mc.nk):
        if mc.tbody_mech[k] != 0:
            play = int(0)
            g0 = el.tbody_geomadr[k]
            for g in range(g0, g0 + el.tbody_geomnum[k]):
                if cull[w, g] == 0:
                    play = 1
            if play != 0:
                if submerged(el, medium, cull, kin, w, k, tbody_bodyid[k]):
                    mc.rows[w, n] = k
                    n += 1
    return n


@wp.func
def record(mc: Mech, force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
           code: wp.array2d(dtype=int), w: int, n: int):  # fmt: skip
    """The treated wrenches into force, torque; what the field applies (tau) and the holds
    (held, prev) recorded for the next pass."""
    nv = mc.nv
    for i in range(nv):
        mc.tau[w, i] = _Z
    for a in range(n):
        for r in range(6):
            for j in range(nv):
                mc.tau[w, j] = mc.tau[w, j] + mc.jac[w, nv * (6 * a + r) + j] * mc.out[w, 6 * a + r]
    for k in range(mc.nk):
        mc.held[w, k] = 0
    for a in range(n):
        k = mc.rows[w, a]
        force[w, k] = vec3d(mc.out[w, 6 * a], mc.out[w, 6 * a + 1], mc.out[w, 6 * a + 2])
        torque[w, k] = vec3d(mc.out[w, 6 * a + 3], mc.out[w, 6 * a + 4], mc.out[w, 6 * a + 5])
        if code[w, k] == ls.STICK:
            mc.held[w, k] = 1
            for r in range(6):
                mc.prev[w, 6 * k + r] = mc.out[w, 6 * a + r]


@wp.kernel
def mechanism_kernel(
    # Model
    el: Elements, medium: Medium, tbody_bodyid: wp.array(dtype=int),
    tbody_rootid: wp.array(dtype=int),
    # Data in
    kin: Kin, ld: Loads, cull: wp.array2d(dtype=int),
    # Data in and out
    mc: Mech, force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
    decision: wp.array2d(dtype=int),
):  # fmt: skip
    """The treatment of world w's tagged mechanism bodies in the medium (engine
    TreatMechanisms): their rows of force, torque (pure wrenches in) become the treated
    wrenches; decision gets PURE, STICK (held) or SLIP."""
    w = wp.tid()
    nv = mc.nv
    nk = mc.nk
    code = decision
    for k in range(nk):
        if mc.tbody_mech[k] != 0:
            code[w, k] = ls.PURE
    dt = f64(ld.timestep[w % ld.timestep.shape[0]])
    time = f64(ld.time[w])
    # 1. The loads: a repeated pass at the same time reads what the first read.
    same_time = mc.time[w, 1] == _ONE and time == mc.time[w, 0]
    valid = predictor_valid(mc, w, time, dt, same_time)
    if not same_time:
        read_loads(mc, ld, w)
    n = gather(el, medium, cull, kin, mc, tbody_bodyid, w)
    ok = n > 0 and nv > 0 and dt > _Z
    if ok:
        ok = setup(mc, kin, ld, tbody_bodyid, tbody_rootid, w, n, dt)
    if not ok:
        for i in range(nv):
            mc.tau[w, i] = _Z
        for k in range(nk):
            mc.held[w, k] = 0
        return
    # 2. Which bodies keep the pure model.
    if valid:
        classify(mc, kin, ld, tbody_bodyid, force, torque, code, w, n, dt)
    anyheld = int(0)
    for a in range(n):
        if code[w, mc.rows[w, a]] == ls.STICK:
            anyheld = 1
    if anyheld != 0:
        hold_system(mc, w, n)
    # 3-4. Hold the others; release the worst-supplied hold on its resistance, and again.
    for a in range(n):
        wr = wrench_of(force, torque, w, mc.rows[w, a])
        for r in range(6):
            mc.out[w, 6 * a + r] = wr[r]
    for _it in range(n + 1):
        if not solve_holds(mc, force, torque, code, w, n, dt):
            for a in range(n):  # not solvable: the pure model
                k = mc.rows[w, a]
                code[w, k] = ls.PURE
                wr = wrench_of(force, torque, w, k)
                for r in range(6):
                    mc.out[w, 6 * a + r] = wr[r]
            break
        a, slip = worst_hold(el, medium, cull, mc, kin, tbody_bodyid, tbody_rootid, force,
                             torque, code, w, n, dt)  # fmt: skip
        if a < 0:
            break
        code[w, mc.rows[w, a]] = ls.SLIP
        for r in range(6):
            mc.out[w, 6 * a + r] = slip[r]
    record(mc, force, torque, code, w, n)
