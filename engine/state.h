// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The engine's state for one mjData: views of its arrays (fields.h, MJRFT_STATE_ARRAYS). The
// persistent ones live in mjData.plugin_state, so mj_copyData, mj_resetData and
// mj_getState/mj_setState carry them; the work arrays live in the instance's plugin_data.

#ifndef MJRFT_ENGINE_STATE_H_
#define MJRFT_ENGINE_STATE_H_

#include "tables.h"

namespace mjrft {

struct State {
#define MJRFT_X(type, name, shape, doc) type* name;
  MJRFT_STATE_ARRAYS(MJRFT_X)
#undef MJRFT_X
};

}  // namespace mjrft

#endif  // MJRFT_ENGINE_STATE_H_
