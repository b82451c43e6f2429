// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "granular.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <shared_mutex>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <utility>

#include <mujoco/mjplugin.h>
#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

#include "forward.h"
#include "watch.h"

namespace mjrft {
namespace {

// The custom numeric field "mjrft.granular:<name>" of m: its data and size, or nullptr.
const f64* Numeric(const mjModel* m, const char* name, int* size) {
  std::string full = std::string(kTablePrefix) + name;
  for (int i = 0; i < m->nnumeric; i++) {
    if (full == m->names + m->name_numericadr[i]) {
      *size = m->numeric_size[i];
      return m->numeric_data + m->numeric_adr[i];
    }
  }
  *size = 0;
  return nullptr;
}

std::string Missing(const char* what) {
  return std::string(kPluginName) + ": the model has no " + kTablePrefix + what +
         " table: load it with mjrft.load_model(path_or_xml), or add the tables to an MjSpec "
         "with mjrft.add_granular(spec), before compiling";
}

// The instance's persistent arrays are laid out in this order in plugin_state.
template <typename F>
void ForEachPersistent(const Sizes& n, F&& f) {
  const i64 nbody = n.nbody, nv = n.nv, nu = n.nu, nk = n.nk, ng = n.ng, nsoil = n.nsoil;
  (void)nbody, (void)nv, (void)nu, (void)nk, (void)ng, (void)nsoil;
#define MJRFT_X(type, name, size, doc) f(&State::name, static_cast<i64>(size));
  MJRFT_STATE_PERSISTENT(MJRFT_X)
#undef MJRFT_X
}

// Assigns a pointer member of State, whatever its element type.
void SetPointer(State* s, f64* State::* member, void* p) { s->*member = static_cast<f64*>(p); }
void SetPointer(State* s, i64* State::* member, void* p) { s->*member = static_cast<i64*>(p); }

// The sizes that fix the state's layout, from the instance's config: MuJoCo asks nstate while
// compiling, before the model's custom numeric fields hold their data, so the loader writes
// these three sizes into the config too (init checks them against the tables).
bool ConfigSizes(const mjModel* m, int instance, Sizes* n, std::string* error) {
  i64 v[3];
  const char* keys[3] = {"ntbody", "ntgeom", "nsoil"};
  for (int i = 0; i < 3; i++) {
    const char* text = mj_getPluginConfig(m, instance, keys[i]);
    char* end = nullptr;
    v[i] = text ? std::strtoll(text, &end, 10) : -1;
    if (!text || end == text || *end != '\0' || v[i] < 0) {
      *error = std::string(kPluginName) + ": config '" + keys[i] + "' must be a count, got '" +
               (text ? text : "") + "': load the model with mjrft.load_model(path_or_xml)";
      return false;
    }
  }
  *n = {m->nbody, m->nv, m->nu, 0, v[1], v[0], v[2], 1, 1, 0};
  return true;
}

}  // namespace

bool Instance::ReadHead(const mjModel* m, Tables* t, std::string* error) {
  int size = 0;
  const f64* format = Numeric(m, "format", &size);
  if (!format) {
    *error = Missing("format");
    return false;
  }
  if (size != 1 || format[0] != kTableFormat) {
    *error = std::string(kPluginName) + ": the model's tables have format " +
             (size ? std::to_string(static_cast<int>(format[0])) : "?") + ", this engine reads " +
             std::to_string(kTableFormat) + ": reload the model with this version of mjrft";
    return false;
  }
  int nsize = 0, nscalar = 0;
  const f64* sizes = Numeric(m, "sizes", &nsize);
  const f64* scalars = Numeric(m, "scalars", &nscalar);
  if (!sizes || !scalars) {
    *error = Missing(sizes ? "scalars" : "sizes");
    return false;
  }
  int i = 0;
#define MJRFT_X(name) t->name = i < nsize ? static_cast<i64>(sizes[i]) : -1, i++;
  MJRFT_TABLE_SIZES(MJRFT_X)
#undef MJRFT_X
  int j = 0;
#define MJRFT_X(type, name, doc) t->name = j < nscalar ? static_cast<type>(scalars[j]) : 0, j++;
  MJRFT_TABLE_SCALARS(MJRFT_X)
#undef MJRFT_X
  if (i != nsize || j != nscalar) {
    bool bad_sizes = i != nsize;
    *error = std::string(kPluginName) + ": the " + (bad_sizes ? "sizes" : "scalars") +
             " table has " + std::to_string(bad_sizes ? nsize : nscalar) + " entries, expected " +
             std::to_string(bad_sizes ? i : j);
    return false;
  }
  return true;
}

i64 Instance::StateSize(const Sizes& n) {
  i64 total = 0;
  ForEachPersistent(n, [&](auto, i64 size) { total += size; });
  return total;
}

std::unique_ptr<Instance> Instance::Create(const mjModel* m, int instance, std::string* error) {
  auto out = std::unique_ptr<Instance>(new (std::nothrow) Instance());
  if (!out) {
    *error = std::string(kPluginName) + ": out of memory";
    return nullptr;
  }
  out->instance_ = instance;
  Tables& t = out->tables_;

  // 1. sizes and scalars, and the state's sizes from them
  if (!ReadHead(m, &t, error)) return nullptr;
  Sizes& n = out->sizes_;
  n = {m->nbody,
       m->nv,
       m->nu,
       t.nelem,
       t.ntgeom,
       t.ntbody,
       t.nsoil,
       t.soil ? t.surface_nrow : 1,
       t.soil ? t.surface_ncol : 1,
       t.nwatch};

  // 2. arrays: f64 tables are read in place from the model, i64 tables converted once
  const i64 nelem = t.nelem, ntgeom = t.ntgeom, ntbody = t.ntbody, ncoef = t.ncoef;
  const i64 surface_nrow = t.surface_nrow, surface_ncol = t.surface_ncol, nvert = t.nvert;
  const i64 nv = m->nv, nu = m->nu, nwatch = t.nwatch;
  (void)nelem, (void)ntgeom, (void)ntbody, (void)ncoef, (void)surface_nrow, (void)surface_ncol;
  (void)nvert, (void)nv, (void)nu, (void)nwatch;
  i64 nint = 0;
#define MJRFT_X(type, name, count, doc) \
  if (std::is_same<type, i64>::value) nint += static_cast<i64>(count);
  MJRFT_TABLE_ARRAYS(MJRFT_X)
#undef MJRFT_X
  out->ints_.assign(nint, 0);
  i64 next = 0;
  std::string bad;
  auto place = [&](const char* name, i64 count, const f64** f, const i64** k) {
    int have = 0;
    const f64* data = Numeric(m, name, &have);
    if (!data && count > 0) {
      bad = Missing(name);
      return;
    }
    // MuJoCo's numeric fields hold at least one value: an empty table is stored as one 0
    if (have != count && !(count == 0 && have == 1) && bad.empty()) {
      bad = std::string(kPluginName) + ": table " + kTablePrefix + name + " has " +
            std::to_string(have) + " values, expected " + std::to_string(count) +
            " (was the model edited after its tables were written? reload it)";
      return;
    }
    if (f) *f = data;
    if (k) {
      i64* dst = out->ints_.data() + next;
      for (i64 c = 0; c < count; c++) dst[c] = static_cast<i64>(data[c]);
      *k = dst;
      next += count;
    }
  };
#define MJRFT_X(type, name, count, doc)                                                     \
  if constexpr (std::is_same<type, i64>::value) {                                           \
    place(#name, static_cast<i64>(count), nullptr, reinterpret_cast<const i64**>(&t.name)); \
  } else {                                                                                  \
    place(#name, static_cast<i64>(count), reinterpret_cast<const f64**>(&t.name), nullptr); \
  }
  MJRFT_TABLE_ARRAYS(MJRFT_X)
#undef MJRFT_X
  if (!bad.empty()) {
    *error = bad;
    return nullptr;
  }

  // 3. the config the state was sized by agrees, references into the model are in range
  Sizes config;
  if (!ConfigSizes(m, instance, &config, error)) return nullptr;
  if (config.nk != t.ntbody || config.ng != t.ntgeom || config.nsoil != t.nsoil) {
    *error = std::string(kPluginName) + ": config (ntbody, ntgeom, nsoil) = (" +
             std::to_string(config.nk) + ", " + std::to_string(config.ng) + ", " +
             std::to_string(config.nsoil) + ") disagrees with the tables (" +
             std::to_string(t.ntbody) + ", " + std::to_string(t.ntgeom) + ", " +
             std::to_string(t.nsoil) + "): reload the model with mjrft.load_model";
    return nullptr;
  }
  for (i64 g = 0; g < t.ntgeom; g++) {
    if (t.tgeom_geomid[g] < 0 || t.tgeom_geomid[g] >= m->ngeom) {
      *error = std::string(kPluginName) + ": tagged geom " + std::to_string(g) + " has id " +
               std::to_string(t.tgeom_geomid[g]) + ", the model has " + std::to_string(m->ngeom) +
               " geoms: reload the model";
      return nullptr;
    }
  }
  for (i64 w = 0; w < t.nwatch; w++) {
    if (t.watch_geomid[w] < 0 || t.watch_geomid[w] >= m->ngeom) {
      *error = std::string(kPluginName) + ": watched geom " + std::to_string(w) + " has id " +
               std::to_string(t.watch_geomid[w]) + ", the model has " + std::to_string(m->ngeom) +
               " geoms: reload the model";
      return nullptr;
    }
  }
  for (i64 k = 0; k < t.ntbody; k++) {
    if (t.tbody_bodyid[k] <= 0 || t.tbody_bodyid[k] >= m->nbody) {
      *error = std::string(kPluginName) + ": tagged body " + std::to_string(k) + " has id " +
               std::to_string(t.tbody_bodyid[k]) + ", the model has " + std::to_string(m->nbody) +
               " bodies: reload the model";
      return nullptr;
    }
  }

  // 4. work arrays
  const i64 nbody = n.nbody, nk = n.nk, ng = n.ng, soil_nrow = n.soil_nrow;
  const i64 soil_ncol = n.soil_ncol;
  (void)nbody, (void)nk, (void)ng, (void)soil_nrow, (void)soil_ncol;
  i64 nf = 0, ni = 0;
#define MJRFT_X(type, name, count, doc) \
  (std::is_same<type, i64>::value ? ni : nf) += static_cast<i64>(count);
  MJRFT_STATE_WORK(MJRFT_X)
#undef MJRFT_X
  out->work_.assign(nf, 0.0);
  out->iwork_.assign(ni, 0);
  nf = ni = 0;
#define MJRFT_X(type, name, count, doc)                                   \
  if constexpr (std::is_same<type, i64>::value) {                         \
    SetPointer(&out->work_state_, &State::name, out->iwork_.data() + ni); \
    ni += static_cast<i64>(count);                                        \
  } else {                                                                \
    SetPointer(&out->work_state_, &State::name, out->work_.data() + nf);  \
    nf += static_cast<i64>(count);                                        \
  }
  MJRFT_STATE_WORK(MJRFT_X)
#undef MJRFT_X
  out->ResetCaches();
  for (i64 i = 0; i < 6 * n.nbody; i++) out->work_state_.xfrc_last[i] = NAN;
  return out;
}

i64 Instance::ArraySize(const char* name) const {
  const Sizes& n = sizes_;
  const i64 nbody = n.nbody, nv = n.nv, nu = n.nu, nelem = n.nelem, ng = n.ng, nk = n.nk;
  const i64 nsoil = n.nsoil, soil_nrow = n.soil_nrow, soil_ncol = n.soil_ncol;
  const i64 nwatch = n.nwatch;
  (void)nbody, (void)nv, (void)nu, (void)nelem, (void)ng, (void)nk, (void)nsoil;
  (void)soil_nrow, (void)soil_ncol, (void)nwatch;
#define MJRFT_X(type, field, size, doc) \
  if (std::strcmp(name, #field) == 0) return static_cast<i64>(size);
  MJRFT_STATE_ARRAYS(MJRFT_X)
#undef MJRFT_X
  return -1;
}

State Instance::Bind(const mjModel* m, mjData* d) const {
  State s = work_state_;
  f64* p = d->plugin_state + m->plugin_stateadr[instance_];
  ForEachPersistent(sizes_, [&](auto member, i64 size) {
    SetPointer(&s, member, p);
    p += size;
  });
  return s;
}

void Instance::ResetState(const mjModel* m, int instance, f64* plugin_state) {
  Sizes n;
  std::string error;
  if (!ConfigSizes(m, instance, &n, &error)) return;  // init refused this model already
  std::memset(plugin_state, 0, sizeof(f64) * StateSize(n));
  // every geom may hold element forces (they are zeroed when it is culled)
  i64 offset = 0;
  ForEachPersistent(n, [&](auto member, i64 size) {
    if constexpr (std::is_same<decltype(member), i64 * State::*>::value) {
      if (member == &State::geom_dirty) {
        i64* dirty = reinterpret_cast<i64*>(plugin_state + offset);
        for (i64 g = 0; g < size; g++) dirty[g] = 1;
      }
    }
    offset += size;
  });
}

void Instance::ResetCaches() {
  // the caches hold nothing, the ground's work grids are empty
  State& w = work_state_;
  const i64 nv = sizes_.nv, nk = sizes_.nk, cells = sizes_.soil_nrow * sizes_.soil_ncol;
  for (i64 i = 0; i < 1 + nk + 6 * nv + 6 * nk; i++) w.mech_cfg[i] = -1.0;
  for (i64 i = 0; i < 1 + 6 * nk; i++) w.mech_hkey[i] = -2;
  for (i64 g = 0; g < sizes_.ng; g++) w.geom_pure_pass[g] = -1;
  for (i64 i = 0; i < 2 * sizes_.nelem; i++) w.elem_depth_pass[i] = -1;
  for (i64 i = 0; i < cells; i++) {
    w.soil_floor[i] = INFINITY;
    w.soil_owner[i] = -1;
  }
}

namespace {

// Subnormal numbers flushed to zero for the length of a pass, the caller's floating-point mode
// restored after it. Why: a body the treatment holds keeps a residue of its twist of ~1e-318
// (the stick cancels it to rounding), and arithmetic on subnormals costs ~100x on x86: a resting
// sphere's steps took 1.9 ms instead of 80 us. Values below 2.2e-308 carry no physics.
class FlushSubnormals {
 public:
  FlushSubnormals() {
#if defined(__SSE2__)
    saved_ = _mm_getcsr();
    _mm_setcsr(saved_ | 0x8040);  // FTZ (bit 15) and DAZ (bit 6)
#endif
  }
  ~FlushSubnormals() {
#if defined(__SSE2__)
    _mm_setcsr(saved_);
#endif
  }
  FlushSubnormals(const FlushSubnormals&) = delete;
  FlushSubnormals& operator=(const FlushSubnormals&) = delete;

 private:
  unsigned saved_ = 0;
};

}  // namespace

i64 Instance::Run(const mjModel* m, mjData* d, int mode) {
  FlushSubnormals flush;
  State s = Bind(m, d);
  // The counters change in every evaluating pass: other values than this instance left are
  // another writer's (mj_resetData, mj_setState, mj_copyData, a pickled mjData).
  bool ours = s.stats[0] == seen_[0] && s.stats[1] == seen_[1] && s.stats[2] == seen_[2];
  if (!ours) {
    ResetCaches();
    s.mech_time[1] = 0.0;  // no previous pass this instance knows of: no predictor
  }
  i64 status = Forward(m, d, tables_, s, mode);
  for (int i = 0; i < 3; i++) seen_[i] = s.stats[i];
  if (status == kOk && mode == kInstalled) watch::ReportSunk(m, d, tables_, s);
  return status;
}

void Instance::CopyFrom(const Instance& src) {
  for (int i = 0; i < 3; i++) seen_[i] = src.seen_[i];
  work_ = src.work_;  // same sizes: the views in work_state_ stay valid
  iwork_ = src.iwork_;
}

namespace {

// The live instances and the mjData each was made for. Read in every pass (shared lock), written
// when an mjData is made, freed, or found holding another mjData's instance.
std::shared_mutex registry_mutex;
std::unordered_map<const Instance*, const mjData*>& Registry() {
  static auto* registry = new std::unordered_map<const Instance*, const mjData*>();
  return *registry;
}

}  // namespace

void Instance::Adopt(std::unique_ptr<Instance> in, mjData* d, int instance) {
  std::unique_lock lock(registry_mutex);
  Registry()[in.get()] = d;
  d->plugin_data[instance] = reinterpret_cast<uintptr_t>(in.release());
}

void Instance::Release(mjData* d, int instance) {
  auto* in = reinterpret_cast<Instance*>(d->plugin_data[instance]);
  d->plugin_data[instance] = 0;
  std::unique_lock lock(registry_mutex);
  auto it = Registry().find(in);
  if (it == Registry().end() || it->second != d) return;  // another mjData's: not ours to free
  Registry().erase(it);
  lock.unlock();
  delete in;
}

Instance* Instance::Find(const mjData* d, int instance) {
  auto* in = reinterpret_cast<Instance*>(d->plugin_data[instance]);
  std::shared_lock lock(registry_mutex);
  auto it = Registry().find(in);
  return it != Registry().end() && it->second == d ? in : nullptr;
}

Instance* Instance::Of(const mjModel* m, mjData* d, int instance, std::string* error) {
  auto* in = reinterpret_cast<Instance*>(d->plugin_data[instance]);
  {
    std::shared_lock lock(registry_mutex);
    auto it = Registry().find(in);
    if (it != Registry().end() && it->second == d) return in;
  }
  std::unique_ptr<Instance> fresh = Create(m, instance, error);
  if (!fresh) return nullptr;
  Instance* out = fresh.get();
  Adopt(std::move(fresh), d, instance);
  return out;
}

namespace {

int NState(const mjModel* m, int instance) {
  Sizes n;
  std::string error;
  if (!ConfigSizes(m, instance, &n, &error)) return 0;  // init reports the reason
  return static_cast<int>(Instance::StateSize(n));
}

int Init(const mjModel* m, mjData* d, int instance) {
  std::string error;
  std::unique_ptr<Instance> in = Instance::Create(m, instance, &error);
  if (!in) {
    mju_warning("%s", error.c_str());
    return -1;
  }
  Instance::ResetState(m, instance, d->plugin_state + m->plugin_stateadr[instance]);
  Instance::Adopt(std::move(in), d, instance);
  return 0;
}

void Destroy(mjData* d, int instance) { Instance::Release(d, instance); }

void Copy(mjData* dest, const mjModel* m, const mjData* src, int instance) {
  const Instance* from = Instance::Find(src, instance);
  std::string error;
  Instance* to = Instance::Of(m, dest, instance, &error);
  if (from && to) to->CopyFrom(*from);
}

void Reset(const mjModel* m, mjtNum* plugin_state, void* plugin_data, int instance) {
  (void)plugin_data;  // the caches are emptied at the next pass (State::stamp is zeroed)
  Instance::ResetState(m, instance, plugin_state);
}

// The message of a failed pass, naming the body and the time in the words of the Python field's
// errors.
void StatusMessage(const mjModel* m, const mjData* d, const Tables& t, i64 status, char* msg,
                   int size) {
  f64 dt = m->opt.timestep;
  long long step =
      dt > 0 && std::isfinite(d->time) ? std::llrint(std::nearbyint(d->time / dt)) : -1;
  if (status <= kBelowGround) {
    i64 b = t.tbody_bodyid[kBelowGround - status];
    std::snprintf(msg, size,
                  "body '%s' reaches below the bottom of the deforming ground (mjrft:region "
                  "zmin = %g m) at time %.6g s (step %lld): the ground is excavated from above, "
                  "so an intruder must enter it from above its surface; lower the region's zmin "
                  "or start the body above the ground",
                  m->names + m->name_bodyadr[b], t.region[2], d->time, step);
  } else {
    i64 b = t.tbody_bodyid[-1 - status];
    std::snprintf(msg, size,
                  "body '%s' has a non-finite position or velocity at time %.6g s (step %lld); "
                  "the granular field refuses to feed NaN forward (check the timestep and "
                  "actuators)",
                  m->names + m->name_bodyadr[b], d->time, step);
  }
}

// One installed pass on d; false with the reason in msg.
bool Pass(const mjModel* m, mjData* d, int instance, char* msg, int size) {
  std::string error;
  Instance* in = Instance::Of(m, d, instance, &error);
  if (!in) {  // init failed and said why; MuJoCo's compiler steps such a model anyway
    std::snprintf(msg, size, "%s: the instance could not be made: %s", kPluginName, error.c_str());
    return false;
  }
  i64 status = in->Run(m, d, kInstalled);
  if (status == kOk) return true;
  StatusMessage(m, d, in->tables(), status, msg, size);
  return false;
}

void Compute(const mjModel* m, mjData* d, int instance, int capability_bit) {
  (void)capability_bit;
  char msg[1000];
  // mju_error does not return (it longjmps out of MuJoCo): only plain data is live here
  if (!Pass(m, d, instance, msg, sizeof(msg))) mju_error("%s", msg);
}

}  // namespace

int GranularInstance(const mjModel* m) {
  for (int i = 0; i < m->nplugin; i++) {
    const mjpPlugin* p = mjp_getPluginAtSlot(m->plugin[i]);
    if (p && std::strcmp(p->name, kPluginName) == 0) return i;
  }
  return -1;
}

void RegisterGranular() {
  // A second copy of the library in one process (another path to it) must not register the name
  // again: MuJoCo treats a second, different plugin of one name as a fatal error.
  int slot = -1;
  if (mjp_getPlugin(kPluginName, &slot)) return;
  mjpPlugin plugin;
  mjp_defaultPlugin(&plugin);
  plugin.name = kPluginName;
  plugin.capabilityflags = mjPLUGIN_PASSIVE;
  static const char* attributes[] = {"ntbody", "ntgeom", "nsoil"};
  plugin.nattribute = sizeof(attributes) / sizeof(attributes[0]);
  plugin.attributes = attributes;
  plugin.nstate = NState;
  plugin.init = Init;
  plugin.destroy = Destroy;
  plugin.copy = Copy;
  plugin.reset = Reset;
  plugin.compute = Compute;
  mjp_registerPlugin(&plugin);
}

}  // namespace mjrft
