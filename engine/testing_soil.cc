// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// C entry points of soil.h and deform.h for the tests (tests/test_engine_soil.py).

#include "api.h"
#include "deform.h"
#include "soil.h"

using mjrft::f64;
using mjrft::i64;

MJRFT_API int mjrft_test_deform_due(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                    const mjrft::State* s) {
  return mjrft::deform::Due(m, d, *t, *s);
}

MJRFT_API int mjrft_test_deform_update(const mjModel* m, const mjData* d, const mjrft::Tables* t,
                                       mjrft::State* s) {
  return mjrft::deform::Update(m, d, *t, *s);
}

MJRFT_API int mjrft_test_soil_footprint(const f64* prm, const f64* vert, i64 start, i64 stop,
                                        const f64* rot, const f64* pos, i64 k, f64* floor,
                                        i64* owner, f64* box, f64 top) {
  return mjrft::soil::Footprint(prm, vert, start, stop, rot, pos, k, floor, owner, box, top);
}

// out (6): volume, mx, my, vx, vy, vz.
MJRFT_API void mjrft_test_soil_excavate(const f64* prm, const f64* grid, f64* soil,
                                        const f64* floor, const i64* owner, const f64* box, i64 k,
                                        const f64* twist, f64 zlo, f64* stats, f64* out) {
  mjrft::soil::Cut cut =
      mjrft::soil::Excavate(prm, grid, soil, floor, owner, box, k, twist, zlo, stats);
  const f64 row[6] = {cut.vol, cut.mx, cut.my, cut.v[0], cut.v[1], cut.v[2]};
  for (int c = 0; c < 6; c++) out[c] = row[c];
}

MJRFT_API void mjrft_test_soil_deposit(const f64* prm, const f64* grid, f64* soil, const f64* floor,
                                       const i64* owner, const f64* box, i64 k, f64 vol, f64 mx,
                                       f64 my, const f64* v, f64* stats, i64* work) {
  mjrft::soil::Deposit(prm, grid, soil, floor, owner, box, k, vol, mx, my, v, stats, work);
}

MJRFT_API int mjrft_test_soil_relax(const f64* prm, const f64* grid, f64* soil, const f64* floor,
                                    i64* mark, i64* queue, f64* box, f64* seen, f64* stats) {
  return mjrft::soil::Relax(prm, grid, soil, floor, mark, queue, box, seen, stats);
}

MJRFT_API void mjrft_test_soil_finish(const f64* prm, const f64* grid, f64* soil, f64* floor,
                                      i64* owner, const f64* box, f64 time) {
  mjrft::soil::Finish(prm, grid, soil, floor, owner, box, time);
}
