// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "soil.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "surface.h"

namespace mjrft::soil {
namespace {

using surface::kDx;
using surface::kDy;
using surface::kNcol;
using surface::kNrow;
using surface::kSoilContact;
using surface::kSoilHead;
using surface::kX0;
using surface::kY0;

constexpr f64 kInf = std::numeric_limits<f64>::infinity();
constexpr f64 kNaN = std::numeric_limits<f64>::quiet_NaN();

// Body-frame point (x, y, z) in the world: rot (3 x 3) body -> world, pos (3).
inline void World(const f64* rot, const f64* pos, f64 x, f64 y, f64 z, f64 out[3]) {
  for (int i = 0; i < 3; i++) {
    out[i] = rot[3 * i] * x + rot[3 * i + 1] * y + rot[3 * i + 2] * z + pos[i];
  }
}

// Offsets in the soil block of the h and c offsets and of the memory p.
struct Offsets {
  i64 oh, oc, op;
};
inline Offsets OffsetsOf(const f64* prm) {
  i64 n = static_cast<i64>(prm[kNcol]) * static_cast<i64>(prm[kNrow]);
  return {kSoilHead, kSoilHead + n, kSoilHead + 2 * n};
}

// True if an intruder presses on vertex (r, c): its floor at the surface (after the cut).
inline bool Contact(const f64* prm, const f64* grid, const f64* soil, const f64* floor, i64 r,
                    i64 c) {
  i64 ncol = static_cast<i64>(prm[kNcol]);
  return floor[r * ncol + c] < grid[r * ncol + c] + soil[kSoilHead + r * ncol + c] + kSoilContact;
}

// True if vertex (r, c), free of contact (and with no intruder over it if open_sky), borders a
// vertex intruder k presses on (8-neighbourhood).
inline bool Rim(const f64* prm, const f64* grid, const f64* soil, const f64* floor,
                const i64* owner, i64 r, i64 c, i64 k, bool open_sky) {
  i64 ncol = static_cast<i64>(prm[kNcol]);
  if ((open_sky && floor[r * ncol + c] < kInf) || Contact(prm, grid, soil, floor, r, c)) {
    return false;
  }
  for (i64 a = -1; a < 2; a++) {
    for (i64 b = -1; b < 2; b++) {
      if (owner[(r + a) * ncol + c + b] == k && Contact(prm, grid, soil, floor, r + a, c + b)) {
        return true;
      }
    }
  }
  return false;
}

// Moves height q [m] of material from vertex i to vertex j (flat indices); an eroded vertex
// loses its loose layer first, then its compacted level follows its surface down.
inline void Move(f64* soil, const Offsets& o, i64 i, i64 j, f64 q) {
  soil[o.oh + i] -= q;
  soil[o.oh + j] += q;
  if (soil[o.oh + i] < soil[o.oc + i]) soil[o.oc + i] = soil[o.oh + i];
}

// Moves material between free vertices i and j (heights hi, hj, intruder floors fi, fj [m],
// +inf where none) if they differ by more than lim [m] (the repose slope's rise between them)
// by more than kSlopeTolerance of it, so that they then differ by lim; returns the height
// moved.
//
// Material enters the gap under a hovering intruder (floor f) only up to f, and only from a
// neighbour that is also under an intruder or no higher than f: the intruder's side holds a
// wall that stands above its floor (a height field cannot undercut it).
inline f64 SettlePair(f64* soil, const Offsets& o, i64 i, f64 hi, f64 fi, i64 j, f64 hj, f64 fj,
                      f64 lim) {
  f64 diff = hi - hj;
  const f64 start = lim + std::max(kSlopeSlack, kSlopeTolerance * lim);
  if (diff > start) {
    if (fj < kInf && fi == kInf && hi > fj) return 0.0;
    f64 q = std::min(0.5 * (diff - lim), fj - hj);
    Move(soil, o, i, j, q);
    return q;
  }
  if (-diff > start) {
    if (fi < kInf && fj == kInf && hj > fi) return 0.0;
    f64 q = std::min(0.5 * (-diff - lim), fi - hi);
    Move(soil, o, j, i, q);
    return q;
  }
  return 0.0;
}

// The relaxation's queue: a ring buffer over the nrow * ncol vertices, each at most once (the
// mark), so it never fills. Indices wrap by comparison, not by division (a pop is the
// relaxation's innermost step).
struct Queue {
  i64* items;
  i64 cap;
  i64 head = 0;  // the oldest waiting vertex's slot
  i64 tail = 0;  // the next free slot
  i64 count = 0;

  // Flat index of the q-th waiting vertex (0: the oldest).
  i64 At(i64 q) const {
    i64 at = head + q;
    return items[at < cap ? at : at - cap];
  }

  // Removes and returns the oldest waiting vertex.
  i64 Pop() {
    i64 i = items[head];
    head = head + 1 < cap ? head + 1 : 0;
    count--;
    return i;
  }

  // Appends vertex i unless it waits already.
  void Push(i64* mark, i64 i) {
    if (mark[i] == kQueued) return;
    items[tail] = i;
    tail = tail + 1 < cap ? tail + 1 : 0;
    mark[i] = kQueued;
    count++;
  }
};

// (height h [m], intruder floor f [m], free) of vertex (r, c): not free if an intruder presses
// on it (it neither gives nor takes).
struct Vertex {
  f64 h, f;
  bool free;
};
inline Vertex Free(const f64* grid, const f64* soil, i64 oh, const f64* floor, i64 r, i64 c,
                   i64 ncol) {
  f64 h = grid[r * ncol + c] + soil[oh + r * ncol + c];
  f64 f = floor[r * ncol + c];
  return {h, f, f >= h + kSoilContact};
}

// Settles free vertex i (row r, column c, height hi, floor fi) with its neighbour at
// (r + a, c + b) (limit lim) on a grid of nrow x ncol vertices; if material moved, queues both.
// Returns vertex i's height after it.
inline f64 SettleInto(const f64* grid, f64* soil, const Offsets& o, const f64* floor, i64* mark,
                      i64 nrow, i64 ncol, f64 lim, Queue& queue, f64* top, i64 i, i64 r, i64 c,
                      f64 hi, f64 fi, i64 a, i64 b) {
  i64 rr = r + a, cc = c + b;
  if (rr < 1 || rr > nrow - 2 || cc < 1 || cc > ncol - 2) return hi;
  Vertex vj = Free(grid, soil, o.oh, floor, rr, cc, ncol);
  if (!vj.free) return hi;
  i64 j = rr * ncol + cc;
  if (SettlePair(soil, o, i, hi, fi, j, vj.h, vj.f, lim) <= 0.0) {
    return hi;  // in repose, or capped by an intruder: settled
  }
  hi = grid[i] + soil[o.oh + i];
  *top = std::max({*top, hi, grid[j] + soil[o.oh + j]});
  queue.Push(mark, j);
  queue.Push(mark, i);
  return hi;
}

// The eight neighbours of a vertex: row step, column step, index of the limit (x, y, diagonal).
constexpr int kNeighbours[8][3] = {{0, 1, 0}, {0, -1, 0},  {1, 0, 1},  {-1, 0, 1},
                                   {1, 1, 2}, {-1, -1, 2}, {1, -1, 2}, {-1, 1, 2}};
// The sweep's pairs of a vertex, each pair once: right, up, up-right, up-left.
constexpr int kSweep[4][3] = {{0, 1, 0}, {1, 0, 1}, {1, 1, 2}, {1, -1, 2}};

}  // namespace

void Union(f64* box, f64 r0, f64 r1, f64 c0, f64 c1) {
  if (r0 <= r1 && c0 <= c1) {
    box[0] = std::min(box[0], r0);
    box[1] = std::max(box[1], r1);
    box[2] = std::min(box[2], c0);
    box[3] = std::max(box[3], c1);
  }
}

int Footprint(const f64* prm, const f64* vert, i64 start, i64 stop, const f64* rot, const f64* pos,
              i64 k, f64* floor, i64* owner, f64* box, f64 top) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  f64 x0 = prm[kX0], y0 = prm[kY0], dx = prm[kDx], dy = prm[kDy];
  int done = 0;
  for (i64 i = start; i < stop; i++) {
    const f64* tri = vert + 9 * i;
    f64 pa[3], pb[3], pc[3];
    World(rot, pos, tri[0], tri[1], tri[2], pa);
    World(rot, pos, tri[3], tri[4], tri[5], pb);
    World(rot, pos, tri[6], tri[7], tri[8], pc);
    f64 ax = pa[0], ay = pa[1], az = pa[2];
    f64 bx = pb[0], by = pb[1], bz = pb[2];
    f64 cx = pc[0], cy = pc[1], cz = pc[2];
    if (std::min({az, bz, cz}) >= top) continue;
    f64 ux = bx - ax, uy = by - ay, wx = cx - ax, wy = cy - ay;
    f64 twice = ux * wy - uy * wx;  // twice the signed xy area: < 0 for a downward-facing face
    if (twice >= 0.0) continue;
    done++;
    i64 c0 = std::max<i64>(0, static_cast<i64>(std::ceil((std::min({ax, bx, cx}) - x0) / dx)));
    i64 c1 =
        std::min<i64>(ncol - 1, static_cast<i64>(std::floor((std::max({ax, bx, cx}) - x0) / dx)));
    i64 r0 = std::max<i64>(0, static_cast<i64>(std::ceil((std::min({ay, by, cy}) - y0) / dy)));
    i64 r1 =
        std::min<i64>(nrow - 1, static_cast<i64>(std::floor((std::max({ay, by, cy}) - y0) / dy)));
    f64 inv = 1.0 / twice;
    for (i64 r = r0; r <= r1; r++) {
      f64 qy = y0 + r * dy - ay;
      for (i64 c = c0; c <= c1; c++) {
        f64 qx = x0 + c * dx - ax;
        f64 b = (qx * wy - qy * wx) * inv;
        f64 g = (ux * qy - uy * qx) * inv;
        // A vertex on a shared edge belongs to both triangles (kEdgeSlack).
        if (b < -kEdgeSlack || g < -kEdgeSlack || b + g > 1.0 + kEdgeSlack) continue;
        f64 z = az + b * (bz - az) + g * (cz - az);
        if (z < floor[r * ncol + c]) {
          floor[r * ncol + c] = z;
          owner[r * ncol + c] = k;
          Union(box, r, r, c, c);
        }
      }
    }
  }
  return done;
}

Cut Excavate(const f64* prm, const f64* grid, f64* soil, const f64* floor, const i64* owner,
             const f64* box, i64 k, const f64* twist, f64 zlo, f64* stats) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  Offsets o = OffsetsOf(prm);
  f64 area = prm[kDx] * prm[kDy];
  f64 vol = 0.0, mx = 0.0, my = 0.0, mz = 0.0;
  for (i64 r = static_cast<i64>(box[0]); r <= static_cast<i64>(box[1]); r++) {
    for (i64 c = static_cast<i64>(box[2]); c <= static_cast<i64>(box[3]); c++) {
      i64 i = r * ncol + c;
      if (owner[i] != k) continue;
      f64 base = grid[i];
      f64 h = base + soil[o.oh + i];
      f64 f = floor[i];
      if (f >= h) continue;  // above the surface, or touching it: nothing to cut
      if (f < zlo) return {-1.0, 0.0, 0.0, {0.0, 0.0, 0.0}};
      if (r == 0 || c == 0 || r == nrow - 1 || c == ncol - 1) {
        stats[kStatEdge] += 1;  // the edge ring never changes (volume bookkeeping)
        continue;
      }
      f64 cut = h - f;
      // The floor is compacted with the larger of the two references over it: the loose
      // surface h, or the compacted level's own c + p (loose material that slumped into an
      // old footprint does not add to the depth its floor remembers).
      f64 ref = std::max(h, base + soil[o.oc + i] + soil[o.op + i]);
      soil[o.oh + i] = f - base;
      soil[o.oc + i] = f - base;
      soil[o.op + i] = ref - f;
      vol += cut * area;
      mx += cut * area * (prm[kX0] + c * prm[kDx]);
      my += cut * area * (prm[kY0] + r * prm[kDy]);
      mz += cut * area * f;
    }
  }
  if (vol <= 0.0) return {0.0, 0.0, 0.0, {0.0, 0.0, 0.0}};
  mx = mx / vol;
  my = my / vol;
  mz = mz / vol;
  // The footprint's centre moves with the intruder: a slipping wheel's bottom moves backwards.
  f64 rx = mx - twist[6], ry = my - twist[7], rz = mz - twist[8];
  Cut out = {vol, mx, my, {0.0, 0.0, 0.0}};
  out.v[0] = twist[0] + twist[4] * rz - twist[5] * ry;
  out.v[1] = twist[1] + twist[5] * rx - twist[3] * rz;
  out.v[2] = twist[2] + twist[3] * ry - twist[4] * rx;
  stats[kStatExcavated] += vol;
  return out;
}

namespace {

// Orderable integer of a double (the integers sort as the doubles do), and back: the work
// array is i64, and the cone's breakpoints are sorted there.
inline i64 Key(f64 x) {
  i64 b;
  std::memcpy(&b, &x, 8);
  return b ^ ((b >> 63) & INT64_MAX);
}
inline f64 Unkey(i64 k) {
  i64 b = k ^ ((k >> 63) & INT64_MAX);
  f64 x;
  std::memcpy(&x, &b, 8);
  return x;
}

// Sorts keys[0..n) in increasing (signed) order; tmp (n) is work space, or nullptr. A least
// significant digit radix sort, a byte a pass, skipping the bytes all keys share (the
// breakpoints of a cone share their sign and most of their exponent): the cone's breakpoints
// number ~1,000, where it takes a third of std::sort's time. The order is the same either way.
void SortKeys(i64* keys, i64 n, i64* tmp) {
  using u64 = std::uint64_t;  // i64's unsigned twin: the same storage may be read as either
  if (tmp == nullptr || n < 64) {
    std::sort(keys, keys + n);
    return;
  }
  constexpr u64 kSign = u64{1} << 63;  // flipped: signed order as unsigned order
  u64* src = reinterpret_cast<u64*>(keys);
  u64* dst = reinterpret_cast<u64*>(tmp);
  i64 count[8][257] = {};  // every byte's counts, in one pass over the keys
  for (i64 i = 0; i < n; i++) {
    u64 k = src[i] ^ kSign;
    for (int byte = 0; byte < 8; byte++) count[byte][((k >> (8 * byte)) & 255) + 1]++;
  }
  for (int byte = 0; byte < 8; byte++) {
    i64* at = count[byte];
    bool shared = false;
    for (int b = 1; b <= 256 && !shared; b++) shared = at[b] == n;
    if (shared) continue;
    for (int b = 0; b < 256; b++) at[b + 1] += at[b];
    for (i64 i = 0; i < n; i++) dst[at[((src[i] ^ kSign) >> (8 * byte)) & 255]++] = src[i];
    std::swap(src, dst);
  }
  if (src != reinterpret_cast<u64*>(keys)) std::memcpy(keys, src, sizeof(i64) * n);
}

// The rim of a deposit: vertex box (r0, r1, c0, c1) and the seed offsets there [m] (rows of
// wcol doubles kept bit for bit in work[0..n); +inf where no rim vertex).
struct Seeds {
  i64 r0, r1, c0, c1, wcol, n;
};

// Rows (of a box) where a distance fell in a pass of the cone's distance transform; lo > hi:
// none.
struct Fell {
  i64 lo, hi;
};

// One raster pass of the cone's distance transform over nr rows of nc distances [m] (doubles
// kept bit for bit in dist, row-major): forward (rows downwards, each vertex from the row before
// it and then from its left neighbour) or backward (rows upwards, from the row after it and its
// right neighbour); x, y and diagonal steps dx, dy, dd [m]. It starts at row from and goes on
// past row to only while the row before fell: the rows that the last pass the other way changed
// (and the one after them) are the only ones whose neighbours changed since this direction last
// ran. A vertex takes the least of its own distance and each neighbour's plus the step; min is
// exact, so neither the order of the candidates nor skipping a row none of whose neighbours
// changed alters the result: every schedule ends at the least sum over the paths from the seeds.
Fell DistancePass(i64* dist, i64 nr, i64 nc, f64 dx, f64 dy, f64 dd, bool forward, i64 from,
                  i64 to) {
  auto load = [](const i64* p) {
    f64 x;
    std::memcpy(&x, p, 8);
    return x;
  };
  auto store = [](i64* p, f64 x) { std::memcpy(p, &x, 8); };
  Fell out{nr, -1};
  const i64 step = forward ? 1 : -1;
  bool before = false;  // whether the row before fell in this pass
  for (i64 r = from; r >= 0 && r < nr; r += step) {
    if ((forward ? r > to : r < to) && !before) break;
    i64* row = dist + r * nc;
    bool fell = false;
    i64 p = r - step;  // the row before
    if (p >= 0 && p < nr) {
      const i64* prev = dist + p * nc;
      for (i64 c = 0; c < nc; c++) {
        f64 x0 = load(row + c);
        f64 x = std::min(x0, load(prev + c) + dy);
        if (c > 0) x = std::min(x, load(prev + c - 1) + dd);
        if (c + 1 < nc) x = std::min(x, load(prev + c + 1) + dd);
        fell |= x < x0;
        store(row + c, x);
      }
    }
    if (forward) {
      for (i64 c = 1; c < nc; c++) {
        f64 x0 = load(row + c), x = std::min(x0, load(row + c - 1) + dx);
        fell |= x < x0;
        store(row + c, x);
      }
    } else {
      for (i64 c = nc - 2; c >= 0; c--) {
        f64 x0 = load(row + c), x = std::min(x0, load(row + c + 1) + dx);
        fell |= x < x0;
        store(row + c, x);
      }
    }
    if (fell) {
      out.lo = std::min(out.lo, r);
      out.hi = std::max(out.hi, r);
    }
    before = fell;
  }
  return out;
}

// Lays height target [m] (volume / cell area) of loose material on the surface as a cone at
// the repose slope around the seeds: every free vertex v near them rises to
// min(max(h_v, H - tan(repose) d_v), floor_v), d_v its distance [m] to the nearest seed along
// the grid's x, y and diagonal steps plus that seed's offset, H the height that conserves the
// volume. The cone's slope between neighbours is the repose slope or less, so the surface
// stays at repose wherever it was (no pair the cone raised is steeper than either the cone or
// the old surface) and the relaxation has nothing to move but the intruders' walls. Works over
// the seeds' box grown until the cone ends inside it; returns false (nothing laid) if that box
// does not fit in work. Material beyond what the free vertices hold under intruders' floors is
// counted in kStatUnplaced.
bool Cone(const f64* prm, const f64* grid, f64* soil, const f64* floor, const Seeds& sd, f64 target,
          f64 height_guess, f64* stats, i64* work, i64 nwork) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  f64 t = prm[surface::kTanRepose];
  const f64 dx = prm[kDx], dy = prm[kDy], dd = std::hypot(dx, dy);
  auto getw = [&](i64 r, i64 c) {
    f64 w;
    std::memcpy(&w, work + (r - sd.r0) * sd.wcol + (c - sd.c0), 8);
    return w;
  };
  // Room for a cone twice the guess's height: a box that is too small is done again larger.
  i64 grow = static_cast<i64>(std::ceil(2.0 * height_guess / (t * std::min(dx, dy)))) + 2;
  for (;;) {
    i64 b0 = std::max<i64>(1, sd.r0 - grow), b1 = std::min<i64>(nrow - 2, sd.r1 + grow);
    i64 a0 = std::max<i64>(1, sd.c0 - grow), a1 = std::min<i64>(ncol - 2, sd.c1 + grow);
    i64 bcol = a1 - a0 + 1, nb = (b1 - b0 + 1) * bcol;
    if (sd.n + 3 * nb > nwork) return false;
    i64* dist = work + sd.n;  // distances [m] as doubles, then the breakpoints' keys
    auto at = [&](i64 r, i64 c) -> i64* { return dist + (r - b0) * bcol + (c - a0); };
    auto getd = [&](i64 r, i64 c) {
      f64 x;
      std::memcpy(&x, at(r, c), 8);
      return x;
    };
    auto putd = [&](i64 r, i64 c, f64 x) { std::memcpy(at(r, c), &x, 8); };
    // Vertex (r, c)'s surface h [m], its room under an intruder's floor, cap = floor - h [m]
    // (+inf: none; below kSoilContact: a wall), and the cone's base there, a = h + t d [m].
    struct Column {
      f64 h, cap, a;
    };
    auto column = [&](i64 r, i64 c) {
      i64 v = r * ncol + c;
      f64 h = grid[v] + soil[kSoilHead + v];
      return Column{h, floor[v] - h, h + t * getd(r, c)};
    };
    for (i64 r = b0; r <= b1; r++) {
      for (i64 c = a0; c <= a1; c++) {
        bool in = r >= sd.r0 && r <= sd.r1 && c >= sd.c0 && c <= sd.c1;
        putd(r, c, in ? getw(r, c) : kInf);
      }
    }
    // Distance along the grid's steps between free vertices (a column an intruder presses on is
    // a wall the material goes around): a forward and a backward pass over the box, then passes
    // each way over the rows the last one changed until nothing changes (around walls). A wall
    // holds NaN: min(x, NaN + step) is x, and a NaN is never replaced (x < NaN is false), so the
    // passes need not test for walls; every later use skips the walls by their capacity (cap <
    // kSoilContact).
    for (i64 r = b0; r <= b1; r++) {
      for (i64 c = a0; c <= a1; c++) {
        i64 v = r * ncol + c;
        if (floor[v] < grid[v] + soil[kSoilHead + v] + kSoilContact) putd(r, c, kNaN);
      }
    }
    i64 brow = b1 - b0 + 1;
    DistancePass(dist, brow, bcol, dx, dy, dd, true, 0, brow - 1);
    Fell fell = DistancePass(dist, brow, bcol, dx, dy, dd, false, brow - 1, 0);
    for (bool forward = true; fell.lo <= fell.hi; forward = !forward) {
      fell = forward ? DistancePass(dist, brow, bcol, dx, dy, dd, true, fell.lo, fell.hi + 1)
                     : DistancePass(dist, brow, bcol, dx, dy, dd, false, fell.hi, fell.lo - 1);
    }
    // Each free vertex holds clamp(H - a, 0, cap), a = h + t d, cap = floor - h: the volume is
    // piecewise linear in H, rising by one at each a and falling by one at each a + cap. A
    // bracket first (a pass per doubling), then the breakpoints below it, sorted.
    f64 amin = kInf, room = 0.0;
    bool open = false;
    for (i64 r = b0; r <= b1; r++) {
      for (i64 c = a0; c <= a1; c++) {
        Column k = column(r, c);
        if (k.cap < kSoilContact || !std::isfinite(k.a)) continue;
        amin = std::min(amin, k.a);
        if (k.cap < kInf) {
          room += k.cap;
        } else {
          open = true;
        }
      }
    }
    bool fits = open || room >= target;
    f64 top = amin;
    if (fits) {
      f64 inc = std::max(2.0 * height_guess, 1e-9);
      for (;;) {
        f64 hb = amin + inc, vol = 0.0;
        for (i64 r = b0; r <= b1; r++) {
          for (i64 c = a0; c <= a1; c++) {
            Column k = column(r, c);
            if (k.cap < kSoilContact) continue;
            f64 q = std::min(hb - k.a, k.cap);
            if (q > 0.0) vol += q;
          }
        }
        if (vol >= target) break;
        inc *= 2.0;
      }
      f64 hb = amin + inc;
      i64* starts = dist + nb;
      i64* ends = starts + nb;
      i64 m = 0, p = 0;
      for (i64 r = b0; r <= b1; r++) {
        for (i64 c = a0; c <= a1; c++) {
          Column k = column(r, c);
          if (k.cap < kSoilContact || !(k.a < hb)) continue;
          starts[m++] = Key(k.a);
          if (k.a + k.cap < hb) ends[p++] = Key(k.a + k.cap);
        }
      }
      i64* spare = sd.n + 4 * nb <= nwork ? ends + nb : nullptr;
      SortKeys(starts, m, spare);
      SortKeys(ends, p, spare);
      f64 held = 0.0, x = Unkey(starts[0]);
      i64 slope = 0, i = 0, j = 0;
      top = hb;
      for (;;) {
        f64 si = i < m ? Unkey(starts[i]) : hb, ej = j < p ? Unkey(ends[j]) : hb;
        f64 next = std::min(si, ej);
        if (slope > 0 && held + slope * (next - x) >= target) {
          top = x + (target - held) / static_cast<f64>(slope);
          break;
        }
        if (i >= m && j >= p) break;  // rounding: the bracket's top
        held += slope * (next - x);
        x = next;
        if (i < m && si <= ej) {
          slope++;
          i++;
        } else {
          slope--;
          j++;
        }
      }
    }
    // The cone must end inside the box (where it does not, a larger box): the box's border, but
    // where it is the grid's, takes nothing.
    bool spills = false;
    bool whole = b0 == 1 && b1 == nrow - 2 && a0 == 1 && a1 == ncol - 2;
    for (i64 r = b0; r <= b1 && !spills && !whole; r++) {
      for (i64 c = a0; c <= a1; c++) {
        bool border = (r == b0 && b0 > 1) || (r == b1 && b1 < nrow - 2) || (c == a0 && a0 > 1) ||
                      (c == a1 && a1 < ncol - 2);
        if (!border) continue;
        Column k = column(r, c);
        if (fits && k.cap >= kSoilContact && top > k.a) {
          spills = true;
          break;
        }
      }
    }
    if ((spills || !fits) && !whole) {
      grow = 2 * grow + 1;
      continue;
    }
    f64 laid = 0.0;
    for (i64 r = b0; r <= b1; r++) {
      for (i64 c = a0; c <= a1; c++) {
        Column k = column(r, c);
        if (k.cap < kSoilContact) continue;
        f64 q = fits ? std::min(top - k.a, k.cap) : k.cap;
        if (q > 0.0 && std::isfinite(k.a)) {
          soil[kSoilHead + r * ncol + c] += q;
          laid += q;
        }
      }
    }
    if (!fits) stats[kStatUnplaced] += (target - laid) * dx * dy;
    return true;
  }
}

}  // namespace

void Deposit(const f64* prm, const f64* grid, f64* soil, const f64* floor, const i64* owner,
             const f64* box, i64 k, f64 vol, f64 mx, f64 my, const f64* v, f64* stats, i64* work) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  f64 vh = std::hypot(v[0], v[1]);
  f64 s = vh + std::abs(v[2]) > 0.0 ? vh / (vh + std::abs(v[2])) : 0.0;
  f64 ux = vh > 0.0 ? v[0] / vh : 0.0;
  f64 uy = vh > 0.0 ? v[1] / vh : 0.0;
  i64 r0 = std::max<i64>(1, static_cast<i64>(box[0]) - 1);
  i64 r1 = std::min<i64>(nrow - 2, static_cast<i64>(box[1]) + 1);
  i64 c0 = std::max<i64>(1, static_cast<i64>(box[2]) - 1);
  i64 c1 = std::min<i64>(ncol - 2, static_cast<i64>(box[3]) + 1);
  i64 wcol = std::max<i64>(0, c1 - c0 + 1);
  // The rim is chosen before anything is deposited: material landing under a hovering intruder
  // can bring that vertex into contact and make its neighbours rim vertices, and weights summed
  // over one rim but spent over another would not conserve the volume. The weights are doubles
  // kept bit for bit in the i64 work array.
  auto put = [&](i64 r, i64 c, f64 w) { std::memcpy(work + (r - r0) * wcol + (c - c0), &w, 8); };
  auto get = [&](i64 r, i64 c) {
    f64 w;
    std::memcpy(&w, work + (r - r0) * wcol + (c - c0), 8);
    return w;
  };
  for (bool open_sky : {true, false}) {
    f64 total = 0.0;
    for (i64 r = r0; r <= r1; r++) {
      for (i64 c = c0; c <= c1; c++) {
        put(r, c, 0.0);
        if (!Rim(prm, grid, soil, floor, owner, r, c, k, open_sky)) continue;
        f64 ex = prm[kX0] + c * prm[kDx] - mx, ey = prm[kY0] + r * prm[kDy] - my;
        f64 e = std::hypot(ex, ey);
        f64 cos = e > 0.0 ? (ex * ux + ey * uy) / e : 0.0;
        f64 w = (1.0 - s) + 2.0 * s * std::max(0.0, cos);
        put(r, c, w);
        total += w;
      }
    }
    if (total > 0.0) {
      // Seeds: each rim vertex, offset by the footprint's extent times how little of the motion
      // points its way (a vertical press: none; ahead of a dragged blade: none; behind it: the
      // whole extent, so the cone rises ahead of the motion and not behind).
      f64 wmax = 0.0;
      i64 nrim = 0;
      for (i64 r = r0; r <= r1; r++) {
        for (i64 c = c0; c <= c1; c++) {
          wmax = std::max(wmax, get(r, c));
          nrim += Rim(prm, grid, soil, floor, owner, r, c, k, open_sky) ? 1 : 0;
        }
      }
      f64 extent = std::max((box[1] - box[0] + 1.0) * prm[kDy], (box[3] - box[2] + 1.0) * prm[kDx]);
      for (i64 r = r0; r <= r1; r++) {
        for (i64 c = c0; c <= c1; c++) {
          bool rim = Rim(prm, grid, soil, floor, owner, r, c, k, open_sky);
          put(r, c, rim ? (1.0 - get(r, c) / wmax) * extent : kInf);
        }
      }
      // A guess of the cone's height: the volume as a ridge of triangular section along a rim
      // of nrim cells, V = rim length x H^2 / (2 tan).
      f64 cell = std::max(prm[kDx], prm[kDy]);
      f64 guess = std::sqrt(2.0 * prm[surface::kTanRepose] * vol / (nrim * cell));
      Seeds sd{r0, r1, c0, c1, wcol, (r1 - r0 + 1) * wcol};
      f64 target = vol / (prm[kDx] * prm[kDy]);
      if (Cone(prm, grid, soil, floor, sd, target, guess, stats, work, nrow * ncol)) return;
      // No room for the cone's box in the work array: the rim takes it all, by weight.
      for (i64 r = r0; r <= r1; r++) {
        for (i64 c = c0; c <= c1; c++) {
          f64 off = get(r, c);
          if (off < kInf) put(r, c, wmax * (1.0 - off / extent));
        }
      }
      f64 sum = 0.0;
      for (i64 r = r0; r <= r1; r++) {
        for (i64 c = c0; c <= c1; c++) sum += get(r, c) < kInf ? get(r, c) : 0.0;
      }
      f64 scale = target / sum;
      for (i64 r = r0; r <= r1; r++) {
        for (i64 c = c0; c <= c1; c++) {
          f64 w = get(r, c);
          if (w < kInf) soil[kSoilHead + r * ncol + c] += w * scale;
        }
      }
      return;
    }
  }
  stats[kStatUnplaced] += vol;
}

bool Relax(const f64* prm, const f64* grid, f64* soil, const f64* floor, i64* mark, i64* queue,
           const f64* boxes, i64 nbox, f64* pending, f64* top, f64* stats) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  Offsets o = OffsetsOf(prm);
  f64 t = prm[surface::kTanRepose];
  const f64 lim[3] = {t * prm[kDx], t * prm[kDy], t * std::hypot(prm[kDx], prm[kDy])};
  Queue q{queue, nrow * ncol};
  // Settles vertex (r, c) with its neighbours at steps (row step, column step, limit kind), in
  // order; false (nothing done) if an intruder presses on it.
  auto settle = [&](i64 r, i64 c, const auto& steps) {
    Vertex vi = Free(grid, soil, o.oh, floor, r, c, ncol);
    if (!vi.free) return false;
    f64 hi = vi.h;
    for (const auto& n : steps) {
      hi = SettleInto(grid, soil, o, floor, mark, nrow, ncol, lim[n[2]], q, top, r * ncol + c, r, c,
                      hi, vi.f, n[0], n[1]);
    }
    return true;
  };
  // The sweeps: each pair of a box once.
  i64 area = 0;
  for (i64 b = 0; b < nbox; b++) {
    const f64* box = boxes + 4 * b;
    i64 r0 = std::max<i64>(1, static_cast<i64>(box[0]));
    i64 r1 = std::min<i64>(nrow - 2, static_cast<i64>(box[1]));
    i64 c0 = std::max<i64>(1, static_cast<i64>(box[2]));
    i64 c1 = std::min<i64>(ncol - 2, static_cast<i64>(box[3]));
    if (r0 > r1 || c0 > c1) continue;
    area += (r1 - r0 + 1) * (c1 - c0 + 1);
    for (i64 r = r0; r <= r1; r++) {
      for (i64 c = c0; c <= c1; c++) settle(r, c, kSweep);
    }
  }
  // Then vertex by vertex wherever material moved.
  i64 visits = 4 * area;
  const i64 budget = kMaxSweeps * visits;
  while (q.count > 0 && visits < budget) {
    i64 i = q.Pop();
    mark[i] = -1;
    if (settle(i / ncol, i % ncol, kNeighbours)) visits += 8;
  }
  stats[kStatVisits] += static_cast<f64>(visits);
  pending[0] = pending[2] = static_cast<f64>(INT32_MAX);
  pending[1] = pending[3] = -1.0;
  if (q.count == 0) return true;
  // What is left waits for the next update (its box).
  for (i64 k = 0; k < q.count; k++) {
    i64 i = q.At(k);
    mark[i] = -1;
    Union(pending, static_cast<f64>(i / ncol), static_cast<f64>(i / ncol),
          static_cast<f64>(i % ncol), static_cast<f64>(i % ncol));
  }
  stats[kStatUnrelaxed] += 1;
  return false;
}

void Mark(const f64* prm, const f64* grid, f64* soil, const f64* floor, const i64* owner,
          const f64* boxes, i64 nbox) {
  i64 ncol = static_cast<i64>(prm[kNcol]);
  f64* q = soil + kSoilHead + 3 * ncol * static_cast<i64>(prm[kNrow]);
  for (i64 k = 0; k < nbox; k++) {
    const f64* box = boxes + 4 * k;
    for (i64 r = static_cast<i64>(box[0]); r <= static_cast<i64>(box[1]); r++) {
      for (i64 c = static_cast<i64>(box[2]); c <= static_cast<i64>(box[3]); c++) {
        i64 v = r * ncol + c;
        if (owner[v] == k && Contact(prm, grid, soil, floor, r, c)) q[v] = static_cast<f64>(k + 1);
      }
    }
  }
}

void Unmark(const f64* prm, f64* soil, i64 r0, i64 r1, i64 c0, i64 c1) {
  i64 ncol = static_cast<i64>(prm[kNcol]);
  f64* q = soil + kSoilHead + 3 * ncol * static_cast<i64>(prm[kNrow]);
  for (i64 r = r0; r <= r1; r++) {
    for (i64 c = c0; c <= c1; c++) q[r * ncol + c] = 0.0;
  }
}

void Finish(const f64* prm, const f64* grid, f64* soil, f64* floor, i64* owner, const f64* boxes,
            i64 nbox, f64 top, f64 time) {
  i64 ncol = static_cast<i64>(prm[kNcol]), nrow = static_cast<i64>(prm[kNrow]);
  for (i64 b = 0; b < nbox; b++) {
    const f64* box = boxes + 4 * b;
    if (box[0] > box[1] || box[2] > box[3]) continue;
    i64 r0 = std::max<i64>(0, static_cast<i64>(box[0]) - 1);
    i64 r1 = std::min<i64>(nrow - 1, static_cast<i64>(box[1]) + 1);
    i64 c0 = std::max<i64>(0, static_cast<i64>(box[2]) - 1);
    i64 c1 = std::min<i64>(ncol - 1, static_cast<i64>(box[3]) + 1);
    for (i64 r = r0; r <= r1; r++) {
      for (i64 c = c0; c <= c1; c++) {
        top = std::max(top, grid[r * ncol + c] + soil[kSoilHead + r * ncol + c]);
        floor[r * ncol + c] = kInf;
        owner[r * ncol + c] = -1;
      }
    }
  }
  soil[surface::kSoilZoff] = std::max(soil[surface::kSoilZoff], top - prm[surface::kZmax]);
  soil[surface::kSoilDone] = 1.0;
  soil[surface::kSoilTime] = time;
}

}  // namespace mjrft::soil
