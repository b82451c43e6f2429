"""The compiled pass's inputs as records: static field tables, MjData arrays, per-MjData state.

Three groups, as MuJoCo Warp groups kernel arguments (model, data in, data out), each a NumPy
record of addresses and sizes that the compiled code unpacks into a ``NamedTuple`` of arrays:

* ``FieldModel`` (``m``): built once per field at load; the elements of every tagged geom in
  their body frame, the tagged geoms and bodies, the medium, the low-speed settings, and views of
  the MjModel fields read live each pass (a user may change ``opt.timestep`` between steps);
* ``MjDataArrays`` (``d``): the MjData fields the pass reads (``xpos`` ... ``geom_xpos``,
  ``time``) and the one it writes (``xfrc_applied``), MuJoCo's names;
* ``FieldData`` (``s``): the field's state for one MjData: the ``xfrc_applied`` ownership
  record, the RK4 stage record, this pass's wrenches and element forces, work arrays and
  counters. It belongs to the MjData being stepped, so two threads stepping two MjData of one
  field never share it.

The records are the only place these layouts are written down: ``pack`` fills one from the
arrays' NamedTuple, the ``unpack_*`` functions rebuild the NamedTuple in compiled code
(``tests/test_paths.py`` round-trips every field). The owner of a record keeps its arrays alive
while their addresses are published.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from mjrft.core.quadrature import PATCH_SIZE
from mjrft.core.soil import N_SOIL_STATS
from mjrft.core.surface import PRM_SIZE

#: Work counters per FieldData: passes evaluated, triangles evaluated, triangles acting, and of
#: the low-speed treatment body-passes stuck, slipping, moved by the implicit step.
N_STATS = 6
STATS = ("calls", "evaluated", "acting", "stuck", "slipping", "implicit")
#: The RK4 stage record (mjrft.field.rk4): time of the last evaluated pass and the passes since,
#: then per tagged body its mode for stages 2-4, the twist of stage 1 (v at the CoM, omega;
#: world), stage 1's implicit correction (world force, torque about the CoM) and the terms of
#: the later stages' energy guard (rk4.step_balance).
RK4_HEAD, RK4_BODY = 2, 49


class FieldModel(NamedTuple):
    """Static tables of one field (built once at load), MuJoCo's names where MuJoCo has one.

    Elements are grouped by tagged geom, tagged geoms by tagged body (bodies in id order).
    """

    nbody: int  # MuJoCo's nbody (rows of xfrc_applied, xpos, ...)
    ngeom: int  # MuJoCo's ngeom (rows of geom_xpos)
    elem_pos: np.ndarray  # (nelem, 3) triangle centroids, body frame [m]
    elem_normal: np.ndarray  # (nelem, 3) outward unit normals, body frame
    elem_area: np.ndarray  # (nelem,) [m^2]
    tgeom_geomid: np.ndarray  # (ntgeom,) MuJoCo geom id of each tagged geom
    tgeom_tbody: np.ndarray  # (ntgeom,) its tagged body (index into tbody_*)
    tgeom_elemadr: np.ndarray  # (ntgeom,) first element
    tgeom_elemnum: np.ndarray  # (ntgeom,) number of elements
    tgeom_rbound: np.ndarray  # (ntgeom,) bounding-sphere radius [m] (0: never culled)
    tbody_bodyid: np.ndarray  # (ntbody,) MuJoCo body id of each tagged body
    tbody_rootid: np.ndarray  # (ntbody,) its root body (cvel's reference is subtree_com there)
    tbody_geomadr: np.ndarray  # (ntbody,) first tagged geom
    tbody_geomnum: np.ndarray  # (ntbody,) number of tagged geoms
    tbody_treat: np.ndarray  # (ntbody,) 1 if the low-speed treatment may act on it
    surface_z: float  # free-surface height [m], world frame
    use_region: int  # 1 if region bounds the medium
    region: np.ndarray  # (2, 3) world box [m]: min corner, max corner
    zeta: float  # scale of the medium [N/m^3]
    alpha_y: float  # generic out-of-plane coefficient
    coef: np.ndarray  # (ncoef,) kernel coefficients (Material.kernel_coefficients)
    material_key: int  # 0: the compiled kernel; else the Python material's key
    treat: int  # 1 if the low-speed treatment is on
    reach: float  # its reach
    jacobian_step: float  # mjrft.field.lowspeed.JACOBIAN_STEP
    rk4_hold_steps: float  # mjrft.field.lowspeed.RK4_HOLD_STEPS
    dsbl_gravity: int  # mjtDisableBit.mjDSBL_GRAVITY
    int_rk4: int  # mjtIntegrator.mjINT_RK4
    opt_timestep: np.ndarray  # (1,) live view of opt.timestep [s]
    opt_gravity: np.ndarray  # (3,) live view of opt.gravity [m/s^2]
    opt_disableflags: np.ndarray  # (1,) int32, live
    opt_integrator: np.ndarray  # (1,) int32, live
    body_mass: np.ndarray  # (nbody,) live [kg]
    body_inertia: np.ndarray  # (nbody, 3) live, principal moments [kg m^2]
    body_gravcomp: np.ndarray  # (nbody,) live
    nv: int  # MuJoCo's nv
    nC: int  # MuJoCo's nC (size of M, the sparse inertia)
    mech: int  # 1 if the treatment acts on bodies in mechanisms (mjrft.field.mechanism)
    tbody_mech: np.ndarray  # (ntbody,) 1 if it is such a body
    tbody_dofmask: np.ndarray  # (ntbody, nv) 1 where dof j moves tagged body k
    M_rownnz: np.ndarray  # (nv,) MuJoCo's layout of M (lower triangle, CSR), int64
    M_rowadr: np.ndarray  # (nv,)
    M_colind: np.ndarray  # (nC,)
    nu: int  # MuJoCo's nu
    nJmom: int  # MuJoCo's nJmom (size of actuator_moment)
    dsbl_actuation: int  # mjtDisableBit.mjDSBL_ACTUATION
    dsbl_clampctrl: int  # mjtDisableBit.mjDSBL_CLAMPCTRL
    actuator_affine: np.ndarray  # (nu,) 1: gain fixed/affine, bias none/affine, not actearly
    actuator_gainaffine: np.ndarray  # (nu,) 1 if its gain is affine (else fixed)
    actuator_biasaffine: np.ndarray  # (nu,) 1 if its bias is affine (else none)
    actuator_actadr: np.ndarray  # (nu,) its activation's address in act (-1: input is ctrl)
    actuator_ctrllimited: np.ndarray  # (nu,)
    actuator_forcelimited: np.ndarray  # (nu,)
    actuator_gainprm: np.ndarray  # (nu, 10) live
    actuator_biasprm: np.ndarray  # (nu, 10) live
    actuator_ctrlrange: np.ndarray  # (nu, 2) live
    actuator_forcerange: np.ndarray  # (nu, 2) live
    surface_prm: np.ndarray  # (surface.PRM_SIZE,) the free surface (mjrft.core.surface)
    surface_grid: np.ndarray  # (surface_nrow, surface_ncol) its grid heights [m], world frame
    soil: int  # 1 if the surface deforms (kind SOIL: mjrft.core.soil)
    nsoil: int  # size of the soil block (surface.soil_block; 1 if the surface does not deform)
    elem_vert: np.ndarray  # (nelem, 9) triangle vertices, body frame [m] (soil; else (1, 9))
    elem_reach: np.ndarray  # (nelem,) largest centroid-corner distance [m] (core.quadrature)
    elem_patch: np.ndarray  # (nelem, quadrature.PATCH_SIZE) corner data, body frame


class MjDataArrays(NamedTuple):
    """The MjData fields the pass reads (``*_in`` in MuJoCo Warp) and writes (xfrc_applied)."""

    xpos: np.ndarray  # (nbody, 3)
    xmat: np.ndarray  # (nbody, 3, 3)
    xipos: np.ndarray  # (nbody, 3)
    ximat: np.ndarray  # (nbody, 3, 3)
    cvel: np.ndarray  # (nbody, 6)
    subtree_com: np.ndarray  # (nbody, 3)
    geom_xpos: np.ndarray  # (ngeom, 3)
    time: np.ndarray  # (1,)
    xfrc_applied: np.ndarray  # (nbody, 6), read and written
    M: np.ndarray  # (nC,) joint-space inertia, MuJoCo's CSR lower triangle
    qvel: np.ndarray  # (nv,)
    qacc: np.ndarray  # (nv,): the previous forward pass's, when the passive callback runs
    cdof: np.ndarray  # (nv, 6)
    ctrl: np.ndarray  # (nu,)
    act: np.ndarray  # (na,)
    actuator_length: np.ndarray  # (nu,): this state's (the transmission runs before passive)
    actuator_velocity: np.ndarray  # (nu,): this state's
    actuator_force: np.ndarray  # (nu,): the previous forward pass's
    actuator_moment: np.ndarray  # (nJmom,) this state's, sparse rows
    moment_rownnz: np.ndarray  # (nu,) int32
    moment_rowadr: np.ndarray  # (nu,) int32
    moment_colind: np.ndarray  # (nJmom,) int32
    userdata: np.ndarray  # (nsoil,) the soil block: the last nsoil entries of userdata


class FieldData(NamedTuple):
    """The field's state for one MjData (world frame; wrenches: force [N], torque about the
    body's CoM [N m])."""

    user: np.ndarray  # (nbody, 6) user part of each tagged row of xfrc_applied
    written: np.ndarray  # (nbody, 6) what the last installed pass wrote there
    user_in: np.ndarray  # (nbody, 6) other applied wrenches for the explicit path
    wrench: np.ndarray  # (nbody, 6) this pass's RFT wrench (held rows: their stage 1's)
    elem_force: np.ndarray  # (nelem, 3) element forces of this pass's pure model [N]
    scratch: np.ndarray  # (nelem, 3) element forces of the treatment's extra evaluations
    rk4: np.ndarray  # (RK4_HEAD + RK4_BODY ntbody,) the RK4 stage record
    geom_dirty: np.ndarray  # (ntgeom,) 1 where elem_force may be nonzero
    cull: np.ndarray  # (ntgeom,) 1 where the geom cannot touch the medium this pass
    keep: np.ndarray  # (ntbody,) 1: keeps its RK4 step's first-stage wrench (RK4_HOLD)
    frz: np.ndarray  # (ntbody,) 1: feels the model with stage 1's twist (RK4_FROZEN)
    slow: np.ndarray  # (ntbody,) 1: later RK4 stages must not evaluate the pure model
    frozen: np.ndarray  # (ntbody, 12) stage 1's twist and implicit correction
    decision: np.ndarray  # (ntbody,) the treatment's decisions (lowspeed PURE ... IMPLICIT)
    stats: np.ndarray  # (N_STATS,) int64 counters (STATS)
    status: np.ndarray  # (1,) int64: status of the last pass (passive.OK or a failure code)
    ring: np.ndarray  # (nring + 1, 2, ntbody, 6) recent (written, user) rows; [0, 0, 0, 0]: count
    report_wrench: np.ndarray  # (nbody, 6) the field's last_wrench (shared by its MjData)
    report_decision: np.ndarray  # (ntbody,) the field's last_decision (shared)
    mech_tau: np.ndarray  # (nv,) generalized force the last pass applied to mechanism bodies
    mech_time: np.ndarray  # (3,) time of the last installed pass, 1 once there was one, 1 if
    #   its predictor was valid
    mech_prev: np.ndarray  # (ntbody, 6) wrench of each body held in the last pass
    mech_held: np.ndarray  # (ntbody,) 1 if held in the last pass
    mech_in: np.ndarray  # (2, nv) qacc and mech_tau as the first pass at this time read them
    mech_in_prev: np.ndarray  # (ntbody, 6) mech_prev as that pass read it
    mech_in_force: np.ndarray  # (nu,) actuator_force as that pass read it
    mech_in_held: np.ndarray  # (ntbody,) mech_held as that pass read it
    mech_R: np.ndarray  # (ntbody, 6) the medium's resistance last evaluated for a hold
    mech_key: np.ndarray  # (ntbody, 19) where: CoM, inertial frame, direction; 1 if valid
    mech_M: np.ndarray  # (nv, nv) M of the configuration the factors below belong to
    mech_cfg: np.ndarray  # (1 + ntbody + 6 nv + 6 ntbody,) that configuration: n, rows, cdof,
    #   CoMs and root subtree CoMs; n = -1: none
    mech_hkey: np.ndarray  # (1 + 6 ntbody,) held rows mech_S factors; [0]: -1 none, -2 no mech_A
    mech_L: np.ndarray  # (nv, nv) work: M, then its Cholesky factor
    mech_J: np.ndarray  # (6 ntbody, nv) work: Jacobians of the bodies in play
    mech_X: np.ndarray  # (6 ntbody, nv) work: rows of L^-1 J^T (M = L L^T)
    mech_A: np.ndarray  # (6 ntbody, 6 ntbody) work: J M^-1 J^T
    mech_S: np.ndarray  # (6 ntbody, 6 ntbody) work: the held bodies' block, factored
    mech_vec: np.ndarray  # (3, max(nv, 6 ntbody)) work vectors
    soil_floor: np.ndarray  # (nrow, ncol) work: intruders' lowest point over each vertex [m]
    soil_owner: np.ndarray  # (nrow, ncol) work: the tagged body occupying it, -1 none
    soil_queue: np.ndarray  # (nrow ncol,) work: the relaxation's queue of vertices
    soil_box: np.ndarray  # (ntbody + 3, 4) work: vertex boxes of footprints, their union, the
    #   box the relaxation starts from and the box it has seen
    soil_stats: np.ndarray  # (soil.N_SOIL_STATS,) counters (soil.SOIL_STATS)


def _sizes(names: tuple[str, ...]) -> list[tuple[str, type]]:
    return [(n, np.int64) for n in names]


_MODEL_SIZES = ("nelem", "ntgeom", "ntbody", "surface_nrow", "surface_ncol", "ncoef")
_FLOAT_SCALARS = {"surface_z", "zeta", "alpha_y", "reach", "jacobian_step", "rk4_hold_steps"}
_INT_SCALARS = {
    "nbody", "ngeom", "use_region", "material_key", "treat", "dsbl_gravity", "int_rk4", "nv",
    "nC", "mech", "nu", "nJmom", "dsbl_actuation", "dsbl_clampctrl", "soil", "nsoil",
}  # fmt: skip


def _record(fields: tuple[str, ...], sizes: tuple[str, ...]) -> np.dtype:
    """One record: sizes (int64), scalars (float64 or int64), array addresses (uint64)."""
    out = _sizes(sizes)
    for name in fields:
        if name in _FLOAT_SCALARS:
            out.append((name, np.float64))
        elif name in _INT_SCALARS:
            out.append((name, np.int64))
        else:
            out.append((name, np.uint64))
    return np.dtype(out)


MODEL_RECORD = _record(FieldModel._fields, _MODEL_SIZES)
#: Per-MjData entry: the MjData's arrays, then the field's state for it.
ENTRY_RECORD = _record(MjDataArrays._fields + FieldData._fields, ("nring", "na"))
ENTRY_SIZE = ENTRY_RECORD.itemsize


def pack(record: np.dtype, parts: tuple[NamedTuple, ...], sizes: dict[str, int]) -> np.ndarray:
    """A (1,) record of ``record`` dtype describing the arrays and scalars of ``parts``.

    Arrays must be C-contiguous and keep their dtype (float64, int64; int32 for the MjModel
    option flags); the caller keeps them alive while the record is in use.
    """
    out = np.zeros(1, dtype=record)
    for key, value in sizes.items():
        out[key] = value
    for part in parts:
        for name, value in zip(part._fields, part, strict=True):
            if isinstance(value, np.ndarray):
                if not value.flags.c_contiguous:
                    raise ValueError(f"{name} must be C-contiguous")
                out[name] = value.ctypes.data
            else:
                out[name] = value
    return out


# ---------------------------------------------------------------------- compiled unpacking
def pointer(target):
    """An intrinsic casting a uint64 address to a pointer to target (a numba type)."""

    @intrinsic
    def as_pointer(typingctx, address):
        sig = types.CPointer(target)(types.uint64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))

        return sig, codegen

    return as_pointer


f64_ptr = pointer(types.float64)
i64_ptr = pointer(types.int64)
i32_ptr = pointer(types.int32)
u64_ptr = pointer(types.uint64)
_model_ptr = pointer(numba.from_dtype(MODEL_RECORD))
_entry_ptr = pointer(numba.from_dtype(ENTRY_RECORD))
_JIT = {"cache": True, "inline": "always"}


@numba.njit(**_JIT)
def _f(address, shape):
    return numba.carray(f64_ptr(address), shape)


@numba.njit(**_JIT)
def _i(address, shape):
    return numba.carray(i64_ptr(address), shape)


@numba.njit(**_JIT)
def _i32(address, shape):
    return numba.carray(i32_ptr(address), shape)


@numba.njit(**_JIT)
def unpack_model(address):
    """FieldModel from the address of its MODEL_RECORD."""
    t = numba.carray(_model_ptr(address), 1)[0]
    nb, ne, ng, nk = t.nbody, t.nelem, t.ntgeom, t.ntbody
    nvert = ne if t.soil else 1
    return FieldModel(
        t.nbody, t.ngeom, _f(t.elem_pos, (ne, 3)), _f(t.elem_normal, (ne, 3)),
        _f(t.elem_area, ne), _i(t.tgeom_geomid, ng), _i(t.tgeom_tbody, ng),
        _i(t.tgeom_elemadr, ng), _i(t.tgeom_elemnum, ng), _f(t.tgeom_rbound, ng),
        _i(t.tbody_bodyid, nk), _i(t.tbody_rootid, nk), _i(t.tbody_geomadr, nk),
        _i(t.tbody_geomnum, nk), _i(t.tbody_treat, nk), t.surface_z, t.use_region,
        _f(t.region, (2, 3)), t.zeta, t.alpha_y, _f(t.coef, t.ncoef), t.material_key, t.treat,
        t.reach, t.jacobian_step, t.rk4_hold_steps, t.dsbl_gravity, t.int_rk4,
        _f(t.opt_timestep, 1), _f(t.opt_gravity, 3),
        numba.carray(i32_ptr(t.opt_disableflags), 1), numba.carray(i32_ptr(t.opt_integrator), 1),
        _f(t.body_mass, nb), _f(t.body_inertia, (nb, 3)), _f(t.body_gravcomp, nb),
        t.nv, t.nC, t.mech, _i(t.tbody_mech, nk), _i(t.tbody_dofmask, (nk, t.nv)),
        _i(t.M_rownnz, t.nv), _i(t.M_rowadr, t.nv), _i(t.M_colind, t.nC), t.nu, t.nJmom,
        t.dsbl_actuation, t.dsbl_clampctrl, _i(t.actuator_affine, t.nu),
        _i(t.actuator_gainaffine, t.nu), _i(t.actuator_biasaffine, t.nu),
        _i(t.actuator_actadr, t.nu), _i(t.actuator_ctrllimited, t.nu),
        _i(t.actuator_forcelimited, t.nu), _f(t.actuator_gainprm, (t.nu, 10)),
        _f(t.actuator_biasprm, (t.nu, 10)), _f(t.actuator_ctrlrange, (t.nu, 2)),
        _f(t.actuator_forcerange, (t.nu, 2)), _f(t.surface_prm, PRM_SIZE),
        _f(t.surface_grid, (t.surface_nrow, t.surface_ncol)), t.soil, t.nsoil,
        _f(t.elem_vert, (nvert, 9)), _f(t.elem_reach, ne), _f(t.elem_patch, (ne, PATCH_SIZE)),
    )  # fmt: skip


@numba.njit(**_JIT)
def unpack_entry(m, address):
    """(MjDataArrays, FieldData) of one MjData from the address of its ENTRY_RECORD."""
    t = numba.carray(_entry_ptr(address), 1)[0]
    nb, ne, ng, nk = m.nbody, m.elem_area.shape[0], m.tgeom_geomid.shape[0], m.tbody_bodyid.shape[0]
    nv = m.nv
    soil_shape = (m.surface_grid.shape[0], m.surface_grid.shape[1]) if m.soil else (1, 1)
    d = MjDataArrays(
        _f(t.xpos, (nb, 3)), _f(t.xmat, (nb, 3, 3)), _f(t.xipos, (nb, 3)),
        _f(t.ximat, (nb, 3, 3)), _f(t.cvel, (nb, 6)), _f(t.subtree_com, (nb, 3)),
        _f(t.geom_xpos, (m.ngeom, 3)), _f(t.time, 1), _f(t.xfrc_applied, (nb, 6)),
        _f(t.M, m.nC), _f(t.qvel, m.nv), _f(t.qacc, m.nv), _f(t.cdof, (m.nv, 6)),
        _f(t.ctrl, m.nu), _f(t.act, t.na), _f(t.actuator_length, m.nu),
        _f(t.actuator_velocity, m.nu), _f(t.actuator_force, m.nu), _f(t.actuator_moment, m.nJmom),
        _i32(t.moment_rownnz, m.nu), _i32(t.moment_rowadr, m.nu), _i32(t.moment_colind, m.nJmom),
        _f(t.userdata, m.nsoil),
    )  # fmt: skip
    s = FieldData(
        _f(t.user, (nb, 6)), _f(t.written, (nb, 6)), _f(t.user_in, (nb, 6)),
        _f(t.wrench, (nb, 6)), _f(t.elem_force, (ne, 3)), _f(t.scratch, (ne, 3)),
        _f(t.rk4, RK4_HEAD + RK4_BODY * nk), _i(t.geom_dirty, ng), _i(t.cull, ng),
        _i(t.keep, nk), _i(t.frz, nk), _i(t.slow, nk), _f(t.frozen, (nk, 12)),
        _i(t.decision, nk), _i(t.stats, N_STATS), _i(t.status, 1),
        _f(t.ring, (t.nring + 1, 2, nk, 6)), _f(t.report_wrench, (nb, 6)),
        _i(t.report_decision, nk), _f(t.mech_tau, nv), _f(t.mech_time, 3),
        _f(t.mech_prev, (nk, 6)), _i(t.mech_held, nk), _f(t.mech_in, (2, nv)),
        _f(t.mech_in_prev, (nk, 6)), _f(t.mech_in_force, m.nu), _i(t.mech_in_held, nk),
        _f(t.mech_R, (nk, 6)),
        _f(t.mech_key, (nk, 19)), _f(t.mech_M, (nv, nv)),
        _f(t.mech_cfg, 1 + nk + 6 * nv + 6 * nk), _i(t.mech_hkey, 1 + 6 * nk),
        _f(t.mech_L, (nv, nv)),
        _f(t.mech_J, (6 * nk, nv)), _f(t.mech_X, (6 * nk, nv)), _f(t.mech_A, (6 * nk, 6 * nk)),
        _f(t.mech_S, (6 * nk, 6 * nk)), _f(t.mech_vec, (3, max(nv, 6 * nk))),
        _f(t.soil_floor, soil_shape), _i(t.soil_owner, soil_shape),
        _i(t.soil_queue, soil_shape[0] * soil_shape[1]), _f(t.soil_box, (nk + 3, 4)),
        _f(t.soil_stats, N_SOIL_STATS),
    )  # fmt: skip
    return d, s


@numba.njit(**_JIT)
def unpack(m_rec, e_rec):
    """(FieldModel, MjDataArrays, FieldData) from the addresses of the field's model record and
    an MjData's entry record.

    The compiled pass hands these two addresses from function to function and each function
    unpacks what it uses: unpacking costs a few loads, while passing the three NamedTuples of
    ~60 arrays by value cost ~0.2 us per call (measured on the lifted ellipsoid rig).
    """
    m = unpack_model(m_rec)
    d, s = unpack_entry(m, e_rec)
    return m, d, s


def arena(specs: dict[str, tuple[tuple[int, ...], type, float]]) -> dict[str, np.ndarray]:
    """C-contiguous arrays carved one after the other out of one allocation.

    specs: name -> (shape, dtype, fill value). The compiled pass touches a few dozen small
    arrays per forward pass; side by side they share cache lines and pages instead of each
    costing a miss after MuJoCo's own work has evicted them (measured: ~0.2 us per pass on the
    ellipsoid rig). Every view starts on an 8-byte boundary.
    """
    offsets, total = {}, 0
    for name, (shape, dtype, _) in specs.items():
        offsets[name] = total
        nbytes = int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
        total += -(-nbytes // 8) * 8
    buffer = np.zeros(max(total, 8), dtype=np.uint8)
    out = {}
    for name, (shape, dtype, fill) in specs.items():
        view = np.ndarray(shape, dtype=dtype, buffer=buffer, offset=offsets[name])
        view[...] = fill
        out[name] = view
    return out
