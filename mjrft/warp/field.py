"""``WarpField``: the granular field's static tables on a Warp device and its per-pass kernels.

Each pass, for the ``nworld`` worlds of an ``mjw.Data``: with a deforming ground,
``soil.deform_kernel`` (nworld) moves each world's ground to its intruders first;
``cull_kernel`` (nworld x tagged geoms) marks the geoms whose bounding sphere is above the
surface or outside the region, as the engine's ``Culled`` (engine/evaluate.cc);
``element_kernel`` (nworld x elements) evaluates every element of a geom in play at its
quadrature point (``mjrft.warp.quadrature``) and adds its force and torque to its body's wrench;
``user_kernel`` (nworld x tagged bodies) reads the user part of ``xfrc_applied`` (the engine's
per-component rule, docs/field.md); the low-speed treatment replaces the wrenches of bodies near
rest (``lowspeed.treat_kernel``, nworld x tagged bodies; ``mechanism.mechanism_kernel``,
nworld); ``write_kernel`` writes user part + RFT wrench into ``xfrc_applied``. Everything runs
in float64 whatever MuJoCo Warp's own precision (float32): poses and velocities are widened on
load.

Frames: element tables in the body frame; everything per world in the world frame; wrenches
are force [N] then torque [N m] about the body's CoM (``xipos``), ``xfrc_applied``'s layout.
"""

from __future__ import annotations

import contextlib
import weakref
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import warp as wp

from mjrft.core import soil as core_soil
from mjrft.core import surface as core_surface
from mjrft.core.material import Material, as_material
from mjrft.field import plugin
from mjrft.field.model import FieldSetup
from mjrft.field.options import SceneOptions
from mjrft.field.scene import Scene, SceneError, scene_from_model
from mjrft.warp import lowspeed as ls
from mjrft.warp import mechanism, soil, surface
from mjrft.warp.law import element_force, f64, forces_kernel, vec3d
from mjrft.warp.lowspeed import Elements, Medium, widen
from mjrft.warp.quadrature import quadrature_point
from mjrft.warp.surface import Surface


class UnsupportedScene(SceneError):
    """The scene uses a feature the Warp field does not have yet; the message names it."""


# --------------------------------------------------------------------------------- kernels
@wp.kernel
def cull_kernel(
    # Model
    tgeom_geomid: wp.array(dtype=int), tgeom_rbound: wp.array(dtype=f64), medium: Medium,
    # Data in
    geom_xpos: wp.array2d(dtype=wp.vec3),
    # Data out
    cull: wp.array2d(dtype=int),
):  # fmt: skip
    """cull[w, g] = 1 if tagged geom g of world w cannot touch the medium (the engine's
    ``Culled``: bounding sphere above the surface or outside the region; radius 0 never)."""
    w, g = wp.tid()
    r = tgeom_rbound[g]
    out = int(0)
    if r > f64(0.0):
        p = geom_xpos[w, tgeom_geomid[g]]
        c = vec3d(f64(p[0]), f64(p[1]), f64(p[2]))
        sf = medium.surface
        sf.w = w
        if c[2] - r >= surface.highest_near(sf, c[0], c[1], r):
            out = 1
        if medium.use_region != 0:
            for i in range(3):
                if c[i] + r < medium.region_lo[i] or c[i] - r > medium.region_hi[i]:
                    out = 1
    cull[w, g] = out


@wp.kernel
def element_kernel(
    # Model
    elem_pos: wp.array(dtype=vec3d), elem_normal: wp.array(dtype=vec3d),
    elem_area: wp.array(dtype=f64), elem_reach: wp.array(dtype=f64),
    elem_patch: wp.array2d(dtype=f64), elem_tgeom: wp.array(dtype=int),
    tgeom_tbody: wp.array(dtype=int), tbody_bodyid: wp.array(dtype=int),
    tbody_rootid: wp.array(dtype=int), medium: Medium, store: int,
    # Data in
    xpos: wp.array2d(dtype=wp.vec3), xmat: wp.array2d(dtype=wp.mat33),
    xipos: wp.array2d(dtype=wp.vec3), cvel: wp.array2d(dtype=wp.spatial_vector),
    subtree_com: wp.array2d(dtype=wp.vec3), cull: wp.array2d(dtype=int),
    # Data out
    force_out: wp.array2d(dtype=vec3d), torque_out: wp.array2d(dtype=vec3d),
    elem_force: wp.array2d(dtype=vec3d),
):  # fmt: skip
    """Element i of world w at its quadrature point: its force into elem_force (if store) and
    its force and torque about the CoM into its body's row of force_out, torque_out (atomic
    adds)."""
    w, i = wp.tid()
    g = elem_tgeom[i]
    sf = medium.surface
    sf.w = w
    f = vec3d(f64(0.0), f64(0.0), f64(0.0))
    if cull[w, g] == 0:
        k = tgeom_tbody[g]
        b = tbody_bodyid[k]
        m = xmat[w, b]
        rot = wp.mat33d(
            f64(m[0, 0]), f64(m[0, 1]), f64(m[0, 2]),
            f64(m[1, 0]), f64(m[1, 1]), f64(m[1, 2]),
            f64(m[2, 0]), f64(m[2, 1]), f64(m[2, 2]),
        )  # fmt: skip
        # cvel = [omega, v] with v at the subtree CoM of the body's root (docs/design.md 3).
        tw = cvel[w, b]
        omega = vec3d(f64(tw[0]), f64(tw[1]), f64(tw[2]))
        v_ref = vec3d(f64(tw[3]), f64(tw[4]), f64(tw[5]))
        q = quadrature_point(
            elem_pos[i], elem_normal[i], elem_area[i], elem_reach[i], elem_patch, i, rot,
            widen(xpos[w, b]), omega, v_ref, widen(subtree_com[w, tbody_rootid[k]]),
            sf, f64(k + 1), medium.use_region, medium.region_lo, medium.region_hi,
        )  # fmt: skip
        if q.w > f64(0.0):
            f = element_force(q.n, q.v, q.w, q.a, medium.co, medium.ay, medium.zeta, medium.lam_rho)
            if f[0] != f64(0.0) or f[1] != f64(0.0) or f[2] != f64(0.0):
                wp.atomic_add(force_out, w, k, f)
                wp.atomic_add(torque_out, w, k, wp.cross(q.p - widen(xipos[w, b]), f))
    if store != 0:
        elem_force[w, i] = f


@wp.kernel
def user_kernel(
    # Model
    tbody_bodyid: wp.array(dtype=int),
    # Data in
    written: wp.array2d(dtype=wp.spatial_vector), xfrc_applied: wp.array2d(dtype=wp.spatial_vector),
    # Data in and out
    user: wp.array2d(dtype=wp.spatial_vector),
):  # fmt: skip
    """The user part of tagged body k's xfrc_applied row: a component that no longer holds what
    the field wrote there was assigned by the user and becomes the user part (the engine's
    rule, docs/field.md)."""
    w, k = wp.tid()
    cur = xfrc_applied[w, tbody_bodyid[k]]
    old = written[w, k]
    u = user[w, k]
    for c in range(6):
        if cur[c] != old[c]:
            u[c] = cur[c]
    user[w, k] = u


@wp.kernel
def restore_kernel(
    # Model
    tbody_bodyid: wp.array(dtype=int),
    # Data in
    user: wp.array2d(dtype=wp.spatial_vector),
    # Data out
    written: wp.array2d(dtype=wp.spatial_vector), xfrc_applied: wp.array2d(dtype=wp.spatial_vector),
):  # fmt: skip
    """xfrc_applied row of tagged body k = its user part (the field's wrench taken out)."""
    w, k = wp.tid()
    written[w, k] = user[w, k]
    xfrc_applied[w, tbody_bodyid[k]] = user[w, k]


@wp.kernel
def fill_rows_kernel(
    mask: wp.array(dtype=int), value: Any,
    # Data out
    arr: wp.array2d(dtype=Any),
):  # fmt: skip
    """arr[w, i] = value in the worlds w where mask[w] != 0 (float64 and int32 arrays: Warp
    makes one overload per type at launch)."""
    w, i = wp.tid()
    if mask[w] != 0:
        arr[w, i] = value


@wp.kernel
def write_kernel(
    # Model
    tbody_bodyid: wp.array(dtype=int),
    # Data in
    force: wp.array2d(dtype=vec3d), torque: wp.array2d(dtype=vec3d),
    user: wp.array2d(dtype=wp.spatial_vector),
    # Data out
    written: wp.array2d(dtype=wp.spatial_vector), xfrc_applied: wp.array2d(dtype=wp.spatial_vector),
):  # fmt: skip
    """xfrc_applied row of tagged body k = user part + RFT wrench, remembered as written."""
    w, k = wp.tid()
    u = user[w, k]
    f = force[w, k]
    t = torque[w, k]
    out = wp.spatial_vector()
    for c in range(3):
        out[c] = u[c] + float(f[c])
        out[3 + c] = u[3 + c] + float(t[c])
    written[w, k] = out
    xfrc_applied[w, tbody_bodyid[k]] = out


# ------------------------------------------------------------------------------ the field
def check_memory(nworld: int, bytes_per_world: int, device, free: int) -> None:
    """Raise MemoryError, before allocating, if nworld worlds of the field's arrays
    (bytes_per_world each) exceed the device's free memory [bytes]."""
    need = nworld * bytes_per_world
    if need > free:
        raise MemoryError(
            f"mjrft.warp: nworld={nworld} needs {need / 2**20:.0f} MiB for the field "
            f"({bytes_per_world} B per world) but {device} has {free / 2**20:.0f} MiB free; "
            "use fewer worlds, or store_element_forces=False"
        )


def _supported(scene: Scene) -> None:
    """Raise UnsupportedScene naming the first feature of the scene the Warp field lacks."""
    m = scene.material
    if not m.compiled or m.fourier is None:
        what = "the agarwal3d force model" if m.agarwal is not None else "a callable material"
        raise UnsupportedScene(
            f"mjrft.warp: {what} ({m.name!r}) is not supported yet; the Warp field evaluates "
            "Fourier-form media under the treers2021 model (a preset or mjrft:coefficients)"
        )


def _mech_sizes(nv: int, nk: int, nu: int) -> dict[str, int]:
    """Per-world sizes of the mechanism treatment's state and scratch (mechanism.Mech)."""
    return {
        "time": 3, "qin": 2 * nv, "tau": nv, "prev": 6 * nk, "in_prev": 6 * nk, "held": nk,
        "in_held": nk, "in_force": nu, "key": 19 * nk, "rcache": 6 * nk, "mm": nv * nv,
        "lo": nv * nv, "jac": 6 * nk * nv, "x": 6 * nk * nv, "a": 36 * nk * nk,
        "s": 36 * nk * nk, "u": nv, "g": nv, "rhs": 6 * nk, "out": 6 * nk, "rows": nk,
    }  # fmt: skip


def _check_integrator(m) -> None:
    """Raise ValueError if the mjw.Model m integrates with RK4, whose stages the treatment
    cannot recognise on MuJoCo Warp (its stages run at the step's start time)."""
    if int(m.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4):
        raise ValueError(
            "mjrft.warp: the low-speed treatment is not supported under the RK4 integrator on "
            "MuJoCo Warp (its stage passes carry no stage time, so the engine's stage rule "
            "cannot hold a stuck body's wrench over the step); use Euler, implicit or "
            "implicitfast, or WarpField(..., low_speed='off')"
        )


def _check_plain(model: mujoco.MjModel) -> None:
    """Raise ValueError if model carries the engine plugin (MuJoCo Warp's put_model fails on a
    model with a plugin instance it cannot run)."""
    engine = model.nplugin > 0 and any(
        model.numeric(i).name.startswith(plugin.PREFIX) for i in range(model.nnumeric)
    )
    if engine:
        raise ValueError(
            "mjrft.warp: this model carries the engine plugin mjrft.granular, which MuJoCo Warp "
            "cannot run (mjw.put_model refuses a model with a plugin instance): give WarpField "
            "and mjw.put_model the plain model (mujoco.MjModel.from_xml_path(path), or the "
            "MjSpec compiled without mjrft.load_model / mjrft.add_granular)"
        )


def _model_name(model: mujoco.MjModel) -> str:
    """The MJCF's ``<mujoco model=...>`` name (the first of the model's names)."""
    return bytes(model.names).split(b"\0", 1)[0].decode() or "(unnamed)"


def _sizes(nq: int, nv: int, nbody: int, ngeom: int) -> str:
    return f"nq={nq}, nv={nv}, nbody={nbody}, ngeom={ngeom}"


#: A model's structure the field's tables depend on: integer arrays (never batched per world)
#: whose values a MuJoCo Warp model of the same MjModel shares exactly.
_STRUCTURE = ("body_parentid", "jnt_type", "geom_type", "geom_bodyid")


@dataclass
class _Worlds:
    """Per-``mjw.Data`` arrays of the field (nworld rows each)."""

    nworld: int
    cull: wp.array  # (nworld, ntgeom) int
    force: wp.array  # (nworld, ntbody) vec3d [N], world frame
    torque: wp.array  # (nworld, ntbody) vec3d [N m] about each body's CoM
    user: wp.array  # (nworld, ntbody) spatial_vector: the user part of xfrc_applied's rows
    written: wp.array  # (nworld, ntbody) spatial_vector: what the field last wrote there
    elem_force: wp.array  # (nworld, nelem) vec3d [N], or (1, 1) if not stored
    decision: wp.array  # (nworld, ntbody) int: the low-speed treatment's (lowspeed.PURE...)
    mech: object  # mechanism.Mech: the mechanism treatment's per-world state, or None
    medium: Medium  # the medium, its surface reading these worlds' soil blocks if it deforms
    ground: object  # soil.Ground: the deforming ground's per-world state and work, or None
    soil: wp.array  # (nworld, block) the deforming ground's blocks (engine surface.h), or None
    owner: weakref.ref  # the mjw.Data these belong to


class WarpField:
    """The granular field for MuJoCo Warp: one scene, any number of worlds, on one device.

    Args:
      model: the compiled MjModel whose ``<custom>`` describes the scene (``mjrft:`` section),
        without the engine plugin: the model ``mjw.put_model`` takes (MuJoCo Warp runs no C
        plugins), e.g. ``mujoco.MjModel.from_xml_path``, not ``mjrft.load_model``.
      material, n_triangles, tolerance, dynamic, low_speed, stick_reach: SceneOptions on top of
        the MJCF's, as ``mjrft.load_model`` takes them (low_speed: the MJCF's ``mjrft:low_speed``,
        default "stick", as the engine's).
      device: the Warp device (default: Warp's default device).
      store_element_forces: keep each element's force per world (``element_forces_of``);
        costs nworld x elements x 24 bytes of device memory.
    Raises:
      UnsupportedScene (a SceneError) naming a feature the Warp field lacks: the agarwal3d
      model, callable materials. SceneError as ``mjrft.load_model``. ValueError for a model
      that carries the engine plugin; at ``install`` or ``treat``, for the treatment under RK4.

    A field serves the MuJoCo Warp model and data of its own model only: ``install`` refuses an
    ``mjw.Model`` whose sizes, body tree, joint or geom types, geom bodies or intruding geoms'
    sizes differ from it, and every method taking an ``mjw.Data`` refuses one whose sizes (nq,
    nv, nbody, ngeom) differ (an ``mjw.Data`` does not know its model), both with a ValueError
    naming the two.

    The element tables are the engine's (``mjrft.field.plugin.setup``: the same meshing,
    culling bounds, material, surface and region as ``mjrft.load_model`` gives the CPU engine),
    and so is the low-speed treatment: of free bodies (``low_speed`` "stick" or "free";
    mjrft.warp.lowspeed) and of bodies in mechanisms ("stick"; mjrft.warp.mechanism), under
    Euler, implicit and implicitfast; "off" is the pure model. So is the deforming ground
    (``mjrft:deform_cell``; mjrft.warp.soil), one height grid with memory per world.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        material: Material | str | None = None,
        *,
        n_triangles: int | None = None,
        tolerance: float | None = None,
        dynamic: float | tuple[float, float] | None = None,
        low_speed: str | None = None,
        stick_reach: float | None = None,
        device: str | None = None,
        store_element_forces: bool = False,
    ) -> None:
        _check_plain(model)
        options = SceneOptions(
            material=material, n_triangles=n_triangles, tolerance=tolerance, low_speed=low_speed,
            stick_reach=stick_reach, dynamic=dynamic,
        )  # fmt: skip
        # Named before plugin.setup, which refuses some of these (callable media) in the
        # engine's terms.
        _supported(scene_from_model(model, **options.given()))
        setup = plugin.setup(model, options)
        self.model = model
        #: The scene, its elements (body frame) and the engine's tables: the CPU engine's
        #: under the same options, one source for both.
        self.setup: FieldSetup = setup
        self.device = wp.get_device(device)
        self.store_element_forces = bool(store_element_forces)
        fm = setup.tables
        self.body_ids = np.asarray(fm["tbody_bodyid"], dtype=np.int64)
        self.nelem = int(fm["nelem"])
        self.ntgeom = int(fm["ntgeom"])
        self.ntbody = int(fm["ntbody"])
        elem_tgeom = np.repeat(np.arange(self.ntgeom), fm["tgeom_elemnum"])
        mat = setup.scene.material
        region = np.asarray(fm["region"], dtype=np.float64).reshape(2, 3)
        dev = self.device

        def arr(x, dtype):
            return wp.array(np.ascontiguousarray(x), dtype=dtype, device=dev)

        self._elem_pos = arr(fm["elem_pos"], vec3d)
        self._elem_normal = arr(fm["elem_normal"], vec3d)
        self._elem_area = arr(fm["elem_area"], f64)
        self._elem_tgeom = arr(elem_tgeom.astype(np.int32), int)
        self._tgeom_geomid = arr(np.asarray(fm["tgeom_geomid"], dtype=np.int32), int)
        self._tgeom_rbound = arr(fm["tgeom_rbound"], f64)
        self._tgeom_tbody = arr(np.asarray(fm["tgeom_tbody"], dtype=np.int32), int)
        self._tbody_bodyid = arr(self.body_ids.astype(np.int32), int)
        self._tbody_rootid = arr(np.asarray(fm["tbody_rootid"], dtype=np.int32), int)
        self._elem_reach = arr(fm["elem_reach"], f64)
        self._elem_patch = arr(fm["elem_patch"], f64)
        self._medium = Medium()
        self._medium.co = arr(np.asarray(fm["coef"][:18], dtype=np.float64), f64)
        self._medium.ay = f64(fm["alpha_y"])
        self._medium.zeta = f64(fm["zeta"])
        self._medium.lam_rho = f64(mat.dynamic)
        self._medium.surface = surface.from_core(setup.scene.surface, dev)
        self._medium.use_region = int(fm["use_region"])
        self._medium.region_lo = vec3d(*region[0])
        self._medium.region_hi = vec3d(*region[1])
        self._elements = Elements()
        for name in ("pos", "normal", "area", "reach", "patch"):
            setattr(self._elements, name, getattr(self, f"_elem_{name}"))
        for name in ("tgeom_elemadr", "tgeom_elemnum", "tbody_geomadr", "tbody_geomnum"):
            setattr(self._elements, name, arr(np.asarray(fm[name], dtype=np.int32), int))
        self._elements.tgeom_geomid = self._tgeom_geomid
        self._elements.tgeom_rbound = self._tgeom_rbound
        #: The low-speed treatment: "stick", "free" or "off" (the scene's, SceneOptions).
        self.low_speed = setup.scene.low_speed.mode
        self._treat = arr(np.asarray(fm["tbody_treat"], dtype=np.int32), int)
        self._treats = bool(fm["treat"]) and bool(np.any(fm["tbody_treat"]))
        self._reach = f64(fm["reach"])
        mech = np.asarray(fm["tbody_mech"], dtype=bool)
        self._mechs = bool(fm["treat"]) and bool(mech.any())
        self._jacobian_step = f64(fm["jacobian_step"])
        #: The model's timestep [s] (the deforming ground's deform_every > 1 counts steps by it).
        self._dt = wp.array([float(model.opt.timestep)], dtype=float, device=dev)
        self._worlds: dict[int, _Worlds] = {}

    @property
    def deforms(self) -> bool:
        """True if the ground deforms (``mjrft:deform_cell``): a height grid per world."""
        return self.setup.scene.surface.kind == core_surface.SOIL

    def _ground_state(self, st: _Worlds) -> None:
        """The deforming ground's per-world arrays of st (blocks as the engine starts them:
        zeros, floors +inf, no owners), and st.medium reading its soil blocks."""
        fm, dev, nworld = self.setup.tables, self.device, st.nworld
        n = int(fm["surface_nrow"]) * int(fm["surface_ncol"])
        st.soil = wp.zeros((nworld, int(fm["nsoil"])), dtype=f64, device=dev)
        gr = soil.Ground()
        gr.floor = wp.array(np.full((nworld, n), np.inf), dtype=f64, device=dev)
        gr.owner = wp.array(np.full((nworld, n), -1, dtype=np.int32), dtype=int, device=dev)
        gr.queue = wp.zeros((nworld, n), dtype=int, device=dev)
        gr.work = wp.zeros((nworld, n), dtype=f64, device=dev)
        gr.box = wp.zeros((nworld, 4 * soil.box_rows(self.ntbody)), dtype=f64, device=dev)
        gr.stats = wp.zeros((nworld, soil.N_STATS), dtype=f64, device=dev)
        gr.status = wp.array(np.full(nworld, -1, dtype=np.int32), dtype=int, device=dev)
        vert = np.asarray(fm["elem_vert"], dtype=np.float64).reshape(-1, 9)
        gr.elem_vert = wp.array(np.ascontiguousarray(vert), dtype=f64, device=dev)
        gr.zlo = f64(np.asarray(fm["region"], dtype=np.float64).reshape(2, 3)[0, 2])
        gr.nk = self.ntbody
        st.ground = gr
        med = Medium()
        for name in Medium.vars:
            setattr(med, name, getattr(self._medium, name))
        med.surface = surface.with_soil(self._medium.surface, st.soil)
        st.medium = med

    @property
    def surface(self) -> Surface:
        """The free surface on the device (``mjrft.warp.surface``)."""
        return self._medium.surface

    # ------------------------------------------------------------------ per-Data state
    def bytes_per_world(self) -> int:
        """Device memory [bytes] the field's arrays take per world."""
        per = self.ntgeom * 4 + self.ntbody * (2 * 24 + 2 * 24 + 4)
        if self._mechs:
            per += 8 * sum(_mech_sizes(self.model.nv, self.ntbody, self.model.nu).values())
        if self.deforms:
            n = int(self.setup.tables["surface_nrow"]) * int(self.setup.tables["surface_ncol"])
            per += 8 * int(self.setup.tables["nsoil"]) + 24 * n + 8 * 4 * soil.box_rows(self.ntbody)
            per += 8 * soil.N_STATS + 4
        return per + (self.nelem * 24 if self.store_element_forces else 0)

    def _worlds_of(self, d) -> _Worlds:
        st = self._worlds.get(id(d))
        if st is not None and st.owner() is d:
            return st
        self._check_data(d)
        nworld = int(d.nworld)
        if self.device.is_cuda:
            check_memory(nworld, self.bytes_per_world(), self.device, self.device.free_memory)
        dev = self.device
        ne = (nworld, self.nelem) if self.store_element_forces else (1, 1)
        xfrc = d.xfrc_applied.numpy()[:, self.body_ids]  # what is there now is the user's
        st = _Worlds(
            nworld=nworld,
            cull=wp.zeros((nworld, self.ntgeom), dtype=int, device=dev),
            force=wp.zeros((nworld, self.ntbody), dtype=vec3d, device=dev),
            torque=wp.zeros((nworld, self.ntbody), dtype=vec3d, device=dev),
            user=wp.array(xfrc, dtype=wp.spatial_vector, device=dev),
            written=wp.array(xfrc, dtype=wp.spatial_vector, device=dev),
            elem_force=wp.zeros(ne, dtype=vec3d, device=dev),
            decision=wp.zeros((nworld, self.ntbody), dtype=int, device=dev),
            mech=self._mech_state(nworld) if self._mechs else None,
            medium=self._medium,
            ground=None,
            soil=None,
            owner=weakref.ref(d),
        )
        if self.deforms:
            self._ground_state(st)
        # Forget the arrays of Data that no longer exist (their ids may be reused).
        self._worlds = {k: v for k, v in self._worlds.items() if v.owner() is not None}
        self._worlds[id(d)] = st
        return st

    def _check_data(self, d) -> None:
        """Raise ValueError if the mjw.Data d's sizes are not this field's model's."""
        mine = self.model
        want = (mine.nq, mine.nv, mine.nbody, mine.ngeom)
        got = tuple(int(a.shape[1]) for a in (d.qpos, d.qvel, d.xpos, d.geom_xpos))
        if got != want:
            raise ValueError(
                f"this mjw.Data belongs to another model ({_sizes(*got)}) than the WarpField's "
                f"model {_model_name(mine)!r} ({_sizes(*want)}): build one WarpField per model"
            )

    def _check_model(self, m) -> None:
        """Raise ValueError if the mjw.Model m was not made from this field's model
        (``mjw.put_model``), naming what differs."""
        mine = self.model
        want = (mine.nq, mine.nv, mine.nbody, mine.ngeom)
        got = (int(m.nq), int(m.nv), int(m.nbody), int(m.ngeom))
        differ = [] if got == want else [f"sizes {_sizes(*got)}, not {_sizes(*want)}"]
        if not differ:
            for name in _STRUCTURE:
                if not np.array_equal(getattr(m, name).numpy(), getattr(mine, name)):
                    differ.append(name)
            tagged = np.unique(np.asarray(self.setup.tables["tgeom_geomid"], dtype=np.int64))
            size = m.geom_size.numpy().reshape(-1, mine.ngeom, 3)[:, tagged]  # every world
            if not np.allclose(size, mine.geom_size[tagged], rtol=1e-6, atol=0.0):
                differ.append("the intruding geoms' geom_size")
        if differ:
            raise ValueError(
                f"this mjw.Model was not made from the WarpField's model {_model_name(mine)!r} "
                f"({'; '.join(differ)} differ): build one WarpField per model"
            )

    def prepare(self, d) -> None:
        """Allocate the field's arrays for d now (before capturing a CUDA graph of mjw.step)."""
        self._worlds_of(d)

    # ------------------------------------------------------------------ the pass
    def compute(self, d) -> None:
        """Every world's RFT wrenches from d's current kinematics (after MuJoCo Warp's position
        and velocity stages: xpos, xmat, xipos, cvel, subtree_com, geom_xpos); read them with
        ``wrenches``. Launches two kernels; graph-capturable once ``prepare(d)`` ran."""
        st = self._worlds_of(d)
        dev = self.device
        if st.ground is not None:  # the ground follows the intruders first (engine step 3)
            wp.launch(
                soil.deform_kernel, dim=st.nworld,
                inputs=[self._elements, st.medium, self._tbody_bodyid, self._tbody_rootid,
                        self._dt, d.time, d.xpos, d.xmat, d.cvel, d.subtree_com,
                        d.geom_xpos],
                outputs=[st.ground], device=dev,
            )  # fmt: skip
        wp.launch(
            cull_kernel, dim=(st.nworld, self.ntgeom),
            inputs=[self._tgeom_geomid, self._tgeom_rbound, st.medium, d.geom_xpos],
            outputs=[st.cull], device=dev,
        )  # fmt: skip
        st.force.zero_()
        st.torque.zero_()
        wp.launch(
            element_kernel, dim=(st.nworld, self.nelem),
            inputs=[self._elem_pos, self._elem_normal, self._elem_area, self._elem_reach,
                    self._elem_patch, self._elem_tgeom, self._tgeom_tbody, self._tbody_bodyid,
                    self._tbody_rootid, st.medium, int(self.store_element_forces), d.xpos,
                    d.xmat, d.xipos, d.cvel, d.subtree_com, st.cull],
            outputs=[st.force, st.torque, st.elem_force], device=dev,
        )  # fmt: skip

    def take_user_part(self, d) -> None:
        """Read the user part of d.xfrc_applied's tagged rows (what the user assigned since the
        field last wrote them, per component)."""
        st = self._worlds_of(d)
        wp.launch(
            user_kernel, dim=(st.nworld, self.ntbody),
            inputs=[self._tbody_bodyid, st.written, d.xfrc_applied], outputs=[st.user],
            device=self.device,
        )  # fmt: skip

    def treat(self, m, d) -> None:
        """The low-speed treatment on the last ``compute``'s wrenches: of the free bodies
        (engine/lowspeed.cc; the user part of xfrc_applied read by the last ``take_user_part`` is
        the user's wrench) and, under low_speed="stick", of the bodies in mechanisms
        (engine/mechanism.cc: it reads the previous pass's qacc and records this pass, so call it
        once per forward pass, as ``passive`` does); nothing under low_speed="off". Needs m, the
        mjw.Model (mass, inertia, gravity, timestep per world). One launch for each."""
        st = self._worlds_of(d)
        if self._mechs:
            _check_integrator(m)
            self._treat_mechanisms(m, d, st)
        if not self._treats:
            return
        _check_integrator(m)
        opt = m.opt
        gravity_on = int(not (int(opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)))
        semi = int(int(opt.integrator) != int(mujoco.mjtIntegrator.mjINT_RK4))
        wp.launch(
            ls.treat_kernel, dim=(st.nworld, self.ntbody),
            inputs=[self._elements, st.medium, self._tbody_bodyid, self._tbody_rootid,
                    self._treat, self._reach, self._jacobian_step, semi, gravity_on,
                    opt.timestep, opt.gravity, m.body_mass, m.body_inertia, m.body_gravcomp,
                    d.xpos, d.xmat, d.xipos, d.ximat, d.cvel, d.subtree_com, st.cull, st.user],
            outputs=[st.force, st.torque, st.decision], device=self.device,
        )  # fmt: skip

    def _treat_mechanisms(self, m, d, st: _Worlds) -> None:
        flags = int(m.opt.disableflags)
        ld = mechanism.Loads()
        ld.timestep = m.opt.timestep
        ld.body_mass = m.body_mass
        ld.body_inertia = m.body_inertia
        ld.m_rownnz, ld.m_rowadr, ld.m_colind = m.M_rownnz, m.M_rowadr, m.M_colind
        ld.gainprm, ld.biasprm = m.actuator_gainprm, m.actuator_biasprm
        ld.ctrlrange, ld.forcerange = m.actuator_ctrlrange, m.actuator_forcerange
        ld.actuation_on = int(not flags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION))
        ld.clampctrl_on = int(not flags & int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL))
        for name in ("time", "qvel", "qacc", "cdof", "act", "ctrl", "actuator_length",
                     "actuator_velocity", "actuator_force", "moment_rownnz", "moment_rowadr",
                     "moment_colind", "actuator_moment"):  # fmt: skip
            setattr(ld, name, getattr(d, name))
        ld.mass_matrix = d.M
        kin = mechanism.Kin()
        for name in ("xpos", "xmat", "xipos", "ximat", "cvel", "subtree_com", "geom_xpos"):
            setattr(kin, name, getattr(d, name))
        wp.launch(
            mechanism.mechanism_kernel, dim=st.nworld,
            inputs=[self._elements, st.medium, self._tbody_bodyid, self._tbody_rootid, kin,
                    ld, st.cull],
            outputs=[st.mech, st.force, st.torque, st.decision], device=self.device,
        )  # fmt: skip

    def _mech_state(self, nworld: int):
        """A Mech of zeroed per-world arrays for nworld worlds, with the field's tables."""
        fm, dev, nv, nk = self.setup.tables, self.device, self.model.nv, self.ntbody
        mc = mechanism.Mech()
        mc.nv, mc.nk, mc.nu = nv, nk, self.model.nu
        mc.reach = f64(fm["reach"])

        def ints(x):
            return wp.array(np.ascontiguousarray(x, dtype=np.int32), dtype=int, device=dev)

        mc.tbody_mech = ints(fm["tbody_mech"])
        mc.dofmask = ints(np.asarray(fm["tbody_dofmask"]).reshape(nk, max(nv, 1))[:, :nv])
        size = np.zeros(nk)
        for g, k in enumerate(fm["tgeom_tbody"]):
            size[k] = max(size[k], fm["tgeom_rbound"][g])
        mc.size = wp.array(size, dtype=f64, device=dev)
        for name in ("affine", "gainaffine", "biasaffine", "actadr", "ctrllimited",
                     "forcelimited"):  # fmt: skip
            setattr(mc, name, ints(np.asarray(fm[f"actuator_{name}"]).reshape(-1)))
        for name, size_ in _mech_sizes(nv, nk, self.model.nu).items():
            dtype = int if name in ("held", "in_held", "rows") else f64
            setattr(mc, name, wp.zeros((nworld, max(size_, 1)), dtype=dtype, device=dev))
        return mc

    def write(self, d) -> None:
        """Write user part + the wrenches into d.xfrc_applied's tagged rows."""
        st = self._worlds_of(d)
        wp.launch(
            write_kernel, dim=(st.nworld, self.ntbody),
            inputs=[self._tbody_bodyid, st.force, st.torque, st.user],
            outputs=[st.written, d.xfrc_applied], device=self.device,
        )  # fmt: skip

    def apply(self, d) -> None:
        """Write user part + the last pass's wrench into d.xfrc_applied's tagged rows
        (``take_user_part`` then ``write``)."""
        self.take_user_part(d)
        self.write(d)

    def passive(self, m, d) -> None:
        """MuJoCo Warp's passive callback (``install``): ``compute``, ``take_user_part``,
        ``treat``, ``write``: five kernel launches, no host synchronisation."""
        self.compute(d)
        self.take_user_part(d)
        self.treat(m, d)
        self.write(d)

    def install(self, m) -> None:
        """Make the field mjw.Model m's passive callback (chained after any callback already
        there), so every forward pass of ``mjw.step`` applies it. Raises ValueError for an
        mjw.Model of another model, or an integrator the treatment does not support."""
        self._check_model(m)
        if self._treats or self._mechs:
            _check_integrator(m)
        prev = m.callback.passive
        if getattr(prev, "__self__", None) is self:
            return

        def chained(m_, d_):
            prev(m_, d_)
            self.passive(m_, d_)

        m.callback.passive = self.passive if prev is None else chained
        self._prev = prev

    def uninstall(self, m, d=None) -> None:
        """Undo ``install``; with d, also give d's tagged rows of xfrc_applied back their user
        part."""
        m.callback.passive = getattr(self, "_prev", None)
        if d is not None:
            st = self._worlds_of(d)
            self.take_user_part(d)
            wp.launch(
                restore_kernel, dim=(st.nworld, self.ntbody),
                inputs=[self._tbody_bodyid, st.user], outputs=[st.written, d.xfrc_applied],
                device=self.device,
            )  # fmt: skip

    def reset(self, d, worlds=None) -> None:
        """Start the field's state over in the worlds of d given by worlds ((nworld,) bool or
        0/1, NumPy or a Warp int array on the device; None: every world), as mj_resetData does
        for the engine's: the deforming ground back to its initial surface, the mechanism
        treatment's records of the previous pass cleared (its next pass is the pure model). Call
        it when you reset those worlds' state; launches kernels only (capturable) given a Warp
        mask."""
        st = self._worlds_of(d)
        if worlds is None:
            worlds = np.ones(st.nworld, dtype=np.int32)
        if not isinstance(worlds, wp.array):
            worlds = np.asarray(worlds).astype(np.int32).reshape(-1)
            if worlds.shape != (st.nworld,):
                raise ValueError(f"worlds: expected shape ({st.nworld},), got {worlds.shape}")
            worlds = wp.array(worlds, dtype=int, device=self.device)
        arrays = []  # (array, value)
        if st.ground is not None:
            gr = st.ground
            arrays += [(st.soil, 0.0), (gr.floor, np.inf), (gr.owner, -1), (gr.box, 0.0),
                       (gr.stats, 0.0)]  # fmt: skip
        if st.mech is not None:
            arrays += [(getattr(st.mech, name), 0) for name in _mech_sizes(1, 1, 1)]
        for arr, value in arrays:
            cast = wp.int32 if arr.dtype == wp.int32 else f64
            wp.launch(
                fill_rows_kernel, dim=arr.shape, inputs=[worlds, cast(value)], outputs=[arr],
                device=self.device,
            )  # fmt: skip

    @contextlib.contextmanager
    def installed(self, m, d=None):
        """``with field.installed(m, d): mjw.step(m, d)``: installed inside, uninstalled on
        exit (d's xfrc_applied rows get their user part back)."""
        self.install(m)
        try:
            yield self
        finally:
            self.uninstall(m, d)

    # ------------------------------------------------------------------ results
    def wrenches(self, d) -> np.ndarray:
        """(nworld, nbody, 6) the last pass's RFT wrench per world and body, ``xfrc_applied``
        layout: force [N] then torque [N m] about the CoM, world frame (float64; a copy)."""
        st = self._worlds_of(d)
        out = np.zeros((st.nworld, self.model.nbody, 6))
        out[:, self.body_ids, :3] = st.force.numpy()
        out[:, self.body_ids, 3:] = st.torque.numpy()
        return out

    def decisions(self, d) -> np.ndarray:
        """(nworld, ntbody) the last pass's low-speed decision per world and tagged body
        (``body_ids`` order): 0 the pure model, 1 stuck, 2 slipping, 3 linearly implicit (the
        engine's codes, ``GranularField.decision_of``); a copy."""
        return self._worlds_of(d).decision.numpy().copy()

    def soil_blocks(self, d) -> np.ndarray:
        """(nworld, block) each world's deforming ground, the engine's soil block (engine
        surface.h: head, then the offsets of the surface h and the compacted level c from the
        initial heights and the memory p [m], nrow x ncol each, row-major); a copy."""
        st = self._worlds_of(d)
        if st.soil is None:
            raise ValueError("this field's ground does not deform (mjrft:deform_cell)")
        return st.soil.numpy().copy()

    def soil_counters(self, d) -> dict[str, np.ndarray]:
        """Each world's deforming-ground counters since its start or reset, the engine's
        ``Soil.counters`` (``mjrft.core.soil.SOIL_STATS``): updates, volume excavated [m^3],
        volume that found no rim [m^3], updates whose relaxation met its budget, triangles
        rasterised, footprint vertices at the edge ring, pairs of neighbouring vertices the
        relaxation compared (its work); each (nworld,), a copy."""
        st = self._worlds_of(d)
        if st.ground is None:
            raise ValueError("this field's ground does not deform (mjrft:deform_cell)")
        stats = st.ground.stats.numpy()
        return {name: stats[:, i].copy() for i, name in enumerate(core_soil.SOIL_STATS)}

    def below_ground(self, d) -> np.ndarray:
        """(nworld,) per world the tagged body (``body_ids`` index) that reached below the
        deforming ground's bottom (mjrft:region zmin) in the last update, else -1. The engine
        raises there; a kernel cannot, so the ground leaves that body's columns uncut."""
        st = self._worlds_of(d)
        if st.ground is None:
            return np.full(st.nworld, -1)
        return st.ground.status.numpy().copy()

    def element_forces_of(self, d) -> np.ndarray:
        """(nworld, nelem, 3) the last pass's element forces [N], world frame, in the engine's
        element order (``store_element_forces=True``)."""
        if not self.store_element_forces:
            raise ValueError("element forces are kept only with store_element_forces=True")
        return self._worlds_of(d).elem_force.numpy()


def element_forces(
    pos: np.ndarray,
    normal: np.ndarray,
    area: np.ndarray,
    vel: np.ndarray,
    material: Material | str,
    surface_z: float = 0.0,
    device: str | None = None,
) -> np.ndarray:
    """``mjrft.element_forces`` evaluated by the Warp law (float64) on a Warp device.

    Args: (n, 3) centroids [m], (n, 3) unit normals, (n,) areas [m^2], (n, 3) velocities
    [m/s], all world frame; material (Fourier form, treers2021), or a preset's name;
    surface_z [m].
    Returns: (n, 3) forces [N], world frame.
    """
    material = as_material(material)
    if not material.compiled or material.fourier is None:
        raise UnsupportedScene(
            f"mjrft.warp.element_forces: material {material.name!r} is not a Fourier-form "
            "medium under the treers2021 model"
        )
    dev = wp.get_device(device)
    n = len(area)

    def arr(x, dtype):
        return wp.array(np.ascontiguousarray(x, dtype=np.float64), dtype=dtype, device=dev)

    out = wp.zeros(n, dtype=vec3d, device=dev)
    wp.launch(
        forces_kernel, dim=n,
        inputs=[arr(material.kernel_coefficients[:18], f64), f64(material.alpha_y0),
                f64(material.zeta), f64(material.dynamic), f64(surface_z), arr(pos, vec3d),
                arr(normal, vec3d), arr(area, f64), arr(vel, vec3d)],
        outputs=[out], device=dev,
    )  # fmt: skip
    return out.numpy()
