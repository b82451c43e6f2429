"""The RFT model on tagged bodies, compiled: state check, culling, and wrenches at a twist.

Every function takes ``m_rec, e_rec``: the addresses of the field's model record and of one
MjData's entry record (``mjrft.field.tables``), and unpacks them into the three groups MuJoCo
Warp would pass: ``m`` the field's static tables (``FieldModel``), ``d`` the MjData's arrays
(``MjDataArrays``), ``s`` the field's state for that MjData (``FieldData``). World frame
throughout; wrenches are force [N] then torque [N m] about the body's CoM (``xipos``).

A geom is evaluated by the compiled kernel (``mjrft.core.kernel.body_wrench``) for Fourier-form
media, or, for media given by Python callables, by their NumPy evaluation
(``mjrft.field.python_material``; an object-mode call, so only where Python holds the GIL).
"""

from __future__ import annotations

import numba
import numpy as np

from mjrft.core import kernel, surface
from mjrft.field import python_material
from mjrft.field.tables import unpack

_JIT = {"cache": True, "error_model": "numpy"}


@numba.njit(**_JIT)
def first_bad_body(m_rec, e_rec):
    """Index k of the first tagged body with a non-finite position or velocity, or -1."""
    m, d, _ = unpack(m_rec, e_rec)
    for k in range(m.tbody_bodyid.shape[0]):
        b = m.tbody_bodyid[k]
        for c in range(3):
            if not np.isfinite(d.xpos[b, c]):
                return k
        for c in range(6):
            if not np.isfinite(d.cvel[b, c]):
                return k
    return -1


@numba.njit(inline="always", **_JIT)
def geom_top(m, d, g):
    """An upper bound [m] of the surface height under tagged geom g's bounding sphere (the
    surface's ceiling if its radius is 0, unknown to MuJoCo)."""
    r = m.tgeom_rbound[g]
    if r <= 0.0:
        return surface.ceiling(m.surface_prm, d.userdata)
    geom = m.tgeom_geomid[g]
    return surface.highest_near(
        m.surface_prm, d.userdata, d.geom_xpos[geom, 0], d.geom_xpos[geom, 1], r
    )


@numba.njit(inline="always", **_JIT)
def culled(m, d, g):
    """True if tagged geom g's bounding sphere cannot touch the medium: entirely above the
    surface or outside the region. A radius of 0 (unknown to MuJoCo) never culls."""
    r = m.tgeom_rbound[g]
    if r <= 0.0:
        return False
    geom = m.tgeom_geomid[g]
    if d.geom_xpos[geom, 2] - r >= geom_top(m, d, g):
        return True
    if m.use_region:
        for c in range(3):
            gc = d.geom_xpos[geom, c]
            if gc + r < m.region[0, c] or gc - r > m.region[1, c]:
                return True
    return False


@numba.njit(inline="always", **_JIT)
def geom_wrench(m, d, g, omega, v_ref, p_ref, com, wrench, elem_force):
    """Add to wrench (6,) the RFT wrench on tagged geom g at its body's pose, moving with angular
    velocity omega (3,) [rad/s] and linear velocity v_ref (3,) [m/s] at the world point p_ref
    (3,); torque about com (3,). Writes the geom's rows of elem_force. Returns #acting."""
    b = m.tbody_bodyid[m.tgeom_tbody[g]]
    start = m.tgeom_elemadr[g]
    stop = start + m.tgeom_elemnum[g]
    if m.material_key == 0:
        return kernel.body_wrench(
            m.elem_pos, m.elem_normal, m.elem_area, m.elem_reach, m.elem_patch, start, stop,
            m.coef, m.alpha_y, m.zeta, m.surface_prm, m.surface_grid, m.use_region != 0,
            m.region, d.userdata,
            d.xmat[b], d.xpos[b], omega, v_ref, p_ref, com,
            wrench, elem_force, np.empty((0, kernel.ROW)),
        )  # fmt: skip
    return _python_geom_wrench(
        m.material_key, start, stop, d.xmat[b], d.xpos[b], omega, v_ref, p_ref, com, wrench,
        elem_force,
    )  # fmt: skip


@numba.njit(**_JIT)
def _python_geom_wrench(key, start, stop, rot, pos, omega, v_ref, p_ref, com, wrench, elem_force):
    """geom_wrench for a medium given by Python callables (object mode: needs the GIL)."""
    with numba.objmode(acting="int64"):
        acting = python_material.geom_wrench(
            key, start, stop, rot, pos, omega, v_ref, p_ref, com, wrench, elem_force
        )
    return acting


@numba.njit(**_JIT)
def twist_wrench(m_rec, e_rec, k, v, omega, out):
    """Set out (6,) to the RFT wrench on tagged body k's geoms in play (not culled this pass),
    the body moving with the twist (v at the CoM [m/s], omega [rad/s]; world frame). Element
    forces go to s.scratch (elem_force keeps the pure model). Returns (#evaluated, #acting)."""
    m, d, s = unpack(m_rec, e_rec)
    out[:] = 0.0
    b = m.tbody_bodyid[k]
    evaluated = 0
    acting = 0
    for g in range(m.tbody_geomadr[k], m.tbody_geomadr[k] + m.tbody_geomnum[k]):
        if s.cull[g]:
            continue
        acting += geom_wrench(m, d, g, omega, v, d.xipos[b], d.xipos[b], out, s.scratch)
        evaluated += m.tgeom_elemnum[g]
    return evaluated, acting


@numba.njit(**_JIT)
def in_play(m_rec, e_rec, k):
    """True if a geom of tagged body k may touch the medium this pass."""
    m, _, s = unpack(m_rec, e_rec)
    for g in range(m.tbody_geomadr[k], m.tbody_geomadr[k] + m.tbody_geomnum[k]):
        if not s.cull[g]:
            return True
    return False


@numba.njit(**_JIT)
def pure_wrenches(m_rec, e_rec):
    """The pure model on every tagged body that neither keeps nor freezes its wrench this pass:
    culls geoms (s.cull), zeroes element forces of geoms that left the medium, and writes
    s.wrench rows and s.elem_force. Returns (#evaluated, #acting)."""
    m, d, s = unpack(m_rec, e_rec)
    for k in range(m.tbody_bodyid.shape[0]):
        if not s.keep[k]:
            s.wrench[m.tbody_bodyid[k]] = 0.0
    evaluated = 0
    acting = 0
    for g in range(m.tgeom_geomid.shape[0]):
        k = m.tgeom_tbody[g]
        if s.keep[k]:
            continue
        b = m.tbody_bodyid[k]
        if culled(m, d, g):  # inlined
            s.cull[g] = 1
            if s.geom_dirty[g]:
                start = m.tgeom_elemadr[g]
                s.elem_force[start : start + m.tgeom_elemnum[g]] = 0.0
                s.geom_dirty[g] = 0
            continue
        s.geom_dirty[g] = 1
        if s.frz[k]:
            continue
        acting += geom_wrench(
            m, d, g, d.cvel[b, :3], d.cvel[b, 3:], d.subtree_com[m.tbody_rootid[k]],
            d.xipos[b], s.wrench[b], s.elem_force,
        )  # fmt: skip
        evaluated += m.tgeom_elemnum[g]
    return evaluated, acting
