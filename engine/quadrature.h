// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The exact surface quadrature of the kernel (mjrft.core.quadrature, docs/accuracy.md,
// "Quadrature"). The kernel evaluates an element at its centroid with its patch's normal and
// area, as a one-point rule, except where that rule is first order: where the free surface
// crosses the triangle, or where the leading boundary n . v = 0 does. There it integrates over
// the part of the triangle that is both submerged and leading, with depth and n . v
// interpolated linearly from the corners, and evaluates the force at that part's
// depth-weighted centroid with the normal interpolated there.
//
// Which elements need it is decided in two steps, so that the others cost one comparison more
// than a one-point rule: bounds per element (reach, spread) hold an element aside in the
// kernel's first pass; the held ones are then tested exactly from their corner values
// (CornerValues, Triage), and only those the surface or the leading boundary crosses, or within
// the band (kUnevenReach), are clipped (ClipHeld).

#ifndef MJRFT_ENGINE_QUADRATURE_H_
#define MJRFT_ENGINE_QUADRATURE_H_

#include "law.h"
#include "tables.h"

namespace mjrft::quadrature {

// Columns of a patch row (kPatchSize): corner offsets from the centroid (3 x 3) [m], corner
// normals (3 x 3), spread (largest distance between the element's normal and a corner normal);
// body frame.
constexpr int kPatchCorner = 0, kPatchNormal = 9, kPatchSpread = 18;
static_assert(kPatchSpread + 1 == kPatchSize, "patch layout");
// Elements whose centroid is within kUnevenReach * reach of the surface are clipped: under a
// level surface a corner's depth differs from the centroid's by at most reach; on an uneven one
// the surface's rise over reach horizontally adds to it, covered up to 45 deg slopes. One band
// for every surface, so that a flat height field gives the flat surface's forces.
constexpr f64 kUnevenReach = 2.0;

// Rows of the held scratch (f64[kHeld][kChunk]), for the elements whose corners are tested
// after a chunk's one-point pass: depth at the centroid [m]; point (3) [m], normal (3) and
// velocity (3) [m/s] of the one-point rule (world frame); corner depths (3) [m]; corner
// n . v - law::kLeadingSlack |v| (3) [m/s], > 0 where the corner leads.
enum HeldRow {
  kHeldDepth = 0,
  kHeldPoint = 1,
  kHeldNormal = 4,
  kHeldVel = 7,
  kHeldD = 10,
  kHeldS = 13
};
constexpr int kHeld = 16;
using Held = f64[kHeld][law::kChunk];

// The depths [m] one pass has looked up under an uneven surface, per element: depth (n, 4),
// the centroid's then its corners'; pass_of (n, 2), the pass that looked up each (centroid,
// corners), -1 none; pass, the current pass. depth null: nothing is kept.
struct DepthMemo {
  f64* depth = nullptr;
  i64* pass_of = nullptr;
  i64 pass = 0;
};

// Corner depths [m] and corner n . v [m/s] of the held elements later[0, nl) into held.
// n . v is taken in the body frame, v = lin_b + ang_b x c at the corner c (the body's motion
// expressed in its frame), so corner normals are not rotated; a corner's depth is measured
// vertically at its world position (surface.h). patch (n, kPatchSize), cent (n, 3) body-frame
// centroids; rot (9) body -> world, row-major; prm, grid, soil the surface, body its tagged
// body + 1 (surface::SoilDepth); memo the depths of an uneven surface's corners this pass has
// looked up already, read and written.
void CornerValues(const f64* patch, const f64* cent, const i64* later, Held& held, int nl,
                  const f64* rot, const f64* ang_b, const f64* lin_b, const f64* prm,
                  const f64* grid, const f64* soil, f64 body, const DepthMemo& memo);

// Sorts the held elements later[0, nl) by their corner values: those trailing everywhere or dry
// leave; those neither the free surface nor the leading boundary crosses, beyond the band
// (band * reach of the surface), are gathered at slots k... of buf (law::Gather) with the
// one-point rule; the rest are moved to the front of later and held. area, reach (n,). Returns
// the next free slot; *nc gets the number of the rest.
int Triage(law::Buf& buf, i64* idx, int k, i64* later, Held& held, int nl, const f64* area,
           const f64* reach, f64 band, int* nc);

// An element's quadrature point: W [m^3] the depth integral over its acting part, a [m^2] that
// part's area, point [m], unit normal and velocity [m/s] there; world frame. W = 0: nothing
// acts.
struct Point {
  f64 w, a;
  f64 x[3], n[3], v[3];
};

// The quadrature point of element i, held at column j: the submerged, leading part of its
// triangle of area [m^2], blended into the one-point rule. patch (n, kPatchSize), normal (n, 3)
// body-frame unit normals; band_r [m] the clipping band; the body at rot (9) body -> world,
// moving with omega (3) [rad/s] and v_ref (3) [m/s] at the world point p_ref (3).
Point ClipHeld(int j, i64 i, const Held& held, const f64* patch, const f64* normal, f64 area,
               f64 band_r, const f64* rot, const f64* omega, const f64* v_ref, const f64* p_ref);

}  // namespace mjrft::quadrature

#endif  // MJRFT_ENGINE_QUADRATURE_H_
