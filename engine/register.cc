// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Registers the engine's plugins when the library is loaded (mj_loadPluginLibrary, or dlopen).

#include <mujoco/mjplugin.h>

#include "granular.h"

mjPLUGIN_LIB_INIT(mjrft_granular) { mjrft::RegisterGranular(); }
