"""The deforming ground (engine/soil.cc, engine/deform.cc) as a Warp kernel: one thread per world.

Each world has its own height grid with memory (the engine's soil block: offsets of the surface
h and the compacted level c, and the memory p, per vertex; docs/terrain.md). At the first pass
of a new time (or every ``deform_every`` steps) the ground follows the intruders, with the
engine's rules step for step: footprints (the downward-facing triangles rasterised onto the
vertices below them), excavation of the occupied columns down to the floor (which remembers the
depth reference), deposition of the cut volume on the footprint's rim, weighted towards the
horizontal motion, and relaxation to the angle of repose (a sweep, then a first-in first-out
queue of the vertices that moved, within a work budget). The update is serial by nature (the
queue's order decides where material goes), so a world's update runs in one thread, in the
engine's order, and gives the engine's ground on the same configurations.

World frame, SI units. Arrays per world: rows of ``Ground``'s 2D arrays.
"""

from __future__ import annotations

import warp as wp

from mjrft.core import soil as core_soil
from mjrft.core import surface as cs
from mjrft.warp import surface
from mjrft.warp.law import f64
from mjrft.warp.lowspeed import Elements, Medium, widen, widen_mat
from mjrft.warp.surface import Surface

_Z = wp.constant(f64(0.0))
_INF = wp.constant(f64(float("inf")))
_BIG = wp.constant(f64(2147483647.0))
EDGE_SLACK = wp.constant(f64(core_soil.EDGE_SLACK))
SLOPE_SLACK = wp.constant(f64(core_soil.SLOPE_SLACK))
MAX_SWEEPS = wp.constant(int(core_soil.MAX_SWEEPS))
QUEUED = wp.constant(-2)
SOIL_DONE = wp.constant(cs.SOIL_DONE)
SOIL_TIME = wp.constant(cs.SOIL_TIME)
SOIL_PENDING = wp.constant(cs.SOIL_PENDING)
SOIL_FOOT = wp.constant(cs.SOIL_FOOT)
SOIL_ZOFF = wp.constant(cs.SOIL_ZOFF)
SOIL_HEAD = wp.constant(cs.SOIL_HEAD)
N_STATS = core_soil.N_SOIL_STATS
#: Slots of the counters (engine soil.h SoilStat).
UPDATES, EXCAVATED, UNPLACED, UNRELAXED, RASTERISED, EDGE = (wp.constant(i) for i in range(6))


@wp.struct
class Ground:
    """Per-world state and work of the deforming ground (rows: worlds): floor (n) [m], owner
    (n), queue (n), work (n) the rim's weights, box (4 (nk + 3)) vertex boxes (r0, r1, c0, c1),
    stats (6) the counters, status (nworld) -1 or the tagged body below the medium's bottom;
    the block itself is the surface's ``soil``. Tables: elem_vert (nelem, 9) each triangle's
    corners, body frame [m]; zlo [m] the medium's bottom; nk."""

    floor: wp.array2d(dtype=f64)
    owner: wp.array2d(dtype=int)
    queue: wp.array2d(dtype=int)
    work: wp.array2d(dtype=f64)
    box: wp.array2d(dtype=f64)
    stats: wp.array2d(dtype=f64)
    status: wp.array(dtype=int)
    elem_vert: wp.array2d(dtype=f64)
    zlo: f64
    nk: int


@wp.func
def union(gr: Ground, w: int, at: int, r0: f64, r1: f64, c0: f64, c1: f64):
    """Grows the box at gr.box[w, at:at + 4] over rows r0..r1, columns c0..c1 (engine Union)."""
    if r0 <= r1 and c0 <= c1:
        gr.box[w, at] = wp.min(gr.box[w, at], r0)
        gr.box[w, at + 1] = wp.max(gr.box[w, at + 1], r1)
        gr.box[w, at + 2] = wp.min(gr.box[w, at + 2], c0)
        gr.box[w, at + 3] = wp.max(gr.box[w, at + 3], c1)


@wp.func
def empty(gr: Ground, w: int, at: int):
    gr.box[w, at] = _BIG
    gr.box[w, at + 1] = -f64(1.0)
    gr.box[w, at + 2] = _BIG
    gr.box[w, at + 3] = -f64(1.0)


@wp.func
def oh(sf: Surface, i: int) -> int:
    return SOIL_HEAD + i


@wp.func
def contact(sf: Surface, gr: Ground, w: int, r: int, c: int) -> bool:
    """An intruder presses on vertex (r, c): its floor at the surface (engine Contact)."""
    i = r * sf.ncol + c
    return gr.floor[w, i] < sf.grid[r, c] + sf.soil[w, SOIL_HEAD + i] + surface.SOIL_CONTACT


@wp.func
def rim(sf: Surface, gr: Ground, w: int, r: int, c: int, k: int, open_sky: bool) -> bool:
    """Vertex (r, c) is free of contact (and of any intruder over it if open_sky) and borders a
    vertex intruder k presses on (engine Rim)."""
    i = r * sf.ncol + c
    if (open_sky and gr.floor[w, i] < _INF) or contact(sf, gr, w, r, c):
        return False
    for a in range(-1, 2):
        for b in range(-1, 2):
            if gr.owner[w, (r + a) * sf.ncol + c + b] == k and contact(sf, gr, w, r + a, c + b):
                return True
    return False


@wp.func
def move(sf: Surface, w: int, n: int, i: int, j: int, q: f64):
    """Moves height q [m] from vertex i to j; an eroded vertex's compacted level follows its
    surface down (engine Move)."""
    sf.soil[w, SOIL_HEAD + i] = sf.soil[w, SOIL_HEAD + i] - q
    sf.soil[w, SOIL_HEAD + j] = sf.soil[w, SOIL_HEAD + j] + q
    if sf.soil[w, SOIL_HEAD + i] < sf.soil[w, SOIL_HEAD + n + i]:
        sf.soil[w, SOIL_HEAD + n + i] = sf.soil[w, SOIL_HEAD + i]


@wp.func
def settle_pair(sf: Surface, w: int, n: int, i: int, hi: f64, fi: f64, j: int, hj: f64,
                fj: f64, lim: f64) -> f64:  # fmt: skip
    """Material moved between free vertices i and j so that they differ by at most lim [m]
    (engine SettlePair); returns the height moved."""
    diff = hi - hj
    if diff > lim + SLOPE_SLACK:
        if fj < _INF and fi == _INF and hi > fj:
            return _Z
        q = wp.min(f64(0.5) * (diff - lim), fj - hj)
        move(sf, w, n, i, j, q)
        return q
    if -diff > lim + SLOPE_SLACK:
        if fi < _INF and fj == _INF and hj > fi:
            return _Z
        q = wp.min(f64(0.5) * (-diff - lim), fi - hi)
        move(sf, w, n, j, i, q)
        return q
    return _Z


@wp.func
def height_at(sf: Surface, w: int, r: int, c: int) -> f64:
    return sf.grid[r, c] + sf.soil[w, SOIL_HEAD + r * sf.ncol + c]


@wp.func
def push(sf: Surface, gr: Ground, w: int, tail: int, count: int, i: int, r: int, c: int,
         seen: int):  # fmt: skip
    """Appends vertex i to world w's queue unless it waits already; returns (tail, count)."""
    n = sf.ncol * sf.nrow
    if gr.owner[w, i] == QUEUED:
        return tail, count
    gr.queue[w, tail] = i
    gr.owner[w, i] = QUEUED
    union(gr, w, seen, f64(r), f64(r), f64(c), f64(c))
    return (tail + 1) % n, count + 1


@wp.func
def settle_into(sf: Surface, gr: Ground, w: int, lim: f64, tail: int, count: int, seen: int,
                i: int, r: int, c: int, hi: f64, fi: f64, a: int, b: int):  # fmt: skip
    """Settles free vertex i (row r, column c) with its neighbour (r + a, c + b); queues both if
    material moved (engine SettleInto). Returns (tail, count)."""
    rr = r + a
    cc = c + b
    if rr < 1 or rr > sf.nrow - 2 or cc < 1 or cc > sf.ncol - 2:
        return tail, count
    j = rr * sf.ncol + cc
    hj = height_at(sf, w, rr, cc)
    fj = gr.floor[w, j]
    if not (fj >= hj + surface.SOIL_CONTACT):
        return tail, count
    if settle_pair(sf, w, sf.ncol * sf.nrow, i, hi, fi, j, hj, fj, lim) <= _Z:
        return tail, count
    t2, c2 = push(sf, gr, w, tail, count, j, rr, cc, seen)
    return push(sf, gr, w, t2, c2, i, r, c, seen)


@wp.func
def limit(sf: Surface, kind: int) -> f64:
    """Repose limit [m] of a pair along x (0), y (1) or a diagonal (2)."""
    if kind == 0:
        return sf.tan_repose * sf.dx
    if kind == 1:
        return sf.tan_repose * sf.dy
    return sf.tan_repose * wp.sqrt(sf.dx * sf.dx + sf.dy * sf.dy)


@wp.func
def relax(sf: Surface, gr: Ground, w: int, bx: int, seen: int) -> bool:
    """Relaxes world w's surface from the vertices of the box at bx to the angle of repose, or
    until the budget is spent (engine Relax); True if it converged."""
    ncol = sf.ncol
    nrow = sf.nrow
    n = ncol * nrow
    r0 = wp.max(1, int(gr.box[w, bx]))
    r1 = wp.min(nrow - 2, int(gr.box[w, bx + 1]))
    c0 = wp.max(1, int(gr.box[w, bx + 2]))
    c1 = wp.min(ncol - 2, int(gr.box[w, bx + 3]))
    if r0 > r1 or c0 > c1:
        return True
    union(gr, w, seen, f64(r0), f64(r1), f64(c0), f64(c1))
    budget = MAX_SWEEPS * 4 * (r1 - r0 + 1) * (c1 - c0 + 1)
    tail = int(0)
    count = int(0)
    for r in range(r0, r1 + 1):  # the sweep: right, up, up-right, up-left
        for c in range(c0, c1 + 1):
            i = r * ncol + c
            hi = height_at(sf, w, r, c)
            fi = gr.floor[w, i]
            if not (fi >= hi + surface.SOIL_CONTACT):
                continue
            tail, count = settle_into(sf, gr, w, limit(sf, 0), tail, count, seen, i, r, c, hi,
                                      fi, 0, 1)  # fmt: skip
            hi = height_at(sf, w, r, c)
            tail, count = settle_into(sf, gr, w, limit(sf, 1), tail, count, seen, i, r, c, hi,
                                      fi, 1, 0)  # fmt: skip
            hi = height_at(sf, w, r, c)
            tail, count = settle_into(sf, gr, w, limit(sf, 2), tail, count, seen, i, r, c, hi,
                                      fi, 1, 1)  # fmt: skip
            hi = height_at(sf, w, r, c)
            tail, count = settle_into(sf, gr, w, limit(sf, 2), tail, count, seen, i, r, c, hi,
                                      fi, 1, -1)  # fmt: skip
    visits = 4 * (r1 - r0 + 1) * (c1 - c0 + 1)
    while count > 0 and visits < budget:
        i = gr.queue[w, ((tail - count) % n + n) % n]
        count -= 1
        r = i // ncol
        c = i % ncol
        gr.owner[w, i] = -1
        hi = height_at(sf, w, r, c)
        fi = gr.floor[w, i]
        if not (fi >= hi + surface.SOIL_CONTACT):
            continue
        for q in range(8):
            a, b, kind = neighbour(q)
            tail, count = settle_into(sf, gr, w, limit(sf, kind), tail, count, seen, i, r, c,
                                      hi, fi, a, b)  # fmt: skip
            hi = height_at(sf, w, r, c)
        visits += 8
    if count == 0:
        return True
    leftover(sf, gr, w, bx, tail, count)
    return False


@wp.func
def neighbour(q: int):
    """Neighbour q of a vertex (engine kNeighbours: right, left, up, down, then the diagonals):
    (row step, column step, limit kind: 0 along x, 1 along y, 2 diagonal)."""
    if q == 0:
        return 0, 1, 0
    if q == 1:
        return 0, -1, 0
    if q == 2:
        return 1, 0, 1
    if q == 3:
        return -1, 0, 1
    if q == 4:
        return 1, 1, 2
    if q == 5:
        return -1, -1, 2
    if q == 6:
        return 1, -1, 2
    return -1, 1, 2


@wp.func
def leftover(sf: Surface, gr: Ground, w: int, bx: int, tail: int, count: int):
    """The vertices still queued leave the queue; box bx becomes their bounding box (what the
    next update relaxes) and the update counts as unrelaxed."""
    ncol = sf.ncol
    n = ncol * sf.nrow
    lo_r = f64(sf.nrow)
    hi_r = -f64(1.0)
    lo_c = f64(ncol)
    hi_c = -f64(1.0)
    for k in range(count):
        i = gr.queue[w, ((tail - count + k) % n + n) % n]
        gr.owner[w, i] = -1
        lo_r = wp.min(lo_r, f64(i // ncol))
        hi_r = wp.max(hi_r, f64(i // ncol))
        lo_c = wp.min(lo_c, f64(i % ncol))
        hi_c = wp.max(hi_c, f64(i % ncol))
    gr.box[w, bx] = lo_r
    gr.box[w, bx + 1] = hi_r
    gr.box[w, bx + 2] = lo_c
    gr.box[w, bx + 3] = hi_c
    gr.stats[w, UNRELAXED] = gr.stats[w, UNRELAXED] + f64(1.0)


@wp.func
def footprint(sf: Surface, gr: Ground, w: int, start: int, stop: int, rot: wp.mat33d,
              pos: wp.vec3d, k: int, kb: int, top: f64) -> int:  # fmt: skip
    """Rasterises intruder k's downward-facing triangles start..stop (engine Footprint);
    returns the number rasterised."""
    ncol = sf.ncol
    nrow = sf.nrow
    done = int(0)
    for i in range(start, stop):
        pa = rot * wp.vec3d(gr.elem_vert[i, 0], gr.elem_vert[i, 1], gr.elem_vert[i, 2]) + pos
        pb = rot * wp.vec3d(gr.elem_vert[i, 3], gr.elem_vert[i, 4], gr.elem_vert[i, 5]) + pos
        pc = rot * wp.vec3d(gr.elem_vert[i, 6], gr.elem_vert[i, 7], gr.elem_vert[i, 8]) + pos
        if wp.min(pa[2], wp.min(pb[2], pc[2])) >= top:
            continue
        ux = pb[0] - pa[0]
        uy = pb[1] - pa[1]
        wx = pc[0] - pa[0]
        wy = pc[1] - pa[1]
        twice = ux * wy - uy * wx
        if twice >= _Z:
            continue
        done += 1
        xmin = wp.min(pa[0], wp.min(pb[0], pc[0]))
        xmax = wp.max(pa[0], wp.max(pb[0], pc[0]))
        ymin = wp.min(pa[1], wp.min(pb[1], pc[1]))
        ymax = wp.max(pa[1], wp.max(pb[1], pc[1]))
        c0 = wp.max(0, int(wp.ceil((xmin - sf.x0) / sf.dx)))
        c1 = wp.min(ncol - 1, int(wp.floor((xmax - sf.x0) / sf.dx)))
        r0 = wp.max(0, int(wp.ceil((ymin - sf.y0) / sf.dy)))
        r1 = wp.min(nrow - 1, int(wp.floor((ymax - sf.y0) / sf.dy)))
        inv = f64(1.0) / twice
        for r in range(r0, r1 + 1):
            qy = sf.y0 + f64(r) * sf.dy - pa[1]
            for c in range(c0, c1 + 1):
                qx = sf.x0 + f64(c) * sf.dx - pa[0]
                b = (qx * wy - qy * wx) * inv
                g = (ux * qy - uy * qx) * inv
                if b < -EDGE_SLACK or g < -EDGE_SLACK or b + g > f64(1.0) + EDGE_SLACK:
                    continue
                z = pa[2] + b * (pb[2] - pa[2]) + g * (pc[2] - pa[2])
                if z < gr.floor[w, r * ncol + c]:
                    gr.floor[w, r * ncol + c] = z
                    gr.owner[w, r * ncol + c] = k
                    union(gr, w, kb, f64(r), f64(r), f64(c), f64(c))
    return done


@wp.struct
class Cut:
    """What excavate cut: vol [m^3] (-1: below the bottom), centroid mx, my [m], velocity v."""

    vol: f64
    mx: f64
    my: f64
    v: wp.vec3d


@wp.func
def excavate(sf: Surface, gr: Ground, w: int, kb: int, k: int, vel: wp.vec3d, om: wp.vec3d,
             ref: wp.vec3d) -> Cut:  # fmt: skip
    """Cuts intruder k's occupied columns down to their floor (engine Excavate); the
    intruder moves with velocity vel at ref and angular velocity om."""
    ncol = sf.ncol
    nrow = sf.nrow
    n = ncol * nrow
    area = sf.dx * sf.dy
    vol = _Z
    mx = _Z
    my = _Z
    mz = _Z
    out = Cut()
    for r in range(int(gr.box[w, kb]), int(gr.box[w, kb + 1]) + 1):
        for c in range(int(gr.box[w, kb + 2]), int(gr.box[w, kb + 3]) + 1):
            i = r * ncol + c
            if gr.owner[w, i] != k:
                continue
            base = sf.grid[r, c]
            h = base + sf.soil[w, SOIL_HEAD + i]
            f = gr.floor[w, i]
            if f >= h:
                continue
            if f < gr.zlo:
                out.vol = -f64(1.0)
                return out
            if r == 0 or c == 0 or r == nrow - 1 or c == ncol - 1:
                gr.stats[w, EDGE] = gr.stats[w, EDGE] + f64(1.0)
                continue
            cut = h - f
            refz = wp.max(
                h, base + sf.soil[w, SOIL_HEAD + n + i] + sf.soil[w, SOIL_HEAD + 2 * n + i]
            )
            sf.soil[w, SOIL_HEAD + i] = f - base
            sf.soil[w, SOIL_HEAD + n + i] = f - base
            sf.soil[w, SOIL_HEAD + 2 * n + i] = refz - f
            vol += cut * area
            mx += cut * area * (sf.x0 + f64(c) * sf.dx)
            my += cut * area * (sf.y0 + f64(r) * sf.dy)
            mz += cut * area * f
    if vol <= _Z:
        return out
    mx = mx / vol
    my = my / vol
    mz = mz / vol
    arm = wp.vec3d(mx, my, mz) - ref
    out.vol = vol
    out.mx = mx
    out.my = my
    out.v = wp.vec3d(
        vel[0] + om[1] * arm[2] - om[2] * arm[1],
        vel[1] + om[2] * arm[0] - om[0] * arm[2],
        vel[2] + om[0] * arm[1] - om[1] * arm[0],
    )
    gr.stats[w, EXCAVATED] = gr.stats[w, EXCAVATED] + vol
    return out


@wp.func
def deposit(sf: Surface, gr: Ground, w: int, kb: int, k: int, cut: Cut):
    """Spreads the cut over the rim of intruder k's footprint, weighted towards the horizontal
    motion (engine Deposit)."""
    ncol = sf.ncol
    nrow = sf.nrow
    v = cut.v
    vh = wp.sqrt(v[0] * v[0] + v[1] * v[1])
    s = _Z
    if vh + wp.abs(v[2]) > _Z:
        s = vh / (vh + wp.abs(v[2]))
    ux = _Z
    uy = _Z
    if vh > _Z:
        ux = v[0] / vh
        uy = v[1] / vh
    r0 = wp.max(1, int(gr.box[w, kb]) - 1)
    r1 = wp.min(nrow - 2, int(gr.box[w, kb + 1]) + 1)
    c0 = wp.max(1, int(gr.box[w, kb + 2]) - 1)
    c1 = wp.min(ncol - 2, int(gr.box[w, kb + 3]) + 1)
    wcol = wp.max(0, c1 - c0 + 1)
    for sky in range(2):
        open_sky = sky == 0
        total = _Z
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                wt = _Z
                if rim(sf, gr, w, r, c, k, open_sky):
                    ex = sf.x0 + f64(c) * sf.dx - cut.mx
                    ey = sf.y0 + f64(r) * sf.dy - cut.my
                    e = wp.sqrt(ex * ex + ey * ey)
                    cs_ = _Z
                    if e > _Z:
                        cs_ = (ex * ux + ey * uy) / e
                    wt = (f64(1.0) - s) + f64(2.0) * s * wp.max(_Z, cs_)
                    total += wt
                gr.work[w, (r - r0) * wcol + (c - c0)] = wt
        if total > _Z:
            scale = cut.vol / (sf.dx * sf.dy) / total
            for r in range(r0, r1 + 1):
                for c in range(c0, c1 + 1):
                    i = SOIL_HEAD + r * ncol + c
                    sf.soil[w, i] = sf.soil[w, i] + gr.work[w, (r - r0) * wcol + (c - c0)] * scale
            return
    gr.stats[w, UNPLACED] = gr.stats[w, UNPLACED] + cut.vol


@wp.func
def head_union(sf: Surface, gr: Ground, w: int, bx: int, at: int):
    """Grows box bx by the vertex box stored in the block's head at at (engine HeadUnion)."""
    if sf.soil[w, at + 1] > sf.soil[w, at] and sf.soil[w, at + 3] > sf.soil[w, at + 2]:
        union(gr, w, bx, sf.soil[w, at], sf.soil[w, at + 1] - f64(1.0), sf.soil[w, at + 2],
              sf.soil[w, at + 3] - f64(1.0))  # fmt: skip


@wp.func
def head_store(sf: Surface, gr: Ground, w: int, at: int, bx: int, keep: bool):
    """Stores box bx in the block's head at at, as zeros if empty or not keep (HeadStore)."""
    if keep and gr.box[w, bx] <= gr.box[w, bx + 1] and gr.box[w, bx + 2] <= gr.box[w, bx + 3]:
        sf.soil[w, at] = gr.box[w, bx]
        sf.soil[w, at + 1] = gr.box[w, bx + 1] + f64(1.0)
        sf.soil[w, at + 2] = gr.box[w, bx + 2]
        sf.soil[w, at + 3] = gr.box[w, bx + 3] + f64(1.0)
    else:
        for c in range(4):
            sf.soil[w, at + c] = _Z


@wp.func
def finish(sf: Surface, gr: Ground, w: int, bx: int, time: f64):
    """Raises the ceiling over box bx, clears floor and owner there and one vertex around it,
    records the time (engine Finish)."""
    ncol = sf.ncol
    nrow = sf.nrow
    top = -_INF
    r0 = wp.max(0, int(gr.box[w, bx]) - 1)
    r1 = wp.min(nrow - 1, int(gr.box[w, bx + 1]) + 1)
    c0 = wp.max(0, int(gr.box[w, bx + 2]) - 1)
    c1 = wp.min(ncol - 1, int(gr.box[w, bx + 3]) + 1)
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            top = wp.max(top, height_at(sf, w, r, c))
            gr.floor[w, r * ncol + c] = _INF
            gr.owner[w, r * ncol + c] = -1
    sf.soil[w, SOIL_ZOFF] = wp.max(sf.soil[w, SOIL_ZOFF], top - sf.zmax)
    sf.soil[w, SOIL_DONE] = f64(1.0)
    sf.soil[w, SOIL_TIME] = time


@wp.func
def footprints(el: Elements, medium: Medium, sf: Surface, gr: Ground, w: int,
               tbody_bodyid: wp.array(dtype=int), xpos: wp.array2d(dtype=wp.vec3),
               xmat: wp.array2d(dtype=wp.mat33), geom_xpos: wp.array2d(dtype=wp.vec3)):  # fmt: skip
    """Rasterises every tagged body's geoms that may touch the medium (not culled, engine
    Culled); box k is body k's footprint, box nk their union (engine Footprints)."""
    nk = gr.nk
    top = surface.ceiling(sf)
    allbox = 4 * nk
    empty(gr, w, allbox)
    for k in range(nk):  # footprints
        kb = 4 * k
        empty(gr, w, kb)
        b = tbody_bodyid[k]
        rot = widen_mat(xmat[w, b])
        pos = widen(xpos[w, b])
        g0 = el.tbody_geomadr[k]
        for g in range(g0, g0 + el.tbody_geomnum[k]):
            r = el.tgeom_rbound[g]
            if r > _Z:  # culled (engine Culled): above the surface or outside the region
                cen = widen(geom_xpos[w, el.tgeom_geomid[g]])
                if cen[2] - r >= surface.highest_near(sf, cen[0], cen[1], r):
                    continue
                if medium.use_region != 0:
                    out = int(0)
                    for q in range(3):
                        if cen[q] + r < medium.region_lo[q] or cen[q] - r > medium.region_hi[q]:
                            out = 1
                    if out != 0:
                        continue
            e0 = el.tgeom_elemadr[g]
            nr = footprint(sf, gr, w, e0, e0 + el.tgeom_elemnum[g], rot, pos, k, kb, top)
            gr.stats[w, RASTERISED] = gr.stats[w, RASTERISED] + f64(nr)
        union(gr, w, allbox, gr.box[w, kb], gr.box[w, kb + 1], gr.box[w, kb + 2],
              gr.box[w, kb + 3])  # fmt: skip


@wp.func
def due(sf: Surface, w: int, now: f64, dt: f64) -> bool:
    """The ground has not yet followed the configuration at time now [s] (engine Due)."""
    last = sf.soil[w, SOIL_TIME]
    if sf.soil[w, SOIL_DONE] == _Z or now < last:
        return True
    if sf.every <= f64(1.0):
        return last != now
    return now - last > (sf.every - f64(0.5)) * dt


@wp.kernel
def deform_kernel(
    # Model
    el: Elements, medium: Medium, tbody_bodyid: wp.array(dtype=int),
    tbody_rootid: wp.array(dtype=int), timestep: wp.array(dtype=float),
    # Data in
    time: wp.array(dtype=float), xpos: wp.array2d(dtype=wp.vec3),
    xmat: wp.array2d(dtype=wp.mat33), cvel: wp.array2d(dtype=wp.spatial_vector),
    subtree_com: wp.array2d(dtype=wp.vec3), geom_xpos: wp.array2d(dtype=wp.vec3),
    # Data in and out
    gr: Ground,
):  # fmt: skip
    """World w's ground follows its intruders' configuration if due (engine deform::Due and
    Update); gr.status[w] gets -1 or the tagged body that reaches below the bottom."""
    w = wp.tid()
    sf = medium.surface
    sf.w = w
    gr.status[w] = -1
    now = f64(time[w])
    if not due(sf, w, now, f64(timestep[w % timestep.shape[0]])):
        return
    nk = gr.nk
    allbox = 4 * nk
    footprints(el, medium, sf, gr, w, tbody_bodyid, xpos, xmat, geom_xpos)
    bad = int(-1)
    for k in range(nk):  # excavation and deposition, intruder by intruder
        kb = 4 * k
        if gr.box[w, kb] > gr.box[w, kb + 1]:
            continue
        b = tbody_bodyid[k]
        tw = cvel[w, b]
        cut = excavate(sf, gr, w, kb, k, wp.vec3d(f64(tw[3]), f64(tw[4]), f64(tw[5])),
                       wp.vec3d(f64(tw[0]), f64(tw[1]), f64(tw[2])),
                       widen(subtree_com[w, tbody_rootid[k]]))  # fmt: skip
        if cut.vol < _Z:
            bad = k
        elif cut.vol > _Z:
            deposit(sf, gr, w, kb, k, cut)
    bx = 4 * (nk + 1)
    seen = 4 * (nk + 2)
    for c in range(4):
        gr.box[w, bx + c] = gr.box[w, allbox + c]
    head_union(sf, gr, w, bx, SOIL_FOOT)
    head_union(sf, gr, w, bx, SOIL_PENDING)
    head_store(sf, gr, w, SOIL_FOOT, allbox, True)
    gr.stats[w, UPDATES] = gr.stats[w, UPDATES] + f64(1.0)
    gr.status[w] = bad
    if gr.box[w, bx] > gr.box[w, bx + 1]:
        sf.soil[w, SOIL_DONE] = f64(1.0)
        sf.soil[w, SOIL_TIME] = now
        return
    gr.box[w, bx] = gr.box[w, bx] - f64(1.0)
    gr.box[w, bx + 1] = gr.box[w, bx + 1] + f64(1.0)
    gr.box[w, bx + 2] = gr.box[w, bx + 2] - f64(1.0)
    gr.box[w, bx + 3] = gr.box[w, bx + 3] + f64(1.0)
    for c in range(4):
        gr.box[w, seen + c] = gr.box[w, bx + c]
    converged = relax(sf, gr, w, bx, seen)
    head_store(sf, gr, w, SOIL_PENDING, bx, not converged)
    finish(sf, gr, w, seen, now)
