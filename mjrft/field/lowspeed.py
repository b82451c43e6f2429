"""Low-speed treatment: a velocity-level stick/slip step for RFT's rate-independent forces.

Why: an RFT force depends on the direction of motion, not on the speed (DESIGN.md section 2).
Near rest it is set-valued, like Coulomb friction: every wrench the medium can supply for some
direction of motion is a possible reaction of a body at rest. An explicit step evaluates it at
the current direction only, so a body that the medium could stop within one step overshoots
through zero velocity, the force flips, and the body chatters, creeps or gains energy
(benchmarks/RESULTS.md, "Stability map"). Smoothing the force in time (exponential filters) or in
speed (a viscous zone) lags or distorts it for moving bodies; linearising it implicitly does not
help either: the force is homogeneous of degree 0 in the velocity, so its Jacobian times the
velocity vanishes (Euler's theorem) and an implicit step can turn the velocity but never stop it.

What: the time-stepping treatment of friction (Moreau; Stewart & Trinkle 1996) applied to one
rigid body. Over a step of length dt, with M the body's 6x6 inertia, xi its twist and f the other
known wrenches (gravity, the user's ``xfrc_applied``, the gyroscopic term):

1. ``xi_free = xi + dt M^-1 f``: the twist at the end of the step without the medium.
2. If the exact force W(xi) keeps the motion's sense over the step,
   ``<xi + reach (xi_free - xi + dt M^-1 W(xi)), xi>_M > 0``, the body keeps moving. If it is
   also fast, ``reach dt |M^-1 W(xi)|_M < |xi|_M`` (the medium alone could not change its twist
   by its whole size within ``reach`` steps), it feels the pure model, bit for bit. Otherwise
   it is slow and moving, where RFT is stiff across the motion: W depends on the direction
   only, so a tilt or sideways drift of size e changes W by ~|W| e / |xi|, and an explicit
   step of such a mode overshoots and grows at the step frequency (an upright ellipsoid
   lowered slowly rocked and tipped over; benchmarks/RESULTS.md, "Rocking"). Such a body gets
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
default 4). The
treatment needs the body's own inertia and every force on it, so it applies to free rigid bodies
(a free joint, no jointed or massive descendants); bodies in mechanisms feel the pure model,
since their actuator and constraint forces are not known when the field runs (MuJoCo computes
them after the passive forces).

Frames: world; twists are (linear velocity of the CoM [m/s], angular velocity [rad/s]) and
wrenches (force [N], torque about the CoM [N m]), both in world coordinates. Pure NumPy (the slow
reference of the compiled version in ``mjrft._native``); imports no mujoco.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Modes: "stick" (the treatment) or "off" (the pure model, for every body at every speed).
MODES = ("stick", "off")
#: Default ``reach``. Measured in the third session, before the implicit step (benchmarks/
#: RESULTS.md, "RK4 and the reach"; settle 1.5 s, hold
#: 2 s, 60 cells per integrator and release): with slip limited to forces that do no work over
#: the step, reaches 1, 4, 8 settle every dropped RK4 body and 49, 56, 58 of 60 slowly lowered
#: ones; 4 and 8 also every Euler/implicitfast body; no thrown body gains energy at any of them
#: (the 10 s map at reach 4: benchmarks/RESULTS.md, "Stability map"). 4 rather than 8: the
#: treatment's speed scale (a body counts as slow while its motion would reverse within
#: ``reach`` steps) stays small, so the pure model keeps more motion.
DEFAULT_REACH = 4.0
#: An RK4 step holds the wrench of its first stage over the other three for a body the treatment
#: stuck or slipped, or whose motion would reverse within this many steps of the change
#: predicted at the step's start; a body moved by the implicit step keeps the first stage's
#: twist and correction; other bodies feel the pure model in every stage
#: (mjrft._native.rk4_hold).
#: Measured at reach 1 with the earlier slip rule (benchmarks/RESULTS.md): 2, 4, 8 settle 38,
#: 46, 51 of 60 slowly lowered RK4 cells (all drops settle), but with 2 and 8 a thrown spinning
#: body gained energy in a step.
RK4_HOLD_STEPS = 4.0
#: Decisions, per body and pass: the pure model, stuck (ends the step at rest), slipping on the
#: force of the free direction, the pure model linearised implicitly (slow moving body).
PURE, STICK, SLIP, IMPLICIT = 0, 1, 2, 3
#: Size of the twist perturbations (relative to |xi|_M) whose secants give the medium's Jacobian
#: for the linearly implicit step. A secant rather than a tangent: each triangle's force jumps
#: where it turns from trailing to leading, so the tangent of the summed force is noisy; 0.1
#: and 0.01 give transverse eigenvalues within 7 % of each other on the mole-crab ellipsoid.
JACOBIAN_STEP = 0.1
#: Relative size below which an energy balance counts as zero (its terms cancel; ~300 eps).
ROUNDING = 64.0 * np.finfo(float).eps


@dataclass(frozen=True)
class LowSpeed:
    """Static configuration of the low-speed treatment (built once at load).

    Attributes:
      mode: "stick" or "off".
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
        """True if the treatment acts."""
        return self.mode != "off"


def inertia_dot(a: np.ndarray, b: np.ndarray, mass: float, inertia: np.ndarray) -> float:
    """Kinetic-energy inner product m a_lin . b_lin + a_ang . I b_ang of two (6,) twists."""
    return float(mass * (a[:3] @ b[:3]) + a[3:] @ (inertia @ b[3:]))


def keeps_sense(
    pure: np.ndarray,
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    other: np.ndarray,
    dt: float,
    steps: float,
) -> bool:
    """True if the twist keeps its sense under ``steps`` times the change predicted for a step.

    ``<xi + steps dt M^-1 (f + W(xi)), xi>_M > 0``; arguments as in :func:`treat` (world frame,
    twists [m/s, rad/s], wrenches [N, N m] about the CoM). With ``steps = reach`` this is the
    treatment's first test; with ``RK4_HOLD_STEPS`` it decides which bodies an RK4 step holds.
    """
    twist = np.asarray(twist, dtype=float)
    change = np.asarray(pure, dtype=float) + np.asarray(other, dtype=float)
    accel = np.concatenate([change[:3] / mass, np.linalg.solve(inertia, change[3:])])
    probe = twist + steps * dt * accel
    return inertia_dot(probe, twist, mass, inertia) > 0.0


def _mass_matrix(mass: float, inertia: np.ndarray) -> np.ndarray:
    """(6, 6) block diagonal of m I_3 and the (3, 3) inertia (world axes)."""
    mm = np.zeros((6, 6))
    mm[:3, :3] = mass * np.eye(3)
    mm[3:, 3:] = inertia
    return mm


def stiff(
    pure: np.ndarray,
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    dt: float,
    steps: float,
) -> bool:
    """True if the medium alone could change the twist by its whole size within ``steps`` steps:
    ``steps dt |M^-1 W(xi)|_M >= |xi|_M``. Arguments as in :func:`treat` (world frame).

    Why: W is homogeneous of degree 0, so its Jacobian across the motion scales as |W| / |xi|;
    an explicit step of a transverse mode (a tilt, a sideways drift) overshoots once
    dt |M^-1 J| passes ~1 and grows at the step frequency once it passes 2 (benchmarks/RESULTS.md,
    "Rocking"). A body this test flags is moved with the linearly implicit force instead.
    """
    mm = _mass_matrix(mass, inertia)
    twist = np.asarray(twist, dtype=float)
    pure = np.asarray(pure, dtype=float)
    w_norm2 = float(pure @ np.linalg.solve(mm, pure))
    return (steps * dt) ** 2 * w_norm2 >= float(twist @ mm @ twist)


def transverse_basis(twist: np.ndarray, mass: float, inertia: np.ndarray) -> np.ndarray:
    """(5, 6) twists, orthonormal in <., .>_M and M-orthogonal to ``twist`` (world frame).

    Gram-Schmidt from the twist's direction over the coordinate axes scaled to unit M-norm,
    taking at each round the axis with the largest remainder (so none is nearly dependent).
    """
    mm = _mass_matrix(mass, inertia)
    basis = [np.asarray(twist, dtype=float) / math.sqrt(float(twist @ mm @ twist))]
    axes = [np.eye(6)[j] / math.sqrt(mm[j, j]) for j in range(6)]
    for _ in range(5):
        best, best_n = None, -1.0
        for a in axes:
            r = a - sum(float(u @ mm @ a) * u for u in basis)
            rn = math.sqrt(max(float(r @ mm @ r), 0.0))
            if rn > best_n:
                best, best_n = r, rn
        basis.append(best / best_n)
    return np.array(basis[1:])


def step_work(
    w: np.ndarray,
    twist: np.ndarray,
    end: np.ndarray,
    other: np.ndarray,
    mass: float,
    dt: float,
    semi_implicit: bool,
) -> float:
    """2 / dt times the mechanical energy a step gains with the medium's wrench w (a guard).

    The trapezoid ``w . (xi + xi_end)``: over a step with constant forces the kinetic energy
    changes by ``dt/2 (w + other) . (xi + xi_end)``, and RK4 moves the body along that mean
    twist, so the work of the other forces cancels with their potential. MuJoCo's Euler,
    implicit and implicitfast (``semi_implicit``) move it with the end twist instead
    (semi-implicit Euler), so a constant force F_c (gravity, the user's force) does
    ``dt F_c . v_end`` of work while the kinetic energy counts ``dt/2 F_c . (v + v_end)``:
    the balance gains ``-dt^2/(2m) F_c . (F_c + f)``, f the medium's force. That is positive
    when the medium decelerates a sinking body (F_c down, F_c + f up) and is the gain the
    slow-lowering map flagged (benchmarks/RESULTS.md, "Euler's energy balance and RK4's
    stick"); the rotation has no potential and keeps the trapezoid. Arguments: (6,) wrench,
    start and end twists and the other wrenches, world frame, as in :func:`treat`; mass [kg];
    dt [s].
    """
    p = float(np.asarray(w, dtype=float) @ (np.asarray(twist) + np.asarray(end)))
    if semi_implicit:
        fc = np.asarray(other, dtype=float)[:3]
        p -= dt * float(fc @ (fc + np.asarray(w, dtype=float)[:3])) / mass
    return p


def implicit_wrench(
    pure: np.ndarray,
    wrench_at: Callable[[np.ndarray], np.ndarray],
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    other: np.ndarray,
    dt: float,
    semi_implicit: bool = False,
) -> np.ndarray | None:
    """The medium's wrench of a linearly implicit (one Newton step of backward Euler), or None.

    ``(M - dt J') d = M (xi_e - c xi)`` and the wrench ``W(xi) + J' d``: xi_e = xi + dt M^-1
    (f + W(xi)) is the explicit step's end, c = |xi_e|_M / |xi|_M, J' = J / c the Jacobian at
    c xi (with c = 1 this is ``(M - dt J) d = dt (f + W)``, Rosenbrock-Euler). J is the medium's
    Jacobian at xi from secants along the 5 transverse directions of :func:`transverse_basis`
    (J xi = 0 exactly: W is homogeneous of degree 0, Euler's theorem; so 5 evaluations, not 6).
    Along the motion this is the explicit step (stopping is the stick's job); across it, the
    step is backward Euler, which damps the stiff transverse modes instead of amplifying them.
    None (the treatment's step 3 decides) if the result is not finite, reverses the motion
    within the step, or gains energy over the step (:func:`step_work`). Arguments as in
    :func:`treat` (world frame; wrenches about the CoM).
    """
    twist = np.asarray(twist, dtype=float)
    pure = np.asarray(pure, dtype=float)
    other = np.asarray(other, dtype=float)
    mm = _mass_matrix(mass, inertia)
    n = math.sqrt(float(twist @ mm @ twist))
    h = JACOBIAN_STEP * n
    jac = np.zeros((6, 6))
    for u in transverse_basis(twist, mass, inertia):
        dw = (np.asarray(wrench_at(twist + h * u), dtype=float) - pure) / h
        jac += np.outer(dw, mm @ u)
    end_pure = twist + np.linalg.solve(mm, dt * (other + pure))
    # Linearise at c xi, c = |xi_end|_M / |xi|_M of the explicit step: the same direction (so
    # the same W) at the speed the step ends with, where the Jacobian is J / c (degree -1). A
    # body speeding up from rest (c >> 1) is otherwise linearised far outside J's validity.
    c = math.sqrt(max(float(end_pure @ mm @ end_pure), 0.0)) / n
    if not c > 0.0:
        return None
    jac /= c
    d_xi = np.linalg.solve(mm - dt * jac, mm @ (end_pure - c * twist))
    f = pure + jac @ d_xi
    if not np.all(np.isfinite(f)):
        return None
    end = twist + np.linalg.solve(mm, dt * (other + f))
    if float(end @ mm @ twist) <= 0.0:
        return None
    if step_work(f, twist, end, other, mass, dt, semi_implicit) > 0.0:
        return None
    return f


def treat(
    pure: np.ndarray,
    wrench_at: Callable[[np.ndarray], np.ndarray],
    twist: np.ndarray,
    mass: float,
    inertia: np.ndarray,
    other: np.ndarray,
    dt: float,
    reach: float = DEFAULT_REACH,
    implicit: bool = True,
    semi_implicit: bool = False,
) -> tuple[np.ndarray, int]:
    """The wrench the medium applies to one free rigid body over a step, and the decision.

    Args:
      pure: (6,) RFT wrench at the current twist (force [N], torque about the CoM [N m]), world.
      wrench_at: maps a (6,) twist (world, as ``twist``) to the RFT wrench at that twist.
      twist: (6,) linear velocity of the CoM [m/s] then angular velocity [rad/s], world.
      mass: [kg] (> 0). inertia: (3, 3) inertia about the CoM [kg m^2], world axes (SPD).
      other: (6,) every other wrench on the body over the step [N, N m], world, about the CoM.
      dt: step [s] (> 0). reach: see the module docstring.
      implicit: False keeps the pure model for slow moving bodies (step 2): the explicit
        step, which rocks a slowly sinking body (benchmarks/RESULTS.md, "Rocking"). The field
        always passes True; under RK4 its later stages keep the first stage's twist and
        implicit correction (mjrft._native.rk4_hold).
      semi_implicit: True where positions advance with the step's end velocity (MuJoCo's
        Euler, implicit, implicitfast), False for RK4: the energy balance the implicit and
        slip guards use (:func:`step_work`). The field passes the model's integrator.
    Returns:
      (wrench (6,), decision): decision is PURE, STICK, SLIP or IMPLICIT.
    """
    twist = np.asarray(twist, dtype=float)
    pure = np.asarray(pure, dtype=float)
    other = np.asarray(other, dtype=float)

    def m_inv(w: np.ndarray) -> np.ndarray:
        return np.concatenate([w[:3] / mass, np.linalg.solve(inertia, w[3:])])

    v_free = twist + dt * m_inv(other)
    if keeps_sense(pure, twist, mass, inertia, other, dt, reach):
        if not (implicit and stiff(pure, twist, mass, inertia, dt, reach)):
            return pure.copy(), PURE
        f = implicit_wrench(pure, wrench_at, twist, mass, inertia, other, dt, semi_implicit)
        if f is not None:
            return f, IMPLICIT
        # Implicitly the motion would reverse within the step (or gain work): step 3 decides.
    n2 = inertia_dot(v_free, v_free, mass, inertia)
    if n2 > 0.0:
        r = np.asarray(wrench_at(v_free), dtype=float)
        if dt * -float(r @ v_free) < n2:
            # Slip only where R adds no energy over the step (step_work: the trapezoid of the
            # power, plus semi-implicit Euler's term); else the pure model where it keeps the
            # motion's sense within this step, else stick.
            end = v_free + dt * m_inv(r)
            if step_work(r, twist, end, other, mass, dt, semi_implicit) <= 0.0:
                return r, SLIP
            if keeps_sense(pure, twist, mass, inertia, other, dt, 1.0):
                return pure.copy(), PURE
    stick = np.concatenate([-mass * v_free[:3], -(inertia @ v_free[3:])]) / dt
    return stick * stick_fraction(stick, twist, other, mass, n2, dt, semi_implicit), STICK


def stick_fraction(
    stick: np.ndarray,
    twist: np.ndarray,
    other: np.ndarray,
    mass: float,
    n2: float,
    dt: float,
    semi_implicit: bool,
) -> float:
    """The largest fraction lam in [0, 1] of the stick wrench that adds no energy over the step.

    The full stick (lam = 1) ends the step at rest. Under RK4 the body still moves by dt xi / 2
    over the step, so a body rising slowly against gravity (|v| < g dt) gains more potential
    energy than the kinetic energy the stick takes (the RK4 flags of the slow lowering;
    benchmarks/RESULTS.md, "Euler's energy balance and RK4's stick"). The wrench lam S ends at
    (1 - lam) xi_free and its :func:`step_work` is the quadratic ``(n2/dt) lam^2 + B lam + C``
    with C <= 0, so the largest root is the answer when lam = 1 would gain; with RK4 it is
    ``1 - dt (S . xi) / n2``.
    Under Euler a passive body's stick never gains (its position does not move). Arguments:
    stick (6,) = -M xi_free / dt, twist (6,), other (6,), world frame as in :func:`treat`;
    n2 = |xi_free|^2_M [kg m^2/s^2] (twice a kinetic energy); mass [kg]; dt [s].
    """
    fc = np.asarray(other, dtype=float)[:3] if semi_implicit else np.zeros(3)
    # Rounding: Euler's balance of a passive stick is exactly -|xi|^2_M / dt <= 0, but its terms
    # cancel; at rest it rounds to +1e-22 and a fraction 1 - 1e-16 would leave the body creeping.
    size = float(
        np.abs(stick) @ np.abs(twist) + dt * np.abs(fc) @ (np.abs(fc) + np.abs(stick[:3])) / mass
    )
    if step_work(stick, twist, np.zeros(6), other, mass, dt, semi_implicit) <= ROUNDING * size:
        return 1.0
    a2 = n2 / dt
    b1 = float(stick @ twist) - a2 - dt * float(fc @ stick[:3]) / mass
    c0 = -dt * float(fc @ fc) / mass
    root = math.sqrt(b1 * b1 - 4.0 * a2 * c0)
    lam = -2.0 * c0 / (b1 + root) if b1 > 0.0 else (root - b1) / (2.0 * a2)
    return min(max(lam, 0.0), 1.0)
