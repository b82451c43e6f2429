// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Geoms that sink without being intruders: the medium acts only on tagged geoms, so a robot's
// untagged knee or body passes through the sand unresisted. Each installed pass checks the
// geoms of watch_geomid (the loader lists the collision geoms of moving bodies that are not
// intruders) and reports, once per geom and mjData, one that is below the local surface,
// naming it, its body and the time: through the handler the Python layer sets (a Python
// warning, mjrft.SinkingWarning), else mju_warning.

#ifndef MJRFT_ENGINE_WATCH_H_
#define MJRFT_ENGINE_WATCH_H_

#include "state.h"

namespace mjrft::watch {

// Receives a report's message (UTF-8, NUL-terminated; valid during the call).
using Handler = void (*)(const char* message);

// Sets the handler of reports (nullptr: mju_warning). Thread-safe.
void SetHandler(Handler handler);

// Depth [m] of watched geom w's lowest point below the local surface at d's pose (<= 0: not
// below it, or outside the region).
f64 Depth(const mjModel* m, const mjData* d, const Tables& t, const State& s, i64 w);

// Reports each watched geom below the local surface that was not reported on this mjData yet
// (s.watch_told), and marks it.
void ReportSunk(const mjModel* m, const mjData* d, const Tables& t, State& s);

}  // namespace mjrft::watch

#endif  // MJRFT_ENGINE_WATCH_H_
