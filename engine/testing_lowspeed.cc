// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// C entry points of lowspeed.h and rk4.h for the tests (tests/test_engine_lowspeed.py).

#include "api.h"
#include "lowspeed.h"
#include "rk4.h"

using mjrft::f64;
using mjrft::i64;

MJRFT_API f64 mjrft_test_m_dot(const f64* a, const f64* b, f64 mass, const f64* iw) {
  return mjrft::lowspeed::MDot(a, b, mass, iw);
}

MJRFT_API void mjrft_test_solve6(f64* a, f64* rhs, f64* x) { mjrft::lowspeed::Solve6(a, rhs, x); }

MJRFT_API f64 mjrft_test_step_work(const f64* w, const f64* twist, const f64* end, const f64* other,
                                   f64 mass, f64 dt, int semi) {
  return mjrft::lowspeed::StepWork(w, twist, end, other, mass, dt, semi != 0);
}

MJRFT_API f64 mjrft_test_stick_fraction(const f64* stick, const f64* twist, const f64* other,
                                        f64 mass, f64 n2, f64 dt, int semi) {
  return mjrft::lowspeed::StickFraction(stick, twist, other, mass, n2, dt, semi != 0);
}

MJRFT_API void mjrft_test_transverse_basis(const f64* twist, f64 mass, const f64* iw, const f64* mm,
                                           f64 n, f64* basis) {
  mjrft::lowspeed::TransverseBasis(twist, mass, iw, mm, n, basis);
}

MJRFT_API void mjrft_test_world_inertia(const f64* x, const f64* inertia, f64* iw, f64* ii) {
  mjrft::lowspeed::WorldInertia(x, inertia, iw, ii);
}

MJRFT_API int mjrft_test_adds_no_energy(const f64* w, const f64* twist, const f64* other, f64 mass,
                                        const f64* iw, const f64* ii, f64 dt, int semi) {
  mjrft::lowspeed::Body body;
  for (int c = 0; c < 6; c++) {
    body.twist[c] = twist[c];
    body.other[c] = other[c];
  }
  body.mass = mass;
  for (int c = 0; c < 9; c++) {
    body.iw[c] = iw[c];
    body.ii[c] = ii[c];
  }
  return mjrft::lowspeed::AddsNoEnergy(w, body, dt, semi != 0);
}

MJRFT_API mjrft::i64 mjrft_test_treat_body(const mjModel* m, const mjData* d,
                                           const mjrft::Tables* t, mjrft::State* s, int k,
                                           const f64* user, f64 dt, int semi, f64* w, f64* ab,
                                           f64* tw) {
  return mjrft::lowspeed::TreatBody(m, d, *t, *s, k, user, dt, semi != 0, w, ab, tw);
}

MJRFT_API void mjrft_test_treat_all(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                    mjrft::State* s, const f64* user) {
  mjrft::lowspeed::TreatAll(m, d, *t, *s, user);
}

MJRFT_API int mjrft_test_stage_held(f64 time, f64 timestep, f64* rec) {
  return mjrft::rk4::StageHeld(time, timestep, rec);
}

MJRFT_API void mjrft_test_read_modes(const mjrft::Tables* t, const f64* rec, i64* keep, i64* frz) {
  mjrft::rk4::ReadModes(*t, rec, keep, frz);
}

MJRFT_API void mjrft_test_write_modes(const mjrft::Tables* t, f64* rec, const i64* decision,
                                      const i64* slow, const f64* frozen) {
  mjrft::rk4::WriteModes(*t, rec, decision, slow, frozen);
}

MJRFT_API void mjrft_test_begin_step(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                     mjrft::State* s) {
  mjrft::rk4::BeginStep(m, d, *t, *s);
}

MJRFT_API f64 mjrft_test_step_balance(const f64* blk, const f64* w, int n, f64 mass, f64 h,
                                      f64* size) {
  return mjrft::rk4::StepBalance(blk, w, n, mass, h, size);
}

MJRFT_API int mjrft_test_guard_stage(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                     mjrft::State* s) {
  return mjrft::rk4::GuardStage(m, d, *t, *s);
}
