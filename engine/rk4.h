// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// RK4's four forward passes per step: which stage a pass is, and what each body feels there
// (tests/field_reference.py states the same rules plainly; docs/stability.md, "RK4").
//
// MuJoCo's RK4 (mj_RungeKutta) runs its stages at t0, t0 + h/2, t0 + h/2, t0 + h, the stage
// times computed as t0 + c h; the same expressions here recognise them exactly. Stage 1 is
// evaluated in full and records, per tagged body, how the later stages treat it (the mjData's
// RK4 record, State::rk4):
//
// * kPerStage: the pure model of each stage (a body moving freely);
// * kHold: stage 1's wrench over the step, for a body the low-speed treatment stuck or slipped,
//   or whose motion would reverse within Tables::rk4_hold_steps steps. Why: the time-stepping
//   stick needs the force constant over the step to end it at rest (per stage it keeps 3/8 of
//   the velocity), and RK4's stage combination does not damp a torque that jumps with the sign
//   of a slow spin;
// * kFrozen: the model at the stage's pose with stage 1's twist, plus stage 1's implicit
//   correction, for a body moved by the linearly implicit step. Why not hold: across a slow
//   motion RFT is stiff, but along it the force changes with depth, and a held force lags it.
//
// A free body evaluated per stage (kPerStage or kFrozen) keeps that only while the step stays
// dissipative: at each later stage, the step completed with that stage's wrench is balanced
// (StepBalance), and where it would add energy the body holds stage 1's wrench from that stage
// on. Why: the force can jump between stages (an edge dipping in at the half step, a slow spin
// whose direction turns), and RK4's combination of such stages is not bounded by any one of
// them. Holding stage 1's wrench is safe: stage 1 checked it (lowspeed::AddsNoEnergy).
//
// Any other pattern of passes (a user's mj_forward, a new step at t0 + h) is evaluated afresh,
// which is always safe.
//
// The record (kRk4Head + kRk4Body * ntbody, tables.h): head (time of the last evaluated pass
// [s], passes since), then per tagged body a block: its mode, stage 1's twist (v at the CoM,
// omega) and implicit correction (12), then for the energy guard of the free bodies not held:
// stage 1's wrench, the weighted sum of the wrenches applied so far, the sum of the forces of
// stages 2-4 so far, stage 1's twist, other wrenches and inverse world inertia (3x3
// row-major). World frame.

#ifndef MJRFT_ENGINE_RK4_H_
#define MJRFT_ENGINE_RK4_H_

#include "state.h"

namespace mjrft::rk4 {

// Modes of a body in the later stages of an RK4 step (stored as f64 in the record).
constexpr f64 kPerStage = 0.0, kHold = 1.0, kFrozen = 2.0;
// Offsets in a body's block.
constexpr int kMode = 0, kTwist1 = 1, kCorrection = 7;
constexpr int kW1 = 13, kAcc = 19, kLin = 25, kTwist = 28, kOther = 34, kIi = 40;
static_assert(kIi + 9 == kRk4Body, "rk4 block layout");
// RK4's stage weights (1, 2, 2, 1) / 6 times 6, by pass number 1-4; and per pass n the summed
// weight of passes n..4 (a stage's wrench continued to the end of the step).
constexpr f64 kWeight[5] = {0.0, 1.0, 2.0, 2.0, 1.0};
constexpr f64 kRestWeight[5] = {0.0, 6.0, 5.0, 3.0, 1.0};

// True if a pass at time [s] is stage 2, 3 or 4 of an RK4 step (timestep [s]) whose stage 1
// was evaluated; updates the record's head rec[0..1] (time of the last evaluated pass, passes
// since).
bool StageHeld(f64 time, f64 timestep, f64* rec);

// keep[k], frz[k] (ntbody each, 0/1) from the modes stage 1 recorded in rec.
void ReadModes(const Tables& t, const f64* rec, i64* keep, i64* frz);

// Records each tagged body's mode for the later stages and its stage-1 twist and implicit
// correction frozen (ntbody, 12), from its decision (ntbody; lowspeed::kImplicit: kFrozen) and
// slow flag (ntbody; kHold).
void WriteModes(const Tables& t, f64* rec, const i64* decision, const i64* slow, const f64* frozen);

// True if tagged body k (record block blk (kRk4Body)) is a free body its RK4 step evaluates per
// stage, which the energy guard watches.
bool Guarded(const mjModel* m, const Tables& t, int k, const f64* blk);

// Stage 1 of an RK4 step: records, for each free body evaluated per stage (not held), what the
// energy guard of the later stages needs (GuardStage), from s.wrench and s.user.
void BeginStep(const mjModel* m, const mjData* d, const Tables& t, State& s);

// The energy [J] / h an RK4 step adds with the wrenches applied in its passes before pass n
// (2-4) and w (6) in pass n and after it; size gets the sum of the magnitudes of its terms.
//
// RK4 ends the step at v1 = v0 + h/6 (a1 + 2 a2 + 2 a3 + a4) and x1 = x0 + h v0 + h^2/6 (a1 +
// a2 + a3), so with constant other forces f_o the medium's forces F_j add, beyond the step
// without them, exactly h (F . v0 + h/(2m) |F|^2 + h/(6m) f_o . (F2 + F3 + F4)),
// F = (F1 + 2 F2 + 2 F3 + F4)/6; the rotation (no potential) adds h (T . w0 + h/2 T . I^-1 T +
// h t_o . I^-1 T), with stage 1's inertia and gyroscopic torque t_o. blk: the body's record
// block; mass [kg]; h [s].
f64 StepBalance(const f64* blk, const f64* w, int n, f64 mass, f64 h, f64* size);

// Stages 2-4 of an RK4 step: a free body evaluated per stage (not held) keeps this stage's
// wrench if the step completed with it adds no energy (StepBalance), else it holds stage 1's
// wrench from this stage on (kHold; s.wrench row restored). Returns the number of bodies held.
int GuardStage(const mjModel* m, const mjData* d, const Tables& t, State& s);

}  // namespace mjrft::rk4

#endif  // MJRFT_ENGINE_RK4_H_
