// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The medium's free surface as a function of horizontal position (world frame): flat, a tilted
// plane, a height grid (a MuJoCo height field) or a deforming grid with memory (soil.h). Depth
// is measured vertically: a point at (x, y, z) is at depth height(x, y) - z (docs/field.md,
// "Surfaces"; mjrft.core.surface states the same rules in Python).
//
// A surface is prm (kPrmSize), grid (nrow x ncol heights [m], row r at y0 + r dy, column c at
// x0 + c dx) and, for a deforming grid, the soil block (per-mjData state, state.h).

#ifndef MJRFT_ENGINE_SURFACE_H_
#define MJRFT_ENGINE_SURFACE_H_

#include <algorithm>

#include "tables.h"

namespace mjrft::surface {

// Kinds (prm[kKind]).
constexpr int kFlat = 0, kPlane = 1, kGrid = 2, kSoil = 3;
// Slots of prm; kSoil only: kTanRepose (tangent of the angle of repose), kEvery (steps between
// updates of the ground; 0: kTravel's rule), kTravel (the ground follows the intruders once
// they have travelled this many cells since it last did; 0: at every step).
enum Prm {
  kKind,
  kZ0,
  kGx,
  kGy,
  kX0,
  kY0,
  kDx,
  kDy,
  kNcol,
  kNrow,
  kZmax,
  kTanRepose,
  kEvery,
  kTravel
};
// Head of a soil block: rise of the highest point above prm[kZmax] [m]; 1 once the grid
// followed a configuration; its time [s]; the vertex box (r0, r1, c0, c1) still relaxing; the
// box of the intruders' last footprints; how far [m] the intruders may have travelled since
// (deform.h, Due) and the time [s] that distance was last accumulated. Then the offsets of h
// and of c [m], the memory p [m] and the press mark q (k + 1 where tagged body k pressed on
// the vertex at the last update, 0 none), nrow * ncol each (row-major). All zero: the initial
// surface.
constexpr int kSoilZoff = 0, kSoilDone = 1, kSoilTime = 2, kSoilPending = 3, kSoilFoot = 7;
constexpr int kSoilTravel = 11, kSoilClock = 12;
constexpr int kSoilHead = 13;
// A point within this height [m] above a deforming surface still touches it (0.1 um: rounding
// must not decide whether an intruder touches the floor it just pressed).
constexpr f64 kSoilContact = 1e-7;

// Levels of a soil block: h, c and p offsets, press marks.
constexpr int kSoilLevels = 4;
// Size of the soil block of an nrow x ncol deforming grid.
inline i64 SoilBlock(i64 nrow, i64 ncol) { return kSoilHead + kSoilLevels * nrow * ncol; }

// Height [m] of a kGrid surface at (x, y) [m]: linear over the two triangles of each cell
// (diagonal (c, r)-(c + 1, r + 1), as MuJoCo's height-field collision), the edge beyond.
f64 GridHeight(const f64* prm, const f64* grid, f64 x, f64 y);

// (h, c, p) [m] at vertex (r, c) of a deforming grid: surface, compacted level, memory.
void SoilVertex(const f64* prm, const f64* grid, const f64* soil, i64 r, i64 c, f64 out[3]);

// Surface height [m] at the horizontal position (x, y) [m].
f64 Height(const f64* prm, const f64* grid, const f64* soil, f64 x, f64 y);

// An upper bound [m] of the height below which a point can be in the medium anywhere: the flat
// height, a grid's highest point, or +inf for a plane.
f64 Ceiling(const f64* prm, const f64* soil);

// An upper bound [m] of the surface height within horizontal distance r [m] of (x, y).
f64 HighestNear(const f64* prm, const f64* soil, f64 x, f64 y, f64 r);

// The cell of (x, y) in a grid: row r, column c, position (fu, fv) inside it, and whether it
// lies in the triangle (c, r)-(c + 1, r)-(c + 1, r + 1) (fu >= fv).
struct Cell {
  i64 r, c;
  f64 fu, fv;
  bool upper;
};
inline Cell CellOf(const f64* prm, f64 x, f64 y) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  f64 u = std::min(std::max((x - prm[kX0]) / prm[kDx], 0.0), ncol - 1.0);
  f64 v = std::min(std::max((y - prm[kY0]) / prm[kDy], 0.0), nrow - 1.0);
  i64 c = std::min(static_cast<i64>(u), ncol - 2);
  i64 r = std::min(static_cast<i64>(v), nrow - 2);
  return {r, c, u - c, v - r, u - c >= v - r};
}

// Linear interpolation over a cell's triangle: a00 at (c, r), a10 at (c + 1, r), a01 at
// (c, r + 1), a11 at (c + 1, r + 1).
inline f64 Tri(f64 a00, f64 a10, f64 a01, f64 a11, f64 fu, f64 fv, bool upper) {
  if (upper) return a00 + fu * (a10 - a00) + fv * (a11 - a10);
  return a00 + fv * (a01 - a00) + fu * (a11 - a01);
}

// Resisting depth [m] of a point of the intruder that presses on some of the vertices a, b, c,
// e of the cell k and not on the others (SoilDepth).
f64 BesideDepth(const f64* prm, const f64* grid, const f64* soil, const Cell& k, const i64* v,
                const bool* pressed, f64 z);

// Resisting depth [m] of the point (x, y, z) under a deforming surface: (h + p) - z below the
// compacted level c, h - z above it (negative above the surface, as under a fixed grid, so that
// the force pass drops an element clear of it after one look-up and clips one the surface
// crosses where it crosses). The levels are interpolated only as far as the point needs: most
// points the force pass asks about lie above the surface, and most below it above c. Inline:
// the force pass asks for every element and corner near the ground.
//
// body: k + 1 for a point of tagged body k (0: no body). In a cell where k presses on some
// vertices and not on the others, a point above the pressed vertices' surface (a side of the
// intruder, not its floor) is beside the intruder: the pressed vertices take the levels of the
// cell's highest free vertex, so the material next to the intruder stands at its own height up
// to the intruder's side rather than sloping down to its floor over the cell. Without it the
// front of a dragged blade meets a surface that rises from its floor to the berm as it crosses
// each cell and drops when it cuts the next vertex: a sawtooth of the cell's period, 57 % of the
// mean drag (benchmarks/deform_blade.py).
inline f64 SoilDepth(const f64* prm, const f64* grid, const f64* soil, f64 x, f64 y, f64 z,
                     f64 body) {
  Cell k = CellOf(prm, x, y);
  i64 ncol = static_cast<i64>(prm[kNcol]);
  i64 n = ncol * static_cast<i64>(prm[kNrow]);
  i64 a = k.r * ncol + k.c, b = a + 1, c = a + ncol, e = c + 1;
  const f64* oh = soil + kSoilHead;
  if (body > 0.0) {
    const f64* q = oh + 3 * n;
    bool pressed[4] = {q[a] == body, q[b] == body, q[c] == body, q[e] == body};
    int count = pressed[0] + pressed[1] + pressed[2] + pressed[3];
    if (count > 0 && count < 4) {
      const i64 v[4] = {a, b, c, e};
      return BesideDepth(prm, grid, soil, k, v, pressed, z);
    }
  }
  f64 g00 = grid[a], g10 = grid[b], g01 = grid[c], g11 = grid[e];
  f64 h = Tri(g00 + oh[a], g10 + oh[b], g01 + oh[c], g11 + oh[e], k.fu, k.fv, k.upper);
  if (z >= h + kSoilContact) return h - z;
  f64 depth = std::max(h - z, 0.0);
  const f64* oc = oh + n;
  f64 lc = Tri(g00 + oc[a], g10 + oc[b], g01 + oc[c], g11 + oc[e], k.fu, k.fv, k.upper);
  if (z < lc + kSoilContact) {
    const f64* op = oc + n;
    depth += Tri(op[a], op[b], op[c], op[e], k.fu, k.fv, k.upper);
  }
  return depth;
}

// Resisting depth [m] of the world point (x, y, z); <= 0 outside the medium. body: k + 1 for a
// point of tagged body k, 0 for none (SoilDepth).
inline f64 Depth(const f64* prm, const f64* grid, const f64* soil, f64 x, f64 y, f64 z,
                 f64 body = 0.0) {
  if (prm[kKind] == kSoil) return SoilDepth(prm, grid, soil, x, y, z, body);
  return Height(prm, grid, soil, x, y) - z;
}

}  // namespace mjrft::surface

#endif  // MJRFT_ENGINE_SURFACE_H_
