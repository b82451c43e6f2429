// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The deforming ground's update on one mjData: the intruders' footprints at the current
// configuration, then excavation, deposition and relaxation (soil.h;
// docs/terrain.md).
//
// The pass runs it once per configuration, before the forces, at the first pass of a new time
// (RK4's later stages and repeated passes at one time do not move the ground), so the forces of
// a step feel the ground as the intruders left it at that step's configuration.

#ifndef MJRFT_ENGINE_DEFORM_H_
#define MJRFT_ENGINE_DEFORM_H_

#include "state.h"

namespace mjrft::deform {

// True if the ground has not yet followed the configuration at this time: with
// mjrft:deform_every = k >= 1, once k steps have passed since it last did; otherwise once the
// intruders may have travelled mjrft:deform_travel cells since (each pass of a new time adds
// the time passed times the fastest speed of a point of a tagged geom that may touch the
// medium, its centre's speed plus its angular speed times its bounding radius; the distance
// lives in the soil block), or at every new time while the last update left slopes to relax;
// and whenever the time went back (a reset or a restored state).
bool Due(const mjModel* m, const mjData* d, const Tables& t, State& s);

// Moves the ground of this mjData (s.soil) to the intruders' current configuration (d->xpos,
// xmat, cvel, subtree_com, geom_xpos, time). Work arrays: s.soil_floor, soil_owner, soil_queue,
// soil_box (rows 0..nk-1: each tagged body's footprint box, nk: their union, nk + 1..2 nk: the
// footprint boxes of the last update, 2 nk + 1: the fingerprint of the state that update left
// (updates, excavated, time, 1), then nk + 2 rows: the relaxation's boxes); counters in
// s.soil_stats. Returns -1, or
// the tagged body that reaches below the medium's bottom (nothing then moved for it).
int Update(const mjModel* m, const mjData* d, const Tables& t, State& s);

}  // namespace mjrft::deform

#endif  // MJRFT_ENGINE_DEFORM_H_
