// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "evaluate.h"

#include <cmath>

#include "kernel.h"
#include "mechanism.h"
#include "surface.h"

namespace mjrft {

int FirstBadBody(const mjModel* m, const mjData* d, const Tables& t) {
  (void)m;
  for (int k = 0; k < t.ntbody; k++) {
    i64 b = t.tbody_bodyid[k];
    for (int c = 0; c < 3; c++) {
      if (!std::isfinite(d->xpos[3 * b + c])) return k;
    }
    for (int c = 0; c < 6; c++) {
      if (!std::isfinite(d->cvel[6 * b + c])) return k;
    }
  }
  return -1;
}

f64 GeomTop(const mjData* d, const Tables& t, const State& s, int g) {
  f64 r = t.tgeom_rbound[g];
  if (r <= 0.0) return surface::Ceiling(t.surface_prm, s.soil);
  const f64* x = d->geom_xpos + 3 * t.tgeom_geomid[g];
  return surface::HighestNear(t.surface_prm, s.soil, x[0], x[1], r);
}

bool Culled(const mjData* d, const Tables& t, const State& s, int g) {
  f64 r = t.tgeom_rbound[g];
  if (r <= 0.0) return false;
  const f64* x = d->geom_xpos + 3 * t.tgeom_geomid[g];
  if (x[2] - r >= GeomTop(d, t, s, g)) return true;
  if (t.use_region) {
    for (int c = 0; c < 3; c++) {
      if (x[c] + r < t.region[c] || x[c] - r > t.region[3 + c]) return true;
    }
  }
  return false;
}

// Adds to wrench (6) the RFT wrench on tagged geom g at its body's pose (kernel::BodyWrench).
static int GeomWrench(const mjData* d, const Tables& t, const State& s, int g, const f64* omega,
                      const f64* v_ref, const f64* p_ref, const f64* com, f64* wrench,
                      f64* elem_force) {
  i64 b = t.tbody_bodyid[t.tgeom_tbody[g]];
  i64 start = t.tgeom_elemadr[g];
  i64 stop = start + t.tgeom_elemnum[g];
  kernel::Medium med = kernel::MediumOf(t, s);
  med.body = static_cast<f64>(t.tgeom_tbody[g] + 1);
  return kernel::BodyWrench(kernel::ElementsOf(t), start, stop, med, s.soil, d->xmat + 9 * b,
                            d->xpos + 3 * b, omega, v_ref, p_ref, com, wrench, elem_force, nullptr);
}

int TwistWrench(const mjModel* m, const mjData* d, const Tables& t, State& s, int k, const f64* v,
                const f64* omega, f64* out, int* acting) {
  (void)m;
  for (int c = 0; c < 6; c++) out[c] = 0.0;
  i64 b = t.tbody_bodyid[k];
  const f64* com = d->xipos + 3 * b;
  int evaluated = 0, act = 0;
  for (i64 g = t.tbody_geomadr[k]; g < t.tbody_geomadr[k] + t.tbody_geomnum[k]; g++) {
    if (s.cull[g]) continue;
    act += GeomWrench(d, t, s, g, omega, v, com, com, out, nullptr);
    evaluated += t.tgeom_elemnum[g];
  }
  if (acting) *acting = act;
  return evaluated;
}

bool InPlay(const Tables& t, const State& s, int k) {
  for (i64 g = t.tbody_geomadr[k]; g < t.tbody_geomadr[k] + t.tbody_geomnum[k]; g++) {
    if (!s.cull[g]) return true;
  }
  return false;
}

int BodyPure(const mjData* d, const Tables& t, State& s, int k, int* acting) {
  i64 b = t.tbody_bodyid[k];
  const f64* cvel = d->cvel + 6 * b;
  f64* w = s.wrench + 6 * b;
  int evaluated = 0, act = 0;
  for (i64 g = t.tbody_geomadr[k]; g < t.tbody_geomadr[k] + t.tbody_geomnum[k]; g++) {
    if (s.cull[g]) continue;
    f64* pure = s.geom_pure + 6 * g;
    f64 before[6];
    for (int c = 0; c < 6; c++) before[c] = w[c];
    act += GeomWrench(d, t, s, static_cast<int>(g), cvel, cvel + 3,
                      d->subtree_com + 3 * t.tbody_rootid[k], d->xipos + 3 * b, w, s.elem_force);
    // The geom's share for the sensors (sensor.h): what it added to its body's sum.
    for (int c = 0; c < 6; c++) pure[c] = w[c] - before[c];
    s.geom_pure_pass[g] = s.pass[0];
    evaluated += static_cast<int>(t.tgeom_elemnum[g]);
  }
  s.lazy[k] = 0;
  if (acting) *acting += act;
  return evaluated;
}

int PureWrenches(const mjModel* m, const mjData* d, const Tables& t, State& s, int* acting,
                 bool defer_held) {
  (void)m;
  for (int k = 0; k < t.ntbody; k++) {
    s.lazy[k] = 0;
    if (!s.keep[k]) {
      f64* w = s.wrench + 6 * t.tbody_bodyid[k];
      for (int c = 0; c < 6; c++) w[c] = 0.0;
    }
  }
  for (int g = 0; g < t.ntgeom; g++) {
    i64 k = t.tgeom_tbody[g];
    if (s.keep[k]) continue;
    if (Culled(d, t, s, g)) {
      s.cull[g] = 1;
      if (s.geom_dirty[g]) {
        f64* f = s.elem_force + 3 * t.tgeom_elemadr[g];
        for (i64 i = 0; i < 3 * t.tgeom_elemnum[g]; i++) f[i] = 0.0;
        s.geom_dirty[g] = 0;
      }
      f64* pure = s.geom_pure + 6 * g;
      for (int c = 0; c < 6; c++) pure[c] = 0.0;
      s.geom_pure_pass[g] = s.pass[0];
      continue;
    }
    s.geom_dirty[g] = 1;
  }
  int evaluated = 0;
  if (acting) *acting = 0;
  for (int k = 0; k < t.ntbody; k++) {
    if (s.keep[k] || s.frz[k]) continue;
    if (defer_held && t.tbody_mech[k] && mechanism::HeldBefore(d, s, k)) {
      s.lazy[k] = 1;
      continue;
    }
    evaluated += BodyPure(d, t, s, k, acting);
  }
  return evaluated;
}

}  // namespace mjrft
