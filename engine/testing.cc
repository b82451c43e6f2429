// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// C entry points of single stages, for the tests that check a rule of the engine against the
// plain references in tests/ (tests/test_field.py: RK4's stage rule; tests/test_mechanism.py:
// the predicted actuator forces).

#include "api.h"
#include "mechanism.h"
#include "rk4.h"

using mjrft::f64;

// rk4::StageHeld on a record rec (kRk4Head + kRk4Body * ntbody values).
MJRFT_API int mjrft_test_stage_held(f64 time, f64 timestep, f64* rec) {
  return mjrft::rk4::StageHeld(time, timestep, rec);
}

// mechanism::ActuatorForces: out (nu) the affine actuators' forces at d's state.
MJRFT_API void mjrft_test_actuator_forces(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                          f64* out) {
  mjrft::mechanism::ActuatorForces(m, d, *t, out);
}
