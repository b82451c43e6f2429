"""The deforming ground's update on one MjData, compiled: the intruders' footprints at the
current configuration, then excavation, deposition and relaxation (``mjrft.core.soil``).

``forward`` runs it once per configuration, before the forces, at the first pass of a new time
(RK4's later stages and repeated passes at one time do not move the ground), so the forces of a
step feel the ground as the intruders left it at that step's configuration.
"""

from __future__ import annotations

import numba
import numpy as np

from mjrft.core import soil, surface
from mjrft.field.evaluate import culled
from mjrft.field.tables import unpack

_JIT = {"cache": True, "error_model": "numpy"}
_BIG = float(np.iinfo(np.int32).max)


@numba.njit(inline="always", **_JIT)
def due(m, d):
    """True if the ground has not yet followed the configuration at this time: at every new
    time, or with mjrft:deform_every = k > 1 once k steps have passed since it last did (or
    the time went back: a reset or a restored state)."""
    block = d.userdata
    t, last = d.time[0], block[surface.SOIL_TIME]
    if block[surface.SOIL_DONE] == 0.0 or t < last:
        return True
    every = m.surface_prm[surface.EVERY]
    if every <= 1.0:
        return last != t
    return t - last > (every - 0.5) * m.opt_timestep[0]


@numba.njit(inline="always", **_JIT)
def _empty(box):
    box[0], box[1], box[2], box[3] = _BIG, -1.0, _BIG, -1.0


@numba.njit(**_JIT)
def _footprints(m, d, s, top):
    """Rasterise every tagged body's geoms that may touch the medium; box k of s.soil_box is
    body k's footprint, the last row their union."""
    nk = m.tbody_bodyid.shape[0]
    allbox = s.soil_box[nk]
    _empty(allbox)
    for k in range(nk):
        kb = s.soil_box[k]
        _empty(kb)
        b = m.tbody_bodyid[k]
        for g in range(m.tbody_geomadr[k], m.tbody_geomadr[k] + m.tbody_geomnum[k]):
            if culled(m, d, g):
                continue
            start = m.tgeom_elemadr[g]
            s.soil_stats[4] += soil.footprint(
                m.surface_prm, m.elem_vert, start, start + m.tgeom_elemnum[g], d.xmat[b],
                d.xpos[b], k, s.soil_floor, s.soil_owner, kb, top,
            )  # fmt: skip
        soil.union(allbox, kb[0], kb[1], kb[2], kb[3])


@numba.njit(**_JIT)
def update(m_rec, e_rec):
    """Move the ground of this MjData to the intruders' current configuration; returns -1, or
    the tagged body that reaches below the medium's bottom (nothing then moved for it)."""
    m, d, s = unpack(m_rec, e_rec)
    prm, grid, block = m.surface_prm, m.surface_grid, d.userdata
    nk = m.tbody_bodyid.shape[0]
    _footprints(m, d, s, surface.ceiling(prm, block))
    allbox = s.soil_box[nk]
    twist = np.empty(9)
    v = np.empty(3)
    bad = -1
    for k in range(nk):
        kb = s.soil_box[k]
        if kb[0] > kb[1]:
            continue
        b = m.tbody_bodyid[k]
        root = m.tbody_rootid[k]
        for c in range(3):  # cvel: (omega, v at the root's subtree CoM), world frame
            twist[c] = d.cvel[b, 3 + c]
            twist[3 + c] = d.cvel[b, c]
            twist[6 + c] = d.subtree_com[root, c]
        vol, mx, my, v[0], v[1], v[2] = soil.excavate(
            prm, grid, block, s.soil_floor, s.soil_owner, kb, k, twist, m.region[0, 2],
            s.soil_stats,
        )  # fmt: skip
        if vol < 0.0:
            bad = k
        elif vol > 0.0:
            soil.deposit(
                prm, grid, block, s.soil_floor, s.soil_owner, kb, k, vol, mx, my, v, s.soil_stats
            )
    # Relax where the intruders are, where they were (a withdrawn rod leaves a hole to slump)
    # and where the last update left slopes unrelaxed. The boxes and the queue are rows of the
    # field's work arrays: an array allocated here would cost an atomic reference count at
    # every pair of vertices the relaxation visits.
    box, seen = s.soil_box[nk + 1], s.soil_box[nk + 2]
    box[:] = allbox
    _head_union(box, block, surface.SOIL_FOOT)
    _head_union(box, block, surface.SOIL_PENDING)
    _head_store(block, surface.SOIL_FOOT, allbox, True)
    s.soil_stats[0] += 1
    if box[0] > box[1]:
        block[surface.SOIL_DONE] = 1.0
        block[surface.SOIL_TIME] = d.time[0]
        return bad
    box[0], box[1], box[2], box[3] = box[0] - 1, box[1] + 1, box[2] - 1, box[3] + 1
    seen[:] = box
    converged = soil.relax(
        prm, grid, block, s.soil_floor, s.soil_owner, s.soil_queue, box, seen, s.soil_stats
    )
    _head_store(block, surface.SOIL_PENDING, box, not converged)
    soil.finish(prm, grid, block, s.soil_floor, s.soil_owner, seen, d.time[0])
    return bad


@numba.njit(inline="always", **_JIT)
def _head_union(box, block, at):
    """Grow box by the vertex box stored at block[at:at + 4] (r0, r1 + 1, c0, c1 + 1; empty
    when r1 + 1 <= r0, as all zeros are after mj_resetData)."""
    if block[at + 1] > block[at] and block[at + 3] > block[at + 2]:
        soil.union(box, block[at], block[at + 1] - 1, block[at + 2], block[at + 3] - 1)


@numba.njit(inline="always", **_JIT)
def _head_store(block, at, box, keep):
    """Store vertex box (4,) (r0, r1, c0, c1) at block[at:at + 4]; an empty box, or any box if
    not keep, as zeros."""
    if keep and box[0] <= box[1] and box[2] <= box[3]:
        block[at], block[at + 1], block[at + 2], block[at + 3] = (
            box[0], box[1] + 1, box[2], box[3] + 1,
        )  # fmt: skip
    else:
        block[at], block[at + 1], block[at + 2], block[at + 3] = 0.0, 0.0, 0.0, 0.0
