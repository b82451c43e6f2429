// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The engine's forward pass on one mjData: the one implementation every path runs. Modes:
//   kInstalled: inside mj_step / mj_forward (the plugin's compute): the RK4 stage rule, then
//               xfrc_applied ownership (tagged rows = user part + RFT);
//   kExplicit:  the wrench of the current state, the treatment balancing s.user_in; reads and
//               writes nothing of the mjData (GranularField.wrench);
//   kBatch:     as kExplicit, for one copy of a batch;
//   kQuery:     the pure model only (GranularField.element_states).

#ifndef MJRFT_ENGINE_FORWARD_H_
#define MJRFT_ENGINE_FORWARD_H_

#include "state.h"

namespace mjrft {

enum Mode { kInstalled = 0, kExplicit = 1, kBatch = 2, kQuery = 3 };

// Status of a pass (s.status[0]): kOk, or -1 - k where tagged body k has a non-finite position
// or velocity, or kBelowGround - k where it reaches below the deforming ground's bottom.
constexpr i64 kOk = 0;
constexpr i64 kBelowGround = -1000000;

// One pass of the engine on one mjData; returns kOk or a failure status. Writes s.wrench,
// s.elem_force, s.decision and, when installed, xfrc_applied and the RK4 record.
i64 Forward(const mjModel* m, mjData* d, const Tables& t, State& s, int mode);

}  // namespace mjrft

#endif  // MJRFT_ENGINE_FORWARD_H_
