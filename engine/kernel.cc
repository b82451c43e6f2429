// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Layout (chosen from measurements on a 2-core machine, benchmarks/kernel.py):
//
// 1. BodyWrench only: a pass puts a chunk's centroids, normals and velocities in the world
//    frame; an element the quadrature's bounds show dry or trailing at every corner leaves at
//    once, one they cannot clear is held aside, and after the pass the held ones are tested
//    exactly from their corners (quadrature::CornerValues, Triage) and only those the free
//    surface or the leading boundary crosses, or near the surface, are clipped
//    (quadrature::ClipHeld). Kept out of the first pass, this work does not slow it;
// 2. law::Gather, scalar and branch-free: every element is written to the next scratch slot and
//    the slot advances only if the element acts (submerged, inside the region, leading), so
//    trailing and dry elements cost only this pass and no branch is mispredicted;
// 3. law::EvaluateModel, one branch-free loop that the compiler vectorises;
// 4. a scalar pass scatters the element forces and accumulates the wrench.
//
// Both drivers share stages 2-4: Forces over world-frame element arrays, and BodyWrench. The
// scratch (about 70 kB) lives on the stack: no allocation in a pass.

#include "kernel.h"

#include <cmath>

#include "law.h"
#include "quadrature.h"
#include "surface.h"

namespace mjrft::kernel {

using law::kChunk;

// 1 plus a margin far above the round-off of a corner's depth against the centroid's (~1e-16
// of the coordinates), far below any element's reach.
constexpr f64 kDrySlack = 1.0 + 1e-9;

Medium MediumOf(const Tables& t) {
  return {t.coef,        t.ncoef,        t.alpha_y,         t.zeta,
          t.surface_prm, t.surface_grid, t.use_region != 0, t.region};
}

Medium MediumOf(const Tables& t, const State& s) {
  Medium med = MediumOf(t);
  f64 kind = t.surface_prm[surface::kKind];
  if (kind == surface::kGrid || kind == surface::kSoil) {
    med.memo = {s.elem_depth, s.elem_depth_pass, s.pass[0]};
  }
  return med;
}

Elements ElementsOf(const Tables& t) {
  return {t.elem_pos, t.elem_normal, t.elem_area, t.elem_reach, t.elem_patch};
}

int BodyWrench(const Elements& e, i64 start, i64 stop, const Medium& med, const f64* soil,
               const f64* rot, const f64* pos, const f64* omega, const f64* v_ref, const f64* p_ref,
               const f64* com, f64* wrench, f64* elem_force, f64* rows) {
  alignas(64) law::Buf buf;
  alignas(64) quadrature::Held held;
  i64 idx[kChunk];
  i64 later[kChunk];  // elements whose corners are tested after the one-point pass
  const f64* cf = e.pos;
  const f64* nf = e.normal;
  const f64* prm = med.surface_prm;
  // Scalar invariants: no reloads in the loop below.
  const f64 r00 = rot[0], r01 = rot[1], r02 = rot[2];
  const f64 r10 = rot[3], r11 = rot[4], r12 = rot[5];
  const f64 r20 = rot[6], r21 = rot[7], r22 = rot[8];
  const f64 ox = pos[0], oy = pos[1], oz = pos[2];
  const f64 wx = omega[0], wy = omega[1], wz = omega[2];
  const f64 ux = v_ref[0], uy = v_ref[1], uz = v_ref[2];
  const f64 qx = p_ref[0], qy = p_ref[1], qz = p_ref[2];
  const f64* lo = med.region;
  const f64* hi = med.region + 3;
  const bool flat = prm[surface::kKind] == surface::kFlat;
  const f64 band = quadrature::kUnevenReach;  // corner depths are within band * reach
  const f64 spin = std::sqrt(wx * wx + wy * wy + wz * wz);
  f64 top = surface::Ceiling(prm, soil);  // an element above it is dry wherever it is
  // The first test of an element is top - (k . c + kz) for its body-frame centroid c: its
  // height below the ceiling, or under a plane (whose ceiling, +inf, would clear nothing) its
  // exact depth z0 + gx x + gy y - z, affine in c. One dot product either way.
  // A corner's depth differs from the centroid's by at most reach under a level surface, and
  // by reach sqrt(1 + |grad|^2) under a plane: an element farther above it than that is dry at
  // every corner (what Triage would find). Under an uneven surface the rise adds to it (band).
  const bool plane = prm[surface::kKind] == surface::kPlane;
  f64 k0 = r20, k1 = r21, k2 = r22, kz = oz;
  f64 dry = flat ? kDrySlack : band;
  if (plane) {
    f64 gx = prm[surface::kGx], gy = prm[surface::kGy];
    k0 = r20 - gx * r00 - gy * r10;
    k1 = r21 - gx * r01 - gy * r11;
    k2 = r22 - gx * r02 - gy * r12;
    kz = oz - gx * ox - gy * oy;
    top = prm[surface::kZ0];
    dry = kDrySlack * std::sqrt(1.0 + gx * gx + gy * gy);
  }
  const f64 lam_rho = law::DynamicCoefficient(med.coef, med.ncoef);
  const bool dyn = lam_rho > 0.0;
  // The body's motion in its own frame, v(c) = lin_b + ang_b x c at the body point c, for the
  // corners' n . v (quadrature::CornerValues).
  f64 ang_b[3], lin_b[3];
  {
    f64 ex = ox - qx, ey = oy - qy, ez = oz - qz;
    f64 tx = ux + wy * ez - wz * ey, ty = uy + wz * ex - wx * ez, tz = uz + wx * ey - wy * ex;
    for (int c = 0; c < 3; c++) {
      ang_b[c] = rot[c] * wx + rot[3 + c] * wy + rot[6 + c] * wz;
      lin_b[c] = rot[c] * tx + rot[3 + c] * ty + rot[6 + c] * tz;
    }
  }
  int count = 0;
  for (i64 c0 = start; c0 < stop; c0 += kChunk) {
    int k = 0, nl = 0;
    i64 c1 = stop < c0 + kChunk ? stop : c0 + kChunk;
    if (elem_force) {
      for (i64 i = 3 * c0; i < 3 * c1; i++) elem_force[i] = 0.0;
    }
    for (i64 i = c0; i < c1; i++) {
      // Dry elements leave here (a well-predicted branch: neighbouring triangles of a mesh are
      // dry together), after three multiply-adds.
      f64 cx = cf[3 * i], cy = cf[3 * i + 1], cz = cf[3 * i + 2];
      f64 depth = top - (k0 * cx + k1 * cy + k2 * cz + kz);
      f64 ri = e.reach[i];
      if (depth <= -dry * ri) continue;
      f64 px = r00 * cx + r01 * cy + r02 * cz + ox;
      f64 py = r10 * cx + r11 * cy + r12 * cz + oy;
      f64 pz = r20 * cx + r21 * cy + r22 * cz + oz;
      if (!flat && !plane) {
        if (med.memo.depth && med.memo.pass_of[2 * i] == med.memo.pass) {
          depth = med.memo.depth[4 * i];
        } else {
          depth = surface::Depth(prm, med.surface_grid, soil, px, py, pz, med.body);
          if (med.memo.depth) {
            med.memo.depth[4 * i] = depth;
            med.memo.pass_of[2 * i] = med.memo.pass;
          }
        }
        if (depth <= -band * ri) continue;
      }
      if (med.use_region &&
          (px < lo[0] || py < lo[1] || pz < lo[2] || px > hi[0] || py > hi[1] || pz > hi[2])) {
        continue;
      }
      f64 mx = nf[3 * i], my = nf[3 * i + 1], mz = nf[3 * i + 2];
      f64 nx = r00 * mx + r01 * my + r02 * mz;
      f64 ny = r10 * mx + r11 * my + r12 * mz;
      f64 nz = r20 * mx + r21 * my + r22 * mz;
      f64 dx = px - qx, dy = py - qy, dz = pz - qz;
      f64 vx = ux + wy * dz - wz * dy;
      f64 vy = uy + wz * dx - wx * dz;
      f64 vz = uz + wx * dy - wy * dx;
      f64 lead = nx * vx + ny * vy + nz * vz;
      // The free surface or the leading boundary may cross the element: its corners are tested
      // after the chunk's one-point pass. Corner depths differ from the centroid's by at most
      // reach under a level surface, and n . v by at most spread |v| + |omega| reach (the corner
      // normals are unit and within spread of the element's), compared without a square root.
      f64 spread = e.patch[kPatchSize * i + quadrature::kPatchSpread];
      f64 excess = std::fabs(lead) - spin * ri;
      bool unsure =
          excess <= 0.0 || excess * excess <= spread * spread * (vx * vx + vy * vy + vz * vz);
      if (!unsure && lead < 0.0) continue;  // trailing at every corner: nothing of it acts
      if (unsure || depth < band * ri) {
        later[nl] = i;
        held[quadrature::kHeldDepth][nl] = depth;
        held[quadrature::kHeldPoint][nl] = px;
        held[quadrature::kHeldPoint + 1][nl] = py;
        held[quadrature::kHeldPoint + 2][nl] = pz;
        held[quadrature::kHeldNormal][nl] = nx;
        held[quadrature::kHeldNormal + 1][nl] = ny;
        held[quadrature::kHeldNormal + 2][nl] = nz;
        held[quadrature::kHeldVel][nl] = vx;
        held[quadrature::kHeldVel + 1][nl] = vy;
        held[quadrature::kHeldVel + 2][nl] = vz;
        nl++;
        continue;
      }
      buf[law::kPx][k] = px;
      buf[law::kPx + 1][k] = py;
      buf[law::kPx + 2][k] = pz;
      if (dyn || rows) buf[law::kArea][k] = e.area[i];  // read by the dynamic term and the rows
      k = law::Gather(buf, idx, k, i, nx, ny, nz, vx, vy, vz, depth, e.area[i], true);
    }
    quadrature::CornerValues(e.patch, cf, later, held, nl, rot, ang_b, lin_b, prm, med.surface_grid,
                             soil, med.body, med.memo);
    int nc = 0;
    k = quadrature::Triage(buf, idx, k, later, held, nl, e.area, e.reach, band, &nc);
    for (int j = 0; j < nc; j++) {
      i64 i = later[j];
      quadrature::Point pt = quadrature::ClipHeld(j, i, held, e.patch, e.normal, e.area[i],
                                                  band * e.reach[i], rot, omega, v_ref, p_ref);
      if (pt.w == 0.0) continue;
      buf[law::kPx][k] = pt.x[0];
      buf[law::kPx + 1][k] = pt.x[1];
      buf[law::kPx + 2][k] = pt.x[2];
      buf[law::kArea][k] = pt.a;
      // Depth 1 and the depth integral W as the area: depth x area is W.
      k = law::Gather(buf, idx, k, i, pt.n[0], pt.n[1], pt.n[2], pt.v[0], pt.v[1], pt.v[2], 1.0,
                      pt.w, true);
    }
    if (rows) {
      for (int j = 0; j < k; j++) {
        f64* row = rows + kRow * idx[j];
        for (int c = 0; c < 3; c++) {
          row[c] = buf[law::kPx + c][j];
          row[3 + c] = buf[law::kNx + c][j];
          row[6 + c] = buf[law::kWx + c][j];
        }
        row[9] = buf[law::kDepthArea][j];
        row[10] = buf[law::kArea][j];
      }
      count += k;
      continue;
    }
    law::EvaluateModel(buf, k, med.coef, med.ncoef, med.alpha_y, med.zeta);
    if (dyn) {  // the velocity at each point: the body's twist (Gather may rescale w)
      for (int j = 0; j < k; j++) {
        f64 dx = buf[law::kPx][j] - qx, dy = buf[law::kPx + 1][j] - qy;
        f64 dz = buf[law::kPx + 2][j] - qz;
        law::Dynamic(buf, j, lam_rho, buf[law::kArea][j], ux + wy * dz - wz * dy,
                     uy + wz * dx - wx * dz, uz + wx * dy - wy * dx);
      }
    }
    for (int j = 0; j < k; j++) {
      f64 fx = buf[law::kFx][j], fy = buf[law::kFx + 1][j], fz = buf[law::kFx + 2][j];
      if (fx == 0.0 && fy == 0.0 && fz == 0.0) continue;
      count++;
      if (elem_force) {
        f64* f = elem_force + 3 * idx[j];
        f[0] = fx;
        f[1] = fy;
        f[2] = fz;
      }
      f64 ax = buf[law::kPx][j] - com[0], ay = buf[law::kPx + 1][j] - com[1];
      f64 az = buf[law::kPx + 2][j] - com[2];
      wrench[0] += fx;
      wrench[1] += fy;
      wrench[2] += fz;
      wrench[3] += ay * fz - az * fy;
      wrench[4] += az * fx - ax * fz;
      wrench[5] += ax * fy - ay * fx;
    }
  }
  return count;
}

int Forces(const f64* pos, const f64* n_hat, const f64* area, const f64* vel, i64 n, const f64* co,
           i64 ncoef, f64 alpha_y, f64 zeta, f64 surface_z, f64* out) {
  alignas(64) law::Buf buf;
  i64 idx[kChunk];
  const f64 lam_rho = law::DynamicCoefficient(co, ncoef);
  const bool dyn = lam_rho > 0.0;
  int count = 0;
  for (i64 c0 = 0; c0 < n; c0 += kChunk) {
    i64 c1 = n < c0 + kChunk ? n : c0 + kChunk;
    for (i64 i = 3 * c0; i < 3 * c1; i++) out[i] = 0.0;
    int k = 0;
    for (i64 i = c0; i < c1; i++) {
      k = law::Gather(buf, idx, k, i, n_hat[3 * i], n_hat[3 * i + 1], n_hat[3 * i + 2], vel[3 * i],
                      vel[3 * i + 1], vel[3 * i + 2], surface_z - pos[3 * i + 2], area[i], true);
    }
    law::EvaluateModel(buf, k, co, ncoef, alpha_y, zeta);
    if (dyn) {
      for (int j = 0; j < k; j++) {
        i64 i = idx[j];
        law::Dynamic(buf, j, lam_rho, area[i], vel[3 * i], vel[3 * i + 1], vel[3 * i + 2]);
      }
    }
    for (int j = 0; j < k; j++) {
      f64* f = out + 3 * idx[j];
      f[0] = buf[law::kFx][j];
      f[1] = buf[law::kFx + 1][j];
      f[2] = buf[law::kFx + 2][j];
      if (f[0] != 0.0 || f[1] != 0.0 || f[2] != 0.0) count++;
    }
  }
  return count;
}

void InputFlags(const f64* pos, const f64* normal, const f64* area, const f64* vel, i64 n,
                bool* bad, bool* nonunit) {
  // Flat or-reductions: x * 0 is NaN exactly for a non-finite x.
  bool b = false;
  for (i64 j = 0; j < 3 * n; j++) b |= (pos[j] + normal[j] + vel[j]) * 0.0 != 0.0;
  for (i64 i = 0; i < n; i++) b |= (area[i] * 0.0 != 0.0) | (area[i] < 0.0);
  bool u = false;
  for (i64 i = 0; i < n; i++) {
    const f64* q = normal + 3 * i;
    f64 n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
    u |= std::fabs(n2 - 1.0) > kUnitNormalSlack;
  }
  *bad = b;
  *nonunit = u;
}

// The first element with a bad input: CheckedUnitNormals' code, its index in *index.
static int FirstBadInput(const f64* pos, const f64* normal, const f64* area, const f64* vel, i64 n,
                         i64* index) {
  for (i64 i = 0; i < n; i++) {
    *index = i;
    for (int c = 0; c < 3; c++) {
      if (!std::isfinite(pos[3 * i + c])) return kBadPos;
      if (!std::isfinite(normal[3 * i + c])) return kBadNormal;
      if (!std::isfinite(vel[3 * i + c])) return kBadVel;
    }
    if (!std::isfinite(area[i])) return kBadArea;
    if (area[i] < 0.0) return kNegativeArea;
    const f64* q = normal + 3 * i;
    if (q[0] == 0.0 && q[1] == 0.0 && q[2] == 0.0) return kZeroNormal;
  }
  *index = -1;
  return kInputOk;
}

int CheckedUnitNormals(const f64* pos, const f64* normal, const f64* area, const f64* vel, i64 n,
                       f64* n_hat, i64* index) {
  // One branch-free pass (a flag is or-ed); only inputs that fail it are searched for the first
  // culprit.
  bool bad = false;
  for (i64 i = 0; i < n; i++) {
    const f64* p = pos + 3 * i;
    const f64* v = vel + 3 * i;
    f64 x0 = normal[3 * i], y0 = normal[3 * i + 1], z0 = normal[3 * i + 2];
    f64 probe = (p[0] + p[1] + p[2]) * 0.0 + (v[0] + v[1] + v[2]) * 0.0;
    probe += (x0 + y0 + z0 + area[i]) * 0.0;
    f64 scale = law::Max(law::Max(std::fabs(x0), std::fabs(y0)), std::fabs(z0));
    bad |= (probe != 0.0) | (area[i] < 0.0) | (scale == 0.0);
    bool unit = std::fabs(x0 * x0 + y0 * y0 + z0 * z0 - 1.0) <= kUnitNormalSlack;
    f64 inv = 1.0 / scale;
    f64 x = x0 * inv, y = y0 * inv, z = z0 * inv;
    f64 q = 1.0 / std::sqrt(x * x + y * y + z * z);
    n_hat[3 * i] = unit ? x0 : x * q;
    n_hat[3 * i + 1] = unit ? y0 : y * q;
    n_hat[3 * i + 2] = unit ? z0 : z * q;
  }
  if (!bad) {
    *index = -1;
    return kInputOk;
  }
  return FirstBadInput(pos, normal, area, vel, n, index);
}

void Trajectory(const Elements& e, i64 n, const f64* co, i64 ncoef, f64 alpha_y, f64 zeta,
                f64 surface_z, const f64* rot, const f64* pos, const f64* lin_vel,
                const f64* ang_vel, const f64* point, i64 T, f64* out) {
  const f64 region[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  f64 prm[kPrmSize] = {};
  prm[surface::kZ0] = surface_z;
  const f64 grid[1] = {0.0};
  const Medium med = {co, ncoef, alpha_y, zeta, prm, grid, false, region};
  for (i64 i = 0; i < 6 * T; i++) out[i] = 0.0;
  for (i64 t = 0; t < T; t++) {
    BodyWrench(e, 0, n, med, grid, rot + 9 * t, pos + 3 * t, ang_vel + 3 * t, lin_vel + 3 * t,
               pos + 3 * t, point + 3 * t, out + 6 * t, nullptr, nullptr);
  }
}

}  // namespace mjrft::kernel
