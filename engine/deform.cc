// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "deform.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "evaluate.h"
#include "lowspeed.h"
#include "soil.h"
#include "surface.h"

namespace mjrft::deform {
namespace {

// An empty vertex box's bounds (the largest int32, as a double).
constexpr f64 kBig = static_cast<f64>(INT32_MAX);

void Empty(f64* box) {
  box[0] = kBig;
  box[1] = -1.0;
  box[2] = kBig;
  box[3] = -1.0;
}

// Rasterises every tagged body's geoms that may touch the medium below top [m]; box k of
// s.soil_box is body k's footprint, row nk their union.
void Footprints(const mjData* d, const Tables& t, State& s, f64 top) {
  i64 nk = t.ntbody;
  f64* allbox = s.soil_box + 4 * nk;
  Empty(allbox);
  for (i64 k = 0; k < nk; k++) {
    f64* kb = s.soil_box + 4 * k;
    Empty(kb);
    i64 b = t.tbody_bodyid[k];
    for (i64 g = t.tbody_geomadr[k]; g < t.tbody_geomadr[k] + t.tbody_geomnum[k]; g++) {
      if (Culled(d, t, s, static_cast<int>(g))) continue;
      i64 start = t.tgeom_elemadr[g];
      s.soil_stats[soil::kStatRasterised] +=
          soil::Footprint(t.surface_prm, t.elem_vert, start, start + t.tgeom_elemnum[g],
                          d->xmat + 9 * b, d->xpos + 3 * b, k, s.soil_floor, s.soil_owner, kb, top);
    }
    soil::Union(allbox, kb[0], kb[1], kb[2], kb[3]);
  }
}

// Grows box by the vertex box stored at block[at..at + 3] (r0, r1 + 1, c0, c1 + 1; empty when
// r1 + 1 <= r0, as all zeros are after mj_resetData).
void HeadUnion(f64* box, const f64* block, int at) {
  if (block[at + 1] > block[at] && block[at + 3] > block[at + 2]) {
    soil::Union(box, block[at], block[at + 1] - 1, block[at + 2], block[at + 3] - 1);
  }
}

// Stores vertex box (4) (r0, r1, c0, c1) at block[at..at + 3]; an empty box, or any box if not
// keep, as zeros.
void HeadStore(f64* block, int at, const f64* box, bool keep) {
  if (keep && box[0] <= box[1] && box[2] <= box[3]) {
    block[at] = box[0];
    block[at + 1] = box[1] + 1;
    block[at + 2] = box[2];
    block[at + 3] = box[3] + 1;
  } else {
    block[at] = block[at + 1] = block[at + 2] = block[at + 3] = 0.0;
  }
}

// The fastest speed [m/s] of a point of a tagged geom that may touch the medium: its centre's
// speed plus its angular speed times its bounding radius (cvel: angular velocity, then the
// velocity of the point at the root's subtree CoM; world frame).
f64 IntruderSpeed(const mjData* d, const Tables& t, const State& s) {
  f64 fastest = 0.0;
  for (int g = 0; g < t.ntgeom; g++) {
    if (Culled(d, t, s, g)) continue;
    i64 k = t.tgeom_tbody[g];
    const f64* om = d->cvel + 6 * t.tbody_bodyid[k];
    f64 v[3];
    lowspeed::PointVelocity(d, t, static_cast<int>(k), d->geom_xpos + 3 * t.tgeom_geomid[g], v);
    f64 spin = std::sqrt(om[0] * om[0] + om[1] * om[1] + om[2] * om[2]);
    fastest = std::max(
        fastest, std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + spin * t.tgeom_rbound[g]);
  }
  return fastest;
}

}  // namespace

bool Due(const mjModel* m, const mjData* d, const Tables& t, State& s) {
  f64* block = s.soil;
  const f64* prm = t.surface_prm;
  f64 now = d->time, last = block[surface::kSoilTime];
  if (block[surface::kSoilDone] == 0.0 || now < last) return true;
  f64 every = prm[surface::kEvery];
  if (every >= 1.0) {
    if (every == 1.0) return last != now;
    return now - last > (every - 0.5) * m->opt.timestep;
  }
  f64 limit = prm[surface::kTravel] * std::min(prm[surface::kDx], prm[surface::kDy]);
  const f64* pending = block + surface::kSoilPending;  // slopes the last update left to relax
  bool relaxing = pending[1] > pending[0] && pending[3] > pending[2];
  if (!(limit > 0.0) || relaxing) return last != now;
  f64 clock = block[surface::kSoilClock];
  if (now > clock) {
    block[surface::kSoilTravel] += IntruderSpeed(d, t, s) * (now - std::max(clock, last));
    block[surface::kSoilClock] = now;
  }
  return block[surface::kSoilTravel] >= limit;
}

int Update(const mjModel* m, const mjData* d, const Tables& t, State& s) {
  (void)m;
  const f64* prm = t.surface_prm;
  const f64* grid = t.surface_grid;
  f64* block = s.soil;
  i64 nk = t.ntbody;
  // Rows of s.soil_box (deform.h): the footprints of the last update and the fingerprint of the
  // state they belong to, kept in the work arrays between updates.
  f64* prev = s.soil_box + 4 * (nk + 1);
  f64* print = s.soil_box + 4 * (2 * nk + 1);
  f64* sweep = s.soil_box + 4 * (2 * nk + 2);
  const bool known = print[3] == 1.0 && block[surface::kSoilDone] == 1.0 &&
                     print[0] == s.soil_stats[soil::kStatUpdates] &&
                     print[1] == s.soil_stats[soil::kStatExcavated] &&
                     print[2] == block[surface::kSoilTime];
  // The last update's press marks, within its footprints' box, which the state keeps.
  const f64* foot = block + surface::kSoilFoot;
  if (foot[1] > foot[0] && foot[3] > foot[2]) {
    soil::Unmark(prm, block, static_cast<i64>(foot[0]), static_cast<i64>(foot[1]) - 1,
                 static_cast<i64>(foot[2]), static_cast<i64>(foot[3]) - 1);
  }
  Footprints(d, t, s, surface::Ceiling(prm, block));
  const f64* allbox = s.soil_box + 4 * nk;

  // Excavation and deposition, intruder by intruder.
  int bad = -1;
  for (i64 k = 0; k < nk; k++) {
    const f64* kb = s.soil_box + 4 * k;
    if (kb[0] > kb[1]) continue;
    i64 b = t.tbody_bodyid[k];
    i64 root = t.tbody_rootid[k];
    f64 twist[9];
    for (int c = 0; c < 3; c++) {  // cvel: (omega, v at the root's subtree CoM), world frame
      twist[c] = d->cvel[6 * b + 3 + c];
      twist[3 + c] = d->cvel[6 * b + c];
      twist[6 + c] = d->subtree_com[3 * root + c];
    }
    soil::Cut cut = soil::Excavate(prm, grid, block, s.soil_floor, s.soil_owner, kb, k, twist,
                                   t.region[2], s.soil_stats);
    if (cut.vol < 0.0) {
      bad = static_cast<int>(k);
    } else if (cut.vol > 0.0) {
      soil::Deposit(prm, grid, block, s.soil_floor, s.soil_owner, kb, k, cut.vol, cut.mx, cut.my,
                    cut.v, s.soil_stats, s.soil_queue);
    }
  }

  // Relax where each intruder is and where it was at the last update (a withdrawn rod leaves a
  // hole to slump), one box each, and where the last update left slopes unrelaxed. Where the
  // last footprints are not known (a state this mjData's updates did not write: a reset, a
  // restored or copied state), the box spanning them all, which the state keeps.
  for (i64 k = 0; k < nk; k++) {
    f64* box = sweep + 4 * k;
    Empty(box);
    const f64* kb = s.soil_box + 4 * k;
    soil::Union(box, kb[0], kb[1], kb[2], kb[3]);
    if (known) soil::Union(box, prev[4 * k], prev[4 * k + 1], prev[4 * k + 2], prev[4 * k + 3]);
  }
  f64* extra = sweep + 4 * nk;
  Empty(extra);
  Empty(extra + 4);
  HeadUnion(extra, block, surface::kSoilPending);
  if (!known) HeadUnion(extra + 4, block, surface::kSoilFoot);
  HeadStore(block, surface::kSoilFoot, allbox, true);
  s.soil_stats[soil::kStatUpdates] += 1;
  for (i64 b = 0; b < nk + 2; b++) {
    f64* box = sweep + 4 * b;
    if (box[0] > box[1]) continue;
    box[0] -= 1;
    box[1] += 1;
    box[2] -= 1;
    box[3] += 1;
  }
  f64 pending[4];
  f64 top = -std::numeric_limits<f64>::infinity();
  bool converged = soil::Relax(prm, grid, block, s.soil_floor, s.soil_owner, s.soil_queue, sweep,
                               nk + 2, pending, &top, s.soil_stats);
  HeadStore(block, surface::kSoilPending, pending, !converged);
  soil::Mark(prm, grid, block, s.soil_floor, s.soil_owner, s.soil_box, nk);
  soil::Finish(prm, grid, block, s.soil_floor, s.soil_owner, s.soil_box, nk, top, d->time);
  for (i64 c = 0; c < 4 * nk; c++) prev[c] = s.soil_box[c];
  print[0] = s.soil_stats[soil::kStatUpdates];
  print[1] = s.soil_stats[soil::kStatExcavated];
  print[2] = block[surface::kSoilTime];
  print[3] = 1.0;
  block[surface::kSoilTravel] = 0.0;
  block[surface::kSoilClock] = d->time;
  return bad;
}

}  // namespace mjrft::deform
