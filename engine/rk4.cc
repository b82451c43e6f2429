// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "rk4.h"

#include <cmath>

#include "lowspeed.h"

namespace mjrft::rk4 {

bool StageHeld(f64 time, f64 timestep, f64* rec) {
  f64 n = rec[1];
  if ((n == 1.0 || n == 2.0) && time == rec[0] + 0.5 * timestep) {
    rec[1] = n + 1.0;
    return true;
  }
  if (n == 3.0 && time == rec[0] + 1.0 * timestep) {
    rec[1] = 4.0;
    return true;
  }
  rec[0] = time;
  rec[1] = 1.0;
  return false;
}

void ReadModes(const Tables& t, const f64* rec, i64* keep, i64* frz) {
  for (int k = 0; k < t.ntbody; k++) {
    f64 mode = rec[kRk4Head + kRk4Body * k];
    keep[k] = mode == kHold;
    frz[k] = mode == kFrozen;
  }
}

void WriteModes(const Tables& t, f64* rec, const i64* decision, const i64* slow,
                const f64* frozen) {
  for (int k = 0; k < t.ntbody; k++) {
    f64* blk = rec + kRk4Head + kRk4Body * k;
    if (decision[k] == lowspeed::kImplicit) {
      blk[kMode] = kFrozen;
    } else {
      blk[kMode] = slow[k] ? kHold : kPerStage;
    }
    for (int c = 0; c < 12; c++) blk[kTwist1 + c] = frozen[12 * k + c];
  }
}

bool Guarded(const mjModel* m, const Tables& t, int k, const f64* blk) {
  return blk[kMode] != kHold && t.tbody_treat[k] != 0 &&
         lowspeed::HasInertia(m, static_cast<int>(t.tbody_bodyid[k]));
}

void BeginStep(const mjModel* m, const mjData* d, const Tables& t, State& s) {
  for (int k = 0; k < t.ntbody; k++) {
    i64 b = t.tbody_bodyid[k];
    f64* blk = s.rk4 + kRk4Head + kRk4Body * k;
    if (!Guarded(m, t, k, blk)) continue;
    lowspeed::Body body;
    f64 gvec[3];
    lowspeed::FreeBodyTerms(m, d, t, k, s.user + 6 * b, &body, gvec);
    const f64* w = s.wrench + 6 * b;
    for (int c = 0; c < 6; c++) {
      blk[kW1 + c] = w[c];
      blk[kAcc + c] = w[c];
      blk[kTwist + c] = body.twist[c];
      blk[kOther + c] = body.other[c];
    }
    for (int c = 0; c < 3; c++) blk[kLin + c] = 0.0;
    for (int c = 0; c < 9; c++) blk[kIi + c] = body.ii[c];
  }
}

f64 StepBalance(const f64* blk, const f64* w, int n, f64 mass, f64 h, f64* size) {
  const f64 rest = kRestWeight[n];
  const f64 count = 5.0 - n;
  f64 wbar[6], itau[3];
  for (int c = 0; c < 6; c++) wbar[c] = (blk[kAcc + c] + rest * w[c]) / 6.0;
  lowspeed::Mv(blk + kIi, 3, 3, wbar + 3, itau);
  f64 p = 0.0;
  f64 sz = 0.0;
  for (int c = 0; c < 6; c++) {
    p += wbar[c] * blk[kTwist + c];
    sz += std::fabs(wbar[c] * blk[kTwist + c]);
  }
  for (int c = 0; c < 3; c++) {
    f64 quad = 0.5 * h * (wbar[c] * wbar[c] / mass + wbar[3 + c] * itau[c]);
    f64 lin = h * blk[kOther + c] * (blk[kLin + c] + count * w[c]) / (6.0 * mass);
    f64 rot = h * blk[kOther + 3 + c] * itau[c];
    p += quad + lin + rot;
    sz += std::fabs(quad) + std::fabs(lin) + std::fabs(rot);
  }
  *size = sz;
  return p;
}

int GuardStage(const mjModel* m, const mjData* d, const Tables& t, State& s) {
  (void)d;
  const int n = static_cast<int>(s.rk4[1]);
  const f64 h = m->opt.timestep;
  int held = 0;
  for (int k = 0; k < t.ntbody; k++) {
    i64 b = t.tbody_bodyid[k];
    f64* blk = s.rk4 + kRk4Head + kRk4Body * k;
    if (!Guarded(m, t, k, blk)) continue;
    f64* w = s.wrench + 6 * b;
    f64 size;
    f64 p = StepBalance(blk, w, n, m->body_mass[b], h, &size);
    if (p > lowspeed::kRounding * size) {
      for (int c = 0; c < 6; c++) w[c] = blk[kW1 + c];
      blk[kMode] = kHold;
      held++;
    }
    for (int c = 0; c < 6; c++) blk[kAcc + c] += kWeight[n] * w[c];
    for (int c = 0; c < 3; c++) blk[kLin + c] += w[c];
  }
  return held;
}

}  // namespace mjrft::rk4
