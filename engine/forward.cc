// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "forward.h"

#include "deform.h"
#include "evaluate.h"
#include "lowspeed.h"
#include "mechanism.h"
#include "rk4.h"

namespace mjrft {
namespace {

// Bodies moved by the implicit step feel, in RK4's later stages, the model at the stage's pose
// with stage 1's twist plus stage 1's correction (rk4::kFrozen). Returns #evaluated.
int FrozenWrenches(const mjModel* m, const mjData* d, const Tables& t, State& s, int* acting) {
  int evaluated = 0;
  *acting = 0;
  for (int k = 0; k < t.ntbody; k++) {
    if (!s.frz[k]) continue;
    f64* w = s.wrench + 6 * t.tbody_bodyid[k];
    const f64* blk = s.rk4 + kRk4Head + kRk4Body * k;
    int na = 0;
    int ne = TwistWrench(m, d, t, s, k, blk + 1, blk + 4, w, &na);
    if (ne > 0) {  // in play: the correction acts where the model does
      for (int c = 0; c < 6; c++) w[c] += blk[7 + c];
    }
    evaluated += ne;
    *acting += na;
  }
  return evaluated;
}

// Components of tagged rows that differ from what was written were assigned by the user: they
// become the user part (s.user) of that component (docs/field.md, "Who owns xfrc_applied").
// "What was written" is the state's record (s.written, which copies of the mjData carry) or what
// the last pass wrote into this very mjData (s.xfrc_last, which mj_setState does not rewind: a
// state restored without xfrc_applied leaves the rows written after the snapshot in place).
void TakeUserPart(const mjData* d, const Tables& t, State& s) {
  for (int k = 0; k < t.ntbody; k++) {
    i64 b = t.tbody_bodyid[k];
    for (int c = 0; c < 6; c++) {
      f64 x = d->xfrc_applied[6 * b + c];
      if (x != s.written[6 * b + c] && x != s.xfrc_last[6 * b + c]) s.user[6 * b + c] = x;
    }
  }
}

// xfrc_applied = user + RFT on every tagged row (kept rows keep what stage 1 wrote), and
// remember what was written.
void WriteRows(mjData* d, const Tables& t, State& s) {
  for (int k = 0; k < t.ntbody; k++) {
    i64 b = t.tbody_bodyid[k];
    for (int c = 0; c < 6; c++) {
      f64 total = s.keep[k] ? d->xfrc_applied[6 * b + c] : s.user[6 * b + c] + s.wrench[6 * b + c];
      d->xfrc_applied[6 * b + c] = total;
      s.written[6 * b + c] = total;
      s.xfrc_last[6 * b + c] = total;
    }
  }
}

}  // namespace

i64 Forward(const mjModel* m, mjData* d, const Tables& t, State& s, int mode) {
  // 1. refuse to feed a non-finite state forward (the caller names the body and the time)
  int bad = FirstBadBody(m, d, t);
  s.status[0] = bad < 0 ? kOk : -1 - bad;
  if (bad >= 0) return s.status[0];
  s.pass[0] += 1;  // the depth memo (kernel.h) keeps nothing from an earlier pass
  for (int g = 0; g < t.ntgeom; g++) s.cull[g] = 0;
  for (int k = 0; k < t.ntbody; k++) s.keep[k] = s.frz[k] = s.slow[k] = 0;

  // 2. under RK4 and installed, recognise stages 2-4 and read what stage 1 decided
  bool held = false;
  if (mode == kInstalled && m->opt.integrator == mjINT_RK4) {
    held = rk4::StageHeld(d->time, m->opt.timestep, s.rk4);
    if (held) rk4::ReadModes(t, s.rk4, s.keep, s.frz);
  }

  // 3. the deforming ground follows the intruders
  if (t.soil && mode != kQuery && !held && deform::Due(m, d, t, s)) {
    int below = deform::Update(m, d, t, s);
    if (below >= 0) {
      s.status[0] = kBelowGround - below;
      return s.status[0];
    }
  }

  // 4. the pure model on every body in play (frozen bodies at stage 1's twist)
  int acting = 0;
  // (mechanism bodies held at the last pass are evaluated only if the treatment needs them)
  int evaluated = PureWrenches(m, d, t, s, &acting, t.mech && mode == kInstalled && !held);
  if (held) {
    int na = 0;
    evaluated += FrozenWrenches(m, d, t, s, &na);
    acting += na;
    if (t.treat) rk4::GuardStage(m, d, t, s);
  }
  if (mode != kQuery) {
    if (evaluated || !held) s.stats[0] += 1;
    s.stats[1] += evaluated;
    s.stats[2] += acting;
  }

  // 5. installed: the user's part of each tagged row
  if (mode == kInstalled) TakeUserPart(d, t, s);

  // 6. the low-speed treatment (a held stage keeps its step's decisions)
  if (!held && mode != kQuery) {
    for (int k = 0; k < t.ntbody; k++) s.decision[k] = lowspeed::kPure;
    for (int i = 0; i < 12 * t.ntbody; i++) s.frozen[i] = 0.0;
    if (t.treat) lowspeed::TreatAll(m, d, t, s, mode == kInstalled ? s.user : s.user_in);
    if (t.mech && mode == kInstalled) mechanism::TreatMechanisms(m, d, t, s);
    if (mode == kInstalled) {
      rk4::WriteModes(t, s.rk4, s.decision, s.slow, s.frozen);
      if (t.treat && m->opt.integrator == mjINT_RK4) rk4::BeginStep(m, d, t, s);
    }
  }

  // 7. installed: xfrc_applied = user part + RFT
  if (mode == kInstalled) WriteRows(d, t, s);
  return kOk;
}

}  // namespace mjrft
