// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// C entry points of the free surface (surface.h) for the Python core layer (mjrft.core.surface,
// through mjrft.core.engine and ctypes): heights and depths of n points of one surface. A
// surface is prm (kPrmSize), grid (nrow x ncol heights [m], row-major) and, for a deforming
// grid, its soil block (SoilBlock(nrow, ncol)); the caller checks that the arrays fit prm.

#include <cstdint>

#include "api.h"
#include "surface.h"

using mjrft::f64;
using mjrft::i64;
namespace surface = mjrft::surface;

// surface_heights: out (n,) surface heights [m] at the horizontal positions (x[i], y[i]) [m],
// world frame.
MJRFT_API void mjrft_surface_heights(const f64* prm, const f64* grid, const f64* soil, const f64* x,
                                     const f64* y, i64 n, f64* out) {
  for (i64 i = 0; i < n; i++) out[i] = surface::Height(prm, grid, soil, x[i], y[i]);
}

// surface_depths: out (n,) resisting depths [m] of the world points (x[i], y[i], z[i]) [m]
// (<= 0 outside the medium); body k + 1 for points of tagged body k (its press marks on a
// deforming ground, surface::SoilDepth), 0 for none.
MJRFT_API void mjrft_surface_depths(const f64* prm, const f64* grid, const f64* soil, const f64* x,
                                    const f64* y, const f64* z, i64 n, f64 body, f64* out) {
  for (i64 i = 0; i < n; i++) out[i] = surface::Depth(prm, grid, soil, x[i], y[i], z[i], body);
}
