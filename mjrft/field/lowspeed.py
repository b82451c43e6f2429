"""Low-speed treatment of free bodies: a velocity-level stick/slip step for RFT's forces.

Why: an RFT force depends on the direction of motion, not on the speed (docs/design.md section 2).
Near rest it is set-valued, like Coulomb friction: every wrench the medium can supply for some
direction of motion is a possible reaction of a body at rest. An explicit step evaluates it at
the current direction only, so a body that the medium could stop within one step overshoots
through zero velocity, the force flips, and the body chatters, creeps or gains energy
(docs/stability.md). Smoothing the force in time (exponential filters) or in speed (a viscous
zone) lags or distorts it for moving bodies; linearising it implicitly does not
help either: the force is homogeneous of degree 0 in the velocity, so its Jacobian times the
velocity vanishes (Euler's theorem) and an implicit step can turn the velocity but never stop it.

What: the time-stepping treatment of friction (Moreau; Stewart & Trinkle 1996) applied to one
rigid body. Over a step of length dt, with M the body's 6x6 inertia, xi its twist and f the other
known wrenches (gravity, the user's ``xfrc_applied``, the gyroscopic term):

1. ``xi_free = xi + dt M^-1 f``: the twist at the end of the step without the medium.
2. If the exact force W(xi) keeps the motion's sense over the step,
   ``<xi + reach (xi_free - xi + dt M^-1 W(xi)), xi>_M > 0``, the body keeps moving. If it is
   also fast, ``reach dt |M^-1 W(xi)|_M < |xi|_M`` (the medium alone could not change its twist
   by its whole size within ``reach`` steps), it feels the pure model, bit for bit, unless the
   explicit step with it would add energy (a force that turns the motion within the step;
   :func:`adds_no_energy`), which is treated as a slow body is. Otherwise
   it is slow and moving, where RFT is stiff across the motion: W depends on the direction
   only, so a tilt or sideways drift of size e changes W by ~|W| e / |xi|, and an explicit
   step of such a mode overshoots and grows at the step frequency (an upright ellipsoid
   lowered slowly rocked and tipped over; docs/stability.md, "Rocking"). Such a body gets
   the wrench of one Newton step of backward Euler, ``W(xi) + J d`` (:func:`implicit_wrench`):
   explicit along the motion (J xi = 0), implicit across it. Where that would reverse the
   motion within the step or gain energy over it, step 3 decides instead.
3. Otherwise the velocity would pass through zero inside the step. The medium's resistance to
   the free motion, R = W(xi_free), is evaluated; if it can dissipate the free motion's momentum
   within the step, ``-R . xi_free >= <xi_free, xi_free>_M / dt``, the body sticks: the wrench is
   ``-M xi_free / dt`` (the body ends the step at rest, held like a block by static friction;
   under RK4, a body rising slowly against gravity gets the largest fraction of it that adds no
   energy, :func:`stick_fraction`).
   Otherwise it slips and feels R: the force of the direction it is actually moving in at the end
   of the step (backward Euler in the direction, which cannot reverse the motion), provided R
   adds no energy over the step: ``R . (xi + xi_end) <= 0`` with ``xi_end = xi_free + dt M^-1 R``
   (the trapezoid; MuJoCo's Euler adds a term of its own, :func:`step_work`).
   R opposes xi_free, but when the other forces turn the motion (a spinning body thrown in) it
   can push along xi; then the body keeps the pure model if that does not reverse its motion
   within this step (reach 1), and sticks otherwise.

``<a, b>_M = m a_lin . b_lin + a_ang . I b_ang`` is the kinetic-energy inner product: the test is
on the whole twist, so translation and rotation stick together (testing them separately was
tried and rejected: a torque that translation causes was then applied to a stuck body and spun
it up). ``reach`` scales the predicted velocity change and is the only knob (1: the exact
time-stepping boundary; larger values hand more of the slow motion to steps 2 (implicit) and 3;
default 4). The treatment needs the body's own inertia and every force on it, so it applies to
free rigid bodies (a free joint, no jointed or massive descendants); bodies in mechanisms, whose
actuator and constraint forces are not known when the field runs (MuJoCo computes them after the
passive forces), get ``mjrft.field.mechanism`` instead.

Frames: world; twists are (linear velocity of the CoM [m/s], angular velocity [rad/s]) and wrenches
(force [N], torque about the CoM [N m]), both in world coordinates. Compiled; the arguments ``m``,
``d``, ``s`` are the field's tables, the MjData's arrays and the field's state for that MjData,
unpacked from the record addresses ``m_rec, e_rec`` (``mjrft.field.tables``).
``tests/field_reference.py`` states the same rules plainly in NumPy, and the tests check this code
against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from mjrft.field.evaluate import in_play, twist_wrench
from mjrft.field.tables import unpack

#: Modes: "stick" (the treatment of free bodies and of bodies in mechanisms,
#: ``mjrft.field.mechanism``), "free" (free bodies only: mechanism bodies feel the pure model) or
#: "off" (the pure model, for every body at every speed).
MODES = ("stick", "free", "off")
#: Default ``reach``: the stability map passes every dropped and lowered body at it
#: (docs/stability.md, "Results"); larger reaches hand more slow motion to the treatment but widen
#: the range of speeds that do not feel the pure model (docs/stability.md, "The reach").
DEFAULT_REACH = 4.0
#: An RK4 step holds the wrench of its first stage over the other three for a body the treatment
#: stuck or slipped, or whose motion would reverse within this many steps of the change
#: predicted at the step's start (mjrft.field.rk4; docs/stability.md, "RK4"); 4, as the reach.
RK4_HOLD_STEPS = 4.0
#: Decisions, per body and pass: the pure model, stuck (ends the step at rest), slipping on the
#: force of the free direction, the pure model linearised implicitly (slow moving body).
PURE, STICK, SLIP, IMPLICIT = 0, 1, 2, 3
#: Size of the twist perturbations (relative to |xi|_M) whose secants give the medium's Jacobian
#: for the linearly implicit step. A secant rather than a tangent: each triangle's force jumps
#: where it turns from trailing to leading, so the tangent of the summed force is noisy; 0.1
#: and 0.01 give transverse eigenvalues within 7 % of each other on the mole-crab ellipsoid.
JACOBIAN_STEP = 0.1
#: Relative size below which an energy balance counts as zero (its terms cancel; ~300 eps):
#: Euler's balance of a passive stick is exactly -|xi|^2_M / dt, but at rest it rounds to
#: +1e-22, and a stick fraction of 1 - 1e-16 would leave the body creeping.
ROUNDING = 64.0 * np.finfo(np.float64).eps
# Counters in FieldData.stats (tables.STATS) of the three treated decisions.
_STAT_OF = (-1, 3, 4, 5)
_JIT = {"cache": True, "error_model": "numpy"}


@dataclass(frozen=True)
class LowSpeed:
    """Static configuration of the low-speed treatment (built once at load).

    Attributes:
      mode: "stick", "free" or "off" (MODES).
      reach: > 0, dimensionless; the pure model is kept while the predicted velocity change over
        ``reach`` steps does not reverse the motion (see the module docstring).
    """

    mode: str = "stick"
    reach: float = DEFAULT_REACH

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"low_speed = {self.mode!r}: expected one of {', '.join(MODES)}")
        r = self.reach
        if not (isinstance(r, int | float | np.floating) and np.isfinite(r) and 0.0 < r <= 1e3):
            raise ValueError(f"stick reach = {r!r}: expected a number in (0, 1000]")

    @property
    def on(self) -> bool:
        """True if the treatment acts (on free bodies at least)."""
        return self.mode != "off"

    @property
    def mechanisms(self) -> bool:
        """True if it acts on bodies in mechanisms too (``mjrft.field.mechanism``)."""
        return self.mode == "stick"


@numba.njit(**_JIT)
def m_dot(a, b, mass, iw):
    """<a, b>_M = m a_lin . b_lin + a_ang . Iw b_ang of two (6,) twists (Iw: world axes)."""
    s = mass * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
    for r in range(3):
        for c in range(3):
            s += a[3 + r] * iw[r, c] * b[3 + c]
    return s


@numba.njit(**_JIT)
def solve6(a, rhs):
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


@numba.njit(**_JIT)
def step_work(w, twist, end, other, mass, dt, semi):
    """2 / dt times the mechanical energy a step gains with the medium's wrench w (a guard).

    The trapezoid ``w . (xi + xi_end)``: over a step with constant forces the kinetic energy
    changes by ``dt/2 (w + other) . (xi + xi_end)``, and RK4 moves the body along that mean
    twist, so the work of the other forces cancels with their potential. MuJoCo's Euler,
    implicit and implicitfast (``semi``) move it with the end twist instead (semi-implicit
    Euler), so a constant force F_c (gravity, the user's force) does ``dt F_c . v_end`` of work
    while the kinetic energy counts ``dt/2 F_c . (v + v_end)``: the balance gains
    ``-dt^2/(2m) F_c . (F_c + f)``, f the medium's force, positive when the medium decelerates
    a sinking body (docs/stability.md, "Energy balances"). The rotation has no potential and
    keeps the trapezoid. (6,) wrench w, start and end twists, the other wrenches; world frame;
    mass [kg]; dt [s].
    """
    p = 0.0
    for c in range(6):
        p += w[c] * (twist[c] + end[c])
    if semi:
        q = 0.0
        for c in range(3):
            q += other[c] * (other[c] + w[c])
        p -= dt * q / mass
    return p


@numba.njit(**_JIT)
def stick_fraction(stick, twist, other, mass, n2, dt, semi):
    """The largest fraction lam in [0, 1] of the stick wrench that adds no energy over the step.

    The full stick (lam = 1) ends the step at rest. Under RK4 the body still moves by dt xi / 2
    over the step, so a body rising slowly against gravity (|v| < g dt) gains more potential
    energy than the kinetic energy the stick takes. The wrench lam S ends at (1 - lam) xi_free
    and its :func:`step_work` is the quadratic ``(n2/dt) lam^2 + B lam + C`` with C <= 0, so the
    largest root is the answer when lam = 1 would gain; with RK4 it is ``1 - dt (S . xi) / n2``.
    Under Euler a passive body's stick never gains. stick (6,) = -M xi_free / dt, twist (6,),
    other (6,), world frame; n2 = |xi_free|^2_M [kg m^2/s^2]; mass [kg]; dt [s].
    """
    size = 0.0  # the balance's terms cancel: rounding counts as zero (ROUNDING)
    for c in range(6):
        size += abs(stick[c] * twist[c])
    if semi:
        for c in range(3):
            size += dt * abs(other[c]) * (abs(other[c]) + abs(stick[c])) / mass
    if step_work(stick, twist, np.zeros(6), other, mass, dt, semi) <= ROUNDING * size:
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


@numba.njit(**_JIT)
def transverse_basis(twist, mass, iw, mm, n):
    """(6, 6): row 0 the twist's unit direction, rows 1-5 orthonormal in <., .>_M and
    M-orthogonal to it (pivoted Gram-Schmidt over the coordinate axes scaled to unit M-norm,
    taking at each round the axis with the largest remainder). n = |twist|_M."""
    basis = np.empty((6, 6))
    basis[0] = twist / n
    axis = np.empty(6)
    res = np.empty(6)
    best = np.empty(6)
    for k in range(1, 6):
        best_n = -1.0
        for j in range(6):
            axis[:] = 0.0
            axis[j] = 1.0 / np.sqrt(mm[j, j])
            res[:] = axis
            for q in range(k):
                res -= m_dot(basis[q], axis, mass, iw) * basis[q]
            rn = np.sqrt(max(m_dot(res, res, mass, iw), 0.0))
            if rn > best_n:
                best_n = rn
                best[:] = res
        basis[k] = best / best_n
    return basis


@numba.njit(**_JIT)
def implicit_wrench(m_rec, e_rec, k, body, dt, semi, w):
    """One Newton step of backward Euler across the motion: replaces w (6,) (the pure wrench at
    twist) and returns True, or leaves it and returns False.

    ``(M - dt J') d = M (xi_e - c xi)`` and the wrench ``W(xi) + J' d``: xi_e = xi + dt M^-1
    (f + W(xi)) is the explicit step's end, c = |xi_e|_M / |xi|_M, J' = J / c the Jacobian at
    c xi. J comes from secants along the 5 transverse directions (J xi = 0 exactly: W is
    homogeneous of degree 0, Euler's theorem). Linearised at c xi, the same direction at the
    speed the step ends with, because a body speeding up from rest (c >> 1) is otherwise
    linearised far outside J's validity. False (step 3 of the treatment decides) if the result
    is not finite, reverses the motion within the step, or gains energy over it. body: tagged
    body k's (twist, other, mass, iw, ii) (:func:`treat_body`).
    """
    m, _, _ = unpack(m_rec, e_rec)
    twist, other, mass, iw, ii = body
    mm = np.zeros((6, 6))
    for c in range(3):
        mm[c, c] = mass
        for r in range(3):
            mm[3 + r, 3 + c] = iw[r, c]
    n = np.sqrt(m_dot(twist, twist, mass, iw))
    basis = transverse_basis(twist, mass, iw, mm, n)
    h = m.jacobian_step * n
    jac = np.zeros((6, 6))
    probe = np.empty(6)
    pw = np.empty(6)
    for q in range(1, 6):
        for c in range(6):
            probe[c] = twist[c] + h * basis[q, c]
        twist_wrench(m_rec, e_rec, k, probe[:3], probe[3:], pw)
        mu = mv(mm, basis[q])
        for r in range(6):
            dw = (pw[r] - w[r]) / h
            for c in range(6):
                jac[r, c] += dw * mu[c]
    end_pure = np.empty(6)
    epa = dt * mv(ii, other[3:] + w[3:])
    for c in range(3):
        end_pure[c] = twist[c] + dt * (other[c] + w[c]) / mass
        end_pure[3 + c] = twist[3 + c] + epa[c]
    cs = np.sqrt(max(m_dot(end_pure, end_pure, mass, iw), 0.0)) / n
    if not cs > 0.0:
        return False
    jac /= cs
    a = mm - dt * jac
    rhs = mv(mm, end_pure - cs * twist)
    d_xi = solve6(a, rhs)
    f = w + mv(jac, d_xi)
    for c in range(6):
        if not np.isfinite(f[c]):
            return False
    end = np.empty(6)  # guards: the motion keeps its sense, no energy added over the step
    ea = dt * mv(ii, other[3:] + f[3:])
    for c in range(3):
        end[c] = twist[c] + dt * (other[c] + f[c]) / mass
        end[3 + c] = twist[3 + c] + ea[c]
    if m_dot(end, twist, mass, iw) <= 0.0:
        return False
    if step_work(f, twist, end, other, mass, dt, semi) > 0.0:
        return False
    w[:] = f
    return True


@numba.njit(inline="always", **_JIT)
def mv(a, x):
    """a (r, c) times x (c,), summed in index order. Written out rather than ``a @ x``: numba's
    matrix products call BLAS through scipy, which a 3x3 or 6x6 product in every pass must not
    need (nor start BLAS threads for)."""
    y = np.empty(a.shape[0])
    for r in range(a.shape[0]):
        acc = 0.0
        for c in range(a.shape[1]):
            acc += a[r, c] * x[c]
        y[r] = acc
    return y


@numba.njit(inline="always", **_JIT)
def dot(x, y):
    """x . y of two (n,) vectors, summed in index order (no BLAS: see :func:`mv`)."""
    acc = 0.0
    for c in range(x.shape[0]):
        acc += x[c] * y[c]
    return acc


@numba.njit(**_JIT)
def world_inertia(x, inertia):
    """(3, 3) inertia about the CoM in world axes, X diag(I) X^T, and its inverse, from the
    inertial frame x (3, 3) (ximat) and the principal moments (3,) [kg m^2]."""
    iw = np.empty((3, 3))
    ii = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            a = 0.0
            ai = 0.0
            for q in range(3):
                a += x[r, q] * inertia[q] * x[c, q]
                ai += x[r, q] * x[c, q] / inertia[q]
            iw[r, c] = a
            ii[r, c] = ai
    return iw, ii


@numba.njit(inline="always", **_JIT)
def com_velocity(m, d, k):
    """(3,) world velocity [m/s] of tagged body k's CoM: cvel's linear part is at the subtree
    CoM of the body's root (docs/design.md section 3)."""
    b = m.tbody_bodyid[k]
    om = d.cvel[b, :3]
    c0 = d.subtree_com[m.tbody_rootid[k]]
    rx, ry, rz = d.xipos[b, 0] - c0[0], d.xipos[b, 1] - c0[1], d.xipos[b, 2] - c0[2]
    v = np.empty(3)
    v[0] = d.cvel[b, 3] + om[1] * rz - om[2] * ry
    v[1] = d.cvel[b, 4] + om[2] * rx - om[0] * rz
    v[2] = d.cvel[b, 5] + om[0] * ry - om[1] * rx
    return v


@numba.njit(inline="always", **_JIT)
def gravity(m, b):
    """(3,) gravity acceleration [m/s^2] on body b, world frame (flag and compensation live)."""
    g = np.zeros(3)
    if m.opt_disableflags[0] & m.dsbl_gravity:
        return g
    comp = m.body_gravcomp[b]
    for c in range(3):
        g[c] = m.opt_gravity[c] * (1.0 - comp)
    return g


@numba.njit(inline="always", **_JIT)
def has_inertia(m, b):
    """True if body b has a positive mass and positive principal moments (it can be treated)."""
    inertia = m.body_inertia[b]
    return m.body_mass[b] > 0.0 and inertia[0] > 0.0 and inertia[1] > 0.0 and inertia[2] > 0.0


@numba.njit(inline="always", **_JIT)
def free_body_terms(m, d, k, user):
    """Tagged free body k's twist and the other wrenches on it over a step: gravity, the user's
    row user (6,), the gyroscopic torque -omega x I omega. Returns (twist (6,), other (6,),
    world inertia (3, 3), its inverse, gravity (3,) [m/s^2]); world frame, torques about the CoM.
    """
    b = m.tbody_bodyid[k]
    mass = m.body_mass[b]
    gvec = gravity(m, b)
    iw, ii = world_inertia(d.ximat[b], m.body_inertia[b])
    om = d.cvel[b, :3]
    v = com_velocity(m, d, k)
    iom = mv(iw, om)
    twist = np.empty(6)
    other = np.empty(6)
    for c in range(3):
        twist[c] = v[c]
        twist[3 + c] = om[c]
        other[c] = mass * gvec[c] + user[c]
    other[3] = user[3] - (om[1] * iom[2] - om[2] * iom[1])
    other[4] = user[4] - (om[2] * iom[0] - om[0] * iom[2])
    other[5] = user[5] - (om[0] * iom[1] - om[1] * iom[0])
    return twist, other, iw, ii, gvec


@numba.njit(**_JIT)
def treat_body(m_rec, e_rec, k, user, dt, semi, w, ab, tw):
    """The low-speed treatment of tagged body k (a free rigid body); returns its decision.

    w (6,): the body's pure RFT wrench, replaced by the treated one. user (6,): the other
    applied wrench on the body (the user's xfrc_applied row). ab (2,): set to |xi|^2_M and
    <d_xi, xi>_M (the motion keeps its sense over n steps if ab[0] + n ab[1] > 0). tw (6,): set
    to the body's twist (v at the CoM, omega). semi: positions advance with the step's end
    velocity (every integrator but RK4; :func:`step_work`). World frame, torques about the CoM.
    """
    m, d, _ = unpack(m_rec, e_rec)
    b = m.tbody_bodyid[k]
    mass = m.body_mass[b]
    if not has_inertia(m, b):
        return PURE
    reach = m.reach
    twist, other, iw, ii, gvec = free_body_terms(m, d, k, user)
    v, om = twist[:3], twist[3:]
    tw[:] = twist
    iom = mv(iw, om)
    tau = other[3:]
    v_free = np.empty(3)
    for c in range(3):
        v_free[c] = v[c] + dt * (gvec[c] + user[c] / mass)
    om_free = om + dt * mv(ii, tau)
    dom_pure = dt * mv(ii, w[3:])
    # <probe, xi>_M = |xi|^2_M + reach <d_xi, xi>_M, d_xi the predicted change over the step.
    sq = mass * dot(v, v) + dot(om, iom)
    dxi = 0.0
    for c in range(3):
        dxi += (v_free[c] - v[c] + dt * w[c] / mass) * mass * v[c]
    dxi += dot(om_free - om + dom_pure, iom)
    ab[0] = sq
    ab[1] = dxi
    # The body's terms: twist and other wrenches (6,), mass [kg], world inertia and inverse.
    body = (twist, other, mass, iw, ii)
    if sq + reach * dxi > 0.0:
        # Stiff across the motion: (reach dt)^2 |M^-1 W|^2_M >= |xi|^2_M (module docstring, 2).
        wn2 = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) / mass + dot(w[3:], mv(ii, w[3:]))
        fast = (reach * dt) ** 2 * wn2 < sq
        if (fast or not m.jacobian_step > 0.0) and adds_no_energy(w, body, dt, semi):
            return PURE
        if m.jacobian_step > 0.0 and implicit_wrench(m_rec, e_rec, k, body, dt, semi, w):
            return IMPLICIT
        # Implicitly the motion would reverse within the step (or gain work): decide below.
    return stick_or_slip(m_rec, e_rec, k, body, v_free, om_free, dt, semi, w, sq + dxi > 0.0)


@numba.njit(**_JIT)
def adds_no_energy(w, body, dt, semi):
    """True if the explicit step with the medium's wrench w (6,) adds no mechanical energy
    (:func:`step_work` <= rounding). A dissipative force can still add energy over a step when
    it turns the motion within it: w . xi < 0 at the start, but the end twist has swung round
    so far that the mean of the two gains (a sharp-edged body spinning into the medium: up to
    12 % of its energy in one step, benchmarks/energy.py). body: (twist, other, mass, iw, ii)."""
    twist, other, mass, _, ii = body
    end = np.empty(6)
    ang = dt * mv(ii, other[3:] + w[3:])
    size = 0.0
    for c in range(3):
        end[c] = twist[c] + dt * (other[c] + w[c]) / mass
        end[3 + c] = twist[3 + c] + ang[c]
    for c in range(6):
        size += abs(w[c]) * (abs(twist[c]) + abs(end[c]))
    if semi:
        for c in range(3):
            size += dt * abs(other[c]) * (abs(other[c]) + abs(w[c])) / mass
    return step_work(w, twist, end, other, mass, dt, semi) <= ROUNDING * size


@numba.njit(**_JIT)
def stick_or_slip(m_rec, e_rec, k, body, v_free, om_free, dt, semi, w, keeps):
    """Step 3 of the treatment (module docstring): slip on R = W(xi_free) if it cannot stop the
    free motion within the step and adds no energy; else the pure model w if the motion keeps
    its sense within this step (``keeps``) and w adds no energy; else stick. Returns the
    decision; sets w (6,). body: (twist, other, mass, iw, ii) as in :func:`treat_body`;
    v_free, om_free (3,): the free motion's end twist."""
    twist, other, mass, iw, ii = body
    n2 = mass * dot(v_free, v_free) + dot(om_free, mv(iw, om_free))
    if n2 > 0.0:
        rw = np.zeros(6)
        twist_wrench(m_rec, e_rec, k, v_free, om_free, rw)
        diss = -(rw[0] * v_free[0] + rw[1] * v_free[1] + rw[2] * v_free[2])
        diss -= rw[3] * om_free[0] + rw[4] * om_free[1] + rw[5] * om_free[2]
        if dt * diss < n2:
            om_end = om_free + dt * mv(ii, rw[3:])
            end = np.empty(6)
            for c in range(3):
                end[c] = v_free[c] + dt * rw[c] / mass
                end[3 + c] = om_end[c]
            if step_work(rw, twist, end, other, mass, dt, semi) <= 0.0:
                for c in range(6):
                    w[c] = rw[c]
                return SLIP
            if keeps and adds_no_energy(w, body, dt, semi):
                return PURE
    iomf = mv(iw, om_free)
    for c in range(3):
        w[c] = -mass * v_free[c] / dt
        w[3 + c] = -iomf[c] / dt
    lam = stick_fraction(w, twist, other, mass, n2, dt, semi)
    for c in range(6):
        w[c] *= lam
    return STICK


@numba.njit(**_JIT)
def treat_all(m_rec, e_rec, user):
    """The low-speed treatment of every treatable tagged body with a geom in play.

    s.wrench rows hold the pure RFT wrenches and are replaced where treated; user (nbody, 6):
    the other applied wrenches. Sets s.decision, s.slow (an RK4 step must not evaluate the
    pure model in its later stages: treated, or reversing within rk4_hold_steps) and s.frozen
    (stage 1's twist and implicit correction of bodies moved by the implicit step).
    """
    m, _, s = unpack(m_rec, e_rec)
    dt = m.opt_timestep[0]
    semi = m.opt_integrator[0] != m.int_rk4
    for k in range(m.tbody_bodyid.shape[0]):
        b = m.tbody_bodyid[k]
        s.slow[k] = False
        if not m.tbody_treat[k] or not dt > 0.0:
            continue
        if not in_play(
            m_rec, e_rec, k
        ):  # nothing of the body can touch the medium: nothing to treat
            continue
        ab = np.zeros(2)
        pure = s.wrench[b].copy()
        dec = treat_body(m_rec, e_rec, k, user[b], dt, semi, s.wrench[b], ab, s.frozen[k, :6])
        for c in range(6):  # only a body moved by the implicit step keeps a record
            s.frozen[k, 6 + c] = s.wrench[b, c] - pure[c] if dec == IMPLICIT else 0.0
            if dec != IMPLICIT:
                s.frozen[k, c] = 0.0
        s.decision[k] = dec
        s.slow[k] = dec != PURE or ab[0] + m.rk4_hold_steps * ab[1] <= 0.0
        if dec != PURE:
            s.stats[_STAT_OF[dec]] += 1
