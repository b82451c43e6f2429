// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Low-speed treatment of intruding bodies in mechanisms (legs, wheels, rig carriages): a joint
// stick/slip step over the mechanism's generalized coordinates (tests/field_reference.py
// states the same rules plainly in NumPy; docs/stability.md, "Mechanisms").
//
// Why: a body on joints feels, besides the medium, its actuators, its joints' coupling to the
// rest of the mechanism and any constraint. MuJoCo computes actuator and constraint forces after
// the passive forces, so the free-body treatment (lowspeed.h), which needs every force on the
// body, cannot act on it; the pure rate-independent model then lets a standing robot creep and
// its foot forces chatter (docs/stability.md, "Mechanisms").
//
// What: the time-stepping (Moreau) treatment of the medium's set-valued reaction near rest, in
// generalized coordinates. With M the joint-space inertia, J_i the 6 x nv Jacobian of intruding
// body i at its CoM (twist: CoM velocity, angular velocity; world) and dt the timestep:
//
// 1. The other generalized forces (actuators, constraints, gravity, bias, the user's) are those
//    of the previous pass, read from MuJoCo's own result: tau_other = M qacc_prev -
//    tau_field_prev (qacc still holds the previous forward pass's acceleration when the passive
//    callback runs; tau_field_prev = sum J_i^T W_i is what the field applied then; a repeated
//    pass at the same time, mj_forward before mj_step, reads what the first pass at that time
//    read, so the trajectory does not depend on extra forward calls). The actuators with fixed
//    or affine gains and affine biases (servos, motors) are brought to this state: their force
//    at this state's control, activation, length and velocity (ActuatorForce) replaces the
//    previous pass's through this state's moments, so a stiff servo's response to the last step
//    is not a step late. The free velocity is u = qvel + dt M^-1 tau_other. A body at rest under
//    constant loads is a fixed point of this predictor; it is not used after a reset or a jump
//    in time (the pure model acts once).
// 2. A body keeps the pure model while its twist keeps its sense and changes by less than its
//    own size over `reach` steps under every force: with the step's predicted change
//    dxi = J_i (u - qvel) + dt J_i M^-1 sum_j J_j^T W_j (the pure model's wrenches W_j on every
//    body in the medium; for a body held at the last pass, the wrench it was held with),
//    <xi + reach dxi, xi> > 0 and reach |dxi| < |xi| in the body's own kinetic-energy metric. A
//    steadily driven rig, whose drive balances the medium, is never held. A body held at the
//    last pass ended that step at rest, where its pure model's direction is round-off: it is held
//    again, and its pure model is evaluated only if needed (it slips on it, or the loads cannot be
//    predicted), so a standing robot's held legs cost no evaluation of their triangles.
// 3. The other bodies in the medium are held jointly: wrenches W_S with J_S (u + dt M^-1 (J_S^T
//    W_S + J_P^T W_P)) = 0 (their twists end the step at zero), W_S = W_ref + the least-norm
//    correction (A = J_S M^-1 J_S^T is singular wherever the mechanism cannot move a body in
//    some direction; the wrench there does no work, so it keeps its value from the previous
//    pass, W_ref, and the load on a statically indeterminate stance does not jump). This is the
//    M-orthogonal projection of the free motion onto the motions that leave the held bodies at
//    rest: it cannot add kinetic energy.
// 4. A held body whose hold the medium cannot supply slips: released alone it would move with
//    xi_f = -dt A_ii W_i; the medium's resistance to that motion R = W(xi_f) must dissipate at
//    least the power the hold does, -R . xi_f >= -W_i . xi_f. The body that fails by most gets R
//    (the force of the direction it would move in; the pure model instead if R would push along
//    its present motion) and the others are solved again, until every hold is supplied.
//
// Frames: world; wrenches are force [N] then torque [N m] about the body's CoM (xipos), twists
// CoM velocity [m/s] then angular velocity [rad/s]. Applies in the installed path only (inside
// mj_step), where M and qacc are MuJoCo's own.
//
// Matrices are row-major with the row stride named by each function; the State's mech_* arrays
// have the shapes of fields.h (mech_L, mech_M: nv x nv; mech_J, mech_X: 6 nk x nv; mech_A,
// mech_S: 6 nk x 6 nk; mech_vec: 3 rows of max(nv, 6 nk)).

#ifndef MJRFT_ENGINE_MECHANISM_H_
#define MJRFT_ENGINE_MECHANISM_H_

#include "state.h"

namespace mjrft::mechanism {

// Regularisation of the hold system, relative to each row's own diagonal: A + eps diag(A). A's
// rows mix forces and torques (mobilities of 7 and 6,500 on a 15 g shin), so it is scaled to a
// unit diagonal first; there its null space (wrenches no joint feels) sits at round-off, 1e-16,
// and a configuration can add a mode that is nearly null: 1e-13 to 1.5e-6 on the light quadruped
// of benchmarks/stance.py standing (5-100 g shins, kp 1-10), where the next is 0.08 or more.
// Stopping the free motion along such a mode exactly takes wrenches of hundreds of N on a 0.6 kg
// robot, which no leg released alone can be given (step 4 then releases legs two at a time,
// alternating). At eps 1e-4 such a mode counts as null (it keeps the wrench of the last pass),
// and a regular mode is solved to 1e-3 of itself or better.
constexpr f64 kHoldRegularisation = 1e-4;
// The medium's resistance to a hold's direction is re-evaluated unless the body has moved less
// than kResistanceReuseM (CoM, and inertial axes times the body's size) and the direction has
// turned less than kResistanceReuseRad since it was last evaluated. A held body at rest keeps
// its place exactly, but its direction jitters by 1e-5-1e-3 rad from step to step (round-off of
// the holds through a light leg's large rotational mobility); an RFT force changes with its
// direction by about that fraction, far less than the margins the check decides on, and the
// reuse halves the treatment's cost on a standing robot (benchmarks/standing.py).
constexpr f64 kResistanceReuseM = 1e-9;
constexpr f64 kResistanceReuseRad = 1e-2;
// Speed [m/s] (CoM speed and body size times angular speed, combined) at which a hold's
// resistance is evaluated when the medium has a dynamic term: the term (lambda rho_c (n.v)^2,
// 1.5e-3 Pa at 1 mm/s for rho_c 1500 kg/m^3) is then ~1e-6 of the quasi-static pressure at a
// millimetre's depth, so the resistance is the medium's to a start from rest.
constexpr f64 kQuasiStaticSpeed = 1e-3;
// The factors of M and of the holds' system are kept while the configuration (cdof, CoMs) moves
// less than this [m, dimensionless]: a body at rest moves ~1e-17 m a step; 1e-12 m of motion
// changes the factors by ~1e-11 of themselves.
constexpr f64 kConfigurationReuse = 1e-12;

// Dense joint-space inertia out (nv x nv, stride nv) from MuJoCo's M (the lower triangle in CSR:
// m->M_rownnz, M_rowadr, M_colind; what mj_fullM expands).
void FullInertia(const mjModel* m, const mjData* d, f64* out);

// In place: the lower Cholesky factor of a[:n, :n] + eps I (a: stride lda, symmetric positive
// semi-definite; only the lower triangle is read and written). Returns false if a pivot is not
// positive.
bool Cholesky(f64* a, int lda, int n, f64 eps);

// In place: x[:n] = (L L^T)^-1 x[:n] for the factor of Cholesky (stride lda).
void ChoSolve(const f64* lower, int lda, int n, f64* x);
// In place: x[:n] = L^-1 x[:n].
void ForwardSolve(const f64* lower, int lda, int n, f64* x);
// In place: x[:n] = L^-T x[:n].
void BackSolve(const f64* lower, int lda, int n, f64* x);

// jac rows [row, row + 6) (stride nv) = tagged body k's Jacobian at its CoM: rows CoM
// velocity, angular velocity (world). cdof is a motion at the subtree CoM of the body's root.
void BodyJacobian(const mjModel* m, const mjData* d, const Tables& t, int k, int row, f64* jac);

// True if the qacc read by the first pass at this time described this state's loads (the pass
// before it was one timestep before); a repeated pass at the same time (same_time) gets the
// first one's answer. Records this pass's time (s.mech_time).
bool PredictorValid(const mjModel* m, const mjData* d, State& s, bool same_time);

// True if tagged body k was held at the last pass (a repeated pass at one time: at the pass
// that read the loads), so that this pass holds it again (Classify).
bool HeldBefore(const mjData* d, const State& s, int k);

// True if an element of tagged body k's geoms in play is below the free surface (the pure
// wrench cannot tell: at rest it is zero).
bool Submerged(const mjData* d, const Tables& t, const State& s, int k);

// Tagged mechanism bodies in the medium this pass (a geom in play with an element below the
// surface: a body out of the medium has nothing to be held by), in increasing order into rows
// (ntbody); returns their number.
int Gather(const mjData* d, const Tables& t, const State& s, i64* rows);

// Force [N] of actuator a at this state by MuJoCo's rule for fixed/affine gains and affine
// biases: gain(x, L, V) x + bias(L, V), x its activation or clamped control, clamped to its
// force range.
f64 ActuatorForce(const mjModel* m, const mjData* d, const Tables& t, int a);

// out (nu) = ActuatorForce of every actuator at the mjData's state (NaN for those whose force
// the rule does not cover); for checking the rule against MuJoCo's own.
void ActuatorForces(const mjModel* m, const mjData* d, const Tables& t, f64* out);

// tau (nv) += the change of the affine actuators' generalized force since the loads were read:
// this state's force (ActuatorForce) minus the previous pass's (s.mech_in_force), through this
// state's moments (sparse rows of d->actuator_moment). A stiff servo's force then follows the
// step it responds to.
void ActuatorUpdate(const mjModel* m, const mjData* d, const Tables& t, const State& s, f64* tau);

// True if the bodies in the medium (rows[:n]) and the configuration (cdof, their CoMs and their
// roots' subtree CoMs, within kConfigurationReuse) are those of the stored factors (s.mech_cfg);
// else stores this configuration, marks the hold system stale and returns false.
bool SameConfiguration(const mjModel* m, const mjData* d, const Tables& t, State& s,
                       const i64* rows, int n);

// Factors M = L L^T (s.mech_L, from s.mech_M) and the Jacobians (s.mech_J), unless the
// configuration is the last pass's (SameConfiguration); and the free velocity u (s.mech_vec
// row 0). Returns false if M is not positive definite.
bool Setup(const mjModel* m, const mjData* d, const Tables& t, State& s, const i64* rows, int n);

// Y = L^-1 J^T as rows (s.mech_X) and A = J M^-1 J^T = Y^T Y (s.mech_A) of the n bodies in the
// medium, unless built for this configuration (s.mech_hkey[0] != -2): only a pass that holds a
// body needs them (a walking robot's feet mostly move, and building A is most of the
// treatment's cost).
void HoldSystem(const mjModel* m, const Tables& t, State& s, int n);

// jac[r, :nv] . x[:nv] (jac: stride nv).
f64 RowDot(const f64* jac, int r, const f64* x, int nv);

// The decisions of the bodies in the medium live in code, indexed by tagged body (the State's
// decision array in TreatMechanisms): lowspeed's kPure, kStick (held) or kSlip.

// code[rows[a]] = kStick for the bodies step 2 does not leave to the pure model (slow, or
// reversing within `reach` steps), and for the bodies held at the last pass: a body the last
// pass held ended that step at rest, where the pure model's direction is round-off, so it is
// held again until the medium cannot supply its hold (WorstHold), and the prediction of the
// others counts it with the wrench it was held with, not the pure model's (which the pass then
// need not evaluate: PureWrenches' defer_held). The others are left as they are. Uses
// s.mech_vec row 1.
void Classify(const mjModel* m, const mjData* d, const Tables& t, State& s, const i64* rows, int n,
              i64* code);

// Wrenches out[a] (n x 6) of the held bodies (step 3), the others' wrenches given in out. The
// reference of a held body (W_ref) is its wrench from the pass that read the loads if it was
// held then, else its pure wrench (s.wrench). Returns false if the system cannot be factored.
// Uses s.mech_vec row 2 and s.mech_S (kept while the held rows stay: s.mech_hkey).
bool SolveHolds(const mjModel* m, const Tables& t, State& s, const i64* rows, int n,
                const i64* code, f64* out);

// xf (6) = -dt A_aa W_a (W_a = out[a]): the twist held body a would take released alone.
// Returns the power its hold dissipates, -W_a . xf.
f64 HoldPower(const Tables& t, const State& s, int a, const f64* out, f64 dt, f64* xf);

// Step 4: the held body whose hold the medium fails to supply by most, its slip wrench in
// slip (6); -1 if every hold is supplied. The medium's resistance is evaluated for the hold of
// most power and then only for holds whose power exceeds the largest shortfall found (no other
// can fall shorter, the resistance being dissipative): a trotting robot's stance legs, which
// fail their holds together, cost one resistance each, not one more per released leg.
int WorstHold(const mjModel* m, const mjData* d, const Tables& t, State& s, const i64* rows, int n,
              const i64* code, const f64* out, f64* slip);

// out (6) = the RFT wrench on tagged body k moving with twist (6) (with a dynamic term: in
// twist's direction at kQuasiStaticSpeed): reused from the last evaluation (s.mech_R) while the
// body and the twist's direction are where they were then (s.mech_key; kResistanceReuseM,
// kResistanceReuseRad).
void Resistance(const mjModel* m, const mjData* d, const Tables& t, State& s, int k,
                const f64* twist, f64* out);

// Largest bounding-sphere radius [m] of tagged body k's geoms.
f64 BodySize(const Tables& t, int k);

// The treatment of every tagged mechanism body in play (installed passes only).
//
// s.wrench rows hold the pure RFT wrenches and are replaced where held or slipping; sets
// s.decision and s.slow of those bodies, and records what the field applied (s.mech_tau,
// s.mech_prev, s.mech_held) for the next pass's predictor and references. The pass's lists
// live in arrays that are dead while it runs (no allocation): the bodies in the medium in
// s.mech_held (read at the start, written at the end), their wrenches in s.mech_vec row 1.
void TreatMechanisms(const mjModel* m, const mjData* d, const Tables& t, State& s);

}  // namespace mjrft::mechanism

#endif  // MJRFT_ENGINE_MECHANISM_H_
