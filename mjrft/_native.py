"""The field's whole per-pass work in native code: no Python between MuJoCo and the kernel.

A field publishes its static tables (elements, geom blocks, parameters) and, per MjData, the
addresses of that MjData's arrays, as plain uint64 words (see the layouts below). ``step`` reads
them through raw pointers, checks the state is finite, culls geoms by their bounding spheres,
evaluates the fused RFT kernel, and applies the ``xfrc_applied`` ownership protocol of
``mjrft.field`` (user part + RFT in the intruding rows). The passive-callback guard
(``mjrft._callback``) calls it directly; Python is entered only for an MjData seen for the first
time (to register it) and when ``step`` reports a problem (so Python can raise a proper error).

Everything here is an implementation detail of ``mjrft.field``; the arrays are owned by the
field, which keeps them alive while their addresses are published.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from mjrft import _kernel

# Words of a field's static table (uint64 each; addresses of arrays owned by the field).
F_NELEM, F_CENT, F_NORM, F_AREA = 0, 1, 2, 3
F_NGEOM, F_GINT, F_GRB = 4, 5, 6
F_NBODY_TAGGED, F_BODIES, F_PARAMS, F_COEF = 7, 8, 9, 10
F_NBODY, F_LAST_WRENCH, F_ELEM_FORCE, F_STATS = 11, 12, 13, 14
F_RING, F_RING_SIZE, F_DIRTY = 15, 16, 17
FIELD_WORDS = 18
# Columns of the (G, 5) int64 geom table.
G_GEOM, G_BODY, G_START, G_STOP, G_ROOT = 0, 1, 2, 3, 4
# Float64 parameters: surface_z, zeta, alpha_y, use_region, region (6).
P_SURFACE, P_ZETA, P_AY, P_USE_REGION, P_REGION = 0, 1, 2, 3, 4
N_PARAMS = 10
# Words of a per-MjData entry.
D_XPOS, D_XMAT, D_XIPOS, D_CVEL, D_SUBTREE_COM, D_GEOM_XPOS, D_XFRC = 0, 1, 2, 3, 4, 5, 6
D_USER, D_WRITTEN = 7, 8
DATA_WORDS = 9
# Return codes of step: 0 ok; -1 - k means tagged body k (in the field's body order) is not
# finite.
OK = 0


def _ptr_intrinsic(dtype):
    @intrinsic
    def as_ptr(typingctx, addr):
        sig = types.CPointer(dtype)(types.uint64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))

        return sig, codegen

    return as_ptr


f64_ptr = _ptr_intrinsic(types.float64)
i64_ptr = _ptr_intrinsic(types.int64)
u64_ptr = _ptr_intrinsic(types.uint64)


@numba.njit(inline="always", cache=True)
def _statics(f):
    """The field's static arrays from its table f (see the F_* layout)."""
    n_el, n_geom, n_bt = f[F_NELEM], f[F_NGEOM], f[F_NBODY_TAGGED]
    return (
        numba.carray(f64_ptr(f[F_CENT]), (n_el, 3)),
        numba.carray(f64_ptr(f[F_NORM]), (n_el, 3)),
        numba.carray(f64_ptr(f[F_AREA]), n_el),
        numba.carray(i64_ptr(f[F_GINT]), (n_geom, 5)),
        numba.carray(f64_ptr(f[F_GRB]), n_geom),
        numba.carray(i64_ptr(f[F_BODIES]), n_bt),
        numba.carray(f64_ptr(f[F_PARAMS]), N_PARAMS),
        numba.carray(f64_ptr(f[F_PARAMS] + 8 * P_REGION), (2, 3)),  # region, no allocation
        numba.carray(f64_ptr(f[F_COEF]), 18),
        numba.carray(i64_ptr(f[F_STATS]), 3),
    )


@numba.njit(inline="always", cache=True)
def _culled(geom_xpos, geom, r, surface_z, use_region, region):
    """True if a geom's bounding sphere (centre geom_xpos[geom], radius r) cannot touch the
    medium: entirely above the surface or outside the region. r = 0 (unknown) never culls."""
    if r <= 0.0:
        return False
    if geom_xpos[geom, 2] - r >= surface_z:
        return True
    if use_region:
        for c in range(3):
            gc = geom_xpos[geom, c]
            if gc + r < region[0, c] or gc - r > region[1, c]:
                return True
    return False


@numba.njit(inline="always", cache=True)
def _first_bad_body(bodies, xpos, cvel):
    """Index k of the first tagged body with a non-finite position or velocity, or -1."""
    for k in range(bodies.shape[0]):
        b = bodies[k]
        for c in range(3):
            if not np.isfinite(xpos[b, c]):
                return k
        for c in range(6):
            if not np.isfinite(cvel[b, c]):
                return k
    return -1


@numba.njit(cache=True, error_model="numpy")
def step(field_addr, data_addr):
    """One forward pass of the field on one MjData; returns OK or -1 - (bad tagged body)."""
    f = numba.carray(u64_ptr(field_addr), FIELD_WORDS)
    e = numba.carray(u64_ptr(data_addr), DATA_WORDS)
    n_el, n_geom, n_bt, nbody = f[F_NELEM], f[F_NGEOM], f[F_NBODY_TAGGED], f[F_NBODY]
    cent, norm, area, gint, grb, bodies, par, region, co, stats = _statics(f)
    last = numba.carray(f64_ptr(f[F_LAST_WRENCH]), (nbody, 6))
    elem_force = numba.carray(f64_ptr(f[F_ELEM_FORCE]), (n_el, 3))
    dirty = numba.carray(i64_ptr(f[F_DIRTY]), n_geom)  # 1: the geom's elem_force may be nonzero
    xpos = numba.carray(f64_ptr(e[D_XPOS]), (nbody, 3))
    xmat = numba.carray(f64_ptr(e[D_XMAT]), (nbody, 3, 3))
    xipos = numba.carray(f64_ptr(e[D_XIPOS]), (nbody, 3))
    cvel = numba.carray(f64_ptr(e[D_CVEL]), (nbody, 6))
    subtree_com = numba.carray(f64_ptr(e[D_SUBTREE_COM]), (nbody, 3))
    xfrc = numba.carray(f64_ptr(e[D_XFRC]), (nbody, 6))
    user = numba.carray(f64_ptr(e[D_USER]), (n_bt, 6))
    written = numba.carray(f64_ptr(e[D_WRITTEN]), (n_bt, 6))
    # Refuse to feed a non-finite state forward (Python names the body and raises).
    bad = _first_bad_body(bodies, xpos, cvel)
    if bad >= 0:
        return -1 - bad
    ngeom_model = 0
    for g in range(n_geom):
        ngeom_model = max(ngeom_model, gint[g, G_GEOM] + 1)
    geom_xpos = numba.carray(f64_ptr(e[D_GEOM_XPOS]), (ngeom_model, 3))
    surface_z, zeta, ay = par[P_SURFACE], par[P_ZETA], par[P_AY]
    use_region = par[P_USE_REGION] != 0.0
    for b in range(nbody):
        for c in range(6):
            last[b, c] = 0.0
    evaluated = 0
    acting = 0
    for g in range(n_geom):
        geom, b = gint[g, G_GEOM], gint[g, G_BODY]
        start, stop = gint[g, G_START], gint[g, G_STOP]
        if _culled(geom_xpos, geom, grb[g], surface_z, use_region, region):
            if dirty[g]:
                for i in range(start, stop):
                    elem_force[i, 0] = 0.0
                    elem_force[i, 1] = 0.0
                    elem_force[i, 2] = 0.0
                dirty[g] = 0
            continue
        dirty[g] = 1
        acting += _kernel.body_wrench(
            cent, norm, area, start, stop, xmat[b], xpos[b], cvel[b, :3], cvel[b, 3:],
            subtree_com[gint[g, G_ROOT]], xipos[b], co, ay, zeta, surface_z, use_region,
            region, last[b], elem_force,
        )  # fmt: skip
        evaluated += stop - start
    stats[0] += 1
    stats[1] += evaluated
    stats[2] += acting
    # xfrc_applied ownership (mjrft.field): a row that differs from what was written was
    # assigned by the user and becomes the user part; then row = user + RFT.
    ring_size = f[F_RING_SIZE]
    ring = numba.carray(f64_ptr(f[F_RING]), (ring_size + 1, 2, n_bt, 6))
    slot = int(ring[0, 0, 0, 0]) % ring_size  # ring[0] holds the write counter
    for k in range(n_bt):
        b = bodies[k]
        assigned = False
        for c in range(6):
            if xfrc[b, c] != written[k, c]:
                assigned = True
        for c in range(6):
            if assigned:
                user[k, c] = xfrc[b, c]
            total = user[k, c] + last[b, c]
            xfrc[b, c] = total
            written[k, c] = total
            ring[1 + slot, 0, k, c] = total
            ring[1 + slot, 1, k, c] = user[k, c]
    ring[0, 0, 0, 0] += 1.0
    return OK


@numba.njit(cache=True, error_model="numpy")
def batch_wrench(field_addr, xpos, xmat, xipos, cvel, subtree_com, geom_xpos, out):
    """RFT wrenches of many simulations of one model in one call (mjrft.batch).

    xpos (S, nbody, 3), xmat (S, nbody, 9), xipos (S, nbody, 3), cvel (S, nbody, 6),
    subtree_com (S, nbody, 3), geom_xpos (S, ngeom, 3): bound MjData fields, world frame.
    out (S, nbody, 6): filled with each body's force and torque at its CoM. Returns OK, or
    -1 - s for the first simulation s whose state is not finite. Copies run one after the
    other: numba threads here compete with MuJoCo's batch threads (measured 3-20x slower on 2
    cores).
    """
    f = numba.carray(u64_ptr(field_addr), FIELD_WORDS)
    n_el, n_geom = f[F_NELEM], f[F_NGEOM]
    cent, norm, area, gint, grb, bodies, par, region, co, stats = _statics(f)
    surface_z, zeta, ay = par[P_SURFACE], par[P_ZETA], par[P_AY]
    use_region = par[P_USE_REGION] != 0.0
    n_sim = xpos.shape[0]
    for s in range(n_sim):
        if _first_bad_body(bodies, xpos[s], cvel[s]) >= 0:
            return -1 - s
    out[:] = 0.0
    evaluated = np.zeros(n_sim, np.int64)
    acting = np.zeros(n_sim, np.int64)
    for s in range(n_sim):
        elem_force = np.empty((n_el, 3))  # scratch: per-element forces are not kept for batches
        for g in range(n_geom):
            geom, b = gint[g, G_GEOM], gint[g, G_BODY]
            start, stop = gint[g, G_START], gint[g, G_STOP]
            if _culled(geom_xpos[s], geom, grb[g], surface_z, use_region, region):
                continue
            acting[s] += _kernel.body_wrench(
                cent, norm, area, start, stop, xmat[s, b].reshape((3, 3)), xpos[s, b],
                cvel[s, b, :3], cvel[s, b, 3:], subtree_com[s, gint[g, G_ROOT]], xipos[s, b],
                co, ay, zeta, surface_z, use_region, region, out[s, b], elem_force,
            )  # fmt: skip
            evaluated[s] += stop - start
    stats[0] += n_sim
    stats[1] += evaluated.sum()
    stats[2] += acting.sum()
    return OK
