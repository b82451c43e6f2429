// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// C entry points of mechanism.h for the tests (tests/test_engine_mechanism.py).

#include "api.h"
#include "mechanism.h"

using mjrft::f64;

MJRFT_API void mjrft_test_treat_mechanisms(const mjModel* m, const mjData* d,
                                           const mjrft::Tables* t, mjrft::State* s) {
  mjrft::mechanism::TreatMechanisms(m, d, *t, *s);
}

MJRFT_API int mjrft_test_mech_cholesky(f64* a, int lda, int n, f64 eps) {
  return mjrft::mechanism::Cholesky(a, lda, n, eps);
}

MJRFT_API void mjrft_test_mech_cho_solve(const f64* lower, int lda, int n, f64* x) {
  mjrft::mechanism::ChoSolve(lower, lda, n, x);
}

MJRFT_API void mjrft_test_actuator_forces(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                          f64* out) {
  mjrft::mechanism::ActuatorForces(m, d, *t, out);
}

MJRFT_API void mjrft_test_full_inertia(const mjModel* m, const mjData* d, f64* out) {
  mjrft::mechanism::FullInertia(m, d, out);
}
