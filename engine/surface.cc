// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "surface.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mjrft::surface {

f64 GridHeight(const f64* prm, const f64* grid, f64 x, f64 y) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  f64 u = (x - prm[kX0]) / prm[kDx];
  f64 v = (y - prm[kY0]) / prm[kDy];
  u = std::min(std::max(u, 0.0), ncol - 1.0);
  v = std::min(std::max(v, 0.0), nrow - 1.0);
  i64 c = std::min(static_cast<i64>(u), ncol - 2);
  i64 r = std::min(static_cast<i64>(v), nrow - 2);
  f64 fu = u - c, fv = v - r;
  f64 h00 = grid[r * ncol + c];
  f64 h11 = grid[(r + 1) * ncol + c + 1];
  if (fu >= fv) {
    f64 h10 = grid[r * ncol + c + 1];
    return h00 + fu * (h10 - h00) + fv * (h11 - h10);
  }
  f64 h01 = grid[(r + 1) * ncol + c];
  return h00 + fv * (h01 - h00) + fu * (h11 - h01);
}

void SoilVertex(const f64* prm, const f64* grid, const f64* soil, i64 r, i64 c, f64 out[3]) {
  i64 ncol = static_cast<i64>(prm[kNcol]);
  i64 n = ncol * static_cast<i64>(prm[kNrow]);
  i64 i = kSoilHead + r * ncol + c;
  f64 base = grid[r * ncol + c];
  out[0] = base + soil[i];
  out[1] = base + soil[i + n];
  out[2] = soil[i + 2 * n];
}

namespace {

// A deforming grid's (h, c, p) interpolated at (x, y) over its cell's triangle: surface,
// compacted level, memory [m].
struct Levels {
  f64 h, c, p;
};
Levels SoilLevels(const f64* prm, const f64* grid, const f64* soil, f64 x, f64 y) {
  Cell k = CellOf(prm, x, y);
  f64 v00[3], v10[3], v01[3], v11[3];
  SoilVertex(prm, grid, soil, k.r, k.c, v00);
  SoilVertex(prm, grid, soil, k.r, k.c + 1, v10);
  SoilVertex(prm, grid, soil, k.r + 1, k.c, v01);
  SoilVertex(prm, grid, soil, k.r + 1, k.c + 1, v11);
  Levels out;
  f64* level[3] = {&out.h, &out.c, &out.p};
  for (int i = 0; i < 3; i++) {
    *level[i] = Tri(v00[i], v10[i], v01[i], v11[i], k.fu, k.fv, k.upper);
  }
  return out;
}

}  // namespace

f64 BesideDepth(const f64* prm, const f64* grid, const f64* soil, const Cell& k, const i64* v,
                const bool* pressed, f64 z) {
  i64 n = static_cast<i64>(prm[kNcol]) * static_cast<i64>(prm[kNrow]);
  const f64* oh = soil + kSoilHead;
  f64 h[4], c[4], p[4], floor = -std::numeric_limits<f64>::infinity();
  int free = -1;
  for (int q = 0; q < 4; q++) {
    h[q] = grid[v[q]] + oh[v[q]];
    c[q] = grid[v[q]] + oh[n + v[q]];
    p[q] = oh[2 * n + v[q]];
    if (pressed[q]) {
      floor = std::max(floor, h[q]);
    } else if (free < 0 || h[q] > h[free]) {
      free = q;
    }
  }
  if (z >= floor + kSoilContact) {  // beside the intruder: the free column up to its side
    for (int q = 0; q < 4; q++) {
      if (!pressed[q]) continue;
      h[q] = h[free];
      c[q] = c[free];
      p[q] = p[free];
    }
  }
  f64 hz = Tri(h[0], h[1], h[2], h[3], k.fu, k.fv, k.upper);
  if (z >= hz + kSoilContact) return hz - z;
  f64 depth = std::max(hz - z, 0.0);
  if (z < Tri(c[0], c[1], c[2], c[3], k.fu, k.fv, k.upper) + kSoilContact) {
    depth += Tri(p[0], p[1], p[2], p[3], k.fu, k.fv, k.upper);
  }
  return depth;
}

f64 Height(const f64* prm, const f64* grid, const f64* soil, f64 x, f64 y) {
  f64 kind = prm[kKind];
  if (kind == kFlat) return prm[kZ0];
  if (kind == kPlane) return prm[kZ0] + prm[kGx] * x + prm[kGy] * y;
  if (kind == kGrid) return GridHeight(prm, grid, x, y);
  return SoilLevels(prm, grid, soil, x, y).h;
}

f64 Ceiling(const f64* prm, const f64* soil) {
  f64 kind = prm[kKind];
  if (kind == kFlat) return prm[kZ0];
  if (kind == kPlane) return std::numeric_limits<f64>::infinity();
  if (kind == kGrid) return prm[kZmax];
  return prm[kZmax] + soil[kSoilZoff] + kSoilContact;
}

f64 HighestNear(const f64* prm, const f64* soil, f64 x, f64 y, f64 r) {
  if (prm[kKind] == kPlane) {
    return prm[kZ0] + prm[kGx] * x + prm[kGy] * y + r * std::hypot(prm[kGx], prm[kGy]);
  }
  return Ceiling(prm, soil);
}

}  // namespace mjrft::surface
