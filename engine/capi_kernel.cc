// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// C entry points of the RFT kernel (kernel.h) for the Python RFT-only API (mjrft.core.engine's
// wrappers, which check the arrays' shapes and sizes before calling), through ctypes: raw
// pointers to C-contiguous float64 / int64 arrays and their sizes, no struct passed by value.
// Rotations are row-major (3, 3) matrices.

#include <cstdint>

#include "api.h"
#include "kernel.h"

using mjrft::f64;
using mjrft::i64;
namespace kernel = mjrft::kernel;

// forces: out (n, 3) [N] on n world-frame elements under the flat surface at surface_z [m];
// returns #acting.
MJRFT_API int mjrft_forces(const f64* pos, const f64* normal, const f64* area, const f64* vel,
                           i64 n, const f64* coef, i64 ncoef, f64 alpha_y, f64 zeta, f64 surface_z,
                           f64* out) {
  return kernel::Forces(pos, normal, area, vel, n, coef, ncoef, alpha_y, zeta, surface_z, out);
}

// checked_unit_normals: writes n_hat (n, 3); returns the code (kernel::InputCode), *index the
// first bad element (-1 if none).
MJRFT_API int mjrft_checked_unit_normals(const f64* pos, const f64* normal, const f64* area,
                                         const f64* vel, i64 n, f64* n_hat, i64* index) {
  return kernel::CheckedUnitNormals(pos, normal, area, vel, n, n_hat, index);
}

// input_flags: *bad (any bad input), *nonunit (any normal not of unit length), 0 or 1.
MJRFT_API void mjrft_input_flags(const f64* pos, const f64* normal, const f64* area, const f64* vel,
                                 i64 n, int* bad, int* nonunit) {
  bool b = false, u = false;
  kernel::InputFlags(pos, normal, area, vel, n, &b, &u);
  *bad = b;
  *nonunit = u;
}

// body_wrench: adds to wrench (6) the RFT wrench on elements [start, stop) of a body (the
// elements' arrays cent, norm (n, 3), area, reach (n,), patch (n, 19), body frame); the medium
// spelled out (coef (ncoef,), alpha_y, zeta, surface_prm (13,), surface_grid, use_region,
// region (2, 3), soil); rot (3, 3), pos, omega, v_ref, p_ref, com (3,); elem_force (n, 3); rows
// NULL or (n, 11) (kernel::kRow); body k + 1 for tagged body k of a deforming ground's field (its
// press marks, surface::SoilDepth), 0 for none. Returns #acting.
MJRFT_API int mjrft_body_wrench(const f64* cent, const f64* norm, const f64* area, const f64* reach,
                                const f64* patch, i64 start, i64 stop, const f64* coef, i64 ncoef,
                                f64 alpha_y, f64 zeta, const f64* surface_prm,
                                const f64* surface_grid, int use_region, const f64* region,
                                const f64* soil, const f64* rot, const f64* pos, const f64* omega,
                                const f64* v_ref, const f64* p_ref, const f64* com, f64* wrench,
                                f64* elem_force, f64* rows, f64 body) {
  const kernel::Elements e = {cent, norm, area, reach, patch};
  kernel::Medium med = {coef,        ncoef,        alpha_y,         zeta,
                        surface_prm, surface_grid, use_region != 0, region};
  med.body = body;
  return kernel::BodyWrench(e, start, stop, med, soil, rot, pos, omega, v_ref, p_ref, com, wrench,
                            elem_force, rows);
}

// trajectory: out (T, 6) wrenches of a body (n elements, body frame) along rot (T, 3, 3),
// pos, lin_vel, ang_vel, point (T, 3) under the flat surface at surface_z [m].
MJRFT_API void mjrft_trajectory(const f64* cent, const f64* norm, const f64* area, const f64* reach,
                                const f64* patch, i64 n, const f64* coef, i64 ncoef, f64 alpha_y,
                                f64 zeta, f64 surface_z, const f64* rot, const f64* pos,
                                const f64* lin_vel, const f64* ang_vel, const f64* point, i64 T,
                                f64* out) {
  const kernel::Elements e = {cent, norm, area, reach, patch};
  kernel::Trajectory(e, n, coef, ncoef, alpha_y, zeta, surface_z, rot, pos, lin_vel, ang_vel, point,
                     T, out);
}
