"""The deforming ground (engine/soil.cc, engine/deform.cc) as a Warp kernel: one thread per world.

Each world has its own height grid with memory (the engine's soil block: offsets of the surface
h and the compacted level c, and the memory p, per vertex; docs/terrain.md). At the first pass
of a new time (or every ``deform_every`` steps) the ground follows the intruders, with the
engine's rules step for step: footprints (the downward-facing triangles rasterised onto the
vertices below them), excavation of the occupied columns down to the floor (which remembers the
depth reference), deposition of the cut volume as a cone at the repose slope around the
footprint's rim (rising ahead of the horizontal motion; the rim alone, by weight, where the
cone's box does not fit in the work row), and relaxation to within SLOPE_TOLERANCE of the
repose slope (a sweep of each intruder's box, where it is and was, then a first-in first-out
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
SLOPE_TOLERANCE = wp.constant(f64(core_soil.SLOPE_TOLERANCE))
MAX_SWEEPS = wp.constant(int(core_soil.MAX_SWEEPS))
QUEUED = wp.constant(-2)
SOIL_DONE = wp.constant(cs.SOIL_DONE)
SOIL_TIME = wp.constant(cs.SOIL_TIME)
SOIL_PENDING = wp.constant(cs.SOIL_PENDING)
SOIL_FOOT = wp.constant(cs.SOIL_FOOT)
SOIL_ZOFF = wp.constant(cs.SOIL_ZOFF)
SOIL_HEAD = wp.constant(cs.SOIL_HEAD)
SOIL_TRAVEL = wp.constant(cs.SOIL_TRAVEL)
SOIL_CLOCK = wp.constant(cs.SOIL_CLOCK)
N_STATS = core_soil.N_SOIL_STATS
#: Slots of the counters (engine soil.h SoilStat).
UPDATES, EXCAVATED, UNPLACED, UNRELAXED, RASTERISED, EDGE, VISITS = (
    wp.constant(i) for i in range(7)
)
assert N_STATS == 7, "mjrft.core.soil.SOIL_STATS and the slots above"


def box_rows(nk: int) -> int:
    """Vertex boxes (r0, r1, c0, c1) per world in ``Ground.box`` for nk tagged bodies: rows
    0..nk-1 each body's footprint, nk their union, nk + 1..2 nk the footprints of the last
    update, 2 nk + 1 the fingerprint of the state that update left (updates, excavated, time,
    1), 2 nk + 2..3 nk + 3 the relaxation's boxes (one per body, the box left unrelaxed, the
    last footprints' union where they are not known), 3 nk + 4 the box the relaxation leaves
    unrelaxed (engine deform.h's soil_box, and Relax's pending)."""
    return 3 * nk + 5


@wp.struct
class Ground:
    """Per-world state and work of the deforming ground (rows: worlds): floor (n) [m], owner
    (n), queue (n), work (n) the deposit's rim offsets, cone distances and breakpoints, box
    (4 box_rows(nk)) vertex boxes (r0, r1, c0, c1), stats (7) the counters, status (nworld)
    -1 or the tagged body below the medium's bottom; the block itself is the surface's
    ``soil``. Tables: elem_vert (nelem, 9) each triangle's
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
    """If free vertices i and j differ by more than lim [m] (the repose slope's rise between
    them) by more than SLOPE_TOLERANCE of it (at least SLOPE_SLACK), material moves so that
    they differ by lim (engine SettlePair); returns the height moved."""
    diff = hi - hj
    start = lim + wp.max(SLOPE_SLACK, SLOPE_TOLERANCE * lim)
    if diff > start:
        if fj < _INF and fi == _INF and hi > fj:
            return _Z
        q = wp.min(f64(0.5) * (diff - lim), fj - hj)
        move(sf, w, n, i, j, q)
        return q
    if -diff > start:
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
def push(sf: Surface, gr: Ground, w: int, tail: int, count: int, i: int):
    """Appends vertex i to world w's queue unless it waits already; returns (tail, count)."""
    n = sf.ncol * sf.nrow
    if gr.owner[w, i] == QUEUED:
        return tail, count
    gr.queue[w, tail] = i
    gr.owner[w, i] = QUEUED
    return (tail + 1) % n, count + 1


@wp.func
def settle_into(sf: Surface, gr: Ground, w: int, lim: f64, tail: int, count: int, top: f64,
                i: int, r: int, c: int, hi: f64, fi: f64, a: int, b: int):  # fmt: skip
    """Settles free vertex i (row r, column c) with its neighbour (r + a, c + b); if material
    moved, queues both and grows top [m] over their heights (engine SettleInto). Returns
    (tail, count, top)."""
    rr = r + a
    cc = c + b
    if rr < 1 or rr > sf.nrow - 2 or cc < 1 or cc > sf.ncol - 2:
        return tail, count, top
    j = rr * sf.ncol + cc
    hj = height_at(sf, w, rr, cc)
    fj = gr.floor[w, j]
    if not (fj >= hj + surface.SOIL_CONTACT):
        return tail, count, top
    if settle_pair(sf, w, sf.ncol * sf.nrow, i, hi, fi, j, hj, fj, lim) <= _Z:
        return tail, count, top
    up = wp.max(top, wp.max(height_at(sf, w, r, c), height_at(sf, w, rr, cc)))
    t2, c2 = push(sf, gr, w, tail, count, j)
    t3, c3 = push(sf, gr, w, t2, c2, i)
    return t3, c3, up


@wp.func
def limit(sf: Surface, kind: int) -> f64:
    """Repose limit [m] of a pair along x (0), y (1) or a diagonal (2)."""
    if kind == 0:
        return sf.tan_repose * sf.dx
    if kind == 1:
        return sf.tan_repose * sf.dy
    return sf.tan_repose * wp.sqrt(sf.dx * sf.dx + sf.dy * sf.dy)


@wp.func
def sweep_box(sf: Surface, gr: Ground, w: int, bx: int, tail: int, count: int, top: f64):
    """One sweep over the free vertices of box bx (clipped to the grid's inner vertices), each
    pair once: right, up, up-right, up-left (engine Relax's sweeps). Returns (tail, count, top,
    the box's vertices)."""
    ncol = sf.ncol
    nrow = sf.nrow
    r0 = wp.max(1, int(gr.box[w, bx]))
    r1 = wp.min(nrow - 2, int(gr.box[w, bx + 1]))
    c0 = wp.max(1, int(gr.box[w, bx + 2]))
    c1 = wp.min(ncol - 2, int(gr.box[w, bx + 3]))
    if r0 > r1 or c0 > c1:
        return tail, count, top, 0
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            tail, count, top, _free = settle_vertex(sf, gr, w, r, c, True, tail, count, top)
    return tail, count, top, (r1 - r0 + 1) * (c1 - c0 + 1)


@wp.func
def settle_vertex(sf: Surface, gr: Ground, w: int, r: int, c: int, sweep: bool, tail: int,
                  count: int, top: f64):  # fmt: skip
    """Settles vertex (r, c) with its neighbours in order (the sweep's four, else all eight),
    unless an intruder presses on it (engine Relax's settle). Returns (tail, count, top, free)."""
    i = r * sf.ncol + c
    hi = height_at(sf, w, r, c)
    fi = gr.floor[w, i]
    if not (fi >= hi + surface.SOIL_CONTACT):
        return tail, count, top, False
    steps = int(8)
    if sweep:
        steps = 4
    for q in range(steps):
        a, b, kind = neighbour(q)
        if sweep:
            a, b, kind = sweep_step(q)
        tail, count, top = settle_into(sf, gr, w, limit(sf, kind), tail, count, top, i, r, c,
                                       hi, fi, a, b)  # fmt: skip
        hi = height_at(sf, w, r, c)
    return tail, count, top, True


@wp.func
def sweep_step(q: int):
    """Neighbour q of a sweep (engine kSweep: right, up, up-right, up-left): (row step, column
    step, limit kind)."""
    if q == 0:
        return 0, 1, 0
    if q == 1:
        return 1, 0, 1
    if q == 2:
        return 1, 1, 2
    return 1, -1, 2


@wp.func
def relax(sf: Surface, gr: Ground, w: int, at: int, nbox: int, pend: int, top: f64):
    """Relaxes world w's surface from the vertices of the nbox boxes from at to the angle of
    repose, or until the budget (the pair visits of MAX_SWEEPS sweeps of the boxes) is spent
    (engine Relax); box pend gets the slopes left unrelaxed (empty if none), top [m] grows over
    every height material moved into. Returns (converged, top)."""
    ncol = sf.ncol
    n = ncol * sf.nrow
    tail = int(0)
    count = int(0)
    area = int(0)
    for b in range(nbox):  # the sweeps: each pair of a box once
        tail, count, top, cells = sweep_box(sf, gr, w, at + 4 * b, tail, count, top)
        area += cells
    visits = 4 * area
    budget = MAX_SWEEPS * visits
    while count > 0 and visits < budget:  # then vertex by vertex wherever material moved
        i = gr.queue[w, ((tail - count) % n + n) % n]
        count -= 1
        gr.owner[w, i] = -1
        tail, count, top, free = settle_vertex(sf, gr, w, i // ncol, i % ncol, False, tail,
                                               count, top)  # fmt: skip
        if free:
            visits += 8
    gr.stats[w, VISITS] = gr.stats[w, VISITS] + f64(visits)
    empty(gr, w, pend)
    if count == 0:
        return True, top
    leftover(sf, gr, w, pend, tail, count)
    return False, top


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
def leftover(sf: Surface, gr: Ground, w: int, pend: int, tail: int, count: int):
    """The vertices still queued leave the queue; box pend grows over them (what the next
    update relaxes) and the update counts as unrelaxed."""
    ncol = sf.ncol
    n = ncol * sf.nrow
    for k in range(count):
        i = gr.queue[w, ((tail - count + k) % n + n) % n]
        gr.owner[w, i] = -1
        union(gr, w, pend, f64(i // ncol), f64(i // ncol), f64(i % ncol), f64(i % ncol))
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


@wp.struct
class Seeds:
    """The rim of a deposit: vertex box r0..r1 x c0..c1 and its seed offsets [m] in the work row
    (rows of wcol, n values from 0; +inf where no rim vertex) (engine Seeds)."""

    r0: int
    r1: int
    c0: int
    c1: int
    wcol: int
    n: int


@wp.struct
class Span:
    """A cone's vertex box b0..b1 x a0..a1 (rows of bcol) and where its distances [m] start in
    the work row (at; its breakpoints follow at at + nb and at + 2 nb, nb its vertices)."""

    b0: int
    b1: int
    a0: int
    a1: int
    bcol: int
    at: int


@wp.func
def dist(sp: Span, r: int, c: int) -> int:
    """Index in the work row of vertex (r, c)'s cone distance."""
    return sp.at + (r - sp.b0) * sp.bcol + (c - sp.a0)


@wp.func
def relax_dist(sf: Surface, gr: Ground, w: int, sp: Span, r: int, c: int, back: int) -> bool:
    """Shortens vertex (r, c)'s distance through its neighbours already passed (those before it,
    or after it if back is 1); True if it changed."""
    dx = sf.dx
    dy = sf.dy
    dd = wp.sqrt(dx * dx + dy * dy)
    s = 1 - 2 * back
    x0 = gr.work[w, dist(sp, r, c)]
    x = x0
    lo_c = (back == 0 and c > sp.a0) or (back == 1 and c < sp.a1)
    hi_c = (back == 0 and c < sp.a1) or (back == 1 and c > sp.a0)
    if lo_c:
        x = wp.min(x, gr.work[w, dist(sp, r, c - s)] + dx)
    if (back == 0 and r > sp.b0) or (back == 1 and r < sp.b1):
        x = wp.min(x, gr.work[w, dist(sp, r - s, c)] + dy)
        if lo_c:
            x = wp.min(x, gr.work[w, dist(sp, r - s, c - s)] + dd)
        if hi_c:
            x = wp.min(x, gr.work[w, dist(sp, r - s, c + s)] + dd)
    if x < x0:
        gr.work[w, dist(sp, r, c)] = x
        return True
    return False


@wp.func
def cone_distances(sf: Surface, gr: Ground, w: int, sd: Seeds, sp: Span):
    """Each vertex of sp's distance [m] to the nearest seed along the grid's x, y and diagonal
    steps plus the seed's offset, around the columns an intruder presses on (+inf there):
    forward and backward passes until nothing changes (engine Cone)."""
    for r in range(sp.b0, sp.b1 + 1):
        for c in range(sp.a0, sp.a1 + 1):
            x = _INF
            if r >= sd.r0 and r <= sd.r1 and c >= sd.c0 and c <= sd.c1:
                x = gr.work[w, (r - sd.r0) * sd.wcol + (c - sd.c0)]
            if contact(sf, gr, w, r, c):
                x = _INF
            gr.work[w, dist(sp, r, c)] = x
    changed = bool(True)
    while changed:
        changed = bool(False)
        for r in range(sp.b0, sp.b1 + 1):
            for c in range(sp.a0, sp.a1 + 1):
                if not contact(sf, gr, w, r, c):
                    if relax_dist(sf, gr, w, sp, r, c, 0):
                        changed = bool(True)
        for rb in range(sp.b1 - sp.b0 + 1):
            for cb in range(sp.a1 - sp.a0 + 1):
                r = sp.b1 - rb
                c = sp.a1 - cb
                if not contact(sf, gr, w, r, c):
                    if relax_dist(sf, gr, w, sp, r, c, 1):
                        changed = bool(True)


@wp.func
def cone_base(sf: Surface, gr: Ground, w: int, sp: Span, r: int, c: int) -> wp.vec3d:
    """(h, cap, a) [m] of vertex (r, c): its surface, the room under its floor, and the level
    h + tan(repose) d at which the cone reaches it."""
    h = height_at(sf, w, r, c)
    return wp.vec3d(
        h, gr.floor[w, r * sf.ncol + c] - h, h + sf.tan_repose * gr.work[w, dist(sp, r, c)]
    )


@wp.func
def cone_held(sf: Surface, gr: Ground, w: int, sp: Span, hb: f64) -> f64:
    """Height [m] (volume / cell area) the free vertices of sp hold under a cone of top hb."""
    vol = _Z
    for r in range(sp.b0, sp.b1 + 1):
        for c in range(sp.a0, sp.a1 + 1):
            v = cone_base(sf, gr, w, sp, r, c)
            if v[1] < surface.SOIL_CONTACT:
                continue
            q = wp.min(hb - v[2], v[1])
            if q > _Z:
                vol += q
    return vol


@wp.func
def sift(gr: Ground, w: int, at: int, root: int, end: int):
    """Moves work[at + root] down the max-heap work[at..at + end)."""
    r = root
    going = bool(True)
    while going:
        child = 2 * r + 1
        if child >= end:
            going = bool(False)
        else:
            if child + 1 < end and gr.work[w, at + child] < gr.work[w, at + child + 1]:
                child += 1
            if gr.work[w, at + r] < gr.work[w, at + child]:
                tmp = gr.work[w, at + r]
                gr.work[w, at + r] = gr.work[w, at + child]
                gr.work[w, at + child] = tmp
                r = child
            else:
                going = bool(False)


@wp.func
def sort_work(gr: Ground, w: int, at: int, m: int):
    """Sorts work[at..at + m) in ascending order (heapsort: in place, one thread)."""
    start = m // 2 - 1
    while start >= 0:
        sift(gr, w, at, start, m)
        start -= 1
    end = m - 1
    while end > 0:
        tmp = gr.work[w, at]
        gr.work[w, at] = gr.work[w, at + end]
        gr.work[w, at + end] = tmp
        sift(gr, w, at, 0, end)
        end -= 1


@wp.func
def cone_top(sf: Surface, gr: Ground, w: int, sp: Span, target: f64, guess: f64,
             amin: f64) -> f64:  # fmt: skip
    """The cone's top H [m] that holds target [m] (volume / cell area) over sp: each free
    vertex holds clamp(H - a, 0, cap), piecewise linear in H; a bracket by doubling, then the
    breakpoints below it, sorted (engine Cone)."""
    inc = wp.max(f64(2.0) * guess, f64(1e-9))
    while cone_held(sf, gr, w, sp, amin + inc) < target:
        inc *= f64(2.0)
    hb = amin + inc
    nb = (sp.b1 - sp.b0 + 1) * sp.bcol
    starts = sp.at + nb
    ends = starts + nb
    m = int(0)
    p = int(0)
    for r in range(sp.b0, sp.b1 + 1):
        for c in range(sp.a0, sp.a1 + 1):
            v = cone_base(sf, gr, w, sp, r, c)
            if v[1] < surface.SOIL_CONTACT or not (v[2] < hb):
                continue
            gr.work[w, starts + m] = v[2]
            m += 1
            if v[2] + v[1] < hb:
                gr.work[w, ends + p] = v[2] + v[1]
                p += 1
    sort_work(gr, w, starts, m)
    sort_work(gr, w, ends, p)
    held = _Z
    x = gr.work[w, starts]
    slope = int(0)
    i = int(0)
    j = int(0)
    while i < m or j < p:
        si = hb
        if i < m:
            si = gr.work[w, starts + i]
        ej = hb
        if j < p:
            ej = gr.work[w, ends + j]
        nxt = wp.min(si, ej)
        if slope > 0 and held + f64(slope) * (nxt - x) >= target:
            return x + (target - held) / f64(slope)
        held += f64(slope) * (nxt - x)
        x = nxt
        if i < m and si <= ej:
            slope += 1
            i += 1
        else:
            slope -= 1
            j += 1
    if slope > 0 and held + f64(slope) * (hb - x) >= target:
        return x + (target - held) / f64(slope)
    return hb  # rounding: the bracket's top


@wp.func
def cone_spills(sf: Surface, gr: Ground, w: int, sp: Span, top: f64) -> bool:
    """The cone of top [m] reaches sp's border where that is not the grid's (engine Cone)."""
    for r in range(sp.b0, sp.b1 + 1):
        for c in range(sp.a0, sp.a1 + 1):
            border = (r == sp.b0 and sp.b0 > 1) or (r == sp.b1 and sp.b1 < sf.nrow - 2)
            border = border or (c == sp.a0 and sp.a0 > 1) or (c == sp.a1 and sp.a1 < sf.ncol - 2)
            if not border:
                continue
            v = cone_base(sf, gr, w, sp, r, c)
            if v[1] >= surface.SOIL_CONTACT and top > v[2]:
                return True
    return False


@wp.func
def cone(sf: Surface, gr: Ground, w: int, sd: Seeds, target: f64, guess: f64) -> bool:
    """Lays height target [m] (volume / cell area) of loose material as a cone at the repose
    slope around the seeds: every free vertex rises to min(max(h, H - tan(repose) d), floor), H
    conserving the volume, over the seeds' box grown until the cone ends inside it; False
    (nothing laid) if that box does not fit in the work row (engine Cone). What the free
    vertices cannot hold under intruders' floors is counted as unplaced."""
    nrow = sf.nrow
    ncol = sf.ncol
    grow = int(wp.ceil(f64(2.0) * guess / (sf.tan_repose * wp.min(sf.dx, sf.dy)))) + 2
    while True:
        sp = Span()
        sp.b0 = wp.max(1, sd.r0 - grow)
        sp.b1 = wp.min(nrow - 2, sd.r1 + grow)
        sp.a0 = wp.max(1, sd.c0 - grow)
        sp.a1 = wp.min(ncol - 2, sd.c1 + grow)
        sp.bcol = sp.a1 - sp.a0 + 1
        sp.at = sd.n
        nb = (sp.b1 - sp.b0 + 1) * sp.bcol
        if sd.n + 3 * nb > nrow * ncol:
            return False
        cone_distances(sf, gr, w, sd, sp)
        amin = _INF
        room = _Z
        is_open = bool(False)
        for r in range(sp.b0, sp.b1 + 1):
            for c in range(sp.a0, sp.a1 + 1):
                v = cone_base(sf, gr, w, sp, r, c)
                if v[1] < surface.SOIL_CONTACT or not (v[2] < _INF):
                    continue
                amin = wp.min(amin, v[2])
                if v[1] < _INF:
                    room += v[1]
                else:
                    is_open = bool(True)
        fits = is_open or room >= target
        top = amin
        if fits:
            top = cone_top(sf, gr, w, sp, target, guess, amin)
        whole = sp.b0 == 1 and sp.b1 == nrow - 2 and sp.a0 == 1 and sp.a1 == ncol - 2
        if not whole:
            if not fits or cone_spills(sf, gr, w, sp, top):
                grow = 2 * grow + 1
                continue
        laid = _Z
        for r in range(sp.b0, sp.b1 + 1):
            for c in range(sp.a0, sp.a1 + 1):
                v = cone_base(sf, gr, w, sp, r, c)
                if v[1] < surface.SOIL_CONTACT:
                    continue
                q = v[1]
                if fits:
                    q = wp.min(top - v[2], v[1])
                if q > _Z and v[2] < _INF:
                    i = SOIL_HEAD + r * ncol + c
                    sf.soil[w, i] = sf.soil[w, i] + q
                    laid += q
        if not fits:
            gr.stats[w, UNPLACED] = gr.stats[w, UNPLACED] + (target - laid) * sf.dx * sf.dy
        return True
    return False


@wp.func
def rim_weights(sf: Surface, gr: Ground, w: int, sd: Seeds, k: int, cut: Cut,
                open_sky: bool) -> f64:  # fmt: skip
    """Each vertex of sd's box gets in the work row its rim weight (1 - s) + 2 s max(0, cos)
    towards the cut's horizontal motion (0 off the rim); returns their sum (engine Deposit)."""
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
    total = _Z
    for r in range(sd.r0, sd.r1 + 1):
        for c in range(sd.c0, sd.c1 + 1):
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
            gr.work[w, (r - sd.r0) * sd.wcol + (c - sd.c0)] = wt
    return total


@wp.func
def deposit(sf: Surface, gr: Ground, w: int, kb: int, k: int, cut: Cut):
    """Lays the cut around the rim of intruder k's footprint as a cone at the repose slope, the
    rim's vertices offset by the footprint's extent times how little of the horizontal motion
    points their way (engine Deposit); the rim alone, by weight, where the cone's box does not
    fit in the work row."""
    sd = Seeds()
    sd.r0 = wp.max(1, int(gr.box[w, kb]) - 1)
    sd.r1 = wp.min(sf.nrow - 2, int(gr.box[w, kb + 1]) + 1)
    sd.c0 = wp.max(1, int(gr.box[w, kb + 2]) - 1)
    sd.c1 = wp.min(sf.ncol - 2, int(gr.box[w, kb + 3]) + 1)
    sd.wcol = wp.max(0, sd.c1 - sd.c0 + 1)
    sd.n = (sd.r1 - sd.r0 + 1) * sd.wcol
    for sky in range(2):
        open_sky = sky == 0
        if rim_weights(sf, gr, w, sd, k, cut, open_sky) > _Z:
            wmax = _Z
            nrim = int(0)
            for r in range(sd.r0, sd.r1 + 1):
                for c in range(sd.c0, sd.c1 + 1):
                    wmax = wp.max(wmax, gr.work[w, (r - sd.r0) * sd.wcol + (c - sd.c0)])
                    if rim(sf, gr, w, r, c, k, open_sky):
                        nrim += 1
            extent = wp.max((gr.box[w, kb + 1] - gr.box[w, kb] + f64(1.0)) * sf.dy,
                            (gr.box[w, kb + 3] - gr.box[w, kb + 2] + f64(1.0)) * sf.dx)  # fmt: skip
            for r in range(sd.r0, sd.r1 + 1):
                for c in range(sd.c0, sd.c1 + 1):
                    at = (r - sd.r0) * sd.wcol + (c - sd.c0)
                    off = _INF
                    if rim(sf, gr, w, r, c, k, open_sky):
                        off = (f64(1.0) - gr.work[w, at] / wmax) * extent
                    gr.work[w, at] = off
            cell = wp.max(sf.dx, sf.dy)
            guess = wp.sqrt(f64(2.0) * sf.tan_repose * cut.vol / (f64(nrim) * cell))
            target = cut.vol / (sf.dx * sf.dy)
            if not cone(sf, gr, w, sd, target, guess):
                rim_by_weight(sf, gr, w, sd, target, wmax, extent)
            return
    gr.stats[w, UNPLACED] = gr.stats[w, UNPLACED] + cut.vol


@wp.func
def rim_by_weight(sf: Surface, gr: Ground, w: int, sd: Seeds, target: f64, wmax: f64,
                  extent: f64):  # fmt: skip
    """Spreads target [m] (volume / cell area) over the rim alone, by weight, from the seed
    offsets in the work row (engine Deposit's fallback)."""
    total = _Z
    for r in range(sd.r0, sd.r1 + 1):
        for c in range(sd.c0, sd.c1 + 1):
            at = (r - sd.r0) * sd.wcol + (c - sd.c0)
            off = gr.work[w, at]
            if off < _INF:
                gr.work[w, at] = wmax * (f64(1.0) - off / extent)
                total += gr.work[w, at]
    scale = target / total
    for r in range(sd.r0, sd.r1 + 1):
        for c in range(sd.c0, sd.c1 + 1):
            wt = gr.work[w, (r - sd.r0) * sd.wcol + (c - sd.c0)]
            if wt < _INF:
                i = SOIL_HEAD + r * sf.ncol + c
                sf.soil[w, i] = sf.soil[w, i] + wt * scale


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
def mark(sf: Surface, gr: Ground, w: int):
    """The press marks over the footprint boxes (rows 0..nk-1): k + 1 where intruder k presses
    on the vertex (engine Mark)."""
    q0 = SOIL_HEAD + 3 * sf.ncol * sf.nrow
    for k in range(gr.nk):
        bx = 4 * k
        for r in range(int(gr.box[w, bx]), int(gr.box[w, bx + 1]) + 1):
            for c in range(int(gr.box[w, bx + 2]), int(gr.box[w, bx + 3]) + 1):
                if gr.owner[w, r * sf.ncol + c] == k and contact(sf, gr, w, r, c):
                    sf.soil[w, q0 + r * sf.ncol + c] = f64(k + 1)


@wp.func
def unmark(sf: Surface, w: int):
    """Clears the press marks over the last update's footprints' box (the soil block's
    SOIL_FOOT; engine Unmark)."""
    q0 = SOIL_HEAD + 3 * sf.ncol * sf.nrow
    if sf.soil[w, SOIL_FOOT + 1] > sf.soil[w, SOIL_FOOT] and (
        sf.soil[w, SOIL_FOOT + 3] > sf.soil[w, SOIL_FOOT + 2]
    ):
        for r in range(int(sf.soil[w, SOIL_FOOT]), int(sf.soil[w, SOIL_FOOT + 1])):
            for c in range(int(sf.soil[w, SOIL_FOOT + 2]), int(sf.soil[w, SOIL_FOOT + 3])):
                sf.soil[w, q0 + r * sf.ncol + c] = _Z


@wp.func
def finish(sf: Surface, gr: Ground, w: int, top: f64, time: f64):
    """Clears floor and owner over the footprint boxes (rows 0..nk-1) and one vertex around
    each, raises the ceiling to the highest of top [m] and the surface there, records the time
    (engine Finish)."""
    ncol = sf.ncol
    nrow = sf.nrow
    for k in range(gr.nk):
        bx = 4 * k
        if gr.box[w, bx] > gr.box[w, bx + 1] or gr.box[w, bx + 2] > gr.box[w, bx + 3]:
            continue
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
def culled(el: Elements, medium: Medium, sf: Surface, w: int, g: int,
           geom_xpos: wp.array2d(dtype=wp.vec3)) -> bool:  # fmt: skip
    """Tagged geom g cannot touch the medium: above the surface or outside the region (engine
    Culled)."""
    r = el.tgeom_rbound[g]
    if r <= _Z:
        return False
    cen = widen(geom_xpos[w, el.tgeom_geomid[g]])
    if cen[2] - r >= surface.highest_near(sf, cen[0], cen[1], r):
        return True
    if medium.use_region != 0:
        for q in range(3):
            if cen[q] + r < medium.region_lo[q] or cen[q] - r > medium.region_hi[q]:
                return True
    return False


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
            if culled(el, medium, sf, w, g, geom_xpos):
                continue
            e0 = el.tgeom_elemadr[g]
            nr = footprint(sf, gr, w, e0, e0 + el.tgeom_elemnum[g], rot, pos, k, kb, top)
            gr.stats[w, RASTERISED] = gr.stats[w, RASTERISED] + f64(nr)
        union(gr, w, allbox, gr.box[w, kb], gr.box[w, kb + 1], gr.box[w, kb + 2],
              gr.box[w, kb + 3])  # fmt: skip


@wp.func
def relax_boxes(sf: Surface, gr: Ground, w: int, known: bool):
    """The relaxation's boxes (box_rows): each intruder's footprint with its last one if known,
    the box the last update left unrelaxed, and the last footprints' union if they are not
    known (a reset or a state this pass did not write); each grown by one vertex (engine
    deform::Update)."""
    nk = gr.nk
    sweep = 4 * (2 * nk + 2)
    prev = 4 * (nk + 1)
    for k in range(nk):
        bx = sweep + 4 * k
        empty(gr, w, bx)
        union(gr, w, bx, gr.box[w, 4 * k], gr.box[w, 4 * k + 1], gr.box[w, 4 * k + 2],
              gr.box[w, 4 * k + 3])  # fmt: skip
        if known:
            union(gr, w, bx, gr.box[w, prev + 4 * k], gr.box[w, prev + 4 * k + 1],
                  gr.box[w, prev + 4 * k + 2], gr.box[w, prev + 4 * k + 3])  # fmt: skip
    extra = sweep + 4 * nk
    empty(gr, w, extra)
    empty(gr, w, extra + 4)
    head_union(sf, gr, w, extra, SOIL_PENDING)
    if not known:
        head_union(sf, gr, w, extra + 4, SOIL_FOOT)
    for b in range(nk + 2):
        bx = sweep + 4 * b
        if gr.box[w, bx] <= gr.box[w, bx + 1]:
            gr.box[w, bx] = gr.box[w, bx] - f64(1.0)
            gr.box[w, bx + 1] = gr.box[w, bx + 1] + f64(1.0)
            gr.box[w, bx + 2] = gr.box[w, bx + 2] - f64(1.0)
            gr.box[w, bx + 3] = gr.box[w, bx + 3] + f64(1.0)


@wp.func
def intruder_speed(el: Elements, medium: Medium, sf: Surface, w: int,
                   tbody_bodyid: wp.array(dtype=int), tbody_rootid: wp.array(dtype=int),
                   cvel: wp.array2d(dtype=wp.spatial_vector),
                   subtree_com: wp.array2d(dtype=wp.vec3),
                   geom_xpos: wp.array2d(dtype=wp.vec3)) -> f64:  # fmt: skip
    """The fastest speed [m/s] of a point of a tagged geom that may touch the medium: its
    centre's speed plus its angular speed times its bounding radius (engine IntruderSpeed)."""
    fastest = _Z
    for k in range(el.tbody_geomadr.shape[0]):
        tw = cvel[w, tbody_bodyid[k]]
        om = wp.vec3d(f64(tw[0]), f64(tw[1]), f64(tw[2]))
        v0 = wp.vec3d(f64(tw[3]), f64(tw[4]), f64(tw[5]))
        o = widen(subtree_com[w, tbody_rootid[k]])
        g0 = el.tbody_geomadr[k]
        for g in range(g0, g0 + el.tbody_geomnum[k]):
            if culled(el, medium, sf, w, g, geom_xpos):
                continue
            v = v0 + wp.cross(om, widen(geom_xpos[w, el.tgeom_geomid[g]]) - o)
            fastest = wp.max(fastest, wp.length(v) + wp.length(om) * el.tgeom_rbound[g])
    return fastest


@wp.func
def due(sf: Surface, w: int, now: f64, dt: f64, speed: f64) -> bool:
    """The ground has not yet followed the configuration at time now [s] (engine Due); speed
    [m/s]: intruder_speed's, accumulated into the soil block under the travel rule."""
    last = sf.soil[w, SOIL_TIME]
    if sf.soil[w, SOIL_DONE] == _Z or now < last:
        return True
    if sf.every >= f64(1.0):
        if sf.every == f64(1.0):
            return last != now
        return now - last > (sf.every - f64(0.5)) * dt
    limit = sf.travel * wp.min(sf.dx, sf.dy)
    relaxing = sf.soil[w, SOIL_PENDING + 1] > sf.soil[w, SOIL_PENDING]
    relaxing = relaxing and sf.soil[w, SOIL_PENDING + 3] > sf.soil[w, SOIL_PENDING + 2]
    if not (limit > _Z) or relaxing:  # no travel rule, or slopes left to relax
        return last != now
    clock = sf.soil[w, SOIL_CLOCK]
    if now > clock:
        sf.soil[w, SOIL_TRAVEL] = sf.soil[w, SOIL_TRAVEL] + speed * (now - wp.max(clock, last))
        sf.soil[w, SOIL_CLOCK] = now
    return sf.soil[w, SOIL_TRAVEL] >= limit


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
    speed = _Z
    if sf.every < f64(1.0) and sf.travel > _Z:
        speed = intruder_speed(el, medium, sf, w, tbody_bodyid, tbody_rootid, cvel, subtree_com,
                               geom_xpos)  # fmt: skip
    if not due(sf, w, now, f64(timestep[w % timestep.shape[0]]), speed):
        return
    nk = gr.nk
    allbox = 4 * nk
    fp = 4 * (2 * nk + 1)  # the last update's fingerprint: is its row of footprints this state's?
    known = gr.box[w, fp + 3] == f64(1.0) and sf.soil[w, SOIL_DONE] == f64(1.0)
    known = known and gr.box[w, fp] == gr.stats[w, UPDATES]
    known = known and gr.box[w, fp + 1] == gr.stats[w, EXCAVATED]
    known = known and gr.box[w, fp + 2] == sf.soil[w, SOIL_TIME]
    unmark(sf, w)
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
    relax_boxes(sf, gr, w, known)
    head_store(sf, gr, w, SOIL_FOOT, allbox, True)
    gr.stats[w, UPDATES] = gr.stats[w, UPDATES] + f64(1.0)
    gr.status[w] = bad
    sweep = 4 * (2 * nk + 2)
    pend = 4 * (3 * nk + 4)
    converged, top = relax(sf, gr, w, sweep, nk + 2, pend, -_INF)
    head_store(sf, gr, w, SOIL_PENDING, pend, not converged)
    mark(sf, gr, w)
    finish(sf, gr, w, top, now)
    prev = 4 * (nk + 1)
    for c in range(4 * nk):
        gr.box[w, prev + c] = gr.box[w, c]
    gr.box[w, fp] = gr.stats[w, UPDATES]
    gr.box[w, fp + 1] = gr.stats[w, EXCAVATED]
    gr.box[w, fp + 2] = sf.soil[w, SOIL_TIME]
    gr.box[w, fp + 3] = f64(1.0)
    sf.soil[w, SOIL_TRAVEL] = _Z
    sf.soil[w, SOIL_CLOCK] = now
