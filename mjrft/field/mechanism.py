"""Low-speed treatment of intruding bodies in mechanisms (legs, wheels, rig carriages): a joint
stick/slip step over the mechanism's generalized coordinates.

Why: a body on joints feels, besides the medium, its actuators, its joints' coupling to the rest
of the mechanism and any constraint. MuJoCo computes actuator and constraint forces after the
passive forces, so the free-body treatment (``mjrft.field.lowspeed``), which needs every force on
the body, cannot act on it; the pure rate-independent model then lets a standing robot creep and
its foot forces chatter (docs/stability.md, "Mechanisms").

What: the time-stepping (Moreau) treatment of the medium's set-valued reaction near rest, in
generalized coordinates. With M the joint-space inertia (``M``), J_i the 6 x nv Jacobian of
intruding body i at its CoM (twist: CoM velocity, angular velocity; world) and dt the timestep:

1. The other generalized forces (actuators, constraints, gravity, bias, the user's) are those of
   the previous pass, read from MuJoCo's own result: ``tau_other = M qacc_prev - tau_field_prev``
   (``qacc`` still holds the previous forward pass's acceleration when the passive callback runs;
   ``tau_field_prev = sum J_i^T W_i`` is what the field applied then; a repeated pass at the
   same time, ``mj_forward`` before ``mj_step``, reads what the first pass at that time read, so
   the trajectory does not depend on extra forward calls). The actuators with fixed or affine
   gains and affine biases (servos, motors) are brought to this state: their force at this
   state's control, activation, length and velocity (MuJoCo's affine rule, ``actuator_force``)
   replaces the previous pass's through this state's moments, so a stiff servo's response to
   the last step is not a step late. The free velocity is ``u = qvel + dt M^-1 tau_other``.
   A body at rest under constant loads is a fixed point of this predictor; it is not used after
   a reset or a jump in time (the pure model acts once).
2. A body keeps the pure model while its twist keeps its sense and changes by less than its
   own size over ``reach`` steps under every force: with the step's predicted change
   ``dxi = J_i (u - qvel) + dt J_i M^-1 sum_j J_j^T W_j`` (the pure model's wrenches W_j on
   every body in the medium), ``<xi + reach dxi, xi> > 0`` and ``reach |dxi| < |xi|`` in the
   body's own kinetic-energy metric. A steadily driven rig, whose drive balances the medium, is
   never held.
3. The other bodies in the medium are held jointly: wrenches W_S with ``J_S (u + dt M^-1 (J_S^T
   W_S + J_P^T W_P)) = 0`` (their twists end the step at zero), W_S = W_ref + the least-norm
   correction (``A = J_S M^-1 J_S^T`` is singular wherever the mechanism cannot move a body in
   some direction; the wrench there does no work, so it keeps its value from the previous pass,
   W_ref, and the load on a statically indeterminate stance does not jump). This is the
   M-orthogonal projection of the free motion onto the motions that leave the held bodies at
   rest: it cannot add kinetic energy.
4. A held body whose hold the medium cannot supply slips: released alone it would move with
   ``xi_f = -dt A_ii W_i``; the medium's resistance to that motion R = W(xi_f) must dissipate at
   least the power the hold does, ``-R . xi_f >= -W_i . xi_f``. The body that fails by most gets
   R (the force of the direction it would move in; the pure model instead if R would push along
   its present motion) and the others are solved again, until every hold is supplied.

Frames: world. Applies in the installed path only (inside ``mj_step``), where ``M`` and ``qacc``
are MuJoCo's own; the explicit and batch paths give mechanism bodies the pure model.
``tests/field_reference.py`` states the same rules plainly in NumPy.
"""

from __future__ import annotations

import numba
import numpy as np

from mjrft.core import surface
from mjrft.field.evaluate import geom_top, in_play, twist_wrench
from mjrft.field.lowspeed import (
    PURE,
    ROUNDING,
    SLIP,
    STICK,
    com_velocity,
    m_dot,
    world_inertia,
)
from mjrft.field.tables import unpack

#: Relative regularisation of the hold system: (A + eps I) with eps this fraction of A's largest
#: diagonal gives the least-norm correction to ~1e-10 of its size (A's eigenvalues for the
#: shipped robots span ~1e1-1e6; eps ~1e-6 absolute).
HOLD_REGULARISATION = 1e-12
#: The medium's resistance to a hold's direction is re-evaluated unless the body has moved less
#: than RESISTANCE_REUSE_M (CoM, and inertial axes times the body's size) and the direction has
#: turned less than RESISTANCE_REUSE_RAD since it was last evaluated. A held body at rest keeps
#: its place exactly, but its direction jitters by 1e-5-1e-3 rad from step to step (round-off of
#: the holds through a light leg's large rotational mobility); an RFT force changes with its
#: direction by about that fraction, far less than the margins the check decides on, and the
#: reuse halves the treatment's cost on a standing robot (benchmarks/standing.py).
RESISTANCE_REUSE_M, RESISTANCE_REUSE_RAD = 1e-9, 1e-2
#: The factors of M and of the holds' system are kept while the configuration (cdof, CoMs) moves
#: less than this [m, dimensionless]: a body at rest moves ~1e-17 m a step; 1e-12 m of motion
#: changes the factors by ~1e-11 of themselves.
CONFIGURATION_REUSE = 1e-12
_JIT = {"cache": True, "error_model": "numpy"}
# The small helpers that take the unpacked tables (m, d, s) are inlined: a call passes every
# array of those NamedTuples by value, ~250 ns a call (the six servos' actuator_force alone
# took 1.5 us a pass).


@numba.njit(inline="always", **_JIT)
def full_inertia(m, d, out):
    """Dense joint-space inertia (nv, nv) from MuJoCo's ``M`` (the lower triangle in CSR:
    ``M_rownnz``, ``M_rowadr``, ``M_colind``; what ``mj_fullM`` expands)."""
    out[:] = 0.0
    for i in range(m.nv):
        for a in range(m.M_rowadr[i], m.M_rowadr[i] + m.M_rownnz[i]):
            j = m.M_colind[a]
            out[i, j] = d.M[a]
            out[j, i] = d.M[a]


@numba.njit(**_JIT)
def cholesky(a, n, eps):
    """In place: the lower Cholesky factor of a[:n, :n] + eps I (symmetric positive
    semi-definite). Returns False if a pivot is not positive."""
    for j in range(n):
        s = a[j, j] + eps
        for q in range(j):
            s -= a[j, q] * a[j, q]
        if not s > 0.0:
            return False
        a[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            t = a[i, j]
            for q in range(j):
                t -= a[i, q] * a[j, q]
            a[i, j] = t / a[j, j]
    return True


@numba.njit(**_JIT)
def cho_solve(lower, n, x):
    """In place: x[:n] = (L L^T)^-1 x[:n] for the factor of ``cholesky``."""
    forward_solve(lower, n, x)
    back_solve(lower, n, x)


@numba.njit(**_JIT)
def forward_solve(lower, n, x):
    """In place: x[:n] = L^-1 x[:n]."""
    for i in range(n):
        s = x[i]
        for q in range(i):
            s -= lower[i, q] * x[q]
        x[i] = s / lower[i, i]


@numba.njit(**_JIT)
def back_solve(lower, n, x):
    """In place: x[:n] = L^-T x[:n]."""
    for i in range(n - 1, -1, -1):
        s = x[i]
        for q in range(i + 1, n):
            s -= lower[q, i] * x[q]
        x[i] = s / lower[i, i]


@numba.njit(inline="always", **_JIT)
def body_jacobian(m, d, k, row, jac):
    """jac[row:row + 6] = tagged body k's Jacobian at its CoM: rows CoM velocity, angular
    velocity (world); ``cdof`` is a motion at the subtree CoM of the body's root."""
    b = m.tbody_bodyid[k]
    c0 = d.subtree_com[m.tbody_rootid[k]]
    rx, ry, rz = d.xipos[b, 0] - c0[0], d.xipos[b, 1] - c0[1], d.xipos[b, 2] - c0[2]
    for j in range(m.nv):
        if not m.tbody_dofmask[k, j]:
            for r in range(6):
                jac[row + r, j] = 0.0
            continue
        w0, w1, w2 = d.cdof[j, 0], d.cdof[j, 1], d.cdof[j, 2]
        jac[row + 0, j] = d.cdof[j, 3] + w1 * rz - w2 * ry
        jac[row + 1, j] = d.cdof[j, 4] + w2 * rx - w0 * rz
        jac[row + 2, j] = d.cdof[j, 5] + w0 * ry - w1 * rx
        jac[row + 3, j] = w0
        jac[row + 4, j] = w1
        jac[row + 5, j] = w2


@numba.njit(inline="always", **_JIT)
def predictor_valid(m, d, s, same_time):
    """True if the qacc read by the first pass at this time described this state's loads (the
    pass before it was one timestep before); a repeated pass at the same time (same_time) gets
    the first one's answer. Records this pass's time."""
    if same_time:
        return s.mech_time[2] == 1.0
    t, dt, t0 = d.time[0], m.opt_timestep[0], s.mech_time[0]
    ok = s.mech_time[1] == 1.0 and abs(t - (t0 + dt)) <= 1e-9 * dt + 1e-12 * abs(t)
    s.mech_time[0] = t
    s.mech_time[1] = 1.0
    s.mech_time[2] = 1.0 if ok else 0.0
    return ok


@numba.njit(inline="always", **_JIT)
def submerged(m, d, s, k):
    """True if an element of tagged body k's geoms in play is below the free surface (the pure
    wrench cannot tell: at rest it is zero)."""
    b = m.tbody_bodyid[k]
    flat = m.surface_prm[surface.KIND] == surface.FLAT
    for g in range(m.tbody_geomadr[k], m.tbody_geomadr[k] + m.tbody_geomnum[k]):
        if s.cull[g]:
            continue
        # An element above the highest surface point near its geom is dry wherever it is: the
        # height alone (three multiply-adds an element) clears it, as it decides under a flat
        # surface, before the surface is looked up.
        top = geom_top(m, d, g)
        for e in range(m.tgeom_elemadr[g], m.tgeom_elemadr[g] + m.tgeom_elemnum[g]):
            z = d.xpos[b, 2]
            for c in range(3):
                z += d.xmat[b, 2, c] * m.elem_pos[e, c]
            if flat or z >= top:
                if z < top:
                    return True
                continue
            x, y = d.xpos[b, 0], d.xpos[b, 1]
            for c in range(3):
                x += d.xmat[b, 0, c] * m.elem_pos[e, c]
                y += d.xmat[b, 1, c] * m.elem_pos[e, c]
            if surface.depth(m.surface_prm, m.surface_grid, d.userdata, x, y, z) > 0.0:
                return True
    return False


@numba.njit(**_JIT)
def gather(m_rec, e_rec, rows):
    """Tagged mechanism bodies in the medium this pass (a geom in play with an element below
    the surface: a body out of the medium has nothing to be held by), into rows (ntbody,);
    returns their number."""
    m, d, s = unpack(m_rec, e_rec)
    n = 0
    for k in range(m.tbody_bodyid.shape[0]):
        if m.tbody_mech[k] and in_play(m_rec, e_rec, k) and submerged(m, d, s, k):
            rows[n] = k
            n += 1
    return n


@numba.njit(inline="always", **_JIT)
def actuator_force(m, d, a):
    """Force of actuator a at this state by MuJoCo's rule for fixed/affine gains and affine
    biases: gain (x, L, V) x + bias (L, V), x its activation or clamped control, clamped to its
    force range."""
    if m.opt_disableflags[0] & m.dsbl_actuation:
        return 0.0
    adr = m.actuator_actadr[a]
    if adr >= 0:
        x = d.act[adr]
    else:
        x = d.ctrl[a]
        if m.actuator_ctrllimited[a] and not m.opt_disableflags[0] & m.dsbl_clampctrl:
            x = min(max(x, m.actuator_ctrlrange[a, 0]), m.actuator_ctrlrange[a, 1])
    length, velocity = d.actuator_length[a], d.actuator_velocity[a]
    g, b = m.actuator_gainprm[a], m.actuator_biasprm[a]
    gain = g[0] + (g[1] * length + g[2] * velocity if m.actuator_gainaffine[a] else 0.0)
    bias = b[0] + b[1] * length + b[2] * velocity if m.actuator_biasaffine[a] else 0.0
    f = gain * x + bias
    if m.actuator_forcelimited[a]:
        f = min(max(f, m.actuator_forcerange[a, 0]), m.actuator_forcerange[a, 1])
    return f


@numba.njit(**_JIT)
def actuator_forces(m_rec, e_rec, out):
    """out (nu,) = ``actuator_force`` of every actuator at the MjData's state (NaN for those
    whose force the rule does not cover); for checking the rule against MuJoCo's own."""
    m, d, _ = unpack(m_rec, e_rec)
    for a in range(m.nu):
        out[a] = actuator_force(m, d, a) if m.actuator_affine[a] else np.nan


@numba.njit(inline="always", **_JIT)
def actuator_update(m, d, s, tau):
    """tau (nv,) += the change of the affine actuators' generalized force since the loads were
    read: this state's force (``actuator_force``) minus the previous pass's, through this
    state's moments. A stiff servo's force then follows the step it responds to."""
    for a in range(m.nu):
        if not m.actuator_affine[a]:
            continue
        df = actuator_force(m, d, a) - s.mech_in_force[a]
        if df == 0.0:
            continue
        start = d.moment_rowadr[a]
        for q in range(start, start + d.moment_rownnz[a]):
            tau[d.moment_colind[q]] += d.actuator_moment[q] * df


@numba.njit(inline="always", **_JIT)
def same_configuration(m, d, s, rows, n):
    """True if the bodies in the medium and the configuration (cdof, their CoMs and their
    roots' subtree CoMs, within CONFIGURATION_REUSE) are those of the stored factors; else
    stores this configuration and returns False."""
    cfg = s.mech_cfg
    nk = m.tbody_bodyid.shape[0]
    key = np.empty(cfg.shape[0])
    key[0] = n
    for a in range(nk):
        key[1 + a] = rows[a] if a < n else -1.0
    p = 1 + nk
    for j in range(m.nv):
        for c in range(6):
            key[p] = d.cdof[j, c]
            p += 1
    for a in range(nk):
        k = rows[a] if a < n else -1
        for c in range(3):
            key[p + c] = d.xipos[m.tbody_bodyid[k], c] if k >= 0 else 0.0
            key[p + 3 + c] = d.subtree_com[m.tbody_rootid[k], c] if k >= 0 else 0.0
        p += 6
    same = cfg[0] >= 0.0
    for q in range(key.shape[0]):
        same = same and abs(key[q] - cfg[q]) <= CONFIGURATION_REUSE
    if not same:
        cfg[:] = key
        s.mech_hkey[0] = -2  # the hold system (and its held rows' factor) is the old one's
    return same


@numba.njit(**_JIT)
def setup(m_rec, e_rec, rows, n):
    """Factor M = L L^T (s.mech_L) and the Jacobians (s.mech_J), unless the configuration is the
    last pass's (``same_configuration``); and the free velocity u (s.mech_vec[0]). Returns False
    if M is not positive definite."""
    m, d, s = unpack(m_rec, e_rec)
    nv, dt = m.nv, m.opt_timestep[0]
    lo = s.mech_L
    if not same_configuration(m, d, s, rows, n):
        full_inertia(m, d, s.mech_M)
        lo[:] = s.mech_M
        if not cholesky(lo, nv, 0.0):
            s.mech_cfg[0] = -1.0
            return False
        for a in range(n):
            body_jacobian(m, d, rows[a], 6 * a, s.mech_J)
    u = s.mech_vec[0]
    for i in range(nv):  # tau_other = M qacc_prev - tau_field_prev
        acc = -s.mech_in[1, i]
        for j in range(nv):
            acc += s.mech_M[i, j] * s.mech_in[0, j]
        u[i] = acc
    actuator_update(m, d, s, u)
    cho_solve(lo, nv, u)
    for i in range(nv):
        u[i] = d.qvel[i] + dt * u[i]
    return True


@numba.njit(**_JIT)
def hold_system(m_rec, e_rec, n):
    """Y = L^-1 J^T as rows (s.mech_X) and A = J M^-1 J^T = Y^T Y (s.mech_A) of the n bodies in
    the medium, unless built for this configuration: only a pass that holds a body needs them
    (a walking robot's feet mostly move, and building A is most of the treatment's cost)."""
    m, _, s = unpack(m_rec, e_rec)
    if s.mech_hkey[0] != -2:
        return
    nv = m.nv
    for r in range(6 * n):
        for j in range(nv):
            s.mech_X[r, j] = s.mech_J[r, j]
        forward_solve(s.mech_L, nv, s.mech_X[r])
    for r in range(6 * n):
        for c in range(r, 6 * n):
            acc = 0.0
            for j in range(nv):
                acc += s.mech_X[r, j] * s.mech_X[c, j]
            s.mech_A[r, c] = acc
            s.mech_A[c, r] = acc
    s.mech_hkey[0] = -1


@numba.njit(**_JIT)
def row_dot(jac, r, x, nv):
    """jac[r, :nv] . x[:nv]."""
    acc = 0.0
    for j in range(nv):
        acc += jac[r, j] * x[j]
    return acc


@numba.njit(**_JIT)
def classify(m_rec, e_rec, rows, n, held):
    """held[a] = 1 for the bodies step 2 does not leave to the pure model (slow, or reversing
    within ``reach`` steps)."""
    m, d, s = unpack(m_rec, e_rec)
    nv, dt = m.nv, m.opt_timestep[0]
    u = s.mech_vec[0]
    g = s.mech_vec[1]  # M^-1 sum J^T W: the medium's generalized acceleration
    g[:nv] = 0.0
    for a in range(n):
        b = m.tbody_bodyid[rows[a]]
        for r in range(6):
            for j in range(nv):
                g[j] += s.mech_J[6 * a + r, j] * s.wrench[b, r]
    cho_solve(s.mech_L, nv, g)
    xi, dxi, pred = np.empty(6), np.empty(6), np.empty(6)
    for a in range(n):
        k = rows[a]
        b = m.tbody_bodyid[k]
        iw, _ = world_inertia(d.ximat[b], m.body_inertia[b])
        mass = m.body_mass[b]
        for r in range(6):
            xi[r] = row_dot(s.mech_J, 6 * a + r, d.qvel, nv)
            # the twist's change over a step under every force, the medium's pure model included
            dxi[r] = row_dot(s.mech_J, 6 * a + r, u, nv) - xi[r]
            dxi[r] += dt * row_dot(s.mech_J, 6 * a + r, g, nv)
            pred[r] = xi[r] + m.reach * dxi[r]
        n2 = m_dot(xi, xi, mass, iw)
        keeps = m_dot(pred, xi, mass, iw) > 0.0
        fast = m.reach * m.reach * m_dot(dxi, dxi, mass, iw) < n2
        held[a] = 0 if (keeps and fast) else 1


@numba.njit(**_JIT)
def solve_holds(m_rec, e_rec, rows, n, held, ref, out):
    """Wrenches out[a] of the held bodies (step 3), the others' wrenches given in out. Returns
    False if the system cannot be factored."""
    m, _, s = unpack(m_rec, e_rec)
    nv, dt = m.nv, m.opt_timestep[0]
    u = s.mech_vec[0]
    idx = np.empty(6 * n, dtype=np.int64)
    h = 0
    for a in range(n):
        if held[a]:
            for r in range(6):
                idx[h] = 6 * a + r
                h += 1
    if h == 0:
        return True
    # rhs = -J_S u / dt - A_S,all W (W: ref for held rows, the given wrenches for the others)
    w_all = np.empty(6 * n)
    for a in range(n):
        for r in range(6):
            w_all[6 * a + r] = ref[a, r] if held[a] else out[a, r]
    rhs = s.mech_vec[2]
    top = 0.0
    for q in range(h):
        r = idx[q]
        acc = -row_dot(s.mech_J, r, u, nv) / dt
        for c in range(6 * n):
            acc -= s.mech_A[r, c] * w_all[c]
        rhs[q] = acc
        top = max(top, s.mech_A[r, r])
    lhs = s.mech_S
    key = s.mech_hkey
    same = key[0] == h
    for q in range(h):
        same = same and key[1 + q] == idx[q]
    if not same:  # factor the held rows' block (kept while configuration and rows stay)
        for q in range(h):
            for p in range(h):
                lhs[q, p] = s.mech_A[idx[q], idx[p]]
        if not cholesky(lhs, h, HOLD_REGULARISATION * top + 1e-300):
            key[0] = -1
            return False
        key[0] = h
        key[1 : 1 + h] = idx[:h]
    cho_solve(lhs, h, rhs)
    q = 0
    for a in range(n):
        if held[a]:
            for r in range(6):
                out[a, r] = ref[a, r] + rhs[q]
                q += 1
    return True


@numba.njit(**_JIT)
def worst_hold(m_rec, e_rec, rows, n, held, out, slip):
    """Step 4: the held body whose hold the medium fails to supply by most, its slip wrench in
    slip (6,); -1 if every hold is supplied."""
    m, d, s = unpack(m_rec, e_rec)
    dt = m.opt_timestep[0]
    worst, margin = -1, 0.0
    xf, r_w = np.empty(6), np.empty(6)
    for a in range(n):
        if not held[a]:
            continue
        for r in range(6):
            acc = 0.0
            for c in range(6):
                acc += s.mech_A[6 * a + r, 6 * a + c] * out[a, c]
            xf[r] = -dt * acc
        hold = 0.0
        for r in range(6):
            hold -= out[a, r] * xf[r]  # power the hold dissipates (>= 0)
        if not hold > 0.0:
            continue  # the hold does nothing: nothing to supply
        resistance(m_rec, e_rec, rows[a], xf, r_w)
        medium = 0.0
        for r in range(6):
            medium -= r_w[r] * xf[r]
        short = hold - medium - ROUNDING * (hold + abs(medium))
        if short > margin:
            worst, margin = a, short
            slip[:] = r_w
    if worst >= 0:
        k = rows[worst]
        b = m.tbody_bodyid[k]
        v = com_velocity(m, d, k)
        power = 0.0
        for r in range(3):
            power += slip[r] * v[r] + slip[3 + r] * d.cvel[b, r]
        if power > 0.0:  # R would push along the present motion: the pure model instead
            slip[:] = s.wrench[b]
    return worst


@numba.njit(**_JIT)
def resistance(m_rec, e_rec, k, twist, out):
    """out (6,) = the RFT wrench on tagged body k moving with twist (6,): reused from the last
    evaluation while the body and the twist's direction are where they were then
    (RESISTANCE_REUSE_M, RESISTANCE_REUSE_RAD)."""
    m, d, s = unpack(m_rec, e_rec)
    b = m.tbody_bodyid[k]
    size = body_size(m, k)
    key = np.empty(19)
    norm = 0.0
    for r in range(6):
        t = twist[r] * (size if r >= 3 else 1.0)
        norm += t * t
    norm = np.sqrt(norm)
    for r in range(3):
        key[r] = d.xipos[b, r]
    for r in range(9):
        key[3 + r] = d.ximat[b, r // 3, r % 3] * size
    for r in range(6):
        key[12 + r] = twist[r] * (size if r >= 3 else 1.0) / norm
    key[18] = 1.0
    old = s.mech_key[k]
    same = old[18] == 1.0
    for r in range(12):
        same = same and abs(key[r] - old[r]) <= RESISTANCE_REUSE_M
    for r in range(12, 18):
        same = same and abs(key[r] - old[r]) <= RESISTANCE_REUSE_RAD
    if same:
        out[:] = s.mech_R[k]
        return
    twist_wrench(m_rec, e_rec, k, twist[:3], twist[3:], out)
    s.mech_R[k] = out
    s.mech_key[k] = key


@numba.njit(inline="always", **_JIT)
def body_size(m, k):
    """Largest bounding-sphere radius of tagged body k's geoms [m]."""
    size = 0.0
    for g in range(m.tbody_geomadr[k], m.tbody_geomadr[k] + m.tbody_geomnum[k]):
        size = max(size, m.tgeom_rbound[g])
    return size


@numba.njit(**_JIT)
def treat_mechanisms(m_rec, e_rec):
    """The treatment of every tagged mechanism body in play (installed passes only).

    s.wrench rows hold the pure RFT wrenches and are replaced where held or slipping; sets
    s.decision and s.slow of those bodies, and records what the field applied (s.mech_tau,
    s.mech_prev, s.mech_held) for the next pass's predictor and references.
    """
    m, d, s = unpack(m_rec, e_rec)
    nv, nk = m.nv, m.tbody_bodyid.shape[0]
    same_time = s.mech_time[1] == 1.0 and d.time[0] == s.mech_time[0]
    valid = predictor_valid(m, d, s, same_time)
    if not same_time:  # a repeated pass (mj_forward, then mj_step) reads what the first read
        s.mech_in[0] = d.qacc
        s.mech_in[1] = s.mech_tau
        s.mech_in_prev[:] = s.mech_prev
        s.mech_in_force[:] = d.actuator_force
        s.mech_in_held[:] = s.mech_held
    rows = np.empty(nk, dtype=np.int64)
    n = gather(m_rec, e_rec, rows)
    if n == 0 or nv == 0 or not m.opt_timestep[0] > 0.0 or not setup(m_rec, e_rec, rows, n):
        s.mech_tau[:] = 0.0
        s.mech_held[:] = 0
        return
    held = np.zeros(n, dtype=np.int64)
    if valid:
        classify(m_rec, e_rec, rows, n, held)
    if held.any():
        hold_system(m_rec, e_rec, n)
    out = np.empty((n, 6))
    ref = np.empty((n, 6))
    for a in range(n):
        k = rows[a]
        b = m.tbody_bodyid[k]
        out[a] = s.wrench[b]
        ref[a] = s.mech_in_prev[k] if s.mech_in_held[k] else s.wrench[b]
    slipping = np.zeros(n, dtype=np.int64)
    slip = np.empty(6)
    for _ in range(n + 1):
        if not solve_holds(m_rec, e_rec, rows, n, held, ref, out):
            for a in range(n):  # not solvable: the pure model
                held[a] = 0
                slipping[a] = 0
                out[a] = s.wrench[m.tbody_bodyid[rows[a]]]
            break
        a = worst_hold(m_rec, e_rec, rows, n, held, out, slip)
        if a < 0:
            break
        held[a] = 0
        slipping[a] = 1
        out[a] = slip
    s.mech_tau[:] = 0.0
    s.mech_held[:] = 0
    for a in range(n):
        k = rows[a]
        b = m.tbody_bodyid[k]
        s.wrench[b] = out[a]
        dec = STICK if held[a] else (SLIP if slipping[a] else PURE)
        s.decision[k] = dec
        s.slow[k] = dec != PURE
        if held[a]:
            s.mech_held[k] = 1
            s.mech_prev[k] = out[a]
            s.stats[3] += 1
        elif slipping[a]:
            s.stats[4] += 1
        for r in range(6):
            for j in range(nv):
                s.mech_tau[j] += s.mech_J[6 * a + r, j] * out[a, r]
