// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Registers the engine's plugins (mjrft.granular, mjrft.sensor) when the library is loaded
// (mj_loadPluginLibrary, or dlopen).

#include <mujoco/mjplugin.h>

#include "granular.h"
#include "sensor.h"

mjPLUGIN_LIB_INIT(mjrft_granular) {
  mjrft::RegisterGranular();
  mjrft::RegisterSensor();
}
