// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "sensor.h"

#include <cmath>
#include <cstdio>
#include <string>

#include "granular.h"
#include "lowest.h"

namespace mjrft {
namespace {

// out (6) = the pure model's wrench on tagged geom g (this pass's element forces), world frame,
// torque about the point p (3).
void PureGeomWrench(const mjData* d, const Tables& t, const State& s, int g, const f64* p,
                    f64 out[6]) {
  for (int c = 0; c < 6; c++) out[c] = 0.0;
  if (s.cull[g]) return;
  i64 b = t.tbody_bodyid[t.tgeom_tbody[g]];
  const f64* R = d->xmat + 9 * b;
  const f64* x = d->xpos + 3 * b;
  for (i64 i = t.tgeom_elemadr[g]; i < t.tgeom_elemadr[g] + t.tgeom_elemnum[g]; i++) {
    const f64* e = t.elem_pos + 3 * i;
    const f64* f = s.elem_force + 3 * i;
    f64 r[3];
    for (int c = 0; c < 3; c++) {
      r[c] = x[c] + R[3 * c] * e[0] + R[3 * c + 1] * e[1] + R[3 * c + 2] * e[2] - p[c];
    }
    out[0] += f[0], out[1] += f[1], out[2] += f[2];
    out[3] += r[1] * f[2] - r[2] * f[1];
    out[4] += r[2] * f[0] - r[0] * f[2];
    out[5] += r[0] * f[1] - r[1] * f[0];
  }
}

// The local surface's height above tagged geom g's lowest point [m] (0 for a geom without one).
f64 TaggedSinkage(const mjModel* m, const mjData* d, const Tables& t, const State& s, int g) {
  f64 low[3];
  f64 depth = Sinkage(m, d, t, s.soil, static_cast<int>(t.tgeom_geomid[g]), low);
  return std::isnan(depth) ? 0.0 : depth;
}

f64 Norm3(const f64* v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

// The tagged index of MuJoCo geom `geom` in t, or -1.
int TaggedGeom(const Tables& t, int geom) {
  for (int g = 0; g < t.ntgeom; g++) {
    if (t.tgeom_geomid[g] == geom) return g;
  }
  return -1;
}

// Checks instance `instance`'s sensors: each on a geom, one that t tags where t is given.
// Returns false with the reason in error. (A model without an mjrft.granular instance passes:
// mjrft.add_granular compiles the model once before it adds one; its sensors read zeros.)
bool CheckSensors(const mjModel* m, int instance, const Tables* t, std::string* error) {
  for (int j = 0; j < m->nsensor; j++) {
    if (m->sensor_type[j] != mjSENS_PLUGIN || m->sensor_plugin[j] != instance) continue;
    const char* name = m->names + m->name_sensoradr[j];
    char msg[600];
    if (m->sensor_objtype[j] != mjOBJ_GEOM || m->sensor_objid[j] < 0) {
      std::snprintf(msg, sizeof(msg),
                    "%s sensor '%s': objtype must be \"geom\" with objname an intruder geom",
                    kSensorPluginName, name);
    } else if (t && TaggedGeom(*t, m->sensor_objid[j]) < 0) {
      int geom = m->sensor_objid[j];
      std::snprintf(msg, sizeof(msg),
                    "%s sensor '%s': geom '%s' (id %d) is not an intruder of the granular "
                    "medium; tag it (docs/mjcf.md, \"Tagging a robot\")",
                    kSensorPluginName, name, m->names + m->name_geomadr[geom], geom);
    } else {
      continue;
    }
    *error = msg;
    return false;
  }
  return true;
}

int NState(const mjModel* m, int instance) {
  (void)m, (void)instance;
  return 0;
}

int NSensorData(const mjModel* m, int instance, int sensor_id) {
  (void)m, (void)instance, (void)sensor_id;
  return kReadingSize;
}

int Init(const mjModel* m, mjData* d, int instance) {
  (void)d;
  int granular = GranularInstance(m);
  const Instance* in = granular >= 0 ? Instance::Find(d, granular) : nullptr;
  std::string error;
  if (!CheckSensors(m, instance, in ? &in->tables() : nullptr, &error)) {
    mju_warning("%s", error.c_str());
    return -1;
  }
  return 0;
}

void Compute(const mjModel* m, mjData* d, int instance, int capability_bit) {
  (void)capability_bit;
  int granular = GranularInstance(m);
  const Instance* in = granular >= 0 ? Instance::Find(d, granular) : nullptr;
  for (int j = 0; j < m->nsensor; j++) {
    if (m->sensor_type[j] != mjSENS_PLUGIN || m->sensor_plugin[j] != instance) continue;
    f64* out = d->sensordata + m->sensor_adr[j];
    int g = in ? TaggedGeom(in->tables(), m->sensor_objid[j]) : -1;
    if (g < 0) {  // no pass has run on d yet: nothing acted
      for (int c = 0; c < kReadingSize; c++) out[c] = 0.0;
      continue;
    }
    State st = in->Bind(m, d);
    GeomReading(m, d, in->tables(), st, g, out);
  }
}

}  // namespace

void GeomReading(const mjModel* m, const mjData* d, const Tables& t, State& s, int g,
                 f64 out[kReadingSize]) {
  // 1. the pure model's wrench on each geom of the body, about the body's centre of mass
  i64 k = t.tgeom_tbody[g];
  i64 b = t.tbody_bodyid[k];
  const f64* com = d->xipos + 3 * b;
  f64 body[6] = {0}, total = 0.0;
  int in_play = 0;
  for (i64 h = t.tbody_geomadr[k]; h < t.tbody_geomadr[k] + t.tbody_geomnum[k]; h++) {
    f64* w = s.geom_pure + 6 * h;
    if (s.geom_pure_pass[h] != s.pass[0]) {  // not evaluated: an RK4 stage, a body held again
      PureGeomWrench(d, t, s, static_cast<int>(h), com, w);
      s.geom_pure_pass[h] = s.pass[0];
    }
    for (int c = 0; c < 6; c++) body[c] += w[c];
    total += Norm3(w);
    in_play += !s.cull[h];
  }
  const f64* pure = s.geom_pure + 6 * g;

  // 2. the geom's share of what the treatment changed: as the pure forces share the body's
  //    load; where no pure force acts (a body held at rest), evenly among its geoms below the
  //    surface, else among those in play
  f64 share = 0.0;
  if (total > 0.0) {
    share = Norm3(pure) / total;
  } else {
    int below = 0;
    bool mine = false;
    for (i64 h = t.tbody_geomadr[k]; h < t.tbody_geomadr[k] + t.tbody_geomnum[k]; h++) {
      bool under = !s.cull[h] && TaggedSinkage(m, d, t, s, static_cast<int>(h)) > 0.0;
      below += under;
      mine = mine || (h == g && under);
    }
    if (below > 0) {
      share = mine ? 1.0 / below : 0.0;
    } else if (in_play && !s.cull[g]) {
      share = 1.0 / in_play;
    }
  }
  const f64* applied = s.wrench + 6 * b;
  f64 w[6];
  for (int c = 0; c < 6; c++) w[c] = pure[c] + share * (applied[c] - body[c]);

  // 3. torque about the geom's centre: T_x = T_com + (com - x) x F
  const f64* x = d->geom_xpos + 3 * t.tgeom_geomid[g];
  f64 r[3] = {com[0] - x[0], com[1] - x[1], com[2] - x[2]};
  out[0] = w[0], out[1] = w[1], out[2] = w[2];
  out[3] = w[3] + r[1] * w[2] - r[2] * w[1];
  out[4] = w[4] + r[2] * w[0] - r[0] * w[2];
  out[5] = w[5] + r[0] * w[1] - r[1] * w[0];

  // 4. sinkage: the local surface's height above the lowest point
  out[6] = TaggedSinkage(m, d, t, s, g);
}

void RegisterSensor() {
  int slot = -1;
  if (mjp_getPlugin(kSensorPluginName, &slot)) return;  // see RegisterGranular
  mjpPlugin plugin;
  mjp_defaultPlugin(&plugin);
  plugin.name = kSensorPluginName;
  plugin.capabilityflags = mjPLUGIN_SENSOR;
  // after mj_fwdVelocity, whose passive stage runs mjrft.granular's pass
  plugin.needstage = mjSTAGE_VEL;
  plugin.nstate = NState;
  plugin.nsensordata = NSensorData;
  plugin.init = Init;
  plugin.compute = Compute;
  mjp_registerPlugin(&plugin);
}

}  // namespace mjrft
