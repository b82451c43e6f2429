// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "quadrature.h"

#include <cmath>

#include "surface.h"

namespace mjrft::quadrature {
namespace {

// Vertices a triangle clipped by two half-planes can have (5), rounded up.
constexpr int kPoly = 8;
using Poly = f64[kPoly][3];

// The part of a triangle that acts: W [m^3] the integral of the depth over it, its
// depth-weighted centroid l (barycentric) and its area a [m^2]; W = 0: nothing acts.
struct Part {
  f64 w, l0, l1, l2, a;
};

// Clips the polygon src[0, ns) (barycentric points, rows) to where the linear function with
// corner values v0, v1, v2 is >= 0 (Sutherland-Hodgman); writes dst, returns its count.
int Clip(const Poly& src, int ns, Poly& dst, f64 v0, f64 v1, f64 v2) {
  int nd = 0;
  for (int k = 0; k < ns; k++) {
    int kb = k + 1 < ns ? k + 1 : 0;
    f64 fa = src[k][0] * v0 + src[k][1] * v1 + src[k][2] * v2;
    f64 fb = src[kb][0] * v0 + src[kb][1] * v1 + src[kb][2] * v2;
    if (fa >= 0.0) {
      for (int c = 0; c < 3; c++) dst[nd][c] = src[k][c];
      nd++;
    }
    if ((fa >= 0.0) != (fb >= 0.0)) {
      f64 t = fa / (fa - fb);
      for (int c = 0; c < 3; c++) dst[nd][c] = src[k][c] + (src[kb][c] - src[k][c]) * t;
      nd++;
    }
  }
  return nd;
}

// The part of a triangle of area [m^2] where depth and lead are >= 0 (both linear, corner
// values d0-d2, s0-s2), in general: a polygon, fanned into triangles. On a triangle with corner
// depths da, db, dc the integral of depth is A (da + db + dc) / 3 and that of depth times the
// barycentric point l is A / 12 ((da + db + dc) (la + lb + lc) + da la + db lb + dc lc).
Part Clipped(f64 d0, f64 d1, f64 d2, f64 s0, f64 s1, f64 s2, f64 area) {
  Poly src = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
  Poly dst;
  int n = Clip(src, 3, dst, d0, d1, d2);
  n = Clip(dst, n, src, s0, s1, s2);
  f64 acc[3] = {0.0, 0.0, 0.0};
  f64 w = 0.0, wet = 0.0;
  for (int k = 1; k < n - 1; k++) {
    f64 frac = std::fabs((src[k][1] - src[0][1]) * (src[k + 1][2] - src[0][2]) -
                         (src[k][2] - src[0][2]) * (src[k + 1][1] - src[0][1]));
    f64 da = src[0][0] * d0 + src[0][1] * d1 + src[0][2] * d2;
    f64 db = src[k][0] * d0 + src[k][1] * d1 + src[k][2] * d2;
    f64 dc = src[k + 1][0] * d0 + src[k + 1][1] * d1 + src[k + 1][2] * d2;
    f64 a = frac * area;
    f64 sd = da + db + dc;
    w += a * sd / 3.0;
    wet += a;
    for (int c = 0; c < 3; c++) {
      f64 lc = src[0][c] + src[k][c] + src[k + 1][c];
      acc[c] += a / 12.0 * (sd * lc + da * src[0][c] + db * src[k][c] + dc * src[k + 1][c]);
    }
  }
  if (!(w > 0.0)) return {0.0, 0.0, 0.0, 0.0, 0.0};
  f64 q = 1.0 / w;
  return {w, acc[0] * q, acc[1] * q, acc[2] * q, wet};
}

// The corner a of a triangle of area [m^2] that the line f = 0 cuts off (f linear, fa on one
// side, fb and fc on the other; depth corner values da, db, dc): W [m^3] the integral of the
// depth over it, (ma, mb, mc) W times its depth-weighted centroid in the triangle's barycentric
// coordinates (a, b, c), and its area a [m^2]. The corner is the triangle a, a + t1 (b - a),
// a + t2 (c - a), t1 = fa / (fa - fb), t2 = fa / (fa - fc), of area t1 t2 A; on it the
// formulas of Clipped.
struct Corner {
  f64 w, ma, mb, mc, a;
};
Corner CornerCut(f64 da, f64 db, f64 dc, f64 fa, f64 fb, f64 fc, f64 area) {
  f64 t1 = fa / (fa - fb);
  f64 t2 = fa / (fa - fc);
  f64 e1 = da + t1 * (db - da);
  f64 e2 = da + t2 * (dc - da);
  f64 a = area * t1 * t2;
  f64 s = da + e1 + e2;
  f64 k = a / 12.0;
  f64 ma = k * (s * (3.0 - t1 - t2) + da + e1 * (1.0 - t1) + e2 * (1.0 - t2));
  return {a * s / 3.0, ma, k * t1 * (s + e1), k * t2 * (s + e2), a};
}

// The Part of a triangle where the linear f >= 0 (corner values f0-f2) and the depth (corner
// values d0-d2) is positive everywhere on it: one line crosses the triangle, so the part is the
// corner it cuts off (CornerCut) or the triangle less that corner, in closed form.
Part Cut(f64 d0, f64 d1, f64 d2, f64 f0, f64 f1, f64 f2, f64 area) {
  bool i0 = f0 >= 0.0, i1 = f1 >= 0.0, i2 = f2 >= 0.0;
  int n = static_cast<int>(i0) + static_cast<int>(i1) + static_cast<int>(i2);
  f64 sd = d0 + d1 + d2;
  if (n == 0) return {0.0, 0.0, 0.0, 0.0, 0.0};
  if (n == 3) {
    f64 q = 1.0 / (4.0 * sd);
    return {area * sd / 3.0, (sd + d0) * q, (sd + d1) * q, (sd + d2) * q, area};
  }
  // The odd corner is the one inside alone (n == 1) or outside alone (n == 2).
  f64 w, m0, m1, m2, a;
  if (i0 == (n == 1)) {
    Corner c = CornerCut(d0, d1, d2, f0, f1, f2, area);
    w = c.w, m0 = c.ma, m1 = c.mb, m2 = c.mc, a = c.a;
  } else if (i1 == (n == 1)) {
    Corner c = CornerCut(d1, d2, d0, f1, f2, f0, area);
    w = c.w, m1 = c.ma, m2 = c.mb, m0 = c.mc, a = c.a;
  } else {
    Corner c = CornerCut(d2, d0, d1, f2, f0, f1, area);
    w = c.w, m2 = c.ma, m0 = c.mb, m1 = c.mc, a = c.a;
  }
  if (n == 2) {
    f64 k = area / 12.0;
    w = area * sd / 3.0 - w;
    a = area - a;
    m0 = k * (sd + d0) - m0;
    m1 = k * (sd + d1) - m1;
    m2 = k * (sd + d2) - m2;
  }
  if (!(w > 0.0)) return {0.0, 0.0, 0.0, 0.0, 0.0};
  f64 q = 1.0 / w;
  return {w, m0 * q, m1 * q, m2 * q, a};
}

// The quadrature point of element i (patch row pr, body-frame unit normal nb) from its acting
// part: the depth integral w [m^3] over it and its depth-weighted centroid (l0, l1, l2),
// blended into the one-point rule's values. d0-d2: corner depths [m]; depth0 [m] at the
// centroid p (3) [m]; band_r [m] the clipping band. Writes out's w, point, normal, velocity
// (not a); w = 0: nothing acts.
//
// Continuity with the one-point rule: the whole triangle's integral (depth-weighted centroid
// l_j = (sum d + d_j) / (4 sum d), normal interpolated there, W = A mean d) is replaced by the
// element's own point, normal and A d_centroid, with a weight ramping from 0 at the surface to
// 1 at the band's edge, where an element leaves the clipped path: an element that nothing clips
// then gets exactly the one-point rule's force, and the force is continuous in the state (the
// implicit step differentiates it).
void Blend(const f64* pr, const f64* nb, f64 area, f64 depth0, f64 band_r, f64 d0, f64 d1, f64 d2,
           f64 w, f64 l0, f64 l1, f64 l2, const f64* rot, const f64* p, const f64* omega,
           const f64* v_ref, const f64* p_ref, Point* out) {
  f64 sd = d0 + d1 + d2;
  f64 ramp = band_r > 0.0 ? law::Min(1.0, law::Max(0.0, sd / (3.0 * band_r))) : 1.0;
  f64 g0 = l0, g1 = l1, g2 = l2;  // the point's barycentric weights, before the ramp
  const f64* b = pr + kPatchNormal;
  f64 mx = l0 * b[0] + l1 * b[3] + l2 * b[6];
  f64 my = l0 * b[1] + l1 * b[4] + l2 * b[7];
  f64 mz = l0 * b[2] + l1 * b[5] + l2 * b[8];
  if (ramp > 0.0) {
    f64 q = 1.0 / (4.0 * sd);
    f64 f0 = (sd + d0) * q, f1 = (sd + d1) * q, f2 = (sd + d2) * q;
    g0 = g0 - ramp * f0;
    g1 = g1 - ramp * f1;
    g2 = g2 - ramp * f2;
    mx += ramp * (nb[0] - (f0 * b[0] + f1 * b[3] + f2 * b[6]));
    my += ramp * (nb[1] - (f0 * b[1] + f1 * b[4] + f2 * b[7]));
    mz += ramp * (nb[2] - (f0 * b[2] + f1 * b[5] + f2 * b[8]));
    w += ramp * area * (depth0 - sd / 3.0);
    if (!(w > 0.0)) {
      *out = Point{};
      return;
    }
  }
  // The point: the centroid plus R (sum_j g_j offset_j), since the l_j and the f_j sum to 1
  // and the corners are the centroid plus R offset_j.
  const f64* o = pr + kPatchCorner;
  f64 ox = g0 * o[0] + g1 * o[3] + g2 * o[6];
  f64 oy = g0 * o[1] + g1 * o[4] + g2 * o[7];
  f64 oz = g0 * o[2] + g1 * o[5] + g2 * o[8];
  f64 x = p[0] + rot[0] * ox + rot[1] * oy + rot[2] * oz;
  f64 y = p[1] + rot[3] * ox + rot[4] * oy + rot[5] * oz;
  f64 z = p[2] + rot[6] * ox + rot[7] * oy + rot[8] * oz;
  f64 inv = 1.0 / std::sqrt(mx * mx + my * my + mz * mz);
  mx = mx * inv;
  my = my * inv;
  mz = mz * inv;
  out->w = w;
  out->x[0] = x;
  out->x[1] = y;
  out->x[2] = z;
  out->n[0] = rot[0] * mx + rot[1] * my + rot[2] * mz;
  out->n[1] = rot[3] * mx + rot[4] * my + rot[5] * mz;
  out->n[2] = rot[6] * mx + rot[7] * my + rot[8] * mz;
  f64 dx = x - p_ref[0], dy = y - p_ref[1], dz = z - p_ref[2];
  out->v[0] = v_ref[0] + omega[1] * dz - omega[2] * dy;
  out->v[1] = v_ref[1] + omega[2] * dx - omega[0] * dz;
  out->v[2] = v_ref[2] + omega[0] * dy - omega[1] * dx;
}

}  // namespace

void CornerValues(const f64* patch, const f64* cent, const i64* later, Held& held, int nl,
                  const f64* rot, const f64* ang_b, const f64* lin_b, const f64* prm,
                  const f64* grid, const f64* soil, f64 body, const DepthMemo& memo) {
  f64 gx = ang_b[0], gy = ang_b[1], gz = ang_b[2];
  f64 lx = lin_b[0], ly = lin_b[1], lz = lin_b[2];
  f64 r20 = rot[6], r21 = rot[7], r22 = rot[8];
  bool flat = prm[surface::kKind] == surface::kFlat;
  f64 top = prm[surface::kZ0];
  for (int j = 0; j < nl; j++) {
    i64 i = later[j];
    const f64* pr = patch + kPatchSize * i;
    f64 bx = cent[3 * i], by = cent[3 * i + 1], bz = cent[3 * i + 2];
    for (int q = 0; q < 3; q++) {
      f64 o0 = pr[3 * q], o1 = pr[3 * q + 1], o2 = pr[3 * q + 2];
      f64 cx = bx + o0, cy = by + o1, cz = bz + o2;
      const f64* g = pr + kPatchNormal + 3 * q;
      // n . v less law::kLeadingSlack |v|: a corner leads iff this is > 0 (law::Gather's rule).
      f64 vx = lx + gy * cz - gz * cy, vy = ly + gz * cx - gx * cz, vz = lz + gx * cy - gy * cx;
      held[kHeldS + q][j] = g[0] * vx + g[1] * vy + g[2] * vz -
                            law::kLeadingSlack * std::sqrt(vx * vx + vy * vy + vz * vz);
      f64 z = held[kHeldPoint + 2][j] + (r20 * o0 + r21 * o1 + r22 * o2);
      held[kHeldD + q][j] = top - z;
    }
  }
  if (flat) return;
  if (prm[surface::kKind] == surface::kPlane) {  // the centroid's depth plus the plane's rise
    f64 px = prm[surface::kGx], py = prm[surface::kGy];
    f64 a0 = px * rot[0] + py * rot[3] - r20;
    f64 a1 = px * rot[1] + py * rot[4] - r21;
    f64 a2 = px * rot[2] + py * rot[5] - r22;
    for (int j = 0; j < nl; j++) {
      const f64* pr = patch + kPatchSize * later[j];
      for (int q = 0; q < 3; q++) {
        f64 o0 = pr[3 * q], o1 = pr[3 * q + 1], o2 = pr[3 * q + 2];
        held[kHeldD + q][j] = held[kHeldDepth][j] + (a0 * o0 + a1 * o1 + a2 * o2);
      }
    }
    return;
  }
  // An uneven surface: the height under each corner (kept out of the loop above, so that a
  // flat surface's loop stays small).
  for (int j = 0; j < nl; j++) {
    i64 i = later[j];
    f64* kept = memo.depth ? memo.depth + 4 * i + 1 : nullptr;
    if (kept && memo.pass_of[2 * i + 1] == memo.pass) {
      for (int q = 0; q < 3; q++) held[kHeldD + q][j] = kept[q];
      continue;
    }
    const f64* pr = patch + kPatchSize * i;
    for (int q = 0; q < 3; q++) {
      f64 o0 = pr[3 * q], o1 = pr[3 * q + 1], o2 = pr[3 * q + 2];
      held[kHeldD + q][j] = surface::Depth(
          prm, grid, soil, held[kHeldPoint][j] + (rot[0] * o0 + rot[1] * o1 + rot[2] * o2),
          held[kHeldPoint + 1][j] + (rot[3] * o0 + rot[4] * o1 + rot[5] * o2),
          held[kHeldPoint + 2][j] + (r20 * o0 + r21 * o1 + r22 * o2), body);
    }
    if (kept) {
      for (int q = 0; q < 3; q++) kept[q] = held[kHeldD + q][j];
      memo.pass_of[2 * i + 1] = memo.pass;
    }
  }
}

int Triage(law::Buf& buf, i64* idx, int k, i64* later, Held& held, int nl, const f64* area,
           const f64* reach, f64 band, int* nc) {
  int rest = 0;
  for (int j = 0; j < nl; j++) {
    i64 i = later[j];
    f64 d0 = held[kHeldD][j], d1 = held[kHeldD + 1][j], d2 = held[kHeldD + 2][j];
    f64 s0 = held[kHeldS][j], s1 = held[kHeldS + 1][j], s2 = held[kHeldS + 2][j];
    if ((s0 < 0.0 && s1 < 0.0 && s2 < 0.0) || (d0 <= 0.0 && d1 <= 0.0 && d2 <= 0.0)) {
      continue;  // nothing of it is both submerged and leading
    }
    if (s0 > 0.0 && s1 > 0.0 && s2 > 0.0 && d0 > 0.0 && d1 > 0.0 && d2 > 0.0 &&
        d0 + d1 + d2 >= 3.0 * band * reach[i]) {
      buf[law::kPx][k] = held[kHeldPoint][j];
      buf[law::kPx + 1][k] = held[kHeldPoint + 1][j];
      buf[law::kPx + 2][k] = held[kHeldPoint + 2][j];
      buf[law::kArea][k] = area[i];
      k = law::Gather(buf, idx, k, i, held[kHeldNormal][j], held[kHeldNormal + 1][j],
                      held[kHeldNormal + 2][j], held[kHeldVel][j], held[kHeldVel + 1][j],
                      held[kHeldVel + 2][j], held[kHeldDepth][j], area[i], true);
      continue;
    }
    if (rest != j) {
      later[rest] = i;
      for (int r = 0; r < kHeld; r++) held[r][rest] = held[r][j];
    }
    rest++;
  }
  *nc = rest;
  return k;
}

Point ClipHeld(int j, i64 i, const Held& held, const f64* patch, const f64* normal, f64 area,
               f64 band_r, const f64* rot, const f64* omega, const f64* v_ref, const f64* p_ref) {
  f64 d0 = held[kHeldD][j], d1 = held[kHeldD + 1][j], d2 = held[kHeldD + 2][j];
  f64 s0 = held[kHeldS][j], s1 = held[kHeldS + 1][j], s2 = held[kHeldS + 2][j];
  Part part;
  if (d0 > 0.0 && d1 > 0.0 && d2 > 0.0) {  // the whole triangle, or the leading boundary cuts it
    part = Cut(d0, d1, d2, s0, s1, s2, area);
  } else if (s0 > 0.0 && s1 > 0.0 && s2 > 0.0) {  // only the free surface cuts it
    part = Cut(d0, d1, d2, d0, d1, d2, area);
  } else {
    part = Clipped(d0, d1, d2, s0, s1, s2, area);
  }
  Point out{};
  if (part.w == 0.0) return out;
  const f64 p[3] = {held[kHeldPoint][j], held[kHeldPoint + 1][j], held[kHeldPoint + 2][j]};
  Blend(patch + kPatchSize * i, normal + 3 * i, area, held[kHeldDepth][j], band_r, d0, d1, d2,
        part.w, part.l0, part.l1, part.l2, rot, p, omega, v_ref, p_ref, &out);
  if (out.w != 0.0) out.a = part.a;
  return out;
}

}  // namespace mjrft::quadrature
