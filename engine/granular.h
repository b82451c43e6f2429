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
  i64 nbody, nv, nu, nelem, ng, nk, nsoil, soil_nrow, soil_ncol, nwatch;
};

// One plugin instance on one mjData.
class Instance {
 public:
  // The instance's tables and work arrays, or nullptr with the reason in error.
  static std::unique_ptr<Instance> Create(const mjModel* m, int instance, std::string* error);

  // The instance of d: the one made for d, or (when d's plugin_data holds another mjData's, as
  // MuJoCo's pickling of an mjData leaves it) a new one made now; nullptr with the reason in error.
  static Instance* Of(const mjModel* m, mjData* d, int instance, std::string* error);
  // A pass of the engine on d in mode (forward.h); returns its status. A state this instance
  // did not write last (reset, or restored by mj_setState) starts as in a new mjData: empty
  // caches, and the mechanism treatment without its predictor for one pass (the previous
  // forward pass's qacc it predicts from is not part of MuJoCo's state).
  i64 Run(const mjModel* m, mjData* d, int mode);
  // mj_copyData: this instance continues src's (its caches and what it last wrote), so a copy
  // steps exactly as the original.
  void CopyFrom(const Instance& src);
  // The State of this instance on d, as it is.
  State Bind(const mjModel* m, mjData* d) const;
  // Zeroes the persistent state of instance `instance` of m at plugin_state.
  static void ResetState(const mjModel* m, int instance, f64* plugin_state);
  // Empties the caches of the work arrays (what a new mjData starts with).
  void ResetCaches();
  // Registers a new instance of d (init) and forgets one (destroy: only d's own is deleted).
  static void Adopt(std::unique_ptr<Instance> in, mjData* d, int instance);
  static void Release(mjData* d, int instance);
  // The instance registered for d, or nullptr (no new one is made).
  static Instance* Find(const mjData* d, int instance);

  const Tables& tables() const { return tables_; }
  // Number of elements of state array `name` (fields.h), or -1 if there is none.
  i64 ArraySize(const char* name) const;
  int instance() const { return instance_; }

  // Number of mjtNum of the persistent state of an instance of these sizes.
  static i64 StateSize(const Sizes& n);
  // The tables' format, sizes and scalars of m into t (arrays untouched); false with the
  // reason in error.
  static bool ReadHead(const mjModel* m, Tables* t, std::string* error);

 private:
  int instance_ = 0;
  i64 seen_[3] = {-1, -1, -1};  // the state's counters (stats[0:3]) after this instance's last pass
  Sizes sizes_{};
  Tables tables_{};
  std::vector<i64> ints_;   // the i64 tables (converted from the model's numeric fields)
  std::vector<f64> work_;   // the f64 work arrays
  std::vector<i64> iwork_;  // the i64 work arrays
  State work_state_{};      // pointers of the work arrays (persistent ones set by Bind)
};

// The index of m's mjrft.granular instance, or -1.
int GranularInstance(const mjModel* m);

// Registers mjrft.granular with MuJoCo (once per process).
void RegisterGranular();

}  // namespace mjrft

#endif  // MJRFT_ENGINE_GRANULAR_H_
