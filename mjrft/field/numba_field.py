"""The numba field, kept only until the C++ engine's parity with it is recorded (tests/test_engine_parity.py).

The granular force field: RFT wrenches on a compiled MjModel's intruding bodies, every step.

``GranularField(model)`` reads the scene from the MJCF (``mjrft.field.scene``), meshes the tagged
geoms once, and maps any MjData of that model to one wrench per body, computed from that data's
current kinematics (``xpos``, ``xmat``, ``cvel``, ``subtree_com``: no lag, no finite
differences). Two ways to apply it, both running the one compiled pass (``mjrft.field.passive``):

* explicit: ``mj_forward``; ``d.xfrc_applied[:] = user + field.wrench(d, user_xfrc=user)``;
  ``mj_step``: the wrench is held over the step (all RK4 stages see the same force);
* installed: ``with field.installed(): mj_step(...)``: in every forward pass the intruding
  bodies' rows of ``xfrc_applied`` are set to the user's part plus that pass's RFT wrench
  (``mjrft.field.ownership``), with RK4's later stages following ``mjrft.field.rk4``.

Why ``xfrc_applied`` and not ``qfrc_passive``: MuJoCo's force/torque sensors (load cells) see
external body forces only through ``cfrc_ext``, which is built from ``xfrc_applied`` and contacts.
A wrench added to ``qfrc_passive`` moves the bodies but is invisible to every load cell.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft.core import kernel, surface
from mjrft.core.elements import ElementSet
from mjrft.core.material import Material
from mjrft.core.surface import Surface
from mjrft.field import guard, lowspeed, ownership, passive, python_material
from mjrft.field.model import (
    BodyElements,
    body_elements,
    build_tables,
    free_rigid,
    mechanism_body,
)
from mjrft.core import soil as _soil
from mjrft.field import scene as _scene
from mjrft.field.scene import Scene, SceneError, scene_from_model
from mjrft.field.signals import HeldSignals
from mjrft.field.soil_view import Soil
from mjrft.field.state import DataState, States, soil_block
from mjrft.field.tables import STATS


def load_plain(
    source: str | mujoco.MjSpec, *, deform_cell: float | None = None, repose: float | None = None
) -> mujoco.MjModel:
    """Compile an MJCF file path (or an MjSpec) with room in ``userdata`` for its deforming
    ground: ``<size nuserdata>`` grows to what mjrft:deform_cell (or deform_cell [m], which
    also sets or overrides it, 0 switching it off; repose [deg] likewise mjrft:repose) needs."""
    spec = source if isinstance(source, mujoco.MjSpec) else mujoco.MjSpec.from_file(str(source))
    for key, value in (("deform_cell", deform_cell), ("repose", repose)):
        if value is not None:
            found = [n for n in spec.numerics if n.name == "mjrft:" + key]
            if found:
                found[0].data = [float(value)]
            else:
                spec.add_numeric(name="mjrft:" + key, data=[float(value)])
    model = spec.compile()
    custom = _scene._custom(model)
    cell = _scene._numeric_field(model, custom, "deform_cell", (1,), "one cell size [m] > 0")
    region = _scene._region(model, custom)
    if cell is None or float(cell[0]) <= 0.0 or region is None:
        return model
    nrow, ncol = _soil.grid_shape(region, float(cell[0]))
    need = surface.soil_block(nrow, ncol)
    if model.nuserdata >= need or nrow * ncol > _soil.MAX_VERTICES:  # the field names the cap
        return model
    spec.nuserdata = need
    return spec.compile()



@dataclass(frozen=True)
class ElementState:
    """Per-element RFT state of one body at one instant, world frame, evaluated elements only.

    Attributes:
      body: body id. index: (n,) element indices into the body's BodyElements.
      pos: (n, 3) quadrature points [m]: the centroid, or for an element the free surface or
        the leading boundary crosses, its submerged leading part's depth-weighted centroid
        (mjrft.core.quadrature); normal: (n, 3) unit normals there; area: (n,) [m^2], for a
        clipped element the area that gives its part's depth integral at that point's depth;
        vel: (n, 3) velocities there [m/s]; force: (n, 3) RFT forces [N], the element law at
        (pos, normal, area, vel) (``mjrft.element_forces``).
    """

    body: int
    index: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    vel: np.ndarray
    force: np.ndarray


class GranularField:
    """RFT force field bound to one compiled MjModel.

    Args:
      model: compiled model whose ``<custom>`` describes the scene (``mjrft.field.scene``).
      material: overrides the MJCF material if given: a ``Material`` or a preset's name.
      n_triangles: overrides the triangle count of every primitive geom (MJCF ``prm`` and
        ``mjrft:triangles``): fewer is faster and less accurate. Mesh geoms keep their own.
      tolerance: instead of n_triangles, the relative RMS force error wanted per primitive geom
        (e.g. 0.01); the count comes from ``mjrft.geometry.triangles_for_tolerance``.
      low_speed: "stick" (default), "free" or "off": the low-speed stick/slip treatment of free
        bodies (``mjrft.field.lowspeed``) and of bodies in mechanisms (``mjrft.field.mechanism``),
        of free bodies only, or none; overrides MJCF ``mjrft:low_speed``.
      stick_reach: the treatment's reach (default ``lowspeed.DEFAULT_REACH``); overrides MJCF
        ``mjrft:stick_reach``.
      deform_cell [m], repose [deg], deform_every [steps]: the deforming ground (docs/terrain.md);
        override MJCF ``mjrft:deform_cell`` (0: off), ``mjrft:repose``, ``mjrft:deform_every``.
      dynamic: the dynamic RFT term (docs/models.md), rho_c [kg/m^3] or (rho_c, lambda);
        overrides MJCF ``mjrft:dynamic`` (0: off).
    Raises:
      mjrft.field.SceneError (a ValueError) naming the geom or field at fault.

    The field's per-pass state belongs to each MjData (``mjrft.field.state``): several MjData of
    one field may be stepped at once from several threads, each exactly as if alone.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        material: Material | str | None = None,
        *,
        n_triangles: int | None = None,
        tolerance: float | None = None,
        low_speed: str | None = None,
        stick_reach: float | None = None,
        deform_cell: float | None = None,
        repose: float | None = None,
        deform_every: int | None = None,
        dynamic: float | tuple[float, float] | None = None,
    ) -> None:
        self.model = model
        self.scene: Scene = scene_from_model(
            model, material, n_triangles=n_triangles, tolerance=tolerance,
            low_speed=low_speed, stick_reach=stick_reach, deform_cell=deform_cell, repose=repose,
            deform_every=deform_every, dynamic=dynamic,
        )  # fmt: skip
        #: Tagged bodies (id order): their elements in the body frame.
        self.bodies: tuple[BodyElements, ...]
        #: Tagged geom id -> its ElementSet in the body frame.
        self.geom_elements: dict[int, ElementSet]
        self.bodies, self.geom_elements = body_elements(model, self.scene)
        self.body_ids = np.array([be.body for be in self.bodies], dtype=np.int64)
        tagged = set(self.body_ids.tolist())
        #: Per body of ``body_ids``: True if the low-speed treatment can act on it (a free rigid
        #: body, ``mjrft.field.model.free_rigid``).
        self.stick_eligible = np.array([free_rigid(model, int(b), tagged) for b in self.body_ids])
        m = self.scene.material
        self._native = m.compiled
        key = 0 if self._native else self._register_python_material()
        #: Per body of ``body_ids``: True if the mechanism treatment acts on it (jointed, not a
        #: free rigid body; ``low_speed`` "stick").
        self.mechanism_eligible = (
            np.array([mechanism_body(model, int(b)) for b in self.body_ids], dtype=bool)
            & ~self.stick_eligible
            & self.scene.low_speed.mechanisms
        )
        self._tables = build_tables(
            model, self.scene, self.bodies, self.stick_eligible, key, self.mechanism_eligible
        )
        #: (nbody, 6) wrench of the most recent installed pass of any of the model's MjData
        #: (updated in place); per MjData see ``wrench_of``.
        self.last_wrench = np.zeros((model.nbody, 6))
        #: Per body of ``body_ids``: the treatment's decision in the most recent pass
        #: (``lowspeed.PURE``, ``STICK``, ``SLIP`` or ``IMPLICIT``).
        self.last_decision = np.zeros(len(self.bodies), dtype=np.int64)
        self._states = States(self._tables, (self.last_wrench, self.last_decision))
        self._states.on_forget = self._unregister

    def _register_python_material(self) -> int:
        if self.scene.surface.kind != surface.FLAT:
            raise SceneError(
                "a material given by Python callables acts under the flat surface only "
                "(mjrft:surface_z); this scene's surface is a tilted plane or a height field"
            )
        quad = [be.quadrature for be in self.bodies]
        region = self.scene.region
        tables = (
            np.concatenate([be.centroids for be in self.bodies]),
            np.concatenate([be.normals for be in self.bodies]),
            np.concatenate([be.areas for be in self.bodies]),
            np.concatenate([q[0] for q in quad]),
            np.concatenate([q[1] for q in quad]),
            np.zeros(18), 0.0, 0.0,  # the kernel's coefficients: unused, the callables act
            self.scene.surface.prm, self.scene.surface.grid, region is not None,
            np.zeros((2, 3)) if region is None else np.ascontiguousarray(region, dtype=float),
            np.zeros(1),
        )  # fmt: skip
        return python_material.register(self, self.scene.material, tables)

    # ------------------------------------------------------------------ description
    @property
    def material(self) -> Material:
        """The medium."""
        return self.scene.material

    @property
    def surface_z(self) -> float:
        """Free-surface height [m], world frame: the flat surface's, or the reference height of
        a tilted plane (at x = y = 0) or a height field (its lowest point); see ``surface``."""
        return self.scene.surface_z

    @property
    def surface(self) -> Surface:
        """The free surface (mjrft.core.surface): ``surface.height(x, y)`` [m], world frame."""
        return self.scene.surface

    @property
    def deforms(self) -> bool:
        """True if the ground deforms and remembers (``mjrft:deform_cell``; ``soil``)."""
        return self.scene.surface.kind == surface.SOIL

    def soil(self, data: mujoco.MjData) -> Soil:
        """The deforming ground of one MjData (read and write; ``mjrft.field.soil_view``)."""
        if not self.deforms:
            raise ValueError(
                "this field's ground does not deform: add <numeric name='mjrft:deform_cell' "
                "data='0.002'/> (and mjrft:region) or pass deform_cell= to GranularField"
            )
        block = soil_block(data, self._tables.arrays.nsoil)
        return Soil(self.scene.surface, block, self._state(data).arrays.soil_stats)

    @property
    def region(self) -> np.ndarray | None:
        """(2, 3) world box of the medium [m] (min corner, max corner), or None."""
        return self.scene.region

    @property
    def low_speed(self) -> lowspeed.LowSpeed:
        """The low-speed treatment (mode, reach)."""
        return self.scene.low_speed

    @property
    def n_elements(self) -> int:
        """Total number of surface triangles over all intruding geoms."""
        return int(sum(len(be.areas) for be in self.bodies))

    @property
    def stats(self) -> dict[str, int]:
        """Work counters since construction, over all MjData: ``calls`` (evaluations of the
        field), ``evaluated`` (triangles handed to the kernel: those of geoms not culled by their
        bounding sphere), ``acting`` (triangles that felt a force: submerged and leading), and of
        the low-speed treatment ``stuck``, ``slipping`` and ``implicit`` (body-passes held at
        rest, given the force of their free direction of motion, or moved with the linearly
        implicit force)."""
        return dict(zip(STATS, (int(x) for x in self._states.stats()), strict=True))

    def body_element_set(self, body: int) -> ElementSet:
        """All tagged elements of a body as one ElementSet in the body frame."""
        be = next((x for x in self.bodies if x.body == body), None)
        if be is None:
            raise ValueError(f"body {body} has no intruding geoms")
        sets = [self.geom_elements[int(g)] for g in be.geoms]
        offsets = np.cumsum([0] + [len(es.vertices) for es in sets[:-1]])
        return ElementSet(
            centroids=be.centroids,
            normals=be.normals,
            areas=be.areas,
            vertices=np.concatenate([es.vertices for es in sets]),
            faces=np.concatenate([es.faces + o for es, o in zip(sets, offsets, strict=True)]),
            corner_normals=be.corner_normals,
        )

    # ------------------------------------------------------------------ per-MjData state
    def _state(self, data: mujoco.MjData) -> DataState:
        """The field's state for an MjData (``mjrft.field.state``), made on first sight."""
        return self._states.of(data)

    def _counted_state(self) -> DataState:
        """A state without MjData (a batch thread's), whose counters the field's stats include."""
        return self._states.counted()

    @staticmethod
    def _unregister(key: int, st: DataState) -> None:
        if st.registered:
            guard.unregister_data(key)
            st.registered = False

    def _raise_bad(self, data: mujoco.MjData, status: int) -> None:
        dt = float(self.model.opt.timestep)
        step = round(data.time / dt) if dt > 0 and np.isfinite(data.time) else -1
        if status <= passive.BELOW_GROUND:
            be = self.bodies[passive.BELOW_GROUND - status]
            raise ValueError(
                f"body '{be.name}' reaches below the bottom of the deforming ground (mjrft:region "
                f"zmin = {self.scene.region[0, 2]:g} m) at time {data.time:.6g} s (step {step}): "
                "the ground is excavated from above, so an intruder must enter it from above "
                "its surface; lower the region's zmin or start the body above the ground"
            )
        be = self.bodies[-1 - status]
        raise FloatingPointError(
            f"body '{be.name}' has a non-finite position or velocity at time {data.time:.6g} s "
            f"(step {step}); the granular field refuses to feed NaN forward (check the timestep "
            "and actuators)"
        )

    def _run(self, st: DataState, data: mujoco.MjData, mode: int) -> None:
        status = passive.step(self._tables.address, st.address, mode)
        if status != passive.OK:
            self._raise_bad(data, status)

    # ------------------------------------------------------------------ queries
    def wrench(
        self,
        data: mujoco.MjData,
        out: np.ndarray | None = None,
        *,
        user_xfrc: np.ndarray | None = None,
    ) -> np.ndarray:
        """RFT wrench on every body, ``xfrc_applied`` layout, low-speed treatment included.

        Args:
          data: MjData of this model with current kinematics (``mj_forward`` outside a step).
          out: optional (nbody, 6) array to fill.
          user_xfrc: (nbody, 6) the other applied wrenches you will add to ``xfrc_applied``
            (world force [N], torque about the CoM [N m]); the treatment balances them when it
            holds a body at rest. Default: none.
        Returns:
          (nbody, 6): world-frame force [N] then torque [N m] about each body's CoM (xipos);
          zero rows for bodies without intruding geoms or out of the medium.
        """
        st = self._state(data)
        user = st.arrays.user_in
        user[:] = 0.0 if user_xfrc is None else user_xfrc
        self._run(st, data, passive.EXPLICIT)
        if out is None:
            out = np.zeros((self.model.nbody, 6))
        else:
            out[:] = 0.0
        out[self.body_ids] = st.arrays.wrench[self.body_ids]
        return out

    def wrench_of(self, data: mujoco.MjData) -> np.ndarray:
        """(nbody, 6) RFT wrench of data's most recent pass (installed or ``wrench``), world
        frame, torque about each CoM; a view, updated in place by that MjData's passes."""
        return self._state(data).arrays.wrench

    def element_states(self, data: mujoco.MjData) -> list[ElementState]:
        """Per-element world-frame state and RFT force of every body with geoms in the medium.

        Uses data's current kinematics (call ``mj_forward`` first outside a step). Forces are the
        pure model's (the low-speed treatment acts on whole bodies: see ``wrench``); elements of
        geoms culled by their bounding sphere and elements outside the region are left out.
        """
        st = DataState(self._tables, (self.last_wrench, self.last_decision), data, ring=1)
        self._run(st, data, passive.QUERY)
        fa, out, offset = st.arrays, [], 0
        for k, be in enumerate(self.bodies):
            first, n = offset, len(be.areas)
            offset += n
            g0 = int(self._tables.arrays.tbody_geomadr[k])
            blocks = [
                np.arange(be.segments[i], be.segments[i + 1])
                for i in range(len(be.geoms))
                if not fa.cull[g0 + i]
            ]
            if not blocks:
                continue
            out.append(self._element_state(data, be, np.concatenate(blocks), fa.elem_force[first:]))
        return out

    def _element_state(self, data, be: BodyElements, idx, elem_force) -> ElementState:
        b = be.body
        rot = data.xmat[b].reshape(3, 3)
        pos = be.centroids[idx] @ rot.T + data.xpos[b]
        if self.region is not None:
            inside = np.all((pos >= self.region[0]) & (pos <= self.region[1]), axis=1)
            idx, pos = idx[inside], pos[inside]
        normal, area = be.normals[idx] @ rot.T, be.areas[idx].copy()
        # cvel = [w, v] with v at the subtree CoM of the body's root (docs/design.md section 3).
        omega, v_ref = data.cvel[b, :3], data.cvel[b, 3:]
        p_ref = data.subtree_com[self.model.body_rootid[b]]
        rows = self._quadrature_rows(data, be, rot, omega, v_ref, p_ref)[idx]
        # A clipped element acts at its submerged leading part's depth-weighted centroid, with
        # the area that gives that part's depth integral W at that point's depth.
        moved = (rows[:, 9] > 0.0) & np.any(rows[:, :3] != pos, axis=1)
        fm, soil = self._tables.arrays, soil_block(data, self._tables.arrays.nsoil)
        for j in np.flatnonzero(moved):
            x, y, z = rows[j, :3]
            depth = surface.depth(fm.surface_prm, fm.surface_grid, soil, x, y, z)
            pos[j], normal[j], area[j] = rows[j, :3], rows[j, 3:6], rows[j, 9] / depth
        vel = v_ref + np.cross(omega, pos - p_ref)
        return ElementState(b, idx, pos, normal, area, vel, elem_force[idx].copy())

    def _quadrature_rows(self, data, be: BodyElements, rot, omega, v_ref, p_ref) -> np.ndarray:
        """The kernel's quadrature rows (n, kernel.ROW) of every element of a body."""
        fm = self._tables.arrays
        k = int(np.flatnonzero(self.body_ids == be.body)[0])
        start = int(fm.tgeom_elemadr[fm.tbody_geomadr[k]])
        n = len(be.areas)
        b = slice(start, start + n)  # the body's block alone: rows and scratch sized to it
        rows = np.zeros((n, kernel.ROW))
        kernel.body_wrench(
            fm.elem_pos[b], fm.elem_normal[b], fm.elem_area[b], fm.elem_reach[b],
            fm.elem_patch[b], 0, n, fm.coef, fm.alpha_y, fm.zeta, fm.surface_prm,
            fm.surface_grid, bool(fm.use_region), fm.region, soil_block(data, fm.nsoil),
            rot.copy(), data.xpos[be.body].copy(), omega.copy(), v_ref.copy(), p_ref.copy(),
            data.xipos[be.body].copy(), np.zeros(6), np.zeros((n, 3)), rows,
        )  # fmt: skip
        return rows

    def user_xfrc(self, data: mujoco.MjData) -> np.ndarray:
        """(nbody, 6) ``xfrc_applied`` without the field's contribution (the user's forces)."""
        return ownership.user_part(data, self._states.find(data), self.body_ids)

    # ------------------------------------------------------------------ installed path
    def installed(self) -> Installed:
        """Make RFT forces act inside every ``mj_step``/``mj_forward`` of this model.

        ``with field.installed(): ...``. Applies to every MjData of the model; other models
        (and model compilation) are not affected. A user's own passive callback keeps running,
        and one set while installed is chained. Entering and leaving are atomic against Ctrl-C.
        """
        return Installed(self)

    def apply_passive(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """The installed pass, from Python: runs in MuJoCo's passive callback for every pass the
        native guard does not run itself (an MjData seen for the first time, which is
        registered here; a failure of the native pass, raised here; Python-callable media).

        Calls no mujoco function: inside a callback, any binding call resets the binding's
        per-thread error escape, after which an exception raised here would abort the process.
        """
        st = self._state(data)
        if st.registered and st.arrays.status[0] != passive.OK:
            status, st.arrays.status[0] = int(st.arrays.status[0]), passive.OK
            self._raise_bad(data, status)  # the native pass failed on this MjData just now
        if not st.owned:
            ownership.take(data, st, self.body_ids, self._states.owned())
            if self._native:
                guard.register_data(self.model, data._address, st.address)
                st.registered = True
        self._run(st, data, passive.INSTALLED)

    def _release_all(self) -> None:
        """Leaving ``installed()``: every MjData gets back its user part of ``xfrc_applied``; the
        states stay (``wrench_of`` still reports each MjData's last pass)."""
        for st in self._states.owned():
            data = st.data()
            if data is not None:
                data.xfrc_applied[:] = ownership.user_part(data, st, self.body_ids)
            st.owned = False
            st.registered = False  # guard.uninstall dropped the model's MjData


class Installed:
    """The context of ``GranularField.installed()``.

    Entering installs the field in MuJoCo's passive callback (atomically: a Ctrl-C during it
    rolls it back and is raised after); leaving uninstalls it and gives every MjData its user
    part of ``xfrc_applied`` back, with Ctrl-C held until both are done. If a previous exit of
    this field was cut short anyway (an interrupt in the few bytecodes before that hold),
    entering again finishes it first, with a RuntimeWarning.
    """

    def __init__(self, field: GranularField) -> None:
        self.field = field

    def __enter__(self) -> GranularField:
        f = self.field
        if guard.installed_handler(f.model) == f.apply_passive:
            warnings.warn(
                "the previous installed() of this field was interrupted on its way out and the "
                "field kept acting since; uninstalling it now",
                RuntimeWarning,
                stacklevel=2,
            )
            self.__exit__(None, None, None)
        guard.install(f.model, f.apply_passive, f._tables.address if f._native else 0)
        return f

    def __exit__(self, *exc: object) -> None:
        with HeldSignals():
            try:
                guard.uninstall(self.field.model)
            finally:
                self.field._release_all()
