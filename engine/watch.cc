// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "watch.h"

#include <atomic>
#include <cmath>
#include <cstdio>

#include "lowest.h"
#include "surface.h"

namespace mjrft::watch {
namespace {

std::atomic<Handler> handler{nullptr};

}  // namespace

void SetHandler(Handler h) { handler.store(h); }

f64 Depth(const mjModel* m, const mjData* d, const Tables& t, const State& s, i64 w) {
  int geom = static_cast<int>(t.watch_geomid[w]);
  // 1. far above the surface (bounding sphere): not below it
  const f64* x = d->geom_xpos + 3 * geom;
  f64 r = m->geom_rbound[geom];
  if (r > 0.0 && x[2] - r >= surface::HighestNear(t.surface_prm, s.soil, x[0], x[1], r)) {
    return 0.0;
  }
  // 2. the lowest point, inside the region where one bounds the medium
  f64 low[3];
  f64 depth = Sinkage(m, d, t, s.soil, geom, low);
  if (std::isnan(depth)) return 0.0;
  if (t.use_region) {
    for (int c = 0; c < 3; c++) {
      if (low[c] < t.region[c] || low[c] > t.region[3 + c]) return 0.0;
    }
  }
  return depth;
}

void ReportSunk(const mjModel* m, const mjData* d, const Tables& t, State& s) {
  for (i64 w = 0; w < t.nwatch; w++) {
    if (s.watch_told[w]) continue;
    f64 depth = Depth(m, d, t, s, w);
    if (!(depth > 0.0)) continue;
    s.watch_told[w] = 1;
    int geom = static_cast<int>(t.watch_geomid[w]);
    int body = m->geom_bodyid[geom];
    const char* gname = m->names + m->name_geomadr[geom];
    char label[64];
    if (!*gname) std::snprintf(label, sizeof(label), "#%d", geom);
    f64 dt = m->opt.timestep;
    long long step = dt > 0 && std::isfinite(d->time) ? std::llrint(d->time / dt) : -1;
    char msg[800];
    std::snprintf(msg, sizeof(msg),
                  "geom '%s' of body '%s' is %.3g mm below the granular medium's surface at time "
                  "%.6g s (step %lld), but it is not an intruder: the medium does not act on it, "
                  "so it passes through unresisted. Tag it (docs/mjcf.md, \"Tagging a robot\"), "
                  "or turn this check off with SceneOptions(watch_sinking=False)",
                  *gname ? gname : label, m->names + m->name_bodyadr[body], depth * 1e3, d->time,
                  step);
    Handler h = handler.load();
    if (h) {
      h(msg);
    } else {
      mju_warning("%s", msg);
    }
  }
}

}  // namespace mjrft::watch
