// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The RFT element law over a body's elements (docs/design.md section 2): the elements are moved
// from the body frame into the world frame, the submerged leading ones inside the region are
// evaluated (with the exact surface quadrature of quadrature.h where the surface or the leading
// boundary crosses an element), and their forces are summed into the body's wrench.

#ifndef MJRFT_ENGINE_KERNEL_H_
#define MJRFT_ENGINE_KERNEL_H_

#include "quadrature.h"
#include "state.h"
#include "tables.h"

namespace mjrft::kernel {

// Rows of the quadrature points written instead of forces (for media given as Python
// callables): point [m] (3), unit normal (3), velocity direction (3), weight W = depth x area
// [m^3] (1), area [m^2] (1) of the part that acts (the element's, or where the quadrature clips
// it its submerged leading part's), world frame.
constexpr int kRow = 11;

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
  f64 alpha_y;              // generic out-of-plane coefficient
  f64 zeta;                 // [N/m^3]
  const f64* surface_prm;   // (kPrmSize,) surface.h
  const f64* surface_grid;  // (nrow, ncol) grid heights [m]
  bool use_region;
  const f64* region;  // (2, 3) world box [m]
  // Under a height grid or deforming ground: the depths a pass has looked up, per element
  // (null: none kept). A pass evaluates a body at one pose, but the low-speed treatment asks
  // for its wrench at several twists; the look-ups, not the law, are then most of the work.
  quadrature::DepthMemo memo = {};
  // k + 1 when the elements are tagged body k's (surface::SoilDepth), 0 for none.
  f64 body = 0.0;
};

// The medium of a plugin instance's tables; with a state, the memo of its pass.
Medium MediumOf(const Tables& t);
Medium MediumOf(const Tables& t, const State& s);
// The elements of a plugin instance's tables.
Elements ElementsOf(const Tables& t);

// Adds to wrench (6) the RFT wrench on elements [start, stop) of a body; returns #acting.
// soil: the deforming ground's block (read only under a kSoil surface). rot (9) body -> world,
// row-major; pos (3) body origin [m]; omega (3) angular velocity [rad/s]; v_ref (3) linear
// velocity [m/s] of the world point p_ref (3) moving with the body; com (3) the point torque is
// taken about [m]; all world frame. elem_force (n, 3): forces [N] written for rows
// [start, stop), zero where nothing acts (nullptr: not written). rows: nullptr, or (n, kRow)
// quadrature points written for the acting elements instead of their forces (rows of the others are
// left as they are).
int BodyWrench(const Elements& e, i64 start, i64 stop, const Medium& med, const f64* soil,
               const f64* rot, const f64* pos, const f64* omega, const f64* v_ref, const f64* p_ref,
               const f64* com, f64* wrench, f64* elem_force, f64* rows);

// Sets out (n, 3) to the forces [N] on n elements given in the world frame: centroids pos
// (n, 3) [m], unit normals n_hat (n, 3), areas (n,) [m^2], velocities vel (n, 3) [m/s], under
// the flat surface at height surface_z [m] (one-point rule). co (ncoef,): Medium's coef.
// Returns #acting (elements with a nonzero force).
int Forces(const f64* pos, const f64* n_hat, const f64* area, const f64* vel, i64 n, const f64* co,
           i64 ncoef, f64 alpha_y, f64 zeta, f64 surface_z, f64* out);

// A normal counts as unit if | |n|^2 - 1 | is below this (a few ulp: what normalising gives).
constexpr f64 kUnitNormalSlack = 4.0 * 2.220446049250313e-16;

// Flags of n elements' inputs (Forces' arrays, C-contiguous): *bad, any non-finite input or
// negative area; *nonunit, any normal not of unit length (kUnitNormalSlack). Branch-free and
// vectorised: about 1 ns per element.
void InputFlags(const f64* pos, const f64* normal, const f64* area, const f64* vel, i64 n,
                bool* bad, bool* nonunit);

// Codes of CheckedUnitNormals: which input of an element is bad.
enum InputCode { kInputOk, kBadPos, kBadNormal, kBadArea, kBadVel, kNegativeArea, kZeroNormal };

// Checks every element's inputs and writes its unit normal into n_hat (n, 3). Returns kInputOk
// (*index = -1) or the code of the first bad element (its index in *index): a non-finite
// position, normal, area or velocity, a negative area, or a zero-length normal. A normal
// already unit (within kUnitNormalSlack, as InputFlags tests) is copied unchanged, so an
// element's force does not depend on the other elements of the call; others are scaled by
// their largest component before they are normalised, so no finite normal overflows or
// underflows.
int CheckedUnitNormals(const f64* pos, const f64* normal, const f64* area, const f64* vel, i64 n,
                       f64* n_hat, i64* index);

// RFT wrenches of a body along a prescribed trajectory under the flat surface at surface_z
// [m], no region: out (T, 6) = force [N], moment [N m] about point[t], world frame, for T
// samples of rot (T, 9) body -> world (row-major), pos (T, 3) body origin [m], lin_vel (T, 3)
// its velocity [m/s], ang_vel (T, 3) [rad/s]; the n elements e in the body frame (BodyWrench).
void Trajectory(const Elements& e, i64 n, const f64* co, i64 ncoef, f64 alpha_y, f64 zeta,
                f64 surface_z, const f64* rot, const f64* pos, const f64* lin_vel,
                const f64* ang_vel, const f64* point, i64 T, f64* out);

}  // namespace mjrft::kernel

#endif  // MJRFT_ENGINE_KERNEL_H_
