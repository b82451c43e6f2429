// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The engine plugin mjrft.granular: a passive-force plugin that applies granular Resistive
// Force Theory to the tagged geoms of a model through xfrc_applied, once per forward pass.
//
// The static tables are read in init from the model's custom numeric fields named
// "mjrft.granular:<table>" (fields.h), which mjrft's Python loader writes (mjrft.load_model), so a
// compiled model, saved as MJB too, is self-contained. Per-mjData state: the persistent arrays
// of fields.h in plugin_state, the work arrays in plugin_data (an Instance).

#ifndef MJRFT_ENGINE_GRANULAR_H_
#define MJRFT_ENGINE_GRANULAR_H_

#include <memory>
#include <string>
#include <vector>

#include "state.h"

namespace mjrft {

constexpr char kPluginName[] = "mjrft.granular";
// Prefix of the custom numeric fields that hold the tables.
constexpr char kTablePrefix[] = "mjrft.granular:";
// Version of the tables' layout; a model written for another is refused by name.
constexpr int kTableFormat = 1;

// The sizes that fix the State's layout.
struct Sizes {
  i64 nbody, nv, nu, nelem, ng, nk, nsoil, soil_nrow, soil_ncol;
};

// One plugin instance on one mjData.
class Instance {
 public:
  // The instance's tables and work arrays, or nullptr with the reason in error.
  static std::unique_ptr<Instance> Create(const mjModel* m, int instance, std::string* error);

  // The State of this instance on d (persistent arrays in d->plugin_state).
  State Bind(const mjModel* m, mjData* d) const;
  // Zeroes the persistent state at plugin_state and resets the caches.
  void Reset(f64* plugin_state);

  const Tables& tables() const { return tables_; }
  // Number of elements of state array `name` (fields.h), or -1 if there is none.
  i64 ArraySize(const char* name) const;
  int instance() const { return instance_; }

  // Number of mjtNum of the persistent state of an instance of these sizes.
  static i64 StateSize(const Sizes& n);
  // Sizes of an instance of m (from its tables); false with the reason in error.
  static bool ReadSizes(const mjModel* m, Sizes* n, std::string* error);

 private:
  int instance_ = 0;
  Sizes sizes_{};
  Tables tables_{};
  std::vector<i64> ints_;   // the i64 tables (converted from the model's numeric fields)
  std::vector<f64> work_;   // the f64 work arrays
  std::vector<i64> iwork_;  // the i64 work arrays
  State work_state_{};      // pointers of the work arrays (persistent ones set by Bind)
};

// Registers mjrft.granular with MuJoCo (once per process).
void RegisterGranular();

}  // namespace mjrft

#endif  // MJRFT_ENGINE_GRANULAR_H_
