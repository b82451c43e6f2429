// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The lowest point of a geom, world frame: what the sinkage of a geom and the check for geoms
// that sink without being intruders (watch.h) measure against the medium's surface.

#ifndef MJRFT_ENGINE_LOWEST_H_
#define MJRFT_ENGINE_LOWEST_H_

#include "tables.h"

namespace mjrft {

// Sets out (3) to the lowest point [m], world frame, of geom `geom` at d's pose: exact for
// spheres, capsules, ellipsoids, cylinders and boxes, the lowest vertex of a mesh, and the
// lowest corner of the geom's bounding box (m->geom_aabb) for any other type. Returns false for
// planes and height fields, which have no lowest point (out untouched).
bool LowestPoint(const mjModel* m, const mjData* d, int geom, f64 out[3]);

// Sinkage [m] of geom `geom`: the height of the medium's surface (t's, with the deforming
// ground's block soil) above its lowest point (LowestPoint, written into low), negative while
// it is above the surface; NaN for a geom without a lowest point.
f64 Sinkage(const mjModel* m, const mjData* d, const Tables& t, const f64* soil, int geom,
            f64 low[3]);

}  // namespace mjrft

#endif  // MJRFT_ENGINE_LOWEST_H_
