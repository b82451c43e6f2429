// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "lowest.h"

#include <cmath>

#include "surface.h"

namespace mjrft {
namespace {

// Column j of the row-major rotation R (geom frame -> world frame).
void Column(const f64* R, int j, f64 out[3]) {
  for (int i = 0; i < 3; i++) out[i] = R[3 * i + j];
}

// +1 for x >= 0, else -1: the lowest of two symmetric points is the one on the side where the
// axis points down; at x = 0 both are equally low.
f64 Sign(f64 x) { return x >= 0.0 ? 1.0 : -1.0; }

// Lowest point of the box of half sizes h (3) centred at c, rotated by R.
void BoxLowest(const f64* c, const f64* R, const f64* h, f64 out[3]) {
  for (int i = 0; i < 3; i++) out[i] = c[i];
  for (int j = 0; j < 3; j++) {
    f64 s = -Sign(R[6 + j]) * h[j];  // R[6 + j]: world z of geom axis j
    for (int i = 0; i < 3; i++) out[i] += s * R[3 * i + j];
  }
}

// Lowest point of a cylinder (radius r, half length h, axis a = R's third column): the end
// whose axis points down, then r along the downward direction perpendicular to the axis.
void CylinderLowest(const f64* c, const f64* R, f64 r, f64 h, f64 out[3]) {
  f64 a[3];
  Column(R, 2, a);
  f64 s = -Sign(a[2]) * h;
  f64 down[3] = {a[2] * a[0], a[2] * a[1], a[2] * a[2] - 1.0};  // -(e_z - a_z a)
  f64 n = std::sqrt(down[0] * down[0] + down[1] * down[1] + down[2] * down[2]);
  for (int i = 0; i < 3; i++) out[i] = c[i] + s * a[i] + (n > 0.0 ? r * down[i] / n : 0.0);
}

// Lowest point of the ellipsoid of radii s centred at c, rotated by R: c - R D w / |w| with
// w = D R^T e_z (D = diag(s)), where the support function in -e_z is reached.
void EllipsoidLowest(const f64* c, const f64* R, const f64* s, f64 out[3]) {
  f64 w[3] = {s[0] * R[6], s[1] * R[7], s[2] * R[8]};
  f64 n = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  for (int i = 0; i < 3; i++) {
    f64 x = 0.0;
    for (int j = 0; j < 3; j++) x += R[3 * i + j] * s[j] * w[j];
    out[i] = c[i] - (n > 0.0 ? x / n : 0.0);
  }
}

// Lowest vertex of mesh `mesh` (its vertices are in the geom frame: MuJoCo re-centres meshes).
void MeshLowest(const mjModel* m, int mesh, const f64* c, const f64* R, f64 out[3]) {
  const float* v = m->mesh_vert + 3 * m->mesh_vertadr[mesh];
  f64 best = INFINITY;
  for (int k = 0; k < m->mesh_vertnum[mesh]; k++) {
    f64 p[3];
    for (int i = 0; i < 3; i++) {
      p[i] = c[i] + R[3 * i] * v[3 * k] + R[3 * i + 1] * v[3 * k + 1] + R[3 * i + 2] * v[3 * k + 2];
    }
    if (p[2] < best) {
      best = p[2];
      for (int i = 0; i < 3; i++) out[i] = p[i];
    }
  }
}

}  // namespace

bool LowestPoint(const mjModel* m, const mjData* d, int geom, f64 out[3]) {
  const f64* c = d->geom_xpos + 3 * geom;
  const f64* R = d->geom_xmat + 9 * geom;
  const f64* size = m->geom_size + 3 * geom;
  switch (m->geom_type[geom]) {
    case mjGEOM_PLANE:
    case mjGEOM_HFIELD:
      return false;
    case mjGEOM_SPHERE:
      out[0] = c[0], out[1] = c[1], out[2] = c[2] - size[0];
      return true;
    case mjGEOM_CAPSULE: {
      CylinderLowest(c, R, 0.0, size[1], out);
      out[2] -= size[0];
      return true;
    }
    case mjGEOM_CYLINDER:
      CylinderLowest(c, R, size[0], size[1], out);
      return true;
    case mjGEOM_ELLIPSOID:
      EllipsoidLowest(c, R, size, out);
      return true;
    case mjGEOM_BOX:
      BoxLowest(c, R, size, out);
      return true;
    case mjGEOM_MESH:
      if (m->geom_dataid[geom] >= 0 && m->mesh_vertnum[m->geom_dataid[geom]] > 0) {
        MeshLowest(m, m->geom_dataid[geom], c, R, out);
        return true;
      }
      [[fallthrough]];
    default: {  // the bounding box (centre, half sizes) in the geom frame
      const f64* aabb = m->geom_aabb + 6 * geom;
      f64 centre[3];
      for (int i = 0; i < 3; i++) {
        centre[i] = c[i] + R[3 * i] * aabb[0] + R[3 * i + 1] * aabb[1] + R[3 * i + 2] * aabb[2];
      }
      BoxLowest(centre, R, aabb + 3, out);
      return true;
    }
  }
}

f64 Sinkage(const mjModel* m, const mjData* d, const Tables& t, const f64* soil, int geom,
            f64 low[3]) {
  if (!LowestPoint(m, d, geom, low)) return NAN;
  return surface::Height(t.surface_prm, t.surface_grid, soil, low[0], low[1]) - low[2];
}

}  // namespace mjrft
