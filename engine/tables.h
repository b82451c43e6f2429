// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The static tables of one plugin instance: built once per mjModel (the plugin's init reads
// them from the model's mjrft: custom section) and read, never written, by every pass.
// mjModel's own fields (opt, body_mass, actuator_gainprm, ...) are read live from m->, since a
// user may change them between steps.

#ifndef MJRFT_ENGINE_TABLES_H_
#define MJRFT_ENGINE_TABLES_H_

#include <cstdint>

#include <mujoco/mujoco.h>

#include "fields.h"

namespace mjrft {

using f64 = mjtNum;
using i64 = std::int64_t;

// Sizes of fixed-length rows (the Python layer writes the same numbers: tests/engine_bridge.py
// checks them against mjrft.core.surface.PRM_SIZE and friends).
constexpr int kPrmSize = 14;    // surface_prm (surface.h)
constexpr int kPatchSize = 19;  // elem_patch row (quadrature.h)
constexpr int kRk4Head = 2;     // rk4 record head (rk4.h)
constexpr int kRk4Body = 49;    // rk4 record per tagged body
constexpr int kNStats = 6;      // stats: calls, evaluated, acting, stuck, slipping, implicit
constexpr int kNSoilStats = 7;  // soil_stats (soil.h)

// Views of the static tables (fields.h); the plugin instance or the test owns the storage.
struct Tables {
#define MJRFT_X(name) i64 name;
  MJRFT_TABLE_SIZES(MJRFT_X)
#undef MJRFT_X
#define MJRFT_X(type, name, doc) type name;
  MJRFT_TABLE_SCALARS(MJRFT_X)
#undef MJRFT_X
#define MJRFT_X(type, name, shape, doc) const type* name;
  MJRFT_TABLE_ARRAYS(MJRFT_X)
#undef MJRFT_X
};

}  // namespace mjrft

#endif  // MJRFT_ENGINE_TABLES_H_
