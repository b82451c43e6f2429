// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Ground that deforms and remembers: a height grid pressed down by intruders, bulldozed and
// relaxed to the angle of repose, with the memory of how deep its compacted columns were
// (mjrft.core.soil states the same rules in Python; docs/terrain.md).
//
// The grid (surface.h, kind kSoil) has vertices every dx, dy over the medium's region; vertex v
// stands for the column of one cell area centred on it. Its state, per mjData (the soil block,
// State::soil), is its surface height h, its compacted level c <= h, its memory p >= 0 and which
// intruder pressed on it at the last update (Mark; the material beside an intruder). The
// resisting depth of a point at height z in the column is (h + p) - z below c and h - z between
// c and h (surface::SoilDepth). Pristine ground has c = h, p = 0.
//
// One update (deform.h, with the functions below) follows the intruders to a new configuration:
//
// 1. Footprints (Footprint): every downward-facing triangle of an intruder (its lower surface,
//    seen from above) is rasterised onto the vertices below it; a vertex whose floor (the
//    lowest such triangle over it) lies below its surface h is occupied.
// 2. Excavation (Excavate): an occupied column is cut down to the floor, which becomes its
//    compacted level (c = h = floor) and remembers as its depth reference the larger of the old
//    surface h and the old c + p (Chrono SCM's sinkage memory plays this role in Bekker-Wong
//    soil).
// 3. Deposition (Deposit): each intruder's excavated volume is laid as a cone at the repose
//    slope around the rim of its footprint (the unoccupied vertices next to it): a vertex at
//    distance d from the rim (along the grid's steps, around pressed columns) rises to
//    max(h, H - tan(repose) d), H conserving the volume. Rim vertices are offset by the
//    footprint's extent times how little of its horizontal motion points their way: a vertical
//    intrusion raises an even ring, a horizontal one bulldozes ahead of it. The cone is no
//    steeper than the repose slope, so ground that was at repose stays so. It lands as loose
//    material (h grows, c and p unchanged).
// 4. Relaxation (Relax): wherever two neighbouring vertices (along x, y and both diagonals)
//    differ by more than tan(repose) times their distance (by more than kSlopeTolerance of
//    that), material moves from the higher to the lower one (half the excess, so the pair ends
//    exactly at the repose slope): one sweep over each intruder's box (where it is and was),
//    then vertex by vertex wherever material moved, never into or out of a column an intruder
//    presses on or the grid's edge ring, and into the gap under a hovering intruder only up to
//    its floor.
//
// Every move subtracts from one vertex exactly what it adds to another, and the edge ring never
// changes, so the volume under the surface (dx dy times the sum of h over the vertices) is
// conserved up to rounding. World frame, SI units; arrays only (no MuJoCo).
//
// Common arguments: prm (kPrmSize) and grid (nrow x ncol initial heights [m]) of the surface;
// soil (surface::SoilBlock) the block; floor (nrow x ncol) [m] the intruders' lowest point per
// vertex (+inf where none); owner (nrow x ncol) the tagged body over each vertex (-1: none);
// a vertex box (4) is (r0, r1, c0, c1) as doubles, empty when r0 > r1; stats (kNSoilStats)
// the work counters (kStat*). All arrays row-major.

#ifndef MJRFT_ENGINE_SOIL_H_
#define MJRFT_ENGINE_SOIL_H_

#include "tables.h"

namespace mjrft::soil {

// Barycentric slack of the rasterisation: a vertex on an edge shared by two triangles is
// covered by both, whatever the rounding.
constexpr f64 kEdgeSlack = 1e-12;
// Relaxation work per update at most, in sweeps of the update's boxes (Relax: the pair visits
// of this many sweeps); what is left continues at the next update (counted in kStatUnrelaxed).
// A wall's excess travels down its slope diffusively, so a deep hole's collapse would take ~its
// width squared in sweeps to settle exactly at one step; the budget bounds a step's cost and
// lets the slope settle over the next steps.
constexpr int kMaxSweeps = 16;
// A neighbouring pair may be steeper than the repose slope by this fraction of its rise, or by
// kSlopeSlack if that is more, before material moves (then it moves until the pair is at the
// repose slope): 1 % of tan(repose), 0.2 deg at 23 deg, inside the scatter of measured angles
// of repose (+-1 deg and more between tests of one medium). A fraction of the slope, not a
// height, so that the relaxation stops at the same angle on every cell size; it sets how far a
// small excess travels down a slope standing at repose, and with it the relaxation's work.
constexpr f64 kSlopeTolerance = 0.01;
// The least excess [m] that moves material (1 um: a thousandth of a 1 mm grain; rounding must
// not keep a pair moving).
constexpr f64 kSlopeSlack = 1e-6;
// Largest grid accepted (vertices): its soil block then takes 4 x 8 bytes per vertex per mjData.
constexpr i64 kMaxVertices = 2000000;
// Slots of soil_stats: updates, volume excavated [m^3], volume that found no rim [m^3], updates
// whose relaxation hit kMaxSweeps, triangles rasterised, footprint vertices at the edge ring,
// pairs of neighbouring vertices the relaxation compared (its work).
enum SoilStat {
  kStatUpdates,
  kStatExcavated,
  kStatUnplaced,
  kStatUnrelaxed,
  kStatRasterised,
  kStatEdge,
  kStatVisits
};
static_assert(kStatVisits + 1 == kNSoilStats, "soil_stats slots");
// owner's value for a vertex waiting in the relaxation's queue (deposition is done by then, and
// Finish clears the owners).
constexpr i64 kQueued = -2;

// Grows box (4) to cover vertex rows r0..r1 and columns c0..c1 (nothing if r0 > r1 or c0 > c1).
void Union(f64* box, f64 r0, f64 r1, f64 c0, f64 c1);

// Rasterises the downward-facing triangles start..stop of intruder k onto the grid. vert
// (n x 9): each triangle's three vertices, body frame [m], counter-clockwise seen from outside;
// rot (3 x 3) body -> world, pos (3) body origin [m]. floor takes, at each vertex under a
// triangle lower than it, the triangle's height there, and owner the intruder's index k; box
// grows to cover those vertices. Triangles whose lowest corner is at or above top [m] are
// skipped. Returns the triangles rasterised.
int Footprint(const f64* prm, const f64* vert, i64 start, i64 stop, const f64* rot, const f64* pos,
              i64 k, f64* floor, i64* owner, f64* box, f64 top);

// What Excavate cut: volume [m^3] (-1: a floor lies below the medium's bottom, 0: nothing),
// the (x, y) of its centroid [m] and the velocity v (3) [m/s] of the intruder's point there.
struct Cut {
  f64 vol, mx, my;
  f64 v[3];
};

// Cuts intruder k's occupied columns (owner == k, inside box) down to their floor. The floor
// becomes the compacted level, remembering as its depth reference the larger of the surface h
// and the old c + p. twist (9): the intruder's velocity [m/s] at a point moving with it, its
// angular velocity [rad/s], that point [m]; world frame. zlo [m]: the medium's bottom. Columns
// on the edge ring are counted (kStatEdge), never cut.
Cut Excavate(const f64* prm, const f64* grid, f64* soil, const f64* floor, const i64* owner,
             const f64* box, i64 k, const f64* twist, f64 zlo, f64* stats);

// Lays volume vol [m^3] of intruder k around the rim of its footprint (the vertices next to
// those it presses on, inside box grown by one vertex, with no intruder over them; failing
// those, the ones under an intruder but free of contact) as a cone at the repose slope (step 3
// above): each rim vertex is offset by the footprint's extent times 1 - w / max w, w = (1 - s) +
// 2 s max(0, cos) the weight of its direction from the footprint's centre (mx, my) [m] against
// the horizontal direction of v (3) [m/s], s = |v_xy| / (|v_xy| + |v_z|). Vertices under an
// intruder take material up to its floor; what finds no room is counted (kStatUnplaced). Loose
// material: h grows, c and p stay. work (nrow * ncol, the relaxation's queue, free until then)
// holds the rim's offsets and the cone's distances and breakpoints; a cone whose box needs more
// falls back to the rim alone, by weight.
void Deposit(const f64* prm, const f64* grid, f64* soil, const f64* floor, const i64* owner,
             const f64* box, i64 k, f64 vol, f64 mx, f64 my, const f64* v, f64* stats, i64* work);

// Relaxes the surface from the vertices of the nbox vertex boxes (nbox x 4) until no pair of
// free neighbouring vertices is steeper than the angle of repose, or the work budget is spent;
// returns true if it converged.
//
// One sweep over each box (the footprints' neighbourhoods: their total area, not the box
// spanning them), then a queue (first in, first out) of the vertices that moved: a vertex taken
// from it is settled against its eight neighbours, and every vertex that moved (it, and each
// neighbour it gave to or took from) joins the queue again, so the work follows the material
// (six legs far apart cost six footprints). A pair of which neither vertex moved since it was in
// repose is still in repose. The budget is the pair visits of kMaxSweeps sweeps of the boxes
// (counted in kStatVisits). On return pending (4) holds the queue's bounding box if it did not
// empty (the slopes left unrelaxed), else an empty box; top [m] has grown over every height
// that material moved into. mark (nrow x ncol): owner, which marks the waiting vertices kQueued
// (and is cleared by Finish); queue (nrow * ncol): work space for the queue. A vertex an
// intruder presses on neither gives nor takes (the gap under a hovering one fills up to its
// floor).
bool Relax(const f64* prm, const f64* grid, f64* soil, const f64* floor, i64* mark, i64* queue,
           const f64* boxes, i64 nbox, f64* pending, f64* top, f64* stats);

// Records, over the nbox vertex boxes (nbox x 4; box k intruder k's footprint), the intruder
// that presses on each vertex (owner k, its floor at the surface): the press mark q = k + 1 of
// surface::SoilDepth.
void Mark(const f64* prm, const f64* grid, f64* soil, const f64* floor, const i64* owner,
          const f64* boxes, i64 nbox);

// Clears the press marks over vertex rows r0..r1 and columns c0..c1.
void Unmark(const f64* prm, f64* soil, i64 r0, i64 r1, i64 c0, i64 c1);

// Closes an update: clears floor and owner over the nbox vertex boxes (nbox x 4: the
// footprints; and one vertex around each), raises the ceiling (soil[kSoilZoff]) to the highest
// of top [m] and the surface there, and records the time [s] of the configuration followed.
void Finish(const f64* prm, const f64* grid, f64* soil, f64* floor, i64* owner, const f64* boxes,
            i64 nbox, f64 top, f64 time);

}  // namespace mjrft::soil

#endif  // MJRFT_ENGINE_SOIL_H_
