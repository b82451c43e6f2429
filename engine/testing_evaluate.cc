// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// C entry points of evaluate.h for the tests (tests/engine_bridge.py).

#include "api.h"
#include "evaluate.h"

using mjrft::f64;

MJRFT_API int mjrft_test_pure_wrenches(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                       mjrft::State* s, int* acting) {
  return mjrft::PureWrenches(m, d, *t, *s, acting);
}

MJRFT_API int mjrft_test_twist_wrench(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                      mjrft::State* s, int k, const f64* v, const f64* omega,
                                      f64* out, int* acting) {
  return mjrft::TwistWrench(m, d, *t, *s, k, v, omega, out, acting);
}
