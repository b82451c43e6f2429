// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Low-speed treatment of free bodies: a velocity-level stick/slip step for RFT's forces
// (mjrft.field.lowspeed states the same rules; docs/stability.md).
//
// Why: an RFT force depends on the direction of motion, not on the speed. Near rest it is
// set-valued, like Coulomb friction: every wrench the medium can supply for some direction of
// motion is a possible reaction of a body at rest. An explicit step evaluates it at the current
// direction only, so a body that the medium could stop within one step overshoots through zero
// velocity, the force flips, and the body chatters, creeps or gains energy. Smoothing the force
// in time or in speed lags or distorts it for moving bodies; linearising it implicitly does not
// help either: the force is homogeneous of degree 0 in the velocity, so its Jacobian times the
// velocity vanishes (Euler's theorem) and an implicit step can turn the velocity but never
// stop it.
//
// What: the time-stepping treatment of friction (Moreau; Stewart & Trinkle 1996) applied to one
// rigid body. Over a step of length dt, with M the body's 6x6 inertia, xi its twist and f the
// other known wrenches (gravity, the user's xfrc_applied, the gyroscopic term):
//
// 1. xi_free = xi + dt M^-1 f: the twist at the end of the step without the medium.
// 2. If the exact force W(xi) keeps the motion's sense over the step,
//    <xi + reach (xi_free - xi + dt M^-1 W(xi)), xi>_M > 0, the body keeps moving. If it is also
//    fast, reach dt |M^-1 W(xi)|_M < |xi|_M, it feels the pure model, bit for bit, unless the
//    explicit step with it would add energy (AddsNoEnergy), which is treated as a slow body is.
//    Otherwise it is slow and moving, where RFT is stiff across the motion (W depends on the
//    direction only, so an explicit step of a tilt overshoots and grows at the step frequency):
//    such a body gets the wrench of one Newton step of backward Euler, W(xi) + J d
//    (ImplicitWrench): explicit along the motion (J xi = 0), implicit across it. Where that
//    would reverse the motion within the step or gain energy over it, step 3 decides instead.
// 3. Otherwise the velocity would pass through zero inside the step. The medium's resistance to
//    the free motion, R = W(xi_free), is evaluated; if it can dissipate the free motion's
//    momentum within the step, -R . xi_free >= <xi_free, xi_free>_M / dt, the body sticks: the
//    wrench is -M xi_free / dt (it ends the step at rest; under RK4 a body rising slowly
//    against gravity gets the largest fraction of it that adds no energy, StickFraction).
//    Otherwise it slips and feels R (backward Euler in the direction, which cannot reverse the
//    motion), provided R adds no energy over the step (StepWork). When the other forces turn
//    the motion R can push along xi; then the body keeps the pure model if that does not
//    reverse its motion within this step (reach 1), and sticks otherwise.
//
// <a, b>_M = m a_lin . b_lin + a_ang . I b_ang is the kinetic-energy inner product: the test is
// on the whole twist, so translation and rotation stick together. reach scales the predicted
// velocity change and is the only knob (Tables::reach). The treatment needs the body's own
// inertia and every force on it, so it applies to free rigid bodies (Tables::tbody_treat);
// bodies in mechanisms get mechanism.h instead.
//
// Frames: world; twists are (linear velocity of the CoM [m/s], angular velocity [rad/s]) and
// wrenches (force [N], torque about the CoM [N m]). 3x3 and 6x6 matrices are row-major. Every
// sum runs in the order the Python reference writes it, so results are bit for bit its own.

#ifndef MJRFT_ENGINE_LOWSPEED_H_
#define MJRFT_ENGINE_LOWSPEED_H_

#include <limits>

#include "state.h"

namespace mjrft::lowspeed {

// Modes of the treatment (the plugin's low_speed attribute): kStick (free bodies and bodies in
// mechanisms), kFree (free bodies only), kOff (the pure model, for every body at every speed).
enum class Mode : int { kStick = 0, kFree = 1, kOff = 2 };

// Default reach: the stability map passes every dropped and lowered body at it.
constexpr f64 kDefaultReach = 4.0;
// An RK4 step holds the wrench of its first stage over the other three for a body the
// treatment stuck or slipped, or whose motion would reverse within this many steps of the
// change predicted at the step's start (rk4.h). Tables::rk4_hold_steps carries it.
constexpr f64 kRk4HoldSteps = 4.0;

// Decisions, per body and pass: the pure model, stuck (ends the step at rest), slipping on the
// force of the free direction, the pure model linearised implicitly (slow moving body).
constexpr i64 kPure = 0, kStick = 1, kSlip = 2, kImplicit = 3;

// Size of the twist perturbations (relative to |xi|_M) whose secants give the medium's Jacobian
// for the linearly implicit step (Tables::jacobian_step carries it). A secant rather than a
// tangent: each triangle's force jumps where it turns from trailing to leading.
constexpr f64 kJacobianStep = 0.1;

// Relative size below which an energy balance counts as zero (its terms cancel): Euler's
// balance of a passive stick is exactly -|xi|^2_M / dt, but at rest it rounds to +1e-22, and a
// stick fraction of 1 - 1e-16 would leave the body creeping.
constexpr f64 kRounding = 64.0 * std::numeric_limits<f64>::epsilon();

// Counter in State::stats of each decision (-1: none).
constexpr int kStatOf[4] = {-1, 3, 4, 5};

// A free body's terms over a step: twist (v at the CoM [m/s], omega [rad/s]), the other
// wrenches on it (gravity, the user's, the gyroscopic torque), mass [kg], world inertia about
// the CoM and its inverse (3x3 row-major [kg m^2], [1/(kg m^2)]). World frame.
struct Body {
  f64 twist[6];
  f64 other[6];
  f64 mass;
  f64 iw[9];
  f64 ii[9];
};

// <a, b>_M = m a_lin . b_lin + a_ang . Iw b_ang of two (6) twists (iw: world axes, 3x3).
f64 MDot(const f64* a, const f64* b, f64 mass, const f64* iw);

// Solves a (6x6) x = rhs (6) by Gaussian elimination with partial pivoting; a and rhs are
// overwritten. x (6) is non-finite if a is singular.
void Solve6(f64* a, f64* rhs, f64* x);

// y (rows) = a (rows x cols) x (cols), summed in index order (no BLAS, as the reference).
void Mv(const f64* a, int rows, int cols, const f64* x, f64* y);

// x . y of two (n) vectors, summed in index order.
f64 Dot(const f64* x, const f64* y, int n);

// 2 / dt times the mechanical energy a step gains with the medium's wrench w (a guard).
//
// The trapezoid w . (xi + xi_end): over a step with constant forces the kinetic energy changes
// by dt/2 (w + other) . (xi + xi_end), and RK4 moves the body along that mean twist, so the
// work of the other forces cancels with their potential. MuJoCo's Euler, implicit and
// implicitfast (semi) move it with the end twist instead (semi-implicit Euler), so a constant
// force F_c does dt F_c . v_end of work while the kinetic energy counts dt/2 F_c . (v + v_end):
// the balance gains -dt^2/(2m) F_c . (F_c + f), f the medium's force. The rotation has no
// potential and keeps the trapezoid. w, twist, end, other (6); mass [kg]; dt [s].
f64 StepWork(const f64* w, const f64* twist, const f64* end, const f64* other, f64 mass, f64 dt,
             bool semi);

// The largest fraction lam in [0, 1] of the stick wrench that adds no energy over the step.
//
// The full stick (lam = 1) ends the step at rest. Under RK4 the body still moves by dt xi / 2
// over the step, so a body rising slowly against gravity gains more potential energy than the
// kinetic energy the stick takes. The wrench lam S ends at (1 - lam) xi_free and its StepWork
// is the quadratic (n2/dt) lam^2 + B lam + C with C <= 0, so the largest root is the answer
// when lam = 1 would gain. stick (6) = -M xi_free / dt, twist (6), other (6);
// n2 = |xi_free|^2_M [kg m^2/s^2]; mass [kg]; dt [s].
f64 StickFraction(const f64* stick, const f64* twist, const f64* other, f64 mass, f64 n2, f64 dt,
                  bool semi);

// basis (6x6): row 0 the twist's unit direction, rows 1-5 orthonormal in <., .>_M and
// M-orthogonal to it (pivoted Gram-Schmidt over the coordinate axes scaled to unit M-norm,
// taking at each round the axis with the largest remainder). mm (6x6) the body's inertia;
// n = |twist|_M.
void TransverseBasis(const f64* twist, f64 mass, const f64* iw, const f64* mm, f64 n, f64* basis);

// World inertia iw = X diag(I) X^T about the CoM and its inverse ii (3x3 each), from the
// inertial frame x (3x3, ximat) and the principal moments inertia (3) [kg m^2].
void WorldInertia(const f64* x, const f64* inertia, f64* iw, f64* ii);

// v (3): world velocity [m/s] of the world point p (3) [m] moving with tagged body k (cvel's
// linear part is at the subtree CoM of the body's root).
void PointVelocity(const mjData* d, const Tables& t, int k, const f64* p, f64* v);

// v (3): world velocity [m/s] of tagged body k's CoM (PointVelocity at xipos).
void ComVelocity(const mjData* d, const Tables& t, int k, f64* v);

// g (3): gravity acceleration [m/s^2] on body b, world frame (flag and compensation read live).
void Gravity(const mjModel* m, int b, f64* g);

// True if body b has a positive mass and positive principal moments (it can be treated).
bool HasInertia(const mjModel* m, int b);

// Tagged free body k's terms (Body) with the user's row user (6); gvec (3) gets its gravity
// acceleration [m/s^2].
void FreeBodyTerms(const mjModel* m, const mjData* d, const Tables& t, int k, const f64* user,
                   Body* body, f64* gvec);

// True if the explicit step with the medium's wrench w (6) adds no mechanical energy (StepWork
// <= rounding). A dissipative force can still add energy over a step when it turns the motion
// within it (a sharp-edged body spinning into the medium: up to 12 % of its energy per step).
bool AddsNoEnergy(const f64* w, const Body& body, f64 dt, bool semi);

// One Newton step of backward Euler across the motion: replaces w (6) (the pure wrench at the
// twist) and returns true, or leaves it and returns false.
//
// (M - dt J') d = M (xi_e - c xi) and the wrench W(xi) + J' d: xi_e = xi + dt M^-1 (f + W(xi))
// is the explicit step's end, c = |xi_e|_M / |xi|_M, J' = J / c the Jacobian at c xi. J comes
// from secants along the 5 transverse directions (J xi = 0 exactly: W is homogeneous of degree
// 0). Linearised at c xi, the same direction at the speed the step ends with, because a body
// speeding up from rest (c >> 1) is otherwise linearised far outside J's validity. False (step
// 3 decides) if the result is not finite, reverses the motion within the step, or gains energy
// over it.
bool ImplicitWrench(const mjModel* m, const mjData* d, const Tables& t, State& s, int k,
                    const Body& body, f64 dt, bool semi, f64* w);

// Step 3 of the treatment: slip on R = W(xi_free) if it cannot stop the free motion within the
// step and adds no energy; else the pure model w if the motion keeps its sense within this step
// (keeps) and w adds no energy; else stick. Returns the decision; sets w (6). v_free, om_free
// (3): the free motion's end twist.
i64 StickOrSlip(const mjModel* m, const mjData* d, const Tables& t, State& s, int k,
                const Body& body, const f64* v_free, const f64* om_free, f64 dt, bool semi, f64* w,
                bool keeps);

// The treatment of tagged body k (a free rigid body); returns its decision.
//
// w (6): the body's pure RFT wrench, replaced by the treated one. user (6): the other applied
// wrench on the body. ab (2): set to |xi|^2_M and <d_xi, xi>_M (the motion keeps its sense over
// n steps if ab[0] + n ab[1] > 0). tw (6): set to the body's twist. semi: positions advance with
// the step's end velocity (every integrator but RK4; StepWork).
i64 TreatBody(const mjModel* m, const mjData* d, const Tables& t, State& s, int k, const f64* user,
              f64 dt, bool semi, f64* w, f64* ab, f64* tw);

// The treatment of every treatable tagged body with a geom in play.
//
// s.wrench rows hold the pure RFT wrenches and are replaced where treated; user (nbody, 6): the
// other applied wrenches. Sets s.decision, s.slow (an RK4 step must not evaluate the pure model
// in its later stages: treated, or reversing within rk4_hold_steps), s.frozen (stage 1's twist
// and implicit correction of bodies moved by the implicit step) and counts s.stats.
void TreatAll(const mjModel* m, const mjData* d, const Tables& t, State& s, const f64* user);

}  // namespace mjrft::lowspeed

#endif  // MJRFT_ENGINE_LOWSPEED_H_
