"""The field's whole per-pass work in native code: no Python between MuJoCo and the kernel.

A field publishes its static tables (elements, geom blocks, parameters) and, per MjData, the
addresses of that MjData's arrays, as plain uint64 words (see the layouts below). ``step`` reads
them through raw pointers, checks the state is finite, culls geoms by their bounding spheres,
evaluates the fused RFT kernel, and applies the ``xfrc_applied`` ownership protocol of
``mjrft.field`` (user part + RFT in the intruding rows). The passive-callback guard
(``mjrft._callback``) calls it directly; Python is entered only for an MjData seen for the first
time (to register it) and when ``step`` reports a problem (so Python can raise a proper error).

Everything here is an implementation detail of ``mjrft.field``; the arrays are owned by the
field, which keeps them alive while their addresses are published.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from mjrft.core import kernel as _kernel

# Words of a field's static table (uint64 each; addresses of arrays owned by the field).
F_NELEM, F_CENT, F_NORM, F_AREA = 0, 1, 2, 3
F_NGEOM, F_GINT, F_GRB = 4, 5, 6
F_NBODY_TAGGED, F_BODIES, F_PARAMS, F_COEF = 7, 8, 9, 10
F_NBODY, F_LAST_WRENCH, F_ELEM_FORCE, F_STATS = 11, 12, 13, 14
F_RING, F_RING_SIZE, F_DIRTY = 15, 16, 17
F_MODEL, F_ELIGIBLE, F_DECISION, F_SCRATCH = 18, 19, 20, 21
F_WORK, F_FROZEN = 22, 23  # per-pass work arrays (int64, float64): no allocation per pass
FIELD_WORDS = 24
# Layout of the int64 work array (F_WORK): keep (nbody), frz (nbody), cull_row (G), slow (n_bt).
# Words of the model-address table (F_MODEL): live MjModel fields the low-speed treatment reads
# (a user may change them between steps: domain randomisation, a new timestep).
M_TIMESTEP, M_GRAVITY, M_DISABLEFLAGS, M_BODY_MASS, M_BODY_INERTIA, M_BODY_GRAVCOMP = range(6)
M_INTEGRATOR = 6
MODEL_WORDS = 7
# mjtIntegrator.mjINT_RK4 (checked against mujoco by the tests; this module imports no mujoco).
INT_RK4 = 1
# Columns of the (G, 5) int64 geom table.
G_GEOM, G_BODY, G_START, G_STOP, G_ROOT = 0, 1, 2, 3, 4
# Float64 parameters: surface_z, zeta, alpha_y, use_region, region (6), low-speed treatment on,
# its reach, MuJoCo's gravity-disable bit, mjrft.lowspeed.RK4_HOLD_STEPS and JACOBIAN_STEP.
P_SURFACE, P_ZETA, P_AY, P_USE_REGION, P_REGION = 0, 1, 2, 3, 4
P_TREAT, P_REACH, P_DSBL_GRAVITY, P_RK4_HOLD, P_JAC_STEP = 10, 11, 12, 13, 14
N_PARAMS = 15
# Words of a per-MjData entry.
D_XPOS, D_XMAT, D_XIPOS, D_CVEL, D_SUBTREE_COM, D_GEOM_XPOS, D_XFRC = 0, 1, 2, 3, 4, 5, 6
D_USER, D_WRITTEN, D_XIMAT = 7, 8, 9
D_TIME, D_RK4 = 10, 11  # address of d->time; the MjData's RK4 stage record (rk4_hold)
DATA_WORDS = 12
# The RK4 stage record: time of the last evaluated pass, the passes since, then per tagged body
# a block of RK4_BODY words: its mode for stages 2-4, the twist (v at the CoM, omega; world)
# of stage 1 and the implicit correction J'd of stage 1 (world force, torque about the CoM).
RK4_HEAD, RK4_BODY = 2, 13
# Modes: evaluate the pure model in every stage; hold stage 1's wrench; evaluate the model at the
# stage's pose with stage 1's twist, plus stage 1's implicit correction (mjrft.lowspeed.IMPLICIT).
RK4_PER_STAGE, RK4_HOLD, RK4_FROZEN = 0, 1, 2
# mjrft.lowspeed.ROUNDING (checked by the tests): a relative size below which an energy
# balance whose terms cancel counts as zero.
ROUNDING = 64.0 * np.finfo(np.float64).eps
# Work counters (F_STATS): passes, triangles evaluated, acting, bodies stuck, bodies slipping
# on the free direction's force, bodies moved with the linearly implicit force (mjrft.lowspeed).
N_STATS = 6
# Return codes of step: 0 ok; -1 - k means tagged body k (in the field's body order) is not
# finite.
OK = 0


def _ptr_intrinsic(dtype):
    @intrinsic
    def as_ptr(typingctx, addr):
        sig = types.CPointer(dtype)(types.uint64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))

        return sig, codegen

    return as_ptr


f64_ptr = _ptr_intrinsic(types.float64)
i64_ptr = _ptr_intrinsic(types.int64)
u64_ptr = _ptr_intrinsic(types.uint64)
i32_ptr = _ptr_intrinsic(types.int32)


@numba.njit(inline="always", cache=True)
def _statics(f):
    """The field's static arrays from its table f (see the F_* layout)."""
    n_el, n_geom, n_bt = f[F_NELEM], f[F_NGEOM], f[F_NBODY_TAGGED]
    return (
        numba.carray(f64_ptr(f[F_CENT]), (n_el, 3)),
        numba.carray(f64_ptr(f[F_NORM]), (n_el, 3)),
        numba.carray(f64_ptr(f[F_AREA]), n_el),
        numba.carray(i64_ptr(f[F_GINT]), (n_geom, 5)),
        numba.carray(f64_ptr(f[F_GRB]), n_geom),
        numba.carray(i64_ptr(f[F_BODIES]), n_bt),
        numba.carray(f64_ptr(f[F_PARAMS]), N_PARAMS),
        numba.carray(f64_ptr(f[F_PARAMS] + 8 * P_REGION), (2, 3)),  # region, no allocation
        numba.carray(f64_ptr(f[F_COEF]), 18),
        numba.carray(i64_ptr(f[F_STATS]), N_STATS),
    )


@numba.njit(inline="always", cache=True)
def _culled(geom_xpos, geom, r, surface_z, use_region, region):
    """True if a geom's bounding sphere (centre geom_xpos[geom], radius r) cannot touch the
    medium: entirely above the surface or outside the region. r = 0 (unknown) never culls."""
    if r <= 0.0:
        return False
    if geom_xpos[geom, 2] - r >= surface_z:
        return True
    if use_region:
        for c in range(3):
            gc = geom_xpos[geom, c]
            if gc + r < region[0, c] or gc - r > region[1, c]:
                return True
    return False


@numba.njit(inline="always", cache=True)
def _first_bad_body(bodies, xpos, cvel):
    """Index k of the first tagged body with a non-finite position or velocity, or -1."""
    for k in range(bodies.shape[0]):
        b = bodies[k]
        for c in range(3):
            if not np.isfinite(xpos[b, c]):
                return k
        for c in range(6):
            if not np.isfinite(cvel[b, c]):
                return k
    return -1


@numba.njit(cache=True)
def rk4_hold(t, h, rec):
    """True if a forward pass at time t [s] is stage 2, 3 or 4 of an RK4 step whose stage 1 this
    field evaluated; then each body follows the mode stage 1 recorded for it: stuck, slipping or
    reversing within ``RK4_HOLD_STEPS`` ones keep that stage's wrench in ``xfrc_applied``
    (RK4_HOLD); ones moved by the linearly implicit step feel the model at the stage's pose but
    stage 1's twist, plus stage 1's implicit correction (RK4_FROZEN); the others feel the pure
    model of each stage.

    MuJoCo's RK4 (``mj_RungeKutta``) runs its stages at t0, t0 + h/2, t0 + h/2, t0 + h, with the
    stage times computed as ``t0 + c h``; the same expression here matches them exactly. rec
    (RK4_HEAD + RK4_BODY tagged bodies,) is the MjData's record: time of the last evaluated
    pass, the passes since (1..4), then the bodies' blocks (written by ``step``; unused here).
    Any other pattern (a user's ``mj_forward``, a new step at t0 + h) evaluates afresh, which is
    always safe. Why hold: the time-stepping stick needs the force constant over the step to end
    it at rest (per stage it keeps 3/8 of the velocity), and RK4's stage combination does not
    damp a torque that jumps with the sign of a slow spin (benchmarks/RESULTS.md, "RK4"). Why
    freeze the twist rather than hold: across a slow motion RFT is stiff (its stages would
    overshoot, as the explicit step does), but along it the force changes with depth, and a held
    force lags it (a dropped 1 g sphere at 5 ms stopped 10.6 % too deep).
    """
    n = rec[1]
    if (n == 1.0 or n == 2.0) and t == rec[0] + 0.5 * h:
        rec[1] = n + 1.0
        return True
    if n == 3.0 and t == rec[0] + 1.0 * h:
        rec[1] = 4.0
        return True
    rec[0] = t
    rec[1] = 1.0
    return False


@numba.njit(cache=True, error_model="numpy")
def _body_twist_wrench(
    b, cull_row, gint, cent, norm, area, xmat, xpos, xipos, v, om, co, ay, zeta, surface_z,
    use_region, region, scratch, out,
):  # fmt: skip
    """Set out (6,) to the RFT wrench on body b's geoms in play moving with the twist (v at the
    CoM [m/s], om [rad/s]; world frame); torque about the CoM. Returns the number of elements
    evaluated and acting."""
    out[:] = 0.0
    evaluated = 0
    acting = 0
    for g in range(gint.shape[0]):
        if gint[g, G_BODY] != b or cull_row[g]:
            continue
        acting += _kernel.body_wrench(
            cent, norm, area, gint[g, G_START], gint[g, G_STOP], xmat[b], xpos[b], om, v,
            xipos[b], xipos[b], co, ay, zeta, surface_z, use_region, region, out, scratch,
        )  # fmt: skip
        evaluated += gint[g, G_STOP] - gint[g, G_START]
    return evaluated, acting


@numba.njit(cache=True)
def _m_dot(a, b, mass, iw):
    """<a, b>_M = m a_lin . b_lin + a_ang . Iw b_ang of two (6,) twists (mjrft.lowspeed)."""
    s = mass * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
    for r in range(3):
        for c in range(3):
            s += a[3 + r] * iw[r, c] * b[3 + c]
    return s


@numba.njit(cache=True, error_model="numpy")
def _solve6(a, rhs):
    """Solve a (6, 6) x = rhs (6,) by Gaussian elimination with partial pivoting (a, rhs are
    overwritten); returns x (non-finite if a is singular)."""
    n = 6
    for k in range(n):
        p = k
        for r in range(k + 1, n):
            if abs(a[r, k]) > abs(a[p, k]):
                p = r
        if p != k:
            for c in range(n):
                a[k, c], a[p, c] = a[p, c], a[k, c]
            rhs[k], rhs[p] = rhs[p], rhs[k]
        for r in range(k + 1, n):
            f = a[r, k] / a[k, k]
            for c in range(k, n):
                a[r, c] -= f * a[k, c]
            rhs[r] -= f * rhs[k]
    x = np.empty(n)
    for k in range(n - 1, -1, -1):
        s = rhs[k]
        for c in range(k + 1, n):
            s -= a[k, c] * x[c]
        x[k] = s / a[k, k]
    return x


@numba.njit(cache=True, error_model="numpy")
def _step_work(w, twist, end, other, mass, dt, semi):
    """2 / dt times the energy a step gains with the medium's wrench w (mjrft.lowspeed.step_work).
    (6,) arrays, world frame; semi: positions advance with the end velocity (not RK4)."""
    p = 0.0
    for c in range(6):
        p += w[c] * (twist[c] + end[c])
    if semi:
        q = 0.0
        for c in range(3):
            q += other[c] * (other[c] + w[c])
        p -= dt * q / mass
    return p


@numba.njit(cache=True, error_model="numpy")
def _stick_fraction(stick, twist, other, mass, n2, dt, semi):
    """The largest fraction of the stick wrench that adds no energy over the step
    (mjrft.lowspeed.stick_fraction). (6,) arrays, world frame; n2 = |xi_free|^2_M."""
    size = 0.0  # the balance's terms cancel: rounding counts as zero (lowspeed.ROUNDING)
    for c in range(6):
        size += abs(stick[c] * twist[c])
    if semi:
        for c in range(3):
            size += dt * abs(other[c]) * (abs(other[c]) + abs(stick[c])) / mass
    if _step_work(stick, twist, np.zeros(6), other, mass, dt, semi) <= ROUNDING * size:
        return 1.0
    a2 = n2 / dt
    b1 = -a2
    c0 = 0.0
    for c in range(6):
        b1 += stick[c] * twist[c]
    if semi:
        for c in range(3):
            b1 -= dt * other[c] * stick[c] / mass
            c0 -= dt * other[c] * other[c] / mass
    root = np.sqrt(b1 * b1 - 4.0 * a2 * c0)
    lam = -2.0 * c0 / (b1 + root) if b1 > 0.0 else (root - b1) / (2.0 * a2)
    return min(max(lam, 0.0), 1.0)


@numba.njit(cache=True, error_model="numpy")
def _implicit(
    b, cull_row, gint, cent, norm, area, xmat, xpos, xipos, twist, other, mass, iw, ii, dt,
    jac_step, co, ay, zeta, surface_z, use_region, region, scratch, w, semi,
):  # fmt: skip
    """The linearly implicit wrench (mjrft.lowspeed.implicit_wrench, compiled): replaces w (6,)
    (the pure wrench at twist) and returns True, or leaves it and returns False. twist, other
    (6,): world frame, about the CoM; iw, ii (3, 3): world-axes inertia and its inverse; semi:
    positions advance with the end velocity (mjrft.lowspeed.step_work)."""
    mm = np.zeros((6, 6))
    for c in range(3):
        mm[c, c] = mass
        for r in range(3):
            mm[3 + r, 3 + c] = iw[r, c]
    n = np.sqrt(_m_dot(twist, twist, mass, iw))
    basis = np.empty((6, 6))
    basis[0] = twist / n
    axis = np.empty(6)
    res = np.empty(6)
    best = np.empty(6)
    for k in range(1, 6):  # pivoted Gram-Schmidt (mjrft.lowspeed.transverse_basis)
        best_n = -1.0
        for j in range(6):
            axis[:] = 0.0
            axis[j] = 1.0 / np.sqrt(mm[j, j])
            res[:] = axis
            for q in range(k):
                res -= _m_dot(basis[q], axis, mass, iw) * basis[q]
            rn = np.sqrt(max(_m_dot(res, res, mass, iw), 0.0))
            if rn > best_n:
                best_n = rn
                best[:] = res
        basis[k] = best / best_n
    h = jac_step * n
    jac = np.zeros((6, 6))
    probe = np.empty(6)
    pw = np.empty(6)
    for k in range(1, 6):
        for c in range(6):
            probe[c] = twist[c] + h * basis[k, c]
        _body_twist_wrench(
            b, cull_row, gint, cent, norm, area, xmat, xpos, xipos, probe[:3], probe[3:], co,
            ay, zeta, surface_z, use_region, region, scratch, pw,
        )  # fmt: skip
        mu = mm @ basis[k]
        for r in range(6):
            dw = (pw[r] - w[r]) / h
            for c in range(6):
                jac[r, c] += dw * mu[c]
    end_pure = np.empty(6)
    epa = dt * (ii @ (other[3:] + w[3:]))
    for c in range(3):
        end_pure[c] = twist[c] + dt * (other[c] + w[c]) / mass
        end_pure[3 + c] = twist[3 + c] + epa[c]
    # Linearised at cs xi, where the Jacobian is J / cs (mjrft.lowspeed.implicit_wrench).
    cs = np.sqrt(max(_m_dot(end_pure, end_pure, mass, iw), 0.0)) / n
    if not cs > 0.0:
        return False
    jac /= cs
    a = mm - dt * jac
    rhs = mm @ (end_pure - cs * twist)
    d_xi = _solve6(a, rhs)
    f = w + jac @ d_xi
    for c in range(6):
        if not np.isfinite(f[c]):
            return False
    # Guards as in the reference: the motion keeps its sense, no energy added over the step.
    end = np.empty(6)
    ea = dt * (ii @ (other[3:] + f[3:]))
    for c in range(3):
        end[c] = twist[c] + dt * (other[c] + f[c]) / mass
        end[3 + c] = twist[3 + c] + ea[c]
    if _m_dot(end, twist, mass, iw) <= 0.0:
        return False
    if _step_work(f, twist, end, other, mass, dt, semi) > 0.0:
        return False
    w[:] = f
    return True


@numba.njit(cache=True, error_model="numpy")
def _treat_body(
    b, cull_row, gint, cent, norm, area, geom_xpos, xmat, xpos, ximat, xipos, cvel,
    subtree_com, user, mass, inertia, gvec, dt, reach, jac_step, co, ay, zeta, surface_z,
    use_region, region, scratch, w, ab, tw, semi,
):  # fmt: skip
    """The low-speed treatment of one free body (mjrft.lowspeed.treat, compiled).

    w (6,): the body's pure RFT wrench (world force, torque about the CoM), replaced by the
    treated one. user (6,): the user's xfrc row; gvec (3,) gravity [m/s^2] acting on the body;
    mass [kg], inertia (3,) principal moments [kg m^2] in the inertial frame ximat[b]; dt [s].
    cull_row (G,): 1 where the geom row is culled this pass. scratch (n_el, 3): element forces
    of the second evaluation (the field's per-element record keeps the pure model). ab (2,):
    set to |xi|^2_M and <d_xi, xi>_M (mjrft.lowspeed.keeps_sense is ab[0] + steps ab[1] > 0)
    when the body is tested. tw (6,): set to the body's twist (v at the CoM, omega; world).
    jac_step: mjrft.lowspeed.JACOBIAN_STEP, 0 for no implicit step. semi: positions advance
    with the step's end velocity (every integrator but RK4; lowspeed.step_work). Returns the
    decision (mjrft.lowspeed PURE, STICK, SLIP or IMPLICIT).
    """
    if mass <= 0.0 or inertia[0] <= 0.0 or inertia[1] <= 0.0 or inertia[2] <= 0.0:
        return 0
    x = ximat[b]
    iw = np.empty((3, 3))  # world-axes inertia and its inverse: X diag(I) X^T
    ii = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            a = 0.0
            ai = 0.0
            for k in range(3):
                a += x[r, k] * inertia[k] * x[c, k]
                ai += x[r, k] * x[c, k] / inertia[k]
            iw[r, c] = a
            ii[r, c] = ai
    om = cvel[b, :3]
    c0 = subtree_com[gint[0, G_ROOT]]
    for g in range(gint.shape[0]):
        if gint[g, G_BODY] == b:
            c0 = subtree_com[gint[g, G_ROOT]]
            break
    rx, ry, rz = xipos[b, 0] - c0[0], xipos[b, 1] - c0[1], xipos[b, 2] - c0[2]
    v = np.empty(3)
    v[0] = cvel[b, 3] + om[1] * rz - om[2] * ry
    v[1] = cvel[b, 4] + om[2] * rx - om[0] * rz
    v[2] = cvel[b, 5] + om[0] * ry - om[1] * rx
    for c in range(3):
        tw[c] = v[c]
        tw[3 + c] = om[c]
    iom = iw @ om
    # Other wrenches over the step: gravity, the user's row, the gyroscopic torque -w x Iw.
    tau = np.empty(3)
    tau[0] = user[3] - (om[1] * iom[2] - om[2] * iom[1])
    tau[1] = user[4] - (om[2] * iom[0] - om[0] * iom[2])
    tau[2] = user[5] - (om[0] * iom[1] - om[1] * iom[0])
    v_free = np.empty(3)
    for c in range(3):
        v_free[c] = v[c] + dt * (gvec[c] + user[c] / mass)
    om_free = om + dt * (ii @ tau)
    dom_pure = dt * (ii @ w[3:])
    # <probe, xi>_M = |xi|^2_M + reach <d_xi, xi>_M, d_xi the predicted change over the step.
    sq = mass * (v @ v) + om @ iom
    dxi = 0.0
    for c in range(3):
        dxi += (v_free[c] - v[c] + dt * w[c] / mass) * mass * v[c]
    dxi += (om_free - om + dom_pure) @ iom
    ab[0] = sq
    ab[1] = dxi
    twist = np.empty(6)
    other = np.empty(6)
    for c in range(3):
        twist[c] = v[c]
        twist[3 + c] = om[c]
        other[c] = mass * gvec[c] + user[c]
        other[3 + c] = tau[c]
    if sq + reach * dxi > 0.0:
        # Stiff across the motion (mjrft.lowspeed.stiff): (reach dt)^2 |M^-1 W|^2_M >= |xi|^2_M.
        wn2 = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) / mass + w[3:] @ (ii @ w[3:])
        if (reach * dt) ** 2 * wn2 < sq or not jac_step > 0.0:
            return 0
        if _implicit(
            b, cull_row, gint, cent, norm, area, xmat, xpos, xipos, twist, other, mass, iw, ii,
            dt, jac_step, co, ay, zeta, surface_z, use_region, region, scratch, w, semi,
        ):  # fmt: skip
            return 3
        # Implicitly the motion would reverse within the step (or gain work): decide below.
    n2 = mass * (v_free @ v_free) + om_free @ (iw @ om_free)
    if n2 > 0.0:
        rw = np.zeros(6)
        _body_twist_wrench(
            b, cull_row, gint, cent, norm, area, xmat, xpos, xipos, v_free, om_free, co, ay,
            zeta, surface_z, use_region, region, scratch, rw,
        )  # fmt: skip
        diss = -(rw[0] * v_free[0] + rw[1] * v_free[1] + rw[2] * v_free[2])
        diss -= rw[3] * om_free[0] + rw[4] * om_free[1] + rw[5] * om_free[2]
        if dt * diss < n2:
            # R adds no energy over the step (lowspeed.treat, lowspeed.step_work).
            om_end = om_free + dt * (ii @ rw[3:])
            end = np.empty(6)
            for c in range(3):
                end[c] = v_free[c] + dt * rw[c] / mass
                end[3 + c] = om_end[c]
            if _step_work(rw, twist, end, other, mass, dt, semi) <= 0.0:
                for c in range(6):
                    w[c] = rw[c]
                return 2
            if sq + dxi > 0.0:  # the pure model keeps the motion's sense over this step
                return 0
    iomf = iw @ om_free
    for c in range(3):
        w[c] = -mass * v_free[c] / dt
        w[3 + c] = -iomf[c] / dt
    lam = _stick_fraction(w, twist, other, mass, n2, dt, semi)
    for c in range(6):
        w[c] *= lam
    return 1


@numba.njit(inline="always", cache=True)
def _gravity(mdl, b, dsbl_bit):
    """(3,) gravity acceleration [m/s^2] on body b, world frame (gravity compensation, flag)."""
    g = np.zeros(3)
    flags = numba.carray(i32_ptr(mdl[M_DISABLEFLAGS]), 1)[0]
    if flags & dsbl_bit:
        return g
    grav = numba.carray(f64_ptr(mdl[M_GRAVITY]), 3)
    comp = numba.carray(f64_ptr(mdl[M_BODY_GRAVCOMP]), b + 1)[b]
    for c in range(3):
        g[c] = grav[c] * (1.0 - comp)
    return g


@numba.njit(cache=True, error_model="numpy")
def _treat_all(
    mdl, eligible, decision, bodies, cull_row, gint, cent, norm, area, geom_xpos, xmat,
    xpos, ximat, xipos, cvel, subtree_com, user, co, par, region, scratch, wrench, stats, slow,
    frozen,
):  # fmt: skip
    """Apply the low-speed treatment to every eligible tagged body with a geom in play.

    wrench (nbody, 6): pure RFT wrenches, replaced where treated; user (n_bt, 6) the user's rows.
    slow (n_bt,): set where an RK4 step must not evaluate the pure model in its later stages
    (treated, or reversing within RK4_HOLD_STEPS). frozen (n_bt, 12): for bodies moved by the
    implicit step, set to their twist (v at the CoM, omega) and the correction J'd (RK4_FROZEN).
    """
    nbody = wrench.shape[0]
    dt = numba.carray(f64_ptr(mdl[M_TIMESTEP]), 1)[0]
    mass_all = numba.carray(f64_ptr(mdl[M_BODY_MASS]), nbody)
    inertia_all = numba.carray(f64_ptr(mdl[M_BODY_INERTIA]), (nbody, 3))
    dsbl = np.int32(par[P_DSBL_GRAVITY])
    jac_step = par[P_JAC_STEP]
    semi = numba.carray(i32_ptr(mdl[M_INTEGRATOR]), 1)[0] != INT_RK4
    for k in range(bodies.shape[0]):
        b = bodies[k]
        slow[k] = False
        if not eligible[k] or not dt > 0.0:
            continue
        in_play = False
        for g in range(gint.shape[0]):
            if gint[g, G_BODY] == b and not cull_row[g]:
                in_play = True
        if not in_play:  # nothing of the body can touch the medium: no force, nothing to treat
            continue
        ab = np.zeros(2)
        pure = wrench[b].copy()
        d = _treat_body(
            b, cull_row, gint, cent, norm, area, geom_xpos, xmat, xpos, ximat, xipos,
            cvel, subtree_com, user[k], mass_all[b], inertia_all[b], _gravity(mdl, b, dsbl), dt,
            par[P_REACH], jac_step, co, par[P_AY], par[P_ZETA], par[P_SURFACE],
            par[P_USE_REGION] != 0.0, region, scratch, wrench[b], ab, frozen[k, :6], semi,
        )  # fmt: skip
        for c in range(6):  # only a body moved by the implicit step has a record (RK4_FROZEN)
            frozen[k, 6 + c] = wrench[b, c] - pure[c] if d == 3 else 0.0
            if d != 3:
                frozen[k, c] = 0.0
        decision[k] = d
        slow[k] = d != 0 or ab[0] + par[P_RK4_HOLD] * ab[1] <= 0.0
        if d == 1:
            stats[3] += 1
        elif d == 2:
            stats[4] += 1
        elif d == 3:
            stats[5] += 1


@numba.njit(cache=True, error_model="numpy")
def step(field_addr, data_addr):
    """One forward pass of the field on one MjData; returns OK or -1 - (bad tagged body)."""
    f = numba.carray(u64_ptr(field_addr), FIELD_WORDS)
    e = numba.carray(u64_ptr(data_addr), DATA_WORDS)
    n_el, n_geom, n_bt, nbody = f[F_NELEM], f[F_NGEOM], f[F_NBODY_TAGGED], f[F_NBODY]
    cent, norm, area, gint, grb, bodies, par, region, co, stats = _statics(f)
    last = numba.carray(f64_ptr(f[F_LAST_WRENCH]), (nbody, 6))
    elem_force = numba.carray(f64_ptr(f[F_ELEM_FORCE]), (n_el, 3))
    dirty = numba.carray(i64_ptr(f[F_DIRTY]), n_geom)  # 1: the geom's elem_force may be nonzero
    xpos = numba.carray(f64_ptr(e[D_XPOS]), (nbody, 3))
    xmat = numba.carray(f64_ptr(e[D_XMAT]), (nbody, 3, 3))
    xipos = numba.carray(f64_ptr(e[D_XIPOS]), (nbody, 3))
    cvel = numba.carray(f64_ptr(e[D_CVEL]), (nbody, 6))
    subtree_com = numba.carray(f64_ptr(e[D_SUBTREE_COM]), (nbody, 3))
    xfrc = numba.carray(f64_ptr(e[D_XFRC]), (nbody, 6))
    user = numba.carray(f64_ptr(e[D_USER]), (n_bt, 6))
    written = numba.carray(f64_ptr(e[D_WRITTEN]), (n_bt, 6))
    # Refuse to feed a non-finite state forward (Python names the body and raises).
    bad = _first_bad_body(bodies, xpos, cvel)
    if bad >= 0:
        return -1 - bad
    mdl = numba.carray(u64_ptr(f[F_MODEL]), MODEL_WORDS)
    rk4 = numba.carray(i32_ptr(mdl[M_INTEGRATOR]), 1)[0] == INT_RK4
    rec = numba.carray(f64_ptr(e[D_RK4]), RK4_HEAD + RK4_BODY * n_bt)
    # keep[b]: body b keeps the wrench its RK4 step's first stage wrote (RK4_HOLD there);
    # frz[b]: body b feels the model at its stage pose with stage 1's twist (RK4_FROZEN).
    # Work arrays owned by the field rather than allocated per pass: above the surface the pass
    # fell from 0.55 to 0.29 us with that (the 1.2x target's margin; RESULTS "Field overhead").
    work = numba.carray(i64_ptr(f[F_WORK]), 2 * nbody + n_geom + n_bt)
    keep = work[:nbody]
    frz = work[nbody : 2 * nbody]
    cull_row = work[2 * nbody : 2 * nbody + n_geom]
    slow = work[2 * nbody + n_geom :]
    work[:] = 0
    held = False
    if rk4:
        t = numba.carray(f64_ptr(e[D_TIME]), 1)[0]
        h = numba.carray(f64_ptr(mdl[M_TIMESTEP]), 1)[0]
        held = rk4_hold(t, h, rec)
        if held:
            for k in range(n_bt):
                mode = rec[RK4_HEAD + RK4_BODY * k]
                keep[bodies[k]] = mode == RK4_HOLD
                frz[bodies[k]] = mode == RK4_FROZEN
    ngeom_model = 0
    for g in range(n_geom):
        ngeom_model = max(ngeom_model, gint[g, G_GEOM] + 1)
    geom_xpos = numba.carray(f64_ptr(e[D_GEOM_XPOS]), (ngeom_model, 3))
    surface_z, zeta, ay = par[P_SURFACE], par[P_ZETA], par[P_AY]
    use_region = par[P_USE_REGION] != 0.0
    for b in range(nbody):
        if keep[b]:
            continue
        for c in range(6):
            last[b, c] = 0.0
    evaluated = 0
    acting = 0
    for g in range(n_geom):
        geom, b = gint[g, G_GEOM], gint[g, G_BODY]
        if keep[b]:
            continue
        start, stop = gint[g, G_START], gint[g, G_STOP]
        if _culled(geom_xpos, geom, grb[g], surface_z, use_region, region):
            cull_row[g] = 1
            if dirty[g]:
                for i in range(start, stop):
                    elem_force[i, 0] = 0.0
                    elem_force[i, 1] = 0.0
                    elem_force[i, 2] = 0.0
                dirty[g] = 0
            continue
        dirty[g] = 1
        if frz[b]:
            continue
        acting += _kernel.body_wrench(
            cent, norm, area, start, stop, xmat[b], xpos[b], cvel[b, :3], cvel[b, 3:],
            subtree_com[gint[g, G_ROOT]], xipos[b], co, ay, zeta, surface_z, use_region,
            region, last[b], elem_force,
        )  # fmt: skip
        evaluated += stop - start
    if held:
        for k in range(n_bt):
            b = bodies[k]
            if frz[b]:
                blk = RK4_HEAD + RK4_BODY * k
                ne, na = _body_twist_wrench(
                    b, cull_row, gint, cent, norm, area, xmat, xpos, xipos,
                    rec[blk + 1 : blk + 4], rec[blk + 4 : blk + 7], co, ay, zeta, surface_z,
                    use_region, region, elem_force, last[b],
                )  # fmt: skip
                if ne > 0:  # in play: the correction acts as the model does (Python path too)
                    for c in range(6):
                        last[b, c] += rec[blk + 7 + c]
                evaluated += ne
                acting += na
    if evaluated or not held:
        stats[0] += 1
    stats[1] += evaluated
    stats[2] += acting
    # xfrc_applied ownership (mjrft.field): a row that differs from what was written was
    # assigned by the user and becomes the user part; then row = user + RFT.
    for k in range(n_bt):
        b = bodies[k]
        assigned = False
        for c in range(6):
            if xfrc[b, c] != written[k, c]:
                assigned = True
        if assigned:
            for c in range(6):
                user[k, c] = xfrc[b, c]
    decision = numba.carray(i64_ptr(f[F_DECISION]), n_bt)
    if not held:  # a held stage keeps its step's decisions; its other bodies feel the pure model
        for k in range(n_bt):
            decision[k] = 0
        frozen = numba.carray(f64_ptr(f[F_FROZEN]), (n_bt, 12))
        frozen[:] = 0.0
        if par[P_TREAT] != 0.0:
            eligible = numba.carray(i64_ptr(f[F_ELIGIBLE]), n_bt)
            ximat = numba.carray(f64_ptr(e[D_XIMAT]), (nbody, 3, 3))
            scratch = numba.carray(f64_ptr(f[F_SCRATCH]), (n_el, 3))
            _treat_all(
                mdl, eligible, decision, bodies, cull_row, gint, cent, norm, area, geom_xpos,
                xmat, xpos, ximat, xipos, cvel, subtree_com, user, co, par, region, scratch,
                last, stats, slow, frozen,
            )  # fmt: skip
        for k in range(n_bt):
            blk = RK4_HEAD + RK4_BODY * k
            rec[blk] = RK4_FROZEN if decision[k] == 3 else (RK4_HOLD if slow[k] else RK4_PER_STAGE)
            for c in range(12):
                rec[blk + 1 + c] = frozen[k, c]
    ring_size = f[F_RING_SIZE]
    ring = numba.carray(f64_ptr(f[F_RING]), (ring_size + 1, 2, n_bt, 6))
    slot = int(ring[0, 0, 0, 0]) % ring_size  # ring[0] holds the write counter
    for k in range(n_bt):
        b = bodies[k]
        for c in range(6):
            total = xfrc[b, c] if keep[b] else user[k, c] + last[b, c]
            xfrc[b, c] = total
            written[k, c] = total
            ring[1 + slot, 0, k, c] = total
            ring[1 + slot, 1, k, c] = user[k, c]
    ring[0, 0, 0, 0] += 1.0
    return OK


@numba.njit(cache=True, error_model="numpy", nogil=True)
def batch_wrench(
    field_addr, xpos, xmat, xipos, ximat, cvel, subtree_com, geom_xpos, user_xfrc, out, counts
):  # fmt: skip
    """RFT wrenches of many simulations of one model in one call (mjrft.batch).

    xpos (S, nbody, 3), xmat (S, nbody, 9), xipos (S, nbody, 3), ximat (S, nbody, 9),
    cvel (S, nbody, 6), subtree_com (S, nbody, 3), geom_xpos (S, ngeom, 3): bound MjData
    fields, world frame. user_xfrc (S, nbody, 6): the user's applied wrenches (the low-speed
    treatment counts them). out (S, nbody, 6): filled with each body's force and torque at its
    CoM. counts (N_STATS,) int64: the field's statistics of these passes are added here, not to
    the field's own (mjrft.batch sums them), so that several threads can run disjoint sets of
    copies at once (the GIL is released). Returns OK, or -1 - s for the first simulation s whose
    state is not finite. Copies run one after the other within a call (numba threads here
    competed with MuJoCo's batch threads: 3-20x slower on 2 cores).
    """
    f = numba.carray(u64_ptr(field_addr), FIELD_WORDS)
    n_el, n_geom, n_bt = f[F_NELEM], f[F_NGEOM], f[F_NBODY_TAGGED]
    cent, norm, area, gint, grb, bodies, par, region, co, _ = _statics(f)
    stats = counts
    surface_z, zeta, ay = par[P_SURFACE], par[P_ZETA], par[P_AY]
    use_region = par[P_USE_REGION] != 0.0
    n_sim = xpos.shape[0]
    for s in range(n_sim):
        if _first_bad_body(bodies, xpos[s], cvel[s]) >= 0:
            return -1 - s
    out[:] = 0.0
    evaluated = np.zeros(n_sim, np.int64)
    acting = np.zeros(n_sim, np.int64)
    elem_force = np.empty((n_el, 3))  # scratch: per-element forces are not kept for batches
    user = np.empty((n_bt, 6))
    decision = np.empty(n_bt, np.int64)
    slow = np.empty(n_bt, np.int64)
    frozen = np.empty((n_bt, 12))
    cull_row = np.zeros(n_geom, np.int64)  # per call, not the field's work: threads share a field
    treat = par[P_TREAT] != 0.0
    mdl = numba.carray(u64_ptr(f[F_MODEL]), MODEL_WORDS)
    eligible = numba.carray(i64_ptr(f[F_ELIGIBLE]), n_bt)
    for s in range(n_sim):
        for g in range(n_geom):
            geom, b = gint[g, G_GEOM], gint[g, G_BODY]
            start, stop = gint[g, G_START], gint[g, G_STOP]
            cull_row[g] = 0
            if _culled(geom_xpos[s], geom, grb[g], surface_z, use_region, region):
                cull_row[g] = 1
                continue
            acting[s] += _kernel.body_wrench(
                cent, norm, area, start, stop, xmat[s, b].reshape((3, 3)), xpos[s, b],
                cvel[s, b, :3], cvel[s, b, 3:], subtree_com[s, gint[g, G_ROOT]], xipos[s, b],
                co, ay, zeta, surface_z, use_region, region, out[s, b], elem_force,
            )  # fmt: skip
            evaluated[s] += stop - start
        if treat:
            for k in range(n_bt):
                for c in range(6):
                    user[k, c] = user_xfrc[s, bodies[k], c]
            _treat_all(
                mdl, eligible, decision, bodies, cull_row, gint, cent, norm, area,
                geom_xpos[s], xmat[s].reshape((-1, 3, 3)), xpos[s],
                ximat[s].reshape((-1, 3, 3)), xipos[s], cvel[s], subtree_com[s], user, co, par,
                region, elem_force, out[s], stats, slow, frozen,
            )  # fmt: skip
    stats[0] += n_sim
    stats[1] += evaluated.sum()
    stats[2] += acting.sum()
    return OK
