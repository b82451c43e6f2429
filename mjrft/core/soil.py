"""Ground that deforms and remembers: a height grid pressed down by intruders, bulldozed and
relaxed to the angle of repose, with the memory of how deep its compacted columns were.

The grid (``mjrft.core.surface``, kind SOIL) has vertices every dx, dy over the medium's region;
vertex v stands for the column of one cell area centred on it. Its state, per MjData (the soil
block, held in ``userdata`` so that MuJoCo copies, saves and resets it with the rest of the
state), is its surface height h, its compacted level c <= h and its memory p >= 0. The resisting
depth of a point at height z in the column is (h + p) - z below c and h - z between c and h
(``surface.soil_depth``). Pristine ground has c = h, p = 0, so pristine depth is h - z.

One update (``mjrft.field.deform.update``, with the functions below) follows the intruders to a
new configuration:

1. *Footprints* (``footprint``): every downward-facing triangle of an intruder (its lower
   surface, seen from above) is rasterised onto the vertices below it; a vertex whose floor (the
   lowest such triangle over it) lies below its surface h is occupied.
2. *Excavation*: an occupied column is cut down to the floor, which becomes its compacted level
   (c = h = floor) and remembers as its depth reference the larger of the old surface h and the
   old c + p (Chrono SCM's sinkage memory plays this role in Bekker-Wong soil).
3. *Deposition*: each intruder's excavated volume is spread over the rim of its footprint (the
   unoccupied vertices next to it), weighted towards the horizontal motion of the footprint's
   centre: a vertical intrusion raises an even rim, a horizontal one bulldozes ahead of it. It
   lands as loose material (h grows, c and p unchanged).
4. *Relaxation*: wherever two neighbouring vertices (along x, y and both diagonals) differ by
   more than tan(repose) times their distance, material moves from the higher to the lower one
   (half the excess, so the pair ends exactly at the repose slope): one sweep over the box of
   recent activity, then vertex by vertex wherever material moved, never into or out of a
   column an intruder presses on or the grid's edge ring, and into the gap under a hovering
   intruder only up to its floor.

Every move subtracts from one vertex exactly what it adds to another, and the edge ring never
changes, so the volume under the surface (dx dy times the sum of h over the vertices) is
conserved up to rounding. World frame, SI units; arrays only (no MuJoCo).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from mjrft.core import surface
from mjrft.core.surface import (
    DX,
    DY,
    NCOL,
    NROW,
    SOIL_CONTACT,
    SOIL_DONE,
    SOIL_HEAD,
    SOIL_TIME,
    SOIL_ZOFF,
    TAN_REPOSE,
    X0,
    Y0,
    ZMAX,
)

_JIT = {"cache": True, "error_model": "numpy"}
#: Barycentric slack of the rasterisation: a vertex on an edge shared by two triangles is
#: covered by both, whatever the rounding.
EDGE_SLACK = 1e-12
#: Relaxation work per update at most, in sweeps of the update's box (``relax``: the pair
#: visits of this many sweeps); what is left continues at the next update (counted in
#: "unrelaxed"). A pile's excess travels down its slope diffusively, so a growing berm would
#: take ~its width squared in sweeps to settle exactly at every step; the budget bounds a step's
#: cost and lets the slope settle over the next steps.
MAX_SWEEPS = 16
#: A neighbouring pair may exceed the repose slope by this much [m] before material moves
#: (1 um: a thousandth of a 1 mm grain). Relaxing to 1 nm instead costs the walking hexapod at
#: a 5 mm cell 3.9 against 3.3 s of wall time for 10 s (Xeon VM); at a 2 mm cell, where the
#: budget runs out at almost every update either way, both cost 20-21 s.
SLOPE_SLACK = 1e-6
#: Largest grid accepted (vertices): its soil block then takes 3 x 8 bytes per vertex per MjData.
MAX_VERTICES = 2_000_000
#: Work counters: updates, volume excavated [m^3], volume that found no rim [m^3], updates whose
#: relaxation hit MAX_SWEEPS, triangles rasterised, footprint vertices at the edge ring.
N_SOIL_STATS = 6
SOIL_STATS = ("updates", "excavated", "unplaced", "unrelaxed", "rasterised", "edge")


@numba.njit(inline="always", **_JIT)
def _world(rot, pos, x, y, z):
    return (
        rot[0, 0] * x + rot[0, 1] * y + rot[0, 2] * z + pos[0],
        rot[1, 0] * x + rot[1, 1] * y + rot[1, 2] * z + pos[1],
        rot[2, 0] * x + rot[2, 1] * y + rot[2, 2] * z + pos[2],
    )


@numba.njit(**_JIT)
def footprint(prm, vert, start, stop, rot, pos, k, floor, owner, box, top):
    """Rasterise the downward-facing triangles start..stop of one intruder onto the grid.

    vert (n, 9): each triangle's three vertices, body frame [m], counter-clockwise seen from
    outside; rot (3, 3) body -> world, pos (3,) body origin [m]. floor (nrow, ncol) [m] takes,
    at each vertex under a triangle lower than it, the triangle's height there, and owner the
    intruder's index k; box (4,) grows to cover those vertices (r0, r1, c0, c1). Triangles
    whose lowest corner is above `top` [m] are skipped. Returns the triangles rasterised.
    """
    ncol, nrow = int(prm[NCOL]), int(prm[NROW])
    x0, y0, dx, dy = prm[X0], prm[Y0], prm[DX], prm[DY]
    done = 0
    for i in range(start, stop):
        ax, ay, az = _world(rot, pos, vert[i, 0], vert[i, 1], vert[i, 2])
        bx, by, bz = _world(rot, pos, vert[i, 3], vert[i, 4], vert[i, 5])
        cx, cy, cz = _world(rot, pos, vert[i, 6], vert[i, 7], vert[i, 8])
        if min(az, bz, cz) >= top:
            continue
        ux, uy, wx, wy = bx - ax, by - ay, cx - ax, cy - ay
        twice = ux * wy - uy * wx  # twice the signed xy area: < 0 for a downward-facing face
        if twice >= 0.0:
            continue
        done += 1
        c0 = max(0, int(math.ceil((min(ax, bx, cx) - x0) / dx)))  # noqa: RUF046
        c1 = min(ncol - 1, int(math.floor((max(ax, bx, cx) - x0) / dx)))  # noqa: RUF046
        r0 = max(0, int(math.ceil((min(ay, by, cy) - y0) / dy)))  # noqa: RUF046
        r1 = min(nrow - 1, int(math.floor((max(ay, by, cy) - y0) / dy)))  # noqa: RUF046
        inv = 1.0 / twice
        for r in range(r0, r1 + 1):
            qy = y0 + r * dy - ay
            for c in range(c0, c1 + 1):
                qx = x0 + c * dx - ax
                b = (qx * wy - qy * wx) * inv
                g = (ux * qy - uy * qx) * inv
                # A vertex on a shared edge belongs to both triangles (EDGE_SLACK).
                if b < -EDGE_SLACK or g < -EDGE_SLACK or b + g > 1.0 + EDGE_SLACK:
                    continue
                z = az + b * (bz - az) + g * (cz - az)
                if z < floor[r, c]:
                    floor[r, c] = z
                    owner[r, c] = k
                    union(box, r, r, c, c)
    return done


@numba.njit(inline="always", **_JIT)
def _offsets(prm):
    n = int(prm[NCOL]) * int(prm[NROW])
    return SOIL_HEAD, SOIL_HEAD + n, SOIL_HEAD + 2 * n


@numba.njit(**_JIT)
def excavate(prm, grid, soil, floor, owner, box, k, twist, zlo, stats):
    """Cut intruder k's occupied columns (owner == k, inside box (4,)) down to their floor and
    return (volume [m^3], x, y of its centroid [m], its point velocity vx, vy, vz [m/s]) for the
    deposition; volume -1 (nothing cut) if a floor lies below zlo [m], the medium's bottom.
    The floor becomes the compacted level, remembering as its depth reference the larger of
    the surface h and the old c + p. twist (9,): the intruder's velocity [m/s] at
    a point moving with it, angular velocity [rad/s], that point [m]; world frame."""
    ncol, nrow = int(prm[NCOL]), int(prm[NROW])
    oh, oc, op = _offsets(prm)
    area = prm[DX] * prm[DY]
    vol, mx, my, mz = 0.0, 0.0, 0.0, 0.0
    for r in range(int(box[0]), int(box[1]) + 1):
        for c in range(int(box[2]), int(box[3]) + 1):
            if owner[r, c] != k:
                continue
            i = r * ncol + c
            base = grid[r, c]
            h = base + soil[oh + i]
            f = floor[r, c]
            if f >= h:  # above the surface, or touching it: nothing to cut
                continue
            if f < zlo:
                return -1.0, 0.0, 0.0, 0.0, 0.0, 0.0
            if r == 0 or c == 0 or r == nrow - 1 or c == ncol - 1:
                stats[5] += 1  # the edge ring never changes (volume bookkeeping)
                continue
            cut = h - f
            # The floor is compacted with the larger of the two references over it: the loose
            # surface h, or the compacted level's own c + p (loose material that slumped into
            # an old footprint does not add to the depth its floor remembers).
            ref = max(h, base + soil[oc + i] + soil[op + i])
            soil[oh + i] = f - base
            soil[oc + i] = f - base
            soil[op + i] = ref - f
            vol += cut * area
            mx += cut * area * (prm[X0] + c * prm[DX])
            my += cut * area * (prm[Y0] + r * prm[DY])
            mz += cut * area * f
    if vol <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    mx, my, mz = mx / vol, my / vol, mz / vol
    # The footprint's centre moves with the intruder: a slipping wheel's bottom moves backwards.
    rx, ry, rz = mx - twist[6], my - twist[7], mz - twist[8]
    vx = twist[0] + twist[4] * rz - twist[5] * ry
    vy = twist[1] + twist[5] * rx - twist[3] * rz
    vz = twist[2] + twist[3] * ry - twist[4] * rx
    stats[1] += vol
    return vol, mx, my, vx, vy, vz


@numba.njit(inline="always", **_JIT)
def _contact(prm, grid, soil, floor, r, c):
    """True if an intruder presses on vertex (r, c): its floor at the surface (after the cut)."""
    return floor[r, c] < grid[r, c] + soil[SOIL_HEAD + r * int(prm[NCOL]) + c] + SOIL_CONTACT


@numba.njit(inline="always", **_JIT)
def _rim(prm, grid, soil, floor, owner, r, c, k, open_sky):
    """True if vertex (r, c), free of contact (and with no intruder over it if open_sky),
    borders a vertex intruder k presses on (8-neighbourhood)."""
    if (open_sky and floor[r, c] < np.inf) or _contact(prm, grid, soil, floor, r, c):
        return False
    for a in range(-1, 2):
        for b in range(-1, 2):
            if owner[r + a, c + b] == k and _contact(prm, grid, soil, floor, r + a, c + b):
                return True
    return False


@numba.njit(**_JIT)
def deposit(prm, grid, soil, floor, owner, box, k, vol, mx, my, v, stats):
    """Spread volume vol [m^3] of intruder k over the rim of its footprint (the vertices next to
    those it presses on, inside box grown by one vertex, with no intruder over them; failing
    those, the ones under an intruder but free of contact), weighted towards the horizontal
    direction of v (3,) [m/s] from the footprint's centre (mx, my) [m]: weight (1 - s) +
    2 s max(0, cos), s = |v_xy| / (|v_xy| + |v_z|), so a vertical intrusion raises an even rim
    and a horizontal one piles ahead. Loose material: h grows, c and p stay."""
    ncol, nrow = int(prm[NCOL]), int(prm[NROW])
    vh = math.hypot(v[0], v[1])
    s = vh / (vh + abs(v[2])) if vh + abs(v[2]) > 0.0 else 0.0
    ux, uy = (v[0] / vh, v[1] / vh) if vh > 0.0 else (0.0, 0.0)
    r0, r1 = max(1, int(box[0]) - 1), min(nrow - 2, int(box[1]) + 1)
    c0, c1 = max(1, int(box[2]) - 1), min(ncol - 2, int(box[3]) + 1)
    # The rim is chosen before anything is deposited: material landing under a hovering
    # intruder can bring that vertex into contact and make its neighbours rim vertices, and
    # weights summed over one rim but spent over another would not conserve the volume.
    weight = np.zeros((max(0, r1 - r0 + 1), max(0, c1 - c0 + 1)))
    for open_sky in (True, False):
        total = 0.0
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                weight[r - r0, c - c0] = 0.0
                if not _rim(prm, grid, soil, floor, owner, r, c, k, open_sky):
                    continue
                ex, ey = prm[X0] + c * prm[DX] - mx, prm[Y0] + r * prm[DY] - my
                e = math.hypot(ex, ey)
                cos = (ex * ux + ey * uy) / e if e > 0.0 else 0.0
                w = (1.0 - s) + 2.0 * s * max(0.0, cos)
                weight[r - r0, c - c0] = w
                total += w
        if total > 0.0:
            scale = vol / (prm[DX] * prm[DY]) / total
            for r in range(r0, r1 + 1):
                for c in range(c0, c1 + 1):
                    soil[SOIL_HEAD + r * ncol + c] += weight[r - r0, c - c0] * scale
            return
    stats[2] += vol


@numba.njit(inline="always", **_JIT)
def _move(soil, oh, oc, i, j, q):
    """Move height q [m] of material from vertex i to vertex j (flat indices); an eroded vertex
    loses its loose layer first, then its compacted level follows its surface down."""
    soil[oh + i] -= q
    soil[oh + j] += q
    if soil[oh + i] < soil[oc + i]:
        soil[oc + i] = soil[oh + i]


@numba.njit(inline="always", **_JIT)
def _settle_pair(soil, oh, oc, i, hi, fi, j, hj, fj, lim):
    """Move material between free vertices i and j (heights hi, hj, intruder floors fi, fj
    [m], inf where none) so that they differ by at most lim [m]; returns the height moved.

    Material enters the gap under a hovering intruder (floor f) only up to f, and only from a
    neighbour that is also under an intruder or no higher than f: the intruder's side holds
    a wall that stands above its floor (a height field cannot undercut it)."""
    diff = hi - hj
    if diff > lim + SLOPE_SLACK:
        if fj < np.inf and fi == np.inf and hi > fj:
            return 0.0
        q = min(0.5 * (diff - lim), fj - hj)
        _move(soil, oh, oc, i, j, q)
        return q
    if -diff > lim + SLOPE_SLACK:
        if fi < np.inf and fj == np.inf and hj > fi:
            return 0.0
        q = min(0.5 * (-diff - lim), fi - hi)
        _move(soil, oh, oc, j, i, q)
        return q
    return 0.0


#: The eight neighbours of a vertex: (row step, column step, index of the limit: x, y, diagonal).
_NEIGHBOURS = ((0, 1, 0), (0, -1, 0), (1, 0, 1), (-1, 0, 1), (1, 1, 2), (-1, -1, 2), (1, -1, 2),
               (-1, 1, 2))  # fmt: skip
#: soil_owner's value for a vertex waiting in the relaxation's queue (deposition is done by
#: then, and ``finish`` clears the owners).
QUEUED = -2


@numba.njit(inline="always", **_JIT)
def _push(queue, tail, count, mark, i, r, c, seen):
    """Append vertex i (row r, column c) to the ring buffer queue (nrow * ncol,) unless it
    waits there already (mark), so the queue never fills; seen (4,) grows over it. Returns
    (tail, count)."""
    if mark[r, c] == QUEUED:
        return tail, count
    queue[tail] = i
    tail = (tail + 1) % queue.shape[0]
    mark[r, c] = QUEUED
    union(seen, r, r, c, c)
    return tail, count + 1


@numba.njit(inline="always", **_JIT)
def _free(grid, soil, oh, floor, r, c, ncol):
    """(height h [m], intruder floor f [m], True) of vertex (r, c), or (.., False) if an
    intruder presses on it (it neither gives nor takes)."""
    h = grid[r, c] + soil[oh + r * ncol + c]
    f = floor[r, c]
    return h, f, f >= h + SOIL_CONTACT


@numba.njit(**_JIT)
def relax(prm, grid, soil, floor, mark, queue, box, seen, stats):
    """Relax the surface from the vertices of box (4,) until no pair of free neighbouring
    vertices is steeper than the angle of repose, or the work budget is spent; returns True if
    it converged.

    One sweep over the box, then a queue (first in, first out) of the vertices that moved: a
    vertex taken from it is settled against its eight neighbours, and every vertex that moved
    (it, and each neighbour it gave to or took from) joins the queue again, so the work follows
    the material, wherever the box's corners are (three legs far apart cost three footprints,
    not the box spanning them). A pair of which neither vertex moved since it was in repose is
    still in repose. The budget is the pair visits of MAX_SWEEPS sweeps of the box. On return
    box holds the queue's bounding box if it did not empty (the slopes left unrelaxed), and
    seen (4,) has grown over every vertex visited. mark (nrow, ncol): soil_owner, which marks
    the waiting vertices QUEUED (and is cleared by ``finish``); queue (nrow * ncol,) int64:
    work space for the queue. A vertex an intruder presses on neither gives nor takes
    (``_settle_pair`` for the gap under a hovering one)."""
    ncol, nrow = int(prm[NCOL]), int(prm[NROW])
    oh, oc, _ = _offsets(prm)
    t = prm[TAN_REPOSE]
    lim = (t * prm[DX], t * prm[DY], t * math.hypot(prm[DX], prm[DY]))
    r0, r1 = max(1, int(box[0])), min(nrow - 2, int(box[1]))
    c0, c1 = max(1, int(box[2])), min(ncol - 2, int(box[3]))
    if r0 > r1 or c0 > c1:
        return True
    union(seen, r0, r1, c0, c1)
    budget = MAX_SWEEPS * 4 * (r1 - r0 + 1) * (c1 - c0 + 1)
    tail, count = 0, 0
    for r in range(r0, r1 + 1):  # the sweep: each pair once (right, up, up-right, up-left)
        for c in range(c0, c1 + 1):
            hi, fi, free_i = _free(grid, soil, oh, floor, r, c, ncol)
            if not free_i:
                continue
            i = r * ncol + c
            for a, b, d in ((0, 1, 0), (1, 0, 1), (1, 1, 2), (1, -1, 2)):
                tail, count = _settle_into(
                    prm, grid, soil, oh, oc, floor, mark, lim, queue, tail, count, seen, i, r,
                    c, hi, fi, a, b, d,
                )  # fmt: skip
                hi = grid[r, c] + soil[oh + i]
    visits = 4 * (r1 - r0 + 1) * (c1 - c0 + 1)
    while count > 0 and visits < budget:
        cap = queue.shape[0]
        i = queue[(tail - count) % cap]
        count -= 1
        r, c = i // ncol, i % ncol
        mark[r, c] = -1
        hi, fi, free_i = _free(grid, soil, oh, floor, r, c, ncol)
        if not free_i:
            continue
        for a, b, d in _NEIGHBOURS:
            tail, count = _settle_into(
                prm, grid, soil, oh, oc, floor, mark, lim, queue, tail, count, seen, i, r, c,
                hi, fi, a, b, d,
            )  # fmt: skip
            hi = grid[r, c] + soil[oh + i]
        visits += 8
    if count == 0:
        return True
    cap = queue.shape[0]
    lo_r, hi_r, lo_c, hi_c = nrow, -1, ncol, -1
    for q in range(count):  # what is left waits for the next update (its box)
        i = queue[(tail - count + q) % cap]
        r, c = i // ncol, i % ncol
        mark[r, c] = -1
        lo_r, hi_r, lo_c, hi_c = min(lo_r, r), max(hi_r, r), min(lo_c, c), max(hi_c, c)
    box[0], box[1], box[2], box[3] = lo_r, hi_r, lo_c, hi_c
    stats[3] += 1
    return False


@numba.njit(inline="always", **_JIT)
def _settle_into(prm, grid, soil, oh, oc, floor, mark, lim, queue, tail, count, seen, i, r, c,
                 hi, fi, a, b, d):  # fmt: skip
    """Settle free vertex i (row r, column c, height hi, floor fi) with its neighbour at
    (r + a, c + b) (limit lim[d]); if material moved, queue both. Returns (tail, count)."""
    ncol, nrow = int(prm[NCOL]), int(prm[NROW])
    rr, cc = r + a, c + b
    if rr < 1 or rr > nrow - 2 or cc < 1 or cc > ncol - 2:
        return tail, count
    hj, fj, free_j = _free(grid, soil, oh, floor, rr, cc, ncol)
    if not free_j:
        return tail, count
    j = rr * ncol + cc
    if _settle_pair(soil, oh, oc, i, hi, fi, j, hj, fj, lim[d]) <= 0.0:
        return tail, count  # in repose, or capped by an intruder: settled
    tail, count = _push(queue, tail, count, mark, j, rr, cc, seen)
    return _push(queue, tail, count, mark, i, r, c, seen)


@numba.njit(**_JIT)
def finish(prm, grid, soil, floor, owner, box, time):
    """Close an update: raise the ceiling over box (4,), clear floor and owner there (and one
    vertex around it), and record the time [s] of the configuration followed."""
    ncol = int(prm[NCOL])
    oh = SOIL_HEAD
    top = -np.inf
    r0, r1 = max(0, int(box[0]) - 1), min(int(prm[NROW]) - 1, int(box[1]) + 1)
    c0, c1 = max(0, int(box[2]) - 1), min(ncol - 1, int(box[3]) + 1)
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            top = max(top, grid[r, c] + soil[oh + r * ncol + c])
            floor[r, c] = np.inf
            owner[r, c] = -1
    soil[SOIL_ZOFF] = max(soil[SOIL_ZOFF], top - prm[ZMAX])
    soil[SOIL_DONE] = 1.0
    soil[SOIL_TIME] = time


@numba.njit(inline="always", **_JIT)
def union(box, r0, r1, c0, c1):
    """Grow box (4,) to cover vertex rows r0..r1 and columns c0..c1 (nothing if r0 > r1)."""
    if r0 <= r1 and c0 <= c1:
        box[0] = min(box[0], r0)
        box[1] = max(box[1], r1)
        box[2] = min(box[2], c0)
        box[3] = max(box[3], c1)


#: Default angle of repose [deg] per material preset, the relaxation's limit slope. Smooth
#: spherical glass beads pile at 20-26 deg (e.g. Zhou et al., Phys. Rev. E 64:021301 (2001),
#: monosized spheres, experiment and DEM; review: Al-Hashemi & Al-Amoudi, Powder Technology
#: 330:397 (2018)); 23 deg is used for the paper's 0.8 mm beads. For poppy seeds and the generic
#: medium no measured value is at hand: 30 deg, typical of dry sands and rounded seeds in the
#: same review. Set mjrft:repose from a tilted-bed or poured-pile test of your own medium.
REPOSE_DEG = {"glass_beads": 23.0, "poppy_seeds_lp": 30.0, "poppy_seeds_cp": 30.0}
DEFAULT_REPOSE_DEG = 30.0


def repose_of(material_name: str) -> float:
    """The default angle of repose [deg] of a material by name (REPOSE_DEG, else 30)."""
    return REPOSE_DEG.get(material_name, DEFAULT_REPOSE_DEG)


def grid_shape(region: np.ndarray, cell: float) -> tuple[int, int]:
    """(nrow, ncol) of the grid with vertices every cell [m] covering region's (2, 3) x-y."""
    lo, hi = region[0, :2], region[1, :2]
    ncol = int(math.ceil((hi[0] - lo[0]) / cell - 1e-9)) + 1  # noqa: RUF046
    nrow = int(math.ceil((hi[1] - lo[1]) / cell - 1e-9)) + 1  # noqa: RUF046
    return nrow, ncol


def grid_over(
    initial: surface.Surface, region: np.ndarray, cell: float, repose_deg: float, every: int = 1
) -> surface.Surface:
    """A SOIL surface with vertices every `cell` [m] over the region's (2, 3) horizontal extent,
    starting as `initial` (sampled at the vertices) with angle of repose repose_deg [deg],
    following the intruders every `every` steps."""
    lo = region[0, :2]
    nrow, ncol = grid_shape(region, cell)
    x = lo[0] + cell * np.arange(ncol)
    y = lo[1] + cell * np.arange(nrow)
    heights = initial.height(*np.meshgrid(x, y))
    out = surface.grid(heights, float(lo[0]), float(lo[1]), cell, cell)
    prm = out.prm.copy()
    prm[surface.KIND] = surface.SOIL
    prm[TAN_REPOSE] = math.tan(math.radians(repose_deg))
    prm[surface.EVERY] = every
    return surface.Surface(prm, out.grid)


def block_views(prm: np.ndarray, block: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Views (nrow, ncol) of a soil block's offsets of h and c [m] and its memory p [m]."""
    nrow, ncol = int(prm[NROW]), int(prm[NCOL])
    n = nrow * ncol
    return tuple(block[SOIL_HEAD + q * n : SOIL_HEAD + (q + 1) * n].reshape(nrow, ncol)
                 for q in range(3))  # fmt: skip


__all__ = [
    "MAX_SWEEPS",
    "MAX_VERTICES",
    "SOIL_STATS",
    "SOIL_TIME",
    "block_views",
    "deposit",
    "excavate",
    "finish",
    "footprint",
    "grid_over",
    "relax",
    "union",
]
