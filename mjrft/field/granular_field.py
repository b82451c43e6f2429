"""The granular force field of a model that carries the engine plugin: what it computes, per MjData.

The forces themselves are computed inside MuJoCo's step by the C++ engine plugin
``mjrft.granular`` (``mjrft.field.plugin``; a model gets it from ``mjrft.load_model``): in every
forward pass the intruding bodies' rows of ``xfrc_applied`` are set to the user's part plus that
pass's RFT wrench, with RK4's later stages following the engine's stage rule. ``GranularField``
is the Python face of one such model: its scene and elements, and for any of its MjData the
engine's state (``wrench_of``, ``element_states``, ``soil``, ``stats_of``), the wrench of a
state without stepping (``wrench``), and the user's part of ``xfrc_applied`` (``user_xfrc``).

Why ``xfrc_applied`` and not ``qfrc_passive``: MuJoCo's force/torque sensors (load cells) see
external body forces only through ``cfrc_ext``, which is built from ``xfrc_applied`` and contacts.
A wrench added to ``qfrc_passive`` moves the bodies but is invisible to every load cell.
"""

from __future__ import annotations

import contextlib
import ctypes
import weakref
from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft.core import surface
from mjrft.core.elements import ElementSet
from mjrft.core.material import Material
from mjrft.core.surface import Surface
from mjrft.field import lowspeed, plugin
from mjrft.field.model import BodyElements
from mjrft.field.options import SceneOptions
from mjrft.field.scene import Scene, SceneError
from mjrft.field.soil_view import Soil

#: Work counters of the engine, per MjData (``stats_of``): passes evaluated, triangles evaluated
#: and acting, body-passes the treatment stuck, slipped, moved by the implicit step.
STATS = ("calls", "evaluated", "acting", "stuck", "slipping", "implicit")
#: Modes of the engine's pass (engine/forward.h).
_EXPLICIT, _QUERY = 1, 3
#: Status of a pass (engine/forward.h): OK, or a failure code naming a tagged body.
_OK, _BELOW_GROUND = 0, -1_000_000


@dataclass(frozen=True)
class ElementState:
    """Per-element RFT state of one body at one instant, world frame, evaluated elements only.

    Attributes:
      body: body id. index: (n,) element indices into the body's BodyElements.
      pos: (n, 3) quadrature points [m]: the centroid, or for an element the free surface or
        the leading boundary crosses, its submerged leading part's depth-weighted centroid
        (mjrft.core.quadrature); normal: (n, 3) unit normals there; area: (n,) [m^2], for a
        clipped element the area that gives its part's depth integral at that point's depth
        (on an uneven surface, where the point lies at or above the surface there, the part's
        own area); vel: (n, 3) velocities there [m/s]; force: (n, 3) RFT forces [N], the
        element law at (pos, normal, area, vel) (under a flat surface ``mjrft.element_forces``
        of these).
    """

    body: int
    index: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    vel: np.ndarray
    force: np.ndarray


class GranularField:
    """The RFT field of a compiled MjModel that carries the ``mjrft.granular`` plugin.

    Args:
      model: a model from ``mjrft.load_model`` (or an MjSpec given ``mjrft.add_granular``).
      options, overrides: the SceneOptions the model was loaded with, when it was loaded outside
        this process (an MJB file, say); they are checked against the model's tables. By default
        those ``load_model`` used.
    Raises:
      mjrft.field.plugin.EngineError if the model has no plugin instance (with how to add one);
      SceneError (a ValueError) naming the geom or field at fault, or options that do not
      reproduce the model's tables.

    The engine's state belongs to each MjData (``mjData.plugin_state``): several MjData of one
    model may be stepped at once from several threads, each exactly as if alone, and
    ``mj_copyData``, ``mj_resetData`` and ``mj_getState`` carry it.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        material: Material | str | None = None,
        *,
        options: SceneOptions | None = None,
        **overrides,
    ) -> None:
        self.model = model
        self._lib = plugin.library()
        self._instance = plugin.instance(model)
        given = SceneOptions.of(options, material=material, **overrides)
        chosen = given if given.given() else plugin.options_of(model)
        setup = plugin.setup(model, chosen)
        _check_tables(model, setup.tables, given.given())
        self.scene: Scene = setup.scene
        #: Tagged bodies (id order): their elements in the body frame.
        self.bodies: tuple[BodyElements, ...] = setup.bodies
        #: Tagged geom id -> its ElementSet in the body frame.
        self.geom_elements: dict[int, ElementSet] = setup.geom_elements
        self.body_ids = setup.body_ids
        #: Per body of ``body_ids``: True if the free-body treatment can act on it.
        self.stick_eligible = setup.stick_eligible
        #: Per body of ``body_ids``: True if the mechanism treatment acts on it.
        self.mechanism_eligible = setup.mechanism_eligible
        self._tables = setup.tables
        self._seen: weakref.WeakSet = weakref.WeakSet()
        self._last: weakref.ref | None = None

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

    # ------------------------------------------------------------------ the engine's state
    def state_array(self, data: mujoco.MjData, name: str) -> np.ndarray:
        """A view of the engine's array `name` for data (engine/fields.h): the persistent ones
        are views into ``data.plugin_state`` (they keep data alive), the work arrays copies."""
        self._check_data(data)
        lib, m, d = self._lib, ctypes.c_void_p(self.model._address), ctypes.c_void_p(data._address)
        address = lib.mjrft_state_array(m, d, self._instance, name.encode())
        size = lib.mjrft_state_size(m, d, self._instance, name.encode())
        if not address:
            raise KeyError(f"the engine has no state array {name!r}")
        kind = dict((n, t) for t, n in plugin.layout().state)[name]
        dtype = np.int64 if kind == "i64" else np.float64
        base = data.plugin_state
        start = (address - base.ctypes.data) // 8
        if 0 <= start and start + size <= base.shape[0]:
            view = base[start : start + size]
            return view.view(np.int64) if dtype is np.int64 else view
        raw = (ctypes.c_double * size).from_address(address)
        return np.frombuffer(raw, dtype=dtype, count=size).copy()

    def _check_data(self, data: mujoco.MjData) -> None:
        m = self.model
        if (data.plugin_state.shape[0], data.xpos.shape[0], data.qpos.shape[0]) != (
            m.npluginstate,
            m.nbody,
            m.nq,
        ):
            raise ValueError(
                "this MjData does not belong to the field's model (its sizes differ): make it "
                "with mujoco.MjData(field.model)"
            )
        self._seen.add(data)
        self._last = weakref.ref(data)

    def wrench_of(self, data: mujoco.MjData) -> np.ndarray:
        """(nbody, 6) RFT wrench of data's most recent pass (inside a step or ``wrench``), world
        frame, torque about each CoM; a view, updated in place by that MjData's passes."""
        return self.state_array(data, "wrench").reshape(self.model.nbody, 6)

    def decision_of(self, data: mujoco.MjData) -> np.ndarray:
        """(ntbody,) the low-speed treatment's decision per body of ``body_ids`` in data's most
        recent pass (``lowspeed.PURE``, ``STICK``, ``SLIP`` or ``IMPLICIT``); a view."""
        return self.state_array(data, "decision")

    @property
    def last_wrench(self) -> np.ndarray:
        """(nbody, 6) ``wrench_of`` the MjData this field was most recently asked about."""
        data = self._last() if self._last is not None else None
        return np.zeros((self.model.nbody, 6)) if data is None else self.wrench_of(data)

    @property
    def last_decision(self) -> np.ndarray:
        """``decision_of`` the MjData this field was most recently asked about."""
        data = self._last() if self._last is not None else None
        if data is None:
            return np.zeros(len(self.bodies), dtype=np.int64)
        return self.decision_of(data)

    def stats_of(self, data: mujoco.MjData) -> dict[str, int]:
        """Work counters of data's passes since it was made or reset: ``calls`` (evaluations of
        the field), ``evaluated`` (triangles handed to the kernel: those of geoms not culled by
        their bounding sphere), ``acting`` (triangles that felt a force), and of the low-speed
        treatment ``stuck``, ``slipping`` and ``implicit`` body-passes."""
        values = self.state_array(data, "stats")
        return dict(zip(STATS, (int(x) for x in values), strict=True))

    @property
    def stats(self) -> dict[str, int]:
        """``stats_of`` summed over the MjData this field was asked about that still exist."""
        total = dict.fromkeys(STATS, 0)
        for data in list(self._seen):
            for k, v in self.stats_of(data).items():
                total[k] += v
        return total

    def soil(self, data: mujoco.MjData) -> Soil:
        """The deforming ground of one MjData (read and write; ``mjrft.field.soil_view``)."""
        if not self.deforms:
            raise ValueError(
                "this field's ground does not deform: add <numeric name='mjrft:deform_cell' "
                "data='0.002'/> (and mjrft:region) or load the model with deform_cell="
            )
        return Soil(
            self.scene.surface, self.state_array(data, "soil"),
            self.state_array(data, "soil_stats"),
        )  # fmt: skip

    def user_xfrc(self, data: mujoco.MjData) -> np.ndarray:
        """(nbody, 6) ``xfrc_applied`` without the field's contribution (the user's forces)."""
        out = data.xfrc_applied.copy()
        rows = self.body_ids
        written = self.state_array(data, "written").reshape(-1, 6)[rows]
        user = self.state_array(data, "user").reshape(-1, 6)[rows]
        current = out[rows]
        out[rows] = np.where(current == written, user, current)
        return out

    # ------------------------------------------------------------------ passes from Python
    def _run(self, data: mujoco.MjData, mode: int) -> None:
        m, d = ctypes.c_void_p(self.model._address), ctypes.c_void_p(data._address)
        status = self._lib.mjrft_forward(m, d, self._instance, mode)
        if status != _OK:
            self._raise_bad(data, int(status))

    def _raise_bad(self, data: mujoco.MjData, status: int) -> None:
        dt = float(self.model.opt.timestep)
        step = round(data.time / dt) if dt > 0 and np.isfinite(data.time) else -1
        if status <= _BELOW_GROUND:
            be = self.bodies[_BELOW_GROUND - status]
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

    def wrench(
        self,
        data: mujoco.MjData,
        out: np.ndarray | None = None,
        *,
        user_xfrc: np.ndarray | None = None,
    ) -> np.ndarray:
        """RFT wrench on every body at data's current state, ``xfrc_applied`` layout, low-speed
        treatment included, without stepping or writing ``xfrc_applied``.

        Args:
          data: MjData of this model with current kinematics (``mj_forward`` outside a step).
          out: optional (nbody, 6) array to fill.
          user_xfrc: (nbody, 6) the other applied wrenches (world force [N], torque about the
            CoM [N m]); the treatment balances them when it holds a body at rest. Default: none.
        Returns:
          (nbody, 6): world-frame force [N] then torque [N m] about each body's CoM (xipos);
          zero rows for bodies without intruding geoms or out of the medium.
        """
        self._check_data(data)
        m, d = ctypes.c_void_p(self.model._address), ctypes.c_void_p(data._address)
        address = self._lib.mjrft_state_array(m, d, self._instance, b"user_in")
        row = ctypes.c_double * (6 * self.model.nbody)
        user = np.ctypeslib.as_array(row.from_address(address))
        user[:] = 0.0 if user_xfrc is None else np.asarray(user_xfrc, dtype=float).ravel()
        self._run(data, _EXPLICIT)
        if out is None:
            out = np.zeros((self.model.nbody, 6))
        else:
            out[:] = 0.0
        out[self.body_ids] = self.wrench_of(data)[self.body_ids]
        return out

    def element_states(self, data: mujoco.MjData) -> list[ElementState]:
        """Per-element world-frame state and RFT force of every body with geoms in the medium.

        Uses data's current kinematics (call ``mj_forward`` first outside a step). Forces are the
        pure model's (the low-speed treatment acts on whole bodies: see ``wrench``); elements of
        geoms culled by their bounding sphere and elements outside the region are left out.
        data's own state is left as it is (the pass runs on a copy).
        """
        self._check_data(data)
        probe = mujoco.MjData(self.model)
        mujoco.mj_copyData(probe, self.model, data)
        self._run(probe, _QUERY)
        elem_force = self.state_array(probe, "elem_force").reshape(-1, 3)
        cull = self.state_array(probe, "cull")
        soil = self.state_array(probe, "soil")
        out, offset = [], 0
        for k, be in enumerate(self.bodies):
            first, n = offset, len(be.areas)
            offset += n
            g0 = int(self._tables["tbody_geomadr"][k])
            blocks = [
                np.arange(be.segments[i], be.segments[i + 1])
                for i in range(len(be.geoms))
                if not cull[g0 + i]
            ]
            if not blocks:
                continue
            out.append(
                self._element_state(probe, k, np.concatenate(blocks), elem_force[first:], soil)
            )
        return out

    def _element_state(self, data, k: int, idx, elem_force, soil) -> ElementState:
        from mjrft.core import engine

        be = self.bodies[k]
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
        t = self._tables
        rows = engine.quadrature_rows(
            be, t, soil, rot, data.xpos[b], omega, v_ref, p_ref, data.xipos[b]
        )[idx]
        # A clipped element acts at its submerged leading part's depth-weighted centroid, with
        # the area that gives that part's depth integral W at that point's depth (as the pass
        # looks it up, the body's press marks included). On an uneven surface the point can lie
        # at or above the surface there while the part's corners are below it: then no area
        # does, and the part's own area stands.
        moved = (rows[:, 9] > 0.0) & np.any(rows[:, :3] != pos, axis=1)
        ground = self.scene.surface
        j = np.flatnonzero(moved)
        if j.size:  # one call of the engine for all of them
            depth = surface.depth(ground.prm, ground.grid, soil, *rows[j, :3].T, body=k + 1)
            below = depth > 0.0
            pos[j], normal[j] = rows[j, :3], rows[j, 3:6]
            area[j] = np.where(below, rows[j, 9] / np.where(below, depth, 1.0), rows[j, 10])
        vel = v_ref + np.cross(omega, pos - p_ref)
        return ElementState(b, idx, pos, normal, area, vel, elem_force[idx].copy())

    # ------------------------------------------------------------------ stepping
    @contextlib.contextmanager
    def installed(self) -> Iterator[GranularField]:
        """The field acts inside every ``mj_step``/``mj_forward`` of its model: the plugin the
        model carries does that always, so this context only yields the field (kept so scripts
        written as ``with field.installed(): ...`` run unchanged)."""
        yield self


def _check_tables(model: mujoco.MjModel, tables: dict, given: dict) -> None:
    """The scene rebuilt here must give the tables the model carries (the same elements, medium,
    surface and treatment), else the field would describe another scene than the engine runs."""
    for name, want in plugin.numerics(tables).items():
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, plugin.PREFIX + name)
        have = model.numeric(i).data if i >= 0 else None
        if want.size == 0:  # MuJoCo stores an empty numeric field as one 0
            want = np.zeros(1)
        if have is None or have.shape != want.shape or not np.array_equal(have, want):
            how = (
                f"the options given ({', '.join(sorted(given))})" if given
                else "the MJCF's own mjrft: values"
            )  # fmt: skip
            raise SceneError(
                f"the model's engine tables ({plugin.PREFIX}{name}) differ from those {how} "
                "give: pass GranularField the SceneOptions the model was loaded with "
                "(mjrft.load_model(path, **options) in this process records them)"
            )
