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
passive forces), get the mechanism treatment instead (engine/mechanism.cc; docs/stability.md,
"Mechanisms").

Frames: world; twists are (linear velocity of the CoM [m/s], angular velocity [rad/s]) and wrenches
(force [N], torque about the CoM [N m]), both in world coordinates. The engine implements the
rules (engine/lowspeed.cc, and engine/mechanism.cc for bodies in mechanisms); this module holds
their configuration and constants. ``tests/field_reference.py`` states the same rules plainly in
NumPy, and the tests check the engine against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Modes: "stick" (the treatment of free bodies and of bodies in mechanisms,
#: engine/mechanism.cc), "free" (free bodies only: mechanism bodies feel the pure model) or
#: "off" (the pure model, for every body at every speed).
MODES = ("stick", "free", "off")
#: Default ``reach``: the stability map passes every dropped and lowered body at it
#: (docs/stability.md, "Results"); larger reaches hand more slow motion to the treatment but widen
#: the range of speeds that do not feel the pure model (docs/stability.md, "The reach").
DEFAULT_REACH = 4.0
#: An RK4 step holds the wrench of its first stage over the other three for a body the treatment
#: stuck or slipped, or whose motion would reverse within this many steps of the change
#: predicted at the step's start (engine/rk4.cc; docs/stability.md, "RK4"); 4, as the reach.
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
        """True if it acts on bodies in mechanisms too (engine/mechanism.cc)."""
        return self.mode == "stick"


#: Regularisation of the mechanism treatment's hold system relative to each row's diagonal,
#: A + eps diag(A): modes nearly null after scaling A to a unit diagonal are treated as null
#: (engine/mechanism.h's kHoldRegularisation says why).
HOLD_REGULARISATION = 1e-4
