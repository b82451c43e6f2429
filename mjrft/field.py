"""The granular force field: RFT wrenches on a compiled MjModel's intruding bodies, every step.

``GranularField(model)`` reads the scene from the MJCF (see ``mjrft.scene``), meshes the tagged
geoms once, and then maps any MjData of that model to one wrench per body, computed from that
data's current kinematics (``xpos``, ``xmat``, ``cvel``, ``subtree_com``: no lag, no finite
differences). Two ways to apply it:

* explicit: ``mj_forward``; ``d.xfrc_applied[:] = user + field.wrench(d)``; ``mj_step`` — the
  wrench is held over the step (all RK4 stages see the same force);
* installed: ``with field.installed(): mj_step(...)`` — in every forward pass (each RK4 stage sees
  its own state) the intruding bodies' rows of ``xfrc_applied`` are set to the user's part plus
  that pass's RFT wrench.

Why ``xfrc_applied`` and not ``qfrc_passive``: MuJoCo's force/torque sensors (load cells) see
external body forces only through ``cfrc_ext``, which is built from ``xfrc_applied`` and contacts.
A wrench added to ``qfrc_passive`` moves the bodies but is invisible to every load cell.

How the user's part survives: per MjData the field remembers the user's part of each intruding
row and what it wrote there. A row that no longer holds what the field wrote was assigned by the
user (a controller, the viewer's perturbation), and that value becomes the user's part; otherwise
the user's part is unchanged. So user forces are never lost or counted twice, for any number of
forward passes per step. Between steps the rows hold user + RFT (``user_xfrc`` gives the user's
part), and leaving ``installed()`` restores the user's values.
"""

from __future__ import annotations

import contextlib
import weakref
from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np

from mjrft import _callback
from mjrft.elements import ElementSet
from mjrft.material import Material
from mjrft.rft import unit_normal_forces
from mjrft.scene import Intruder, Scene, geom_elements, scene_from_model


@dataclass(frozen=True, eq=False)
class BodyElements:
    """All tagged elements of one body, in the body frame (built once at load).

    Attributes:
      body: body id; name: body name.
      centroids: (n, 3) [m], normals: (n, 3) unit, areas: (n,) [m^2]; body frame.
      geoms: (k,) tagged geom ids; segments: (k + 1,) element offsets of each geom's block.
    """

    body: int
    name: str
    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    geoms: np.ndarray
    segments: np.ndarray


@dataclass(frozen=True)
class ElementState:
    """Per-element RFT state of one body at one instant, world frame, evaluated elements only.

    Attributes:
      body: body id. index: (n,) element indices into the body's BodyElements.
      pos: (n, 3) centroids [m]; normal: (n, 3) unit normals; area: (n,) [m^2];
      vel: (n, 3) centroid velocities [m/s]; force: (n, 3) RFT forces [N].
    """

    body: int
    index: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    vel: np.ndarray
    force: np.ndarray


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b for (3,) or (n, 3) operands (np.cross is slow on small arrays)."""
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _quat_mat(q: np.ndarray) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, dtype=np.float64))
    return m.reshape(3, 3)


#: How many past writes of xfrc_applied rows the field remembers, to recognise MjData copies.
XFRC_HISTORY = 4096


_NO_REGION = np.zeros((2, 3))


@dataclass(eq=False)
class _DataState:
    """xfrc ownership of one MjData: user part and rows written (intruding bodies' rows), and
    the address table the native pass reads."""

    ref: weakref.ref
    user: np.ndarray
    written: np.ndarray
    entry: np.ndarray
    finalizer: weakref.finalize | None = None


def _native_words() -> int:
    from mjrft._native import DATA_WORDS

    return DATA_WORDS


class GranularField:
    """RFT force field bound to one compiled MjModel.

    Args:
      model: compiled model whose ``<custom>`` describes the scene (``mjrft.scene``).
      material: overrides the MJCF material if given.
      n_triangles: overrides the triangle count of every primitive geom (MJCF ``prm`` and
        ``mjrft:triangles``): fewer is faster and less accurate. Mesh geoms keep their own.
      tolerance: instead of n_triangles, the relative RMS force error wanted per primitive geom
        (e.g. 0.01); the count comes from ``mjrft.geometry.triangles_for_tolerance``.
    Raises:
      mjrft.scene.SceneError (a ValueError) naming the geom or field at fault.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        material: Material | None = None,
        *,
        n_triangles: int | None = None,
        tolerance: float | None = None,
    ) -> None:
        self.model = model
        self.scene: Scene = scene_from_model(
            model, material, n_triangles=n_triangles, tolerance=tolerance
        )
        self.material = self.scene.material
        self.surface_z = self.scene.surface_z
        self.region = self.scene.region
        by_body: dict[int, list[tuple[Intruder, ElementSet]]] = {}
        for intr in self.scene.intruders:
            es = geom_elements(model, intr)
            # Geom frame -> body frame (geom_pos/quat already absorb MuJoCo's mesh re-centring).
            es_body = es.transformed(
                _quat_mat(model.geom_quat[intr.geom]), model.geom_pos[intr.geom]
            )
            by_body.setdefault(intr.body, []).append((intr, es_body))
        self.geom_elements: dict[int, ElementSet] = {}
        self.bodies: tuple[BodyElements, ...] = tuple(
            self._pack(b, items) for b, items in sorted(by_body.items())
        )
        self.body_ids = np.array([be.body for be in self.bodies], dtype=np.int64)
        self._body_names = {be.body: be.name for be in self.bodies}
        # The compiled kernel serves Fourier-form media with a constant alpha_y (the presets and
        # tables); callables take the NumPy path.
        self._compiled = self.material.fourier is not None and self.material.alpha_y_fn is None
        self._root = {int(b): int(model.body_rootid[b]) for b in self.body_ids}
        n_el = self.n_elements
        # One element index space over all bodies (bodies' blocks in body order).
        offsets = np.cumsum([0] + [len(be.areas) for be in self.bodies])
        self._elem_force_all = np.zeros((n_el, 3))
        #: Per body: (n, 3) world-frame force [N] on each element at the last compiled evaluation.
        self._elem_force = {
            be.body: self._elem_force_all[o : o + len(be.areas)]
            for be, o in zip(self.bodies, offsets, strict=False)
        }
        self._stats = np.zeros(3, dtype=np.int64)
        #: (nbody, 6) wrench of the most recent forward pass of the installed field (updated in
        #: place: keep a reference if you like).
        self.last_wrench = np.zeros((model.nbody, 6))
        # Recent writes to the intruding xfrc rows and the user part behind each: an MjData copy
        # carries rows the field wrote, and is recognised by them. Slot 0 holds the counter.
        n_bt = len(self.bodies)
        self._ring = np.zeros((XFRC_HISTORY + 1, 2, n_bt, 6))
        # Per MjData address: its state (user part, rows written, native address table).
        self._data: dict[int, _DataState] = {}
        self._table = self._native_table(offsets) if self._compiled else None

    def _native_table(self, offsets: np.ndarray) -> np.ndarray:
        """Publish the static arrays for mjrft._native.step (kept alive by self)."""
        from mjrft import _native as nt

        self._n_cent = np.ascontiguousarray(np.concatenate([be.centroids for be in self.bodies]))
        self._n_norm = np.ascontiguousarray(np.concatenate([be.normals for be in self.bodies]))
        self._n_area = np.ascontiguousarray(np.concatenate([be.areas for be in self.bodies]))
        rows = []
        for be, o in zip(self.bodies, offsets, strict=False):
            for gi, g in enumerate(be.geoms):
                start, stop = o + be.segments[gi], o + be.segments[gi + 1]
                rows.append((int(g), be.body, start, stop, self._root[be.body]))
        self._n_gint = np.array(rows, dtype=np.int64).reshape(-1, 5)
        self._n_grb = np.array([self.model.geom_rbound[r[0]] for r in rows], dtype=np.float64)
        self._n_par = np.zeros(nt.N_PARAMS)
        self._n_par[nt.P_SURFACE] = self.surface_z
        self._n_par[nt.P_ZETA] = self.material.zeta
        self._n_par[nt.P_AY] = self.material.alpha_y0
        if self.region is not None:
            self._n_par[nt.P_USE_REGION] = 1.0
            self._n_par[nt.P_REGION :] = self.region.ravel()
        self._n_coef = np.ascontiguousarray(self.material.kernel_coefficients)
        t = np.zeros(nt.FIELD_WORDS, dtype=np.uint64)
        t[nt.F_NELEM] = len(self._n_area)
        t[nt.F_CENT] = self._n_cent.ctypes.data
        t[nt.F_NORM] = self._n_norm.ctypes.data
        t[nt.F_AREA] = self._n_area.ctypes.data
        t[nt.F_NGEOM] = len(rows)
        t[nt.F_GINT] = self._n_gint.ctypes.data
        t[nt.F_GRB] = self._n_grb.ctypes.data
        t[nt.F_NBODY_TAGGED] = len(self.body_ids)
        t[nt.F_BODIES] = self.body_ids.ctypes.data
        t[nt.F_PARAMS] = self._n_par.ctypes.data
        t[nt.F_COEF] = self._n_coef.ctypes.data
        t[nt.F_NBODY] = self.model.nbody
        t[nt.F_LAST_WRENCH] = self.last_wrench.ctypes.data
        t[nt.F_ELEM_FORCE] = self._elem_force_all.ctypes.data
        t[nt.F_STATS] = self._stats.ctypes.data
        t[nt.F_RING] = self._ring.ctypes.data
        t[nt.F_RING_SIZE] = XFRC_HISTORY
        self._n_dirty = np.ones(len(rows), dtype=np.int64)
        t[nt.F_DIRTY] = self._n_dirty.ctypes.data
        return t

    @property
    def stats(self) -> dict[str, int]:
        """Work counters since construction: ``calls`` (evaluations of the field), ``evaluated``
        (triangles handed to the kernel: those of geoms not culled by their bounding sphere) and
        ``acting`` (triangles that felt a force: submerged and leading)."""
        c, e, a = (int(x) for x in self._stats)
        return {"calls": c, "evaluated": e, "acting": a}

    def _pack(self, body: int, items: list[tuple[Intruder, ElementSet]]) -> BodyElements:
        for intr, es in items:
            self.geom_elements[intr.geom] = es
        sizes = [len(es) for _, es in items]
        return BodyElements(
            body=body,
            name=items[0][0].body_name,
            centroids=np.concatenate([es.centroids for _, es in items]),
            normals=np.concatenate([es.normals for _, es in items]),
            areas=np.concatenate([es.areas for _, es in items]),
            geoms=np.array([intr.geom for intr, _ in items], dtype=np.int64),
            segments=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        )

    # ------------------------------------------------------------------ queries
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
        )

    @property
    def n_elements(self) -> int:
        """Total number of surface triangles over all intruding geoms."""
        return int(sum(len(be.areas) for be in self.bodies))

    def _geom_may_act(self, data: mujoco.MjData, g: int) -> bool:
        """False if the geom's bounding sphere is above the surface or outside the region."""
        c = data.geom_xpos[g]
        r = self.model.geom_rbound[g]
        if r <= 0.0:  # MuJoCo leaves rbound 0 for some geoms: never cull those
            return True
        if c[2] - r >= self.surface_z:
            return False
        if self.region is not None:
            if np.any(c + r < self.region[0]) or np.any(c - r > self.region[1]):
                return False
        return True

    def _candidates(self, data: mujoco.MjData, be: BodyElements) -> np.ndarray | None:
        """Element indices of geoms that may be in the medium; None if none may."""
        keep = [self._geom_may_act(data, int(g)) for g in be.geoms]
        if not any(keep):
            return None
        if all(keep):
            return np.arange(be.segments[-1])
        return np.concatenate(
            [np.arange(be.segments[i], be.segments[i + 1]) for i, k in enumerate(keep) if k]
        )

    def element_states(self, data: mujoco.MjData) -> list[ElementState]:
        """Per-element world-frame state and RFT force of every body with geoms in the medium.

        Uses data's current kinematics (call ``mj_forward`` first outside a step).
        """
        out = []
        for be in self.bodies:
            idx = self._candidates(data, be)
            if idx is None:
                continue
            b = be.body
            rot = data.xmat[b].reshape(3, 3)
            pos = be.centroids[idx] @ rot.T + data.xpos[b]
            if self.region is not None:
                inside = np.all((pos >= self.region[0]) & (pos <= self.region[1]), axis=1)
                idx, pos = idx[inside], pos[inside]
            normal = be.normals[idx] @ rot.T
            # cvel = [w, v] with v at the subtree CoM of the body's root (DESIGN.md section 3).
            w, v0 = data.cvel[b, :3], data.cvel[b, 3:]
            vel = v0 + _cross(w, pos - data.subtree_com[self.model.body_rootid[b]])
            area = be.areas[idx]
            f = unit_normal_forces(pos, normal, area, vel, self.material, self.surface_z)
            out.append(ElementState(b, idx, pos, normal, area, vel, f))
        return out

    def wrench(self, data: mujoco.MjData, out: np.ndarray | None = None) -> np.ndarray:
        """RFT wrench on every body, ``xfrc_applied`` layout.

        Args:
          data: MjData of this model with current kinematics (``mj_forward`` outside a step).
          out: optional (nbody, 6) array to fill.
        Returns:
          (nbody, 6): world-frame force [N] then torque [N m] about each body's CoM (xipos);
          zero rows for bodies without intruding geoms or out of the medium.
        """
        if out is None:
            out = np.zeros((self.model.nbody, 6))
        else:
            out[:] = 0.0
        self._check_finite(data)
        if self._compiled:
            self._wrench_compiled(data, out)
            return out
        for st in self.element_states(data):
            f = st.force
            out[st.body, :3] = f.sum(axis=0)
            out[st.body, 3:] = _cross(st.pos - data.xipos[st.body], f).sum(axis=0)
            self._count(len(st.index), int(np.count_nonzero(np.any(f != 0.0, axis=1))))
        return out

    def _wrench_compiled(self, data: mujoco.MjData, out: np.ndarray) -> None:
        """The hot path: one fused kernel call per evaluated geom block (mjrft._kernel)."""
        from mjrft import _kernel

        m = self.material
        co, ay, zeta = m.kernel_coefficients, m.alpha_y0, m.zeta
        use_region = self.region is not None
        region = self.region if use_region else _NO_REGION
        for be in self.bodies:
            b = be.body
            rot = pos = omega = v_ref = p_ref = com = None
            evaluated = acting = 0
            for gi, g in enumerate(be.geoms):
                start, stop = be.segments[gi], be.segments[gi + 1]
                if not self._geom_may_act(data, int(g)):
                    self._elem_force[b][start:stop] = 0.0
                    continue
                if rot is None:
                    rot = data.xmat[b].reshape(3, 3)
                    pos, com = data.xpos[b], data.xipos[b]
                    omega, v_ref = data.cvel[b, :3], data.cvel[b, 3:]
                    p_ref = data.subtree_com[self._root[b]]
                acting += _kernel.body_wrench(
                    be.centroids, be.normals, be.areas, start, stop, rot, pos, omega, v_ref,
                    p_ref, com, co, ay, zeta, self.surface_z, use_region, region, out[b],
                    self._elem_force[b],
                )  # fmt: skip
                evaluated += stop - start
            self._count(evaluated, acting)

    def _count(self, evaluated: int, acting: int) -> None:
        self._stats += (1, evaluated, acting)

    def _check_finite(self, data: mujoco.MjData) -> None:
        b = self.body_ids
        if not (np.all(np.isfinite(data.xpos[b])) and np.all(np.isfinite(data.cvel[b]))):
            bad = next(
                int(i)
                for i in b
                if not (np.all(np.isfinite(data.xpos[i])) and np.all(np.isfinite(data.cvel[i])))
            )
            raise FloatingPointError(
                f"body '{self._body_names[bad]}' has a non-finite position or velocity at time "
                f"{data.time:.6g} s; the granular field refuses to feed NaN forward (check the "
                "timestep and actuators)"
            )

    # ------------------------------------------------------------------ application
    def apply_passive(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Set the intruding rows of ``xfrc_applied`` to user part + RFT (the installed path).

        Runs in MuJoCo's passive callback, for every forward pass the native guard does not
        handle itself: an MjData seen for the first time (registered here), a problem the
        native pass reported (raised here), Python-only materials, or a chained user callback.
        Calls no mujoco function: inside a callback, any binding call resets the binding's
        per-thread error escape, after which an exception raised here would abort the process.
        """
        st = self._state(data)
        if self._table is not None:
            from mjrft import _native

            status = _native.step(self._table.ctypes.data, st.entry.ctypes.data)
            if status != _native.OK:
                self._check_finite(data)  # raises, naming the body
                raise FloatingPointError(f"granular field failed with status {status}")
            return
        w = self.wrench(data)
        rows = self.body_ids
        current = data.xfrc_applied[rows]
        assigned = np.any(current != st.written, axis=1)
        st.user[assigned] = current[assigned]
        total = st.user + w[rows]
        data.xfrc_applied[rows] = total
        st.written[:] = total
        counter = int(self._ring[0, 0, 0, 0])
        slot = 1 + counter % XFRC_HISTORY
        self._ring[slot, 0], self._ring[slot, 1] = total, st.user
        self._ring[0, 0, 0, 0] = counter + 1
        self.last_wrench[:] = w

    def _state(self, data: mujoco.MjData) -> _DataState:
        """Ownership state of an MjData, registering it (and its arrays) on first sight."""
        key = data._address
        st = self._data.get(key)
        if st is not None and st.ref() is data:
            return st
        current = np.array(data.xfrc_applied[self.body_ids])
        st = _DataState(
            ref=weakref.ref(data),
            user=self._adopt(current),
            written=current.copy(),
            entry=np.zeros(_native_words(), dtype=np.uint64),
        )
        if self._table is not None:
            from mjrft import _native as nt

            for word, arr in (
                (nt.D_XPOS, data.xpos),
                (nt.D_XMAT, data.xmat),
                (nt.D_XIPOS, data.xipos),
                (nt.D_CVEL, data.cvel),
                (nt.D_SUBTREE_COM, data.subtree_com),
                (nt.D_GEOM_XPOS, data.geom_xpos),
                (nt.D_XFRC, data.xfrc_applied),
                (nt.D_USER, st.user),
                (nt.D_WRITTEN, st.written),
            ):
                st.entry[word] = arr.ctypes.data
            _callback.register_data(self.model, key, st.entry.ctypes.data)
        st.finalizer = weakref.finalize(data, self._forget, key, st)
        self._data[key] = st
        return st

    def _forget(self, key: int, st: _DataState) -> None:
        if self._data.get(key) is st:
            self._data.pop(key)
            _callback.unregister_data(key)

    def _adopt(self, current: np.ndarray) -> np.ndarray:
        """User part of rows first seen on an MjData.

        A copy of a tracked MjData carries rows the field wrote (user + RFT); the field keeps
        the user part behind each of its last XFRC_HISTORY writes. Rows matching none of them
        are all the user's.
        """
        n = min(int(self._ring[0, 0, 0, 0]), XFRC_HISTORY)
        if n:
            hits = np.flatnonzero(np.all(self._ring[1 : n + 1, 0] == current, axis=(1, 2)))
            if hits.size:
                return self._ring[1 + hits[-1], 1].copy()
        return current.copy()

    def user_xfrc(self, data: mujoco.MjData) -> np.ndarray:
        """(nbody, 6) ``xfrc_applied`` without the field's contribution (the user's forces)."""
        out = np.array(data.xfrc_applied)
        st = self._data.get(data._address)
        if st is not None and st.ref() is data:
            rows = self.body_ids
            current = out[rows]
            assigned = np.any(current != st.written, axis=1)
            out[rows] = np.where(assigned[:, None], current, st.user)
        return out

    def _restore_user_xfrc(self) -> None:
        for key, st in list(self._data.items()):
            data = st.ref()
            if data is not None:
                data.xfrc_applied[:] = self.user_xfrc(data)
            st.finalizer.detach()
            self._data.pop(key)
            _callback.unregister_data(key)
        self._ring[0, 0, 0, 0] = 0.0

    @contextlib.contextmanager
    def installed(self) -> Iterator[GranularField]:
        """Make RFT forces act inside every ``mj_step``/``mj_forward`` of this model.

        Applies to every MjData of the model; other models (and model compilation) are not
        affected. A user's own passive callback keeps running.
        """
        table = 0 if self._table is None else self._table.ctypes.data
        _callback.install(self.model, lambda m, d: self.apply_passive(m, d), table)
        try:
            yield self
        finally:
            _callback.uninstall(self.model)
            self._restore_user_xfrc()
