// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The RFT element law over a body's elements (docs/design.md section 2): the elements are moved
// from the body frame into the world frame, the submerged leading ones inside the region are
// evaluated (with the exact surface quadrature of quadrature.h where the surface or the leading
// boundary crosses an element), and their forces are summed into the body's wrench.

#ifndef MJRFT_ENGINE_KERNEL_H_
#define MJRFT_ENGINE_KERNEL_H_

#include "tables.h"

namespace mjrft::kernel {

// Rows of the quadrature points written instead of forces (for media given as Python
// callables): point [m] (3), unit normal (3), velocity direction (3), weight W = depth x area
// [m^3] (1), world frame.
constexpr int kRow = 10;

// Elements of one body, body frame (rows of Tables' elem_* arrays, or of an ElementSet).
struct Elements {
  const f64* pos;     // (n, 3) centroids [m]
  const f64* normal;  // (n, 3) outward unit normals
  const f64* area;    // (n,) [m^2]
  const f64* reach;   // (n,) largest centroid-corner distance [m]
  const f64* patch;   // (n, kPatchSize) corner offsets, corner normals, spread
};

// The medium and its free surface.
struct Medium {
  const f64* coef;  // (ncoef,) kernel coefficients (Material.kernel_coefficients)
  i64 ncoef;
  f64 alpha_y;             // generic out-of-plane coefficient
  f64 zeta;                // [N/m^3]
  const f64* surface_prm;  // (kPrmSize,) surface.h
  const f64* surface_grid; // (nrow, ncol) grid heights [m]
  bool use_region;
  const f64* region;  // (2, 3) world box [m]
};

// The medium of a plugin instance's tables.
Medium MediumOf(const Tables& t);
// The elements of a plugin instance's tables.
Elements ElementsOf(const Tables& t);

// Adds to wrench (6) the RFT wrench on elements [start, stop) of a body; returns #acting.
// soil: the deforming ground's block (read only under a kSoil surface). rot (9) body -> world,
// row-major; pos (3) body origin [m]; omega (3) angular velocity [rad/s]; v_ref (3) linear
// velocity [m/s] of the world point p_ref (3) moving with the body; com (3) the point torque is
// taken about [m]; all world frame. elem_force (n, 3): forces [N] written for rows
// [start, stop), zero where nothing acts. rows: nullptr, or (n, kRow) quadrature points written
// for the acting elements instead of their forces (rows of the others are left as they are).
int BodyWrench(const Elements& e, i64 start, i64 stop, const Medium& med, const f64* soil,
               const f64* rot, const f64* pos, const f64* omega, const f64* v_ref,
               const f64* p_ref, const f64* com, f64* wrench, f64* elem_force, f64* rows);

}  // namespace mjrft::kernel

#endif  // MJRFT_ENGINE_KERNEL_H_
